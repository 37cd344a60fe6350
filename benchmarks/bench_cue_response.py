"""How MCAs answer one cue at a time: a step in one channel from the neutral pose, nothing else.

    python benchmarks/bench_cue_response.py --mca dpc=mca_drake/data/default_policy.npz \
        --mca nmpc-rti --mca washout [--json results/cue_response.json]

For each channel a 10 s step (w_x, w_y 0.05 rad/s, w_z 0.03 rad/s, f_x 0.5, f_y 0.3, a_z 1.0
m/s^2; 20 s flights on the analytical plant, the step from 2 s) and for each MCA: the share of
the step rendered (achieved / asked) 0.2, 0.5, 1, 2, 4, 7 and 9.9 s into it, and the cross-talk
(rms of every other channel during the step, rad/s or m/s^2: cues the vehicle did not make).
An MCA that tracks a channel alone renders it whole and fast with little cross-talk; a
classical washout renders the onset only. An MCA is `label=policy.npz` (DPC) or an MCA name.
Writes the figures with their provenance (date, command, calibration, machine) to `--json`,
by default `benchmarks/results/cue_response.json`.
"""

from __future__ import annotations

import argparse

import numpy as np
from common import default_result_path, parse_mca, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.conventions import CHANNELS
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")

STEP_SIZES = (0.05, 0.05, 0.03, 0.5, 0.3, 1.0)  # rad/s, m/s^2
STEP_START_S, STEP_LENGTH_S, FLIGHT_S, TIME_STEP_S = 2.0, 10.0, 20.0, 0.01
SAMPLE_TIMES_S = (0.2, 0.5, 1.0, 2.0, 4.0, 7.0, 9.9)


def step_reference(channel: int) -> Reference:
    """A step of STEP_SIZES[channel] in one channel, zeros elsewhere."""
    t = np.arange(int(FLIGHT_S / TIME_STEP_S)) * TIME_STEP_S
    y = np.zeros((t.size, len(CHANNELS)))
    on = (t >= STEP_START_S) & (t < STEP_START_S + STEP_LENGTH_S)
    y[on, channel] = STEP_SIZES[channel]
    return Reference(y=y, time_step=TIME_STEP_S, name=f"{CHANNELS[channel]} step")


def step_response(mca, channel: int) -> dict:
    """The rendered shares at SAMPLE_TIMES_S and the other channels' rms during the step."""
    result = run_closed_loop(
        mca=mca, reference=step_reference(channel), progress=False, robot=KR500
    )
    start = round(STEP_START_S / TIME_STEP_S)
    during = slice(start, start + round(STEP_LENGTH_S / TIME_STEP_S))
    achieved = result.outputs[:, channel] / STEP_SIZES[channel]
    share = [float(achieved[start + round(s / TIME_STEP_S)]) for s in SAMPLE_TIMES_S]
    rms = np.sqrt(np.mean(result.outputs[during] ** 2, axis=0))
    others = {CHANNELS[k]: float(rms[k]) for k in range(len(CHANNELS)) if k != channel}
    return {"share": share, "cross_talk_rms": others}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mca", action="append", required=True, help="label=policy.npz or name")
    parser.add_argument(
        "--json", default=default_result_path("cue_response.json"), help="write the figures here"
    )
    args = parser.parse_args()
    figures: dict[str, dict] = {}
    times = " ".join(f"{s:g}" for s in SAMPLE_TIMES_S)
    print(f"share of the step rendered at {times} s into it; cross-talk rms of the others")
    for text in args.mca:
        label, mca = parse_mca(text)
        figures[label] = {}
        for channel, name in enumerate(CHANNELS):
            response = step_response(mca, channel)
            figures[label][name] = response
            shares = " ".join(f"{v:5.2f}" for v in response["share"])
            worst = max(response["cross_talk_rms"].items(), key=lambda item: item[1])
            print(f"{label:10s} {name:4s} {shares}   largest cross-talk {worst[0]} {worst[1]:.3f}")
    report = {
        "provenance": result_header(),
        "sample_times_s": list(SAMPLE_TIMES_S),
        "step_sizes": dict(zip(CHANNELS, STEP_SIZES, strict=True)),
        "mcas": figures,
    }
    atomic_write_json(args.json, report)


if __name__ == "__main__":
    main()
