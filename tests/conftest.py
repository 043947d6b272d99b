import functools
import hashlib
import os
import signal
import socket

# MuJoCo picks its OpenGL backend when it is first imported (below): the offscreen one that
# scenarios.video renders with, as the command line does (an explicit MUJOCO_GL wins).
os.environ.setdefault("MUJOCO_GL", "egl")

import compile_once
import numpy as np
import pytest
from hypothesis import settings
from hypothesis import strategies as st

# Before any kernel module is imported: the test processes (both pytest-xdist workers, the pools
# they start) compile each numba kernel signature once between them, not once each.
compile_once.install()

from impactqp.controller.measured.dataset import DatasetHeader, TrialEntry
from impactqp.controller.measured.dataset_writer import DatasetWriter
from impactqp.controller.measured.impact import measure_impact
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot import ACCELERATION_LIMIT, JERK_LIMIT, VELOCITY_LIMIT, PandaModel, SingularPostureError
from impactqp.controller.model.robot_description import PANDA, ROBOTS
from impactqp.controller.model.tool_description import TOOLS
from impactqp.controller.runtime.interface import RobotInterface
from impactqp.scenarios.run import RunRequest, run
from impactqp.sim.generation import STANDING_WALL, dataset_header
from impactqp.sim.plant import PlantParameters
from impactqp.sim.runner import TrialSpec, run_approach
from impactqp.sim.scene import build_scene

# No property test may fail on its timing: a busy machine (CI shares its cores) can stall any
# example for a second; hypothesis's default 200 ms deadline would call that a failure.
settings.register_profile("impactqp", deadline=None)
settings.load_profile("impactqp")

# The tests of Ctrl-C need SIGINT as a terminal delivers it. A test run started in the background of
# a non-interactive shell (or by a tool that does so) inherits SIGINT ignored, and so would every
# process it starts: put Python's own handler back in each test process.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

CONTROL_PERIOD = 1e-3
LIMIT_TOLERANCE = 1e-9
JOINTS = len(PANDA.joints)
G1_HEADER = dataset_header(STANDING_WALL, RobotChoice(ROBOTS["g1"]))
"""The header of the G1's simulated trials."""
ARMS = [name for name in ROBOTS if not ROBOTS[name].floating]
"""The built-in fixed-base arms (the descriptions whose base is fixed)."""
FRANKA_ARMS = [name for name in ARMS if ROBOTS[name].finger_joints]
"""The built-in arms carrying the Franka Hand (the Panda's kinematic chain and postures)."""
"""The joints of the robot the tests drive (``PandaModel()``, the ``robot`` fixture)."""


@functools.cache
def g1_model() -> RobotModel:
    """The G1's model (its description's), built once for the tests."""
    return RobotModel("g1")


@pytest.fixture(scope="session")
def robot() -> PandaModel:
    return PandaModel()


def joint_positions(margin: float = 0.1):
    """Hypothesis strategy: q uniformly inside the joint limits, ``margin`` rad from each."""
    model = PandaModel()
    lo, hi = model.q_min + margin, model.q_max - margin
    return st.lists(st.floats(0.0, 1.0), min_size=model.nq, max_size=model.nq).map(lambda u: lo + np.array(u) * (hi - lo))


def random_state(robot, rng, speed=0.5):
    """A random non-singular state inside the limits; speed is the fraction of dq_max."""
    span = robot.q_max - robot.q_min
    while True:
        q = robot.q_min + span * rng.uniform(0.1, 0.9, JOINTS)
        try:
            return robot.terms(q, rng.uniform(-speed, speed, JOINTS) * robot.dq_max)
        except SingularPostureError:
            continue


def unit_vectors():
    return (
        st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)
        .map(np.array)
        .filter(lambda v: np.linalg.norm(v) > 0.2)
        .map(lambda v: v / np.linalg.norm(v))
    )


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A failed test that ran franky-sim servers (``item.franky_sim_servers``, set by the
    ``franky_sim`` fixture of ``test_franky_sim.py``) shows each server's own output."""
    outcome = yield
    report = outcome.get_result()
    if report.failed:
        for server in getattr(item, "franky_sim_servers", ()):
            report.sections.append((f"franky-sim server output ({server.output})", server.output_text()))


class ForwardingRobot(RobotInterface):
    """A robot interface that forwards every call to ``robot`` (a real backend); a test
    subclass overrides ``read`` to inject what it needs at a given cycle."""

    def __init__(self, robot: RobotInterface):
        self.robot = robot
        self.period = robot.period

    def read(self):
        return self.robot.read()

    def start(self):
        return self.robot.start()

    def write(self, dq_cmd):
        self.robot.write(dq_cmd)

    def force_log(self):
        return self.robot.force_log()


@pytest.fixture(scope="session")
def retract_run(tmp_path_factory):
    """(report, result, log directory) of one logged unpaced run of ``impactqp run``'s default on
    the sim backend: approach at 0.15 m/s, impact, retract."""
    log_dir = tmp_path_factory.mktemp("run")
    report, result = run(RunRequest(speed=0.15, duration=0.6, unpaced=True, log=str(log_dir)))
    return report, result, log_dir


