"""The viability clamp of a hexapod: its legs' stroke, speed and acceleration as well as
its coordinates' box.

A serial robot's actuators are its joints, and `mca_drake.safety.ViabilityClamp` clamps each
joint's command into the exact interval that keeps it able to stop inside its limits. A
hexapod's actuators are its legs: each leg is a double integrator in its own length l_i,
with l_i'' = J_i(q) u + c_i(q, qd) for the coordinates' command u (J = dl/dq, c the
legs' acceleration at u = 0: the centripetal terms of `legs.leg_motion`). Over one
control period the leg's acceleration is that of the period's start to first order in the
period, so the per-leg viability interval of `ViabilityClamp` (on the leg's stroke, speed
and acceleration, with reserves) turns into two linear inequalities on u. The clamp passes
a command that satisfies them and the coordinates' box intervals unchanged (the common
case: no solve), and otherwise returns the command nearest to it that satisfies both,

    minimise |W (u - u_cmd)|^2   subject to   box_lo <= u <= box_hi,
                                              leg_lo - c <= J u <= leg_hi - c,

with W = diag(1 / qdd_max) (each coordinate's change relative to its own acceleration
limit), solved exactly by the dual active-set method (`mca_drake.qp.dual_active_set`),
hot-started from the last solve's active set.

Reserves: the legs' viability brakes and commands with `ACCELERATION_SHARE` of their
acceleration, and the pose's command, constant over the period, does not hold a leg's
acceleration constant (J and c change with the pose): where a command would ask more than
the limit (less `RATE_RESERVE`) of a leg at the period's end, that end's acceleration
bound, linearised about the end state the command reaches, joins the constraints (twice at
most). The stroke keeps `POSITION_RESERVE` at each end, the speed `RATE_RESERVE`.

Where the box and the legs cannot both hold (a box interval that asks for more
acceleration than the legs can give), the legs win: the command nearest the box's clamp of
the command that the legs allow; where J is singular, each leg's own clamp mapped back
through J^-1. The box is the MCAs' planning range and a guard against the poses near
singularities; the legs are the machine.

`mca_drake.platforms.clamp.platform_clamp` gives the clamp of any platform.
"""

from __future__ import annotations

import math

import numpy as np

from mca_drake.platforms.leg_platform import LegPlatform
from mca_drake.qp.dual_active_set import solve_dual_active_set
from mca_drake.safety import ViabilityClamp

# What the clamp keeps in reserve of each leg limit for the period's remainder (the leg's
# acceleration changes within a period as J and c do: of order h^3 times the pose's jerk,
# micrometres at 100 Hz): of the range at each end (m of a leg's stroke, rad of an arm's
# angle), and of the speed and acceleration.
POSITION_RESERVE = 1e-3
RATE_RESERVE = 0.01
# The share of a leg's acceleration the clamp commands and brakes with: the rest is kept for
# what the legs' coupling adds within a period (the centripetal terms c change with the
# pose's rates; a leg braked at its full acceleration at the start may need more at the end).
ACCELERATION_SHARE = 0.9
# Linearisations of the period's end acceleration bound about the end state (each about the
# last command's).
END_PASSES = 2


