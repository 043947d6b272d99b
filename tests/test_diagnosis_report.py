"""The Markdown + PNG diagnosis report (scenarios/diagnosis_report.py)."""


from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.measured.impact import POST_HALF_WIDTH, PRE_SAMPLES
from impactqp.scenarios.diagnosis_report import (
    NEAR_ZERO_STDS,
    FeasibleSpeed,
    jump_noise_std,
    markdown,
    near_zero_jumps,
    trusted_speed_text,
    write_report,
)
from impactqp.scenarios.readable import parameters_text
from impactqp.sim.causes import PayloadCause
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.generation import DatasetRequest, generate_dataset


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    data = tmp_path_factory.mktemp("data")
    generate_dataset(data, DatasetRequest(postures=["elbow_up", "elbow_left"], speeds=[0.12], seed=1))
    return diagnose(data, causes=[PayloadCause()])


def test_report_is_written_without_touching_other_files(result, tmp_path):
    path = write_report(result, tmp_path / "report")
    text = path.read_text()
    for heading in ("# Impact diagnosis", "## What the nominal simulation gets wrong", "## Candidate causes",
                    "## Predictors and simulations per condition", "## Selection steps", "## Fitted parameters",
                    "## Trials (normalised residual of the final model, noise units)"):
        assert heading in text
    # a nominal plant: nothing is explained, so no fitted value is printed as a result
    assert not result.explained and "no fitted value is a result" in text and "95 % interval" not in text
    assert all(f"| {t.id} |" in text for t in result.trials)
    assert "What it means for your robot" not in text
    speeds = [FeasibleSpeed("elbow_up", 0.31, 0.42, 0.27)]
    text = write_report(result, tmp_path / "report", speeds).read_text()
    assert "| elbow_up | 0.310 | 0.420 | 0.270 |" in text
    assert "your robot can hit at 0.270 m/s, not 0.420 m/s" in text
    for figure in ("jumps.png", "error_vs_speed.png", "predictor_errors.png"):
        assert (tmp_path / "report" / figure).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    (tmp_path / "report" / "notes.txt").write_text("the user's own file")
    write_report(result, tmp_path / "report")
    assert (tmp_path / "report" / "notes.txt").read_text() == "the user's own file"
    assert sorted(p.name for p in (tmp_path / "report").iterdir()) == [
        "error_vs_speed.png", "jumps.png", "notes.txt", "predictor_errors.png", "report.md"
    ]


def test_report_writes_json_booleans_and_grouped_parameters(result):
    text = markdown(result, [FeasibleSpeed("elbow_up", 0.31, 0.42, 0.27)])
    assert f"(explained: {str(result.explained).lower()};" in text
    assert "True" not in text and "False" not in text
    assert "| true |" in text or "| false |" in text  # the selection steps
    assert f"- parameters: {parameters_text(result.summary()['parameters'])}" in text
    assert "{'" not in text  # no Python dict
    assert "Trust the " in text


def test_candidates_are_sorted_by_gain(result):
    text = markdown(result)
    section = text.split("## Candidate causes")[1].split("##")[0]
    gains = [float(line.split("|")[3].strip(" %")) for line in section.splitlines() if line.startswith("| ") and "%" in line]
    assert gains == sorted(gains, reverse=True) and gains


def test_every_figure_has_a_title_and_labelled_axes(result, tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    import impactqp.scenarios.diagnosis_report as report

    figures = []
    monkeypatch.setattr(report, "save", lambda fig, path: figures.append(fig))
    write_report(result, tmp_path)
    assert len(figures) == 3
    for fig in figures:
        assert fig._suptitle is not None or all(ax.get_title() for ax in fig.axes)
        for ax in fig.axes:
            assert ax.get_xlabel() and "(rad/s)" in ax.get_ylabel()
    jumps = figures[0]
    assert "pooled" in jumps._suptitle.get_text()
    assert len({ax.get_ylim() for ax in jumps.axes}) == 1  # postures on one y scale
    for fig in figures:
        plt.close(fig)


def noisy_trial(rng, sigma, jump, samples=60, pre=40):
    """A trial whose velocities ramp smoothly, carry white noise ``sigma`` and jump by ``jump``
    after sample ``pre``."""
    t = np.arange(samples)[:, None]
    dq = 0.01 * t + 1e-4 * t**2 + rng.normal(0.0, sigma, (samples, JOINTS)) + (t > pre) * jump
    return SimpleNamespace(dq_log=dq, jump_samples=(pre, pre + 2), jump=np.asarray(jump, float))


@settings(max_examples=20, deadline=None)
@given(st.floats(min_value=1e-3, max_value=0.05), st.integers(min_value=0, max_value=1000))
def test_jump_noise_is_the_sample_noise_of_the_means_a_jump_takes(sigma, seed):
    rng = np.random.default_rng(seed)
    diagnosis = SimpleNamespace(trials=[noisy_trial(rng, sigma, np.zeros(JOINTS)) for _ in range(30)])
    expected = sigma * np.sqrt(1.0 / PRE_SAMPLES + 1.0 / (2 * POST_HALF_WIDTH + 1))
    assert jump_noise_std(diagnosis) == pytest.approx(np.full(JOINTS, expected), rel=0.15)


def test_near_zero_jumps_are_those_within_the_noise():
    rng = np.random.default_rng(0)
    sigma = 0.004
    jump = np.array([0.5, -0.3, 0.0, 0.2, 0.0, 1.0, 0.0])
    diagnosis = SimpleNamespace(trials=[noisy_trial(rng, sigma, jump) for _ in range(6)])
    assert near_zero_jumps(diagnosis).tolist() == [False, False, True, False, True, False, True]
    noise = jump_noise_std(diagnosis)
    assert np.all(NEAR_ZERO_STDS * noise < 0.2) and np.all(noise > 0.0)


def test_the_report_says_which_maximum_speed_to_trust():
    rows = [FeasibleSpeed("elbow_up", 0.155, 0.292, 0.112)]
    explained = trusted_speed_text(SimpleNamespace(explained=True, causes=["armature"]), rows)
    assert explained.startswith("Trust the extended simulation") and "armature" in explained
    assert "closed form (0.155 m/s) is above the trusted 0.112 m/s" in explained
    unexplained = trusted_speed_text(SimpleNamespace(explained=False, causes=[]), rows)
    assert unexplained.startswith("Trust the nominal simulation")
    assert "is below the trusted 0.292 m/s" in unexplained


def test_the_speed_sentence_says_not_only_when_the_answers_differ():
    assert "not 0.420" in FeasibleSpeed("elbow_up", 0.31, 0.42, 0.27).sentence()
    same = FeasibleSpeed("elbow_up", 0.31, 0.3494, 0.3491).sentence()
    assert "not" not in same.split("m/s")[1] and "holds" in same and "0.349 m/s" in same
