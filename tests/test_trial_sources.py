"""The command sources of a trial (sim/trial_sources.py): the arm's Cartesian approach and
replay; the whole-body QP driving the simulated G1's trial."""

from dataclasses import replace

import numpy as np
import pytest

from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.robot import PandaModel, RobotModel
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.controller.model.max_speed import Setting, closed_form_max_speed
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.qp.command import Status
from impactqp.scenarios.stance_check import StancePlant, trial_at_contact_speed
from impactqp.sim.observed_criteria import capture_margin
from impactqp.sim.runner import (
    DEFAULT_CONTROL_PERIOD, LATENCY, NORMAL, SERVO_GAIN, SETTLE, SINK, WallNotReachedError, run_impact_trial, run_source,
    servoed_plant,
)
from impactqp.sim.humanoid_scene import build_humanoid_scene
from impactqp.sim.trial_loop import Ending
from impactqp.sim.trial_sources import CartesianApproachCommand, CommandReplay, QpCommand, TrialStart
from impactqp.tasks import ContactApproachTask

FOOT_ONSETS = {"foot_slip", "foot_lift"}
PUSH_STEP, PUSH_SPEED, PUSH_STEPS = 200, 0.1, 1300  # control step of the push, m/s it adds to the pelvis, steps of the trial


@pytest.fixture(scope="module")
def robot():
    return RobotModel("g1")


@pytest.fixture(scope="module")
def trial(robot):
    """A moderate asked speed (0.3 m/s) in the parallel stance, the QP fed its own command also
    after the stop (``balance_feedback``: it brakes and does not balance)."""
    return run_impact_trial(robot, STANCES["parallel"], 0.3, source=QpCommand(feedback="commanded", balance_feedback="commanded"))


def test_the_qp_drives_the_hand_to_the_wall_and_the_robot_stands(trial):
    assert trial.source == "qp"
    assert trial.impact.impulse @ NORMAL > 0.0
    assert 0.0 < trial.contact_speed <= 0.3 * 1.02
    assert not trial.fell


def test_every_cycle_is_ok_and_every_command_is_finite_and_within_the_limits(robot, trial):
    record = trial.record
    start = int(round(SETTLE / DEFAULT_CONTROL_PERIOD))
    assert record.first_step == start and len(record.statuses) == len(trial.commands) - start
    assert record.not_ok == sum(s != Status.OK for s in record.statuses) == 0, record.messages
    assert np.all(np.isfinite(trial.commands))
    assert np.all(np.abs(trial.commands) <= robot.dq_max)
    np.testing.assert_array_equal(trial.commands[:start], 0.0)


def test_the_commands_change_within_the_acceleration_and_jerk_limits(trial):
    """Given its own command as the state, the QP's commands step by its accelerations times dt:
    within its description's limits, changing by at most the jerk limit per cycle, through the impact. (Its first
    command starts from the measured state after the settling, a few mrad/s off rest.)"""
    start = trial.record.first_step
    acceleration = np.diff(trial.commands[start:], axis=0) / DEFAULT_CONTROL_PERIOD
    g1 = ROBOTS["g1"]
    assert np.all(np.abs(acceleration) <= g1.ddq_max * (1 + 1e-9))
    jerk = np.diff(acceleration, axis=0) / DEFAULT_CONTROL_PERIOD
    assert np.all(np.abs(jerk) <= g1.dddq_max * (1 + 1e-6))


def test_the_qp_brakes_the_hand_after_the_stop(robot, trial):
    """From the stop on the approach target is 0: the commanded joint velocities decay to rest
    within the trial, at the acceleration limit at most."""
    stop = trial.impact.pre_index + int(round(LATENCY / DEFAULT_CONTROL_PERIOD))
    at_stop = np.abs(trial.commands[stop]).max()
    assert at_stop > 0.0
    assert np.abs(trial.commands[-1]).max() < 0.1 * at_stop


def test_predicted_post_impact_joint_velocities_are_within_the_limits_at_the_contact(robot, trial):
    record = trial.record
    before = record.cycle(trial.impact.pre_index) - 1
    post = record.predicted_post_impact[before]
    assert record.impact_constraints_on[before]
    assert np.all(np.isfinite(post)) and np.all(np.abs(post[robot.base_nv:]) <= robot.dq_max)


