"""What the occupant perceives: vestibular models, thresholds and motion sickness.

- `models`: the canal and otolith transfer functions (Telban & Cardullo, Ormsby) and the
  typed `PerceptionConfig`;
- `filters`: their exact discretisation at the control period and `perceive`;
- `sickness`: the subjective-vertical-conflict model (Bos & Bles) and its incidence;
- `scores`: the perceived PI, false cues and sickness of a run (the summary's `perceived`).

Plain numpy and scipy; the torch version for training is `mca_drake.learning.perception`
and the Drake system `mca_drake.systems.vestibular.VestibularModel`.
"""

from mca_drake.perception.filters import DiscreteFilter, discretize, perceive, vestibular_filter
from mca_drake.perception.models import (
    VESTIBULAR_MODELS,
    PerceptionConfig,
    TransferFunction,
    VestibularModelParameters,
)
from mca_drake.perception.scores import PerceivedRun, perceived_run
from mca_drake.perception.sickness import (
    SicknessParameters,
    SicknessResult,
    subjective_vertical_conflict,
)

__all__ = [
    "VESTIBULAR_MODELS",
    "DiscreteFilter",
    "PerceivedRun",
    "PerceptionConfig",
    "SicknessParameters",
    "SicknessResult",
    "TransferFunction",
    "VestibularModelParameters",
    "discretize",
    "perceive",
    "perceived_run",
    "subjective_vertical_conflict",
    "vestibular_filter",
]
