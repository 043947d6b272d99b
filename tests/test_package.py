"""The package as a user installs it: one import name, its first names, and acyclic layers."""

from __future__ import annotations

import ast
import importlib
import os
import pkgutil
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import grimp
import pytest

import impactqp

TESTS = Path(__file__).parent


def test_import_impactqp_exposes_the_first_names():
    for name in ("PandaModel", "JUMP_MODELS", "jump_model", "ImpactAwareController", "ControllerConfig"):
        assert hasattr(impactqp, name), name
    assert impactqp.__version__ and impactqp.__version__[0].isdigit()


def test_the_first_names_are_listed_and_an_unknown_name_is_an_attribute_error():
    assert set(impactqp.__all__) <= set(dir(impactqp))
    assert impactqp.PandaModel is impactqp.controller.model.robot.PandaModel
    with pytest.raises(AttributeError, match="no_such_name"):
        impactqp.no_such_name


def packages() -> list[str]:
    """Every package of the project, as pyproject.toml installs them."""
    import tomllib

    return tomllib.loads((TESTS.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]


@pytest.mark.parametrize("package", packages())
def test_every_name_of_every_package_all_resolves(package):
    module = importlib.import_module(package)
    assert module.__all__ and len(set(module.__all__)) == len(module.__all__)
    missing = [name for name in module.__all__ if not hasattr(module, name)]
    assert missing == []


@pytest.mark.parametrize("package", packages())
def test_no_exported_name_is_also_a_submodule(package):
    # a submodule, once imported, becomes the package's attribute of its name and would hide a
    # lazily exported name (``from impactqp.scenarios import run`` must stay the module)
    module = importlib.import_module(package)
    submodules = {info.name for info in pkgutil.iter_modules(module.__path__)}
    assert sorted(submodules & set(module.__all__)) == []


def test_the_top_level_names_are_few_and_are_all_that_dir_lists():
    assert len(impactqp.__all__) <= 60
    public = {name for name in dir(impactqp) if not name.startswith("__")}
    assert public == {name for name in impactqp.__all__ if not name.startswith("__")}
    assert "__version__" in impactqp.__all__


def test_the_top_level_names_are_the_layers_own():
    assert impactqp.RobotModel is impactqp.controller.model.robot.RobotModel
    assert impactqp.ImpactSession is impactqp.controller.runtime.session.ImpactSession
    assert impactqp.FrameTask is impactqp.tasks.FrameTask
    assert impactqp.PostImpactVelocityLimit is impactqp.constraints.PostImpactVelocityLimit
    assert impactqp.BadInputError is impactqp.controller.model.validation.BadInputError
    assert impactqp.TrialRunner is impactqp.scenarios.trial.TrialRunner


def test_import_impactqp_alone_loads_no_numpy_pinocchio_or_mujoco():
    code = "import sys, impactqp\nprint(sorted(m for m in ('numpy', 'pinocchio', 'mujoco') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("setpriv") is None,
                    reason="needs root and setpriv to run as a user who can write neither the checkout nor a home")
def test_a_user_who_cannot_write_the_install_nor_a_home_runs_the_compiled_kernels():
    """numba caches a kernel beside its source or in the user's cache directory and refuses to
    load it when neither can be written; the package then caches in the temporary directory."""
    cache = Path(tempfile.mkdtemp(prefix="impactqp-cache-test-"))  # not under pytest's folders, which only root enters
    cache.chmod(0o777)
    try:
        _run_as_nobody(cache)
    finally:
        shutil.rmtree(cache, ignore_errors=True)


