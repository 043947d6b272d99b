import tomllib

import matplotlib.image

from impactqp.scenarios.sweep import store
from impactqp.scenarios.sweep.backends import run_sweep
from impactqp.scenarios.sweep.cells import Simulation
from impactqp.scenarios.sweep.config import EXAMPLE, parse_config
from impactqp.scenarios.sweep.plots import write_plots


def assert_images(paths):
    for path in paths:
        image = matplotlib.image.imread(path)
        assert image.ndim == 3 and image.shape[0] > 100 and image.std() > 0.0


def test_one_speed_and_one_binding_figure_per_normal_restitution_and_impact_duration(tmp_path):
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(size=[0.1, 0.1])
    data["settings"].update(restitution=[0.0, 0.4], normals=[[-1.0, 0.0, 0.0], [-1.0, 0.0, -0.2]])
    data["controller"].update(jump_model=["crb", "gm"])  # the closed form does not depend on it
    config = parse_config(data)
    run_sweep(config, tmp_path, progress=False, plots=False)
    paths = write_plots(config, store.read_table(tmp_path), tmp_path)
    assert len(paths) == 2 * 2 * 2 and len({p.name for p in paths}) == len(paths)
    assert_images(paths)


def test_simulated_sweeps_add_one_figure_per_controller_setting(tmp_path):
    """Out of reach (no trial runs): the simulated maps are blank, the figures still drawn."""
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(origin=[1.5, 0.0, 0.5], size=[0.1, 0.1])
    data["controller"].update(jump_model=["crb", "gm"])
    config = parse_config(data)
    run_sweep(config, tmp_path, progress=False, plots=False, simulation=Simulation())
    paths = write_plots(config, store.read_table(tmp_path), tmp_path)
    simulated = [p for p in paths if p.name.startswith("simulated_")]
    assert len(simulated) == 2 and len(paths) == 2 + 2
    assert_images(paths)


def test_figure_file_names_carry_the_normal_and_every_panel_is_labelled(tmp_path):
    """Out of reach cells (origin 1.5 m away) are grey and named in the legend; the maps of the
    speeds share one colour scale and the difference is centred on zero."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import CenteredNorm

    from impactqp.scenarios.sweep.plots import Slice, binding_figure, speed_figure

    data = tomllib.loads(EXAMPLE)
    data["grid"].update(size=[0.3, 0.2])
    data["settings"].update(normals=[[-1.0, 0.0, 0.0], [-0.6, 0.0, -0.8]])
    config = parse_config(data)
    run_sweep(config, tmp_path, progress=False, plots=False)
    table = store.read_table(tmp_path)
    names = {p.name for p in write_plots(config, table, tmp_path)}
    assert "speed_normal0_n-1_0_0_restitution0_duration0.png" in names
    assert "binding_normal1_n-0.6_0_-0.8_restitution0_duration0.png" in names
    piece = Slice(config, table.to_pydict(), 0, 0, 0)
    for figure in (speed_figure(piece), binding_figure(piece)):
        title = figure._suptitle.get_text()
        assert "n = [-1, 0, 0]" in title and "delta_t = 0.015 s" in title and "[0.6, -0.2, 0.5] m" in title
        for ax in figure.axes:
            if ax.get_label() == "<colorbar>":
                continue
            assert ax.get_xlabel() == "u (m) along [0, 1, 0]" and ax.get_ylabel() == "v (m) along [0, 0, 1]"
            assert ax.get_title()
        legend = [t.get_text() for t in figure.legends[0].get_texts()]
        assert "unreachable" in legend
        plt.close(figure)
    figure = speed_figure(piece)
    maps = [ax.images[-1] for ax in figure.axes if ax.images]
    assert maps[0].get_clim() == maps[1].get_clim()  # gm and crb on one scale
    assert isinstance(maps[2].norm, CenteredNorm) and "(m/s)" in figure.axes[2].get_title()
    plt.close(figure)
