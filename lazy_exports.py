"""Lazy exports of a package (PEP 562): a name is imported from its module on first use, so that
importing a package runs none of the modules it exports from."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import import_module


def lazy_exports(namespace: dict, exports: Mapping[str, str]) -> tuple[Callable, Callable]:
    """The package's ``__getattr__`` and ``__dir__``: ``exports`` maps each exported name to the
    module that defines it; a name, once imported, is kept in ``namespace`` (the package's globals).

    ``dir()`` of the package lists its exports and its dunder names (``__version__``...), never
    the helpers its ``__init__`` imports nor the submodules loaded so far."""

    def __getattr__(name: str):
        if name not in exports:
            raise AttributeError(f"module {namespace['__name__']!r} has no attribute {name!r}")
        value = getattr(import_module(exports[name]), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*(name for name in namespace if name.startswith("__")), *exports})

    return __getattr__, __dir__
