"""How much of a platform's joint ranges a run uses, and whether it left them.

Positions, velocities and accelerations are normalised by the platform's limits so that
+-1 is a limit and a magnitude above 1 a violation (the paper's Fig. 5).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mca_drake.input_checks import as_float_array, same_shapes
from mca_drake.platforms.serial import SerialChain


def normalized_joint_usage(values, lower, upper) -> np.ndarray:
    """Joint values mapped to [-1, 1] by their limits, keeping 0 at 0 (the neutral pose).

    Positive values are divided by `upper`, negative ones by |lower|, so asymmetric limits
    (the KR500's joints 2 and 3) still map each limit to +-1 and a magnitude above 1 is a
    violation (the paper's Fig. 5). Requires lower < 0 < upper.

    Args:
        values: shape (..., n).
        lower: lower bounds, shape (n,).
        upper: upper bounds, shape (n,).
    """
    lower = as_float_array("lower", lower)
    upper = as_float_array("upper", upper, last_dim=lower.shape[-1])
    values = as_float_array("values", values, last_dim=lower.shape[-1])
    if not (np.all(lower < 0) and np.all(upper > 0)):
        raise ValueError(f"limits must straddle zero; got lower {lower}, upper {upper}")
    return np.where(values >= 0, values / upper, values / -lower)


@dataclasses.dataclass(frozen=True)
class JointUsage:
    """Normalised joint usage (each (T, n), see `normalized_joint_usage`) and violations."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray

    def violations(self, tolerance: float = 1e-9) -> dict[str, int]:
        """Number of samples (time steps) with any joint beyond its limit, per limit type."""
        return {
            name: int(np.sum(np.any(np.abs(usage) > 1.0 + tolerance, axis=-1)))
            for name, usage in (("q", self.q), ("qd", self.qd), ("qdd", self.qdd))
        }

    def peak(self) -> dict[str, np.ndarray]:
        """Largest |usage| per joint, per limit type (shape (n,) each)."""
        return {
            name: np.max(np.abs(usage), axis=0)
            for name, usage in (("q", self.q), ("qd", self.qd), ("qdd", self.qdd))
        }


def joint_usage(q, qd, qdd, robot: SerialChain) -> JointUsage:
    """Joint positions, velocities and accelerations normalised by the platform's limits.

    Args:
        q: joint positions, rad (m for a prismatic joint), shape (T, n).
        qd: joint velocities, rad/s (m/s), shape (T, n).
        qdd: joint accelerations, rad/s^2 (m/s^2), shape (T, n).
        robot: the platform.
    """
    n = robot.num_joints
    q = as_float_array("q", q, last_dim=n)
    qd = as_float_array("qd", qd, last_dim=n)
    qdd = as_float_array("qdd", qdd, last_dim=n)
    same_shapes(q=q, qd=qd, qdd=qdd)
    return JointUsage(
        q=normalized_joint_usage(q, robot.q_min, robot.q_max),
        qd=normalized_joint_usage(qd, -robot.qd_max, robot.qd_max),
        qdd=normalized_joint_usage(qdd, -robot.qdd_max, robot.qdd_max),
    )


def limit_violations(q, qd, qdd, robot: SerialChain, tolerance: float = 1e-9) -> dict:
    """Samples outside the platform's limits, per limit type: {"q": n, "qd": n, "qdd": n}."""
    return joint_usage(q, qd, qdd, robot).violations(tolerance)


def joint_range_used(q, robot: SerialChain) -> np.ndarray:
    """Per joint, the fraction of its range a run swept: (max q - min q) / (q_max - q_min),
    shape (n,), for q of shape (T, n). How much of the platform an MCA uses."""
    q = as_float_array("q", q, last_dim=robot.num_joints)
    return (q.max(axis=0) - q.min(axis=0)) / (robot.q_max - robot.q_min)
