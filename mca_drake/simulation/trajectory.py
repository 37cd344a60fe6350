"""The time series of a run as a CSV file: one row per control period, what the vehicle did
and what the cabin did, the joints, and what the input plausibility guard did.

Columns: `t` (s); `ref_<ch>` and `cue_<ch>` for the channels of `conventions.CHANNELS`
(`w_x w_y w_z` rad/s, `f_x f_y a_z` m/s^2: the reference the run is scored against, and
the platform's output y); `q_<joint>` (rad or m), `qd_<joint>`, `qdd_<joint>` per joint of
the platform, by its joint names; `plausibility`, what the guard did in that period
(`cueing.plausibility.REACTIONS`; "off" without a guard); and for live runs `health`, the
supervisor's state in that period. Floats are written with repr, so the file round-trips.
"""

import csv
import io
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_text
from mca_drake.conventions import CHANNELS
from mca_drake.cueing.plausibility import REACTIONS
from mca_drake.platforms.serial import SerialChain


def trajectory_header(robot: SerialChain, live: bool = False) -> list[str]:
    """The column names of a trajectory of a run on `robot` (with `health` for a live run)."""
    joints = list(robot.joint_names)
    columns = ["t", *(f"ref_{c}" for c in CHANNELS), *(f"cue_{c}" for c in CHANNELS)]
    for prefix in ("q", "qd", "qdd"):
        columns += [f"{prefix}_{name}" for name in joints]
    return columns + ["plausibility"] + (["health"] if live else [])


def trajectory_csv(
    robot: SerialChain,
    times: np.ndarray,
    reference: np.ndarray,
    outputs: np.ndarray,
    states: np.ndarray,
    accelerations: np.ndarray,
    reactions: np.ndarray | None = None,
    health: list[str] | None = None,
) -> str:
    """The CSV text of a trajectory: `times` (T), `reference` and `outputs` (T, 6), `states`
    (T, 2n) = [q, qd], `accelerations` (T, n), `reactions` (T, indices in REACTIONS; None:
    no guard) and, for a live run, `health` (T names).

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
    if health is not None and len(health) != rows:
        raise ValueError(f"trajectory: {len(health)} health states for {rows} periods")
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(trajectory_header(robot, live=health is not None))
    numbers = np.column_stack([times, reference, outputs, states, accelerations])
    for k, row in enumerate(numbers.tolist()):
        reaction = "off" if reactions is None else REACTIONS[int(reactions[k])]
        extra = [reaction] + ([health[k]] if health is not None else [])
        writer.writerow([repr(v) for v in row] + extra)
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


__all__ = ["trajectory_csv", "trajectory_header", "write_trajectory"]
