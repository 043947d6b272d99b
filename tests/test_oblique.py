"""The oblique-impact study (``scenarios.oblique``) and the measurement of a simulated oblique
impact (``controller.measured.oblique_impact``): the momentum balance of a simulated impact, the
wall's friction cone, a frictionless wall, the rules of the simulated mode and the command end to
end."""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.measured.oblique_impact import (
    STICK_SPEED,
    impact_window,
    measure_oblique_impact,
    observed_mode,
    path_least_speed,
    tangential_part,
)
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.scenarios.cli import main
from impactqp.scenarios.cli.exit_codes import EXIT_BAD_INPUT
from impactqp.scenarios.oblique import GRIDS, ObliqueTrials, held_row, velocity_agrees
from impactqp.sim.generation import tangential_direction
from impactqp.sim.plant import PlantParameters
from impactqp.sim.runner import TrialSpec, run_approach
from impactqp.sim.scene import NOSLIP_ITERATIONS, build_scene
from impactqp.sim.trial_sources import CARTESIAN

NORMAL = DEFAULT_WALL.normal
MOMENTUM_TOLERANCE = 0.01
"""Share of |J^T iota| left by the momentum balance: the period's M, h and J are taken at its
start sample (they change within the 1 ms period)."""
MUJOCO_MIN_FRICTION = 1e-5
"""MuJoCo's smallest friction coefficient (mjMINMU): a pair of friction 0 keeps this much."""


@pytest.fixture(scope="module")
def trials():
    return ObliqueTrials(RobotChoice.of("panda"))


def simulate(trials, friction, ratio, posture="elbow_right", speed=0.12):
    """The log and the scene of one oblique trial (v_t = ratio v_n along the wall's tangent)."""
    scene = trials.scene(friction)
    spec = TrialSpec(posture, trials.choice.posture(posture).q, speed, ratio * speed * tangential_direction(NORMAL))
    return run_approach(scene, trials.robot, spec, CARTESIAN).log, scene


@pytest.fixture(scope="module")
def sliding(trials):
    return simulate(trials, 0.1, 1.0)


@pytest.fixture(scope="module")
def sticking(trials):
    return simulate(trials, 0.6, 0.5, "elbow_left")


@pytest.fixture(scope="module")
def frictionless(trials):
    return simulate(trials, 0.0, 1.0)


@pytest.mark.parametrize("case", ["sliding", "sticking"])
def test_measured_impulse_is_the_integral_of_the_contact_force_over_the_window(trials, case, request):
    log, scene = request.getfixturevalue(case)
    m = measure_oblique_impact(log, trials.robot, NORMAL)
    h = scene.timestep
    inside = (log.force_t >= log.force_t[m.start] - 0.5 * h) & (log.force_t <= log.force_t[m.end] + 0.5 * h)
    assert np.all(log.force[log.force_t < log.force_t[m.start] - 0.5 * h] == 0.0)  # nothing before the start
    np.testing.assert_allclose(m.impulse, h * log.force[inside].sum(axis=0), rtol=1e-12, atol=1e-15)
    assert m.normal_impulse == pytest.approx(NORMAL @ m.impulse, rel=1e-12)
    np.testing.assert_allclose(m.tangential_impulse + m.normal_impulse * NORMAL, m.impulse, atol=1e-14)
    assert abs(NORMAL @ m.tangential_impulse) < 1e-14


@pytest.mark.parametrize("case", ["sliding", "sticking", "frictionless"])
def test_momentum_balance_of_a_simulated_oblique_impact(trials, case, request):
    """Over the impact, sum M (dq_{k+1} - dq_k) = sum J^T iota_k + sum (tau_k - h_k) dt: the robot's
    momentum changes by the wall's impulse and the servo's (the servo's part is 10-20 % of the
    wall's, so a balance without it fails)."""
    log, scene = request.getfixturevalue(case)
    robot = trials.robot
    m = measure_oblique_impact(log, robot, NORMAL)
    substeps, dt = int(round(log.control_period / scene.timestep)), log.control_period
    change, wall, servo = np.zeros(robot.nv), np.zeros(robot.nv), np.zeros(robot.nv)
    for k in range(m.pre_index, m.post_index):
        terms = robot.terms(log.q[k], log.dq[k], check_limits=False)
        change += terms.M @ (log.dq[k + 1] - log.dq[k])
        wall += terms.J.T @ (scene.timestep * log.force[k * substeps:(k + 1) * substeps].sum(axis=0))
        servo += (log.tau[k] - terms.h) * dt
    assert np.linalg.norm(change - wall - servo) <= MOMENTUM_TOLERANCE * np.linalg.norm(wall)
    assert np.linalg.norm(change - wall) > MOMENTUM_TOLERANCE * np.linalg.norm(wall)
    # the window's impulse is the measured one, up to the force after the impact's end
    window = scene.timestep * log.force[m.pre_index * substeps:m.post_index * substeps].sum(axis=0)
    assert np.linalg.norm(window - m.impulse) <= 0.01 * np.linalg.norm(m.impulse)


