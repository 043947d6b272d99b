"""The campaign's figures (scenarios/campaign_figures.py): every panel labelled, the postures on one
y scale, the y range holding every value, the predicted jumps plotted as the rows hold them, the
titles naming the robot, the tool and the speeds, a speed axis from 0."""

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.model.jump import METHODS
from impactqp.scenarios.campaign_table import Table1, TableRow
import impactqp.scenarios.campaign_figures as campaign_figures
from impactqp.scenarios.campaign_figures import CampaignFigures, y_limits


SUBJECT = "panda with impact_tip"


def posture_rows(posture, scale, seed, speeds=(0.1, 0.15)):
    rng = np.random.default_rng(seed)
    return [
        TableRow(f"{posture}{k}", posture, v, 0.0, v, {m: 0.1 for m in METHODS}, scale * rng.normal(size=JOINTS),
                 {m: scale * rng.random(JOINTS) for m in METHODS},
                 predicted_jump={m: scale * rng.normal(size=JOINTS) for m in METHODS})
        for k, v in enumerate(speeds)
    ]


def drawn_figures(monkeypatch, tmp_path, rows):
    """The figures CampaignFigures would write, by file name (not saved)."""
    figures = []
    monkeypatch.setattr(campaign_figures, "save_figure", lambda fig, path: figures.append((path.name, fig)) or path)
    CampaignFigures(Table1(rows), SUBJECT).write(tmp_path)
    return dict(figures)


def test_every_figure_panel_is_labelled_and_the_postures_share_their_y_scale(tmp_path, monkeypatch):
    """Two postures with jumps 10 times apart: their figures still share the y range; the error
    figure has a panel for every predictor of Table I (classical_normal included)."""
    import matplotlib.pyplot as plt

    import impactqp.scenarios.campaign_figures as campaign_figures

    rows = posture_rows("elbow_up", 1.0, 0) + posture_rows("elbow_left", 0.1, 1)
    by_name = drawn_figures(monkeypatch, tmp_path, rows)
    figures = list(by_name.items())
    assert sorted(by_name) == [
        "errors_elbow_left.png", "errors_elbow_up.png", "jumps_elbow_left.png", "jumps_elbow_up.png",
        "predicted_elbow_left.png", "predicted_elbow_up.png",
    ]
    for kind in ("jumps", "errors"):
        limits = [by_name[f"{kind}_{p}.png"].axes[0].get_ylim() for p in ("elbow_up", "elbow_left")]
        assert limits[0] == limits[1]
    errors = by_name["errors_elbow_up.png"]
    assert [ax.get_title() for ax in errors.axes] == list(METHODS) and "classical_normal" in METHODS
    assert "elbow_up" in errors._suptitle.get_text()
    for name, fig in figures:
        for ax in fig.axes:
            if not name.startswith("predicted"):
                assert "(m/s)" in ax.get_xlabel() and "(rad/s)" in ax.get_ylabel(), name
        plt.close(fig)
    assert "elbow_up" in by_name["jumps_elbow_up.png"].axes[0].get_title()


def test_y_limits_hold_every_value():
    low, high = y_limits([np.array([-1.0, 2.0]), np.array([0.5])])
    assert low < -1.0 and high > 2.0
    assert y_limits([np.array([0.2, 0.3])], zero=True)[0] == 0.0
    assert y_limits([]) is None


def test_the_predicted_jumps_are_plotted_against_the_simulated_ones_per_joint(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    rows = posture_rows("elbow_up", 1.0, 2, speeds=(0.08, 0.1, 0.12))
    fig = drawn_figures(monkeypatch, tmp_path, rows)["predicted_elbow_up.png"]
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert len(panels) == JOINTS
    for j, ax in enumerate(panels):
        by_label = {line.get_label(): line for line in ax.get_lines()}
        for method in ("crb", "gm", "classical"):
            np.testing.assert_array_equal(by_label[method].get_xdata(), [r.measured_jump[j] for r in rows])
            np.testing.assert_array_equal(by_label[method].get_ydata(), [r.predicted_jump[method][j] for r in rows])
        diagonal = by_label["predicted = simulated"]
        np.testing.assert_array_equal(diagonal.get_xdata(), diagonal.get_ydata())
        assert ax.get_xlim() == ax.get_ylim()
        shown = np.concatenate([by_label[m].get_xydata().ravel() for m in ("crb", "gm", "classical")])
        assert ax.get_xlim()[0] < shown.min() and shown.max() < ax.get_xlim()[1]
    title = fig._suptitle.get_text()
    assert SUBJECT in title and "0.08-0.12 m/s" in title
    plt.close(fig)


def test_every_title_names_robot_tool_and_speed_and_one_speed_is_one_point_from_zero(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    by_name = drawn_figures(monkeypatch, tmp_path, posture_rows("elbow_up", 1.0, 3, speeds=(0.1,)))
    for name, fig in by_name.items():
        title = fig._suptitle.get_text() if fig._suptitle is not None else fig.axes[0].get_title()
        assert SUBJECT in title and "0.1 m/s" in title, name
        for ax in fig.axes:
            if "speed" in ax.get_xlabel():
                assert ax.get_xlim()[0] == 0.0 and ax.get_xlim()[1] == pytest.approx(0.115), name
        plt.close(fig)
