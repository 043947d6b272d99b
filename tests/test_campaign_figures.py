"""The campaign's figures (scenarios/campaign_figures.py): every panel labelled, the postures on one
y scale, the y range holding every value."""

import numpy as np

from conftest import JOINTS
from impactqp.controller.model.jump import METHODS
from impactqp.scenarios.campaign_table import Table1, TableRow
from impactqp.scenarios.campaign_figures import CampaignFigures, y_limits


def posture_rows(posture, scale, seed):
    rng = np.random.default_rng(seed)
    return [
        TableRow(f"{posture}{k}", posture, v, 0.0, v, {m: 0.1 for m in METHODS}, scale * rng.normal(size=JOINTS),
                 {m: scale * rng.random(JOINTS) for m in METHODS})
        for k, v in enumerate((0.1, 0.15))
    ]


def test_every_figure_panel_is_labelled_and_the_postures_share_their_y_scale(tmp_path, monkeypatch):
    """Two postures with jumps 10 times apart: their figures still share the y range; the error
    figure has a panel for every predictor of Table I (classical_normal included)."""
    import matplotlib.pyplot as plt

    import impactqp.scenarios.campaign_figures as campaign_figures

    figures = []
    monkeypatch.setattr(campaign_figures, "save_figure", lambda fig, path: figures.append((path.name, fig)) or path)
    rows = posture_rows("elbow_up", 1.0, 0) + posture_rows("elbow_left", 0.1, 1)
    CampaignFigures(Table1(rows)).write(tmp_path)
    by_name = dict(figures)
    assert sorted(by_name) == [
        "errors_elbow_left.png", "errors_elbow_up.png", "jumps_elbow_left.png", "jumps_elbow_up.png"
    ]
    for kind in ("jumps", "errors"):
        limits = [by_name[f"{kind}_{p}.png"].axes[0].get_ylim() for p in ("elbow_up", "elbow_left")]
        assert limits[0] == limits[1]
    errors = by_name["errors_elbow_up.png"]
    assert [ax.get_title() for ax in errors.axes] == list(METHODS) and "classical_normal" in METHODS
    assert "elbow_up" in errors._suptitle.get_text()
    for name, fig in figures:
        for ax in fig.axes:
            assert "(m/s)" in ax.get_xlabel() and "(rad/s)" in ax.get_ylabel(), name
        plt.close(fig)
    assert "elbow_up" in by_name["jumps_elbow_up.png"].axes[0].get_title()


def test_y_limits_hold_every_value():
    low, high = y_limits([np.array([-1.0, 2.0]), np.array([0.5])])
    assert low < -1.0 and high > 2.0
    assert y_limits([np.array([0.2, 0.3])], zero=True)[0] == 0.0
    assert y_limits([]) is None