@pytest.mark.parametrize(("case", "mu"), [("sliding", 0.1), ("sticking", 0.6)])
def test_simulated_tangential_impulse_lies_inside_the_walls_friction_cone(trials, case, mu, request):
    log, _ = request.getfixturevalue(case)
    m = measure_oblique_impact(log, trials.robot, NORMAL)
    assert m.normal_impulse > 0.0
    assert np.linalg.norm(m.tangential_impulse) <= mu * m.normal_impulse * (1 + 1e-9)
    normal_force = log.force @ NORMAL
    tangential_force = np.linalg.norm(log.force - np.outer(normal_force, NORMAL), axis=1)
    assert np.all(tangential_force <= mu * normal_force + 1e-9)


def test_sliding_contact_uses_the_whole_cone_and_a_sticking_one_less(trials, sliding, sticking):
    slid = measure_oblique_impact(sliding[0], trials.robot, NORMAL)
    stuck = measure_oblique_impact(sticking[0], trials.robot, NORMAL)
    assert np.linalg.norm(slid.tangential_impulse) == pytest.approx(0.1 * slid.normal_impulse, rel=1e-3)
    assert slid.mode == "slip" and stuck.mode == "stick"
    assert np.linalg.norm(stuck.tangential_impulse) < 0.5 * 0.6 * stuck.normal_impulse


def test_a_simulated_slide_that_turns_past_90_degrees_without_stopping_is_a_slip(trials, sticking):
    """On `elbow_left` at mu = 0.1 the tangential velocity turns by more than 90 degrees during
    the impact without coming near 0: a slip, as the law says (the former rule, v_t+ . v_t- < 0,
    called it a reversal). The sticking trial's path comes to rest."""
    log, _ = simulate(trials, 0.1, 0.5, "elbow_left")
    m = measure_oblique_impact(log, trials.robot, NORMAL)
    assert m.post_tangential @ m.pre_tangential < 0.0
    assert STICK_SPEED < m.least_tangential_speed <= min(np.linalg.norm(m.pre_tangential), np.linalg.norm(m.post_tangential))
    assert m.mode == "slip"
    stuck = measure_oblique_impact(sticking[0], trials.robot, NORMAL)
    assert stuck.least_tangential_speed <= STICK_SPEED


def test_a_frictionless_wall_gives_no_tangential_impulse(trials, frictionless):
    m = measure_oblique_impact(frictionless[0], trials.robot, NORMAL)
    assert m.normal_impulse > 0.1
    assert np.linalg.norm(m.tangential_impulse) <= 10 * MUJOCO_MIN_FRICTION * m.normal_impulse
    # with no friction the contact keeps sliding: its tangential velocity only gains
    assert np.linalg.norm(m.post_tangential) > np.linalg.norm(m.pre_tangential)


FRANKA_STIFFNESS = (3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0)
"""N m/rad: a Franka's default joint impedance (libfranka's examples)."""


def stiff_run(friction, ratio, noslip_iterations):
    """One Panda ``elbow_right`` trial on the Franka joint impedance (v_t = ratio v_n), its wall's
    scene with ``noslip_iterations``: the measured impact."""
    stiff = ObliqueTrials(RobotChoice.of("panda"), PlantParameters(servo_stiffness=FRANKA_STIFFNESS))
    surface = Surface(DEFAULT_WALL.point, NORMAL, friction)
    stiff.scenes[friction] = build_scene(surface, stiff.plant, noslip_iterations=noslip_iterations)
    log, _ = simulate(stiff, friction, ratio)
    return measure_oblique_impact(log, stiff.robot, NORMAL)


def test_noslip_reads_a_pressed_stick_as_stick_and_leaves_a_slide_as_it_was():
    """The stiff servo presses the tool into a wall of mu = 0.6 with |p_t| / p_n inside the cone:
    Coulomb's contact sticks. MuJoCo's soft friction creeps above STICK_SPEED (a "slip"); with the
    study's noslip it stops. At mu = 0.1 the contact slides on the cone, and noslip leaves its v_t+
    (within 0.5 mm/s)."""
    creeping, held = (stiff_run(0.6, 0.5, n) for n in (0, NOSLIP_ITERATIONS))
    for m in (creeping, held):
        assert np.linalg.norm(m.tangential_impulse) < 0.9 * 0.6 * m.normal_impulse
    assert creeping.least_tangential_speed > STICK_SPEED and creeping.mode == "slip"
    assert held.mode == "stick"
    soft, slid = (stiff_run(0.1, 1.0, n) for n in (0, NOSLIP_ITERATIONS))
    assert soft.mode == slid.mode == "slip"
    assert np.linalg.norm(slid.post_tangential - soft.post_tangential) < 5e-4


