"""Feasibility maps: the highest feasible contact speed over a grid of contact points and settings.

Its names are exported lazily (PEP 562): importing the configuration loads neither Ray nor
Parquet."""

from impactqp.lazy_exports import lazy_exports as _lazy_exports

_EXPORTS = {
    "SweepConfig": "config",
    "load_config": "config",
    "parse_config": "config",
    "Simulation": "cells",
    "evaluate_cells": "cells",
    "SweepSummary": "backends",
    "run_sweep": "backends",
    "read_table": "store",
    "write_plots": "plots",
}
_EXPORTS = {name: f"{__name__}.{module}" for name, module in _EXPORTS.items()}

__all__ = list(_EXPORTS)


__getattr__, __dir__ = _lazy_exports(globals(), _EXPORTS)
