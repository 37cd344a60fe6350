"""DPC inference: the policy-file format, its reader and the numpy policy (no torch).

A policy file (.npz, no pickle) holds the exported weights of
`mca_drake.learning.policy_network.PolicyNetwork` and a JSON metadata string; for a platform
of n joints: W1 (hidden, 12 + 2n), W2 (3n, hidden), input_scale (12 + 2n), lower, upper (3n)
(the KR500's n = 6: 24 inputs, 18 outputs); a policy with a reference preview (metadata
`preview_steps` > 0) has 24 more inputs, the reference at `preview_offsets`. The metadata's
`platform` names the platform the policy was trained for (`check_policy_platform`).
`PolicyInference` evaluates it in numpy, equal to the torch network (tested to 1e-6): the
same scaled inputs, two bias-free layers with the exact (erf) GELU between, and the
saturation to the limits.
"""

import dataclasses
import functools
import math
from pathlib import Path

import numpy as np
from scipy.special import erf

from mca_drake.atomic_io import load_npz_with_metadata
from mca_drake.conventions import NUM_CHANNELS
from mca_drake.cueing.predictor import check_predictor
from mca_drake.cueing.recognition import (
    HANDBACK_REASONS,
    RECOGNITION_REASONS,
    RECOGNIZED_POLICIES,
)
from mca_drake.cueing.reference_range import (
    ReferenceRange,
    policy_reference_range,
    run_outside,
)
from mca_drake.references.driving.car import CARS
from mca_drake.references.synthetic import VEHICLE_ENVELOPES
from mca_drake.resources import (
    MOVED_POLICIES,
    PLATFORMS_WITH_OWN_POLICY,
    PLATFORMS_WITH_POLICIES,
    SHIPPED_POLICIES,
    check_profile,
    data_dir,
)

_SQRT_HALF = np.sqrt(0.5)

POLICY_FORMAT = "mca-drake-policy-1"
# The arrays of a policy file, in the order `PolicyNetwork.export` writes them.
POLICY_ARRAYS = ("W1", "W2", "input_scale", "lower", "upper")
# A policy with a reference preview of N control periods (its file's `preview_steps`) also
# reads the reference at this many instants spread evenly over the next N periods
# (`preview_offsets`): 6 more inputs each.
PREVIEW_POINTS = 4


def preview_offsets(preview_steps: int) -> np.ndarray:
    """The samples ahead a policy with a preview of `preview_steps` periods reads, shape
    (PREVIEW_POINTS,): N i / PREVIEW_POINTS rounded, i = 1..PREVIEW_POINTS (at least 1)."""
    points = np.arange(1, PREVIEW_POINTS + 1)
    return np.maximum(np.rint(preview_steps * points / PREVIEW_POINTS).astype(int), 1)


def input_size(preview_steps: int, joints: int) -> int:
    """The inputs of a policy for a platform of `joints` joints: [y (6), x = [q, qd]
    (2 joints), target (6)], plus 6 per preview instant with a preview."""
    return (
        NUM_CHANNELS
        + 2 * joints
        + NUM_CHANNELS
        + (NUM_CHANNELS * PREVIEW_POINTS if preview_steps else 0)
    )


def output_size(joints: int) -> int:
    """The outputs of a policy for a platform of `joints` joints: [u (joints),
    x_hat = [q, qd] (2 joints)]."""
    return 3 * joints


def policy_joints(arrays: dict[str, np.ndarray]) -> int:
    """The joint count of a policy's arrays (a third of its outputs)."""
    return arrays["W2"].shape[0] // 3


# The platform a policy file that names none was trained for: every shipped policy's.
UNNAMED_POLICY_PLATFORM = "kr500"


