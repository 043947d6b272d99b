import tomllib

import matplotlib.image

from impactqp.scenarios.sweep import store
from impactqp.scenarios.sweep.backends import run_sweep
from impactqp.scenarios.sweep.config import EXAMPLE, parse_config
from impactqp.scenarios.sweep.plots import write_plots


def test_one_speed_and_one_binding_figure_per_normal_and_restitution(tmp_path):
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(size=[0.1, 0.1])
    data["settings"].update(restitution=[0.0, 0.4], normals=[[-1.0, 0.0, 0.0], [-1.0, 0.0, -0.2]])
    config = parse_config(data)
    run_sweep(config, tmp_path, progress=False, plots=False)
    paths = write_plots(config, store.read_table(tmp_path), tmp_path)
    assert len(paths) == 2 * 2 * 2
    for path in paths:
        image = matplotlib.image.imread(path)
        assert image.ndim == 3 and image.shape[0] > 100 and image.std() > 0.0
