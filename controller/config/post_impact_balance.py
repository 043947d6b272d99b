"""The standing robot's balance after the impact: the tasks of a running controller re-weighted so
that its centre of mass is brought back over the support polygon (``balance_after_impact``).

At the impact the hand's impulse sets the whole body moving (the post-impact CoM velocity of
``docs/floating-base.md``). The approach's tasks keep the hand's task first (weight 100) and hold
the CoM at its start with a soft PD (weight 10, k_p = 100 /s^2): fed the blended state
(``sim.trial_loop.ControllerSource``) the QP sees the body move, but this CoM task hardly slows
it. The balance phase changes targets and
weights only (no reset: the acceleration memory and the jerk limit stay):

- the CoM task's target moves, in x and y, to the centre of the support polygon (the mean of its
  vertices, the held contacts where the command stands now; the height is kept), its PD stiffens
  to k_p = :data:`COM_STIFFNESS` (natural frequency 30 rad/s, below the standing servo's 40:
  faster would ask the servo for what it cannot follow) and critically damped (k_d = 2 sqrt(k_p):
  the damping of the CoM's momentum), its weight :data:`COM_WEIGHT` above every other task;
- the hand holds where it is (its speed target 0: ``QpDriver.stop``) with its weights scaled by
  :data:`HAND_SCALE`: it no longer competes with the balance; it is not retracted, because
  pulling the arm back is one more momentum the body must absorb while it is already moving.

What it does on the close stance, measured: docs/whole-body-qp.md ("The state the QP is given,
and the balance after the impact").
"""

from __future__ import annotations

import numpy as np

from impactqp.tasks import CentreOfMassTask, ContactApproachTask

from ..model.humanoid_stance import support_polygon

COM_STIFFNESS = 900.0  # 1/s^2: k_p of the CoM task after the impact
COM_WEIGHT = 1000.0  # the CoM task's weight after the impact, per axis
HAND_SCALE = 1e-3  # the hand task's weights after the impact, relative to the approach's


def balance_after_impact(controller) -> None:
    """Re-weight a standing robot's controller for the balance after the impact (module
    docstring), from its last command; a controller without held contacts or CoM task is left
    unchanged."""
    robot = controller.robot
    com = next((t for t in controller.tasks if isinstance(t, CentreOfMassTask)), None)
    if not robot.description.held_contacts or com is None or controller.memory.q_cmd is None:
        return
    centre = support_polygon(robot, controller.memory.q_cmd).mean(axis=0)
    target = com.target.copy()
    target[:2] = centre[:2]
    com.hold(target, COM_STIFFNESS, np.full(3, COM_WEIGHT))
    for task in controller.tasks:
        if isinstance(task, ContactApproachTask):
            task.weight = task.weight * HAND_SCALE