def assert_continuous_within_limits(dq_cmd):
    """Velocity, acceleration and jerk of commands sent from rest stay inside the datasheet limits."""
    dq = np.vstack([np.zeros((2, np.shape(dq_cmd)[1])), dq_cmd])
    ddq = np.diff(dq, axis=0) / CONTROL_PERIOD
    jerk = np.diff(ddq, axis=0) / CONTROL_PERIOD
    assert np.all(np.isfinite(dq))
    assert np.all(np.abs(dq) <= VELOCITY_LIMIT * (1 + LIMIT_TOLERANCE))
    assert np.all(np.abs(ddq) <= ACCELERATION_LIMIT * (1 + LIMIT_TOLERANCE))
    assert np.all(np.abs(jerk) <= JERK_LIMIT * (1 + LIMIT_TOLERANCE))


DATASET_HEADER = DatasetHeader(TOOLS["impact_tip"], DEFAULT_WALL, 1e-3)


@pytest.fixture(scope="session")
def dataset_logs():
    """Two simulated trials (elbow_left, 0.1 and 0.15 m/s) of a plant with armature, by speed."""
    scene = build_scene(plant=PlantParameters(armature=[0.2] * JOINTS))
    return {
        speed: run_approach(scene, PandaModel(), TrialSpec("elbow_left", PANDA.postures["elbow_left"].q, speed, after_contact=0.05)).log
        for speed in (0.1, 0.15)
    }


def dataset_entry(name, speed, log, force=True):
    """The manifest entry of the trial ``name`` logged in ``log``."""
    return TrialEntry(
        id=name,
        file=f"{name}.csv",
        force_file=f"{name}_force.csv" if force else None,
        reference_normal_speed=speed,
        reference_tangential_velocity=(0.0, 0.0, 0.0),
        posture="elbow_left",
        impact_time=measure_impact(log).t_contact_start,
    )


def write_dataset(directory, logs):
    """Write a dataset of two trials into ``directory``: "fast" with its force file, "slow"
    without (``logs``: ``dataset_logs``); returns the directory."""
    writer = DatasetWriter(directory, DATASET_HEADER)
    writer.add_trial(dataset_entry("fast", 0.15, logs[0.15]), logs[0.15])
    writer.add_trial(dataset_entry("slow", 0.1, logs[0.1], force=False), logs[0.1])
    return directory


@pytest.fixture()
def dataset(tmp_path, dataset_logs):
    """A dataset of two trials: "fast" with its force file, "slow" without."""
    return write_dataset(tmp_path, dataset_logs)


def file_digests(directory):
    """SHA-256 of every file in ``directory``, by name: equal before and after means untouched."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(directory.iterdir())}


def g1_log(seed: int, scale: float = 1.0):
    """A synthetic G1 log of 80 control samples (1 ms): joint positions inside the G1's limits, unit
    base quaternions, other values drawn at ``scale``, and a 20 N wall force (0.5 ms samples) from
    30 to 35 ms, so that an impact is found."""
    rng, model, n = np.random.default_rng(seed), g1_model(), 80
    joints = len(model.joint_names)
    quaternion = rng.normal(size=(n, 4))
    base = np.column_stack([scale * rng.normal(size=(n, 3)), quaternion / np.linalg.norm(quaternion, axis=1)[:, None],
                            scale * rng.normal(size=(n, 6))])
    force_t = np.arange(2 * n) * 0.5e-3
    force = np.zeros((2 * n, 3))
    force[60:70, 0] = -20.0
    return TrialLog(
        np.arange(n) * 1e-3, rng.uniform(model.q_min, model.q_max, (n, joints)),
        *(scale * rng.normal(size=(n, joints)) for _ in range(3)), force_t, force, base=base,
    )


def g1_dataset(directory, seed: int = 0):
    """A G1 dataset of one synthetic trial ``g`` (``g1_log``) in ``directory``; its log."""
    log = g1_log(seed)
    entry = TrialEntry(id="g", file="g.csv", reference_normal_speed=0.3, force_file="g_force.csv",
                       posture="parallel", impact_time=0.03)
    DatasetWriter(directory, G1_HEADER).add_trial(entry, log)
    return log


FRANKA_COMMAND_PORT = 1337
"""The TCP port libfranka (and so panda-python) connects to."""


def reserved_robot_address(listen: bool) -> tuple[str, socket.socket]:
    """A loopback address whose robot port this process holds: bound without SO_REUSEADDR, so
    that no other socket (a franky-sim server of a parallel test, which takes the first free
    127.x.y.z) can take it; not listening, a connection there is refused (no robot answers),
    listening, it is accepted by this socket alone. Away from the addresses franky-sim tries
    first."""
    for last in range(1, 255):
        address = f"127.0.9.{last}"
        reserved = socket.socket()
        try:
            reserved.bind((address, FRANKA_COMMAND_PORT))
        except OSError:
            reserved.close()
            continue
        if listen:
            reserved.listen(8)
        return address, reserved
    raise RuntimeError("no free loopback address for a robot port")


@pytest.fixture
def no_robot_address():
    """A loopback address where no robot answers: a connection to the robot port is refused."""
    address, reserved = reserved_robot_address(listen=False)
    yield address
    reserved.close()
