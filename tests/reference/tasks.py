"""Plain-numpy statements of the compiled task kernels (``tasks``): the rows each class's
``compute_into`` must write."""

import numpy as np
import pinocchio as pin

from impactqp.tasks import CentreOfMassTask, ContactApproachTask, DampingTask, FrameTask, PostureTask


def reference_rows(task, terms, A, b) -> None:
    """The rows A, b of ``task`` at ``terms`` in plain numpy (``compute_into`` itself for a class
    without a kernel)."""
    if isinstance(task, ContactApproachTask):
        # b = [k_v (v* - v); k_R log(R* R^T) - d_R w] - dJ6 dq, its linear part in the surface frame
        np.multiply(task._twist_gain, terms.J6 @ terms.dq, out=b)
        b[:3] += task._reference_acceleration
        b[3:] += task.orientation_stiffness * pin.log3(task.target_rotation @ terms.contact_rotation.T)
        b -= terms.dJ6_dq
        b[:3] = task.basis @ b[:3]
        np.matmul(task.basis, terms.J6[:3], out=A[:3])
        A[3:] = terms.J6[3:]
    elif isinstance(task, PostureTask):  # the actuated joints: the last rows of q and dq
        rows = task.rows
        A[:] = np.eye(A.shape[1])[-rows:]
        np.subtract(task.stiffness * (task.target - terms.q[-rows:]), task.damping * terms.dq[-rows:], out=b)
    elif type(task) is FrameTask:
        # b = kp [p* - p; log(R* R^T)] - kd J6 v - dJ6 v
        position, rotation, J6, drift = task.frame_state(terms)
        error = np.concatenate([task.target_position - position, pin.log3(task.target_rotation @ rotation.T)])
        A[:] = J6
        b[:] = task.stiffness * error - task.damping * (J6 @ terms.dq) - drift
    elif isinstance(task, CentreOfMassTask):
        A[:] = terms.Jcom
        b[:] = task.stiffness * (task.target - terms.com) - task.damping * (terms.Jcom @ terms.dq) - terms.dJcom_dq
    elif isinstance(task, DampingTask):
        A[:] = np.eye(A.shape[1])
        np.multiply(-task.gain, terms.dq, out=b)
    else:
        task.compute_into(terms, A, b)
