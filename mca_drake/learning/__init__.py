"""torch learning: the torch plant, plant-model candidates, the curriculum trainer with
checkpoints, the DPC policy network and its training. See `plant_candidates` for the
registry, `configs` for the training configs (readable without torch).

The names below load their module (and torch) on first use, so that `learning.configs`
can be imported without torch.
"""

from __future__ import annotations

import importlib

# public name -> the module that defines it
_EXPORTS = {
    "CheckpointError": "mca_drake.learning.checkpoint",
    "CurriculumTrainer": "mca_drake.learning.trainer",
    "TrainConfig": "mca_drake.learning.configs",
    "TrainResult": "mca_drake.learning.trainer",
    "make_output_model": "mca_drake.learning.plant_candidates",
    "make_state_model": "mca_drake.learning.plant_candidates",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_EXPORTS[name]), name)
