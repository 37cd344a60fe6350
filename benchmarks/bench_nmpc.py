"""NMPC step times and PI, both modes, at the shipped (tuned) weights and the paper's.

    python benchmarks/bench_nmpc.py [--duration 300] [--converged-duration 300]
        [--vehicle light] [--seed 1000] [--adversarial-duration 5]
        [--baseline DIR --baseline-converged-duration 30] [--json results/nmpc.json]

On one evaluation flight (analytical plant, closed loop), per weight set and mode: step
median, p99 and max (ms) and the PI; then the PI gap rti - converged over the converged
window. First, a profile of both modes (where a step's time goes). Then converged NMPC
(shipped weights) on the adversarial references (3 g steps, 3 rad/s spins, a 1 g chirp):
step median and max. From the converged mean step time it extrapolates the default-size
evaluation suite's converged cost (20 flights x 300 s).

`--baseline DIR` runs the same flight (and adversarial) measurements with the mca_drake of
another checkout (e.g. `git worktree add /tmp/base <commit>`) in a subprocess, one after the
other in this run, so that before and after are timed under the same conditions; converged
mode there may be slow, hence its own window (a shorter one is rerun here for the PI).
The machine's calibration is printed first. Every figure goes to `--json` with its
provenance (date, command, calibration, machine), by default `benchmarks/results/nmpc.json`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from common import default_result_path, print_calibration, result_header, run_with_checkout

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing import NmpcConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")

# Runs of the default-size evaluation suite that use converged NMPC: cases A and B,
# 10 flights each, 300 s at 100 Hz.
SUITE_CONVERGED_STEPS = 2 * 10 * 300 * 100


# The fields of NmpcConfig that tuning sets ("shipped" weights are this checkout's defaults).
WEIGHT_FIELDS = (
    "output_weights",
    "input_weight",
    "washout_weight",
    "terminal_position_weight",
    "terminal_velocity_weight",
)


def shipped_weights() -> dict:
    """This checkout's default (tuned) NMPC weights."""
    default = NmpcConfig()
    return {name: getattr(default, name) for name in WEIGHT_FIELDS}


def measure_flight(
    vehicle: str, seed: int, duration_s: float, converged_s: float, weights: dict
) -> dict:
    """Both modes at both weight sets ("shipped": `weights`; "paper") on one flight:
    {label: figures}. Uses only what every checkout since the typed configs has, so that
    --baseline times an older checkout at the same weights."""
    reference = flight_reference(FlightSpec(vehicle=vehicle, seed=seed), duration_s)
    out = {}
    for label in ("shipped", "paper"):
        for mode, seconds in (("rti", duration_s), ("converged", converged_s)):
            config = (
                NmpcConfig(mode=mode, **weights) if label == "shipped" else NmpcConfig.paper(mode)
            )
            result = run_closed_loop(
                mca=config, reference=reference, duration_s=seconds, progress=False, robot=KR500
            )
            out[f"{label}/{mode}"] = _figures(result, seconds)
            print(f"  {label:8s} {mode:9s} {_line(out[f'{label}/{mode}'])}", flush=True)
        if converged_s < duration_s:  # rti over the converged window, for the PI gap
            config = (
                NmpcConfig(mode="rti", **weights) if label == "shipped" else NmpcConfig.paper("rti")
            )
            result = run_closed_loop(
                mca=config, reference=reference, duration_s=converged_s, progress=False, robot=KR500
            )
            out[f"{label}/rti_window"] = _figures(result, converged_s)
    return out


def _figures(result, seconds: float) -> dict:
    steps = np.asarray(result.step_times_s, dtype=float)
    s = result.summary
    return {
        "seconds": seconds,
        "median_ms": float(np.median(steps) * 1e3),
        "p99_ms": float(np.percentile(steps, 99) * 1e3),
        "max_ms": float(steps.max() * 1e3),
        "mean_ms": float(steps.mean() * 1e3),
        "pi": float(s["pi"]),
        "violations": int(sum(s["violations"].values())),
        "failures": int(s["solver_failures"]),
    }


