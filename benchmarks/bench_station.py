"""Real-time factor of the KR500 station closed loop, and measured-vs-analytical PI.

    python benchmarks/bench_station.py [--minutes 10] [--mca dpc] [--repeats 1] [--seed 1000]
    python benchmarks/bench_station.py --case C [--minutes 5] [--mca dpc]
        [--json results/station_case_c.json]

Runs the MCA at 100 Hz on the 1 kHz MultibodyPlant station (inverse dynamics, head IMU)
over a built-in light-aircraft flight, `repeats` times, and once on the analytical plant.
Prints the real-time factor (simulated s per wall s; median and spread over repeats), the
per-channel RMSE/CC and PI of both plants, and their PI difference. Targets: real-time
factor >= 10 for a 10-minute DPC flight; |PI_multibody - PI_analytical| <= 0.1.

`--case C` (or A, B) instead flies every flight of that case of the evaluation suite
(`mca_drake.studies.evaluation.default_cases`; C: aircraft used in neither training nor
tuning) on both plants and prints per flight the two PIs and their difference, then the
median and largest |difference| (target: within 0.1 on case C), and writes them with their
provenance (date, command, calibration, machine) to `--json`, by default
`benchmarks/results/station_case_<case>.json`.
"""

from __future__ import annotations

import argparse
import os
import platform

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.platforms.files import load_platform
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.references.jsbsim import fly
from mca_drake.references.reference import reference_from_recording
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.evaluation import default_cases

KR500 = load_platform("kr500")


def compare_case(
    case_name: str, mca: str, duration: float, json_path: str, calibration: dict[str, float]
) -> None:
    """Station against analytical plant on every flight of an evaluation case (`duration`
    s each); the figures go to `json_path`."""
    cases = {case.name: case for case in default_cases()}
    if case_name not in cases:
        raise SystemExit(f"unknown case '{case_name}'; valid: {', '.join(cases)}")
    case = cases[case_name]
    print(f"{mca}, case {case.name} ({case.label()}), {duration:.0f} s flights, 1 kHz plant")
    rows = []
    for seed in case.seeds:
        vehicle = case.vehicle_of(seed)
        reference = flight_reference(FlightSpec(vehicle=vehicle, seed=seed), duration)
        station, analytical = (
            run_closed_loop(
                plant=plant,
                mca=mca,
                reference=reference,
                duration_s=duration,
                progress=False,
                robot=KR500,
            ).summary
            for plant in ("multibody", "analytical")
        )
        row = {
            "vehicle": vehicle,
            "seed": seed,
            "pi_multibody": station["pi"],
            "pi_analytical": analytical["pi"],
            "pi_zero_motion": analytical["pi_zero_motion"],
            "difference": station["pi"] - analytical["pi"],
            "realtime_factor_multibody": station["realtime_factor"],
            "violations_multibody": int(sum(station["violations"].values())),
        }
        rows.append(row)
        print(
            f"  {vehicle:9s} {seed}: PI multibody {row['pi_multibody']:+.4f}, analytical "
            f"{row['pi_analytical']:+.4f} (zero motion {row['pi_zero_motion']:+.4f}), "
            f"difference {row['difference']:+.4f}; real-time factor "
            f"{row['realtime_factor_multibody']:.1f}; violations {row['violations_multibody']}",
            flush=True,
        )
    gaps = np.abs([r["difference"] for r in rows])
    print(
        f"|PI multibody - PI analytical|: median {np.median(gaps):.4f}, max {gaps.max():.4f} "
        f"over {len(rows)} flights (target <= 0.1)"
    )
    report = {"provenance": result_header(calibration), "case": case.name, "mca": mca}
    atomic_write_json(json_path, report | {"flights": rows})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--mca", default="dpc")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument(
        "--json",
        help="write the figures to this JSON file (with --case: by default "
        "benchmarks/results/station_case_<case>.json)",
    )
    parser.add_argument("--case", help="an evaluation case (A, B, C): station vs analytical")
    args = parser.parse_args()
    calibration = print_calibration()
    if args.case:
        json_path = args.json or default_result_path(f"station_case_{args.case.lower()}.json")
        compare_case(args.case, args.mca, 60.0 * args.minutes, json_path, calibration)
        return
    duration = 60.0 * args.minutes
    reference = reference_from_recording(
        fly("light", duration, args.seed), name=f"light {args.seed}"
    )
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores")
    print(f"{args.mca}, {duration:.0f} s light flight seed {args.seed}, 1 kHz plant")
    rtf, station = [], None
    for _ in range(args.repeats):
        station = run_closed_loop(
            plant="multibody",
            mca=args.mca,
            reference=reference,
            duration_s=duration,
            progress=False,
            robot=KR500,
        )
        rtf.append(station.summary["realtime_factor"])
        print(f"  multibody run: real-time factor {rtf[-1]:.1f}")
    analytical = run_closed_loop(
        mca=args.mca, reference=reference, duration_s=duration, progress=False, robot=KR500
    )
    s, a = station.summary, analytical.summary
    print(
        f"real-time factor (multibody): median {np.median(rtf):.1f} "
        f"(min {min(rtf):.1f}, max {max(rtf):.1f}, n {len(rtf)}); analytical plant: "
        f"{a['realtime_factor']:.1f}"
    )
    print(f"{'':16}" + "".join(f"{c:>9}" for c in ("w_x", "w_y", "w_z", "f_x", "f_y", "a_z")))
    for name, summ in (("multibody", s), ("analytical", a)):
        print(f"{name + ' RMSE':<16}" + "".join(f"{v:9.4f}" for v in summ["rmse"]))
        print(f"{name + ' CC':<16}" + "".join(f"{v:9.4f}" for v in summ["cc"]))
    print(
        f"PI multibody {s['pi']:.4f}, analytical {a['pi']:.4f} (zero motion "
        f"{a['pi_zero_motion']:.4f}), "
        f"difference {s['pi'] - a['pi']:+.4f} (target |d| <= 0.1)"
    )
    print(
        f"joint tracking error rms {s['joint_tracking_error_rad']['rms']:.2e} rad, max "
        f"{s['joint_tracking_error_rad']['max']:.2e} rad; violations {s['violations']}; "
        f"DPC step median {s['step_time_s']['median'] * 1e6:.1f} us"
    )
    if args.json:
        figures = {
            "provenance": result_header(calibration),
            "realtime_factor": rtf,
            "pi_multibody": s["pi"],
            "pi_analytical": a["pi"],
            "summary_multibody": s,
            "summary_analytical": a,
        }
        atomic_write_json(args.json, figures)


if __name__ == "__main__":
    main()
