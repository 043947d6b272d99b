"""``pip install impactqp``: the wheel and the sdist carry every file a run opens, and the wheel
installed in a fresh virtual environment runs the smoke commands (``tests/wheel_smoke.py``) from
outside the repository; the release workflow builds both artefacts and runs the same smoke test;
the changelog's version is the project's.

Offline: the wheel is built without build isolation, and the fresh environment sees the
dependencies already installed beside the tests (a ``.pth`` file naming their site directories),
never the editable install of the checkout.
"""

from __future__ import annotations

import os
import re
import shutil
import site
import subprocess
import sys
import tarfile
import tomllib
import zipfile
from pathlib import Path

import yaml

ROOT = Path(__file__).parent.parent
SMOKE = ROOT / "tests" / "wheel_smoke.py"
WORKFLOW = ROOT / ".github" / "workflows" / "release.yml"
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
SOURCE_IGNORED = shutil.ignore_patterns(
    ".git", ".venv", "venv", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache", ".hypothesis", "out", "runs"
)


def data_files() -> set[str]:
    """The files a run opens, as the wheel names them: the built-in robot descriptions and plants."""
    found = [*ROOT.glob("controller/model/robots/*.toml"), *ROOT.glob("sim/plants/*.json"), ROOT / "py.typed"]
    return {"impactqp/" + path.relative_to(ROOT).as_posix() for path in found}


def build_wheel(source: Path, out: Path) -> Path:
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q", "-w", str(out),
         str(source)],
        check=True, capture_output=True, text=True,
    )
    (wheel,) = out.glob("impactqp-*.whl")
    return wheel


def build_sdist(source: Path, out: Path) -> Path:
    """The sdist, by the build backend itself (in a subprocess: it works in the source directory)."""
    code = "import sys, setuptools.build_meta as b; print(b.build_sdist(sys.argv[1]))"
    name = subprocess.run([sys.executable, "-c", code, str(out)], cwd=source, check=True, capture_output=True,
                          text=True).stdout.split()[-1]
    return out / name


def wheel_names(wheel: Path) -> set[str]:
    with zipfile.ZipFile(wheel) as archive:
        return set(archive.namelist())


def dependency_lines() -> list[str]:
    """The lines of a ``.pth`` file that make this interpreter's installed dependencies importable:
    each site directory, then the import lines of its ``.pth`` files (the cmeel packages, such as
    Pinocchio, find their modules through one), leaving out the editable install of ``impactqp``
    and any path to a checkout."""
    lines = []
    for directory in map(Path, site.getsitepackages()):
        lines.append(str(directory))
        for pth in sorted(directory.glob("*.pth")):
            if "__editable__" in pth.name or "impactqp" in pth.name:
                continue
            for line in pth.read_text(encoding="utf-8").splitlines():
                if line.startswith("import ") and "impactqp" not in line:
                    lines.append(line)
    return lines


def fresh_environment(where: Path) -> Path:
    """A virtual environment without pip, whose site directory also reads the dependencies; its
    Python."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(where)], check=True, capture_output=True)
    python = where / "bin" / "python"
    purelib = subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                             check=True, capture_output=True, text=True).stdout.strip()
    (Path(purelib) / "impactqp_test_dependencies.pth").write_text("\n".join(dependency_lines()) + "\n")
    return python


def clean_environment() -> dict[str, str]:
    """os.environ without what would put the checkout on the path."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP")}


def test_the_wheel_installs_in_a_fresh_environment_and_runs(tmp_path):
    source = tmp_path / "source"  # a copy: building writes build/ and *.egg-info beside the sources
    shutil.copytree(ROOT, source, ignore=SOURCE_IGNORED, symlinks=True)
    wheel = build_wheel(source, tmp_path / "wheel")
    names = wheel_names(wheel)
    assert data_files() <= names, sorted(data_files() - names)
    assert not any(name.startswith(("impactqp/docs/", "impactqp/tests/", "docs/", "tests/")) for name in names)

    sdist = build_sdist(source, tmp_path / "sdist")
    with tarfile.open(sdist) as archive:
        members = {name.split("/", 1)[1] for name in archive.getnames() if "/" in name}
        archive.extractall(tmp_path / "unpacked", filter="data")
    assert {name.removeprefix("impactqp/") for name in data_files()} <= members
    (unpacked,) = (tmp_path / "unpacked").iterdir()
    assert data_files() <= wheel_names(build_wheel(unpacked, tmp_path / "wheel_from_sdist"))

    python = fresh_environment(tmp_path / "env")
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "--no-index", "-q",
                    str(wheel)], check=True, capture_output=True, text=True)
    away = tmp_path / "elsewhere"  # outside the repository: no impactqp/ below the working directory
    away.mkdir()
    out = subprocess.run([python, str(SMOKE)], cwd=away, env=clean_environment(), capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    assert f"from {tmp_path / 'env'}" in out.stdout


def test_the_smoke_script_refuses_the_checkout(tmp_path):
    """Run with the checkout on the path, the smoke test fails: it checks where impactqp came from."""
    out = subprocess.run([sys.executable, str(SMOKE)], cwd=tmp_path, capture_output=True, text=True,
                         env={**clean_environment(), "PYTHONPATH": os.environ.get("PYTHONPATH", "")})
    assert out.returncode == 1 and "wheel smoke:" in out.stderr, out.stdout + out.stderr


def test_the_release_workflow_builds_both_artefacts_smoke_tests_and_publishes():
    workflow = yaml.safe_load(WORKFLOW.read_text(encoding="utf-8"))
    trigger = workflow.get("on", workflow.get(True))  # YAML 1.1 reads a bare `on` as true
    assert trigger["push"]["tags"] == ["v*"]
    steps = [step for job in workflow["jobs"].values() for step in job["steps"]]
    runs = "\n".join(step.get("run", "") for step in steps)
    assert re.search(r"python -m build --sdist --wheel\b", runs)
    assert "tests/wheel_smoke.py" in runs and "pip install dist/*.whl" in runs
    publish = [job for job in workflow["jobs"].values()
               if any(step.get("uses", "").startswith("pypa/gh-action-pypi-publish@") for step in job["steps"])]
    assert len(publish) == 1 and publish[0]["permissions"]["id-token"] == "write"  # trusted publishing
    smoke = [name for name, job in workflow["jobs"].items() if "tests/wheel_smoke.py" in str(job["steps"])]
    needs = publish[0]["needs"]
    assert set(smoke) <= set([needs] if isinstance(needs, str) else needs)


def test_the_changelog_s_latest_release_is_the_project_s_version():
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    releases = re.findall(r"^## \[(\d+\.\d+\.\d+)\] - \d{4}-\d{2}-\d{2}$", changelog, re.MULTILINE)
    assert releases and releases[0] == PROJECT["version"]
    assert "Keep a Changelog" in changelog