def _line(f: dict) -> str:
    return (
        f"{f['seconds']:5.0f} s: step median {f['median_ms']:6.2f} ms, p99 {f['p99_ms']:6.2f}, "
        f"max {f['max_ms']:7.2f}; PI {f['pi']:+.4f}; "
        f"violations {f['violations']}, failures {f['failures']}"
    )


def measure_adversarial(duration_s: float) -> dict:
    """Converged NMPC (shipped weights) on every adversarial reference."""
    from mca_drake.references.adversarial import ADVERSARIAL_KINDS, adversarial_reference

    out = {}
    for kind in ADVERSARIAL_KINDS:
        result = run_closed_loop(
            mca=NmpcConfig(mode="converged"),
            reference=adversarial_reference(kind, duration_s),
            duration_s=duration_s,
            progress=False,
            robot=KR500,
        )
        out[kind] = _figures(result, duration_s)
        print(f"  {kind:8s} {_line(out[kind])}", flush=True)
    return out


# Where an NMPC step's time goes: (label, functions whose cumulative time it is).
PROFILE_PARTS = (
    ("output Jacobians (kinematics)", ("plant_output_jacobians",)),
    ("Gauss-Newton model (H, g)", ("_gauss_newton",)),
    ("QP on the guessed active set", ("_on_active_set",)),
    ("dual active-set QP (from the guess)", ("solve_dual_active_set",)),
    ("Drake QP set-up (stage costs)", ("_update_qp",)),
    ("Drake QP solve", ("_solve_qp",)),
    ("line search (true cost)", ("cost",)),
    ("output Hessians (start, update)", ("_starting_hessians", "psb_update")),
    ("curvature model (assembly, convexity)", ("_convex_model",)),
    ("whole solve", ("_solve",)),
)


def profile_modes(vehicle: str, seed: int, seconds: float) -> dict:
    """cProfile of both modes (shipped weights) on `seconds` of the flight: the share of
    the solve's time in each part of PROFILE_PARTS (parts nest: the model holds the
    Jacobians)."""
    import cProfile
    import pstats

    reference = flight_reference(FlightSpec(vehicle=vehicle, seed=seed), seconds)
    out = {}
    for mode in ("rti", "converged"):
        profiler = cProfile.Profile()
        profiler.enable()
        run_closed_loop(
            mca=NmpcConfig(mode=mode),
            reference=reference,
            duration_s=seconds,
            progress=False,
            robot=KR500,
        )
        profiler.disable()
        stats = pstats.Stats(profiler).stats  # {(file, line, name): (cc, nc, tt, ct, callers)}
        cumulative = {}
        for (file, _, name), (_, _, _, ct, _) in stats.items():
            if "mca_drake" in file:
                cumulative[name] = cumulative.get(name, 0.0) + ct
        steps = round(seconds / 0.01)
        out[mode] = {
            label: sum(cumulative.get(n, 0.0) for n in names) / steps * 1e3
            for label, names in PROFILE_PARTS
        }
        print(f"  {mode} (ms per step, under the profiler):", flush=True)
        for label, ms in out[mode].items():
            print(f"    {label:32s} {ms:7.3f}")
    return out