class LegClamp:
    """Clamps a hexapod's coordinate accelerations (rad/s^2, m/s^2) so that its legs and
    its coordinates stay viable (module docstring).

    Args:
        platform: the hexapod.
        h: control period, s.
        tolerance: a change of the command larger than this counts as an intervention.
        position_coefficient: c of the step q' = q + h qd + c h^2 u
            (`mca_drake.safety`); 1/2, the exact step, by default.
        period_end: also bound the legs' accelerations at the period's end (default on;
            off, the clamp is the plain QP on the period's start).
    """

    def __init__(
        self,
        platform: LegPlatform,
        h: float,
        tolerance: float = 1e-9,
        position_coefficient: float = 0.5,
        period_end: bool = True,
    ):
        self.platform = platform
        self._end_passes = END_PASSES if period_end else 0
        self.h, self.tolerance = float(h), float(tolerance)
        self.box = ViabilityClamp.for_robot(platform, h, position_coefficient)
        geometry = platform.actuators
        legs = len(platform.actuator_names)
        keep = 1.0 - RATE_RESERVE
        self.legs = ViabilityClamp(
            [geometry.min_position + POSITION_RESERVE] * legs,
            [geometry.max_position - POSITION_RESERVE] * legs,
            [geometry.max_speed * keep] * legs,
            [geometry.max_acceleration * ACCELERATION_SHARE] * legs,
            h,
            position_coefficient=position_coefficient,
        )
        self._end_limit = geometry.max_acceleration * keep
        self._weights = 1.0 / np.square(platform.qdd_max)
        self._H = np.diag(self._weights)
        self._identity = np.eye(platform.num_joints)
        self._active = None  # the last solve's active set: the next one's hot start
        self.solves = 0  # commands that needed the QP
        self.fallbacks = 0  # commands where the box and the legs could not both hold

    def leg_state(self, x) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(lengths, speeds, c, J) of the legs at state x = [q, qd] (12): lengths (m),
        speeds (m/s), accelerations at zero command c (m/s^2), each (6,), and dl/dq (6, 6)."""
        x = np.asarray(x, dtype=float)
        n = self.platform.num_joints
        return self.platform.actuator_rates(x[:n], x[n:])

    def _leg_intervals(self, x):
        lengths, speeds, drift, J = self.leg_state(x)
        lo, hi, viable = self.legs.intervals(np.concatenate([lengths, speeds]))
        return np.array(lo), np.array(hi), viable, drift, J

    def is_viable(self, x) -> bool:
        """Whether state x = [q, qd] (12) is viable for the box and for every leg."""
        if not self.box.is_viable(x):
            return False
        lengths, speeds, _, _ = self.leg_state(x)
        return self.legs.is_viable(np.concatenate([lengths, speeds]))

    def __call__(self, x, u) -> tuple[np.ndarray, bool]:
        """(u_safe, intervened) for state x = [q, qd] (12) and command u (6). A non-finite
        command is replaced by braking (and counts)."""
        command = np.asarray(u, dtype=float)
        finite = bool(np.all(np.isfinite(command)))
        n = self.platform.num_joints
        if not finite:
            command = -np.asarray(x, dtype=float)[n:] / self.h
        box_lo, box_hi, _ = self.box.intervals(x)
        box = (self._identity, np.array(box_lo), np.array(box_hi))
        leg_lo, leg_hi, _, drift, J = self._leg_intervals(x)
        rows = [box, (J, leg_lo - drift, leg_hi - drift)]
        safe = command if finite and _holds(rows, command) else self._nearest(command, rows)
        for _ in range(self._end_passes):
            end = self._end_rows(x, safe)
            if end is None:
                break
            rows = [*rows[:2], end]
            safe = self._nearest(command, rows)
        changed = bool(np.max(np.abs(safe - command)) > self.tolerance)
        return safe, (not finite) or changed

    def _end_rows(self, x, u):
        """The legs' acceleration bound at the period's end, linear in u about the end state
        u reaches, or None where u keeps every leg's acceleration there within it: the
        pose's command is constant over the period, a leg's acceleration is not."""
        x = np.asarray(x, dtype=float)
        n, h = self.platform.num_joints, self.h
        q, qd = x[:n] + h * x[n:] + 0.5 * h * h * u, x[n:] + h * u
        _, _, drift, J = self.platform.actuator_rates(q, qd)
        limit = self._end_limit
        if np.all(np.abs(drift + J @ u) <= limit):
            return None
        return J, -limit - drift, limit - drift

    def _nearest(self, command, rows) -> np.ndarray:
        """The command nearest `command` within every row (C, lo, hi) of `rows` (the box,
        the legs at the period's start, at its end); where the box and the legs cannot
        both hold, the command nearest the box's clamp of it that the legs allow (at both
        ends of the period, else at its start); where J is singular, each leg's own clamp
        mapped back."""
        self.solves += 1
        box, legs = rows[0], rows[1:]
        target = np.clip(command, box[1], box[2])
        attempts = ((command, rows), (target, legs), (target, legs[:1]))
        for aim, part in attempts:
            C, lo, hi = (np.concatenate(parts) for parts in zip(*part, strict=True))
            guess = (
                self._active if self._active is not None and self._active.size == lo.size else None
            )
            solution = solve_dual_active_set(self._H, -self._weights * aim, C, lo, hi, guess=guess)
            if solution is not None:
                self._active = solution.active
                return solution.d
            self._active = None
            self.fallbacks += 1
        J, leg_lo, leg_hi = legs[0]
        safe, *_ = np.linalg.lstsq(J, np.clip(J @ target, leg_lo, leg_hi), rcond=None)
        return safe if all(math.isfinite(v) for v in safe) else np.zeros_like(command)


def _holds(rows, u) -> bool:
    """Whether u satisfies lo <= C u <= hi for every row (C, lo, hi)."""
    for C, lo, hi in rows:
        value = C @ u
        if not np.all((lo <= value) & (value <= hi)):
            return False
    return True


__all__ = ["ACCELERATION_SHARE", "POSITION_RESERVE", "RATE_RESERVE", "LegClamp"]
