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
"""

import dataclasses
from pathlib import Path

from mca_drake.cueing.dpc import DpcConfig
from mca_drake.cueing.nmpc import NmpcConfig
from mca_drake.cueing.washout import WashoutConfig
from mca_drake.resources import PROFILES, check_profile, data_dir, split_profile

__all__ = ["PROFILES", "ProfileSettings", "load_profile", "profile_config", "split_profile"]


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
    """The NMPC and washout settings of a shipped profile, each labelled with it."""
    from pydrake.common.yaml import yaml_load_typed  # the YAML loader the scenarios use

    settings = yaml_load_typed(schema=ProfileSettings, filename=str(profile_path(profile)))
    settings.nmpc.profile = profile
    settings.washout.profile = profile
    settings.nmpc.validate()
    settings.washout.validate()
    return settings


def profile_config(kind: type, profile: str):
    """The config of MCA class `kind` (DpcConfig, NmpcConfig or WashoutConfig) with the
    settings of `profile`: what a scenario's `!WashoutConfig {profile: ground, ...}` starts
    from before its own fields."""
    if kind is DpcConfig:
        return DpcConfig(profile=check_profile(profile))
    settings = load_profile(profile)
    return settings.nmpc if kind is NmpcConfig else settings.washout