def policy_platform_record(metadata: dict) -> dict:
    """A policy file's record of the platform it was trained for (`SerialChain.summary`:
    name, kind, dof, joints); {"name": UNNAMED_POLICY_PLATFORM} where it names none."""
    record = metadata.get("platform", {"name": UNNAMED_POLICY_PLATFORM})
    if not isinstance(record, dict) or not isinstance(record.get("name"), str):
        raise ValueError(f"policy platform must be a record with a name; got {record!r}")
    dof = record.get("dof")
    if dof is not None and (isinstance(dof, bool) or not isinstance(dof, int) or dof < 1):
        raise ValueError(f"policy platform dof must be a whole number >= 1; got {dof!r}")
    return record


def policy_platform(metadata: dict) -> str:
    """The name of the platform a policy file was trained for (its metadata's
    `platform.name`; UNNAMED_POLICY_PLATFORM where it names none)."""
    return policy_platform_record(metadata)["name"]


def check_policy_platform(path, metadata: dict, platform_name: str) -> None:
    """Raises ValueError, naming both, unless the policy file at `path` (its `metadata`) was
    trained for the platform `platform_name`: its joints, limits and kinematics are the ones
    the policy learned to command."""
    trained = policy_platform(metadata)
    if trained != platform_name:
        raise ValueError(
            f"policy {path} was trained for platform '{trained}', not for '{platform_name}': "
            f"a policy commands the joints of the platform it was trained on"
        )


def policy_preview_steps(metadata: dict) -> int:
    """A policy file's reference preview, control periods (0: causal), from its metadata;
    ValueError for a value that is not a whole number >= 0."""
    value = metadata.get("preview_steps", 0)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"policy preview_steps must be a whole number >= 0; got {value!r}")
    return value


