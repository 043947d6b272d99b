"""The figure of one impact (``scenarios.impact_figure``): what it plots is each predictor's
dq+ = dq- + Delta dq (eq. (19)) and the description's +-dq_max, read from its artists before it is
saved; its title names the robot, the tool, the posture and the speed."""

import matplotlib.pyplot as plt
import numpy as np
import pytest

from impactqp.controller.model.choice import DEFAULT_CHOICE
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.impact_figure import (
    AFTER_MS,
    BEFORE_MS,
    PREDICTORS,
    ImpactLabel,
    velocity_figure,
    write_velocity_figure,
)
from impactqp.scenarios.trial import TrialRunner
from impactqp.sim.runner import TrialSpec


@pytest.fixture(scope="module")
def trial():
    posture = DEFAULT_CHOICE.posture("elbow_up")
    runner = TrialRunner.build(DEFAULT_WALL, None, DEFAULT_CHOICE)
    return runner.run(TrialSpec(posture.name, posture.q, 0.1, jump_model="crb", start_at_rest=True, start_distance=0.05))


LABEL = ImpactLabel(DEFAULT_CHOICE.robot, DEFAULT_CHOICE.tool.name, "elbow_up")


@pytest.fixture(scope="module")
def figure(trial):
    fig = velocity_figure(trial, LABEL)
    yield fig
    plt.close(fig)


def lines_of(ax, label):
    return [line for line in ax.get_lines() if line.get_label() == label or (label == "+-dq_max" and line.get_color() == "tab:red")]


def test_every_joint_has_a_panel_with_its_velocity_around_the_impact(trial, figure):
    axes = [ax for ax in figure.axes if ax.get_visible()]
    robot = LABEL.robot
    assert [ax.get_title() for ax in axes] == list(robot.joints)
    t_ms = (trial.log.t - trial.impact.t_contact_start) * 1e3
    window = (t_ms >= -BEFORE_MS) & (t_ms <= AFTER_MS)
    for j, ax in enumerate(axes):
        (simulated,) = lines_of(ax, "simulated dq")
        np.testing.assert_array_equal(simulated.get_xdata(), t_ms[window])
        np.testing.assert_array_equal(simulated.get_ydata(), trial.log.dq[window, j])


def test_the_predictions_and_the_limits_are_the_predictors_and_the_descriptions(trial, figure):
    axes = [ax for ax in figure.axes if ax.get_visible()]
    dq_max = LABEL.robot.dq_max
    for j, ax in enumerate(axes):
        for method in PREDICTORS:
            (line,) = lines_of(ax, f"{method} dq+")
            expected = trial.impact.dq_pre[j] + trial.predicted[method][j]  # eq. (19)
            np.testing.assert_allclose(line.get_ydata(), [expected, expected], rtol=0, atol=1e-15)
            assert line.get_xdata()[0] == 0.0
        limits = sorted(line.get_ydata()[0] for line in lines_of(ax, "+-dq_max"))
        assert limits == [-dq_max[j], dq_max[j]]
        low, high = ax.get_ylim()
        shown = np.concatenate([line.get_ydata() for line in ax.get_lines() if line.get_color() != "tab:red"
                                and line.get_color() != "0.6"])
        assert low < shown.min() and shown.max() < high  # every velocity and prediction in view
        off_scale = [t.get_text() for t in ax.texts]
        assert (dq_max[j] > high) == any("off scale" in t for t in off_scale)


def test_the_title_names_robot_tool_posture_and_speed(trial, figure):
    title = figure._suptitle.get_text()
    for name in (LABEL.robot.name, LABEL.tool, LABEL.posture, f"{trial.contact_speed:.3f} m/s"):
        assert name in title


def test_the_figure_is_written_by_suffix_and_another_is_refused(trial, tmp_path):
    path = write_velocity_figure(trial, LABEL, tmp_path / "velocities.svg")
    assert path.read_text().lstrip().startswith("<?xml") and "svg" in path.read_text()[:400]
    with pytest.raises(BadInputError, match="--figure"):
        write_velocity_figure(trial, LABEL, tmp_path / "velocities.jpg")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["velocities.svg"]
