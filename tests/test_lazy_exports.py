import subprocess
import sys

import pytest

from impactqp.lazy_exports import lazy_exports


def test_a_name_is_imported_on_first_use_and_kept():
    namespace = {"__name__": "pkg"}
    getattr_, dir_ = lazy_exports(namespace, {"hypot": "math", "sqrt": "math"})
    assert dir_() == ["__name__", "hypot", "sqrt"]
    import math

    assert getattr_("hypot") is math.hypot
    assert namespace["hypot"] is math.hypot  # the next look-up is an ordinary global
    with pytest.raises(AttributeError, match="module 'pkg' has no attribute 'cos'"):
        getattr_("cos")


def test_dir_lists_the_exports_and_the_dunders_only():
    namespace = {"__name__": "pkg", "__version__": "1", "_helper": None, "submodule": None}
    _, dir_ = lazy_exports(namespace, {"hypot": "math"})
    assert dir_() == ["__name__", "__version__", "hypot"]


def test_importing_the_packages_imports_none_of_their_exports():
    code = (
        "import sys, impactqp, impactqp.controller\n"
        "print([m for m in ('numpy', 'impactqp.controller.qp', 'impactqp.controller.model.robot') if m in sys.modules])\n"
        "impactqp.ControllerConfig\n"
        "print('impactqp.controller.config' in sys.modules, 'ControllerConfig' in vars(impactqp))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "[]" and out[1] == "True True"
