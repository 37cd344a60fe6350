"""The evaluation suite's cases and settings, and the files of its runs.

`EvaluationCase` is a set of flights or drives (the paper's cases A and B, and C to E);
`EvaluationConfig` the MCAs, cases, flight length, bound and platform of a suite. Each run
is one JSON file (`run_path`); `finished_run` and `finished_bound` find the runs on disk
that a resumed suite keeps: made with the same MCA config, duration, policy and platform.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

from mca_drake.atomic_io import (
    file_sha256,
)
from mca_drake.conventions import FIRST_EVALUATION_SEED
from mca_drake.cueing import (
    DpcConfig,
    McaConfig,
    as_mca_config,
    mca_config_from_name,
    mca_config_record,
    mca_name,
)
from mca_drake.cueing.dpc import for_vehicle
from mca_drake.cueing.optimal import OptimalConfig
from mca_drake.cueing.recognition import RecognitionConfig
from mca_drake.input_checks import MAX_DURATION_S, check_range
from mca_drake.platforms.files import DEFAULT_PLATFORM, PlatformField, load_platform, packaged_name
from mca_drake.references.drives import DriveSpec
from mca_drake.references.flights import FlightSpec
from mca_drake.references.jsbsim import UNSEEN_VEHICLES

# The MCAs a suite compares by default (DPC is tested against each other one).
DEFAULT_MCAS = ("dpc", "nmpc-converged", "nmpc-rti", "washout", "nmpc-rti-perceived")


@dataclasses.dataclass
class EvaluationCase:
    """A set of flights, or of drives: of one vehicle, or of several (`vehicles`, dealt to
    the seeds in turn: seed i flies vehicles[i % len(vehicles)]). With `manoeuvres` the
    case drives cars (`references.drives`): seed i drives manoeuvres[i % n] in the car
    vehicles[i % len(vehicles)]."""

    # Label in the report ("A", "B", "C").
    name: str
    # The vehicle (`mca_drake.references.jsbsim.VEHICLES`, or a car of
    # `references.driving.CARS` for drives) when `vehicles` is empty.
    vehicle: str
    # Flight seeds: evaluation flights, from FIRST_EVALUATION_SEED on.
    seeds: tuple[int, ...]
    # Several vehicles, dealt to the seeds in turn.
    vehicles: tuple[str, ...] = ()
    # Who flies the flights (`references.flights.PILOTS`).
    pilot: str = "scripted"
    # Drives instead of flights: the manoeuvres (`references.driving.MANOEUVRES`), dealt
    # to the seeds in turn.
    manoeuvres: tuple[str, ...] = ()

    def vehicle_of(self, seed: int) -> str:
        """The vehicle that flight `seed` of this case flies."""
        if not self.vehicles:
            return self.vehicle
        return self.vehicles[self.seeds.index(seed) % len(self.vehicles)]

    def spec_of(self, seed: int) -> FlightSpec | DriveSpec:
        """The flight, or the drive, of seed `seed` of this case."""
        vehicle = self.vehicle_of(seed)
        if self.manoeuvres:
            manoeuvre = self.manoeuvres[self.seeds.index(seed) % len(self.manoeuvres)]
            return DriveSpec(manoeuvre=manoeuvre, seed=seed, car=vehicle)
        return FlightSpec(vehicle=vehicle, seed=seed, pilot=self.pilot)

    def label(self) -> str:
        """The case's vehicles for the report: "light", or "t6texan2, T38, ...", and who
        flies them where it is not the scripted pilot (or what the cars drive)."""
        vehicles = ", ".join(self.vehicles) if self.vehicles else self.vehicle
        if self.manoeuvres:
            return f"{vehicles} ({', '.join(self.manoeuvres)} drives)"
        return vehicles if self.pilot == "scripted" else f"{vehicles} ({self.pilot} pilot)"


# The name of the bound's run files and report entries.
BOUND = "optimal"


# Case D's cars and drives: the three cars, each driving proving-ground roads and laps.
DRIVE_CARS = ("bmw-320i", "ford-escort", "vw-vanagon")
DRIVE_MANOEUVRES = ("proving-ground", "lap")
# Case E's aircraft: those of cases A to C, flown by the route pilot.
ROUTE_VEHICLES = ("light", "jet", *UNSEEN_VEHICLES)


def default_cases() -> tuple[EvaluationCase, ...]:
    """The paper's two cases, 10 light-aircraft and 10 jet flights unseen in training;
    case C: 10 flights of aircraft neither trained nor tuned on; case D: 10 drives of
    three cars over proving-ground roads and laps (`references.driving`); case E: 10 flights of
    cases A to C's aircraft flown by the route pilot, a pilot no training, tuning or
    recipe choice ever saw (`references.jsbsim.route`)."""
    return (
        EvaluationCase("A", "light", tuple(range(1000, 1010))),
        EvaluationCase("B", "jet", tuple(range(2000, 2010))),
        EvaluationCase("C", "", tuple(range(3000, 3010)), vehicles=UNSEEN_VEHICLES),
        EvaluationCase(
            "D", "", tuple(range(4000, 4010)), vehicles=DRIVE_CARS, manoeuvres=DRIVE_MANOEUVRES
        ),
        EvaluationCase("E", "", tuple(range(5000, 5010)), vehicles=ROUTE_VEHICLES, pilot="route"),
    )


@dataclasses.dataclass
class EvaluationConfig:
    """What to evaluate; defaults: the paper's scenario set, 5 minutes per flight."""

    # The MCAs compared, as typed configs (names stand for their default configs); each is
    # labelled in the report by its name (`mca_drake.cueing.mca_name`), so no two may share
    # one.
    mcas: tuple[McaConfig, ...] = dataclasses.field(
        default_factory=lambda: tuple(mca_config_from_name(n) for n in DEFAULT_MCAS)
    )
    cases: tuple[EvaluationCase, ...] = dataclasses.field(default_factory=default_cases)
    # Simulated seconds per flight.
    duration_s: float = 300.0
    # The offline-optimal bound's settings: each flight's bound is solved too
    # (`mca_drake.simulation.optimal_bound`) and every MCA's share of the achievable
    # improvement reported; None: no bound.
    bound: OptimalConfig | None = None
    # The motion platform every run cues on: a packaged name (its tuned settings are the
    # defaults of the MCAs named), a platform file or a description.
    platform: PlatformField = DEFAULT_PLATFORM

    def __post_init__(self) -> None:
        self.mcas = tuple(as_mca_config(m, packaged_name(self.platform)) for m in self.mcas)

    def validate(self) -> None:
        """Raises ValueError for no or two MCAs of one name, training seeds, no flight or a
        bad duration."""
        if not self.mcas:
            raise ValueError("mcas is empty: nothing to evaluate")
        name = load_platform(self.platform).name  # ValueError or FileNotFoundError
        for mca in self.mcas:
            if isinstance(mca, DpcConfig):
                mca.policy_path(name)  # a platform without a policy: the command that trains one
        if not any(case.seeds for case in self.cases):
            raise ValueError("no flight to evaluate: every case is empty")
        check_range(
            "EvaluationConfig", "duration_s", self.duration_s, 0.0, MAX_DURATION_S, low_open=True
        )
        for case in self.cases:
            if any(not FIRST_EVALUATION_SEED <= s < 2**32 for s in case.seeds):
                raise ValueError(
                    f"case {case.name}: flight seeds must be evaluation seeds, in "
                    f"[{FIRST_EVALUATION_SEED}, 2^32): lower ones are for training and tuning"
                )
            if len(set(case.seeds)) != len(case.seeds):
                raise ValueError(f"case {case.name}: a flight seed repeats")
            for seed in case.seeds[: max(len(case.vehicles), len(case.manoeuvres), 1)]:
                case.spec_of(seed).validate()
        if self.bound is not None:
            self.bound.validate()
        names = self.names()
        if len(set(names)) != len(names):
            raise ValueError(f"two MCAs share a name in {names}; compare distinct MCAs")

    def names(self) -> list[str]:
        """The report's label of every MCA, in order."""
        return [mca_name(m) for m in self.mcas]


