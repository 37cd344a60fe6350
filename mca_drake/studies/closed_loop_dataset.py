"""Closed-loop dataset: an MCA cueing JSBSim flights, cut into n_p-long segments.

For each flight seed: fly its vehicle (`mca_drake.references.flights`), scale the
recording into a reference, run ReferenceSource -> MCA -> MotionCueingPlant at 100 Hz, and
cut the logged trajectory into non-overlapping segments holding U, X, Y, F, dF, ddF and the
reference R (see `mca_drake.segments`). Each flight is one file, written atomically; a
re-run skips flights whose file exists with the same configuration, so a killed run
resumes. The flights run in parallel local processes. `merge` joins them and labels a
70:20:10 train/validation/test split with a fixed seed.

The paper's size, the default: five 15-minute light-aircraft flights, n_p = 256 (about
1750 segments). Each flight's reference comes from one of three sources (`TRAINING_SOURCES`),
drawn from its seed with the configured shares: the scripted pilot (the default, all of
them), a pilot whose style is drawn per flight (`random_style_share`,
`references.jsbsim.style`), or synthetic band-limited motion in the vehicle's envelope
(`synthetic_share`, `references.synthetic`), so that the policy learns the task rather than
one pilot's habits. A mixed-vehicle set lists `vehicles`: the seeds are dealt to them in turn
(seed i flies vehicles[i % len(vehicles)]), so every flight keeps a seed of its own. A car
(`references.driving.CARS`) among them drives instead: a lap or the proving ground, dealt
from the seed (`references.drives.training_spec`), its source "drive". The MCA
defaults to NMPC in rti mode (at the tuned weights), which tracks the converged solution to
within a few 1e-4 of PI (benchmarks/bench_nmpc.py) at a fraction of the cost.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import time
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import check_writable
from mca_drake.conventions import CONTROL_PERIOD_S, FIRST_EVALUATION_SEED
from mca_drake.cueing import McaConfig, NmpcConfig, as_mca_config, mca_config_record
from mca_drake.input_checks import MAX_DURATION_S, check_config_numbers, check_range
from mca_drake.platforms.files import DEFAULT_PLATFORM, PlatformField, load_platform, packaged_name
from mca_drake.platforms.kinematics import cut_trajectory
from mca_drake.references.drives import (
    check_training_motion_vehicle,
    drive_recording,
    is_car,
    training_spec,
)
from mca_drake.references.flights import training_recording
from mca_drake.references.reference import ReferenceScaling, reference_from_recording
from mca_drake.segments import (
    DEFAULT_DATASET_DIR,
    SOURCE_COLUMNS,
    SPLIT_NAMES,
    SegmentDataset,
    kept_file,
    package_versions,
)
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.parallel import run_tasks

# The stream of a seed that chooses its flight's source, apart from the flight's own draws.
SOURCE_STREAM = 2


@dataclasses.dataclass
class ClosedLoopDatasetConfig:
    """What to simulate and where to write it; defaults are the paper's dataset."""

    # Vehicle flown by JSBSim (`mca_drake.references.jsbsim.VEHICLES`), or a car that
    # drives (`mca_drake.references.driving.CARS`), when `vehicles` is empty.
    vehicle: str = "light"
    # Vehicles of a mixed set: flight_seeds[i] flies (or drives) vehicles[i % len(vehicles)].
    vehicles: tuple[str, ...] = ()
    # Seeds of the flights; evaluation uses seeds from 1000 on, never these.
    flight_seeds: tuple[int, ...] = (100, 101, 102, 103, 104)
    # Length of each flight, s.
    flight_duration_s: float = 900.0
    # Probability that a flight is flown by a random-style pilot (each flight's source is
    # drawn from its seed: `flight_source`).
    random_style_share: float = 0.0
    # Probability that a flight's reference is synthetic instead of flown; the rest are the
    # scripted pilot's.
    synthetic_share: float = 0.0
    # Segment length n_p, steps.
    horizon: int = 256
    # Motion cueing algorithm that generates the trajectories (a config, or a name for its
    # default config).
    mca: McaConfig = dataclasses.field(default_factory=lambda: NmpcConfig(mode="rti"))
    # Scaling of the recordings into references.
    scaling: ReferenceScaling = dataclasses.field(default_factory=ReferenceScaling)
    # Train, validation and test fractions, and the seed of the shuffle before the split.
    split_fractions: tuple[float, float, float] = (0.7, 0.2, 0.1)
    split_seed: int = 0
    # Floating-point type of the stored arrays.
    dtype: str = "float32"
    # The motion platform the MCA cues on: a packaged name, a platform file or a
    # description (`mca_drake.platforms.files.load_platform`).
    platform: PlatformField = DEFAULT_PLATFORM

    def __post_init__(self) -> None:
        self.mca = as_mca_config(self.mca, packaged_name(self.platform))

    def validate(self) -> None:
        """Raises ValueError for an unknown vehicle, no seeds, a bad horizon, split or
        flight length; before any flight is simulated."""
        check_config_numbers(self)
        load_platform(self.platform)  # ValueError or FileNotFoundError naming the problem
        for vehicle in self.vehicles or (self.vehicle,):
            check_training_motion_vehicle(vehicle)
        if not self.flight_seeds:
            raise ValueError("flight_seeds is empty")
        if len(set(self.flight_seeds)) != len(self.flight_seeds):
            raise ValueError(f"flight_seeds repeat a seed: {self.flight_seeds}")
        if any(s >= FIRST_EVALUATION_SEED for s in self.flight_seeds):
            raise ValueError(
                f"flight_seeds from {FIRST_EVALUATION_SEED} on are evaluation flights, never "
                f"trained on; got {self.flight_seeds}"
            )
        if any(not 0 <= s < 2**32 for s in self.flight_seeds):
            raise ValueError(f"flight_seeds must be in [0, 2^32); got {self.flight_seeds}")
        if self.horizon < 1:
            raise ValueError(f"horizon must be at least 1 step; got {self.horizon}")
        check_range(
            "ClosedLoopDatasetConfig",
            "flight_duration_s",
            self.flight_duration_s,
            0.0,
            MAX_DURATION_S,
            low_open=True,
        )
        if self.flight_duration_s < self.horizon * CONTROL_PERIOD_S:
            raise ValueError("flight_duration_s is shorter than one segment")
        shares = (self.random_style_share, self.synthetic_share)
        if min(shares) < 0 or sum(shares) > 1:
            raise ValueError(
                "random_style_share and synthetic_share must be non-negative and sum to at "
                f"most 1; got {shares}"
            )
        if not 0 <= self.split_seed < 2**32:
            raise ValueError(f"split_seed must be in [0, 2^32); got {self.split_seed}")
        fractions = self.split_fractions
        if len(fractions) != 3 or min(fractions) < 0 or abs(sum(fractions) - 1) > 1e-9:
            raise ValueError(f"split_fractions must be three shares summing to 1; got {fractions}")
        self.scaling.validate()

    def record(self) -> dict:
        """The config as a JSON-ready dict, the MCA's tagged with its class."""
        return {**dataclasses.asdict(self), "mca": mca_config_record(self.mca)}

    def flights(self) -> list[tuple[str, int]]:
        """(vehicle, seed) of every flight, in seed order: the seeds dealt to `vehicles` in
        turn, or all to `vehicle`."""
        vehicles = self.vehicles or (self.vehicle,)
        return [(vehicles[i % len(vehicles)], s) for i, s in enumerate(self.flight_seeds)]

    def flight_source(self, seed: int, vehicle: str | None = None) -> str:
        """Where the flight of `seed` by `vehicle` (default `vehicle`, the config's) gets
        its reference: "drive" for a car, else one of `TRAINING_SOURCES`, drawn from the
        seed's own stream with the configured shares, so a flight keeps its source whatever
        the other seeds."""
        if is_car(self.vehicle if vehicle is None else vehicle):
            return "drive"
        u = np.random.default_rng([seed, SOURCE_STREAM]).uniform()
        if u < self.synthetic_share:
            return "synthetic"
        if u < self.synthetic_share + self.random_style_share:
            return "random-style"
        return "scripted"

    def flight_key(self, vehicle: str) -> str:
        """Hash of everything that shapes one flight's file of `vehicle` (not the seeds, the
        other vehicles or the split)."""
        fields = self.record()
        for name in ("flight_seeds", "split_fractions", "split_seed", "vehicles"):
            fields.pop(name)
        if fields["platform"] == DEFAULT_PLATFORM:
            fields.pop("platform")  # the KR500's flight files keep the keys they always had
        fields["vehicle"] = vehicle
        return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:16]