@dataclasses.dataclass
class DpcConfig:
    """The DPC motion-cueing algorithm: which trained policy runs (paper eq. 11).

    In YAML: `mca: !DpcConfig {policy: results/policy/policy.npz}`.
    """

    # Policy file (`mca-drake train-policy`); empty: the policy shipped with the package for
    # `profile`.
    policy: str = ""
    # The shipped profile (`mca_drake.cueing.profiles`: "ground" for cars) whose policy runs
    # when `policy` is empty, and which names the MCA ("dpc-ground"); "": the flight default.
    profile: str = ""
    # The vehicle cued, as `FlightSpec.vehicle` or a recording's header names it. With
    # `policy` and `profile` empty the shipped policy of its flight envelope runs, or for a
    # car the ground policy (`vehicle_policy_name`); "" or a vehicle outside the fleet: the
    # default policy. `run_closed_loop` fills it from the reference's `vehicle`, the live
    # loop from its protocol's kind ("car" for the racing simulators) when it is empty.
    vehicle: str = ""
    # What runs when nothing names the policy, the profile or the vehicle (a recording of
    # X-Plane or a logger, a flight simulator's stream): "recognize", the shipped policy of
    # the vehicle recognized from the reference as it goes (`cueing.recognition`: a
    # transport, a light aircraft, a car, else the default policy), handed over smoothly;
    # "default", the default policy throughout.
    unnamed: str = "recognize"
    # When the network reads the reference clipped, channel by channel, into the range of
    # the references its policy was trained on (`reference_range`; a policy without a range
    # reads it as it is): "unnamed" where the policy is recognized (`recognizes`: a
    # recording or stream that may be any vehicle), "always", or "never". A network beyond
    # its training extrapolates: a car's 0.5 g of lateral force made the flight policy
    # throw the cabin before the car was recognized; clipped, it reads the strongest
    # lateral force it knows (decision 0025).
    range_clip: str = "unnamed"
    # The forecast of the reference a policy with a preview reads (`cueing.predictor`:
    # "linear", "learned" or a model file), for live use, where nobody knows the future;
    # "": a preview policy reads the recorded future. With `policy` and `profile` empty it
    # runs the shipped predictive policy (`PREDICTIVE_POLICY`), trained on that forecast:
    # `dpc-predictive`.
    predictor: str = ""
    # A policy file that stands for the shipped default policy wherever that would run: a
    # reference the recognizer recognizes nothing in, a vehicle outside every envelope, or
    # `unnamed` "default". Empty: the shipped one. For trying a retrained default inside the
    # DPC that recognizes the others (the transports', the light aircraft's, the ground's),
    # as its selection does (`benchmarks/bench_selection.py`); not with a `predictor`, whose
    # policies are the shipped predictive twins.
    default_policy: str = ""
    # A vehicle named of the light or transport envelope runs its envelope's policy while
    # the reference stays inside that envelope's bounds (the recognizer's,
    # `cueing.recognition`) and hands back to the default policy for good once it leaves
    # them (smoothly, as a recognized policy does): a hand-flown light aircraft pulled
    # beyond what its policy was trained on is cued better by the default, trained on every
    # aircraft (decision 0039). False: the envelope's policy throughout.
    envelope_handback: bool = True

    def validate(self) -> None:
        """Raises ValueError for an unknown profile or `unnamed`, FileNotFoundError when the
        policy file does not exist."""
        check_profile(self.profile)
        check_predictor(self.predictor)
        if self.unnamed not in UNNAMED_CHOICES:
            raise ValueError(
                f"DpcConfig.unnamed must be one of {', '.join(UNNAMED_CHOICES)}; got "
                f"{self.unnamed!r}"
            )
        if not isinstance(self.envelope_handback, bool):
            raise ValueError(
                f"DpcConfig.envelope_handback must be true or false; got {self.envelope_handback!r}"
            )
        if self.range_clip not in RANGE_CLIP_CHOICES:
            raise ValueError(
                f"DpcConfig.range_clip must be one of {', '.join(RANGE_CLIP_CHOICES)}; got "
                f"{self.range_clip!r}"
            )
        if self.policy and not Path(self.policy).is_file():
            raise FileNotFoundError(f"DpcConfig.policy: policy file {self.policy!r} not found")
        if self.default_policy:
            if self.predictor:
                raise ValueError(
                    "DpcConfig.default_policy replaces a causal policy; a predictor runs the "
                    "shipped predictive twins: give one or the other"
                )
            if not Path(self.default_policy).is_file():
                raise FileNotFoundError(
                    f"DpcConfig.default_policy: policy file {self.default_policy!r} not found"
                )
        if self.profile and not self.policy:
            # the profile's shipped policy: ValueError or FileNotFoundError
            self.policy_path(UNNAMED_POLICY_PLATFORM)

    def policy_path(self, platform: str) -> Path:
        """The policy file this config runs on the platform named `platform`: `policy`, or
        the shipped one of `profile`, or the shipped one for `vehicle`'s envelope, each the
        KR500's or, on another packaged platform, its own (`PLATFORMS_WITH_POLICIES`).

        Raises:
            FileNotFoundError: no policy is shipped for the platform (the message gives the
                commands that make one), or the install lacks the file.
        """
        if self.policy:
            return Path(self.policy)
        if self.predictor:
            return predictive_policy_path(platform, predictive_policy_name(self))
        if self.profile:
            name = f"{check_profile(self.profile)}_policy"
        else:
            name = vehicle_policy_name(self.vehicle)
        return self._policy_file(platform, name)

    def _policy_file(self, platform: str, name: str) -> Path:
        """The shipped policy `name` on `platform`, or `default_policy` in the default's
        place."""
        if name == "default_policy" and self.default_policy:
            return Path(self.default_policy)
        return _platform_policy_path(platform, name)

    def cues_ground(self) -> bool:
        """Whether the config is the ground profile's or names a car (`GROUND_VEHICLES`)."""
        return self.profile == "ground" or self.vehicle in GROUND_VEHICLES

    def recognizes(self) -> bool:
        """Whether the policy is recognized from the reference: nothing names the policy, the
        profile or the vehicle, and `unnamed` is "recognize"."""
        named = self.policy or self.profile or self.vehicle or self.predictor
        return not named and self.unnamed == "recognize"

    def hands_back(self) -> bool:
        """Whether the vehicle is named, of an envelope with its own policy (light,
        transport), nothing else names the policy, and `envelope_handback` hands that
        policy back to the default when the reference leaves the envelope."""
        named = self.policy or self.profile or self.predictor
        envelope_policy = vehicle_policy_name(self.vehicle) in ENVELOPE_POLICIES.values()
        return bool(self.vehicle) and envelope_policy and not named and self.envelope_handback

    def first_policy(self) -> int:
        """The index in `recognition.RECOGNIZED_POLICIES` of the policy a DPC with
        `recognized_policy_paths` starts in: the named vehicle's envelope policy where it
        `hands_back`, else the default."""
        if self.hands_back():
            return RECOGNIZED_POLICIES.index(vehicle_policy_name(self.vehicle))
        return 0

    def clips_reference(self) -> bool:
        """Whether the network reads the reference clipped into its policy's training range
        (`range_clip`)."""
        return self.range_clip == "always" or (self.range_clip == "unnamed" and self.recognizes())

    def recognized_policy_paths(self, platform: str) -> tuple[Path, ...] | None:
        """The shipped policies the recognizer chooses between on the platform named
        `platform`, in the order of `cueing.recognition.RECOGNIZED_POLICIES` (the default
        first), where it `recognizes` the vehicle or a named one `hands_back` to another
        file; else None (one policy runs throughout)."""
        if not (self.recognizes() or self.hands_back()):
            return None
        paths = tuple(self._policy_file(platform, name) for name in RECOGNIZED_POLICIES)
        if not self.recognizes() and paths[self.first_policy()] == paths[0]:
            return None  # a platform whose default stands for the envelope's: nothing to hand
        return paths


