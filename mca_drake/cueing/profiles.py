"""Profiles: MCA settings shipped for a kind of vehicle motion other than flight.

The MCAs' defaults are tuned (NMPC, washout) and trained (DPC) on flights. A profile holds
another set for one context: "ground" for cars, with the NMPC's weights and the washout's
filters tuned on training drives (`mca-drake tune` with cars for vehicles) and a DPC policy
trained on drives. It is named by the MCA's name with the profile's appended
(`nmpc-rti-ground`, `nmpc-converged-ground`, `washout-ground`, `dpc-ground`) wherever an MCA
name goes: `--mca`, a scenario's `mca`, the suite's `--mcas`. The config it gives carries the
profile in its `profile` field, so summaries and reports name it.

The NMPC's and the washout's settings are in `mca_drake/data/profiles/<profile>.yaml` (with
the tune that produced them); the DPC's policy is the shipped policy `<profile>_policy`
(`mca_drake.resources.SHIPPED_POLICIES`).

A packaged motion platform other than the KR500 may ship its own tuned settings in the same
format, `mca_drake/data/platforms/<platform>.yaml` (`load_platform_settings`): they are the
defaults of the NMPC and the washout on that platform (`mca_config_from_name(name,
platform)`), as the class defaults are the KR500's.
"""

import dataclasses
from pathlib import Path

import yaml

from mca_drake.cueing.dpc import DpcConfig
from mca_drake.cueing.nmpc_config import NmpcConfig
from mca_drake.cueing.washout import WashoutConfig
from mca_drake.resources import PROFILES, check_profile, data_dir, split_profile

__all__ = [
    "PROFILES",
    "ProfileSettings",
    "load_platform_settings",
    "load_profile",
    "profile_config",
    "split_profile",
]


@dataclasses.dataclass
class ProfileSettings:
    """One profile file: the NMPC's settings (its mode and objective are set by the name
    that asks for it) and the washout's."""

    nmpc: NmpcConfig = dataclasses.field(default_factory=NmpcConfig)
    washout: WashoutConfig = dataclasses.field(default_factory=WashoutConfig)


def profile_path(profile: str) -> Path:
    """The settings file of a shipped profile (FileNotFoundError if the install lacks it)."""
    path = data_dir() / "profiles" / f"{check_profile(profile)}.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"no settings for profile '{profile}' at {path}; reinstall")
    return path


def load_profile(profile: str) -> ProfileSettings:
    """The NMPC and washout settings of a shipped profile, each labelled with it.

    Read with PyYAML's safe loader (no Drake needed: the torch training path uses a
    profile's NMPC objective); every key must be a field of its config and every value of
    that field's type, or ValueError names the file and the key.
    """
    settings = read_settings(profile_path(profile))
    settings.nmpc.profile = profile
    settings.washout.profile = profile
    settings.nmpc.validate()
    settings.washout.validate()
    return settings


def platform_settings_path(platform: str) -> Path:
    """Where the tuned settings of the packaged platform `platform` are shipped (the file
    need not exist: most platforms run the KR500's defaults until tuned)."""
    return data_dir() / "platforms" / f"{platform}.yaml"


def load_platform_settings(platform: str) -> ProfileSettings | None:
    """The tuned NMPC and washout settings shipped for the platform named `platform`
    (`mca-drake tune --platform P`), or None where none are shipped (the class defaults,
    tuned on the KR500, apply). ValueError names the file and the key of a bad file."""
    path = platform_settings_path(platform) if platform else None
    if path is None or not path.is_file():
        return None
    settings = read_settings(path)
    settings.nmpc.validate()
    settings.washout.validate()
    return settings


def read_settings(path: Path) -> ProfileSettings:
    """A settings file (sections `nmpc` and `washout`, each a mapping of its config's
    fields; a missing section: the class defaults), read with PyYAML's safe loader."""
    with open(path, encoding="utf-8") as f:
        document = yaml.safe_load(f) or {}
    if not isinstance(document, dict) or not set(document) <= {"nmpc", "washout"}:
        raise ValueError(f"{path}: want a mapping with the sections nmpc and washout")
    return ProfileSettings(
        nmpc=_typed_config(NmpcConfig, document.get("nmpc"), f"{path}: nmpc"),
        washout=_typed_config(WashoutConfig, document.get("washout"), f"{path}: washout"),
    )


def _typed_config(kind: type, fields, where: str):
    """`kind()` with `fields` (a mapping from the YAML file) set, each checked against the
    default's type: numbers for floats (ints accepted, bools not), lists of numbers for
    lists."""
    if fields is None:
        return kind()
    if not isinstance(fields, dict):
        raise ValueError(f"{where}: want a mapping of {kind.__name__} fields")
    default = kind()
    names = {f.name for f in dataclasses.fields(kind)}
    values = {}
    for key, value in fields.items():
        if key not in names:
            raise ValueError(f"{where}: {key!r} is not a {kind.__name__} field")
        values[key] = _checked_value(getattr(default, key), value, f"{where}.{key}")
    return dataclasses.replace(default, **values)


def _is_number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _checked_value(default, value, where: str):
    if isinstance(default, float) and _is_number(value):
        return float(value)
    if isinstance(default, list | tuple) and isinstance(value, list):
        if all(_is_number(v) for v in value):
            return type(default)(float(v) for v in value)
    elif type(value) is type(default):
        return value
    raise ValueError(f"{where}: {value!r} is not a {type(default).__name__} like {default!r}")


def profile_config(kind: type, profile: str):
    """The config of MCA class `kind` (DpcConfig, NmpcConfig or WashoutConfig) with the
    settings of `profile`: what a scenario's `!WashoutConfig {profile: ground, ...}` starts
    from before its own fields."""
    if kind is DpcConfig:
        return DpcConfig(profile=check_profile(profile))
    settings = load_profile(profile)
    return settings.nmpc if kind is NmpcConfig else settings.washout
