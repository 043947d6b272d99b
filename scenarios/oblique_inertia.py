"""The simulated plant's inverse inertia at the contact, against the predictors' (``impactqp
oblique --inverse-inertia``, docs/frictional-impacts.md, "Whose W the simulated arm has").

The frictional law's mode and post-impact velocity hang on W, the map from an impulse iota on the
robot at the contact point to the change of that point's velocity (dv = W iota). The predictors
take W_crb (eq. 20: the robot as one rigid body, its joints locked over the impact, the paper's
premise of a stiff high-gain servo), or W_gm = J M^-1 J^T (eq. 22: the joints free over the
impact; the classical law's W too, for a fixed base). This study measures the W of MuJoCo's plant.

Measurement: the arm at rest at a named posture, its servo holding the posture (``dq_cmd = 0``),
away from any wall; a force pulse f(t) = iota_k pi / (2 tau) sin(pi t / tau) at the contact point
along the contact frame's axis e_k (t1, t2, n; ``frictional_impact.contact_frame``), applied as
the joint torque J(q0)^T f; the pulse's impulse iota_k = h sum f (``PULSE_IMPULSE``, small: the
response is linear); dv_k = J (dq(tau) - dq_0(tau)) at the pulse's end, dq_0 the same run without
the pulse (it removes what the servo and gravity do alone). Column k of W_sim is dv_k / iota_k,
expressed in world axes. The pulse's duration tau stands for the contact's: MuJoCo's contact of
time constant solref[0] = 7 ms (the scene's) lasts 12.8 to 23 ms from the first force to the end
of restitution (``scenarios.oblique``), a stiffer contact less.

Servos (:data:`SERVOS`), every one holding the posture, run as the simulated trials run them
(``sim.trial_loop.ServoedPlant``):

- the scene's computed-torque servo (``sim.servo``) of bandwidth omega: tau = M (omega^2 e + 2
  omega de) + h, joint stiffness omega^2 M, its torque held for each 1 ms control period.
  5 rad/s is the default plant's (``sim.plant``); 50 and 500 rad/s are stiffer ones of the same law;
- a joint impedance (``sim.servo.JointImpedanceServo``, the plant's ``servo_stiffness``) at a
  real Franka's default joint stiffness K = (3000, 3000, 3000, 2500, 2500, 2000, 2000) N m/rad
  (libfranka's ``examples/examples_common.cpp``, ``setDefaultBehavior``: the internal joint
  impedance of the joint position and velocity interfaces), critically damped, D_i = 2 sqrt(K_i
  M_ii(q)) (libfranka does not publish its damping), recomputed at every physics step (a drive's
  joint controller runs faster than the 1 kHz command). An arm of another joint count has none.

Reported per posture, servo and tau: n^T W n, the stick coefficient mu_bar = |W_tt^-1 W_tn|
(Stronge eq. 4.12, the seed paper's Sec. VI-B) and the relative distance ||W_sim - W|| / ||W||
(Frobenius) to W_gm and to W_crb, beside W_gm's and W_crb's own n^T W n and mu_bar.

The oblique study's reference row "plant" (:func:`with_plant_row`, ``impactqp oblique``) is the
frictional law with this W of the study's own plant over ``oblique.IMPACT_DURATION``: what the
law gives with the W the plant has over the impact (docs/frictional-impacts.md, "What v_t+ misses").
"""

from __future__ import annotations

import mujoco
import numpy as np

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.frictional_impact import contact_frame, stick_direction
from impactqp.controller.model.jump import crb_inverse_inertia, gm_inverse_inertia
from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.sim.plant import PlantParameters
from impactqp.sim.runner import DEFAULT_CONTROL_PERIOD
from impactqp.sim.scene import build_scene
from impactqp.sim.servo import JointImpedanceServo
from impactqp.sim.trial_loop import ServoedPlant

from .oblique import IMPACT_DURATION, POSTURES, fixed_base, law_row, summary