# The shipped policies of `dpc-predictive` (a DpcConfig with a predictor and no policy), one
# for each causal policy the DPC picks by vehicle: the default, the light aircraft's and the
# transports' (`ENVELOPE_POLICIES`) and, for a car or the ground profile, the ground's; each
# that policy widened to read a preview and fine-tuned reading the packaged learned forecast
# (docs/guides/training.md, "the predictive policies").
PREDICTIVE_POLICY = "predictive_policy"
# Each causal policy the DPC picks (`vehicle_policy_name`) and its predictive twin.
PREDICTIVE_TWINS = {
    "default_policy": PREDICTIVE_POLICY,
    "light_policy": "light_predictive_policy",
    "transport_policy": "transport_predictive_policy",
    "ground_policy": "ground_predictive_policy",
}


def predictive_policy_name(config: "DpcConfig") -> str:
    """The predictive twin of the shipped policy `dpc` would run for `config`'s vehicle or
    profile: the ground's for a car or the ground profile, that of its flight envelope where
    it has one, else the default's."""
    causal = "ground_policy" if config.cues_ground() else vehicle_policy_name(config.vehicle)
    return PREDICTIVE_TWINS[causal]


def predictive_policy_path(platform: str, name: str = PREDICTIVE_POLICY) -> Path:
    """The shipped predictive policy `name` (`predictive_policy_name`) on the platform named
    `platform`; FileNotFoundError, with the commands that make one, on a platform that
    ships none (only the KR500 does)."""
    if platform != UNNAMED_POLICY_PLATFORM:
        raise FileNotFoundError(
            f"no predictive policy is shipped for platform '{platform}': train one with "
            "`mca-drake train-policy --preview-steps 256 --preview-predictor learned "
            f"--time-stretch-fraction 0 --platform {platform}` and pass it as --policy with "
            "the predictor"
        )
    return shipped_policy_path(name)


def _platform_policy_path(platform: str, name: str) -> Path:
    """The shipped policy that stands for the KR500's `name` on `platform`."""
    if platform == UNNAMED_POLICY_PLATFORM:
        return default_policy_path() if name == "default_policy" else shipped_policy_path(name)
    return shipped_policy_path(platform_policy_name(platform, name))