def flight_path(out_dir: Path, seed: int) -> Path:
    """Where one flight's segments are kept while a dataset is built (resumable per flight)."""
    return Path(out_dir) / f"flight_{seed:05d}.npz"


def simulate_flight(
    config: ClosedLoopDatasetConfig, seed: int, vehicle: str | None = None
) -> SegmentDataset:
    """One flight of `vehicle` (default `config.vehicle`) through the closed loop, cut into
    segments (no file written)."""
    vehicle = vehicle or config.vehicle
    robot = load_platform(config.platform)
    started = time.perf_counter()
    origin = config.flight_source(seed, vehicle)
    if origin == "drive":
        spec = training_spec(vehicle, seed)
        recording = drive_recording(spec, config.flight_duration_s)
        name = spec.name()
    else:
        recording = training_recording(origin, vehicle, seed, config.flight_duration_s)
        name = f"{vehicle} flight seed {seed}" + ("" if origin == "scripted" else f", {origin}")
    reference = reference_from_recording(recording, config.scaling, name=name)
    result = run_closed_loop(mca=config.mca, reference=reference, robot=robot, progress=False)
    n_p = config.horizon
    n_segments = result.commands.shape[0] // n_p
    keep = slice(0, n_segments * n_p)
    arrays = cut_trajectory(
        result.states[keep],
        result.commands[keep],
        result.reference[keep],
        robot,
        n_p,
        np.dtype(config.dtype),
    )
    source = np.column_stack(
        [np.full(n_segments, seed), n_p * np.arange(n_segments), np.full(n_segments, -1)]
    ).astype(np.int64)
    metadata = {
        "kind": "closed-loop MCA dataset, one flight",
        "config": config.record(),
        "config_key": config.flight_key(vehicle),
        "flight_seed": seed,
        "vehicle": vehicle,
        "reference_source": origin,
        "platform": robot.summary(),
        "source_columns": list(SOURCE_COLUMNS),
        "summary": result.summary,
        "recording_metadata": recording.metadata,
        "wall_time_s": time.perf_counter() - started,
        "versions": package_versions(),
    }
    return SegmentDataset(arrays, source, metadata)


