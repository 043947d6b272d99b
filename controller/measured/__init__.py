"""Measured impact data: the dataset format, its reader and validator, the impact detection,
the jump extraction and an oblique impact's impulse, tangential velocity and mode. Beside the ground; importing it never imports MuJoCo.

Its names are exported lazily (PEP 562), as the ground's: importing one module loads only its
own imports."""

from impactqp.lazy_exports import lazy_exports as _lazy_exports

_EXPORTS = {
    "TrialLog": "trial_log",
    "Dataset": "dataset",
    "DatasetHeader": "dataset",
    "DatasetTrial": "dataset",
    "DatasetWriter": "dataset_writer",
    "DatasetError": "dataset",
    "TrialEntry": "dataset",
    "read_dataset": "dataset",
    "read_header": "dataset",
    "validate": "dataset_check",
    "ImpactMeasurement": "impact",
    "ImpactNotFoundError": "impact",
    "measure_impact": "impact",
    "ObliqueImpact": "oblique_impact",
    "measure_oblique_impact": "oblique_impact",
    "import_franka_logs": "franka_log",
}
_EXPORTS = {name: f"{__name__}.{module}" for name, module in _EXPORTS.items()}

__all__ = list(_EXPORTS)


__getattr__, __dir__ = _lazy_exports(globals(), _EXPORTS)
