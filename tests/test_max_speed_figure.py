"""The figure of ``max-speed --figure`` (scenarios/max_speed_figure.py): one bar per predictor
and simulation, of the report's speed, each predictor's naming what binds it; the title names
the robot, the tool, the posture and the speed every predictor allows."""

import matplotlib.pyplot as plt
import pytest

from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.max_speed_figure import max_speed_figure, write_max_speed_figure

REPORT = {
    "posture": "elbow_up",
    "predicted_max_speed": {"classical": 0.58, "gm": 0.41, "crb": 0.155, "robust": 0.155},
    "binding": {"classical": {"criterion": "velocity_post", "joint": 6}, "gm": {"criterion": "impulsive_torque", "joint": 6},
                "crb": {"criterion": "impulsive_torque", "joint": 4}, "robust": {"criterion": "impulsive_torque", "joint": 4}},
    "qp_limited_speed": 0.1551, "simulated_max_speed": 0.2737,
}
STANCE = {
    "posture": "close", "predicted_max_speed": {"crb": 0.5, "gm": None, "robust": 0.5},
    "binding": {"crb": {"criterion": "capture", "where": "edge 2"}, "gm": {"criterion": "", "where": ""},
                "robust": {"criterion": "capture", "where": "edge 2"}},
    "simulated_max_speed": 0.7,
}


@pytest.mark.parametrize("report", [REPORT, STANCE])
def test_every_bar_is_a_speed_of_the_report_and_names_what_binds_it(report):
    fig = max_speed_figure(report, "panda with impact_tip")
    (ax,) = fig.axes
    widths = [patch.get_width() for patch in ax.patches]
    labels = [tick.get_text() for tick in ax.get_yticklabels()]
    predicted = {m: v for m, v in report["predicted_max_speed"].items() if v is not None}
    simulated = [report[k] for k in ("qp_limited_speed", "simulated_max_speed") if k in report]
    assert widths == list(predicted.values()) + simulated
    assert labels[:len(predicted)] == [f"{m} (closed form)" for m in predicted]
    texts = [t.get_text() for t in ax.texts]
    for k, method in enumerate(predicted):
        binding = report["binding"][method]
        assert binding["criterion"] in texts[k]
        assert (f"joint {binding['joint']}" if "joint" in binding else binding["where"]) in texts[k]
    assert ax.get_xlim()[0] == 0.0 and ax.get_xlim()[1] > max(widths)
    title = ax.get_title()
    assert "panda with impact_tip" in title and report["posture"] in title
    assert f"{report['predicted_max_speed']['robust']:.3f} m/s" in title
    plt.close(fig)


def test_the_figure_is_written_by_suffix_and_another_is_refused(tmp_path):
    path = write_max_speed_figure(REPORT, "panda with impact_tip", tmp_path / "speed.pdf")
    assert path.read_bytes()[:5] == b"%PDF-"
    with pytest.raises(BadInputError, match="--figure"):
        write_max_speed_figure(REPORT, "panda with impact_tip", tmp_path / "speed.gif")
    assert [p.name for p in tmp_path.iterdir()] == ["speed.pdf"]
