"""The replay backend (``controller.runtime.replay_backend``) plays a logged run back through the
loop: the controller sends the same commands and sees the same torques."""

import numpy as np
import pytest

from impactqp.controller.model.validation import BadInputError
from impactqp.controller.runtime.loop import BRAKING
from impactqp.controller.runtime.replay_backend import load_trial
from impactqp.scenarios.run import RunRequest, run

from conftest import g1_dataset


def test_a_replayed_trial_reproduces_the_logged_commands(retract_run):
    _, original, log_dir = retract_run
    report, replayed = run(RunRequest(backend="replay", dataset=str(log_dir), log=None))
    controlled = np.array([p not in ("stop", BRAKING) for p in original.phases])
    # the CSV keeps 10 significant digits of every logged state
    assert np.allclose(replayed.log.dq_cmd[controlled], original.log.dq_cmd[controlled], rtol=0.0, atol=1e-6)
    # the replay reports each logged torque with the next state, so its own log has the same rows
    n = len(original.log) - 1
    assert np.allclose(replayed.log.tau[:n], original.log.tau[:n], rtol=1e-9, atol=1e-6)
    assert report["impact"]["time"] == pytest.approx(original.session.detector.t_detect)


def test_a_g1_dataset_is_refused_naming_why(tmp_path):
    g1_dataset(tmp_path)
    with pytest.raises(BadInputError, match="its robot g1 has a floating base"):
        load_trial(tmp_path, None)
