"""Small training sets for the DPC tests: segments at rest at the neutral pose with given
targets, 70 % training and 30 % validation, and segments of given arrays and sources."""

from __future__ import annotations

import numpy as np

from mca_drake.segments import SOURCE_COLUMNS, SegmentDataset, core_shapes

SEGMENT_METADATA = {
    "source_columns": list(SOURCE_COLUMNS),
    "split_names": ["train", "validation", "test"],
}


def segments_of(arrays: dict, source) -> SegmentDataset:
    """A segment dataset of `arrays` (float32; at least R, shape (n, T, 6)) from `source`
    rows (flight_seed, start_step, split), the other core arrays zero."""
    source = np.asarray(source, dtype=np.int64)
    n, horizon = source.shape[0], arrays["R"].shape[1]
    zeros = {name: np.zeros((n, horizon, *shape)) for name, shape in core_shapes(6).items()}
    merged = zeros | arrays
    arrays32 = {k: v.astype(np.float32) for k, v in merged.items()}
    return SegmentDataset(arrays32, source, SEGMENT_METADATA)


def rest_segments(targets: np.ndarray, platform: dict | None = None) -> SegmentDataset:
    """Segments of `targets` R (n, T, 6) starting at rest at the neutral pose (every other
    array zero), the first 70 % for training and the rest for validation; made on the
    platform of the `platform` record (`SerialChain.summary`; None: a dataset that names
    none, the KR500's)."""
    n, horizon = targets.shape[:2]
    joints = 6 if platform is None else platform["dof"]
    zeros = lambda *s: np.zeros((n, horizon, *s))  # noqa: E731
    arrays = {"U": zeros(joints), "X": zeros(2 * joints), "Y": zeros(6), "R": targets}
    arrays |= {name: zeros(4, 4) for name in ("F", "dF", "ddF")}
    split = np.zeros(n, dtype=np.int64)
    split[n * 7 // 10 :] = 1
    source = np.stack([np.zeros(n), np.zeros(n), split], 1).astype(np.int64)
    meta = {
        "source_columns": ["flight_seed", "start_step", "split"],
        "split_names": ["train", "validation", "test"],
    }
    if platform is not None:
        meta["platform"] = platform
    return SegmentDataset({k: v.astype(np.float32) for k, v in arrays.items()}, source, meta)
