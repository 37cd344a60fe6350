"""Perceived-motion scores of a run: the `perceived` block of every result summary.

The vehicle's motion (the scaled reference r, what a perfect MCA would render) and the
simulator's (the achieved y) both pass through the same vestibular model, from rest; the
perceived PI is equation (10) on the perceived signals, with zero motion's beside it (no
motion is perceived as nothing). A wrong cue is felt where the perceived error exceeds the
channel's threshold (`PerceptionConfig`); the sickness figures are the subjective-vertical-
conflict model's (`mca_drake.perception.sickness`) for the simulator's occupant and for the
reference's.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mca_drake.conventions import CHANNELS, GRAVITY
from mca_drake.input_checks import as_float_array, same_shapes
from mca_drake.metrics import TrackingScore, tracking_score
from mca_drake.perception.filters import vestibular_filter
from mca_drake.perception.models import PerceptionConfig
from mca_drake.perception.sickness import SicknessResult, subjective_vertical_conflict


def specific_force_of(signals: np.ndarray, head_z_up: np.ndarray | None = None) -> np.ndarray:
    """The specific force at the head with gravity, (T, 3) m/s^2, from y-like signals (T, 6).

    y carries f_x and f_y with gravity but the vertical channel without it (a_z, or for a
    reference s_f (f_z - g)); the vertical specific force is that plus g times the z
    component of the world's up axis in the head frame, `head_z_up` (T,) (R_WH[2, 2]; 1 when
    level, the default: exact for a reference, whose channel already holds f_z - g)."""
    vertical = np.ones(signals.shape[0]) if head_z_up is None else np.asarray(head_z_up, float)
    return np.column_stack([signals[:, 3], signals[:, 4], signals[:, 5] + GRAVITY * vertical])


@dataclasses.dataclass(frozen=True)
class PerceivedRun:
    """What the occupant perceived of a run against what the reference would have given.

    Attributes:
        target: the perceived reference, shape (T, 6), units of y.
        achieved: the perceived simulator output, shape (T, 6).
        score: RMSE, CC and PI of `achieved` against `target`.
        zero_motion: the same for no motion at all (perceived as zeros).
        false_cue_share: per channel, the share of samples whose perceived error exceeds its
            threshold, shape (6,), 0 to 1.
        sickness: the sickness model over the simulator's motion.
        reference_sickness: the same over the reference's.
        model: the vestibular model's name.
    """

    target: np.ndarray
    achieved: np.ndarray
    score: TrackingScore
    zero_motion: TrackingScore
    false_cue_share: np.ndarray
    sickness: SicknessResult
    reference_sickness: SicknessResult
    model: str

    def summary(self) -> dict:
        """The summary's `perceived` block (`mca_drake.simulation.closed_loop`)."""
        return {
            "model": self.model,
            "pi": self.score.pi,
            "pi_zero_motion": self.zero_motion.pi,
            "rmse": self.score.rmse.tolist(),
            "cc": self.score.cc.tolist(),
            "false_cue_share": self.false_cue_share.tolist(),
            "sickness": {
                "simulator": self.sickness.summary(),
                "reference": self.reference_sickness.summary(),
            },
        }


def perceived_run(
    reference,
    outputs,
    time_step: float,
    config: PerceptionConfig | None = None,
    head_z_up=None,
) -> PerceivedRun:
    """The perceived scores of a run.

    Args:
        reference: r_n, shape (T, 6), T >= 2, channels of y.
        outputs: y_n, shape (T, 6).
        time_step: the sample period, s.
        config: the vestibular model and thresholds (default PerceptionConfig()).
        head_z_up: R_WH[2, 2] per sample (T,), for the simulator's vertical specific force
            (`specific_force_of`); None: level.
    """
    config = config or PerceptionConfig()
    reference = as_float_array("reference", reference, last_dim=len(CHANNELS))
    outputs = as_float_array("outputs", outputs, last_dim=len(CHANNELS))
    same_shapes(reference=reference, outputs=outputs)
    if head_z_up is not None:
        head_z_up = as_float_array("head_z_up", head_z_up)
        if head_z_up.shape != (outputs.shape[0],):
            raise ValueError(f"head_z_up must have shape ({outputs.shape[0]},)")
    model = vestibular_filter(config, time_step)
    target = model.run(reference)[0]
    achieved = model.run(outputs)[0]
    score = tracking_score(target, achieved)
    zero_motion = tracking_score(target, np.zeros_like(target))
    felt = np.abs(achieved - target) > config.thresholds
    return PerceivedRun(
        target=target,
        achieved=achieved,
        score=score,
        zero_motion=zero_motion,
        false_cue_share=felt.mean(axis=0),
        sickness=subjective_vertical_conflict(
            specific_force_of(outputs, head_z_up), outputs[:, :3], time_step
        ),
        reference_sickness=subjective_vertical_conflict(
            specific_force_of(reference), reference[:, :3], time_step
        ),
        model=config.model,
    )