def test_the_feet_show_no_onset_the_scripted_trial_does_not_show_at_the_same_contact_speed(robot, trial):
    q = stance_posture(robot, STANCES["parallel"])
    scripted = trial_at_contact_speed(robot, "parallel", q, trial.contact_speed, StancePlant())
    assert scripted.source == "scripted" and scripted.record is None
    assert abs(scripted.contact_speed - trial.contact_speed) <= 0.02 * trial.contact_speed
    assert FOOT_ONSETS & set(trial.failures) <= set(scripted.failures)


def test_a_source_that_tracks_the_speed_is_asked_the_target_once(robot):
    q = stance_posture(robot, STANCES["parallel"])
    qp = trial_at_contact_speed(robot, "parallel", q, 0.2, StancePlant(), QpCommand())
    assert qp.normal_speed == 0.2 and qp.source == "qp"


def test_unknown_feedback_is_bad_input():
    with pytest.raises(BadInputError):
        QpCommand(feedback="predicted")


def test_a_body_the_qp_leans_stays_over_its_feet(robot):
    """The QP leans the body to reach the wall; the servo's standing feed-forward follows the
    posture, so 0.4 s after the contact the CoM is still over the feet (fed the start stance's
    feed-forward, the ankles yielded and this trial ended falling backwards)."""
    trial = run_impact_trial(robot, STANCES["wide"], 0.6, source=QpCommand())
    assert trial.contact_speed > 0.4
    assert not trial.fell


def test_the_measured_state_fed_to_the_standing_qp_never_sets_off_the_impact_brake(robot):
    """The G1's controller fed its measured state: the impact brake (a fixed base's: the standing
    servo's lag would set it off before any contact) never engages; a trial that reaches the wall
    is evaluated. Fed the measured state, the standing QP turns infeasible during the approach
    (issue 33), and whether the hand still reaches the wall depends on rounding (it does on some
    machines, not on others): the brake is checked on the record either way."""
    try:
        trial = run_impact_trial(robot, STANCES["parallel"], 0.5, source=QpCommand(feedback="measured"))
    except WallNotReachedError as missed:
        statuses = missed.run.driver.record.statuses
    else:
        statuses = trial.record.statuses
        assert np.isfinite(trial.max_velocity_ratio)
    assert statuses and Status.IMPACT_BRAKE not in statuses


class Pushed:
    """A source that kicks the plant's pelvis forward (its free joint's x velocity, MuJoCo's world
    frame) by PUSH_SPEED at control step PUSH_STEP, and keeps its QP's base x (its command's, from
    the state it was given) at each step."""

    def __init__(self, driver, data):
        self.driver, self.data, self.k, self.estimates = driver, data, 0, []

    def step(self, q, v):
        if self.k == PUSH_STEP:
            self.data.qvel[0] += PUSH_SPEED
        self.k += 1
        command = self.driver.step(q, v)
        last = self.driver.source.last  # None while settling
        self.estimates.append(q[0] if last is None else last.q_cmd[0])
        return command


def pushed_standing(robot, feedback):
    """Quiet standing in the parallel stance (the hand's speed target 0, the wall 1 m away), a push
    on the pelvis: the QP's base x estimate at each step and the CoM's margin inside the support
    polygon (m) at each step after the push."""
    q0 = stance_posture(robot, STANCES["parallel"])
    contact = robot.terms(q0).contact_point
    scene = build_humanoid_scene(robot, wall_x=float(contact[0]) + 1.0)
    wall = Surface(np.array([scene.wall_x, contact[1], contact[2]]), NORMAL.copy())
    start = TrialStart(robot, q0, np.zeros(robot.nv), wall, 0.3, settle=SETTLE, sink=SINK)
    driver = QpCommand(feedback=feedback, balance_feedback=feedback).start(start)
    driver.stop()
    pushed = Pushed(driver, scene.data)
    run = run_source(servoed_plant(scene, robot, DEFAULT_CONTROL_PERIOD, SERVO_GAIN), pushed, Ending(PUSH_STEPS),
                     (start.plant_start(), start.dq0), robot.dq_max)
    margins = np.array([capture_margin(robot, q, np.zeros(3)) for q in run.record.q[PUSH_STEP:]])
    return np.array(pushed.estimates), run.record, margins, driver.record


@pytest.fixture(scope="module")
def pushes(robot):
    return {feedback: pushed_standing(robot, feedback) for feedback in ("commanded", "blended")}


def test_a_push_on_the_pelvis_is_seen_by_the_blended_state_and_not_by_the_commanded_one(pushes):
    """After the push the plant's pelvis moves forward; the blended state follows it, the commanded
    state (the QP's own integration) does not."""
    for feedback, moved in (("blended", True), ("commanded", False)):
        estimates, record, _, _ = pushes[feedback]
        plant_moved = record.q[-1, 0] - record.q[PUSH_STEP, 0]
        estimate_moved = estimates[-1] - estimates[PUSH_STEP]
        assert plant_moved > 0.0
        assert (estimate_moved > 0.5 * plant_moved) == moved