PULSE_IMPULSE = 1e-3
"""N s: each pulse's impulse (small: the plant's response is linear in it)."""
PULSE_DURATIONS = (0.001, 0.007, 0.015)
"""s: a 1 ms pulse (a hard contact), the scene's contact time constant and its impacts' length."""
FRANKA_JOINT_STIFFNESS = (3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0)
"""N m/rad: libfranka's default joint impedance (``setDefaultBehavior``, module docstring)."""
SERVOS = ("computed-torque 5 rad/s", "computed-torque 50 rad/s", "computed-torque 500 rad/s", "Franka joint impedance")
"""The servos of the study (module docstring), by name."""
WALL_DISTANCE = 2.0
"""m: the wall is moved this far behind the default one: no contact during the pulses."""


def servos(joints: int) -> dict[str, PlantParameters]:
    """The plants of the servos of :data:`SERVOS` for an arm of ``joints`` joints (Franka's
    impedance for 7 joints only)."""
    chosen = {name: PlantParameters(servo_gain=gain) for name, gain in zip(SERVOS, (5.0, 50.0, 500.0))}
    if joints == len(FRANKA_JOINT_STIFFNESS):
        chosen[SERVOS[3]] = PlantParameters(servo_stiffness=FRANKA_JOINT_STIFFNESS)
    return chosen


class HeldArm:
    """The arm of ``choice`` on ``plant`` in a scene without contact, at rest at a posture, its
    servo holding it, pushed by force pulses at the contact point (module docstring)."""

    def __init__(self, choice: RobotChoice, plant: PlantParameters):
        self.choice, self.robot = fixed_base(choice), choice.model()
        away = DEFAULT_WALL.point - WALL_DISTANCE * DEFAULT_WALL.normal
        scene = build_scene(Surface(away, DEFAULT_WALL.normal), plant, robot=choice.robot, tool=choice.tool)
        self.plant = ServoedPlant(scene, DEFAULT_CONTROL_PERIOD)

    def response(self, q: np.ndarray, force: np.ndarray, duration: float) -> np.ndarray:
        """dq at the end of a half-sine pulse of the contact force ``force`` (N s: its impulse)
        over ``duration`` s, the arm starting at rest at q, the servo run as ``ServoedPlant``
        runs it (the computed torque held for each control period, the joint impedance
        recomputed at every physics step)."""
        plant = self.plant
        model, data, servo = plant.scene.model, plant.scene.data, plant.servo
        h = model.opt.timestep
        steps = int(round(duration / h))
        shape = np.sin(np.pi * (np.arange(steps) + 0.5) / steps)
        shape /= h * shape.sum()  # h sum(shape) = 1: the pulse's impulse is exactly ``force``
        plant.reset(q)
        generalized = self.robot.terms(q).J.T @ force
        hold, each_step = np.zeros(model.nv), isinstance(servo, JointImpedanceServo)
        for k in range(steps):
            mujoco.mj_step1(model, data)
            if k % plant.substeps == 0:
                torque = servo.torque(hold, plant.control_period).copy()
            elif each_step:  # as ``ServoedPlant`` runs it
                torque = servo.torque_at((k % plant.substeps) * h).copy()
            data.qfrc_applied[:] = torque + shape[k] * generalized
            mujoco.mj_step2(model, data)
        return data.qvel.copy()

    def inverse_inertia(self, q: np.ndarray, duration: float) -> np.ndarray:
        """W_sim (3 x 3, world axes) at posture q for pulses of ``duration`` s."""
        J = self.robot.terms(q).J
        frame = contact_frame(DEFAULT_WALL.normal)
        held = self.response(q, np.zeros(3), duration)
        columns = [J @ (self.response(q, PULSE_IMPULSE * frame[:, k], duration) - held) / PULSE_IMPULSE
                   for k in range(3)]
        return np.column_stack(columns) @ frame.T  # from the contact frame's impulses to world axes


