"""The slowest converged NMPC steps, captured once and replayed: an A/B bench for the solver.

    python benchmarks/replay_nmpc_steps.py capture DIR [--per-case 6] [--flight-duration 60]
    python benchmarks/replay_nmpc_steps.py replay DIR [--baseline CHECKOUT] [--repeats 3]

`capture` runs converged NMPC (shipped weights, analytical plant) in closed loop on the seven
adversarial references (5 s each) and on two development flights (light seed 5, jet seed 6:
neither evaluation nor training seeds) and keeps, per case, the inputs of its slowest solves
(state, references, warm start, active-set guess, output-Hessian estimates) as one .npz per
step in DIR. `replay` solves each of them again with this checkout's solver (and, with
`--baseline`, with another checkout's in a subprocess, one after the other) and prints per
step the time (median of the repeats), the Gauss-Newton iterations and how the solve stopped,
then the totals: time, iterations, the slowest step and the stops. The same starts for both
solvers make iteration counts comparable exactly, which the closed loop cannot (a different
plan moves every later state); `bench_nmpc.py` measures the closed loop.

A stop other than "kkt" deserves a look: a solver change that ends solves early by another
rule (a short damped step, the iteration cap) is not faster, it is less converged.
"""

from __future__ import annotations

import argparse
import collections
import copy
import heapq
import itertools
import time
from pathlib import Path

import numpy as np
from common import print_calibration, run_with_checkout

from mca_drake.atomic_io import atomic_write_json, atomic_write_npz
from mca_drake.cueing.nmpc import MotionCueingOcp, NmpcConfig
from mca_drake.platforms.files import load_platform

KR500 = load_platform("kr500")

# Development flights: (vehicle, seed); seeds outside the evaluation (>= 1000) and training
# (100-140) ranges.
FLIGHTS = (("light", 5), ("jet", 6))


class SlowestSolves:
    """Records the inputs of the `keep` slowest `MotionCueingOcp.solve` calls while active
    (the closed loop builds its own controller, so the class's method is wrapped)."""

    def __init__(self, keep: int):
        self.keep = keep
        self.heap: list = []  # a min-heap of (seconds, call number, inputs)
        self._calls = itertools.count()

    def __enter__(self):
        solve = self._solve = MotionCueingOcp.solve
        record = self._record

        def timed(ocp, x0, refs, U_guess=None, mode=None, active_guess=None, output_hessians=None):
            start = time.perf_counter()
            result = solve(ocp, x0, refs, U_guess, mode, active_guess, output_hessians)
            # solve leaves its inputs as they were: copied only when kept
            record(time.perf_counter() - start, (x0, refs, U_guess, active_guess, output_hessians))
            return result

        MotionCueingOcp.solve = timed
        return self

    def __exit__(self, *exc):
        MotionCueingOcp.solve = self._solve

    def _record(self, seconds: float, inputs: tuple) -> None:
        if len(self.heap) == self.keep and seconds <= self.heap[0][0]:
            return
        item = (seconds, next(self._calls), copy.deepcopy(inputs))
        if len(self.heap) < self.keep:
            heapq.heappush(self.heap, item)
        else:
            heapq.heapreplace(self.heap, item)

    def slowest_first(self) -> list[tuple[float, tuple]]:
        """(seconds, (x0, refs, U_guess, active_guess, output_hessians)), slowest first."""
        return [(t, inputs) for t, _, inputs in sorted(self.heap, reverse=True)]


