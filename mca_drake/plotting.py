"""Figures a motion-cueing engineer looks at. Every function returns a matplotlib Figure;
`save_figure` writes it atomically. Uses the non-interactive Agg backend unless a notebook
already chose one."""

from __future__ import annotations

import io
import os

import matplotlib

if "ipykernel" not in matplotlib.get_backend().lower() and "inline" not in (
    matplotlib.get_backend().lower()
):
    matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mca_drake.atomic_io import atomic_write_bytes
from mca_drake.conventions import CHANNELS
from mca_drake.metrics import tracking_score

CHANNEL_LABELS = (
    "roll rate w_x [rad/s]",
    "pitch rate w_y [rad/s]",
    "yaw rate w_z [rad/s]",
    "surge f_x [m/s²]",
    "sway f_y [m/s²]",
    "heave a_z [m/s²]",
)


def plot_outputs(times, achieved, target=None, title: str = "", achieved_label: str = "achieved"):
    """Six panels (one per channel of y) against time; `target` is drawn under `achieved`.

    Args:
        times: shape (T,), s.
        achieved: shape (T, 6), the channels of y.
        target: optional shape (T, 6).
    """
    times = np.asarray(times, dtype=float)
    achieved = np.asarray(achieved, dtype=float)
    if achieved.shape != (times.size, len(CHANNELS)):
        raise ValueError(f"achieved must have shape ({times.size}, 6); got {achieved.shape}")
    fig, axes = plt.subplots(3, 2, figsize=(11, 7), sharex=True)
    for k, ax in enumerate(axes.T.ravel()):
        if target is not None:
            ax.plot(times, np.asarray(target)[:, k], color="0.6", lw=1.2, label="target")
        ax.plot(times, achieved[:, k], color="C0", lw=1.0, label=achieved_label)
        ax.set_ylabel(CHANNEL_LABELS[k], fontsize=8)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=8, loc="upper right")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def save_figure(fig, path: str | os.PathLike, dpi: int = 110) -> None:
    """Writes `fig` as PNG (or the format of the suffix) atomically and closes it."""
    buffer = io.BytesIO()
    fmt = os.path.splitext(str(path))[1].lstrip(".") or "png"
    fig.savefig(buffer, format=fmt, dpi=dpi)
    plt.close(fig)
    atomic_write_bytes(path, buffer.getvalue())


RECORDING_LABELS = (
    "omega_x [rad/s]",
    "omega_y [rad/s]",
    "omega_z [rad/s]",
    "f_x [m/s²]",
    "f_y [m/s²]",
    "f_z [m/s²]",
)


def plot_recording(recording, title: str = ""):
    """The six channels of a vehicle recording (angular velocity, specific force) vs time."""
    data = np.column_stack([recording.omega, recording.f])
    fig, axes = plt.subplots(3, 2, figsize=(11, 7), sharex=True)
    for k, ax in enumerate(axes.T.ravel()):
        ax.plot(recording.t, data[:, k], color="C1" if k >= 3 else "C0", lw=0.8)
        ax.set_ylabel(RECORDING_LABELS[k], fontsize=8)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    meta = ", ".join(f"{k}: {v}" for k, v in recording.metadata.items() if k in ("vehicle", "seed"))
    fig.suptitle(title or f"Recording ({meta})" if meta else title or "Recording")
    fig.tight_layout()
    return fig


def plot_loss_curves(history, title: str = ""):
    """Training and validation loss per epoch (log scale), one colour band per curriculum
    step. `history`: a sequence of records with stage, horizon, train_loss and
    validation_loss attributes (`mca_drake.learning.trainer.EpochRecord`)."""
    if not history:
        raise ValueError("no epochs to plot")
    train = np.array([r.train_loss for r in history])
    val = np.array([r.validation_loss for r in history])
    x = np.arange(1, len(history) + 1)
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.semilogy(x, train, color="C0", lw=1.0, label="training")
    ax.semilogy(x, val, color="C1", lw=1.0, label="validation")
    stages = [r.stage for r in history]
    for k, stage in enumerate(sorted(set(stages))):
        idx = [i for i, s in enumerate(stages) if s == stage]
        ax.axvspan(idx[0] + 0.5, idx[-1] + 1.5, color=f"C{k % 10}", alpha=0.06)
        ax.text(
            idx[0] + 1, ax.get_ylim()[1], f"n_p={history[idx[0]].horizon}", fontsize=8, va="top"
        )
    ax.set_xlabel("epoch (over all curriculum steps)")
    ax.set_ylabel("loss")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return fig


