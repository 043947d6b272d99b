"""Smoke test of an installed ``impactqp``: the commands a user runs first, from the installed
console script, with the package data the wheel must carry (the built-in robot descriptions,
``controller/model/robots/*.toml``, and plants, ``sim/plants/*.json``).

Run it with the Python of the environment the wheel was installed in, from a directory outside
the repository: ``ENV/bin/python tests/wheel_smoke.py``. The release workflow
(``.github/workflows/release.yml``) and ``tests/test_wheel.py`` both run it. It fails (exit code 1,
one line saying why) when ``impactqp`` is not imported from that environment (the checkout or an
editable install instead), or when a command fails.
"""

from __future__ import annotations

import json
import subprocess
import sys
from importlib import metadata
from pathlib import Path

COMMANDS = (
    ["postures", "--robot", "ur5", "--json"],
    ["predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.15", "--json"],
    ["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "identified_panda", "--json"],
)
"""The smoke commands: every built-in description is read by ``postures``; ``predict`` is the
first command of the README; ``simulate`` runs one short impact in MuJoCo on a built-in plant."""


def installed_here() -> str:
    """Where ``impactqp`` is imported from; an error when that is not this environment."""
    import impactqp

    where = Path(impactqp.__file__).resolve()
    if Path(sys.prefix).resolve() not in where.parents:
        raise SystemExit(f"wheel smoke: impactqp is imported from {where}, not from the environment {sys.prefix}")
    editable = sorted(name for name in sys.modules if "__editable__" in name)
    if editable:
        raise SystemExit(f"wheel smoke: an editable install is loaded ({', '.join(editable)})")
    return str(where.parent)


def main() -> int:
    package = installed_here()
    script = Path(sys.executable).parent / "impactqp"
    version = subprocess.run([script, "--version"], capture_output=True, text=True, check=False)
    if version.stdout.split()[-1:] != [metadata.version("impactqp")]:
        raise SystemExit(f"wheel smoke: impactqp --version printed {version.stdout!r} {version.stderr!r}")
    for command in COMMANDS:
        out = subprocess.run([script, *command], capture_output=True, text=True, check=False)
        if out.returncode != 0:
            raise SystemExit(f"wheel smoke: impactqp {' '.join(command)} ended with {out.returncode}: {out.stderr.strip()}")
        json.loads(out.stdout)
        print(f"ok: impactqp {' '.join(command)}")
    print(f"impactqp {metadata.version('impactqp')} from {package}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
