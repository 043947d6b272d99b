"""One closed-loop impact trial with the QP controller, and what was observed in it (its
``sim.trial_result.TrialResult``).

Set-up
------
The MuJoCo plant (``sim.scene``) is driven by the impact-aware QP controller
(``controller.config.ControllerConfig.approach``, the command source ``sim.trial_sources.QpCommand``)
at 1 kHz through the plant's joint servo (``sim.runner.run_approach``). The trial starts ``start_distance`` in front of the surface at the
posture ``approach_start`` finds for the contact posture, either already moving at the reference
velocity dq0 = J6+ [-v_n n + v_t; 0] (``start_at_rest=False``, as the paper's constant-velocity
approach) or at rest (``start_at_rest=True``: the controller accelerates by itself, which is how
the QP reaches its own highest feasible speed when asked for more).

Controller state: the commanded state, not the measured one
-----------------------------------------------------------
A kinematic-controlled robot's QP integrates its own command: at cycle k it is given
(q_cmd, dq_cmd) of cycle k-1 (the measured state only at the first cycle), as mc_rtc does for a
position/velocity-controlled robot. The servo alone sees the plant. Feeding it the measured state
instead (``feedback="measured"``) closes a positive loop through the servo's acceleration
feed-forward: the controller commands dq_cmd = dq_measured + ddq dt, so the servo's feed-forward
(dq_cmd_k - dq_cmd_{k-1}) / dt repeats, every period, the acceleration the impact imposed in the
previous one: the contact is cut short and a wrist joint runs away while the controller reports
"ok" (``docs/simulation.md``, "Controller in the loop", has the numbers). With the commanded
state the jump is the one of ``sim.trial_sources.CartesianApproachCommand``.
After the contact the controller keeps its reference: it keeps commanding the approach into the
wall, like ``CartesianApproachCommand`` (the servo then presses with a slowly growing force).

The controller's posture task weight is 0 (``posture_weight``): a posture task pulls the arm back
towards the start posture, and the contact speed ends below the reference.

Observed criteria (docs/max-speed.md, as measured in the simulation)
----------------------------------------------------------------------
With the impact of :func:`controller.measured.impact.measure_impact` (contact start t_c, pre-impact state
(q-, dq-), contact impulse iota_sim integrated from the contact force, contact duration
delta_t_sim):

- contact speed         v_c = -n . J(q-) dq-
- velocity ratio        max over i and t in [t_c, t_c + 50 ms] of |dq_i(t)| / dq_max_i
- impulsive torque      max_i |J(q-)^T iota_sim|_i / delta_t_sim / tau_max_i
- violated              either ratio > 1
(the criteria of a robot without held contacts, ``sim.observed_criteria``, watching [t_c, t_c + 50 ms])
- predictions           each predictor's own jump at (q-, dq-), v- = J(q-) dq-
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from impactqp.controller.model.jump import JUMP_MODELS, METHODS
from impactqp.controller.model.max_speed import Setting, closed_form_max_speed
from impactqp.controller.model.choice import DEFAULT_CHOICE, RobotChoice
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import PandaModel, RobotModel
from impactqp.constraints import jump_model_names
from impactqp.controller.measured.impact import ImpactNotFoundError, measure_impact
from impactqp.sim.plant import PlantParameters
from impactqp.sim.process_pool import ProcessPool
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.sim.runner import OBSERVATION_WINDOW, TrialSpec, run_approach, run_impact_trial
from impactqp.sim.observed_criteria import TrialObservation, observe
from impactqp.sim.trial_result import TrialResult
from impactqp.sim.trial_sources import SCRIPTED, QpCommand, TrialSource
from impactqp.sim.scene import Scene, build_scene
from impactqp.controller.model.validation import BadInputError

# Time allowed to the controller, from rest, to reach its approach speed (it needs less: docs/results.md).
ACCELERATION_ALLOWANCE = 0.25


class TrialRunner:
    """Runs :class:`TrialSpec` trials of one robot model: an arm's on one scene (surface and
    plant), driven by its QP (``source`` None: ``QpCommand`` configured by each spec), each a
    ``sim.trial_result.TrialResult``; a robot with held contacts at the stance ``spec.posture`` of its
    description (``sim.runner.run_impact_trial``: the wall placed before its hand, scene
    None) at the hand speed ``spec.normal_speed``, driven by ``source`` (None: the scripted arm),
    each a ``TrialResult`` with its ``held`` part."""

    def __init__(self, scene: Scene | None, robot: RobotModel | None = None, source: TrialSource | None = None):
        self.scene = scene
        self.robot = PandaModel() if robot is None else robot
        self.source = source

    @classmethod
    def build(
        cls, surface: Surface, plant: PlantParameters | None = None, choice: RobotChoice = DEFAULT_CHOICE,
        source: TrialSource | None = None,
    ) -> TrialRunner:
        """A runner of ``choice``'s robot and tool: its scene (none for a robot with held
        contacts: each trial builds its own) and its model."""
        held = choice.robot.held_contacts
        return cls(None if held else build_scene(surface, plant, robot=choice.robot, tool=choice.tool), choice.model(), source)

    @property
    def surface(self) -> Surface:
        return self.scene.surface

    def source_of(self, spec: TrialSpec) -> TrialSource:
        """The trial's command source: the runner's, or the robot's default controller
        (``sim.trial_sources.QpCommand``) with the spec's jump model, c_r, delta_t and feedback,
        posture task weight 0."""
        if self.source is not None:
            return self.source
        return QpCommand(method=spec.jump_model, feedback=spec.feedback, restitution=spec.restitution,
                         impact_duration=spec.impact_duration, posture_weight=0.0)

    def duration(self, spec: TrialSpec) -> float:
        """Simulated time: the approach at the expected speed, plus ``after_contact``.

        From rest the expected speed is the reference capped by the closed-form maximum of the
        controller's jump model(s) at the contact posture, plus the acceleration allowance.
        """
        speed = spec.normal_speed
        if not spec.start_at_rest:
            return spec.start_distance / speed + spec.after_contact
        if spec.jump_model is not None:
            terms = self.robot.terms(spec.q_contact)
            for name in jump_model_names(spec.jump_model):
                setting = Setting(name, spec.restitution, impact_duration=spec.impact_duration)
                limit = closed_form_max_speed(self.robot, terms, self.surface.normal, setting)
                speed = min(speed, 0.9 * limit.speed)
        return ACCELERATION_ALLOWANCE + spec.start_distance / speed + spec.after_contact

    def run(self, spec: TrialSpec) -> TrialResult:
        """Simulate the trial (``sim.runner.run_approach`` with the QP in the loop, or the standing
        robot's trial) and evaluate it (raises ``ImpactNotFoundError`` without impact,
        ``UnreachableStartError`` when the surface is out of reach)."""
        description = self.robot.description
        if description.held_contacts:
            return run_impact_trial(self.robot, description.stances[spec.posture], spec.normal_speed,
                                    q0=spec.q_contact, source=self.source or SCRIPTED)
        source = self.source_of(spec)
        run = run_approach(self.scene, self.robot, spec, source, self.duration(spec))
        return self.evaluate(spec, run.log, run.driver.controller.fallback_count, source.name)

    def evaluate(self, spec: TrialSpec, log: TrialLog, fallback_count: int = 0, source: str = "qp") -> TrialResult:
        """The observed criteria and the predictions of the module docstring, from a simulated
        ``log`` (``ImpactNotFoundError`` when its tool never touched the wall)."""
        robot, normal = self.robot, self.surface.normal
        if not log.force.any():  # no impact to look for in the torques: say what the trial did
            raise ImpactNotFoundError(
                f"the tool never touched the wall: the simulated trial lasted {log.t[-1]:.3f} s from "
                f"{spec.start_distance:.3f} m in front of it at a commanded {spec.normal_speed:.3f} m/s"
            )
        impact = measure_impact(log)
        terms = robot.terms(impact.q_pre, impact.dq_pre, check_limits=False)
        v_pre = terms.J @ impact.dq_pre
        window = (log.t >= impact.t_contact_start - 1e-9) & (
            log.t <= impact.t_contact_start + OBSERVATION_WINDOW + 1e-9
        )
        if log.t[-1] < impact.t_contact_start + OBSERVATION_WINDOW - 1e-9:
            raise ValueError(
                f"the trial ends {log.t[-1] - impact.t_contact_start:.3f} s after the contact, "
                f"less than the {OBSERVATION_WINDOW * 1e3:.0f} ms observation window"
            )
        first = int(np.flatnonzero(window)[0])
        observation = TrialObservation(robot, log, window, first, first, impact.impulse, impact.duration, terms.J,
                                       log.control_period)
        predicted = {
            name: JUMP_MODELS[name].predict(terms, normal, v_pre, spec.restitution).dq_jump
            for name in METHODS
        }
        return TrialResult(
            trial_id=spec.trial_id,
            posture=spec.posture,
            normal_speed=spec.normal_speed,
            tangential_velocity=spec.tangential_velocity,
            jump_model=spec.jump_model,
            log=log,
            impact=impact,
            measured_jump=impact.dq_jump,
            contact_speed=float(-normal @ v_pre),
            predicted=predicted,
            criteria=observe(observation),
            source=source,
            fallback_count=fallback_count,
        )


# ---------------------------------------------------------------------------- processes
_WORKER: TrialRunner | None = None


def _init_worker(surface: Surface, plant: PlantParameters | None, choice: RobotChoice) -> None:
    global _WORKER
    _WORKER = TrialRunner.build(surface, plant, choice)


def _run_in_worker(spec: TrialSpec) -> TrialResult:
    return _WORKER.run(spec)


class TrialPool(ProcessPool):
    """Runs trials on ``jobs`` processes (``sim.process_pool.ProcessPool``); every worker builds
    its own scene, robot model and controllers, of ``choice``'s robot and tool. ``jobs=1`` runs
    in this process."""

    def __init__(
        self, surface: Surface, plant: PlantParameters | None = None, jobs: int = 1,
        choice: RobotChoice = DEFAULT_CHOICE,
    ):
        if jobs < 1:
            raise BadInputError(f"--jobs must be >= 1, got {jobs}")
        super().__init__(jobs, initializer=_init_worker, initargs=(surface, plant, choice))

    def map(self, specs: Iterable[TrialSpec]) -> Iterator[TrialResult]:
        """Results in the order of ``specs``."""
        return super().map(_run_in_worker, specs)