def _run_one(config: ClosedLoopDatasetConfig, vehicle: str, seed: int, out_dir: str) -> str:
    path = flight_path(Path(out_dir), seed)
    simulate_flight(config, seed, vehicle).save(path)
    return str(path)


def generate_closed_loop_dataset(
    config: ClosedLoopDatasetConfig | None = None,
    out_dir: str | Path = DEFAULT_DATASET_DIR,
    workers: int = 1,
    progress: bool = True,
    address: str | None = None,
) -> Path:
    """Simulates every flight not yet on disk (in `workers` processes), then merges them.

    Returns:
        The merged file `out_dir/dataset.npz`; per-flight files stay beside it.
    """
    config = config or ClosedLoopDatasetConfig()
    config.validate()
    # absolute: a cluster's workers write here from folders of their own
    out_dir = check_writable(Path(out_dir).resolve(), folder=True)
    todo = [
        (config, vehicle, s, str(out_dir))
        for vehicle, s in config.flights()
        if not kept_file(flight_path(out_dir, s), "config_key", config.flight_key(vehicle))
    ]
    run_tasks(
        _run_one,
        todo,
        workers=workers,
        address=address,
        total=len(config.flight_seeds),
        description="closed-loop flights",
        unit="flight",
        progress=progress,
    )
    return merge(config, out_dir)


