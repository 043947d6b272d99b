import numpy as np
import pytest
from hypothesis import strategies as st

from impactqp.controller.model.robot import PandaModel


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