def run_path(out: Path, case: str, mca: str, seed: int) -> Path:
    return out / "runs" / f"{case}_{mca}_{seed}.json"


def policy_fingerprint(config, platform: str) -> str:
    """SHA-256 of a DpcConfig's policy file on the platform named `platform` (recorded in
    every DPC run so that a resumed evaluation never mixes runs of two policies); for a DPC
    that recognizes the vehicle, those of the policies it chooses between
    (`DpcConfig.recognized_policy_paths`) and of the recognizer's settings, joined by "+";
    "+clip" appended where the network reads the reference clipped into its range
    (`DpcConfig.clips_reference`); "" for other MCAs."""
    if not isinstance(config, DpcConfig):
        return ""
    recognized = config.recognized_policy_paths(platform)
    # a clipped reference changes the commands: a run of either kind is not the other's
    clip = "+clip" if config.clips_reference() else ""
    if recognized is None:
        return file_sha256(config.policy_path(platform)) + clip
    settings = json.dumps(dataclasses.asdict(RecognitionConfig()), sort_keys=True)
    return (
        "+".join(
            [
                *(file_sha256(path) for path in recognized),
                hashlib.sha256(settings.encode()).hexdigest(),
            ]
        )
        + clip
    )


def run_platform(summary: dict) -> str:
    """The name of the platform a run's summary ran on (a run that names none: the KR500)."""
    record = summary.get("platform", {})
    return record.get("name", DEFAULT_PLATFORM) if isinstance(record, dict) else ""


