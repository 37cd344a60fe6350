"""The hazard replay: a flight cued clean and with the hazards live telemetry brings, with
and without the input plausibility guard (`mca_drake.cueing.plausibility`).

    python benchmarks/bench_hazards.py [--vehicle light] [--seed 700] [--duration 60]
        [--mcas dpc,nmpc-rti,washout] [--json benchmarks/results/hazards.json]

Flies a validation flight (seed 700 on: never training or evaluation seeds) and injects, one
at a time, at `HAZARD_AT_S` (the touchdown at `TOUCHDOWN_AT_S`) into its reference:

- `spike`: one sample of +50 m/s^2 of the vehicle's vertical specific force (25 on the
  reference at the default scale);
- `frozen`: the stream stops for 3 s, repeating its last sample (a paused game);
- `reset`: every channel jumps to the flight's state 60 s later and goes on from there (a
  reset or teleport);
- `touchdown`: in the first second, the vertical specific force of a flight dropped onto its
  gear (as a simulator's flight that starts on the ground gives it): up to 7.5 g over
  60 ms (`TOUCHDOWN_SHAPE`).

(NaN and inf never reach a recording's reference; live, the decoders drop such packets and
the guard holds a channel that is not finite: `tests/test_plausibility.py`.) Each MCA cues
the clean flight and each hazard with the guard and without it (`enabled: false`). Per hazard
and MCA: the run's PI against the clean run's, its jolts (`mca_drake.metrics.jolts`: the
largest change of the cabin's specific force (f_x, f_y, a_z) between two periods, m/s^2, as
peak jerk, m/s^3, and the peak angular acceleration) against the clean run's, the largest
departure from the clean run's cue and the time until the cue is back within 0.05 of it for
good (s), violations, and the guard's counts. Written with the date, command and calibration.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing.configs import mca_config_from_name
from mca_drake.cueing.plausibility import PlausibilityConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.drives import motion_reference
from mca_drake.references.flights import FlightSpec
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop

HAZARD_AT_S = 20.0
HAZARDS = ("spike", "frozen", "reset", "touchdown")
# The touchdown: when (s), its peak (g of vertical specific force) and its shape, per sample.
TOUCHDOWN_AT_S = 0.4
TOUCHDOWN_PEAK_G = 7.5
TOUCHDOWN_SHAPE = (0.3, 0.8, 1.0, 0.7, 0.4, 0.15)
# The reference's force scale (ReferenceScaling's default s_f).
FORCE_SCALE = 0.5
# The cue counts as recovered once every channel stays within this of the clean run's.
RECOVERED = 0.05


def hazard_at_s(hazard: str) -> float:
    """When `hazard` is injected, s."""
    return TOUCHDOWN_AT_S if hazard == "touchdown" else HAZARD_AT_S


def injected(y: np.ndarray, hazard: str, h: float) -> np.ndarray:
    """The reference `y` (T, 6) with `hazard` injected at `hazard_at_s(hazard)`."""
    k = round(hazard_at_s(hazard) / h)
    out = y.copy()
    if hazard == "touchdown":
        extra_g = (TOUCHDOWN_PEAK_G - 1.0) * np.asarray(TOUCHDOWN_SHAPE)
        out[k : k + len(TOUCHDOWN_SHAPE), 5] += FORCE_SCALE * 9.81 * extra_g
    elif hazard == "spike":
        out[k, 5] += 25.0
    elif hazard == "frozen":
        out[k : k + round(3.0 / h)] = y[k - 1]
    elif hazard == "reset":
        shift = round(60.0 / h)
        out[k:] = np.concatenate([y[k + shift :], np.repeat(y[-1:], shift, axis=0)])[: len(y) - k]
    else:
        raise ValueError(f"unknown hazard {hazard!r}")
    return out


def figures(run, clean, h: float, at_s: float, recovers: bool = True) -> dict:
    """The hazard's figures of one run against the clean run of the same MCA (a reset does
    not come back to the clean flight: `recovers` False, no recovery time); `at_s` is when
    the hazard came."""
    departure = np.abs(run.outputs - clean.outputs).max(axis=1)
    k = round(at_s / h)
    off = np.flatnonzero(departure[k:] > RECOVERED)
    return {
        "pi": run.summary["pi"],
        # the summary's jolts (metrics.jolts): the largest change of (f_x, f_y, a_z)
        "jolts": run.summary["jolts"],
        "largest_departure_from_clean": float(departure.max()),
        "recovered_after_s": (float((off[-1] + 1) * h) if off.size else 0.0) if recovers else None,
        "violations": int(sum(run.summary["violations"].values())),
        "plausibility": run.summary.get("plausibility"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--vehicle", default="light")
    parser.add_argument("--seed", type=int, default=700)
    parser.add_argument("--duration", type=float, default=60.0, help="s of the flight cued")
    parser.add_argument("--mcas", default="dpc,nmpc-rti,washout")
    parser.add_argument("--cache", default="results/validation/flights")
    parser.add_argument("--json", help="default benchmarks/results/hazards.json")
    args = parser.parse_args()
    calibration = print_calibration()
    robot = load_platform("kr500")
    spec = FlightSpec(vehicle=args.vehicle, seed=args.seed)
    # cued for the flight's duration, with 60 s more to reset into
    full = motion_reference(spec, args.duration + 60.0, cache_dir=Path(args.cache))
    h = full.time_step
    n = round(args.duration / h) + 1
    results: dict = {}
    for name in args.mcas.split(","):
        mca = mca_config_from_name(name)
        clean_reference = dataclasses.replace(full, y=full.y[:n])
        clean = run_closed_loop(mca=mca, reference=clean_reference, robot=robot, progress=False)
        clean_change = clean.summary["jolts"]["peak_force_change_m_s2"]
        entry = {
            "clean": {"pi": clean.summary["pi"], "jolts": clean.summary["jolts"]},
            "hazards": {},
        }
        for hazard in HAZARDS:
            y = injected(full.y, hazard, h)[:n]
            rows = {}
            for guarded in (True, False):
                reference = Reference(y, h, full.name, full.vehicle)
                run = run_closed_loop(
                    mca=mca,
                    reference=reference,
                    robot=robot,
                    progress=False,
                    plausibility=PlausibilityConfig(enabled=guarded),
                )
                label = "guarded" if guarded else "unguarded"
                rows[label] = figures(
                    run, clean, h, hazard_at_s(hazard), recovers=hazard != "reset"
                )
            entry["hazards"][hazard] = rows
            for label, row in rows.items():
                print(
                    f"{name:8s} {hazard:10s} {label:9s} PI {row['pi']:.3f} (clean "
                    f"{clean.summary['pi']:.3f}) force change "
                    f"{row['jolts']['peak_force_change_m_s2']:.3f} (clean {clean_change:.3f}) "
                    f"departure {row['largest_departure_from_clean']:.3f} recovered after "
                    f"{row['recovered_after_s']} s violations {row['violations']}",
                    flush=True,
                )
        results[name] = entry
    out = args.json or default_result_path("hazards.json")
    header = result_header(calibration) | {
        "flight": f"{args.vehicle} {args.seed}",
        "hazard_at_s": HAZARD_AT_S,
        "touchdown": {"at_s": TOUCHDOWN_AT_S, "peak_g": TOUCHDOWN_PEAK_G},
    }
    atomic_write_json(out, {"provenance": header, "duration_s": args.duration, "mcas": results})


if __name__ == "__main__":
    main()
