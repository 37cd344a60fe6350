"""The car motion a run cues: a built-in drive (`references.driving`), named like a flight.

`DriveSpec` names a drive (a scenario's `flight` field takes one where it takes a
`FlightSpec`); `drive_recording` turns it into a `Recording`. `motion_recording` and
`motion_reference` (the motion-cueing `Reference`) take either spec, so that scenarios and
studies take drives as they take flights.
"""

import dataclasses
from pathlib import Path

from mca_drake.references.driving.car import check_car
from mca_drake.references.driving.courses import MANOEUVRES
from mca_drake.references.driving.drive import DEFAULT_HEAD_OFFSET_M, drive
from mca_drake.references.driving.road import ROAD_CLASSES
from mca_drake.references.flights import FlightSpec, flight_recording
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
    with `scaling`, default s_w = s_f = 0.5), named by the spec."""
    recording = motion_recording(spec, duration_s, cache_dir=cache_dir, progress=progress)
    return reference_from_recording(recording, scaling, name=spec.name())
