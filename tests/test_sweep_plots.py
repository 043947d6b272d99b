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
