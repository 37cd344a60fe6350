"""The range of the references a DPC policy was trained on, and how much of a run's reference
lay outside it: a guard for the unseen, so a user sees when to prefer the NMPC.

A network is trustworthy where it was trained. Of its inputs, the reference is the one the
closed loop does not shape (the state and the cue follow from the policy's own commands), so
the guard watches the reference: per channel of `conventions.CHANNELS`, the low and high
quantiles (`RANGE_QUANTILE` left out on each side) of the training flights' references, with
their mirror images where training mirrored them (`MIRROR_CHANNEL_SIGNS`). A run's
out-of-distribution share is the share of its control periods in which any channel lies
outside (a training flight itself has at most 12 x `RANGE_QUANTILE` of its samples there).

A policy file trained here carries its range in its metadata (`reference_range`, from its
dataset's targets); the shipped policies' ranges are in
`mca_drake/data/policy_reference_ranges.json`, computed from their datasets' flights by
`scripts/policy_reference_ranges.py`.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from mca_drake.conventions import CHANNELS, MIRROR_CHANNEL_SIGNS, NUM_CHANNELS
from mca_drake.resources import data_dir

# Share of the training samples left out of the range on each side of each channel.
RANGE_QUANTILE = 0.001
# The shipped policies' ranges, by policy name (a platform's moved policy, e.g.
# "kr500-rail_light_policy", reads the same references as the KR500's "light_policy").
SHIPPED_RANGES_FILE = "policy_reference_ranges.json"


@dataclasses.dataclass(frozen=True)
class ReferenceRange:
    """The references a policy was trained on, channel by channel (`CHANNELS`, the units of
    `Reference.y`: rad/s and m/s^2 after scaling).

    Attributes:
        low, high: the RANGE_QUANTILE and 1 - RANGE_QUANTILE quantiles per channel (6 each).
        source: what they were computed from, in words.
    """

    low: tuple[float, ...]
    high: tuple[float, ...]
    source: str = ""

    def __post_init__(self) -> None:
        low, high = np.asarray(self.low, float), np.asarray(self.high, float)
        if low.shape != (NUM_CHANNELS,) or high.shape != (NUM_CHANNELS,):
            raise ValueError(f"a reference range has {NUM_CHANNELS} lows and highs")
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(low <= high)):
            raise ValueError(f"reference range: lows {self.low} must be finite and <= highs")

    def record(self) -> dict:
        """The range as JSON-ready data (`from_record` reads it back)."""
        return {"low": list(self.low), "high": list(self.high), "source": self.source}

    @classmethod
    def from_record(cls, record: dict) -> ReferenceRange:
        """A range from `record`; ValueError, naming what is wrong, for anything else."""
        if not isinstance(record, dict) or not {"low", "high"} <= set(record):
            raise ValueError(f"a reference range record has 'low' and 'high'; got {record!r}")
        try:
            low = tuple(float(v) for v in record["low"])
            high = tuple(float(v) for v in record["high"])
        except (TypeError, ValueError):
            raise ValueError(
                f"reference range: lows and highs must be numbers; {record!r}"
            ) from None
        return cls(low, high, str(record.get("source", "")))


def reference_range(references: Iterable[np.ndarray], *, mirrored: bool, source: str = ""):
    """The `ReferenceRange` of training references (each (T, 6)), with their mirror images
    (`MIRROR_CHANNEL_SIGNS`) where `mirrored` (training mirrored a share of its windows)."""
    samples = np.concatenate([np.asarray(y, float).reshape(-1, NUM_CHANNELS) for y in references])
    if mirrored:
        samples = np.concatenate((samples, samples * np.asarray(MIRROR_CHANNEL_SIGNS)))
    if samples.shape[0] == 0 or not np.all(np.isfinite(samples)):
        raise ValueError("reference_range needs finite samples")
    low = np.quantile(samples, RANGE_QUANTILE, axis=0)
    high = np.quantile(samples, 1.0 - RANGE_QUANTILE, axis=0)
    return ReferenceRange(tuple(low.tolist()), tuple(high.tolist()), source)


def outside(y: np.ndarray, ranges: ReferenceRange) -> np.ndarray:
    """Where the reference `y` (T, 6) lies outside `ranges`, (T, 6) booleans."""
    y = np.asarray(y, float)
    return (y < np.asarray(ranges.low)) | (y > np.asarray(ranges.high))


def outside_share(mask: np.ndarray) -> dict:
    """The summary's out-of-distribution record of an `outside` mask (T, 6): `share` (of
    the control periods with any channel outside) and `channels` (each channel's share)."""
    if mask.shape[0] == 0:
        return {"share": 0.0, "channels": dict.fromkeys(CHANNELS, 0.0)}
    per_channel = mask.mean(axis=0)
    return {
        "share": float(mask.any(axis=1).mean()),
        "channels": {c: float(v) for c, v in zip(CHANNELS, per_channel, strict=True)},
    }


def shipped_ranges() -> dict[str, ReferenceRange]:
    """The shipped policies' ranges by policy name ({} where the file is missing)."""
    path = data_dir() / SHIPPED_RANGES_FILE
    if not path.is_file():
        return {}
    records = json.loads(path.read_text())
    return {name: ReferenceRange.from_record(r) for name, r in records["policies"].items()}


def policy_reference_range(path, metadata: dict) -> ReferenceRange | None:
    """The range of the policy file at `path` (its `metadata`): its own `reference_range`,
    else a shipped policy's by name (a platform's moved policy: the KR500's it was moved
    from), else None (a policy trained before ranges were recorded)."""
    if "reference_range" in metadata:
        return ReferenceRange.from_record(metadata["reference_range"])
    name = Path(path).stem
    ranges = shipped_ranges()
    if name in ranges:
        return ranges[name]
    base = name.split("_", 1)[1] if "_" in name else ""
    return ranges.get(base) if base.endswith("_policy") else None


def run_outside(y: np.ndarray, segments: list[tuple[float, ReferenceRange | None]], dt: float):
    """The out-of-distribution record of a run whose reference is `y` (T, 6), sampled every
    `dt` s, cued by policies that took over at the given times (the first at 0), each with
    its range; None when a policy that ran has no range."""
    if any(r is None for _, r in segments):
        return None
    mask = np.zeros(np.shape(y), dtype=bool)
    starts = [math.floor(t / dt + 1e-9) for t, _ in segments] + [len(y)]
    for (_, ranges), start, end in zip(segments, starts, starts[1:], strict=False):
        mask[start:end] = outside(y[start:end], ranges)
    return outside_share(mask)


__all__ = [
    "RANGE_QUANTILE",
    "ReferenceRange",
    "outside",
    "outside_share",
    "policy_reference_range",
    "reference_range",
    "run_outside",
    "shipped_ranges",
]
