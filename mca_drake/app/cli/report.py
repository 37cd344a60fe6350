"""What the closed-loop commands print: a readable result table, not the summary JSON.

The full summary goes to its JSON file; the terminal gets the figures an engineer reads
first: the PI beside not moving at all, each channel's RMSE and CC, the same for the
perceived signals (vestibular models) with the wrong cues felt and the sickness estimate, how
much of each joint's range the run used, the MCA's step time and the real-time factor.
"""

from __future__ import annotations

import sys

import numpy as np

from mca_drake.conventions import CHANNELS
from mca_drake.metrics import rmse


def format_closed_loop_report(result) -> str:
    """The result table of a closed-loop run (a `ClosedLoopResult`), as text.

    Rows: per output channel, the RMSE and CC of the run and the RMSE of zero motion (whose
    CC is 0); the PI of both; the perceived RMSE, CC, share of time a wrong cue is felt and
    perceived PI; the sickness model's conflict and incidence; the share of each joint's
    range swept; the step time (median, p99, max, us); the real-time factor; limit
    violations and interventions.
    """
    summary = result.summary
    width = 9
    header = f"{'':<18}" + "".join(f"{c:>{width}}" for c in CHANNELS)

    def row(name: str, values) -> str:
        return f"{name:<18}" + "".join(f"{v:>{width}.3f}" for v in values)

    lines = [
        f"{summary['mca']} on the {summary['plant']} plant, {summary['reference']}, "
        f"{summary['duration_s']:g} s",
        *policy_lines(summary),
        "",
        header,
        row("RMSE", summary["rmse"]),
        row("CC", summary["cc"]),
        row("RMSE zero motion", rmse(result.reference, np.zeros_like(result.reference))),
        "",
        f"PI {summary['pi']:.3f}   zero motion {summary['pi_zero_motion']:.3f}   "
        "(sum of RMSE - CC over the channels; lower is better, minimum -6)",
        *_perceived_rows(summary.get("perceived"), row),
        "joint range used  "
        + "  ".join(f"j{i + 1} {v:.0%}" for i, v in enumerate(summary["joint_range_used"])),
        _timing_row(summary),
        f"limits            violations {summary['violations']}, safety interventions "
        f"{summary['safety_interventions']}, solver failures {summary['solver_failures']}",
    ]
    return "\n".join(lines)


# Above this share of the time outside its policy's training range a DPC run says to
# compare the NMPC: a policy is trusted where it was trained.
OUT_OF_RANGE_NOTICE = 0.05


def suggests_nmpc(outside: dict | None) -> bool:
    """Whether a DPC run's report says to compare the NMPC: its `out_of_distribution`
    share above OUT_OF_RANGE_NOTICE (False for a policy without a range: None)."""
    return outside is not None and outside["share"] > OUT_OF_RANGE_NOTICE


def policy_lines(summary: dict) -> list[str]:
    """The DPC's policy in words, for a report: which file and why, its changes of policy
    (a vehicle recognized from the reference) and the share of the time the reference lay
    outside the policy's training range; [] for other MCAs."""
    if not summary.get("policy_file"):
        return []
    reason = summary.get("policy_reason", "")
    lines = [f"policy {summary['policy_file']}{': ' + reason if reason else ''}"]
    changes = summary.get("policy_changes") or []
    if changes:
        lines.append(
            "policy changes: "
            + ", ".join(f"{c['t_s']:.1f} s {c['policy_file']}" for c in changes)
            + " (each handed over smoothly)"
        )
    outside = summary.get("out_of_distribution")
    if outside is not None:
        channels = sorted(outside["channels"].items(), key=lambda item: -item[1])
        most = ", ".join(f"{c} {v:.1%}" for c, v in channels[:2] if v > 0)
        line = (
            f"reference outside the policy's training range {outside['share']:.1%} of the "
            f"time" + (f" (most: {most})" if most else "")
        )
        if suggests_nmpc(outside):
            line += "; the policy was not trained on such motion: compare --mca nmpc-rti"
        lines.append(line)
    elif "out_of_distribution" in summary:
        lines.append("the policy records no training range (trained before ranges were kept)")
    return lines


def _timing_row(summary: dict) -> str:
    """The MCA's step times and the real-time factor; for an offline solve (no control
    steps: the optimal bound) its solver's figures instead."""
    steps = summary["step_time_s"]
    if steps is None:
        solver = summary["solver"]
        return (
            f"solver            {solver['iterations']} SQP iterations, KKT residual "
            f"{solver['kkt_residual']:.1e}, {solver['solve_time_s']:.1f} s, started from "
            f"{solver['start']}"
        )
    return (
        f"MCA step time     median {steps['median'] * 1e6:.1f} us, p99 {steps['p99'] * 1e6:.1f}"
        f" us, max {steps['max'] * 1e6:.1f} us; real-time factor "
        f"{summary['realtime_factor']:.1f}"
    )


def _perceived_rows(perceived: dict | None, row) -> list[str]:
    """The table's perceived block (none for a summary without one)."""
    if not perceived:
        return []
    sim, ref = perceived["sickness"]["simulator"], perceived["sickness"]["reference"]
    return [
        "",
        f"perceived ({perceived['model']} vestibular model)",
        row("perceived RMSE", perceived["rmse"]),
        row("perceived CC", perceived["cc"]),
        row("wrong cue felt", perceived["false_cue_share"]),
        f"perceived PI {perceived['pi']:.3f}   zero motion {perceived['pi_zero_motion']:.3f}",
        f"sickness          conflict RMS {sim['conflict_rms_m_s2']:.3f} m/s^2 (reference "
        f"{ref['conflict_rms_m_s2']:.3f}), incidence at the end {sim['msi_final_percent']:.2g} %"
        f" (reference {ref['msi_final_percent']:.2g} %)",
    ]


def format_pi(summary: dict) -> str:
    """One line: the PI beside zero motion's, and the perceived PI where there is one."""
    line = (
        f"PI {summary['pi']:.3f} (zero motion {summary['pi_zero_motion']:.3f}; lower is "
        "better, minimum -6)"
    )
    perceived = summary.get("perceived")
    if perceived:
        line += (
            f"; perceived PI {perceived['pi']:.3f} (zero motion {perceived['pi_zero_motion']:.3f})"
        )
    return line


def hold_meshcat(meshcat) -> None:
    """Keeps the Meshcat server (and its recording) alive until the user is done."""
    if meshcat is None or not sys.stdin.isatty():
        return
    try:
        input(f"replay the recording at {meshcat.web_url()}; press Enter to exit ")
    except (EOFError, KeyboardInterrupt):
        pass
