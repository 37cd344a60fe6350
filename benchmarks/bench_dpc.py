"""DPC step time inside the Drake diagram, and the converged-NMPC / DPC step-time ratio
measured in the same run on the same flight.

    python benchmarks/bench_dpc.py [--policy results/policy/policy.npz] [--seconds 60]
        [--converged-seconds 20] [--repeats 1] [--json results/dpc.json]

On a light-aircraft flight (analytical plant, closed loop), DPC for `--seconds` and then
converged NMPC for `--converged-seconds`, `--repeats` times one after the other: per run the
step time (median, p10, p90, p99, max), the PI and the real-time factor; over the runs the
median step time's median, min and max, and the ratio converged NMPC / DPC. Without --policy
the DPC runs the shipped policy for the light aircraft (`DpcConfig(vehicle="light")`: the
light policy, decision 0016), or, if the install has none, an untrained network (the step
time does not depend on the weights; the PI printed then means nothing). Writes the
figures with their provenance (date, command, calibration, machine) to `--json`, by default
`benchmarks/results/dpc.json`.
"""

from __future__ import annotations

import argparse
import hashlib
import tempfile
from pathlib import Path

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing import DpcConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.jsbsim import fly
from mca_drake.references.reference import reference_from_recording
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")


def _policy_path(arg: str | None, folder: str) -> tuple[str, str]:
    if arg:
        return arg, "given"
    try:
        return str(DpcConfig(vehicle="light").policy_path()), "shipped, light aircraft"
    except FileNotFoundError:
        import torch

        from mca_drake.learning.policy_network import PolicyNetwork, save_policy

        torch.manual_seed(0)
        path = Path(folder) / "untrained.npz"
        save_policy(path, PolicyNetwork(KR500), {"note": "untrained, for timing only"})
        return str(path), "untrained (timing only)"


def _run_figures(result) -> dict:
    """Step-time percentiles (s), PI and real-time factor of one closed-loop run."""
    t = result.step_times_s
    return {
        "step_time_s": {
            "median": float(np.median(t)),
            "p10": float(np.percentile(t, 10)),
            "p90": float(np.percentile(t, 90)),
            "p99": float(np.percentile(t, 99)),
            "max": float(t.max()),
        },
        "pi": result.summary["pi"],
        "pi_zero_motion": result.summary["pi_zero_motion"],
        "realtime_factor": result.summary["realtime_factor"],
    }


def _spread(values: list[float]) -> dict:
    """Median, min and max of `values`."""
    return {"median": float(np.median(values)), "min": min(values), "max": max(values)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy")
    parser.add_argument("--seconds", type=float, default=60.0, help="DPC flight length")
    parser.add_argument("--converged-seconds", type=float, default=20.0)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=1, help="runs of both, one after another")
    parser.add_argument(
        "--json", default=default_result_path("dpc.json"), help="write the figures here"
    )
    args = parser.parse_args()
    calibration = print_calibration()
    reference = reference_from_recording(fly("light", max(args.seconds, 30.0), args.seed))
    seconds_of = {"dpc": args.seconds, "nmpc-converged": args.converged_seconds}
    report = {"provenance": result_header(calibration), "vehicle": "light", "seed": args.seed}
    runs: dict[str, list[dict]] = {mca: [] for mca in seconds_of}
    ratios = []
    with tempfile.TemporaryDirectory() as folder:
        policy, kind = _policy_path(args.policy, folder)
        report["policy"] = kind
        report["policy_sha256"] = hashlib.sha256(Path(policy).read_bytes()).hexdigest()
        configs = {"dpc": DpcConfig(policy=str(policy)), "nmpc-converged": "nmpc-converged"}
        for _ in range(args.repeats):
            results = {}
            for mca, seconds in seconds_of.items():
                r = run_closed_loop(
                    mca=configs[mca],
                    reference=reference,
                    duration_s=seconds,
                    progress=False,
                    robot=KR500,
                )
                results[mca] = r
                runs[mca].append(_run_figures(r))
                t = r.step_times_s
                print(
                    f"{mca:15s} {seconds:4.0f} s: step median {np.median(t) * 1e6:9.1f} us, "
                    f"p10 {np.percentile(t, 10) * 1e6:9.1f}, "
                    f"p90 {np.percentile(t, 90) * 1e6:9.1f}, "
                    f"p99 {np.percentile(t, 99) * 1e6:9.1f}, max {t.max() * 1e6:9.1f}; "
                    f"PI {r.summary['pi']:.3f} (zero motion {r.summary['pi_zero_motion']:.3f}); "
                    f"{r.summary['realtime_factor']:.1f}x real time"
                )
            ratio = np.median(results["nmpc-converged"].step_times_s) / np.median(
                results["dpc"].step_times_s
            )
            ratios.append(float(ratio))
            print(f"policy: {kind}; converged NMPC / DPC median step time: {ratio:.0f}x")
    for mca, seconds in seconds_of.items():
        medians = [run["step_time_s"]["median"] for run in runs[mca]]
        report[mca] = {"seconds": seconds, "runs": runs[mca], "step_median_s": _spread(medians)}
    report["step_time_ratio"] = _spread(ratios)
    atomic_write_json(args.json, report)
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
