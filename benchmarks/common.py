"""Timing helpers for the benchmark scripts: repeated wall-clock samples, median and spread."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def time_calls(fn: Callable[[], object], *, repeats: int, warmup: int = 3) -> list[float]:
    """Wall-clock seconds of `repeats` calls of `fn` after `warmup` untimed calls."""
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - start)
    return samples


def describe(samples: list[float], unit: str = "ms") -> str:
    """'median X (p10 A, p90 B, n N) unit' for samples in seconds."""
    scale = {"s": 1.0, "ms": 1e3, "us": 1e6}[unit]
    ordered = sorted(samples)
    p10 = ordered[int(0.1 * (len(ordered) - 1))]
    p90 = ordered[int(0.9 * (len(ordered) - 1))]
    return (
        f"median {statistics.median(samples) * scale:.3f} {unit} "
        f"(p10 {p10 * scale:.3f}, p90 {p90 * scale:.3f}, n {len(samples)})"
    )
