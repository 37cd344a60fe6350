"""The vehicle motion a run cues: a recording file or a built-in JSBSim flight.

`FlightSpec` names it (a scenario's `flight` field); `flight_recording` and
`flight_reference` turn it into a `Recording` and a motion-cueing `Reference`: the one place
where a flight becomes a reference, for closed-loop scenarios, the evaluation suite and the
closed-loop dataset alike.
"""

import dataclasses
import json
from pathlib import Path

import numpy as np

from mca_drake.conventions import FIRST_EVALUATION_SEED
from mca_drake.references.jsbsim import FlightConfig, FlightError, check_vehicle, fly
from mca_drake.references.jsbsim.route import EVALUATION_ONLY
from mca_drake.references.jsbsim.style import (
    PilotStyle,
    sample_human_operator,
    sample_pilot_style,
)
from mca_drake.references.recording import Recording, load_recording, save_recording
from mca_drake.references.reference import Reference, ReferenceScaling, reference_from_recording
from mca_drake.references.synthetic import VEHICLE_ENVELOPES, SyntheticConfig, synthetic_recording

# Who flies a built-in flight: the scripted pilot, a pilot whose style is drawn from the
# flight's seed (`jsbsim.style.sample_pilot_style`), the independent route pilot
# (`jsbsim.route`), which flies evaluation flights only, or a human operator drawn from the
# seed (`jsbsim.style.sample_human_operator`: McRuer's crossover model, with reaction delay,
# neuromuscular lag and remnant), which no training flies: the validation pilot.
PILOTS = ("scripted", "random-style", "route", "human")
# The random pilot's style comes from its own stream of the seed, so the flight's own draws
# (turbulence, heading, plan) are those of the scripted pilot's flight of that seed.
STYLE_STREAM = 1
# Where a training flight's reference comes from: the scripted pilot, a random-style
# pilot, or synthetic motion in the vehicle's envelope (never the route pilot).
TRAINING_SOURCES = ("scripted", "random-style", "synthetic")
# Styles drawn for one seed at most: a style whose flight leaves the airframe's envelope
# (a FlightError, about 1 in 70 flights at the ranges' corners) is replaced by the next.
MAX_STYLE_DRAWS = 5


@dataclasses.dataclass
class FlightSpec:
    """The vehicle motion a scenario cues."""

    # Recording CSV (columns t, omega_x, omega_y, omega_z, f_x, f_y, f_z); empty: fly the
    # built-in JSBSim flight below.
    recording: str = ""
    # Aircraft of the built-in flight (`mca_drake.references.jsbsim.VEHICLES`: "light" the
    # c172p, "jet" the global5000, ...).
    vehicle: str = "light"
    # Seed of the built-in flight's pilot (training used 100-104; evaluation 1000 on).
    seed: int = 1000
    # Who flies it (`PILOTS`): "scripted", "random-style" (a style drawn from the seed),
    # "route" (the independent route pilot; evaluation seeds only) or "human" (a human
    # operator drawn from the seed; no training flies it).
    pilot: str = "scripted"

    def validate(self) -> None:
        """Raises ValueError for an unknown vehicle or pilot, or a missing recording file."""
        if not self.recording:
            check_vehicle(self.vehicle)
        if self.pilot not in PILOTS:
            raise ValueError(f"unknown flight.pilot '{self.pilot}'; valid: {', '.join(PILOTS)}")
        if self.pilot in EVALUATION_ONLY and self.seed < FIRST_EVALUATION_SEED:
            raise ValueError(
                f"the {self.pilot} pilot flies evaluation flights only (seeds from "
                f"{FIRST_EVALUATION_SEED} on); got seed {self.seed}"
            )
        if not self.recording and not 0 <= self.seed < 2**32:
            raise ValueError(f"flight.seed must be in [0, 2^32); got {self.seed}")
        if self.recording and not Path(self.recording).is_file():
            raise ValueError(f"flight.recording {self.recording!r} not found")

    def flown_by(self) -> str:
        """The vehicle of a built-in flight; "" for a recording, whose aircraft the spec
        does not know (`vehicle` then only holds its default)."""
        return "" if self.recording else self.vehicle

    def name(self) -> str:
        """How summaries name the flight: the recording's path, or the built-in flight."""
        if self.recording:
            return self.recording
        pilot = "" if self.pilot == "scripted" else f", {self.pilot} pilot"
        return f"built-in {self.vehicle} flight, seed {self.seed}{pilot}"


