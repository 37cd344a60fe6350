"""A built-in smooth joint motion that exercises every joint inside its Table I limits.

Used by the default `mca-drake simulate` job and by smoke tests that need a closed loop
without a vehicle reference. Joint i follows q_i(t) = A_i (1 - cos(2 pi t / T_i)), which starts at
rest in the neutral pose, with A_i chosen so that position, velocity and acceleration stay
within fixed fractions of the limits.
"""

from __future__ import annotations

import numpy as np

from mca_drake.robot import KR500, load_kr500

# Periods (s) differ per joint so the head moves in all six output channels.
DEMO_PERIODS_S = np.array([9.0, 7.0, 6.0, 5.0, 4.5, 4.0])
# Fractions of the position (positive side), velocity and acceleration limits used at peak.
POSITION_FRACTION, VELOCITY_FRACTION, ACCELERATION_FRACTION = 0.3, 0.5, 0.8


def demo_amplitudes(robot: KR500 | None = None) -> np.ndarray:
    """A_i (rad), shape (6,), the largest amplitudes that respect all three fractions."""
    robot = robot if robot is not None else load_kr500()
    w = 2 * np.pi / DEMO_PERIODS_S
    # peak q = 2A, peak qd = A w, peak qdd = A w^2
    return np.minimum.reduce(
        [
            POSITION_FRACTION * robot.q_max / 2,
            VELOCITY_FRACTION * robot.qd_max / w,
            ACCELERATION_FRACTION * robot.qdd_max / w**2,
        ]
    )


def demo_joint_motion(times, robot: KR500 | None = None):
    """(q, qd, qdd) of the demo motion at `times` (s, shape (T,)); each shape (T, 6)."""
    t = np.asarray(times, dtype=float)[:, None]
    A = demo_amplitudes(robot)
    w = 2 * np.pi / DEMO_PERIODS_S
    return A * (1 - np.cos(w * t)), A * w * np.sin(w * t), A * w**2 * np.cos(w * t)
