"""Joint-limit viability: which accelerations keep the robot able to stop inside its limits.

A joint at (q, qd) with acceleration limit a can brake to rest below q_max exactly when

    q + max(qd, 0)^2 / (2 a) <= q_max                                   (stoppable)

and mirrored for q_min. Under the exact zero-order-hold step of period h, braking at -a
keeps a stoppable state stoppable (the left side is invariant: q' + qd'^2 / 2a =
q + qd^2 / 2a), so the set is viable. `viable_acceleration_bounds` gives, per joint, the
interval of u for which the next state x' = step(x, u) is stoppable, within |qd'| <= qd_max
and |u| <= a, and which does not pass the limit within the step either (a command that
reverses the joint peaks at q + qd^2 / 2|u| mid-step: near a limit it must brake at least
qd^2 / 2 (q_max - q)): every u in it keeps the robot inside its limits forever (by braking
later), and the interval is never empty from a viable state. Clamping any command into it is the
safety filter ("viability clamp") that every MCA can use.

The step need not be the exact one: N semi-implicit Euler substeps of h / N (qd += h u / N,
then q += h qd / N, as Drake's discrete MultibodyPlant steps) give
q' = q + h qd + c h^2 u with c = (N + 1) / (2 N) >= 1/2 and the same qd' = qd + h u. Braking
at -a then changes q + qd^2 / 2a by (1/2 - c) h^2 a <= 0, so the set stays viable, and the
bounds below take the `position_coefficient` c (1/2: the exact step).
"""

from __future__ import annotations

import math

import numpy as np

VIABILITY_TOLERANCE = 1e-6  # rad/s^2


def _upper_bound(q, qd, q_max, qd_max, a, h, c=0.5):
    """Largest u keeping the upper side viable: stoppability below q_max after one step,
    qd' <= qd_max and q' <= q_max. Shapes (..., 6); c: the position coefficient."""
    with np.errstate(invalid="ignore", divide="ignore"):
        # q' + qd'^2 / 2a <= q_max with q' = q + h qd + c h^2 u, qd' = qd + h u (qd' >= 0):
        # A2 u^2 + B1 u + C <= 0
        A2 = h * h / (2 * a)
        B1 = c * (h * h) + h * qd / a
        C = q + h * qd + qd * qd / (2 * a) - q_max
        disc = B1 * B1 - 4 * A2 * C
        root = (-B1 + np.sqrt(np.maximum(disc, 0.0))) / (2 * A2)
        # On qd' >= 0 (u >= -qd / h) the left side increases with u, so the bound is the
        # larger root when it lies there; otherwise no u with qd' >= 0 is stoppable and u
        # must make qd' negative (then only q' <= q_max, the position bound, remains).
        stop = np.where((disc >= 0) & (qd + h * root >= 0), root, -qd / h)
    velocity = (qd_max - qd) / h
    position = (q_max - q - h * qd) / (c * (h * h))
    bound = np.minimum(np.minimum(stop, velocity), np.minimum(position, a))
    # Within half a period of the limit at the current speed, a command that reverses the
    # joint inside the period may peak beyond q_max while its end state is below it.
    # From a stoppable state that braking is at most a; a state stoppable only within the
    # tolerance gets the strongest braking, -a.
    room = q_max - q
    with np.errstate(invalid="ignore", divide="ignore"):
        peak = np.maximum(np.where(room > 0, -qd * qd / (2 * room), -a), -a)
    return np.where((qd > 0) & (2 * room < h * qd), np.minimum(bound, peak), bound)


def viable_acceleration_bounds(q, qd, q_min, q_max, qd_max, qdd_max, h, position_coefficient=0.5):
    """Per-joint interval [lo, hi] of accelerations (rad/s^2) that keep the robot viable.

    Args:
        q: joint positions, rad, shape (..., 6).
        qd: joint velocities, rad/s, shape (..., 6).
        q_min: lower position limits, rad (m for a prismatic joint), shape (n,).
        q_max: upper position limits, rad (m for a prismatic joint), shape (n,).
        qd_max: velocity limits, rad/s (m/s), shape (n,).
        qdd_max: acceleration limits, rad/s^2 (m/s^2), shape (n,).
        h: control period, s.
        position_coefficient: c of the step q' = q + h qd + c h^2 u (module docstring);
            1/2, the exact zero-order-hold step, by default.

    Returns:
        (lo, hi, viable): lo <= hi where `viable`; where the state is already not viable
        (lo > hi, e.g. after a disturbance) both are set to the strongest braking command,
        -sign(qd) qdd_max, and `viable` is False.
    """
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    a = np.asarray(qdd_max, float)
    c = _checked_coefficient(position_coefficient)
    hi = _upper_bound(q, qd, q_max, qd_max, a, h, c)
    lo = -_upper_bound(-q, -qd, -np.asarray(q_min, float), qd_max, a, h, c)
    lo, hi = np.maximum(lo, -a), np.minimum(hi, a)
    # On the stopping boundary the braking command is the bound itself; round-off of order
    # 1e-12 may put it on the wrong side, which a tolerance of 1e-6 rad/s^2 (5e-11 rad of
    # position per step) absorbs.
    viable = lo <= hi + VIABILITY_TOLERANCE
    hi = np.maximum(hi, lo)
    brake = np.clip(-qd / h, -a, a)
    lo = np.where(viable, lo, brake)
    hi = np.where(viable, hi, brake)
    return lo, hi, viable


