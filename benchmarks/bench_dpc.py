"""DPC step time inside the Drake diagram, and the converged-NMPC / DPC step-time ratio
measured in the same run on the same flight.

    python benchmarks/bench_dpc.py [--policy results/policy/policy.npz] [--seconds 60]
        [--converged-seconds 20]

Without --policy the shipped default is used, or, if there is none yet, an untrained
network (the step time does not depend on the weights; the PI printed then means nothing).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from common import print_calibration

from mca_drake.cueing import DpcConfig
from mca_drake.references.jsbsim import fly
from mca_drake.references.reference import reference_from_recording
from mca_drake.simulation.closed_loop import run_closed_loop


def _policy_path(arg: str | None, folder: str) -> tuple[str, str]:
    if arg:
        return arg, "given"
    from mca_drake.cueing.dpc import default_policy_path

    try:
        return str(default_policy_path()), "shipped default"
    except FileNotFoundError:
        import torch

        from mca_drake.learning.policy import PolicyNetwork, save_policy

        torch.manual_seed(0)
        path = Path(folder) / "untrained.npz"
        save_policy(path, PolicyNetwork(), {"note": "untrained, for timing only"})
        return str(path), "untrained (timing only)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--policy")
    parser.add_argument("--seconds", type=float, default=60.0, help="DPC flight length")
    parser.add_argument("--converged-seconds", type=float, default=20.0)
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args()
    print_calibration()
    reference = reference_from_recording(fly("light", max(args.seconds, 30.0), args.seed))
    with tempfile.TemporaryDirectory() as folder:
        policy, kind = _policy_path(args.policy, folder)
        results = {}
        configs = {"dpc": DpcConfig(policy=str(policy)), "nmpc-converged": "nmpc-converged"}
        for mca, seconds in (("dpc", args.seconds), ("nmpc-converged", args.converged_seconds)):
            r = run_closed_loop(
                mca=configs[mca], reference=reference, duration_s=seconds, progress=False
            )
            results[mca] = r
            t = r.step_times_s
            print(
                f"{mca:15s} {seconds:4.0f} s: step median {np.median(t) * 1e6:9.1f} us, "
                f"p10 {np.percentile(t, 10) * 1e6:9.1f}, p90 {np.percentile(t, 90) * 1e6:9.1f}, "
                f"p99 {np.percentile(t, 99) * 1e6:9.1f}, max {t.max() * 1e6:9.1f}; "
                f"PI {r.summary['pi']:.3f} (zero motion {r.summary['pi_zero_motion']:.3f}); "
                f"{r.summary['realtime_factor']:.1f}x real time"
            )
    ratio = np.median(results["nmpc-converged"].step_times_s) / np.median(
        results["dpc"].step_times_s
    )
    print(f"policy: {kind}; converged NMPC / DPC median step time: {ratio:.0f}x")


if __name__ == "__main__":
    main()