def merge(config: ClosedLoopDatasetConfig, out_dir: str | Path) -> Path:
    """Joins the per-flight files of `config` and labels the train/validation/test split."""
    out_dir = Path(out_dir)
    parts = [SegmentDataset.load(flight_path(out_dir, s)) for s in config.flight_seeds]
    merged = SegmentDataset.concatenate(parts)
    order = np.random.default_rng(config.split_seed).permutation(len(merged))
    bounds = np.round(np.cumsum((0.0, *config.split_fractions)) * len(merged)).astype(int)
    labels = np.empty(len(merged), dtype=np.int64)
    for index, (a, b) in enumerate(itertools.pairwise(bounds)):
        labels[order[a:b]] = index
    merged.source[:, SOURCE_COLUMNS.index("split")] = labels
    merged.metadata = _dataset_metadata(
        {str(p.metadata["flight_seed"]): p.metadata["summary"] for p in parts},
        {seed: vehicle for vehicle, seed in config.flights()},
        config=config.record(),
        platform=load_platform(config.platform).summary(),
    )
    return merged.save(out_dir / "dataset.npz")


def _dataset_metadata(flights: dict, flight_vehicles: dict, **provenance) -> dict:
    """A closed-loop dataset's metadata: its flights' summaries and vehicles (seed -> ...),
    the source and split layout, where it came from (`provenance`) and the versions."""
    return {
        "kind": "closed-loop MCA dataset",
        **provenance,
        "source_columns": list(SOURCE_COLUMNS),
        "split_names": list(SPLIT_NAMES),
        "flights": flights,
        "flight_vehicles": flight_vehicles,
        "versions": package_versions(),
    }


def join_datasets(paths: list[str | Path], out: str | Path) -> Path:
    """Joins closed-loop datasets of different flights into one file at `out` (atomically).

    Each segment keeps its split label; the metadata holds the union of the parts' flights
    and flight_vehicles and each part's path and config (`joined_from`). For adding flights of
    one aircraft class to a mixed set without regenerating it.

    Raises:
        ValueError: fewer than two parts, a part that is not a closed-loop dataset (no
            flight_vehicles), parts that share a flight seed, or parts with different arrays,
            horizons or platforms.
    """
    if len(paths) < 2:
        raise ValueError(f"join needs at least two datasets; got {len(paths)}")
    parts = [SegmentDataset.load(p) for p in paths]
    flights: dict[str, object] = {}
    vehicles: dict[str, str] = {}
    for path, part in zip(paths, parts, strict=True):
        names = part.metadata.get("flight_vehicles")
        if not isinstance(names, dict):
            raise ValueError(f"{path} is not a closed-loop dataset (no flight_vehicles)")
        shared = sorted(set(names) & set(vehicles), key=int)
        if shared:
            raise ValueError(f"{path} repeats flights {shared} of an earlier part")
        vehicles.update(names)
        flights.update(part.metadata.get("flights", {}))
    made_on = {
        json.dumps(part.metadata.get("platform", {"name": DEFAULT_PLATFORM})) for part in parts
    }
    if len(made_on) > 1:
        raise ValueError(f"the datasets were made on different platforms: {sorted(made_on)}")
    joined = SegmentDataset.concatenate(parts)
    joined.metadata = _dataset_metadata(
        flights,
        vehicles,
        platform=json.loads(made_on.pop()),
        joined_from=[
            {"path": str(p), "config": part.metadata.get("config")}
            for p, part in zip(paths, parts, strict=True)
        ],
    )
    return joined.save(out)
