"""The time series of a run as a CSV file: one row per control period, what the vehicle did
and what the cabin did, the joints, and what the input plausibility guard did.

Columns: `t` (s); `ref_<ch>` and `cue_<ch>` for the channels of `conventions.CHANNELS`
(`w_x w_y w_z` rad/s, `f_x f_y a_z` m/s^2: the reference the run is scored against, and
the platform's output y); `q_<joint>` (rad or m), `qd_<joint>`, `qdd_<joint>` per joint of
the platform, by its joint names; `plausibility`, what the guard did in that period
(`cueing.plausibility.REACTIONS`; "off" without a guard); and for live runs `health`, the
supervisor's state in that period, `mode`, the operator's (`live.controls.MODES`), and
`intensity`, the share of the reference cued (the operator's intensity times the fade of
a pause; the channels' gains are the summary's `controls` block), then a column per
control or vehicle state the stream carried (`references.vehicle_signals.SIGNALS` names, SI,
`nan` where a sample lacked it). Floats are written with repr, so the file round-trips.
"""

import csv
import io
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_text
from mca_drake.conventions import CHANNELS
from mca_drake.cueing.plausibility import REACTIONS
from mca_drake.platforms.serial import SerialChain

# The columns a live run's trajectory adds (module docstring).
LIVE_COLUMNS = ("health", "mode", "intensity")


def trajectory_header(robot: SerialChain, extra: tuple[str, ...] = ()) -> list[str]:
    """The column names of a trajectory of a run on `robot`, with the `extra` columns after
    `plausibility` (a live run's: LIVE_COLUMNS)."""
    joints = list(robot.joint_names)
    columns = ["t", *(f"ref_{c}" for c in CHANNELS), *(f"cue_{c}" for c in CHANNELS)]
    for prefix in ("q", "qd", "qdd"):
        columns += [f"{prefix}_{name}" for name in joints]
    return [*columns, "plausibility", *extra]


def trajectory_csv(
    robot: SerialChain,
    times: np.ndarray,
    reference: np.ndarray,
    outputs: np.ndarray,
    states: np.ndarray,
    accelerations: np.ndarray,
    reactions: np.ndarray | None = None,
    extra: dict[str, list] | None = None,
) -> str:
    """The CSV text of a trajectory: `times` (T), `reference` and `outputs` (T, 6), `states`
    (T, 2n) = [q, qd], `accelerations` (T, n), `reactions` (T, indices in REACTIONS; None:
    no guard) and, for a live run, the `extra` columns by name (T values each:
    LIVE_COLUMNS).

    Raises:
        ValueError: arrays whose lengths or widths disagree.
    """
    n = robot.num_joints
    rows = len(times)
    shapes = {
        "reference": (reference, 6),
        "outputs": (outputs, 6),
        "states": (states, 2 * n),
        "accelerations": (accelerations, n),
    }
    for name, (array, width) in shapes.items():
        if np.shape(array) != (rows, width):
            raise ValueError(
                f"trajectory: {name} has shape {np.shape(array)}, not ({rows}, {width})"
            )
    if reactions is not None and len(reactions) != rows:
        raise ValueError(f"trajectory: {len(reactions)} reactions for {rows} periods")
    extra = extra or {}
    for name, values in extra.items():
        if len(values) != rows:
            raise ValueError(f"trajectory: {len(values)} values of {name} for {rows} periods")
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(trajectory_header(robot, tuple(extra)))
    columns = list(zip(*extra.values(), strict=True)) if extra else [()] * rows
    numbers = np.column_stack([times, reference, outputs, states, accelerations])
    for k, row in enumerate(numbers.tolist()):
        reaction = "off" if reactions is None else REACTIONS[int(reactions[k])]
        writer.writerow([repr(v) for v in row] + [reaction] + [str(v) for v in columns[k]])
    return buffer.getvalue()


def write_trajectory(path, result, robot: SerialChain) -> Path:
    """Writes the trajectory of a finished closed-loop run (`ClosedLoopResult`) to `path`,
    atomically; returns the path."""
    text = trajectory_csv(
        robot,
        result.times,
        result.reference,
        result.outputs,
        result.states,
        result.accelerations,
        result.reactions,
    )
    return atomic_write_text(path, text)


__all__ = ["LIVE_COLUMNS", "trajectory_csv", "trajectory_header", "write_trajectory"]