def test_the_blended_qp_brings_the_pushed_com_back_and_ends_better_than_the_commanded_one(pushes):
    """Fed the blended state the QP stops the CoM's drift and brings it back towards the centre of
    the support polygon within PUSH_STEPS; fed its own command the CoM keeps drifting further: the
    smallest margin and the last are both worse, and no cycle of the blended QP is not OK."""
    _, _, blended, record = pushes["blended"]
    _, _, commanded, _ = pushes["commanded"]
    assert blended[0] > 0.0 and blended.min() > 0.0 and record.not_ok == 0
    assert blended[-1] > blended.min()  # it came back
    assert blended.min() > commanded.min()
    assert blended[-1] > commanded[-1]


@pytest.fixture(scope="module")
def close_stance_trial(robot):
    """The close stance's QP-driven trial fed the blended state, asked for 0.9 times its closed
    form (crb, the stance's posture)."""
    stance = STANCES["close"]
    limit = closed_form_max_speed(robot, robot.terms(stance_posture(robot, stance)), NORMAL).speed
    return run_impact_trial(robot, stance, 0.9 * limit, source=QpCommand(feedback="blended"))


def test_the_close_stance_stands_after_an_impact_at_nine_tenths_of_its_closed_form(robot, close_stance_trial):
    """Fed its own command the QP never saw the body sway after the impact and this trial fell
    0.4 s after it; fed the blended state, balancing after the impact
    (``controller.config.post_impact_balance``), on ankles that carry the body's pendulum
    (``sim.servo``: with the foot's inertia alone the body was in neutral balance about its
    ankles and the margin fell to 0 by the trial's end), it stands: no fall, no onset, the capture
    margin positive at every step from the contact to the end, every cycle OK."""
    trial = close_stance_trial
    assert not trial.fell and trial.record.not_ok == 0 and not trial.failures
    first = trial.impact.pre_index  # the last step before the wall contact
    q, v = trial.held.q_log[first:], np.column_stack([trial.log.base[first:, robot.base_nq:], trial.log.dq[first:]])
    margins = [capture_margin(robot, qk, robot.terms(qk).Jcom @ vk) for qk, vk in zip(q, v)]
    assert min(margins) > 0.0


def test_the_post_impact_com_velocity_decays(robot, close_stance_trial):
    """The balance after the impact: the CoM's horizontal speed at the end of the trial is below
    its speed just after the impact, and its speed along the wall's normal (the impulse's
    direction) less than half of it."""
    trial = close_stance_trial
    q_end = trial.held.q_log[-1]
    v_end = np.concatenate([trial.log.base[-1, robot.base_nq:], trial.log.dq[-1]])
    after, end = trial.held.post_com_velocity, robot.terms(q_end).Jcom @ v_end
    assert np.linalg.norm(end[:2]) < np.linalg.norm(after[:2])
    assert abs(NORMAL @ end) < 0.5 * abs(NORMAL @ after)


ARM = PandaModel()


@pytest.mark.parametrize(
    "dq_cmd", [np.zeros((5, ARM.n_joints - 1)), np.full((5, ARM.n_joints), np.nan), np.zeros((0, ARM.n_joints))]
)
def test_bad_replays_are_rejected(dq_cmd):
    with pytest.raises(ValueError):
        CommandReplay(dq_cmd, ARM.n_joints)


def test_a_replay_gives_its_rows_in_order_and_no_more():
    rows = np.arange(2.0 * ARM.n_joints).reshape(2, ARM.n_joints)
    replay = CommandReplay(rows, ARM.n_joints)
    q = np.zeros(ARM.nq)
    assert len(replay) == 2
    np.testing.assert_array_equal(replay.step(q, q).dq_cmd, rows[0])
    np.testing.assert_array_equal(replay.step(q, q).dq_cmd, rows[1])
    with pytest.raises(IndexError, match="only 2 control steps"):
        replay.step(q, q)


def test_a_negative_approach_speed_is_bad_input():
    with pytest.raises(ValueError, match="normal_speed"):
        CartesianApproachCommand(ARM, DEFAULT_WALL, -0.1)


