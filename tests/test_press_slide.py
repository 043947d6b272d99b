"""First-principles checks of the steady press after an impact (controller/model/press_slide.py):
the rate balance and the surface's constraint, Coulomb's stick and slide, linearity in the
reference's speed, frame invariance, and the model against MuJoCo's joint-impedance plant
pressing a wall."""

import numpy as np
import pytest
from conftest import joint_positions
from hypothesis import given, reject, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from impactqp.controller.measured.oblique_impact import measure_oblique_impact, tangential_part
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.press_slide import contact_compliance, press_slide
from impactqp.controller.model.robot import PandaModel, SingularPostureError
from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.oblique import ObliqueTrials
from impactqp.sim.generation import tangential_direction
from impactqp.sim.plant import PlantParameters
from impactqp.sim.runner import TrialSpec, run_approach
from impactqp.sim.trial_sources import CARTESIAN

ROBOT = PandaModel()
FRANKA_STIFFNESS = (3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0)
"""N m/rad: a Franka's default joint impedance (libfranka's examples)."""
SETTINGS = settings(max_examples=60, deadline=None)
units = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).map(np.array).filter(lambda x: np.linalg.norm(x) > 0.1)
frictions = st.floats(0.0, 1.5)
stiffnesses = st.lists(st.floats(200.0, 5000.0), min_size=ROBOT.nv, max_size=ROBOT.nv).map(np.array)


def compliance_at(q, K):
    """C = J K^-1 J^T at q; a singular posture is rejected as an example (hypothesis)."""
    try:
        return contact_compliance(ROBOT.terms(q), K)
    except SingularPostureError:
        reject()


def reference(normal, tangent, into):
    """A reference contact velocity with normal part -into (into the surface) and the tangential
    part of ``tangent``."""
    return tangential_part(tangent, normal) - into * normal


def scale(press):
    return max(np.linalg.norm(press.force_rate), 1.0)


@SETTINGS
@given(q=joint_positions(), K=stiffnesses, n=units, t=units, into=st.floats(0.01, 0.5), mu=frictions)
def test_the_press_balances_the_rates_stays_on_the_surface_and_obeys_coulomb(q, K, n, t, into, mu):
    """v = v_ref + C f' (the drive's deflection rate), n^T v = 0, f'_n > 0; a stick does not move
    and keeps f' inside the cone; a slide keeps f' on the cone's edge opposite to its velocity."""
    C, n = compliance_at(q, K), n / np.linalg.norm(n)
    v_ref = reference(n, t, into)
    press = press_slide(C, n, v_ref, mu)
    rate_n, rate_t = n @ press.force_rate, tangential_part(press.force_rate, n)
    speed = np.linalg.norm(v_ref)
    np.testing.assert_allclose(press.velocity, v_ref + C @ press.force_rate, atol=1e-9 * speed)
    assert abs(n @ press.velocity) <= 1e-12 * speed
    assert rate_n > 0.0
    if press.mode == "stick":
        assert np.linalg.norm(press.velocity) == 0.0
        assert np.linalg.norm(rate_t) <= mu * rate_n * (1 + 1e-9) + 1e-12 * scale(press)
    else:
        s = press.direction
        np.testing.assert_allclose(rate_t, -mu * rate_n * s, atol=1e-9 * scale(press))
        v_t = press.velocity
        assert s @ v_t > 0.0 and abs(n @ s) < 1e-12
        assert np.linalg.norm(np.cross(s, v_t)) <= 1e-6 * np.linalg.norm(v_t) + 1e-12 * speed


@SETTINGS
@given(q=joint_positions(), K=stiffnesses, n=units, t=units, into=st.floats(0.01, 0.5), mu=frictions,
       factor=st.floats(0.1, 10.0))
def test_the_press_is_linear_in_the_reference_speed(q, K, n, t, into, mu, factor):
    """Every equation is homogeneous in (v_ref, v, f'): a reference k times faster gives the same
    mode and direction, k times the velocity and the force rate."""
    C, n = compliance_at(q, K), n / np.linalg.norm(n)
    v_ref = reference(n, t, into)
    one, scaled = press_slide(C, n, v_ref, mu), press_slide(C, n, factor * v_ref, mu)
    assert scaled.mode == one.mode
    np.testing.assert_allclose(scaled.velocity, factor * one.velocity, atol=1e-7 * factor * np.linalg.norm(v_ref))
    np.testing.assert_allclose(scaled.force_rate, factor * one.force_rate, rtol=1e-7, atol=1e-7 * factor * scale(one))


@SETTINGS
@given(q=joint_positions(), K=stiffnesses, n=units, t=units, into=st.floats(0.01, 0.5), mu=frictions,
       rotation=st.integers(0, 2**32 - 1))
