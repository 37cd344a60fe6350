"""Helpers for the benchmark scripts: repeated wall-clock samples, median and spread; the
machine's calibration and the `provenance` block of a result file; the `--mca` argument of
the scripts that compare MCAs."""

from __future__ import annotations

import datetime
import json
import os
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

# Where each benchmark writes its current result file by default (benchmarks/README.md).
RESULTS_DIR = Path(__file__).resolve().parent / "results"


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


def in_ms(figures: dict) -> dict:
    """Figures in seconds (a summary such as {median, p99, max}) as strings in ms, three
    decimals; None (JSON's null for NaN) as "-"."""
    return {k: "-" if v is None else f"{v * 1e3:.3f}" for k, v in figures.items()}


def run_with_checkout(checkout: str, script: str, args_for: Callable[[str], list[str]]) -> dict:
    """Runs the benchmark `script` with the mca_drake of another `checkout` (e.g. a `git
    worktree` of an older commit) in a subprocess, and returns the JSON it writes to the path
    that `args_for(path)` passes it (its command-line arguments): a before-and-after in one
    run, on the same machine under the same load."""
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "figures.json")
        env = dict(os.environ, PYTHONPATH=str(Path(checkout).resolve()))
        subprocess.run([sys.executable, script, *args_for(out)], env=env, check=True)
        return json.loads(Path(out).read_text())


def calibration_s() -> dict[str, float]:
    """Wall time of a fixed numpy workload (200 products of 200 x 200 matrices) and a fixed
    pure-Python loop (2e6 additions), the best of three each, s."""
    rng = np.random.default_rng(0)
    a = rng.standard_normal((200, 200))

    def numpy_work():
        b = a
        for _ in range(200):
            b = np.tanh(a @ b)

    def python_work():
        total = 0
        for i in range(2_000_000):
            total += i

    out = {}
    for name, work in (("numpy_s", numpy_work), ("python_s", python_work)):
        times = []
        for _ in range(3):
            start = time.perf_counter()
            work()
            times.append(time.perf_counter() - start)
        out[name] = min(times)
    return out


def print_calibration() -> dict[str, float]:
    """Prints (and returns) `calibration_s` with the machine's core count and CPU, so that
    figures from different machines (or loads) can be compared: every benchmark starts so."""
    figures = calibration_s()
    print(
        f"calibration: numpy {figures['numpy_s'] * 1e3:.1f} ms, pure Python "
        f"{figures['python_s'] * 1e3:.1f} ms; {os.cpu_count()} cores, "
        f"{platform.processor() or platform.machine()}",
        flush=True,
    )
    return figures


def machine() -> dict:
    """The machine a result was measured on: core count and CPU as the platform names it."""
    return {"cores": os.cpu_count(), "cpu": platform.processor() or platform.machine()}


def result_header(calibration: dict[str, float] | None = None) -> dict:
    """The `provenance` block every result file starts with: the UTC date (ISO), the command
    line that wrote it, the machine's calibration (`calibration_s`, s; measured now unless
    given) and the machine, so that figures from different days and machines compare."""
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).date().isoformat(),
        "command": shlex.join(["python", *sys.argv]),
        "calibration": calibration_s() if calibration is None else calibration,
        "machine": machine(),
    }


def default_result_path(name: str) -> str:
    """The stable path of a benchmark's current result file, `benchmarks/results/<name>`,
    whatever the working directory."""
    return str(RESULTS_DIR / name)


def parse_mca(text: str):
    """(label, MCA) of a `--mca` argument: `label=policy.npz` is a DPC with that policy file
    (SystemExit if it is missing), anything else an MCA name that labels itself."""
    # mca_drake's cueing configs: only the scripts that compare MCAs need them
    from mca_drake.cueing.dpc import DpcConfig

    label, _, policy = text.partition("=")
    if not policy:
        return label, label
    if not Path(policy).is_file():
        raise SystemExit(f"--mca {text}: policy file {policy!r} not found")
    return label, DpcConfig(policy=policy)