def finished_run(
    out: Path, case: EvaluationCase, config: McaConfig, seed: int, duration_s: float, platform: str
) -> dict | None:
    """The summary of a finished run of (case, MCA, seed) on disk, or None: not there,
    unreadable, not a JSON object, or made with another MCA config, duration or DPC policy
    (then it is run again and overwritten)."""
    path = run_path(out, case.name, mca_name(config), seed)
    if not path.is_file():
        return None
    config = for_vehicle(config, case.vehicle_of(seed))  # as `run_closed_loop` records it
    try:
        summary = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(summary, dict):  # valid JSON but no summary (a list, a number): redo
        return None
    same = (
        "perceived" in summary  # every figure of the report, perceived ones included
        and same_config(summary.get("mca_config"), config)
        and summary.get("duration_s") == duration_s
        and summary.get("policy_sha256", "") == policy_fingerprint(config, platform)
        and run_platform(summary) == platform
    )
    return summary if same else None


def same_config(recorded, config: McaConfig) -> bool:
    """Whether a run file's `mca_config` record is that of `config`. A field the record
    lacks (the run is older than the field) counts as the field's default: the run was made
    with the behaviour the default stands for, so a config at that default matches it."""
    if not isinstance(recorded, dict):
        return False
    current = mca_config_record(config)
    defaults = mca_config_record(type(config)())
    missing = current.keys() - recorded.keys()
    if recorded.keys() - current.keys():
        return False  # a field this code no longer has: another config
    return all(recorded[k] == current[k] for k in recorded) and all(
        current[k] == defaults[k] for k in missing
    )


def finished_bound(
    out: Path, case: str, config: OptimalConfig, seed: int, duration_s: float, platform: str
):
    """The summary of a finished bound of (case, seed) on disk made with `config` and
    `duration_s` on the platform named `platform`, or None (then it is solved again)."""
    path = run_path(out, case, BOUND, seed)
    try:
        summary = json.loads(path.read_text()) if path.is_file() else None
    except (OSError, ValueError):
        return None
    record = {"type": "OptimalConfig", **dataclasses.asdict(config)}
    if not isinstance(summary, dict) or summary.get("mca_config") != record:
        return None
    if run_platform(summary) != platform:
        return None
    return summary if summary.get("duration_s") == duration_s else None