def training_recording(
    source: str,
    vehicle: str,
    seed: int,
    duration_s: float,
    *,
    cache_dir: str | Path | None = None,
) -> Recording:
    """The recording of a training flight from `source` (`TRAINING_SOURCES`): the
    scripted or a random-style pilot's flight of `vehicle` and `seed`, or synthetic motion
    in the vehicle's envelope (`references.synthetic`, seeded by `seed`)."""
    if source not in TRAINING_SOURCES:
        raise ValueError(f"unknown source '{source}'; valid: {', '.join(TRAINING_SOURCES)}")
    if source == "synthetic":
        check_vehicle(vehicle)
        config = SyntheticConfig(
            envelope=VEHICLE_ENVELOPES[vehicle], duration_s=duration_s, seed=seed
        )
        return synthetic_recording(config)
    spec = FlightSpec(vehicle=vehicle, seed=seed, pilot=source)
    return flight_recording(spec, duration_s, cache_dir=cache_dir)


def pilot_style(seed: int, draw: int = 0) -> PilotStyle:
    """The random-style pilot's style for a flight seed: draw `draw` of its style stream."""
    return sample_pilot_style(np.random.default_rng([seed, STYLE_STREAM, draw]))


def human_operator(seed: int, draw: int = 0) -> PilotStyle:
    """The human-operator pilot's style for a flight seed: draw `draw` of its own stream."""
    return sample_human_operator(seed, np.random.default_rng([seed, HUMAN_STREAM, draw]))


# The human operator's style comes from a stream of the seed of its own.
HUMAN_STREAM = 3


def _fly_drawn_style(
    vehicle: str, duration_s: float, seed: int, progress: bool, pilot: str
) -> Recording:
    """The flight of `seed` flown by its random-style pilot (`pilot_style`) or its human
    operator (`human_operator`): the first of the seed's draws whose flight stays in the
    airframe's envelope; the style in the metadata (`pilot_style`, JSON)."""
    draw_style = pilot_style if pilot == "random-style" else human_operator
    errors = []
    for draw in range(MAX_STYLE_DRAWS):
        style = draw_style(seed, draw)
        try:
            recording = fly(
                vehicle, duration_s, seed, config=FlightConfig(style=style), progress=progress
            )
        except FlightError as error:
            errors.append(str(error))
            continue
        recording.metadata["pilot"] = pilot
        recording.metadata["pilot_style"] = json.dumps(dataclasses.asdict(style))
        return recording
    raise FlightError(
        f"{vehicle} seed {seed}: none of {MAX_STYLE_DRAWS} {pilot} pilot styles flew "
        f"{duration_s:g} s; the last: {errors[-1]}"
    )


def flight_recording(
    flight: FlightSpec,
    duration_s: float,
    *,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> Recording:
    """The recording of `flight`: its CSV file, or the built-in JSBSim flight of
    `duration_s` seconds (deterministic for its seed).

    Args:
        cache_dir: a folder where built-in flights are kept as CSV files
            (`{vehicle}_{seed}_{duration}s.csv`), read instead of flown again.
        progress: a progress bar while JSBSim flies.
    """
    flight.validate()
    if flight.recording:
        # read only what the run needs: a long file asked for a few seconds is not parsed whole
        return load_recording(flight.recording, max_duration_s=duration_s)
    cached = None
    if cache_dir is not None:
        pilot = "" if flight.pilot == "scripted" else f"{flight.pilot}_"
        cached = Path(cache_dir) / f"{flight.vehicle}_{pilot}{flight.seed}_{duration_s:g}s.csv"
        if cached.is_file():
            return load_recording(cached)
    if flight.pilot in ("random-style", "human"):
        recording = _fly_drawn_style(
            flight.vehicle, duration_s, flight.seed, progress, flight.pilot
        )
    else:
        pilot = "route" if flight.pilot == "route" else "scripted"
        recording = fly(flight.vehicle, duration_s, flight.seed, progress=progress, pilot=pilot)
    if cached is not None:
        save_recording(cached, recording)
    return recording


def flight_reference(
    flight: FlightSpec,
    duration_s: float,
    *,
    scaling: ReferenceScaling | None = None,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> Reference:
    """The motion-cueing reference of `flight` (`flight_recording`, then
    `reference_from_recording` with `scaling`, default s_w = s_f = 0.5), named by
    `FlightSpec.name`, with the vehicle of a built-in flight (`FlightSpec.flown_by`) or the
    one a recording's header names (`# vehicle: bmw-320i`, as `mca-drake drive` writes it;
    "" where it names none)."""
    recording = flight_recording(flight, duration_s, cache_dir=cache_dir, progress=progress)
    return reference_from_recording(
        recording, scaling, name=flight.name(), vehicle=cued_vehicle(flight, recording)
    )


def cued_vehicle(flight: FlightSpec, recording) -> str:
    """The vehicle a flight's reference is cued as: a built-in flight's own, or the one
    its recording's header names (`# vehicle: ...`; "" where it names none)."""
    return flight.flown_by() or str(recording.metadata.get("vehicle", ""))
