"""Plain-numpy statement of the compiled pass of ``controller.model.crb_prediction``."""

import numpy as np
from scipy.linalg import expm

from impactqp.controller.model.crb_prediction import (
    AXIS, INERTIA, KIND, LEVER, MASS, ON_PATH, PARENT, PRISMATIC, ROTATION, TRANSLATION, KinematicTree,
)
from impactqp.controller.model.jump import skew


def reference_crb_state(tree: KinematicTree, q: np.ndarray):
    """``crb_state``: (J, contact point, centre of mass, inertia about it, mass) of the locked
    robot at q, with each joint's rotation exp([a]x q) and world matrices in numpy."""
    rotations, origins = [], []
    for i, row in enumerate(tree.joints):
        parent = int(row[PARENT])
        R_parent, o_parent = (np.eye(3), np.zeros(3)) if parent < 0 else (rotations[parent], origins[parent])
        axis = row[AXIS:AXIS + 3]
        R = R_parent @ row[ROTATION:ROTATION + 9].reshape(3, 3)
        o = o_parent + R_parent @ row[TRANSLATION:TRANSLATION + 3]
        if row[KIND] == PRISMATIC:
            o = o + q[i] * (R @ axis)
        else:
            R = R @ expm(skew(axis) * q[i])
        rotations.append(R)
        origins.append(o)
    masses = tree.joints[:, MASS]
    centres = np.array([o + R @ row[LEVER:LEVER + 3] for R, o, row in zip(rotations, origins, tree.joints)])
    mass = masses.sum()
    com = masses @ centres / mass
    inertia = sum(
        R @ row[INERTIA:INERTIA + 9].reshape(3, 3) @ R.T + m * (d @ d * np.eye(3) - np.outer(d, d))
        for R, row, m, d in zip(rotations, tree.joints, masses, centres - com)
    )
    point = origins[tree.contact_joint] + rotations[tree.contact_joint] @ tree.contact_translation
    J = np.zeros((3, len(tree.joints)))
    for i, row in enumerate(tree.joints):
        if row[ON_PATH]:
            z = rotations[i] @ row[AXIS:AXIS + 3]
            J[:, i] = z if row[KIND] == PRISMATIC else np.cross(z, point - origins[i])
    return J, point, com, inertia, mass