# "recognize": the policy of the vehicle recognized from the reference; "default": the
# default policy (`DpcConfig.unnamed`).
UNNAMED_CHOICES = ("recognize", "default")
# DpcConfig.range_clip: clip the reference into the policy's training range where the policy
# is recognized, always, or never.
RANGE_CLIP_CHOICES = ("unnamed", "always", "never")


def platform_policy_name(platform: str, name: str) -> str:
    """The shipped policy that stands for the KR500's policy `name` (`MOVED_POLICIES`) on the
    packaged platform `platform` (`PLATFORMS_WITH_POLICIES`): "<platform>_<name>", the
    KR500's moved onto its joints (`mca-drake transfer-policy`), chosen as the KR500's are.
    Moved, they cued validation flights better than the KR500 default fine-tuned on a
    dataset made on the platform (docs/concepts/platforms.md; decision 0022). A platform
    whose joints no KR500 policy shares ships policies trained on it
    (`PLATFORMS_WITH_OWN_POLICY`): "<platform>_<name>" where it ships that one, else its
    "<platform>_default_policy", which stands for every other name.
    FileNotFoundError, with the commands that make one, for a platform that ships none."""
    if name not in MOVED_POLICIES:
        raise ValueError(f"'{name}' is not one of the policies platforms carry: {MOVED_POLICIES}")
    if platform in PLATFORMS_WITH_OWN_POLICY:
        own = PLATFORMS_WITH_OWN_POLICY[platform]
        return f"{platform}_{name if name in own else 'default_policy'}"
    if platform not in PLATFORMS_WITH_POLICIES:
        raise FileNotFoundError(
            f"no policy is shipped for platform '{platform}': move the KR500's onto it with "
            f"`mca-drake transfer-policy mca_drake/data/default_policy.npz --platform "
            f"{platform}` (its joints named as the KR500's) or train one with `mca-drake "
            f"dataset closed-loop --platform {platform}` and `mca-drake train-policy "
            f"--platform {platform}`, then pass it as --policy (DpcConfig.policy)"
        )
    return f"{platform}_{name}"


def vehicle_policy_name(vehicle: str) -> str:
    """The shipped policy for `vehicle`: "ground_policy" for a car (`GROUND_VEHICLES`), that
    of a fleet aircraft's flight envelope in `ENVELOPE_POLICIES`, else "default_policy"
    (also for "" and names outside the fleet)."""
    return _vehicle_policy(vehicle)[0]


def _vehicle_policy(vehicle: str) -> tuple[str, str]:
    """(the shipped policy for `vehicle`, why, in words)."""
    if not vehicle:
        return "default_policy", "no vehicle named: the default policy"
    if vehicle in GROUND_VEHICLES:
        return "ground_policy", f"vehicle {vehicle!r} is a car: the ground policy"
    envelope = VEHICLE_ENVELOPES.get(vehicle, "")
    if envelope in ENVELOPE_POLICIES:
        return ENVELOPE_POLICIES[envelope], f"vehicle {vehicle!r}: the {envelope} envelope's"
    if envelope:
        return "default_policy", f"vehicle {vehicle!r}: the {envelope} envelope flies the default"
    return "default_policy", f"vehicle {vehicle!r} is not in the fleet: the default policy"


def policy_choice(config: DpcConfig, platform: str) -> tuple[Path, str]:
    """The policy file `config` runs on `platform` (`DpcConfig.policy_path`) and why, in
    words, for a summary: given as a file, a profile's, the vehicle's, or the default
    because nothing named the vehicle."""
    path = config.policy_path(platform)
    if config.policy:
        return path, "given as DpcConfig.policy"
    if config.predictor:
        if config.cues_ground():
            why = "a car or the ground profile: the ground policy"
        else:
            why = _vehicle_policy(config.vehicle)[1]
        return path, f"{why} (its predictive twin, reading the {config.predictor} forecast)"
    if config.profile:
        return path, f"the {config.profile} profile's"
    return path, _vehicle_policy(config.vehicle)[1]