# ---------------------------------------------------------------------------- the rules
vectors = st.tuples(*[st.floats(-1.0, 1.0)] * 2).map(lambda v: np.array([0.0, v[0], v[1]]))


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 0.01), st.floats(0.0, 0.01))
def test_observed_mode_follows_its_stated_rules(least, post):
    mode = observed_mode(least, max(least, post))
    if least > STICK_SPEED:
        assert mode == "slip"  # never stopped, however far its direction turned
    else:
        assert mode == ("stick" if max(least, post) <= STICK_SPEED else "reversal")


def test_a_slide_that_turns_without_stopping_is_a_slip():
    """The velocity turns by 180 degrees around 0 at 5 mm/s (the old rule, v_t+ . v_t- < 0, read
    it as a reversal); a path through 0 stopped; one that starts at rest and slides off reversed."""
    angles = np.linspace(0.0, np.pi, 50)
    turning = 0.005 * np.column_stack([np.zeros(50), np.cos(angles), np.sin(angles)])
    least = path_least_speed(turning)
    assert least == pytest.approx(0.005 * np.cos(np.pi / 98), rel=1e-12)  # a chord's midpoint
    assert observed_mode(least, 0.005) == "slip"
    through = np.array([[0.0, 0.1, 0.0], [0.0, -0.1, 0.001]])
    assert path_least_speed(through) == pytest.approx(0.1 * 0.001 / np.hypot(0.2, 0.001), rel=1e-12)
    assert observed_mode(path_least_speed(through), 0.1) == "reversal"
    assert observed_mode(path_least_speed(through[:1] * 0.001), 0.0001) == "stick"


@settings(max_examples=200, deadline=None)
@given(st.lists(vectors, min_size=1, max_size=6))
def test_the_least_speed_of_a_path_is_no_more_than_any_of_its_points(points):
    """The piecewise-linear path's distance to 0: at most each sample's norm, at least the
    distance of every segment's densely sampled points less the sampling's chord."""
    path = np.array(points)
    least = path_least_speed(path)
    assert least <= min(np.linalg.norm(path, axis=1)) + 1e-15
    shares = np.linspace(0.0, 1.0, 1001)[:, None]
    dense = [np.linalg.norm(a + shares * (b - a), axis=1).min() for a, b in zip(path[:-1], path[1:])]
    spacing = max([np.linalg.norm(b - a) / 1000 for a, b in zip(path[:-1], path[1:])], default=0.0)
    if dense:
        assert min(dense) - spacing / 2 - 1e-15 <= least <= min(dense) + 1e-15


def test_impact_window_ends_at_separation_at_the_first_force_minimum_or_at_the_log_s_end():
    rising_then_falling = np.array([0.0, 0.0, 5.0, 9.0, 7.0, 3.0, 0.5, 0.0])
    assert impact_window(rising_then_falling) == (2, 6, "separation")
    pressing = np.array([0.0, 8.0, 6.0, 4.0, 3.0, 3.5, 5.0])
    assert impact_window(pressing) == (1, 4, "force minimum")
    growing = np.array([0.0, 4.0, 6.0, 5.5, 5.8, 6.5, 7.0])  # a dip too shallow to end on, then the press
    assert impact_window(growing) == (1, 3, "force minimum")
    press = np.array([0.0, 4.0, 6.0, 6.5, 7.0, 7.5])  # the force never falls: no minimum in the log
    assert impact_window(press) == (1, 5, "log end")


def test_tangential_part_is_orthogonal_to_the_normal_and_keeps_the_rest():
    rng = np.random.default_rng(3)
    for _ in range(20):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        x = rng.normal(size=3)
        t = tangential_part(x, n)
        assert abs(n @ t) < 1e-12
        np.testing.assert_allclose(t + (n @ x) * n, x, atol=1e-12)


def test_velocity_agreement_is_20_percent_or_a_centimetre_per_second():
    t = np.array([0.0, 1.0, 0.0])
    assert velocity_agrees(0.0 * t, 0.0099 * t)
    assert not velocity_agrees(0.0 * t, 0.0101 * t)
    assert velocity_agrees(0.119 * t, 0.1 * t)
    assert not velocity_agrees(0.121 * t, 0.1 * t)


