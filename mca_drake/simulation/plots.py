"""The plots of a closed-loop run: tracking (the paper's Fig. 4), the same for what the
occupant perceives (the vestibular models) and joint usage (Fig. 5)."""

from __future__ import annotations

from pathlib import Path

from mca_drake.perception.filters import perceive
from mca_drake.perception.models import PerceptionConfig
from mca_drake.platforms.serial import SerialChain
from mca_drake.platforms.usage import joint_usage
from mca_drake.plotting import plot_joint_usage, plot_tracking, save_figure

_PLANT_NAMES = {"multibody": "KR500 MultibodyPlant", "analytical": "analytical plant"}


def tracking_figure(result):
    """Target against measured output per channel, RMSE and CC in the panel titles, the
    run's PI and the zero-motion PI in the title (Fig. 4). `result`: a ClosedLoopResult."""
    s = result.summary
    title = (
        f"{s['mca']} on the {_PLANT_NAMES.get(s['plant'], s['plant'])}: PI {s['pi']:.3f} "
        f"(zero motion {s['pi_zero_motion']:.3f})"
    )
    return plot_tracking(result.times, result.reference, result.outputs, title)


def perceived_figure(result):
    """What the occupant perceives: the vestibular model's outputs of the reference against
    those of the simulator's motion per channel, perceived RMSE and CC in the panel titles
    and the perceived PI in the title. `result`: a ClosedLoopResult."""
    s = result.summary
    perceived = s["perceived"]
    config = PerceptionConfig(model=perceived["model"])
    step = float(result.times[1] - result.times[0])
    title = (
        f"{s['mca']}, perceived ({perceived['model']}): PI {perceived['pi']:.3f} "
        f"(zero motion {perceived['pi_zero_motion']:.3f})"
    )
    return plot_tracking(
        result.times,
        perceive(result.reference, config, step),
        perceive(result.outputs, config, step),
        title,
    )


def joint_usage_figure(result, robot: SerialChain):
    """Normalised joint positions, velocities and accelerations as strip charts (Fig. 5)."""
    n = robot.num_joints
    usage = joint_usage(result.states[:, :n], result.states[:, n:], result.accelerations, robot)
    return plot_joint_usage(usage, title=f"{result.summary['mca']}: normalised joint usage")


def write_closed_loop_plots(
    result, folder: str | Path, robot: SerialChain
) -> tuple[Path, Path, Path]:
    """Writes `tracking.png` (Fig. 4), `perceived.png` (the same, perceived) and
    `joint_usage.png` (Fig. 5) of a ClosedLoopResult into `folder` (created if missing);
    returns their paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    tracking, perceived = folder / "tracking.png", folder / "perceived.png"
    usage = folder / "joint_usage.png"
    save_figure(tracking_figure(result), tracking)
    save_figure(perceived_figure(result), perceived)
    save_figure(joint_usage_figure(result, robot), usage)
    return tracking, perceived, usage