def test_the_cartesian_command_moves_the_contact_frame_at_the_reference_twist():
    """J6 dq_cmd = [-v_n n + v_t; 0] wherever J6 has full row rank (least squares is exact)."""
    v_t = np.array([0.0, 0.04, 0.0])
    command = CartesianApproachCommand(ARM, DEFAULT_WALL, 0.15, v_t)
    q = ARM.description.postures["elbow_up"].q
    twist = ARM.contact_jacobian6(q) @ command.step(q, np.zeros(ARM.nv)).dq_cmd
    np.testing.assert_allclose(twist, np.concatenate([-0.15 * DEFAULT_WALL.normal + v_t, np.zeros(3)]), atol=1e-12)


def test_the_plant_starts_sink_below_the_start_posture_and_q0_is_left_alone(robot):
    q0 = stance_posture(robot, STANCES["parallel"])
    start = TrialStart(robot, q0.copy(), np.zeros(robot.nv), DEFAULT_WALL, 0.2, sink=SINK)
    lowered = start.plant_start()
    assert lowered[2] == q0[2] - SINK and np.array_equal(np.delete(lowered, 2), np.delete(q0, 2))
    np.testing.assert_array_equal(start.q0, q0)
    arm_q0 = ARM.description.postures["elbow_up"].q
    np.testing.assert_array_equal(TrialStart(ARM, arm_q0, np.zeros(ARM.nv), DEFAULT_WALL, 0.2).plant_start(), arm_q0)


def test_the_qp_source_configures_the_description_s_approach_towards_the_start_s_wall():
    start = TrialStart(ARM, ARM.description.postures["elbow_up"].q, np.zeros(ARM.nv), DEFAULT_WALL, 0.12,
                       np.array([0.0, 0.03, 0.0]))
    config = QpCommand(method="gm", restitution=0.2, impact_duration=0.01, posture_weight=0.0).config(start)
    approach = next(t for t in config.tasks if t.type == "contact_approach")
    assert approach.params["speed"] == 0.12 and approach.params["tangential_velocity"] == [0.0, 0.03, 0.0]
    assert (config.impact.jump_model, config.impact.restitution, config.impact.impact_duration) == ("gm", 0.2, 0.01)
    assert config.robot == "panda"
    np.testing.assert_array_equal(config.surface.surface().normal, DEFAULT_WALL.normal)


@pytest.mark.parametrize("stance", ["parallel", "far", "step"])
def test_the_governor_caps_the_hand_s_target_at_the_closed_form_of_the_contact_posture(robot, stance):
    """Asked above the closed form's highest speed at the contact posture (the impact rows'
    predictor, restitution and duration), the approach's speed target and its run-up are those of
    that speed times the governor; asked below it, without a contact posture, without impact rows
    or without a governor, the asked speed's."""
    stance_q = stance_posture(robot, STANCES[stance])
    setting = Setting("gm", 0.1, impact_duration=0.005)
    limit = closed_form_max_speed(robot, robot.terms(stance_q), NORMAL, setting).speed
    source = QpCommand(method="gm", restitution=0.1, impact_duration=0.005, governor=0.95)

    def target(source, speed, contact_posture=stance_q):
        start = TrialStart(robot, stance_q, np.zeros(robot.nv), DEFAULT_WALL, speed, contact_posture=contact_posture)
        return next(t for t in source.config(start).tasks if t.type == "contact_approach").params["speed"]

    assert target(source, 2.0 * limit) == pytest.approx(0.95 * limit, rel=1e-12)
    assert target(source, 0.9 * limit) == 0.9 * limit
    assert target(source, 2.0 * limit, None) == 2.0 * limit
    assert target(replace(source, governor=None), 2.0 * limit) == 2.0 * limit
    assert target(replace(source, method=None), 2.0 * limit) == 2.0 * limit
    governed, _ = source.start_posture(robot, stance_q, NORMAL, 2.0 * limit)
    asked, _ = replace(source, governor=None).start_posture(robot, stance_q, NORMAL, 0.95 * limit)
    np.testing.assert_array_equal(governed, asked)


@pytest.mark.parametrize("stance", ["parallel", "step"])
def test_the_wall_of_a_run_up_trial_is_where_the_stance_s_hand_is(robot, stance):
    """The run-up's gap puts the wall at the stance's contact point along the normal: the hand
    meets it in the stance's posture, the closed form's."""
    stance_q = stance_posture(robot, STANCES[stance])
    for speed in (0.3, 1.2):
        run_up, gap = QpCommand().start_posture(robot, stance_q, NORMAL, speed)
        assert gap > 0.0
        wall = robot.terms(run_up).contact_point - gap * NORMAL
        assert wall @ NORMAL == pytest.approx(robot.terms(stance_q).contact_point @ NORMAL, abs=1e-12)