def test_the_held_row_reads_v_t_from_the_press_where_the_contact_was_still_closed():
    """The held row is the impact law's, its v_t+ the press's where the simulated window did not
    end at a separation, each agreement judged against the simulated v_t+."""
    t = tangential_direction(NORMAL)
    impact = {"mode": "slip", "law_mode": "slip", "post_tangential": (0.13 * t).tolist(), "velocity_agrees": False}
    press = {"mode": "slip", "law_mode": "slip", "post_tangential": (0.06 * t).tolist(), "velocity_agrees": True}
    for rule, post, agrees in (("log end", 0.06, True), ("force minimum", 0.06, True), ("separation", 0.13, False)):
        simulated = {"end_rule": rule, "post_tangential": (0.064 * t).tolist(), "mode": "slip"}
        held = held_row(impact, press, simulated)
        np.testing.assert_allclose(held["post_tangential"], post * t)
        assert held["velocity_agrees"] is agrees and held["mode"] == "slip"
        assert held["post_from"] == ("impact" if rule == "separation" else "press")


# ---------------------------------------------------------------------------- the command
@pytest.mark.parametrize(("robot", "tool", "servo"), [
    ("panda", "impact_tip", ["--servo-stiffness", "3000,3000,3000,2500,2500,2000,2000"]), ("fr3", "franka_hand", []),
])
def test_the_small_grid_runs_end_to_end_through_the_command(tmp_path, capsys, robot, tool, servo):
    out = tmp_path / "oblique"
    argv = ["oblique", "--robot", robot, "--tool", tool, "--grid", "small", "--jobs", "1", "--out", str(out), *servo]
    assert main(argv) == 0
    report = json.loads((out / "oblique.json").read_text())
    assert report["robot"] == robot and report["tool"] == tool
    assert report["servo"].startswith("joint impedance K = 3000" if servo else "computed torque")
    assert len(report["rows"]) == len(GRIDS["small"].trials(RobotChoice.of(robot, tool)))
    for row in report["rows"]:
        simulated = row["simulated"]
        assert simulated["mode"] in ("slip", "stick", "reversal")
        p_n, p_t = simulated["normal_impulse"], np.linalg.norm(simulated["tangential_impulse"])
        assert p_t <= row["friction"] * p_n * (1 + 1e-9)
        assert set(row["predicted"]) == {"classical", "gm", "crb", "plant"} | ({"impedance", "press", "held"} if servo else set())
    if servo:  # the joint impedance's v_t+ is the law's with the held arm's W (the plant's, the model's), not CRB's
        assert all(r["predicted"][m]["velocity_agrees"] for r in report["rows"] for m in ("plant", "impedance"))
        assert not any(r["predicted"]["crb"]["velocity_agrees"] for r in report["rows"])
    summary = report["summary"]["all"]
    for method, s in summary.items():
        agreed = sum(r["predicted"][method]["mode_agrees"] for r in report["rows"])
        assert s["mode_agreement"] == pytest.approx(100.0 * agreed / len(report["rows"]))
    text = (out / "oblique.md").read_text()
    assert text.startswith(f"# Oblique impacts: the {robot}") and text in capsys.readouterr().out


@pytest.mark.parametrize("argv", [
    ["--grid", "huge"], ["--robot", "g1"], ["--jobs", "0"], ["--jump-model", "crb"], ["--qp-speed", "--grid", "huge"],
    ["--qp-speed", "--robot", "g1"], ["--qp-speed", "--jump-model", "classical_normal"], ["--qp-speed", "--jump-model", "nope"],
    ["--inverse-inertia", "--qp-speed"], ["--inverse-inertia", "--grid", "small"], ["--inverse-inertia", "--robot", "g1"],
    ["--servo-stiffness", "3000,3000"], ["--servo-stiffness", "0,0,0,0,0,0,0"], ["--servo-stiffness", "stiff"],
    ["--qp-speed", "--servo-stiffness", "3000,3000,3000,2500,2500,2000,2000"],
])
def test_bad_input_of_the_command_is_one_line_and_exit_code_2(tmp_path, capsys, argv):
    assert main(["oblique", "--out", str(tmp_path / "x"), *argv]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_the_study_refuses_a_floating_base():
    from impactqp.controller.model.validation import BadInputError
    from impactqp.scenarios.oblique import run_oblique_study

    with pytest.raises(BadInputError, match="fixed-base arm"):
        run_oblique_study(RobotChoice.of("g1"), GRIDS["small"])
