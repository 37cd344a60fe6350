"""Every packaged platform on the same flights: what each MCA cues on it, and at what cost.

    python benchmarks/bench_platforms.py [--flights 4] [--duration 120]
        [--mcas dpc,nmpc-rti,washout] [--bound] [--station-seconds 60]
        [--json results/platforms.json]

Flies the same built-in flights (validation seeds 700.., light aircraft and jet in turn:
flights nothing trains or tunes on, and not the evaluation suite's) through each MCA on
the analytical plant of every packaged platform (`mca-drake platforms`), each MCA as its
name means on that platform (its shipped policy, its tuned settings), and once through
the NMPC-rti on each platform's MultibodyPlant station. Prints and writes, per platform and
MCA: the median PI and perceived PI over the flights (with the interquartile range), the
worst flight, limit violations, joint range used, the MCA's step time (median and p99 over
every step) and, with --bound, the share of the achievable improvement it gets (median
over flights of (PI_zero - PI) / (PI_zero - PI_bound), each flight's offline-optimal bound
on that platform); per platform, the station's real-time factor and how its shipped
policy was trained (command and wall time, from the policy file); and the rail's gain over
the KR500 per channel (median over flights of the RMSE decrease and CC increase). An MCA
name with a suffix runs a variant beside the shipped settings: `nmpc-rti:kr500-weights`
(the KR500's tuned weights on another platform), `nmpc-rti:box` (the NMPC without the legs'
rows). A platform with no shipped policy skips the DPC; the legged platforms' clamp
interventions (commands the legs' limits changed) are counted. The result file holds the
date, command, machine and calibration; the legged platforms' run beside the KR500 is
written with `--platforms kr500,hexapod,rig-2dof,rig-3dof --mcas
dpc,nmpc-rti,nmpc-rti:box,nmpc-rti:kr500-weights,washout --json
benchmarks/results/platforms_legged.json`, and with the bound on 30 s of the same flights
(the hexapod's bound takes minutes per 30 s) with `--mcas dpc,nmpc-rti,washout --bound
--duration 30 --station-seconds 10 --json benchmarks/results/platforms_legged_bound.json`.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.conventions import CHANNELS
from mca_drake.cueing import DpcConfig, mca_config_from_name
from mca_drake.cueing.dpc import load_policy_arrays
from mca_drake.platforms.files import load_platform, packaged_name, packaged_platforms
from mca_drake.platforms.leg_platform import LegPlatform
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.simulation.optimal_bound import run_optimal_bound
from mca_drake.studies.evaluation import improvement_share

FIRST_SEED = 700
VEHICLES = ("light", "jet")


def _flights(count: int) -> list[tuple[str, int]]:
    return [(VEHICLES[i % len(VEHICLES)], FIRST_SEED + i) for i in range(count)]


def _spread(values) -> dict:
    values = np.asarray(values, float)
    q1, median, q3 = np.percentile(values, [25, 50, 75])
    return {"median": float(median), "q1": float(q1), "q3": float(q3)}


def policy_provenance(platform: str) -> dict | None:
    """How the platform's shipped DPC policy was made: its file, command and training wall
    time (this run and the runs its starting weights came from), from the file itself; None
    where none is shipped for it (a legged platform's, so far)."""
    try:
        path = DpcConfig().policy_path(platform)
    except FileNotFoundError:
        return None
    _, metadata = load_policy_arrays(path)
    return {
        "file": path.name,
        "command": metadata.get("command", ""),
        "training_wall_s": metadata.get("training_wall_s"),
        "training_wall_s_total": metadata.get("training_wall_s_total"),
    }


# MCA name suffixes of variants measured beside the shipped settings: ":kr500-weights" (the
# class defaults, tuned on the KR500, instead of the platform's tuned settings) and ":box"
# (the NMPC without the legs' rows: only the coordinates' box and the clamp hold the legs).
VARIANTS = ("kr500-weights", "box")


def mca_variant(mca: str, platform: str):
    """The MCA config of `mca` on `platform` (a packaged name): NAME as it means there, or
    NAME:VARIANT[:VARIANT] (`VARIANTS`)."""
    base, *variants = mca.split(":")
    unknown = set(variants) - set(VARIANTS)
    if unknown:
        raise SystemExit(f"unknown MCA variant {sorted(unknown)}; valid: {', '.join(VARIANTS)}")
    config = mca_config_from_name(base, "" if "kr500-weights" in variants else platform)
    if "box" in variants:
        config = dataclasses.replace(config, leg_constraints=False)
    return config


def variant_differs(mca: str, robot) -> bool:
    """Whether a variant runs anything other than its base MCA on `robot`: ":box" only on a
    legged platform, ":kr500-weights" only where the platform ships tuned settings."""
    base, *variants = mca.split(":")
    if "box" in variants and not isinstance(robot, LegPlatform):
        return False
    tuned = mca_config_from_name(base, packaged_name(robot.name))
    return "kr500-weights" not in variants or tuned != mca_config_from_name(base)


def measure(platforms, mcas, flights, duration: float, station_seconds: float, bound: bool) -> dict:
    """{platform: {"mcas": {mca: figures}, "station": figures, "bound": figures}} on the
    given flights."""
    references = {
        (vehicle, seed): flight_reference(FlightSpec(vehicle=vehicle, seed=seed), duration)
        for vehicle, seed in flights
    }
    out = {}
    for name in platforms:
        robot = load_platform(name)
        bounds = {}
        if bound:
            for (vehicle, seed), reference in references.items():
                s = run_optimal_bound(reference=reference, robot=robot, progress=False).summary
                bounds[seed] = {"pi": s["pi"], "wall_s": s["solver"]["solve_time_s"]}
                print(f"{name:>11}     bound {vehicle:>5} {seed}: PI {s['pi']:.3f}", flush=True)
        per_mca = {}
        shipped = policy_provenance(robot.name) is not None
        for mca in mcas:
            if mca.split(":")[0] == "dpc" and not shipped:
                print(f"{name:>11}       dpc: no policy shipped for this platform", flush=True)
                continue
            if not variant_differs(mca, robot):
                continue  # the same MCA as its base name here
            runs, step_times = [], []
            for (vehicle, seed), reference in references.items():
                result = run_closed_loop(
                    mca=mca_variant(mca, packaged_name(name)),
                    reference=reference,
                    plant="analytical",
                    robot=robot,
                    progress=False,
                )
                s = result.summary
                runs.append(
                    {
                        "vehicle": vehicle,
                        "seed": seed,
                        "pi": s["pi"],
                        "perceived_pi": s["perceived"]["pi"],
                        "pi_zero_motion": s["pi_zero_motion"],
                        "rmse": s["rmse"],
                        "cc": s["cc"],
                        "violations": s["violations"],
                        "interventions": s["safety_interventions"],
                        "joint_range_used": s["joint_range_used"],
                    }
                )
                if seed in bounds:
                    runs[-1]["bound_share"] = improvement_share(
                        s["pi_zero_motion"], s["pi"], bounds[seed]["pi"]
                    )
                step_times.append(result.step_times_s)
                print(f"{name:>11} {mca:>9} {vehicle:>5} {seed}: PI {s['pi']:.3f}", flush=True)
            steps = np.concatenate(step_times)
            per_mca[mca] = {
                "pi": _spread([r["pi"] for r in runs]),
                "perceived_pi": _spread([r["perceived_pi"] for r in runs]),
                "worst_pi": max(r["pi"] for r in runs),
                "violations": int(sum(sum(r["violations"].values()) for r in runs)),
                # commands the platform's viability clamp changed (a legged platform's legs)
                "interventions": int(sum(r["interventions"] for r in runs)),
                "joint_range_used": np.median([r["joint_range_used"] for r in runs], 0).tolist(),
                "step_time_s": {
                    "median": float(np.median(steps)),
                    "p99": float(np.percentile(steps, 99)),
                },
                "runs": runs,
            }
            if bounds:
                per_mca[mca]["bound_share"] = _spread([r["bound_share"] for r in runs])
        vehicle, seed = flights[0]
        reference = flight_reference(FlightSpec(vehicle=vehicle, seed=seed), station_seconds)
        station = run_closed_loop(
            mca=mca_config_from_name("nmpc-rti", packaged_name(name)),
            reference=reference,
            plant="multibody",
            robot=robot,
            progress=False,
        ).summary
        out[name] = {
            "platform": robot.summary(),
            "policy": policy_provenance(robot.name),
            "mcas": per_mca,
            "bound": {
                "pi": _spread([b["pi"] for b in bounds.values()]),
                "wall_s": _spread([b["wall_s"] for b in bounds.values()]),
            }
            if bounds
            else None,
            "station": {
                "mca": "nmpc-rti",
                "flight": f"{vehicle} {seed}, {station_seconds:g} s",
                "realtime_factor": station["realtime_factor"],
                "pi": station["pi"],
                "violations": station["violations"],
            },
        }
    return out


def rail_gain(results: dict, mca: str) -> dict | None:
    """Per channel, the median over flights of the KR500's RMSE less the rail's and of the
    rail's CC less the KR500's (positive: the rail cues that channel better)."""
    if "kr500" not in results or "kr500-rail" not in results:
        return None
    if mca not in results["kr500"]["mcas"] or mca not in results["kr500-rail"]["mcas"]:
        return None
    base, rail = results["kr500"]["mcas"][mca]["runs"], results["kr500-rail"]["mcas"][mca]["runs"]
    rmse = np.median(
        [np.subtract(b["rmse"], r["rmse"]) for b, r in zip(base, rail, strict=True)], 0
    )
    cc = np.median([np.subtract(r["cc"], b["cc"]) for b, r in zip(base, rail, strict=True)], 0)
    pi = np.median([b["pi"] - r["pi"] for b, r in zip(base, rail, strict=True)])
    return {
        "pi_decrease": float(pi),
        "rmse_decrease": dict(zip(CHANNELS, rmse.round(4).tolist(), strict=True)),
        "cc_increase": dict(zip(CHANNELS, cc.round(4).tolist(), strict=True)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=4)
    parser.add_argument("--duration", type=float, default=120.0, help="s per flight")
    parser.add_argument("--mcas", default="dpc,nmpc-rti,washout")
    parser.add_argument("--bound", action="store_true", help="each flight's bound and shares")
    parser.add_argument("--platforms", default=",".join(packaged_platforms()))
    parser.add_argument("--station-seconds", type=float, default=60.0)
    parser.add_argument("--json", default=default_result_path("platforms.json"))
    args = parser.parse_args()
    calibration = print_calibration()
    mcas = args.mcas.split(",")
    flights = _flights(args.flights)
    results = measure(
        args.platforms.split(","), mcas, flights, args.duration, args.station_seconds, args.bound
    )
    gains = {mca: rail_gain(results, mca) for mca in mcas}
    print()
    for name, figures in results.items():
        for mca, f in figures["mcas"].items():
            pi, perceived, steps = f["pi"], f["perceived_pi"], f["step_time_s"]
            print(
                f"{name:>11} {mca:>9}: PI {pi['median']:.3f} ({pi['q1']:.3f}..{pi['q3']:.3f}), "
                f"perceived {perceived['median']:.3f}, worst {f['worst_pi']:.3f}, violations "
                f"{f['violations']}, step {steps['median'] * 1e3:.2f} ms (p99 "
                f"{steps['p99'] * 1e3:.2f})"
                + (f", bound share {f['bound_share']['median']:.2f}" if "bound_share" in f else "")
            )
        station = figures["station"]
        print(f"{name:>11} station: real-time factor {station['realtime_factor']:.1f}")
    for mca, gain in gains.items():
        if gain:
            print(f"rail gain, {mca}: PI {gain['pi_decrease']:+.3f}; RMSE {gain['rmse_decrease']}")
    atomic_write_json(
        args.json,
        {
            "provenance": result_header(calibration),
            "flights": [{"vehicle": v, "seed": s} for v, s in flights],
            "duration_s": args.duration,
            "platforms": results,
            "rail_gain": gains,
        },
    )
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