def capture(directory: Path, per_case: int, flight_duration: float) -> None:
    """Writes the `per_case` slowest converged solves of every case to `directory`."""
    # imported here: only capturing flies references
    from mca_drake.references.adversarial import ADVERSARIAL_KINDS, adversarial_reference
    from mca_drake.references.flights import FlightSpec, flight_reference
    from mca_drake.simulation.closed_loop import run_closed_loop

    cases = [(kind, adversarial_reference(kind, 5.0), 5.0) for kind in ADVERSARIAL_KINDS]
    for vehicle, seed in FLIGHTS:
        reference = flight_reference(FlightSpec(vehicle=vehicle, seed=seed), flight_duration)
        cases.append((f"{vehicle}{seed}", reference, flight_duration))
    directory.mkdir(parents=True, exist_ok=True)
    for name, reference, duration in cases:
        with SlowestSolves(per_case) as recorder:
            run_closed_loop(
                mca=NmpcConfig(mode="converged"),
                reference=reference,
                duration_s=duration,
                progress=False,
                robot=KR500,
            )
        for rank, (seconds, inputs) in enumerate(recorder.slowest_first()):
            names = ("x0", "refs", "U", "active", "hessians")
            # a None (no warm start, guess or estimates) is left out and read back as None
            arrays = {k: v for k, v in zip(names, inputs, strict=True) if v is not None}
            atomic_write_npz(directory / f"{name}_{rank}.npz", arrays)
            print(f"{name}_{rank}: {seconds * 1e3:.1f} ms", flush=True)


def replay(directory: Path, repeats: int) -> dict:
    """{step name: {ms, iterations, stop, cost}} of this checkout's solver on every step."""
    files = sorted(directory.glob("*.npz"))
    if not files:
        raise SystemExit(f"no captured steps (*.npz) in {directory}: run 'capture' first")
    ocp = MotionCueingOcp(NmpcConfig(mode="converged"), load_platform("kr500"))
    out = {}
    for path in files:
        with np.load(path) as f:
            inputs = {k: f[k] for k in f.files}
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            result = ocp.solve(
                inputs["x0"],
                inputs["refs"],
                U_guess=inputs.get("U"),
                active_guess=inputs.get("active"),
                output_hessians=inputs.get("hessians"),
            )
            times.append(time.perf_counter() - start)
        out[path.stem] = {
            "ms": float(np.median(times)) * 1e3,
            "iterations": result.iterations,
            "stop": result.stop,
            "cost": result.cost,
        }
    return out


def totals(steps: dict) -> str:
    """One line: total time and iterations, the slowest step, the stops."""
    slowest = max(steps, key=lambda name: steps[name]["ms"])
    stops = dict(collections.Counter(s["stop"] for s in steps.values()))
    return (
        f"total {sum(s['ms'] for s in steps.values()):.0f} ms, "
        f"{sum(s['iterations'] for s in steps.values())} iterations; slowest {slowest} "
        f"{steps[slowest]['ms']:.1f} ms ({steps[slowest]['iterations']} iterations); stops {stops}"
    )


def replay_elsewhere(checkout: str, directory: Path, repeats: int) -> dict:
    """`replay` with the mca_drake of another checkout, in a subprocess."""
    return run_with_checkout(
        checkout,
        __file__,
        lambda out: ["replay", str(directory), "--repeats", str(repeats), "--json", out, "--quiet"],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    cap = sub.add_parser("capture", help="record the slowest converged steps")
    cap.add_argument("directory", type=Path)
    cap.add_argument("--per-case", type=int, default=6)
    cap.add_argument("--flight-duration", type=float, default=60.0, help="s")
    rep = sub.add_parser("replay", help="solve the recorded steps again")
    rep.add_argument("directory", type=Path)
    rep.add_argument("--repeats", type=int, default=3)
    rep.add_argument("--baseline", help="another checkout, replayed after this one")
    rep.add_argument("--json", help="write the per-step figures here")
    rep.add_argument("--quiet", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.command == "capture":
        capture(args.directory, args.per_case, args.flight_duration)
        return
    if not args.quiet:
        print_calibration()
    steps = replay(args.directory, args.repeats)
    if args.json:
        atomic_write_json(args.json, steps)
    if args.quiet:
        return
    base = replay_elsewhere(args.baseline, args.directory, args.repeats) if args.baseline else None
    for name, s in steps.items():
        line = f"  {name:<12} {s['ms']:7.1f} ms {s['iterations']:3d} it {s['stop']:<10}"
        if base and name in base:
            b = base[name]
            line += f" | baseline {b['ms']:7.1f} ms {b['iterations']:3d} it {b['stop']:<10}"
            line += f" cost {s['cost'] - b['cost']:+.1e}"
        print(line)
    print("this checkout:", totals(steps))
    if base:
        print("baseline:     ", totals(base))


if __name__ == "__main__":
    main()