def _run_as_nobody(cache: Path) -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")} | {"HOME": "/nonexistent", "TMPDIR": str(cache)}
    env.pop("XDG_CACHE_HOME", None)
    script = "from impactqp import RobotModel, JUMP_MODELS; r = RobotModel(); t = r.terms(r.description.postures['elbow_up'].q); print(JUMP_MODELS['gm'].predict(t, [-1, 0, 0], [0.1, 0, 0]).dq_jump[0])"
    done = subprocess.run(
        ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", sys.executable, "-c", script],
        env=env, capture_output=True, text=True, timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert list(cache.glob("impactqp-numba-65534/**/*.nbi"))


def test_only_impactqp_is_importable_outside_the_checkout(tmp_path):
    code = "import impactqp\ntry:\n    import controller\nexcept ModuleNotFoundError:\n    print('absent')\n"
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "absent"


def _strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's strongly connected components of a directed graph (iterative)."""
    index, low, on_stack, stack, components, counter = {}, {}, set(), [], [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = set()
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.add(member)
                        if member == node:
                            break
                    components.append(component)
            elif child not in index:
                index[child] = low[child] = counter[0]
                counter[0] += 1
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(graph[child])))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return components


def test_strongly_connected_components_find_a_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert sorted(map(sorted, _strongly_connected(graph))) == [["a", "b", "c"], ["d"]]


def test_no_import_cycle_between_modules_counting_imports_inside_functions():
    graph = grimp.build_graph("impactqp")  # grimp records imports made inside functions too
    edges = {m: set(graph.find_modules_directly_imported_by(m)) for m in graph.modules}
    cycles = [c for c in _strongly_connected(edges) if len(c) > 1]
    assert cycles == []


def test_tests_do_not_import_benchmark_code():
    offenders = []
    for path in TESTS.glob("test_*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            if any(n.startswith("impactqp.scenarios.bench") for n in names):
                offenders.append(path.name)
    assert offenders == []


def test_every_subpackage_is_installed():
    """Every folder with an __init__.py is a package listed in pyproject.toml (else a wheel drops it)."""
    import tomllib

    root = TESTS.parent
    listed = set(tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {"impactqp"} | {
        "impactqp." + ".".join(init.parent.relative_to(root).parts)
        for init in root.glob("*/**/__init__.py")
        if not {".venv", "tests", "build"} & set(init.parts)
    }
    assert found == listed


def test_the_license_and_the_typing_marker_ship_with_the_package():
    import tomllib

    root = Path(impactqp.__file__).parent
    project = tomllib.loads((root / "pyproject.toml").read_text())
    assert (root / "py.typed").is_file() and "py.typed" in project["tool"]["setuptools"]["package-data"]["impactqp"]
    assert project["project"]["license-files"] == ["LICENSE"]
    assert (root / "LICENSE").read_text().startswith("BSD 3-Clause License")


MAX_PARAMETERS = 8
"""A function takes at most this many parameters (positional and keyword-only, not self or cls,
not *args or **kwargs); past it, a small dataclass."""
MAX_MODULE_LINES = 450
"""A module has at most this many lines; past it, it is split by idea."""
def package_modules() -> list[Path]:
    """Every module of every package pyproject.toml installs."""
    root = TESTS.parent
    return [path for package in packages() for path in sorted(root.joinpath(*package.split(".")[1:]).glob("*.py"))]


def parameters(function: ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda) -> list[str]:
    """The parameters a caller passes: positional and keyword-only, without self or cls."""
    args = function.args
    names = [a.arg for a in (*args.posonlyargs, *args.args, *args.kwonlyargs)]
    return names[1:] if names[:1] in (["self"], ["cls"]) else names


def test_parameters_are_counted_without_self_and_the_catch_alls():
    source = "class C:\n    def f(self, a, /, b, *rest, c, **options): pass\ng = lambda x, y=1: x\n"
    functions = [n for n in ast.walk(ast.parse(source)) if isinstance(n, (ast.FunctionDef, ast.Lambda))]
    assert [parameters(f) for f in functions] == [["a", "b", "c"], ["x", "y"]]


def test_no_function_takes_more_than_eight_parameters():
    over = []
    for path in package_modules():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                where = f"{path.relative_to(TESTS.parent)}:{getattr(node, 'name', 'lambda')}"
                if len(parameters(node)) > MAX_PARAMETERS:
                    over.append(where)
    assert over == []


def test_no_module_is_longer_than_450_lines():
    long = [
        str(path.relative_to(TESTS.parent)) for path in package_modules()
        if len(path.read_text().splitlines()) > MAX_MODULE_LINES
    ]
    assert sorted(long) == []
