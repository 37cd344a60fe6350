"""The offline-optimal bound of one flight: solve time, memory, iterations and KKT residual.

    python benchmarks/bench_optimal.py [--duration 300] [--vehicle light] [--seed 1000]
        [--objectives inertial,perceived] [--json results/optimal.json]

Per objective, `run_optimal_bound` on one evaluation flight (analytical plant) from the
NMPC-rti's closed-loop trajectory: the solve's wall time (the Gauss-Newton iterations, one
core: BLAS limited to one thread), the peak resident memory of a process that does only
that (each objective in a subprocess of its own, so that one's memory does not hide the
other's), the iterations, the KKT residual reached and whether it met the tolerance, and
the bound's PI and perceived PI beside the NMPC-rti's and zero motion's. The target is a
300 s flight in at most 10 minutes.

The machine's calibration is printed first; every figure goes to `--json` with its
provenance, by default `benchmarks/results/optimal.json`.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import default_result_path, print_calibration, result_header

OBJECTIVES = ("inertial", "perceived")


def solve_one(vehicle: str, seed: int, duration_s: float, objective: str) -> dict:
    """The bound of one flight with one objective, in this process: its figures."""
    from threadpoolctl import threadpool_limits

    from mca_drake.cueing.optimal import OptimalConfig
    from mca_drake.platforms.files import load_platform
    from mca_drake.references.flights import FlightSpec, flight_reference
    from mca_drake.simulation.optimal_bound import run_optimal_bound

    KR500 = load_platform("kr500")

    reference = flight_reference(FlightSpec(vehicle=vehicle, seed=seed), duration_s)
    start = time.perf_counter()
    with threadpool_limits(limits=1):
        result = run_optimal_bound(
            reference=reference,
            config=OptimalConfig(objective=objective),
            progress=True,
            robot=KR500,
        )
    s = result.summary
    solver = s["solver"]
    return {
        "objective": objective,
        "wall_s": time.perf_counter() - start,
        "solve_s": solver["solve_time_s"],
        "iterations": solver["iterations"],
        "kkt_residual": solver["kkt_residual"],
        "converged": solver["converged"],
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "pi": s["pi"],
        "perceived_pi": s["perceived"]["pi"],
        "pi_zero_motion": s["pi_zero_motion"],
        "start": solver["start"],
        "start_costs": solver["start_costs"],
        "cost": solver["cost"],
        "violations": s["violations"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=300.0, help="flight length, s")
    parser.add_argument("--vehicle", default="light")
    parser.add_argument("--seed", type=int, default=1000, help="an evaluation flight's seed")
    parser.add_argument("--objectives", default=",".join(OBJECTIVES))
    parser.add_argument("--json", default=default_result_path("optimal.json"))
    parser.add_argument("--one", help=argparse.SUPPRESS)  # internal: solve one, print JSON
    args = parser.parse_args()
    if args.one:
        figures = solve_one(args.vehicle, args.seed, args.duration, args.one)
        Path(args.json).write_text(json.dumps(figures))
        return
    calibration = print_calibration()
    runs = []
    from mca_drake.atomic_io import atomic_write_json

    def write() -> None:
        """The figures so far, with their provenance (after each objective: a killed run
        keeps what it finished)."""
        result = {
            "provenance": result_header(calibration),
            "flight": {"vehicle": args.vehicle, "seed": args.seed, "duration_s": args.duration},
            "runs": runs,
        }
        atomic_write_json(args.json, result)

    for objective in args.objectives.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "one.json"
            command = [sys.executable, __file__, "--one", objective, "--json", str(out)]
            command += ["--duration", str(args.duration), "--vehicle", args.vehicle]
            command += ["--seed", str(args.seed)]
            env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
            subprocess.run(command, check=True, env=env)
            figures = json.loads(out.read_text())
        runs.append(figures)
        print(
            f"{objective}: {figures['solve_s']:.0f} s, {figures['iterations']} iterations, KKT "
            f"residual {figures['kkt_residual']:.1e}, peak memory {figures['peak_rss_mb']:.0f} "
            f"MB; PI {figures['pi']:.3f}, perceived PI {figures['perceived_pi']:.3f} (zero "
            f"motion PI {figures['pi_zero_motion']:.3f})",
            flush=True,
        )
        write()
    print(f"figures: {args.json}")


if __name__ == "__main__":
    main()
