"""The car motion a run cues: a built-in drive (`references.driving`), named like a flight.

`DriveSpec` names a drive (a scenario's `flight` field takes one where it takes a
`FlightSpec`); `drive_recording` turns it into a `Recording`. `motion_recording` and
`motion_reference` (the motion-cueing `Reference`) take either spec, so that scenarios and
studies take drives as they take flights.

Training and tuning name their references as (vehicle, seed) pairs; a vehicle that is a car
(`references.driving.CARS`) drives instead of flying: `training_spec` turns a pair into a
`FlightSpec` or a `DriveSpec`, the drive's manoeuvre dealt from the seed
(`TRAINING_MANOEUVRES`).
"""

import dataclasses
from pathlib import Path

from mca_drake.conventions import FIRST_EVALUATION_SEED
from mca_drake.references.driving.car import CARS, check_car
from mca_drake.references.driving.courses import MANOEUVRES
from mca_drake.references.driving.drive import DEFAULT_HEAD_OFFSET_M, drive
from mca_drake.references.driving.road import ROAD_CLASSES
from mca_drake.references.flights import FlightSpec, cued_vehicle, flight_recording
from mca_drake.references.jsbsim import check_training_vehicle
from mca_drake.references.recording import Recording, load_recording, save_recording
from mca_drake.references.reference import Reference, ReferenceScaling, reference_from_recording


@dataclasses.dataclass
class DriveSpec:
    """A built-in drive: a car through a manoeuvre on a road, drawn from a seed."""

    # The manoeuvre (`references.driving.MANOEUVRES`).
    manoeuvre: str = "lap"
    # Seed of the manoeuvre's settings, the driver's pace and the road.
    seed: int = 1000
    # The car (`references.driving.CARS`).
    car: str = "bmw-320i"
    # ISO 8608 road class A-H; empty: a smooth road.
    road_class: str = "B"
    # The driver's head from the car's centre of gravity, m (forward, left, up).
    head_offset_m: list[float] = dataclasses.field(
        default_factory=lambda: list(DEFAULT_HEAD_OFFSET_M)
    )

    def validate(self) -> None:
        """Raises ValueError for an unknown manoeuvre, car or road, or a bad seed or offset."""
        if self.manoeuvre not in MANOEUVRES:
            raise ValueError(
                f"unknown drive manoeuvre '{self.manoeuvre}'; valid: {', '.join(MANOEUVRES)}"
            )
        check_car(self.car)
        if self.road_class and self.road_class not in ROAD_CLASSES:
            raise ValueError(
                f"unknown road class '{self.road_class}'; valid: {', '.join(ROAD_CLASSES)}"
            )
        if not 0 <= self.seed < 2**32:
            raise ValueError(f"drive seed must be in [0, 2^32); got {self.seed}")
        if len(self.head_offset_m) != 3:
            raise ValueError(f"head_offset_m must hold 3 values; got {self.head_offset_m}")

    def name(self) -> str:
        """How summaries name the drive."""
        return f"built-in {self.manoeuvre} drive ({self.car}), seed {self.seed}"


def drive_recording(
    spec: DriveSpec,
    duration_s: float,
    *,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> Recording:
    """The recording of `spec`, `duration_s` s long (driven, or read from `cache_dir`, where
    drives are kept as CSV files named by every field that shapes them)."""
    spec.validate()
    cached = None
    if cache_dir is not None:
        offset = "_".join(f"{v:g}" for v in spec.head_offset_m)
        road = spec.road_class or "smooth"
        name = f"drive_{spec.manoeuvre}_{spec.car}_{road}_{offset}_{spec.seed}_{duration_s:g}s"
        cached = Path(cache_dir) / f"{name}.csv"
        if cached.is_file():
            return load_recording(cached)
    recording = drive(
        spec.manoeuvre,
        duration_s,
        spec.seed,
        car=spec.car,
        road_class=spec.road_class,
        head_offset_m=spec.head_offset_m,
        progress=progress,
    )
    if cached is not None:
        save_recording(cached, recording)
    return recording


def motion_recording(
    spec: FlightSpec | DriveSpec,
    duration_s: float,
    *,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> Recording:
    """The recording of a flight or a drive spec."""
    if isinstance(spec, DriveSpec):
        return drive_recording(spec, duration_s, cache_dir=cache_dir, progress=progress)
    return flight_recording(spec, duration_s, cache_dir=cache_dir, progress=progress)


def motion_reference(
    spec: FlightSpec | DriveSpec,
    duration_s: float,
    *,
    scaling: ReferenceScaling | None = None,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> Reference:
    """The motion-cueing reference of a flight or a drive spec (`reference_from_recording`
    with `scaling`, default s_w = s_f = 0.5), named by the spec, with its vehicle or car."""
    recording = motion_recording(spec, duration_s, cache_dir=cache_dir, progress=progress)
    vehicle = spec.car if isinstance(spec, DriveSpec) else cued_vehicle(spec, recording)
    return reference_from_recording(recording, scaling, name=spec.name(), vehicle=vehicle)


# The manoeuvres of training and tuning drives: seed s drives TRAINING_MANOEUVRES[s % 2],
# the courses whose bends, straights, lane changes and braking hold every cue a drive has
# (a mixed set of an even number of vehicles deals each car seeds of one parity: list the
# cars so that each gets both, or an odd number of vehicles).
TRAINING_MANOEUVRES = ("lap", "proving-ground")


def is_car(vehicle: str) -> bool:
    """Whether `vehicle` names a car (`references.driving.CARS`) rather than an aircraft."""
    return vehicle in CARS


def check_training_motion_vehicle(vehicle: str) -> str:
    """`vehicle` if training and tuning may use it (a car, or a training aircraft:
    `references.jsbsim.check_training_vehicle`), else ValueError (naming the cars too)."""
    if is_car(vehicle):
        return vehicle
    try:
        return check_training_vehicle(vehicle)
    except ValueError as error:
        raise ValueError(f"{error}; cars: {', '.join(CARS)}") from None


def training_spec(vehicle: str, seed: int, *, pilot: str = "scripted") -> FlightSpec | DriveSpec:
    """The reference that training and tuning name (vehicle, seed): a drive of the car
    `vehicle` through TRAINING_MANOEUVRES[seed % 2] on the default road, or a flight of the
    aircraft flown by `pilot`.

    Raises:
        ValueError: an evaluation seed (from FIRST_EVALUATION_SEED on) or a vehicle that
            training never uses.
    """
    check_training_motion_vehicle(vehicle)
    if not 0 <= seed < FIRST_EVALUATION_SEED:
        raise ValueError(
            f"seed {seed}: training and tuning use seeds 0 to {FIRST_EVALUATION_SEED - 1}; "
            "evaluation flights and drives are never trained or tuned on"
        )
    if is_car(vehicle):
        manoeuvre = TRAINING_MANOEUVRES[seed % len(TRAINING_MANOEUVRES)]
        return DriveSpec(manoeuvre=manoeuvre, seed=seed, car=vehicle)
    return FlightSpec(vehicle=vehicle, seed=seed, pilot=pilot)
