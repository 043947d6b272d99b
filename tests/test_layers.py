"""No import cycle, counting parent packages: each module of a low layer, imported alone in a fresh
interpreter, loads nothing of the layers above it (``sys.modules`` after the import).

import-linter follows the imports written in the modules; this test also sees the implicit import
of every parent package's ``__init__`` (``impactqp``, ``impactqp.controller``), which is how the
ground used to load the QP."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent

QP_AND_ABOVE = ("impactqp.controller.qp", "impactqp.controller.config", "impactqp.controller.runtime")
ABOVE_THE_GROUND = (*QP_AND_ABOVE, "impactqp.tasks", "impactqp.constraints", "impactqp.sim", "impactqp.scenarios")
MUJOCO = ("mujoco", "impactqp.sim", "impactqp.scenarios")

# package folder -> the packages none of its modules may load
FORBIDDEN = {
    "controller/model": (*ABOVE_THE_GROUND, "impactqp.controller.measured", "mujoco"),
    "controller/measured": (*ABOVE_THE_GROUND, "mujoco"),
    "controller/runtime": MUJOCO,
}


def modules_of(folder: str) -> list[str]:
    package = "impactqp." + folder.replace("/", ".")
    names = sorted(p.stem for p in (ROOT / folder).glob("*.py") if p.stem != "__init__")
    return [package] + [f"{package}.{name}" for name in names]


def loaded_by(module: str) -> set[str]:
    """The names in ``sys.modules`` of a fresh interpreter after ``import module``."""
    code = f"import sys\nimport {module}\nprint('\\n'.join(sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return set(out.stdout.split())


def offending(loaded: set[str], packages: tuple[str, ...]) -> list[str]:
    """The loaded modules that are one of ``packages`` or inside one."""
    return sorted(name for name in loaded if any(name == p or name.startswith(p + ".") for p in packages))


CASES = [(module, folder) for folder in FORBIDDEN for module in modules_of(folder)]


@pytest.mark.parametrize(("module", "folder"), CASES, ids=[module for module, _ in CASES])
def test_a_module_imported_alone_loads_no_layer_above_it(module, folder):
    assert offending(loaded_by(module), FORBIDDEN[folder]) == []


def test_every_package_of_the_low_layers_is_checked():
    assert {m for m, _ in CASES} >= {"impactqp.controller.model.robot", "impactqp.controller.measured.dataset",
                                     "impactqp.controller.runtime.loop", "impactqp.controller.runtime.session"}


def test_the_check_sees_what_an_import_loads():
    # the configuration builds the QP: the same check must report it
    assert "impactqp.controller.qp" in offending(loaded_by("impactqp.controller.config"), QP_AND_ABOVE)


def test_import_impactqp_loads_none_of_its_layers():
    loaded = loaded_by("impactqp")
    assert sorted(name for name in loaded if name.startswith("impactqp.")) == ["impactqp.lazy_exports"]
    assert "mujoco" not in loaded
