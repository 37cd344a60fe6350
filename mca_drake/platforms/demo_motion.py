"""A built-in smooth joint motion that exercises every joint of a platform inside its limits.

Used by the default `mca-drake simulate` job and by smoke tests that need a closed loop
without a vehicle reference. Joint i follows q_i(t) = A_i (1 - cos(2 pi t / T_i)), which starts at
rest in the neutral pose, with A_i chosen so that position, velocity and acceleration stay
within fixed fractions of the limits.
"""

from __future__ import annotations

import numpy as np

from mca_drake.platforms.serial import SerialChain

# Periods (s) differ per joint so the head moves in all six output channels; joint i of a
# platform takes the i-th.
DEMO_PERIODS_S = np.array([9.0, 7.0, 6.0, 5.0, 4.5, 4.0, 3.5, 3.0])
# Fractions of the position (its room above home), velocity and acceleration limits used at peak.
POSITION_FRACTION, VELOCITY_FRACTION, ACCELERATION_FRACTION = 0.3, 0.5, 0.8


def _periods(robot: SerialChain) -> np.ndarray:
    if robot.num_joints > DEMO_PERIODS_S.size:
        raise ValueError(
            f"the demo motion has periods for {DEMO_PERIODS_S.size} joints; platform "
            f"'{robot.name}' has {robot.num_joints}"
        )
    return DEMO_PERIODS_S[: robot.num_joints]


def demo_amplitudes(robot: SerialChain) -> np.ndarray:
    """A_i (rad or m), shape (n,), the largest amplitudes that respect all three fractions."""
    w = 2 * np.pi / _periods(robot)
    # peak q = 2A, peak qd = A w, peak qdd = A w^2
    return np.minimum.reduce(
        [
            POSITION_FRACTION * (robot.q_max - robot.home) / 2,
            VELOCITY_FRACTION * robot.qd_max / w,
            ACCELERATION_FRACTION * robot.qdd_max / w**2,
        ]
    )


def demo_joint_motion(times, robot: SerialChain):
    """(q, qd, qdd) of the demo motion at `times` (s, shape (T,)); each shape (T, n), about
    the platform's home pose."""
    t = np.asarray(times, dtype=float)[:, None]
    A = demo_amplitudes(robot)
    w = 2 * np.pi / _periods(robot)
    return robot.home + A * (1 - np.cos(w * t)), A * w * np.sin(w * t), A * w**2 * np.cos(w * t)