def with_plant_row(report: dict, choice: RobotChoice, plant: PlantParameters | None) -> dict:
    """The report of ``scenarios.oblique.run_oblique_study`` on ``plant`` (None: the default
    plant) with one more row per trial, "plant": the same frictional law with the simulated
    plant's own W, measured at the trial's posture at rest over ``IMPACT_DURATION``
    (:meth:`HeldArm.inverse_inertia`), from the measured v- and read as the predictors are; and
    its summary again. A reference, not a predictor: what the law gives with the W the plant has
    over the impact, so that a predictor's miss splits into its W's share and the rest."""
    arm = HeldArm(choice, PlantParameters() if plant is None else plant)
    postures = {row["posture"] for row in report["rows"]}
    plant_W = {name: arm.inverse_inertia(choice.posture(name).q, IMPACT_DURATION) for name in sorted(postures)}
    normal = DEFAULT_WALL.normal
    rows = []
    for row in report["rows"]:
        simulated = row["simulated"]
        pre_velocity = np.asarray(simulated["pre_tangential"]) - simulated["contact_speed"] * normal
        plant_row = law_row(plant_W[row["posture"]], pre_velocity, row["friction"], simulated)
        rows.append({**row, "predicted": {**row["predicted"], "plant": plant_row}})
    return {**report, "plant_pulse": IMPACT_DURATION, "rows": rows, "summary": summary(rows)}


def describe(W: np.ndarray, normal: np.ndarray) -> dict:
    """n^T W n and the stick coefficient mu_bar of W at the contact of normal n."""
    frame = contact_frame(normal)
    return {"normal_inverse_mass": float(normal @ W @ normal),
            "mu_bar": float(np.linalg.norm(stick_direction(frame.T @ W @ frame)))}


def distance(W: np.ndarray, reference: np.ndarray) -> float:
    """||W - reference|| / ||reference|| (Frobenius)."""
    return float(np.linalg.norm(W - reference) / np.linalg.norm(reference))


def run_inverse_inertia_study(choice: RobotChoice, durations=PULSE_DURATIONS, postures: int = POSTURES) -> dict:
    """The study of ``choice``'s arm (module docstring): its JSON report."""
    robot, normal = fixed_base(choice).model(), DEFAULT_WALL.normal
    arms = {name: HeldArm(choice, plant) for name, plant in servos(robot.n_joints).items()}
    rows = []
    for name in tuple(choice.robot.postures)[:postures]:
        q = choice.posture(name).q
        terms = robot.terms(q)
        W_gm, W_crb = gm_inverse_inertia(terms), crb_inverse_inertia(terms)
        row = {"posture": name, "gm": describe(W_gm, normal), "crb": describe(W_crb, normal), "simulated": []}
        for servo, arm in arms.items():
            for duration in durations:
                W = arm.inverse_inertia(q, duration)
                row["simulated"].append({
                    "servo": servo, "duration": duration, **describe(W, normal),
                    "distance_gm": distance(W, W_gm), "distance_crb": distance(W, W_crb), "W": W.tolist(),
                })
        rows.append(row)
    return {"robot": choice.robot.name, "tool": choice.tool.name, "normal": normal.tolist(),
            "pulse_impulse": PULSE_IMPULSE, "rows": rows}


def markdown(report: dict) -> str:
    """The report as Markdown: per posture, W_gm's and W_crb's n^T W n and mu_bar, then one line
    per servo and pulse duration."""
    lines = [f"# The simulated plant's inverse inertia at the contact: the {report['robot']}", "",
             "| posture | W | pulse (ms) | n^T W n (1/kg) | mu_bar | \\|W - W_gm\\| / \\|W_gm\\| | \\|W - W_crb\\| / \\|W_crb\\| |",
             "|---|---|---|---|---|---|---|"]
    for row in report["rows"]:
        for name in ("gm", "crb"):
            entry = row[name]
            lines.append(f"| {row['posture']} | W_{name} | | {entry['normal_inverse_mass']:.3f} | {entry['mu_bar']:.3f} | | |")
        for entry in row["simulated"]:
            lines.append(
                f"| {row['posture']} | {entry['servo']} | {1e3 * entry['duration']:g} | {entry['normal_inverse_mass']:.3f} "
                f"| {entry['mu_bar']:.3f} | {entry['distance_gm']:.3f} | {entry['distance_crb']:.3f} |")
    return "\n".join(lines) + "\n"
