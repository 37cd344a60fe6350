"""The MCA configurations as one union, and the shorthand names of their defaults.

Every motion cueing algorithm is chosen and configured by its typed dataclass: `DpcConfig`,
`NmpcConfig` or `WashoutConfig`. A scenario's `mca` field is their union, so YAML picks one
by its tag and sets any of its fields (`mca: !NmpcConfig {mode: rti, washout_weight: 0.3}`).
The names `dpc`, `nmpc-rti`, `nmpc-converged` and `washout` are shorthands for the default
config of each (`--mca nmpc-rti`), and name an MCA in summaries and reports; the NMPC's
names take `-perceived` for its perceived objective (`nmpc-rti-perceived`).
"""

import dataclasses
from typing import Union

from mca_drake.cueing.dpc import DpcConfig
from mca_drake.cueing.nmpc import NmpcConfig
from mca_drake.cueing.washout import WashoutConfig

# typing.Union, not `|`: Drake's YAML loader reads the members' tags from it.
McaConfig = Union[DpcConfig, NmpcConfig, WashoutConfig]  # noqa: UP007
MCA_CONFIG_TYPES = (DpcConfig, NmpcConfig, WashoutConfig)
MCA_NAMES = (
    "dpc",
    "nmpc-rti",
    "nmpc-converged",
    "washout",
    "nmpc-rti-perceived",
    "nmpc-converged-perceived",
)


def mca_config_from_name(name: str) -> McaConfig:
    """The default config of the MCA called `name` (one of MCA_NAMES).

    Raises:
        ValueError: an unknown name; the message lists the valid ones.
    """
    if name == "dpc":
        return DpcConfig()
    if name in MCA_NAMES and name.startswith("nmpc-"):
        mode, _, objective = name.removeprefix("nmpc-").partition("-")
        return NmpcConfig(mode=mode, objective=objective or "inertial")
    if name == "washout":
        return WashoutConfig()
    raise ValueError(f"unknown MCA '{name}'; valid: {', '.join(MCA_NAMES)}")


def as_mca_config(mca: McaConfig | str) -> McaConfig:
    """`mca` itself if it is an MCA config, else the default config of that name."""
    if isinstance(mca, str):
        return mca_config_from_name(mca)
    if not isinstance(mca, MCA_CONFIG_TYPES):
        valid = ", ".join(t.__name__ for t in MCA_CONFIG_TYPES)
        raise TypeError(f"an MCA is one of {valid} or a name; got {type(mca).__name__}")
    return mca


def mca_name(config: McaConfig) -> str:
    """The name of the MCA that `config` configures (MCA_NAMES): "nmpc-" plus the NMPC's
    mode (and "-perceived" for its perceived objective, "-previewN" for a preview of N
    samples), "dpc" or "washout"."""
    if isinstance(config, NmpcConfig):
        suffix = "-perceived" if config.objective == "perceived" else ""
        if config.preview_steps:
            suffix += f"-preview{config.preview_steps}"
        return f"nmpc-{config.mode}{suffix}"
    if isinstance(config, DpcConfig):
        return "dpc"
    if isinstance(config, WashoutConfig):
        return "washout"
    raise TypeError(f"not an MCA config: {type(config).__name__}")


def mca_config_record(config: McaConfig) -> dict:
    """The full config as a JSON-ready dict tagged with its class: {"type": "NmpcConfig",
    "mode": "rti", ...}; every summary records the config that ran this way."""
    return {"type": type(config).__name__, **dataclasses.asdict(config)}
