"""What a training set covers: per-vehicle spread of its references beside the evaluation's.

A policy learns the motion it is shown. `dataset_reference_spread` gives, per vehicle of a
closed-loop dataset (`closed_loop_dataset`), the standard deviation of every scaled
reference channel (w_x, w_y, w_z rad/s; f_x, f_y, a_z m/s^2, as the MCA sees them) and the
99th percentile of |a_z|; `flight_reference_spread` gives the same for built-in flights
(the evaluation cases'), so the two can be read side by side (`spread_markdown`).
`source_reference_spread` gives it for the references of a training source (the scripted
pilot, random-style pilots, synthetic motion: `references.flights.TRAINING_SOURCES`)
before any MCA has cued them, and `inside_share` how much of the evaluation's motion lies
inside the range a training set spans, channel by channel.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from mca_drake.conventions import CHANNELS
from mca_drake.references.flights import FlightSpec, flight_reference, training_recording
from mca_drake.references.reference import ReferenceScaling, reference_from_recording
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


def flight_references(
    flights: Iterable[tuple[str, int]],
    duration_s: float,
    *,
    pilot: str = "scripted",
    scaling: ReferenceScaling | None = None,
    cache_dir: str | Path | None = None,
) -> dict[str, list[np.ndarray]]:
    """Per vehicle, the references y (T, 6) of built-in flights (vehicle, seed) of
    `duration_s` s flown by `pilot` (flown, or read from `cache_dir`)."""
    grouped: dict[str, list[np.ndarray]] = {}
    for vehicle, seed in flights:
        reference = flight_reference(
            FlightSpec(vehicle=vehicle, seed=seed, pilot=pilot),
            duration_s,
            scaling=scaling,
            cache_dir=cache_dir,
        )
        grouped.setdefault(vehicle, []).append(reference.y)
    return grouped


def source_references(
    source: str,
    flights: Iterable[tuple[str, int]],
    duration_s: float,
    *,
    scaling: ReferenceScaling | None = None,
    cache_dir: str | Path | None = None,
) -> dict[str, list[np.ndarray]]:
    """Per vehicle, the references y (T, 6) of training flights (vehicle, seed) from
    `source` (`references.flights.TRAINING_SOURCES`), scaled as flights are."""
    grouped: dict[str, list[np.ndarray]] = {}
    for vehicle, seed in flights:
        recording = training_recording(source, vehicle, seed, duration_s, cache_dir=cache_dir)
        grouped.setdefault(vehicle, []).append(reference_from_recording(recording, scaling).y)
    return grouped


def grouped_spread(grouped: dict[str, list[np.ndarray]]) -> dict[str, dict]:
    """Per vehicle and over all ("all"), the `spread` of grouped references."""
    out = {v: spread(np.concatenate(ys), len(ys)) for v, ys in grouped.items()}
    out["all"] = spread(
        np.concatenate([y for ys in grouped.values() for y in ys]),
        sum(len(ys) for ys in grouped.values()),
    )
    return out


def flight_reference_spread(
    flights: Iterable[tuple[str, int]],
    duration_s: float,
    *,
    pilot: str = "scripted",
    scaling: ReferenceScaling | None = None,
    cache_dir: str | Path | None = None,
) -> dict[str, dict]:
    """Per vehicle, the `spread` of the references of built-in flights (vehicle, seed) of
    `duration_s` s flown by `pilot` (flown, or read from `cache_dir`)."""
    return grouped_spread(
        flight_references(flights, duration_s, pilot=pilot, scaling=scaling, cache_dir=cache_dir)
    )


def inside_share(training: np.ndarray, evaluation: np.ndarray, tail: float = 0.5) -> list[float]:
    """Per channel, the share of the evaluation's reference samples (T, 6) that lie inside
    the range the training references (T', 6) span, from their `tail` to their 100 - `tail`
    percentile: 1 where training covers every value the evaluation reaches."""
    training = np.asarray(training, float).reshape(-1, len(CHANNELS))
    evaluation = np.asarray(evaluation, float).reshape(-1, len(CHANNELS))
    low, high = np.percentile(training, [tail, 100.0 - tail], axis=0)
    inside = (evaluation >= low) & (evaluation <= high)
    return [round(float(v), 4) for v in inside.mean(axis=0)]


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
