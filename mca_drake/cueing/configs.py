"""The MCA configurations as one union, and the shorthand names of their defaults.

Every motion cueing algorithm is chosen and configured by its typed dataclass: `DpcConfig`,
`NmpcConfig` or `WashoutConfig`. A scenario's `mca` field is their union, so YAML picks one
by its tag and sets any of its fields (`mca: !NmpcConfig {mode: rti, washout_weight: 0.3}`).
The names `dpc`, `nmpc-rti`, `nmpc-converged` and `washout` are shorthands for the default
config of each (`--mca nmpc-rti`), and name an MCA in summaries and reports; the NMPC's
names take `-perceived` for its perceived objective (`nmpc-rti-perceived`) and
`-predictive` for a forecast of the reference as its preview (`nmpc-rti-predictive`,
`mca_drake.cueing.predictor`); `dpc-predictive` runs the shipped predictive policy on that
forecast. Any name takes a
shipped profile's suffix for that profile's settings (`washout-ground`, `nmpc-rti-ground`,
`dpc-ground`; `mca_drake.cueing.profiles`).
"""

import dataclasses
from pathlib import Path
from typing import Union

from mca_drake.cueing.dpc import DpcConfig
from mca_drake.cueing.nmpc_config import NmpcConfig
from mca_drake.cueing.profiles import (
    PROFILES,
    load_platform_settings,
    profile_config,
    split_profile,
)
from mca_drake.cueing.washout import WashoutConfig

# typing.Union, not `|`: Drake's YAML loader reads the members' tags from it.
McaConfig = Union[DpcConfig, NmpcConfig, WashoutConfig]  # noqa: UP007
MCA_CONFIG_TYPES = (DpcConfig, NmpcConfig, WashoutConfig)
# The forecast of the named predictive NMPCs (`nmpc-rti-predictive`): the packaged learned
# one, which forecasts the validation flights and drives best (benchmarks/bench_predictor.py)
# and cued the suite's flights better than the linear one (decision 0033).
NAMED_PREDICTOR = "learned"
MCA_NAMES = (
    "dpc",
    "nmpc-rti",
    "nmpc-converged",
    "washout",
    "nmpc-rti-perceived",
    "nmpc-converged-perceived",
    "nmpc-rti-predictive",
    "nmpc-converged-predictive",
    "dpc-predictive",
)


def mca_config_from_name(name: str, platform: str = "") -> McaConfig:
    """The default config of the MCA called `name` (one of MCA_NAMES), or its shipped
    profile's config where the name ends in one ("washout-ground": `cueing.profiles`). On
    the packaged platform named `platform` ("": none) that ships tuned settings
    (`profiles.load_platform_settings`), the NMPC's and the washout's defaults are those.

    Raises:
        ValueError: an unknown name; the message lists the valid ones.
    """
    base, profile = split_profile(name)
    tuned = load_platform_settings(platform) if not profile else None
    if tuned is not None and base in MCA_NAMES and not base.startswith("dpc"):
        default = mca_config_from_name(base)
        if isinstance(default, NmpcConfig):
            return dataclasses.replace(
                tuned.nmpc,
                mode=default.mode,
                objective=default.objective,
                preview_steps=default.preview_steps,
                predictor=default.predictor,
            )
        return tuned.washout
    if profile:
        if base not in MCA_NAMES:
            raise ValueError(
                f"unknown MCA '{name}'; valid: {', '.join(MCA_NAMES)}, each with a profile "
                f"suffix ({', '.join(f'-{p}' for p in PROFILES)})"
            )
        default = mca_config_from_name(base)
        config = profile_config(type(default), profile)
        if isinstance(config, DpcConfig):  # the profile's predictive policy for a predictor
            config = dataclasses.replace(config, predictor=default.predictor)
        if isinstance(config, NmpcConfig):
            config = dataclasses.replace(
                config,
                mode=default.mode,
                objective=default.objective,
                preview_steps=default.preview_steps,
                predictor=default.predictor,
            )
        return config
    if name == "dpc":
        return DpcConfig()
    if name == "dpc-predictive":  # the shipped predictive policy on the packaged forecast
        return DpcConfig(predictor=NAMED_PREDICTOR)
    if name in MCA_NAMES and name.startswith("nmpc-"):
        mode, _, variant = name.removeprefix("nmpc-").partition("-")
        if variant == "predictive":  # the packaged forecast over the whole horizon
            horizon = NmpcConfig().horizon_steps
            return NmpcConfig(mode=mode, preview_steps=horizon, predictor=NAMED_PREDICTOR)
        return NmpcConfig(mode=mode, objective=variant or "inertial")
    if name == "washout":
        return WashoutConfig()
    raise ValueError(f"unknown MCA '{name}'; valid: {', '.join(MCA_NAMES)}")


