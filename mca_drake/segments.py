"""SegmentDataset: n_p-long plant trajectories (U, X, Y, F, dF, ddF) and their file format.

Both the open-loop excitation dataset (Algorithm 1) and the closed-loop NMPC dataset are
collections of segments, as the paper's equation (12) defines them:

    U   (J, n_p, n)      joint accelerations u_t of the platform's n joints, rad/s^2 or m/s^2
    X   (J, n_p, 2n)     states x_t = [q_t, qd_t] at the start of each step
    Y   (J, n_p, 6)      outputs y_t = y(x_t, u_t) (the paper's y_(t+1))
    F   (J, n_p, 4, 4)   head pose F(q_t)
    dF  (J, n_p, 4, 4)   its first time derivative
    ddF (J, n_p, 4, 4)   its second time derivative (with u_t)

plus optional extra per-segment arrays (e.g. the reference R (J, n_p, 6) of a closed-loop
run) and a `source` table naming where each segment came from. Files are `.npz` (numpy's
zip of arrays, no pickle) with a JSON metadata entry, written atomically.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import itertools
import json
import os
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_npz, load_npz_with_metadata

# Columns of `SegmentDataset.source` in the closed-loop datasets, and the split labels of
# the "split" column (`mca_drake.studies.closed_loop_dataset.merge`).
SOURCE_COLUMNS = ("flight_seed", "start_step", "split")
SPLIT_NAMES = ("train", "validation", "test")

CORE_ARRAYS = ("U", "X", "Y", "F", "dF", "ddF")


def core_shapes(joints: int) -> dict[str, tuple[int, ...]]:
    """Each core array's shape per step for a platform of `joints` joints: a dataset's
    array `name` is (J, n_p, *core_shapes(n)[name])."""
    return {
        "U": (joints,),
        "X": (2 * joints,),
        "Y": (6,),
        "F": (4, 4),
        "dF": (4, 4),
        "ddF": (4, 4),
    }


FORMAT = "mca-drake segments v1"

# Where `mca-drake dataset closed-loop` writes, and where training looks by default.
DEFAULT_DATASET_DIR = "datasets/closed_loop"
DEFAULT_DATASET = f"{DEFAULT_DATASET_DIR}/dataset.npz"


# The platform of a dataset whose metadata names none: datasets were made on the KR500 before
# platforms were named.
UNNAMED_DATASET_PLATFORM = "kr500"


def dataset_platform(metadata: dict) -> str:
    """The name of the platform a segment dataset was made on (its metadata's
    `platform.name`; UNNAMED_DATASET_PLATFORM where it names none)."""
    record = metadata.get("platform", {"name": UNNAMED_DATASET_PLATFORM})
    name = record.get("name") if isinstance(record, dict) else None
    if not isinstance(name, str):
        raise ValueError(f"dataset platform must be a record with a name; got {record!r}")
    return name


def kept_file(path: str | os.PathLike, field: str, value) -> bool:
    """Whether `path` holds a segment dataset whose metadata[field] is `value`: a study's
    finished part, made with the settings the study has now (False for a missing or
    damaged file, which is then made again)."""
    if not Path(path).is_file():
        return False
    try:
        return SegmentDataset.load(path).metadata.get(field) == value
    except ValueError:
        return False


@dataclasses.dataclass
class SegmentDataset:
    """A set of J trajectory segments of n_p steps (see the module docstring for shapes).

    Attributes:
        arrays: name -> array with leading shape (J, n_p); at least the CORE_ARRAYS.
        source: (J, k) integer table identifying each segment's origin; its column names
            are `metadata["source_columns"]`.
        metadata: JSON-serialisable description: configuration, seeds, versions.
    """

    arrays: dict[str, np.ndarray]
    source: np.ndarray
    metadata: dict

    def __post_init__(self) -> None:
        missing = [k for k in CORE_ARRAYS if k not in self.arrays]
        if missing:
            raise ValueError(f"segment dataset lacks arrays {missing}")
        if self.arrays["U"].ndim != 3:
            raise ValueError(f"array U has shape {self.arrays['U'].shape}; expected (J, n_p, n)")
        J, n_p, joints = self.arrays["U"].shape
        shapes = core_shapes(joints)
        for name, array in self.arrays.items():
            expected = (J, n_p, *shapes[name]) if name in shapes else None
            if array.shape[:2] != (J, n_p) or (expected and array.shape != expected):
                raise ValueError(
                    f"array {name} has shape {array.shape}; expected {expected or (J, n_p, '...')}"
                )
        if self.source.shape[0] != J:
            raise ValueError(f"source has {self.source.shape[0]} rows for {J} segments")

    def __len__(self) -> int:
        return self.arrays["U"].shape[0]

    @property
    def horizon(self) -> int:
        """n_p, the number of steps per segment."""
        return self.arrays["U"].shape[1]

    def __getattr__(self, name: str) -> np.ndarray:
        # Convenience: dataset.U, dataset.X, ... (only called for missing attributes).
        arrays = self.__dict__.get("arrays", {})
        if name in arrays:
            return arrays[name]
        raise AttributeError(name)

    def subset(self, index: np.ndarray) -> SegmentDataset:
        """The segments at `index` (an integer array or boolean mask)."""
        return SegmentDataset(
            {k: v[index] for k, v in self.arrays.items()}, self.source[index], dict(self.metadata)
        )

    def split(
        self, fractions: tuple[float, ...] = (0.7, 0.2, 0.1), seed: int = 0
    ) -> tuple[SegmentDataset, ...]:
        """Shuffles with `seed` and splits by `fractions` (default train:val:test 70:20:10)."""
        if not np.isclose(sum(fractions), 1.0) or min(fractions) < 0:
            raise ValueError(f"fractions must be non-negative and sum to 1; got {fractions}")
        order = np.random.default_rng(seed).permutation(len(self))
        bounds = np.round(np.cumsum((0.0, *fractions)) * len(self)).astype(int)
        return tuple(self.subset(order[a:b]) for a, b in itertools.pairwise(bounds))

    @staticmethod
    def concatenate(parts: list[SegmentDataset], metadata: dict | None = None) -> SegmentDataset:
        """Joins datasets with the same arrays and horizon."""
        if not parts:
            raise ValueError("nothing to concatenate")
        names = set(parts[0].arrays)
        for part in parts:
            if set(part.arrays) != names or part.horizon != parts[0].horizon:
                raise ValueError("datasets to concatenate must share arrays and horizon")
        return SegmentDataset(
            {k: np.concatenate([p.arrays[k] for p in parts]) for k in parts[0].arrays},
            np.concatenate([p.source for p in parts]),
            metadata if metadata is not None else dict(parts[0].metadata),
        )

    def save(self, path: str | os.PathLike) -> Path:
        """Writes an .npz file atomically (no pickled objects inside)."""
        meta = json.dumps({"format": FORMAT, **self.metadata})
        arrays = {"source": self.source, "metadata_json": np.array(meta), **self.arrays}
        return atomic_write_npz(path, arrays)

    @staticmethod
    def load(path: str | os.PathLike) -> SegmentDataset:
        """Reads a file written by `save`; raises ValueError if it is not one."""
        arrays, metadata = load_npz_with_metadata(path, "segment dataset")
        if "source" not in arrays:
            raise ValueError(f"{path} is not a segment dataset file: no source array")
        source = arrays.pop("source")
        if metadata.get("format") != FORMAT:
            raise ValueError(f"{path}: unknown format {metadata.get('format')!r}; want {FORMAT}")
        return SegmentDataset(arrays, source, metadata)


def package_versions() -> dict[str, str]:
    """Versions of the packages that shape generated data (for dataset metadata)."""
    versions = {}
    for name in ("mca-drake", "numpy", "scipy", "drake", "torch", "jsbsim"):
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


def split_of(dataset: SegmentDataset) -> dict[str, SegmentDataset]:
    """The labelled train/validation/test parts of a merged closed-loop dataset."""
    column = dataset.source[:, SOURCE_COLUMNS.index("split")]
    return {name: dataset.subset(column == i) for i, name in enumerate(SPLIT_NAMES)}


def consecutive_runs(dataset: SegmentDataset) -> list[np.ndarray]:
    """The rows of `dataset` in runs of consecutive segments of one flight, in time order:
    per flight (by seed, ascending), a new run starts at every gap in its start steps."""
    seed_col = SOURCE_COLUMNS.index("flight_seed")
    step_col = SOURCE_COLUMNS.index("start_step")
    runs: list[np.ndarray] = []
    for flight in np.unique(dataset.source[:, seed_col]):
        rows = np.flatnonzero(dataset.source[:, seed_col] == flight)
        rows = rows[np.argsort(dataset.source[rows, step_col])]
        gaps = np.flatnonzero(np.diff(dataset.source[rows, step_col]) != dataset.horizon) + 1
        runs.extend(np.split(rows, gaps))
    return runs


def long_windows(
    dataset: SegmentDataset, segments: int, fractions=(0.7, 0.2, 0.1), seed: int = 0
) -> dict[str, SegmentDataset]:
    """Windows of `segments` consecutive segments of one flight, joined in time, split
    train/validation/test by window with `seed` (a split of its own: the per-segment labels
    of `mca_drake.studies.closed_loop_dataset.merge` would cut most windows apart).

    For DPC training on rollouts longer than n_p: a policy trained on 2.56 s rollouts only
    ever sees the first 2.56 s of its own drift. Returns {"train", "validation", "test"}.
    """
    if segments < 1:
        raise ValueError(f"segments must be at least 1; got {segments}")
    n_p = dataset.horizon
    windows = [
        run[k : k + segments]
        for run in consecutive_runs(dataset)
        for k in range(0, len(run) - segments + 1, segments)
    ]
    if not windows:
        raise ValueError(f"no run of {segments} consecutive segments in the dataset")
    index = np.stack(windows)  # (W, segments)
    arrays = {
        k: v[index].reshape(len(windows), segments * n_p, *v.shape[2:])
        for k, v in dataset.arrays.items()
    }
    source = dataset.source[index[:, 0]].copy()
    meta = {**dataset.metadata, "window_segments": segments}
    joined = SegmentDataset(arrays, source, meta)
    parts = joined.split(tuple(fractions), seed=seed)
    return dict(zip(SPLIT_NAMES, parts, strict=True))
