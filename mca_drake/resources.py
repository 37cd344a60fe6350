"""The files the package carries: the KR500 model, the scenario files and the policies.

`models/` and `diagrams/` at the top of the source tree are the sources; a wheel carries
copies of them as package data (`mca_drake/data/models`, `mca_drake/data/diagrams`, copied
by setup.py at build time), so an installed package runs from any folder. In a source
checkout (an editable install) the top-level folders themselves are used.
"""

from __future__ import annotations

import importlib.resources
import importlib.util
from pathlib import Path

# The folders a wheel carries, by their name in the source tree.
PACKAGED_FOLDERS = ("models", "diagrams")
# The packaged platforms other than the KR500 that ship policies, and the KR500's policies
# each carries moved onto its joints, as <platform>_<name> (`cueing.dpc.platform_policy_name`).
PLATFORMS_WITH_POLICIES = ("kr500-rail", "fanuc-m900ib700")
MOVED_POLICIES = ("default_policy", "light_policy", "transport_policy", "ground_policy")
# The packaged platforms whose joints no KR500 policy shares (a legged platform's pose
# coordinates) that ship policies trained on them, <platform>_<name>, by the KR500's policy
# names they ship (`MOVED_POLICIES`); the first, <platform>_default_policy, stands for every
# other one of the KR500's there (`cueing.dpc.platform_policy_name`).
PLATFORMS_WITH_OWN_POLICY = {
    "hexapod": ("default_policy", "ground_policy"),
    "rig-2dof": ("default_policy",),
    "rig-3dof": ("default_policy",),
}
# Policy files shipped with the package (mca_drake/data/<name>.npz).
SHIPPED_POLICIES = (
    "default_policy",
    "policy_v6",
    "ground_policy",
    "light_policy",
    "transport_policy",
    "predictive_policy",
    "ground_predictive_policy",
    "light_predictive_policy",
    "transport_predictive_policy",
    *(f"{platform}_{name}" for platform in PLATFORMS_WITH_POLICIES for name in MOVED_POLICIES),
    *(
        f"{platform}_{name}"
        for platform, names in PLATFORMS_WITH_OWN_POLICY.items()
        for name in names
    ),
)
# MCA profiles shipped for vehicle motion other than flight (`mca_drake.cueing.profiles`): the
# NMPC's and washout's settings in data/profiles/<name>.yaml, the DPC's policy
# <name>_policy; "" stands for the flight defaults.
PROFILES = ("ground",)


def split_profile(name: str) -> tuple[str, str]:
    """(MCA name, profile) of an MCA name that may end in a profile: "washout-ground" ->
    ("washout", "ground"); "nmpc-rti" -> ("nmpc-rti", "")."""
    for profile in PROFILES:
        if name.endswith(f"-{profile}"):
            return name.removesuffix(f"-{profile}"), profile
    return name, ""


def check_profile(profile: str) -> str:
    """`profile` if it is "" (the flight defaults) or a shipped profile, else ValueError."""
    if profile and profile not in PROFILES:
        raise ValueError(f"unknown MCA profile '{profile}'; valid: {', '.join(PROFILES)}")
    return profile


def drake_installed() -> bool:
    """Whether pydrake can be imported here. Where it cannot (a GPU machine that only
    trains), `mca-drake` offers its torch commands alone and the robot's URDF is read
    without Drake (`mca_drake.platforms.urdf_chain`)."""
    return importlib.util.find_spec("pydrake") is not None


def data_dir() -> Path:
    """The package's data folder (mca_drake/data): shipped policies, and in an installed
    package the copies of models/ and diagrams/."""
    return Path(str(importlib.resources.files("mca_drake") / "data"))


def packaged_folder(name: str) -> Path:
    """The folder `name` ("models" or "diagrams"): the wheel's copy, else the checkout's.

    Raises:
        ValueError: `name` is not one of `PACKAGED_FOLDERS`.
        FileNotFoundError: neither copy exists (a broken install).
    """
    if name not in PACKAGED_FOLDERS:
        raise ValueError(f"unknown packaged folder '{name}'; valid: {', '.join(PACKAGED_FOLDERS)}")
    packaged = data_dir() / name
    if packaged.is_dir():
        return packaged
    checkout = Path(__file__).resolve().parent.parent / name
    if checkout.is_dir():
        return checkout
    raise FileNotFoundError(
        f"the package's {name}/ folder is missing (looked in {packaged} and {checkout}); "
        "reinstall mca-drake from its wheel or a source checkout"
    )


def packaged_scenarios() -> dict[str, Path]:
    """The scenario files the package carries, by name (file name without `.yaml`)."""
    return {p.stem: p for p in sorted(packaged_folder("diagrams").glob("*.yaml"))}


def scenario_path(name_or_path: str | Path) -> Path:
    """A scenario file given by its path or by its packaged name.

    Args:
        name_or_path: an existing YAML file, or the name of a packaged scenario with or
            without `.yaml` ("closed_loop_dpc", "diagrams/live_rsi.yaml" from any folder).

    Raises:
        FileNotFoundError: no such file and no packaged scenario of that name; the message
            lists the packaged names.
    """
    path = Path(name_or_path)
    if path.is_file():
        return path
    if path.exists() and not path.is_dir():
        raise FileNotFoundError(f"scenario {path} is not a regular file (a FIFO or a device?)")
    packaged = packaged_scenarios()
    stem = path.name.removesuffix(".yaml")
    # A bare name, or diagrams/NAME.yaml typed from outside a checkout.
    if stem in packaged and (path.parent == Path(".") or path.parent.name == "diagrams"):
        return packaged[stem]
    if path.is_dir():
        raise FileNotFoundError(f"scenario {path} is a directory, not a YAML file")
    raise FileNotFoundError(
        f"scenario file not found: {path}; packaged scenarios: {', '.join(packaged)}"
    )
