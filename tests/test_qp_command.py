"""Command and Status: the status is an enum that is still the string it always was."""

import json

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.qp import Command, Status

STRINGS = {
    Status.OK: "ok",
    Status.VELOCITY_CLIPPED: "ok_velocity_clipped",
    Status.FALLBACK_INFEASIBLE: "fallback_infeasible",
    Status.FALLBACK_INVALID_STATE: "fallback_invalid_state",
    Status.FALLBACK_SINGULAR: "fallback_singular_posture",
    Status.FALLBACK_SOLVER_ERROR: "fallback_solver_error",
    Status.IMPACT_BRAKE: "impact_brake",
}


def command(status) -> Command:
    zeros = np.zeros(JOINTS)
    return Command(zeros, zeros, zeros, status, [], [], zeros, zeros)


def test_every_status_has_a_string():
    assert set(STRINGS) == set(Status)


@pytest.mark.parametrize("status", list(Status))
def test_a_status_is_its_string_for_comparison_printing_and_json(status):
    text = STRINGS[status]
    assert status == text and text == status and isinstance(status, str)
    assert Status(text) is status
    assert str(status) == f"{status}" == "%s" % status == text
    assert json.dumps({"status": status}) == json.dumps({"status": text})
    assert json.loads(json.dumps(status)) == text
    assert {text: 1}[status] == 1  # same hash as the string
    assert np.array([status]).tolist() == [text]


@pytest.mark.parametrize("status", list(Status))
def test_only_the_fallback_statuses_are_fallbacks(status):
    """The two ok statuses and the impact brake (the planned behaviour after an impact) are not."""
    expected = STRINGS[status].startswith("fallback")
    assert status.is_fallback == expected
    assert command(status).is_fallback == expected
    assert command(STRINGS[status]).is_fallback == expected  # a plain string too


def test_command_defaults_and_slots():
    c = command(Status.OK)
    assert (c.impact_constraints_active, c.solver, c.message, c.phase) == (False, "", "", "approach")
    with pytest.raises(AttributeError):
        c.unknown = 1  # slotted: one is made per cycle
