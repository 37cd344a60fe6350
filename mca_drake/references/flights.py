"""The vehicle motion a run cues: a recording file or a built-in JSBSim flight.

`FlightSpec` names it (a scenario's `flight` field); `flight_recording` and
`flight_reference` turn it into a `Recording` and a motion-cueing `Reference`: the one place
where a flight becomes a reference, for closed-loop scenarios, the evaluation suite and the
closed-loop dataset alike.
"""

import dataclasses
from pathlib import Path

from mca_drake.references.jsbsim import check_vehicle, fly
from mca_drake.references.recording import Recording, load_recording, save_recording
from mca_drake.references.reference import Reference, ReferenceScaling, reference_from_recording


@dataclasses.dataclass
class FlightSpec:
    """The vehicle motion a scenario cues."""

    # Recording CSV (columns t, omega_x, omega_y, omega_z, f_x, f_y, f_z); empty: fly the
    # built-in JSBSim flight below.
    recording: str = ""
    # Built-in flight: "light" (c172p) or "jet" (global5000).
    vehicle: str = "light"
    # Seed of the built-in flight's scripted pilot (training used 100-104; evaluation 1000 on).
    seed: int = 1000

    def validate(self) -> None:
        """Raises ValueError for an unknown vehicle or a missing recording file."""
        if not self.recording:
            check_vehicle(self.vehicle)
        if not self.recording and not 0 <= self.seed < 2**32:
            raise ValueError(f"flight.seed must be in [0, 2^32); got {self.seed}")
        if self.recording and not Path(self.recording).is_file():
            raise ValueError(f"flight.recording {self.recording!r} not found")

    def name(self) -> str:
        """How summaries name the flight: the recording's path, or the built-in flight."""
        if self.recording:
            return self.recording
        return f"built-in {self.vehicle} flight, seed {self.seed}"


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
        cached = Path(cache_dir) / f"{flight.vehicle}_{flight.seed}_{duration_s:g}s.csv"
        if cached.is_file():
            return load_recording(cached)
    recording = fly(flight.vehicle, duration_s, flight.seed, progress=progress)
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
    `FlightSpec.name`."""
    recording = flight_recording(flight, duration_s, cache_dir=cache_dir, progress=progress)
    return reference_from_recording(recording, scaling, name=flight.name())
