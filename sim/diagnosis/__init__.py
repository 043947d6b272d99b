"""Diagnose the gap between measured impacts and the simulation: replay, compare, fit causes.

The steps of ``diagnose`` (``pipeline``), one module each:

1. **Measure** and 2. **Replay** (``trials``): the valid trials of the dataset, their impacts
   measured like simulated ones, each replayed in the simulation from its logged state with its
   logged commands.
3. **Compare** (``comparison``): errors (25)-(26) of the nominal simulation per joint, posture
   and speed, and of the classical, GM and CRB predictors.
4. **Extend** (``fitting``): candidate causes (``sim.causes``) fitted by bounded least squares
   over the replays.
5. **Select the causes** (``search``, on the cross-validation of ``selection``): a bounded
   search over sets of causes (paths from the best first steps, screened forward steps,
   refinements, backward removals) on the held-out normalised residual over trials.
6. **Bound the parameters** (``intervals``): profile-likelihood and bootstrap 95 % intervals,
   open sides and the trials that would settle them.
7. **One timing** (``timing``): the causes are named only when the final model's replays line up
   with every trial at one shift, up to the replay's own timing (a homogeneity test).

The result and its report (``result``): ``Diagnosis.summary()`` is the JSON of
``impactqp diagnose --json``. Method and JSON keys: ``docs/diagnosis.md``.
"""

from .pipeline import diagnose
from .result import Diagnosis, interval_text
from .selection import EXPLAINED_GAIN, STEP_GAIN
from .trials import ReplaySetting, load_trials, replay_all

__all__ = [
    "EXPLAINED_GAIN", "STEP_GAIN", "Diagnosis", "ReplaySetting", "diagnose", "interval_text", "load_trials", "replay_all",
]
