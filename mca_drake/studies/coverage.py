"""What a training set covers: per-vehicle spread of its references beside the evaluation's.

A policy learns the motion it is shown. `dataset_reference_spread` gives, per vehicle of a
closed-loop dataset (`closed_loop_dataset`), the standard deviation of every scaled
reference channel (w_x, w_y, w_z rad/s; f_x, f_y, a_z m/s^2, as the MCA sees them) and the
99th percentile of |a_z|; `flight_reference_spread` gives the same for built-in flights
(the evaluation cases'), so the two can be read side by side (`spread_markdown`).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from mca_drake.conventions import CHANNELS
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.references.reference import ReferenceScaling
from mca_drake.segments import SOURCE_COLUMNS, SegmentDataset


def spread(y: np.ndarray, flights: int) -> dict:
    """Spread of references y (T, 6) pooled over `flights` flights: {"flights", "minutes",
    "std" (6 channels), "a_z_p99" (m/s^2)}."""
    y = np.asarray(y, float).reshape(-1, len(CHANNELS))
    return {
        "flights": int(flights),
        "minutes": round(y.shape[0] * 0.01 / 60.0, 1),
        "std": [round(float(v), 4) for v in y.std(axis=0)],
        "a_z_p99": round(float(np.percentile(np.abs(y[:, CHANNELS.index("a_z")]), 99)), 3),
    }


def dataset_reference_spread(dataset: SegmentDataset) -> dict[str, dict]:
    """Per vehicle of a merged closed-loop dataset (its `flight_vehicles` metadata; a
    one-vehicle set's config vehicle otherwise), the `spread` of its references R."""
    if "R" not in dataset.arrays:
        raise ValueError("the dataset holds no references R (not a closed-loop dataset)")
    seeds = dataset.source[:, SOURCE_COLUMNS.index("flight_seed")]
    meta = dataset.metadata
    by_seed = {int(k): v for k, v in meta.get("flight_vehicles", {}).items()}
    fallback = meta.get("config", {}).get("vehicle", "unknown")
    vehicles = np.array([by_seed.get(int(s), fallback) for s in seeds])
    out = {}
    for vehicle in dict.fromkeys(vehicles.tolist()):
        rows = vehicles == vehicle
        out[vehicle] = spread(dataset.arrays["R"][rows], len(np.unique(seeds[rows])))
    out["all"] = spread(dataset.arrays["R"], len(np.unique(seeds)))
    return out


def flight_reference_spread(
    flights: Iterable[tuple[str, int]],
    duration_s: float,
    *,
    scaling: ReferenceScaling | None = None,
    cache_dir: str | Path | None = None,
) -> dict[str, dict]:
    """Per vehicle, the `spread` of the references of built-in flights (vehicle, seed) of
    `duration_s` s (flown, or read from `cache_dir`)."""
    grouped: dict[str, list[np.ndarray]] = {}
    for vehicle, seed in flights:
        reference = flight_reference(
            FlightSpec(vehicle=vehicle, seed=seed),
            duration_s,
            scaling=scaling,
            cache_dir=cache_dir,
        )
        grouped.setdefault(vehicle, []).append(reference.y)
    out = {v: spread(np.concatenate(ys), len(ys)) for v, ys in grouped.items()}
    out["all"] = spread(
        np.concatenate([y for ys in grouped.values() for y in ys]),
        sum(len(ys) for ys in grouped.values()),
    )
    return out


def spread_markdown(tables: dict[str, dict[str, dict]]) -> str:
    """Markdown of several spread tables ({title: `dataset_reference_spread` or
    `flight_reference_spread` result}), one row per vehicle."""
    header = " | ".join(f"std {c}" for c in CHANNELS)
    lines = [
        f"| set | vehicle | flights | minutes | {header} | p99 abs a_z |",
        "|---" * (5 + len(CHANNELS)) + "|",
    ]
    for title, table in tables.items():
        for vehicle, s in table.items():
            stds = " | ".join(f"{v:.3f}" for v in s["std"])
            lines.append(
                f"| {title} | {vehicle} | {s['flights']} | {s['minutes']:.1f} | {stds} | "
                f"{s['a_z_p99']:.2f} |"
            )
    return "\n".join(lines) + "\n"