def plot_pi_boxes(report: dict, key: str = "pi"):
    """PI distributions per MCA, one panel per case (the paper's Fig. 3). `report`: the
    dictionary of `mca_drake.studies.evaluation.write_report`; `key`: the figure per run,
    "pi" or "perceived_pi"."""
    cases = [(name, c) for name, c in report["cases"].items() if c["mcas"]]
    if not cases:
        raise ValueError("the report has no runs to plot")
    fig, axes = plt.subplots(1, len(cases), figsize=(5 * len(cases), 4), squeeze=False)
    for ax, (name, case) in zip(axes[0], cases, strict=True):
        labels = list(case["mcas"])
        labels = [m for m in labels if key in case["mcas"][m]]
        ax.boxplot([case["mcas"][m][key] for m in labels], tick_labels=labels)
        ax.set_title(f"Case {name}: {case['vehicle']}")
        ax.set_ylabel(f"{key.replace('_', ' ').replace('pi', 'PI')} (lower is better)")
        ax.tick_params(axis="x", labelrotation=30)
        ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    return fig


def plot_tracking(times, target, measured, title: str = ""):
    """Target against measured output per channel with RMSE and CC in each panel's title
    (the paper's Fig. 4).

    Args:
        times: shape (T,), s.
        target: the target outputs, shape (T, 6), the channels of y.
        measured: the achieved outputs, shape (T, 6).
    """
    times = np.asarray(times, dtype=float)
    target = np.asarray(target, dtype=float)
    measured = np.asarray(measured, dtype=float)
    if target.shape != (times.size, 6) or measured.shape != target.shape:
        raise ValueError(
            f"target and measured must have shape ({times.size}, 6); got {target.shape}, "
            f"{measured.shape}"
        )
    score = tracking_score(target, measured)
    fig = plot_outputs(times, measured, target, title=title, achieved_label="measured")
    # plot_outputs lays the channels out column by column on a 3 x 2 grid
    for k, ax in enumerate(np.array(fig.axes).reshape(3, 2).T.ravel()):
        ax.set_title(f"RMSE {score.rmse[k]:.3f}, CC {score.cc[k]:.3f}", fontsize=9)
    fig.tight_layout()
    return fig


def plot_joint_usage(usage, title: str = "", max_points: int = 2000, seed: int = 0):
    """Strip (swarm-like) charts of normalised joint positions, velocities and accelerations
    (the paper's Fig. 5): one column of jittered points per joint, +-1 are the Table I
    limits (dashed).

    Args:
        usage: a `mca_drake.platforms.usage.JointUsage` (each field shape (T, n)).
        max_points: samples drawn per joint (evenly subsampled) to keep the figure light.
    """
    rng = np.random.default_rng(seed)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), sharey=True)
    for ax, (name, values) in zip(
        axes,
        (("position q", usage.q), ("velocity qd", usage.qd), ("acceleration qdd", usage.qdd)),
        strict=True,
    ):
        values = np.asarray(values, dtype=float)
        step = max(1, values.shape[0] // max_points)
        for j in range(values.shape[1]):
            v = values[::step, j]
            x = j + 1 + rng.uniform(-0.28, 0.28, v.size)
            ax.scatter(x, v, s=2, alpha=0.35, color=f"C{j}", rasterized=True)
            peak = np.max(np.abs(values[:, j])) if values.size else 0.0
            ax.text(j + 1, 1.12, f"{peak:.2f}", ha="center", fontsize=7)
        for bound in (-1.0, 1.0):
            ax.axhline(bound, color="k", ls="--", lw=0.8)
        ax.set_xticks(range(1, values.shape[1] + 1))
        ax.set_xlabel("joint")
        ax.set_title(f"normalised {name} (peak |.| above)", fontsize=9)
        ax.set_ylim(-1.25, 1.25)
        ax.grid(alpha=0.3, axis="y")
    axes[0].set_ylabel("value / limit")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
