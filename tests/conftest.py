import numpy as np
import pytest
from hypothesis import strategies as st

from impactqp.controller.model.robot import PandaModel
from impactqp.scenarios.robot.interface import RobotInterface


@pytest.fixture(scope="session")
def robot() -> PandaModel:
    return PandaModel()


def joint_positions(margin: float = 0.1):
    """Hypothesis strategy: q uniformly inside the joint limits, ``margin`` rad from each."""
    model = PandaModel()
    lo, hi = model.q_min + margin, model.q_max - margin
    return st.lists(st.floats(0.0, 1.0), min_size=7, max_size=7).map(lambda u: lo + np.array(u) * (hi - lo))


def unit_vectors():
    return (
        st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)
        .map(np.array)
        .filter(lambda v: np.linalg.norm(v) > 0.2)
        .map(lambda v: v / np.linalg.norm(v))
    )


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