def policy_record(
    config: DpcConfig, platform: str, changes=(), reference=None, time_step: float = 0.0
) -> dict:
    """A run's record of its policy, for its summary: `policy_file` (the name of the file
    that ran last) and `policy_reason` (why, `policy_choice`); for a policy recognized from
    the reference also `policy_changes`, one {t_s, policy_file, reason} per change of
    policy (`changes`: (time s, index in `recognition.RECOGNIZED_POLICIES`) each, from the
    DPC system's `policy_changes`). Given the run's `reference` (T, 6, one row per control
    period of `time_step` s) also `out_of_distribution`: the share of the periods in which
    it lay outside the range of the references the running policy was trained on, in all
    and per channel (`reference_range.run_outside`); None for a policy without a range."""
    paths = config.recognized_policy_paths(platform)
    if paths is None:
        path, why = policy_choice(config, platform)
        record = {"policy_file": path.name, "policy_reason": why}
        segments = [(0.0, path)]
    else:
        first = config.first_policy()
        last = changes[-1][1] if changes else first
        if config.hands_back():
            reasons = {first: _vehicle_policy(config.vehicle)[1], 0: HANDBACK_REASONS[first]}
        else:
            reasons = dict(enumerate(RECOGNITION_REASONS))
        record = {
            "policy_file": paths[last].name,
            "policy_reason": reasons[last],
            "policy_changes": [
                {"t_s": round(t, 6), "policy_file": paths[i].name, "reason": reasons[i]}
                for t, i in changes
            ],
        }
        segments = [(0.0, paths[first]), *((t, paths[i]) for t, i in changes)]
    if reference is not None:
        ranges = [(t, _policy_range(str(path))) for t, path in segments]
        record["out_of_distribution"] = run_outside(np.asarray(reference), ranges, time_step)
    return record


@functools.lru_cache(maxsize=32)
def _policy_range(path: str) -> ReferenceRange | None:
    """The reference range of the policy file at `path` (`policy_reference_range`)."""
    return policy_reference_range(path, load_policy_arrays(path)[1])


def for_vehicle(config, vehicle: str):
    """`config` for cueing `vehicle`: a DpcConfig without a vehicle gets it (and with it the
    policy of its envelope, when neither `policy` nor `profile` is set); any other config,
    or one that names its vehicle already, is returned as it is."""
    if isinstance(config, DpcConfig) and not config.vehicle and vehicle:
        return dataclasses.replace(config, vehicle=vehicle)
    return config


# The shipped policy for the aircraft of a flight envelope (`VEHICLE_ENVELOPES`): one
# policy trained on every training flight balances the fighters' and trainers' large,
# fast manoeuvres against the light aircraft's small forces, which the default fine-tuned on
# the light aircraft's flights alone renders better (docs/decisions/0016-flight-policies-by-
# envelope.md, 0040). The transports fly the recipe's step 2 fine-tuned on the wide-body's
# flights, its slow forces weighed twice the NMPC's, which renders every transport's
# validation flights better than the default (decisions 0020, 0038, 0040). The aerobatic
# trainers and the fighters fly the default policy.
ENVELOPE_POLICIES = {"light": "light_policy", "transport": "transport_policy"}
# Vehicles cued by the ground policy: the cars `mca-drake drive` drives (their names are in
# its recordings' headers) and "car", what a racing simulator's stream or a recording of a
# car of no known model says.
GROUND_VEHICLES = frozenset({*CARS, "car"})