def test_asked_twice_its_closed_form_the_qp_meets_the_wall_within_ten_percent_below_it_and_stands(robot):
    """The far stance: the QP's rows at the posture it leans into allow more than the stance's
    closed form, and ungoverned, asked 1.3 times it, the hand met the wall 1.29 times as fast.
    Governed, asked twice the closed form, the contact is at most the closed form and within 10 %
    of it, no onset, every cycle OK, standing."""
    stance = STANCES["far"]
    limit = closed_form_max_speed(robot, robot.terms(stance_posture(robot, stance)), NORMAL).speed
    trial = run_impact_trial(robot, stance, 2.0 * limit, source=QpCommand())
    assert 0.9 * limit <= trial.contact_speed <= limit
    assert not trial.fell and trial.record.not_ok == 0 and not trial.failures


@pytest.mark.parametrize("stance", ["parallel", "close"])
def test_from_its_run_up_the_qp_holds_the_hand_at_the_orientation_of_the_contact_posture(robot, stance):
    """The run-up turns the hand (the arm moved back along J_arm^+ (-n), orientation free): the
    approach's orientation target is the stance's hand rotation, not the one at the start, and
    without a contact posture it is left to the reset (the start's)."""
    stance_q = stance_posture(robot, STANCES[stance])
    run_up, _ = QpCommand().start_posture(robot, stance_q, NORMAL, 1.0)
    start = TrialStart(robot, run_up, np.zeros(robot.nv), DEFAULT_WALL, 1.0, contact_posture=stance_q)
    controller = QpCommand().start(start).controller
    controller.reset(run_up, np.zeros(robot.nv))
    approach = next(t for t in controller.tasks if isinstance(t, ContactApproachTask))
    np.testing.assert_allclose(approach.target_rotation, robot.terms(stance_q).contact_rotation, atol=1e-12)
    turned = robot.terms(run_up).contact_rotation
    assert np.linalg.norm(turned - robot.terms(stance_q).contact_rotation) > 1e-3  # the run-up did turn the hand
    plain = QpCommand().start(TrialStart(robot, run_up, np.zeros(robot.nv), DEFAULT_WALL, 1.0)).controller
    plain.reset(run_up, np.zeros(robot.nv))
    plain_approach = next(t for t in plain.tasks if isinstance(t, ContactApproachTask))
    np.testing.assert_allclose(plain_approach.target_rotation, turned, atol=1e-12)


def test_fed_its_own_command_the_close_stance_balances_after_the_impact_and_stands(robot):
    """Fed its own command during the approach, the QP did not see its body after the impact and
    the close stance asked for 0.9 times its closed form fell 0.4 s after the contact; from the
    stop on it is given the blended state (``QpCommand.balance_feedback``) and balances
    (``controller.config.post_impact_balance``): it stands, no onset, every cycle OK."""
    stance = STANCES["close"]
    limit = closed_form_max_speed(robot, robot.terms(stance_posture(robot, stance)), NORMAL).speed
    trial = run_impact_trial(robot, stance, 0.9 * limit, source=QpCommand(feedback="commanded"))
    assert trial.contact_speed > 0.8 * limit
    assert not trial.fell and trial.record.not_ok == 0 and not trial.failures


def test_the_balance_feedback_is_checked_and_given_at_the_stop_to_a_standing_robot_only(robot):
    with pytest.raises(BadInputError):
        QpCommand(balance_feedback="predicted")
    arm_q0 = ARM.description.postures["elbow_up"].q
    for model, q0 in ((robot, stance_posture(robot, STANCES["parallel"])), (ARM, arm_q0)):
        driver = QpCommand(feedback="commanded").start(TrialStart(model, q0, np.zeros(model.nv), DEFAULT_WALL, 0.2))
        assert driver.source.feedback == "commanded"
        driver.stop()
        assert driver.source.feedback == ("blended" if model is robot else "commanded")


def test_the_default_feedback_is_the_blend_for_a_standing_robot_and_the_command_for_an_arm(robot):
    arm_q0 = ARM.description.postures["elbow_up"].q
    for model, q0, expected in ((robot, stance_posture(robot, STANCES["parallel"]), "blended"), (ARM, arm_q0, "commanded")):
        driver = QpCommand().start(TrialStart(model, q0, np.zeros(model.nv), DEFAULT_WALL, 0.2))
        assert driver.source.feedback == expected
        driver.stop()
        assert driver.source.feedback == expected
