"""The motion cueing algorithms as plain numpy math, each with its typed config.

- `nmpc_config`: NmpcConfig, the NMPC's settings (no Drake needed).
- `nmpc`: the NMPC optimal control problem (Drake MathematicalProgram).
- `washout`: WashoutConfig and the classical washout filters.
- `dpc`: DpcConfig, the policy-file reader and numpy inference of the DPC policy.
- `configs`: the union of the three configs (`McaConfig`) and their shorthand names.
- `optimal`: the offline-optimal bound (whole recording, perfect preview) and its config.
- `shooting`: the double integrator over a multiple-shooting program's intervals.

The Drake systems that run them in a diagram are in `mca_drake.systems`.
"""

from mca_drake.cueing.configs import (
    MCA_NAMES,
    McaConfig,
    as_mca_config,
    mca_config_from_name,
    mca_config_record,
    mca_name,
    on_platform,
)
from mca_drake.cueing.dpc import DpcConfig
from mca_drake.cueing.nmpc_config import NmpcConfig
from mca_drake.cueing.washout import WashoutConfig

__all__ = [
    "MCA_NAMES",
    "DpcConfig",
    "McaConfig",
    "NmpcConfig",
    "WashoutConfig",
    "as_mca_config",
    "mca_config_from_name",
    "mca_config_record",
    "mca_name",
    "on_platform",
]