def default_policy_path() -> Path:
    """The policy shipped with the package (mca_drake/data/default_policy.npz); raises
    FileNotFoundError with the command that makes one if it is missing."""
    try:
        return shipped_policy_path("default_policy")
    except FileNotFoundError:
        raise FileNotFoundError(
            f"no default policy at {data_dir() / 'default_policy.npz'}; train one with "
            "`mca-drake train-policy` and pass --policy, or reinstall the package"
        ) from None


def shipped_policy_path(name: str) -> Path:
    """A policy file shipped with the package: "default_policy" (the default DPC policy),
    "policy_v6" (the paper reproduction: five c172p flights, the paper's loss),
    "ground_policy" (the ground profile's, trained on drives) or "light_policy" (the light
    aircraft's, `ENVELOPE_POLICIES`).

    Raises:
        ValueError: `name` is not a shipped policy (the message lists them).
        FileNotFoundError: the file is missing from the install.
    """
    if name not in SHIPPED_POLICIES:
        raise ValueError(f"unknown shipped policy '{name}'; valid: {', '.join(SHIPPED_POLICIES)}")
    path = data_dir() / f"{name}.npz"
    if not path.is_file():
        raise FileNotFoundError(f"no shipped policy '{name}' at {path}; reinstall mca-drake")
    return path


# Largest inflated policy file accepted, bytes (the shipped ones hold about 60 kB).
POLICY_MAX_BYTES = 16 * 2**20


def load_policy_arrays(path) -> tuple[dict[str, np.ndarray], dict]:
    """(arrays, metadata) of a policy file; ValueError with the reason if it is not one or
    its arrays do not fit together, FileNotFoundError if it is missing."""
    path = Path(path)
    # a policy is tens of kilobytes: anything near a megabyte is not one
    stored, metadata = load_npz_with_metadata(
        path, "policy", names=frozenset(POLICY_ARRAYS), max_bytes=POLICY_MAX_BYTES
    )
    missing = [k for k in POLICY_ARRAYS if k not in stored]
    if missing:
        raise ValueError(f"{path} is not a policy file: arrays {missing} are missing")
    unknown = sorted(set(stored) - set(POLICY_ARRAYS))
    if unknown:
        # a newer format's part (a filter, say) left out would run the network wrongly
        raise ValueError(f"{path}: arrays {unknown} are not part of {POLICY_FORMAT}")
    raw = {k: stored[k] for k in POLICY_ARRAYS}
    not_real = [k for k, v in raw.items() if v.dtype.kind not in "fiu"]
    if not_real:
        raise ValueError(f"{path}: arrays {not_real} are not real numbers")
    arrays = {k: v.astype(float) for k, v in raw.items()}
    if metadata.get("format") != POLICY_FORMAT:
        raise ValueError(f"{path}: unknown policy format {metadata.get('format')!r}")
    if arrays["W1"].ndim != 2 or arrays["W2"].ndim != 2 or arrays["W2"].shape[0] % 3:
        raise ValueError(
            f"{path}: W1 {arrays['W1'].shape} and W2 {arrays['W2'].shape} are not the layers "
            "of a policy (W2 has 3 rows per joint)"
        )
    hidden, joints = arrays["W1"].shape[0], policy_joints(arrays)
    named = policy_platform_record(metadata).get("dof", joints)
    if named != joints:
        raise ValueError(f"{path}: the policy has {joints} joints, its platform record {named}")
    inputs = input_size(policy_preview_steps(metadata), joints)
    expected = {
        "W1": (hidden, inputs),
        "W2": (output_size(joints), hidden),
        "input_scale": (inputs,),
        "lower": (output_size(joints),),
        "upper": (output_size(joints),),
    }
    for name, shape in expected.items():
        if arrays[name].shape != shape:
            raise ValueError(f"{path}: array {name} has shape {arrays[name].shape}, not {shape}")
        if not np.all(np.isfinite(arrays[name])):
            raise ValueError(f"{path}: array {name} holds NaN or inf")
    if np.any(arrays["lower"] > arrays["upper"]) or np.any(arrays["input_scale"] <= 0):
        raise ValueError(f"{path}: bounds or input scales are inconsistent")
    return arrays, metadata


