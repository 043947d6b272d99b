"""What a dataset holds of its robot, read from its description (controller/measured/dataset_robot.py):
the trial columns (a floating base's state only for a floating base), the contact frame of a
robot that carries no tool, the quaternion check."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import ARMS, JOINTS, g1_model
from impactqp.controller.measured.dataset import TRIAL_COLUMNS
from impactqp.controller.measured.dataset_robot import (
    BASE_COLUMNS,
    QUATERNION,
    QUATERNION_TOLERANCE,
    ContactFrame,
    base_columns,
    contact_frame_from_dict,
    quaternion_problem,
    trial_columns,
)
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.validation import BadInputError

CONTACT_FRAME = ROBOTS["g1"].contact.name


def test_columns_come_from_the_robot():
    columns = trial_columns("g1")
    joints = len(ROBOTS["g1"].joints)
    model = g1_model()
    assert joints == model.n_joints == model.model.nv - model.base_nv
    assert len(BASE_COLUMNS) == model.base_nq + model.base_nv and base_columns("g1") == BASE_COLUMNS
    assert columns[: 1 + len(BASE_COLUMNS)] == ["t", *BASE_COLUMNS]
    assert len(columns) == 1 + len(BASE_COLUMNS) + 4 * joints and len(set(columns)) == len(columns)
    assert columns[-1] == f"dq_cmd{joints}" and f"q{joints + 1}" not in columns
    # the arm's columns are unchanged
    assert TRIAL_COLUMNS == trial_columns("panda") == trial_columns("fr3") == trial_columns(ROBOTS["panda"])


@pytest.mark.parametrize("arm", ARMS)
def test_a_fixed_base_has_no_base_columns(arm):
    joints = len(ROBOTS[arm].joints)
    assert base_columns(arm) == ()
    assert trial_columns(arm) == ["t"] + [f"{x}{i}" for x in ("q", "dq", "tau", "dq_cmd") for i in range(1, joints + 1)]
    assert TRIAL_COLUMNS == ["t"] + [f"{x}{i}" for x in ("q", "dq", "tau", "dq_cmd") for i in range(1, JOINTS + 1)]


def test_the_contact_frame_is_the_g1_contact_frame_and_reads_back():
    palm = ContactFrame.of("g1")
    assert palm.frame == CONTACT_FRAME and palm.name == CONTACT_FRAME
    assert contact_frame_from_dict(palm.as_dict(), "g1") == palm


@pytest.mark.parametrize("arm", ARMS)
def test_an_arm_has_no_contact_frame(arm):
    with pytest.raises(BadInputError, match="no contact point"):
        ContactFrame.of(arm)


@pytest.mark.parametrize("tool", [
    {"frame": "left_palm", "contact_point": [0, 0, 0]},
    {"frame": CONTACT_FRAME, "contact_point": [0, 0, 0.01]},
    {"frame": CONTACT_FRAME, "contact_point": [0, 0]},
    {"frame": CONTACT_FRAME},
    {"frame": CONTACT_FRAME, "contact_point": [0, 0, 0], "mass": 1.0},
])
def test_another_tool_is_bad_input(tool):
    with pytest.raises(BadInputError):
        contact_frame_from_dict(tool, "g1")


@settings(max_examples=30, deadline=None)
@given(quaternion=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda x: np.linalg.norm(x) > 0.1),
       rows=st.integers(1, 20), bad=st.integers(0, 19), factor=st.floats(0.5, 2.0))
def test_quaternion_problem_names_the_first_row_off_the_unit_sphere(quaternion, rows, bad, factor):
    base = np.zeros((rows, len(BASE_COLUMNS)))
    base[:, QUATERNION] = np.asarray(quaternion) / np.linalg.norm(quaternion)
    assert quaternion_problem(base, "f.csv") is None
    if abs(factor - 1.0) > 10 * QUATERNION_TOLERANCE:
        base[bad % rows:, QUATERNION] *= factor
        assert f"data row {bad % rows + 1}," in quaternion_problem(base, "f.csv")