def _checked_coefficient(c: float) -> float:
    if not (math.isfinite(c) and 0.5 <= c <= 1.0):
        raise ValueError(f"position_coefficient must be in [0.5, 1]; got {c}")
    return float(c)


def substep_position_coefficient(substeps: int) -> float:
    """c = (N + 1) / (2 N) of N semi-implicit Euler substeps per step (module docstring)."""
    if substeps < 1:
        raise ValueError(f"substeps must be >= 1; got {substeps}")
    return (substeps + 1) / (2 * substeps)


def is_stoppable(q, qd, q_min, q_max, qdd_max, tol: float = 1e-9) -> np.ndarray:
    """Whether each joint can brake to rest inside [q_min, q_max], shape (..., 6)."""
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    reach_up = q + np.maximum(qd, 0) ** 2 / (2 * qdd_max)
    reach_down = q - np.minimum(qd, 0) ** 2 / (2 * qdd_max)
    return (reach_up <= q_max + tol) & (reach_down >= q_min - tol)


class ViabilityClamp:
    """The joint-limit safety filter for any MCA: clamps a commanded acceleration into the
    exact viability interval (`viable_acceleration_bounds`) of the robot's true limits.

    The same interval, for one state, in plain Python floats with constants prepared once:
    for six joints that is several times faster than numpy's per-call overhead, which
    matters to controllers with a budget of microseconds (tested equal).

    Args:
        q_min: lower position limits, rad (m for a prismatic joint), shape (n,).
        q_max: upper position limits, rad (m for a prismatic joint), shape (n,).
        qd_max: velocity limits, rad/s (m/s), shape (n,).
        qdd_max: acceleration limits, rad/s^2 (m/s^2), shape (n,).
        h: control period, s.
        tolerance: a change of the command larger than this (rad/s^2) counts as an
            intervention.
        position_coefficient: c of the step q' = q + h qd + c h^2 u (module docstring);
            1/2, the exact zero-order-hold step, by default.
    """

    def __init__(
        self,
        q_min,
        q_max,
        qd_max,
        qdd_max,
        h: float,
        tolerance: float = 1e-9,
        position_coefficient: float = 0.5,
    ):
        self.q_min, self.q_max = np.asarray(q_min, float), np.asarray(q_max, float)
        self.qd_max, self.qdd_max = np.asarray(qd_max, float), np.asarray(qdd_max, float)
        self.h, self.tolerance = float(h), float(tolerance)
        self._n = self.q_min.size
        h = self.h
        self._c = _checked_coefficient(position_coefficient)
        self._b0 = self._c * (h * h)
        # Per joint, as Python floats (numpy scalars make arithmetic slow): a, h/a, 1/2a,
        # 4 A2 and 1/(2 A2) with A2 = h^2/2a, qd_max, and the upper and mirrored lower limit.
        self._joint_constants = [
            (a, h / a, 1 / (2 * a), 2 * h * h / a, a / (h * h), vmax, upper, -lower)
            for a, vmax, upper, lower in zip(
                self.qdd_max.tolist(),
                self.qd_max.tolist(),
                self.q_max.tolist(),
                self.q_min.tolist(),
                strict=True,
            )
        ]

        # The far-from-limits test of `__call__` per joint: a, h a, c h^2 a, 1/2a, qd_max,
        # the upper and mirrored lower limit less a margin (1e-9 rad) that keeps its verdict
        # on the safe side of round-off.
        self._free_constants = [
            (a, h * a, self._b0 * a, 1 / (2 * a), vmax, upper - 1e-9, lower - 1e-9)
            for a, _, _, _, _, vmax, upper, lower in self._joint_constants
        ]

    @classmethod
    def for_robot(cls, robot, h: float, position_coefficient: float = 0.5) -> ViabilityClamp:
        """The clamp of a `mca_drake.platforms.serial.SerialChain` description."""
        return cls(
            robot.q_min,
            robot.q_max,
            robot.qd_max,
            robot.qdd_max,
            h,
            position_coefficient=position_coefficient,
        )

    def _joint_interval(self, j: int, q: float, v: float) -> tuple[float, float]:
        """(lo, hi) of joint j, in plain floats: for one state, Python arithmetic on a few
        joints is three times faster than numpy's per-call overhead."""
        h, b0 = self.h, self._b0
        a, h_over_a, inv_2a, four_A2, inv_2A2, vmax, upper, lower = self._joint_constants[j]
        hi = lo = 0.0
        for side, qs, vs, lim in ((1, q, v, upper), (-1, -q, -v, lower)):
            B1 = b0 + vs * h_over_a
            disc = B1 * B1 - four_A2 * (qs + h * vs + vs * vs * inv_2a - lim)
            root = (math.sqrt(disc if disc > 0.0 else 0.0) - B1) * inv_2A2
            stop = root if (disc >= 0.0 and vs + h * root >= 0.0) else -vs / h
            bound = min(stop, (vmax - vs) / h, (lim - qs - h * vs) / b0, a)
            room = lim - qs
            if vs > 0.0 and 2.0 * room < h * vs:  # may peak beyond the limit mid-period
                bound = min(bound, max(-vs * vs / (2.0 * room) if room > 0.0 else -a, -a))
            if side > 0:
                hi = bound
            else:
                lo = max(-bound, -a)
        return lo, hi

    def _interval(self, j: int, q: float, v: float) -> tuple[float, float, bool]:
        """(lo, hi, viable) of joint j at (q, v): the full range far from the limits (the
        common case costs a few float operations instead of the two quadratics of
        `_joint_interval`), and the strongest braking command, not viable, where no command
        keeps the joint inside."""
        h = self.h
        a, ha, b0a, inv_2a, vmax, upper, lower = self._free_constants[j]
        # Far from the limits every |u| <= a is viable: full acceleration either way
        # leaves a state that can still brake in time (q' + max(qd', 0)^2 / 2a inside,
        # which also bounds q' and the mid-step peak), within qd_max.
        up, down = v + ha, ha - v
        if (
            (v if v > 0.0 else -v) + ha <= vmax
            and q + h * v + b0a + (up * up * inv_2a if up > 0.0 else 0.0) <= upper
            and -q - h * v + b0a + (down * down * inv_2a if down > 0.0 else 0.0) <= lower
        ):
            return -a, a, True
        lo, hi = self._joint_interval(j, q, v)
        if not lo <= hi + VIABILITY_TOLERANCE:  # not viable: brake as hard as allowed
            brake = min(max(-v / h, -a), a)
            return brake, brake, False
        return lo, max(hi, lo), True

    def intervals(self, x) -> tuple[list[float], list[float], bool]:
        """Per joint, the interval [lo, hi] of viable commands at state x = [q, qd] (2n),
        as lists; and whether every joint is viable (where one is not, its interval is its
        strongest braking command alone)."""
        xs = np.asarray(x, float).tolist()
        n = self._n
        lows, highs, viable = [], [], True
        for j in range(n):
            lo, hi, ok = self._interval(j, xs[j], xs[n + j])
            lows.append(lo)
            highs.append(hi)
            viable = viable and ok
        return lows, highs, viable

    def is_viable(self, x) -> bool:
        """Whether state x = [q, qd] (2n) is viable: every joint has a non-empty interval,
        so some command keeps the robot inside its limits from here on."""
        xs = np.asarray(x, float).tolist()
        n = self._n
        for j in range(n):
            lo, hi = self._joint_interval(j, xs[j], xs[n + j])
            if not lo <= hi + VIABILITY_TOLERANCE:
                return False
        return True

    def __call__(self, x, u) -> tuple[np.ndarray, bool]:
        """(u_safe, intervened) for state x = [q, qd] (2n) and command u (n). A non-finite
        command is replaced by the strongest braking command (and counts)."""
        n, h = self._n, self.h
        xs = np.asarray(x, float).tolist()
        us = u if type(u) is list else np.asarray(u, float).tolist()  # a list: the DPC's
        finite = all(math.isfinite(c) for c in us)
        safe, intervened = [], not finite
        for j in range(n):
            v = xs[n + j]
            lo, hi, viable = self._interval(j, xs[j], v)
            a = self._free_constants[j][0]
            c = us[j] if finite else min(max(-v / h, -a), a)
            s = min(max(c, lo), hi)
            intervened = intervened or not viable or abs(s - c) > self.tolerance
            safe.append(s)
        return np.array(safe), intervened
