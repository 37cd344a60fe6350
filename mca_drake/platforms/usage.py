"""How much of a platform's joint ranges a run uses, and whether it left them.

Positions, velocities and accelerations are normalised by the platform's limits so that
+-1 is a limit and a magnitude above 1 a violation (the paper's Fig. 5). A platform whose
actuators are not its coordinates (a hexapod's legs) has its actuators' lengths, speeds and
accelerations normalised the same way, about their neutral lengths.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mca_drake.input_checks import as_float_array, same_shapes
from mca_drake.platforms.leg_platform import LegPlatform
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
    # The actuators' usage where they are not the joints (a hexapod's legs), else None.
    actuators: JointUsage | None = None

    def _named(self) -> tuple[tuple[str, np.ndarray], ...]:
        named = (("q", self.q), ("qd", self.qd), ("qdd", self.qdd))
        if self.actuators is not None:
            a = self.actuators
            named += (
                ("actuator_position", a.q),
                ("actuator_speed", a.qd),
                ("actuator_acceleration", a.qdd),
            )
        return named

    def violations(self, tolerance: float = 1e-9) -> dict[str, int]:
        """Number of samples (time steps) with any joint beyond its limit, per limit type
        (q, qd, qdd; and actuator_position, actuator_speed, actuator_acceleration for a
        platform whose actuators are not its joints)."""
        return {
            name: int(np.sum(np.any(np.abs(usage) > 1.0 + tolerance, axis=-1)))
            for name, usage in self._named()
        }

    def peak(self) -> dict[str, np.ndarray]:
        """Largest |usage| per joint (or actuator), per limit type (shape (n,) each)."""
        return {name: np.max(np.abs(usage), axis=0) for name, usage in self._named()}


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
        actuators=_actuator_usage(q, qd, qdd, robot),
    )


def _actuator_usage(q, qd, qdd, robot) -> JointUsage | None:
    """A legged platform's actuators' usage: positions about their neutral ones, speeds and
    accelerations; None for a platform whose actuators are its joints."""
    if not isinstance(robot, LegPlatform):
        return None
    geometry = robot.actuators
    positions, speeds, accelerations = robot.actuator_motion(q, qd, qdd)
    neutral = robot.actuator_positions(robot.home)
    # A pose beyond a crank's reach has no arm angle (NaN): infinitely far beyond every limit.
    beyond = ~np.isfinite(positions)
    positions, speeds, accelerations = (
        np.where(beyond, 0.0, values) for values in (positions - neutral, speeds, accelerations)
    )
    legs = len(robot.actuator_names)
    speed = np.full(legs, geometry.max_speed)
    acceleration = np.full(legs, geometry.max_acceleration)
    usage = JointUsage(
        q=normalized_joint_usage(
            positions, geometry.min_position - neutral, geometry.max_position - neutral
        ),
        qd=normalized_joint_usage(speeds, -speed, speed),
        qdd=normalized_joint_usage(accelerations, -acceleration, acceleration),
    )
    for values in (usage.q, usage.qd, usage.qdd):
        values[beyond] = np.inf
    return usage


def limit_violations(q, qd, qdd, robot: SerialChain, tolerance: float = 1e-9) -> dict:
    """Samples outside the platform's limits, per limit type: {"q": n, "qd": n, "qdd": n}."""
    return joint_usage(q, qd, qdd, robot).violations(tolerance)


def joint_range_used(q, robot: SerialChain) -> np.ndarray:
    """Per joint, the fraction of its range a run swept: (max q - min q) / (q_max - q_min),
    shape (n,), for q of shape (T, n). How much of the platform an MCA uses."""
    q = as_float_array("q", q, last_dim=robot.num_joints)
    return (q.max(axis=0) - q.min(axis=0)) / (robot.q_max - robot.q_min)