def as_mca_config(mca: McaConfig | str, platform: str = "") -> McaConfig:
    """`mca` itself if it is an MCA config, else the default config of that name; on the
    packaged platform named `platform` ("": none), as `on_platform` gives it."""
    if isinstance(mca, str):
        return mca_config_from_name(mca, platform)
    if not isinstance(mca, MCA_CONFIG_TYPES):
        valid = ", ".join(t.__name__ for t in MCA_CONFIG_TYPES)
        raise TypeError(f"an MCA is one of {valid} or a name; got {type(mca).__name__}")
    return on_platform(mca, platform)


def on_platform(config: McaConfig, platform: str) -> McaConfig:
    """`config` for the packaged platform named `platform` ("": none): a config equal to
    the class defaults of its name (what `--mca nmpc-rti` or `mca: nmpc-rti` give) stands
    for that name, and becomes the name's defaults on the platform, its tuned settings
    where it ships them (`profiles.load_platform_settings`); a config with any field set
    otherwise is the user's and is returned as it is."""
    if not platform or load_platform_settings(platform) is None:
        return config
    name = mca_name(config)
    try:
        default = mca_config_from_name(name)
    except ValueError:  # a preview NMPC's name, say: no shorthand stands for it
        return config
    return mca_config_from_name(name, platform) if config == default else config


def mca_name(config: McaConfig) -> str:
    """The name of the MCA that `config` configures (MCA_NAMES): "nmpc-" plus the NMPC's
    mode (and "-perceived" for its perceived objective, "-previewN" for a preview of N
    samples, "-predictive" for a forecast as the preview), "dpc" or "washout", each with
    "-<profile>" for a shipped profile's settings."""
    if not isinstance(config, MCA_CONFIG_TYPES):
        raise TypeError(f"not an MCA config: {type(config).__name__}")
    profile = f"-{config.profile}" if config.profile else ""
    if isinstance(config, NmpcConfig):
        suffix = "-perceived" if config.objective == "perceived" else ""
        if config.predictor:
            suffix += "-predictive" + _predictor_suffix(config)
        elif config.preview_steps:
            suffix += f"-preview{config.preview_steps}"
        return f"nmpc-{config.mode}{suffix}{profile}"
    if isinstance(config, DpcConfig) and config.predictor:
        predictor = config.predictor
        forecast = "" if predictor == NAMED_PREDICTOR else f"-{Path(predictor).stem}"
        return f"dpc-predictive{forecast}{profile}"
    return ("dpc" if isinstance(config, DpcConfig) else "washout") + profile


def _predictor_suffix(config: NmpcConfig) -> str:
    """What a predictive NMPC's name adds to "-predictive" where it is not the named MCA's:
    the predictor if it is not NAMED_PREDICTOR, the forecast's length if it is not the
    whole horizon."""
    predictor = config.predictor
    suffix = "" if predictor == NAMED_PREDICTOR else f"-{Path(predictor).stem}"
    if config.preview_steps != config.horizon_steps:
        suffix += f"{config.preview_steps}"
    return suffix


def mca_config_record(config: McaConfig) -> dict:
    """The full config as a JSON-ready dict tagged with its class: {"type": "NmpcConfig",
    "mode": "rti", ...}; every summary records the config that ran this way."""
    return {"type": type(config).__name__, **dataclasses.asdict(config)}
