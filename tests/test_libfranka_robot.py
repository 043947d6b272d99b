"""What both libfranka backends share: the load ``set_load`` gets is the declared tool's, moved
into the flange frame, each entry of the ``[libfranka]`` table replacing the tool's; the settings
reach the robot on connect in libfranka's order."""

import numpy as np
import pinocchio as pin
import pytest
from conftest import reserved_robot_address

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.robot_config import RobotConfig
from impactqp.controller.runtime.collision_thresholds import CollisionThresholds, fixed_thresholds
from impactqp.controller.runtime.libfranka_robot import LibfrankaRobot, declared_load


@pytest.fixture(scope="module", params=["panda", "fr3"])
def robot(request):
    return request.param


@pytest.mark.parametrize("tool", ["impact_tip", "franka_hand", "pad"])
def test_the_declared_load_is_the_tools_mass_com_and_inertia_in_the_flange_frame(robot, tool):
    model = RobotModel(robot, tool)
    load = declared_load(model, RobotConfig())
    described = model.tool
    assert load.mass == described.mass
    # a rigid change of frame keeps the distance of the centre of mass from the frame's origin
    # (both frames share theirs on these arms) and the inertia's eigenvalues
    assert np.linalg.norm(load.com) == pytest.approx(np.linalg.norm(described.com), abs=1e-12)
    inertia = np.reshape(load.inertia, (3, 3), order="F")
    assert np.allclose(inertia, inertia.T)
    assert np.allclose(np.linalg.eigvalsh(inertia), np.linalg.eigvalsh(described.inertia), atol=1e-12)
    # the centre of mass maps back to the tool's in the world at any configuration
    data = model.model.createData()
    q = 0.5 * (model.q_min + model.q_max)
    pin.framesForwardKinematics(model.model, data, q)
    flange = data.oMf[model.model.getFrameId(model.description.flange_frame)]
    tool_frame = data.oMf[model.tool_frame_id]
    assert np.allclose(flange.act(np.array(load.com)), tool_frame.act(described.com), atol=1e-12)


def test_each_entry_of_the_robot_table_replaces_the_tools(robot):
    model = RobotModel(robot, "pad")
    tool_load = declared_load(model, RobotConfig())
    heavier = declared_load(model, RobotConfig(load_mass=1.5))
    assert heavier.mass == 1.5 and heavier.com == tool_load.com and heavier.inertia == tool_load.inertia
    moved = declared_load(model, RobotConfig(load_com=[0.0, 0.0, 0.1]))
    assert moved.com == [0.0, 0.0, 0.1] and moved.mass == tool_load.mass


class SettingsRobot:
    """Records the settings calls of a libfranka ``Robot``; refuses the one named ``refuse``."""

    def __init__(self, refuse=None):
        self.calls, self.refuse = [], refuse

    def __getattr__(self, name):
        def call(*args):
            if name == self.refuse:
                raise RuntimeError(f"{name} refused")
            self.calls.append((name, args))

        return call


def test_connect_sets_the_reflex_impedance_and_the_declared_load_or_names_what_was_refused():
    model = RobotModel("fr3", "pad")
    settings = RobotConfig()
    robot = SettingsRobot()
    LibfrankaRobot(robot, (RuntimeError,), (RuntimeError,), settings).configure("ip", model)
    names = [name for name, _ in robot.calls]
    assert names == ["set_collision_behavior", "set_joint_impedance", "set_load"]
    load = declared_load(model, settings)
    assert robot.calls[-1][1] == (load.mass, load.com, load.inertia)
    defaults = fixed_thresholds(settings)  # no impact given: the table's lists or the defaults
    assert robot.calls[0][1] == (defaults.lower_torque, defaults.upper_torque, defaults.lower_force, defaults.upper_force)
    given = CollisionThresholds([1.0] * 7, [2.0] * 7, [3.0] * 6, [4.0] * 6, "why")
    robot = SettingsRobot()
    connected = LibfrankaRobot(robot, (RuntimeError,), (RuntimeError,), settings)
    connected.configure("ip", model, given)
    assert robot.calls[0] == ("set_collision_behavior", ([1.0] * 7, [2.0] * 7, [3.0] * 6, [4.0] * 6))
    assert connected.report()["collision_thresholds"] == given.to_dict()
    refusing = LibfrankaRobot(SettingsRobot("set_load"), (RuntimeError,), (RuntimeError,), settings)
    with pytest.raises(BadInputError, match="the robot at ip refused the load: set_load refused"):
        refusing.configure("ip", model)


@pytest.fixture
def silent_peer():
    """A local server at a loopback address of its own, on libfranka's port (a franky-sim test
    cannot take it), that accepts every connection and never answers."""
    import threading

    address, server = reserved_robot_address(listen=True)
    accepted = []
    running = threading.Event()
    running.set()

    def accept():
        server.settimeout(0.1)
        while running.is_set():
            try:
                accepted.append(server.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield address
    running.clear()
    thread.join()
    for connection in accepted:
        connection.close()
    server.close()


@pytest.mark.parametrize("backend", ["franka", "panda"])
def test_a_robot_that_accepts_and_never_answers_is_one_line_within_seconds(silent_peer, backend):
    import importlib
    import time

    from impactqp.controller.runtime.libfranka_robot import ANSWER_TIMEOUT

    module = {"franka": "pylibfranka", "panda": "panda_py.libfranka"}[backend]
    pytest.importorskip(module, reason=f"{module} is not installed")
    backend_module = importlib.import_module(f"impactqp.controller.runtime.{backend}_backend")
    Robot = backend_module.FrankaRobot if backend == "franka" else backend_module.PandaRobot
    start = time.monotonic()
    with pytest.raises(BadInputError, match="accepted the connection but did not answer within"):
        Robot.connect(silent_peer, realtime=False)
    # the bindings' import in the child (unbounded by the answer's deadline) plus the deadline
    assert time.monotonic() - start < 10.0 + ANSWER_TIMEOUT