class PolicyInference:
    """u, x_hat = policy(y, x, target) in numpy from the arrays of a policy file.

    Args:
        arrays: W1 (hidden, 12 + 2n), W2 (3n, hidden), input_scale (12 + 2n), lower, upper
            (3n) for a platform of n joints, as written by
            `mca_drake.learning.policy_network.save_policy` (see `load_policy_arrays`).
        reference_range: where given, the target (and each preview sample) is clipped,
            channel by channel, into this range of the policy's training references before
            the network reads it (`DpcConfig.range_clip`); None: read as it is.
    """

    def __init__(
        self, arrays: dict[str, np.ndarray], reference_range: ReferenceRange | None = None
    ):
        # Fold the input scaling and GELU's 1/sqrt(2) into the first layer and GELU's
        # 1/2 and sqrt(2) into the second: with b = W1 v / sqrt(2),
        # W2 gelu(W1 v) = W2 (1/2) sqrt(2) b (1 + erf(b)) = (W2 / sqrt(2)) (b + b erf(b)):
        # two fewer vector operations per step (the DPC's step budget is 25 us).
        self._W1 = np.ascontiguousarray(arrays["W1"] / arrays["input_scale"][None, :] * _SQRT_HALF)
        self._W2 = np.ascontiguousarray(arrays["W2"] * _SQRT_HALF)
        self._lower, self._upper = arrays["lower"].copy(), arrays["upper"].copy()
        self.joints = n = policy_joints(arrays)
        # u's rows and bounds alone, for `command`
        self._W2_u = np.ascontiguousarray(self._W2[:n])
        self._u_bounds = list(zip(self._lower[:n].tolist(), self._upper[:n].tolist(), strict=True))
        self.reference_range = reference_range
        self._low = self._high = None
        if reference_range is not None:
            self._low, self._high = np.array(reference_range.low), np.array(reference_range.high)

    def _features(self, y, x, target, preview) -> np.ndarray:
        """The network's input: y, x, the target and the preview, the last two clipped into
        the reference range where there is one (NaN passes the clip: `command` sees it)."""
        if self._low is not None:
            target = np.minimum(np.maximum(target, self._low), self._high)
            if len(preview):
                rows = np.reshape(preview, (-1, 6))
                preview = np.minimum(np.maximum(rows, self._low), self._high).reshape(-1)
        return np.concatenate((y, x, target, preview))

    def __call__(self, y, x, target, preview=()) -> tuple[np.ndarray, np.ndarray]:
        """(u (n), x_hat (2n)) for y (6), x (2n), target (6) and, for a policy with a
        preview, the reference at its `preview_offsets` (24); 1-D numpy arrays."""
        # A new feature vector per call (0.1 us), not a buffer on self: one inference object
        # may serve several contexts at once.
        b = self._W1 @ self._features(y, x, target, preview)
        z = np.minimum(np.maximum(self._W2 @ (b + b * erf(b)), self._lower), self._upper)
        return z[: self.joints], z[self.joints :]

    def command(self, y, x, target, preview=()) -> list[float]:
        """u alone, as `__call__` computes it, in n Python floats: the live loop's step
        (fewer numpy calls, and none to bound u). NaN in all where an input is not finite
        (their sum is not: one call instead of a check per input) or the network overflows,
        which the bounds would otherwise hide."""
        features = self._features(y, x, target, preview)
        if not math.isfinite(features.sum()):
            return [math.nan] * self.joints
        b = self._W1 @ features
        raw = (self._W2_u @ (b + b * erf(b))).tolist()
        if not all(map(math.isfinite, raw)):
            return [math.nan] * self.joints
        return [min(max(v, low), high) for v, (low, high) in zip(raw, self._u_bounds, strict=True)]