def run_baseline(directory: str, args) -> dict:
    """measure_flight with the mca_drake of `directory`, in a subprocess."""
    return run_with_checkout(
        directory,
        __file__,
        lambda out: [
            *("--measure-flight-only", out),
            *("--vehicle", args.vehicle, "--seed", str(args.seed)),
            *("--duration", str(args.duration)),
            *("--converged-duration", str(args.baseline_converged_duration)),
            *("--adversarial-duration", str(args.adversarial_duration)),
            *("--weights", json.dumps(shipped_weights())),
        ],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--vehicle", default="light")
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--duration", type=float, default=300.0, help="rti flight, s")
    parser.add_argument("--converged-duration", type=float, default=300.0)
    parser.add_argument("--adversarial-duration", type=float, default=5.0, help="0: skip")
    parser.add_argument("--baseline", help="a checkout to compare with (its mca_drake)")
    parser.add_argument("--baseline-converged-duration", type=float, default=30.0)
    parser.add_argument("--profile", type=float, default=20.0, help="profiled seconds, 0: none")
    parser.add_argument(
        "--json", default=default_result_path("nmpc.json"), help="write every figure here"
    )
    parser.add_argument("--measure-flight-only", help=argparse.SUPPRESS)
    parser.add_argument("--weights", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure_flight_only:  # the --baseline subprocess
        import mca_drake

        print(f"baseline: {Path(mca_drake.__file__).parent}", flush=True)
        figures = measure_flight(
            args.vehicle,
            args.seed,
            args.duration,
            args.converged_duration,
            json.loads(args.weights),
        )
        if args.adversarial_duration > 0:
            print("  adversarial references, converged:", flush=True)
            figures["adversarial"] = measure_adversarial(args.adversarial_duration)
        Path(args.measure_flight_only).write_text(json.dumps(figures))
        return
    report = {"provenance": result_header(print_calibration())}
    if args.profile > 0:
        print(f"profile, {args.profile:g} s of the flight:", flush=True)
        report["profile"] = profile_modes(args.vehicle, args.seed, args.profile)
    print(f"{args.vehicle} flight, seed {args.seed}, analytical plant:", flush=True)
    report["shipped_weights"] = shipped_weights()
    report["flight"] = measure_flight(
        args.vehicle, args.seed, args.duration, args.converged_duration, shipped_weights()
    )
    for weights in ("shipped", "paper"):
        flight = report["flight"]
        rti = flight.get(f"{weights}/rti_window", flight[f"{weights}/rti"])
        gap = rti["pi"] - flight[f"{weights}/converged"]["pi"]
        print(f"PI gap rti - converged, {weights} weights: {gap:+.4f}")
    converged = report["flight"]["shipped/converged"]
    core_hours = converged["mean_ms"] * 1e-3 * SUITE_CONVERGED_STEPS / 3600
    report["suite_converged_core_hours"] = core_hours
    print(
        f"default-size suite, converged NMPC: {core_hours:.2f} core-hours "
        f"(mean step {converged['mean_ms']:.2f} ms x {SUITE_CONVERGED_STEPS} steps)"
    )
    if args.adversarial_duration > 0:
        print(f"adversarial references, converged, {args.adversarial_duration:g} s each:")
        report["adversarial"] = measure_adversarial(args.adversarial_duration)
        medians = [f["median_ms"] for f in report["adversarial"].values()]
        worst = max(f["max_ms"] for f in report["adversarial"].values())
        print(f"  adversarial: median of medians {np.median(medians):.2f} ms, max {worst:.2f}")
    if args.baseline:
        print(f"baseline {args.baseline}:", flush=True)
        report["baseline"] = run_baseline(args.baseline, args)
        # the converged PI over the baseline's (shorter) window, with this checkout
        window = args.baseline_converged_duration
        reference = flight_reference(FlightSpec(vehicle=args.vehicle, seed=args.seed), window)
        same_window = {}
        for weights in ("shipped", "paper") if window != args.converged_duration else ():
            config = (
                NmpcConfig(mode="converged")  # the shipped weights are the defaults here
                if weights == "shipped"
                else NmpcConfig.paper("converged")
            )
            result = run_closed_loop(
                mca=config, reference=reference, duration_s=window, progress=False, robot=KR500
            )
            same_window[f"{weights}/converged"] = _figures(result, window)
        report["converged_on_baseline_window"] = same_window
        compared = [
            (label, before, same_window.get(label, report["flight"][label]))
            for label, before in report["baseline"].items()
            if label not in ("adversarial",) and not label.endswith("rti_window")
        ]
        compared += [
            (f"adversarial {kind}", before, report["adversarial"][kind])
            for kind, before in report["baseline"].get("adversarial", {}).items()
        ]
        for label, before, after in compared:
            print(
                f"  {label:20s} ({before['seconds']:.0f} s) step median "
                f"{before['median_ms']:.2f} -> {after['median_ms']:.2f} ms, p99 "
                f"{before['p99_ms']:.2f} -> {after['p99_ms']:.2f}, max {before['max_ms']:.2f} "
                f"-> {after['max_ms']:.2f}; PI {before['pi']:+.4f} -> {after['pi']:+.4f} "
                f"({after['pi'] - before['pi']:+.4f})"
            )
    if args.json:
        atomic_write_json(args.json, report)


if __name__ == "__main__":
    main()
