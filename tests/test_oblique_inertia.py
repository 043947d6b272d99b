"""The simulated plant's inverse inertia at the contact (scenarios/oblique_inertia.py): identities
of the rigid multibody and of its servos, from first principles."""

import json

import numpy as np
import pytest

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.frictional_impact import frictional_impulse
from impactqp.controller.model.impedance_inverse_inertia import impedance_inverse_inertia
from impactqp.controller.model.jump import gm_inverse_inertia
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.scenarios.cli import main
from impactqp.scenarios.oblique import IMPACT_DURATION, POSTURES
from impactqp.scenarios.oblique_inertia import (
    FRANKA_JOINT_STIFFNESS,
    PULSE_DURATIONS,
    SERVOS,
    HeldArm,
    describe,
    distance,
    servos,
    with_plant_row,
)
from impactqp.sim.plant import PlantParameters

CHOICE = RobotChoice.of("panda", "impact_tip")


@pytest.fixture(scope="module")
def posture():
    q = CHOICE.posture("elbow_right").q
    return q, gm_inverse_inertia(CHOICE.model().terms(q))


@pytest.mark.parametrize("gain", [5.0, 500.0])
def test_a_pulse_within_one_control_period_meets_the_free_joints(posture, gain):
    """The computed-torque servo's torque is held over each 1 ms control period: a pulse inside
    one period meets the rigid multibody with its joints free, whose inverse inertia at the
    contact is J M^-1 J^T (MuJoCo's M is Pinocchio's), whatever the gain."""
    q, W_gm = posture
    W = HeldArm(CHOICE, PlantParameters(servo_gain=gain)).inverse_inertia(q, 0.001)
    np.testing.assert_allclose(W, W_gm, atol=2e-3 * np.abs(W_gm).max())


def test_a_computed_torque_servo_only_scales_the_free_joints_inverse_inertia(posture):
    """The computed-torque feedback M (omega^2 e + 2 omega de) pushes back along M^-1 J^T iota only:
    over a longer pulse W_sim = c W_gm with 0 < c < 1, so its stick coefficient is W_gm's."""
    q, W_gm = posture
    W = HeldArm(CHOICE, PlantParameters(servo_gain=50.0)).inverse_inertia(q, 0.015)
    c = np.sum(W * W_gm) / np.sum(W_gm * W_gm)
    assert 0.0 < c < 1.0
    np.testing.assert_allclose(W, c * W_gm, atol=2e-2 * np.abs(W_gm).max())
    assert describe(W, DEFAULT_WALL.normal)["mu_bar"] == pytest.approx(describe(W_gm, DEFAULT_WALL.normal)["mu_bar"], rel=2e-2)


def test_the_plant_row_is_the_law_with_the_plants_own_inverse_inertia(posture):
    """On the default plant W_sim = c W_gm over the pulse (above): a contact that sticks (mu =
    0.6 above W_gm's mu_bar) stops fully, P = -W_sim^-1 v-, so the plant row's normal impulse is
    W_gm's over c, and its mode the stick of the simulated row."""
    q, W_gm = posture
    W = HeldArm(CHOICE, PlantParameters()).inverse_inertia(q, IMPACT_DURATION)
    c = np.sum(W * W_gm) / np.sum(W_gm * W_gm)
    simulated = {"pre_tangential": [0.0, 0.03, 0.0], "contact_speed": 0.12, "mode": "stick", "post_tangential": [0.0] * 3}
    row = {"series": "grid", "posture": "elbow_right", "friction": 0.6, "simulated": simulated, "predicted": {}}
    report = with_plant_row({"rows": [row]}, CHOICE, None)
    plant = report["rows"][0]["predicted"]["plant"]
    normal = DEFAULT_WALL.normal
    free = frictional_impulse(W_gm, normal, np.array([0.0, 0.03, 0.0]) - 0.12 * normal, 0.6, 0.0)
    assert plant["mode"] == "stick" and plant["mode_agrees"] and plant["velocity_agrees"]
    assert plant["normal_impulse"] == pytest.approx(normal @ free.impulse / c, rel=2e-2)
    assert report["plant_pulse"] == IMPACT_DURATION and report["summary"]["all"]["plant"]["mode_agreement"] == 100.0


@pytest.mark.parametrize("name", list(CHOICE.robot.postures)[:POSTURES])
def test_the_joint_impedance_plants_W_is_the_held_arms_from_the_model(name):
    """The plant's joint impedance tau = K (q0 - q) - D dq + h, D_i = 2 sqrt(K_i M_ii), is the
    linear system M x'' + D x' + K x = J^T f about the posture up to M's and D's change with q:
    the plant's W_sim over each pulse is the model's W_K(T) (``impedance_inverse_inertia``), within
    the physics step's sampling of the pulse (4 steps over 1 ms: 5 %; 2 % over 7 and 15 ms)."""
    q = CHOICE.posture(name).q
    arm = HeldArm(CHOICE, PlantParameters(servo_stiffness=FRANKA_JOINT_STIFFNESS))
    for duration in PULSE_DURATIONS:
        W = impedance_inverse_inertia(CHOICE.model().terms(q), FRANKA_JOINT_STIFFNESS, duration)
        assert distance(W, arm.inverse_inertia(q, duration)) < (0.05 if duration < 0.005 else 0.02)


def test_the_servos_of_the_study():
    assert list(servos(7)) == list(SERVOS)
    assert servos(7)[SERVOS[3]].servo_stiffness == FRANKA_JOINT_STIFFNESS
    assert list(servos(6)) == list(SERVOS[:3])  # Franka's impedance has seven joints


def test_the_command_writes_the_study(tmp_path, capsys):
    """``oblique --inverse-inertia``: its JSON and Markdown, per posture the predictors' rows and
    one per servo and pulse."""
    out = tmp_path / "w"
    assert main(["oblique", "--inverse-inertia", "--out", str(out)]) == 0
    report = json.loads((out / "inverse-inertia.json").read_text())
    assert [row["posture"] for row in report["rows"]] == list(CHOICE.robot.postures)[:POSTURES]
    for row in report["rows"]:
        assert [(e["servo"], e["duration"]) for e in row["simulated"]] == [
            (servo, duration) for servo in SERVOS for duration in PULSE_DURATIONS]
        assert row["gm"]["mu_bar"] > 0.0 and row["crb"]["mu_bar"] > 0.0
    assert (out / "inverse-inertia.md").read_text() in capsys.readouterr().out