def test_the_press_does_not_depend_on_the_world_frame(q, K, n, t, into, mu, rotation):
    """Rotating the compliance, the normal and the reference by R rotates the velocity, the force
    rate and the slide's direction by R."""
    C, n = compliance_at(q, K), n / np.linalg.norm(n)
    v_ref = reference(n, t, into)
    R = Rotation.random(random_state=rotation).as_matrix()
    press, turned = press_slide(C, n, v_ref, mu), press_slide(R @ C @ R.T, R @ n, R @ v_ref, mu)
    assert turned.mode == press.mode
    np.testing.assert_allclose(turned.velocity, R @ press.velocity, atol=1e-7 * np.linalg.norm(v_ref))
    np.testing.assert_allclose(turned.force_rate, R @ press.force_rate, atol=1e-7 * scale(press))
    np.testing.assert_allclose(turned.direction, R @ press.direction, atol=1e-6)


@SETTINGS
@given(q=joint_positions(), K=stiffnesses, n=units, t=units, into=st.floats(0.01, 0.5))
def test_without_friction_the_force_grows_along_the_normal_and_a_large_friction_sticks(q, K, n, t, into):
    """mu = 0: f' = f'_n n, v_t = v_ref,t + f'_n C_tn. Above the stick's own ratio |f'_t| / f'_n of
    f' = -C^-1 v_ref, the contact sticks; below it, it slides."""
    C, n = compliance_at(q, K), n / np.linalg.norm(n)
    v_ref = reference(n, t, into)
    free = press_slide(C, n, v_ref, 0.0)
    np.testing.assert_allclose(tangential_part(free.force_rate, n), 0.0, atol=1e-9 * scale(free))
    rate_n = n @ free.force_rate
    np.testing.assert_allclose(free.velocity, tangential_part(v_ref + rate_n * C @ n, n), atol=1e-9 * np.linalg.norm(v_ref))
    held = np.linalg.solve(0.5 * (C + C.T), -v_ref)
    if not n @ held > 0.0:
        return  # holding the contact still would pull on the surface: no stick at any mu
    ratio = np.linalg.norm(tangential_part(held, n)) / (n @ held)
    if ratio <= 1.5:  # the frictions of real contacts
        assert press_slide(C, n, v_ref, ratio * 1.001 + 1e-9).mode == "stick"
        if ratio > 1e-3:
            assert press_slide(C, n, v_ref, ratio * 0.99).mode == "slide"


def test_bad_input_is_refused_in_one_line():
    terms = ROBOT.terms(next(iter(ROBOT.description.postures.values())).q)
    C = contact_compliance(terms, FRANKA_STIFFNESS)
    n = np.array([0.0, 0.0, 1.0])
    with pytest.raises(BadInputError, match="into the surface"):
        press_slide(C, n, np.array([0.1, 0.0, 0.0]), 0.3)
    with pytest.raises(BadInputError, match="3 x 3"):
        press_slide(C[:2], n, -0.1 * n, 0.3)
    with pytest.raises(BadInputError, match="stiffness > 0"):
        contact_compliance(terms, np.zeros(ROBOT.nv))


@pytest.mark.parametrize("friction, ratio", [(0.3, 0.5), (0.6, 0.5)])
def test_mujocos_impedance_held_arm_presses_as_the_model_says(friction, ratio):
    """The Panda on the Franka joint impedance, its Cartesian approach going on into a wall of
    friction mu (``elbow_left``, v_t = ratio v_n): over the log's last 20 ms, MuJoCo's contact
    slides (or sticks) as the press of the model at q- says, its tangential velocity within 20 %
    (or 2 mm/s) and its normal force's growth rate within 20 %."""
    study = ObliqueTrials(RobotChoice.of("panda"), PlantParameters(servo_stiffness=FRANKA_STIFFNESS))
    normal, speed = DEFAULT_WALL.normal, 0.12
    tangential = ratio * speed * tangential_direction(normal)
    spec = TrialSpec("elbow_left", study.choice.posture("elbow_left").q, speed, tangential)
    log = run_approach(study.scene(friction), study.robot, spec, CARTESIAN).log
    measured = measure_oblique_impact(log, study.robot, normal)
    assert measured.end_rule == "log end"  # the contact never lets go: the press
    press = press_slide(contact_compliance(study.robot.terms(measured.q_pre), FRANKA_STIFFNESS), normal,
                        tangential - speed * normal, friction)
    late = log.t >= log.t[-1] - 0.02
    velocities = np.array([tangential_part(study.robot.terms(q).J @ dq, normal) for q, dq in zip(log.q[late], log.dq[late])])
    simulated = velocities.mean(axis=0)
    tolerance = max(0.2 * np.linalg.norm(simulated), 2e-3)
    assert np.linalg.norm(press.velocity - simulated) <= tolerance
    pressing = log.force_t >= log.force_t[-1] - 0.02
    slope = np.polyfit(log.force_t[pressing], log.force[pressing] @ normal, 1)[0]
    assert abs(normal @ press.force_rate - slope) <= 0.2 * slope
