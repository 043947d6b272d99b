"""No import cycle, counting parent packages: each module of a low layer, imported alone in a fresh
interpreter, loads nothing of the layers above it (``sys.modules`` after the import).

import-linter follows the imports written in the modules; this test also sees the implicit import
of every parent package's ``__init__`` (``impactqp``, ``impactqp.controller``), which is how the
ground used to load the QP.

The fresh interpreters are forked from one that has loaded only the third-party libraries the
low layers build on (``PRELOADED``: none of them imports impactqp, and none is a package the
checks forbid), so that each module's check costs its own import, not the libraries'
(``ImportProbe``)."""

from __future__ import annotations

import json
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


PRELOADED = ("numpy", "scipy.linalg", "pinocchio", "numba")
"""Loaded before the fork: the heavy libraries of the low layers, none of the forbidden packages."""

PROBE = f"""
import json, os, sys
for library in {PRELOADED!r}:
    __import__(library)
for line in sys.stdin:
    read, write = os.pipe()
    if os.fork() == 0:  # the child imports one module and reports what it loaded
        os.close(read)
        try:
            __import__(line.strip())
            report = sorted(sys.modules)
        except BaseException as error:
            report = {{"error": repr(error)}}
        with os.fdopen(write, "w") as out:
            json.dump(report, out)
        os._exit(0)
    os.close(write)
    with os.fdopen(read) as answer:
        print(answer.read(), flush=True)
    os.wait()
"""


class ImportProbe:
    """A Python process that has loaded ``PRELOADED`` and forks a fresh child per module asked."""

    def __init__(self):
        self.process = subprocess.Popen([sys.executable, "-c", PROBE], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        text=True)

    def loaded_by(self, module: str) -> set[str]:
        """The names in ``sys.modules`` of a fresh child after ``import module``."""
        self.process.stdin.write(module + "\n")
        self.process.stdin.flush()
        report = json.loads(self.process.stdout.readline())
        assert isinstance(report, list), f"import {module} failed: {report}"
        return set(report)

    def close(self):
        self.process.stdin.close()
        self.process.wait(timeout=60)


@pytest.fixture(scope="module")
def probe():
    probe = ImportProbe()
    yield probe
    probe.close()


def offending(loaded: set[str], packages: tuple[str, ...]) -> list[str]:
    """The loaded modules that are one of ``packages`` or inside one."""
    return sorted(name for name in loaded if any(name == p or name.startswith(p + ".") for p in packages))


CASES = [(module, folder) for folder in FORBIDDEN for module in modules_of(folder)]


@pytest.mark.parametrize(("module", "folder"), CASES, ids=[module for module, _ in CASES])
def test_a_module_imported_alone_loads_no_layer_above_it(probe, module, folder):
    assert offending(probe.loaded_by(module), FORBIDDEN[folder]) == []


def test_every_package_of_the_low_layers_is_checked():
    assert {m for m, _ in CASES} >= {"impactqp.controller.model.robot", "impactqp.controller.measured.dataset",
                                     "impactqp.controller.runtime.loop", "impactqp.controller.runtime.session"}


def test_the_check_sees_what_an_import_loads(probe):
    # the configuration builds the QP: the same check must report it
    assert "impactqp.controller.qp" in offending(probe.loaded_by("impactqp.controller.config"), QP_AND_ABOVE)
    assert "mujoco" in probe.loaded_by("impactqp.sim.scene")


def test_the_children_start_fresh(probe):
    """What one child imported is not in the next one's ``sys.modules``; the preloaded libraries
    import nothing of impactqp and no forbidden package."""
    assert "impactqp.sim.scene" in probe.loaded_by("impactqp.sim.scene")
    fresh = probe.loaded_by("json")
    assert not any(name == "mujoco" or name.startswith(("impactqp", "mujoco.")) for name in fresh)
    assert set(PRELOADED) <= fresh


def test_import_impactqp_loads_none_of_its_layers(probe):
    loaded = probe.loaded_by("impactqp")
    assert sorted(name for name in loaded if name.startswith("impactqp.")) == ["impactqp.lazy_exports"]
    assert "mujoco" not in loaded
