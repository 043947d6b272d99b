"""The G1's part of the dataset format (controller/measured/humanoid_format.py)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.measured.dataset import TRIAL_COLUMNS, trial_columns
from impactqp.controller.measured.humanoid_format import (
    BASE_COLUMNS,
    G1,
    PALM,
    QUATERNION,
    QUATERNION_TOLERANCE,
    contact_frame_from_dict,
    g1_model,
    joint_count,
    quaternion_problem,
)
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.validation import BadInputError

CONTACT_FRAME = ROBOTS["g1"].contact.name


def test_columns_come_from_the_robot():
    columns = trial_columns(G1)
    joints = joint_count()
    model = g1_model()
    assert joints == model.n_joints == model.model.nv - model.base_nv
    assert columns[: 1 + len(BASE_COLUMNS)] == ["t", *BASE_COLUMNS]
    assert len(columns) == 1 + len(BASE_COLUMNS) + 4 * joints and len(set(columns)) == len(columns)
    assert columns[-1] == f"dq_cmd{joints}" and f"q{joints + 1}" not in columns
    # the arm's columns are unchanged
    assert TRIAL_COLUMNS == trial_columns("panda") == trial_columns("fr3")
    assert TRIAL_COLUMNS == ["t"] + [f"{x}{i}" for x in ("q", "dq", "tau", "dq_cmd") for i in range(1, JOINTS + 1)]


def test_the_contact_frame_is_the_g1_contact_frame_and_reads_back():
    assert PALM.frame == CONTACT_FRAME and PALM.name == CONTACT_FRAME
    assert contact_frame_from_dict(PALM.as_dict()) == PALM


@pytest.mark.parametrize("tool", [
    {"frame": "left_palm", "contact_point": [0, 0, 0]},
    {"frame": CONTACT_FRAME, "contact_point": [0, 0, 0.01]},
    {"frame": CONTACT_FRAME, "contact_point": [0, 0]},
    {"frame": CONTACT_FRAME},
    {"frame": CONTACT_FRAME, "contact_point": [0, 0, 0], "mass": 1.0},
])
def test_another_tool_is_bad_input(tool):
    with pytest.raises(BadInputError):
        contact_frame_from_dict(tool)


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
