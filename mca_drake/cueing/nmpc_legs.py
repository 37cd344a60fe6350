"""The legs' limits in the NMPC's plan: a legged platform's stroke and speed, linearised
about the plan at every Gauss-Newton iteration.

The NMPC plans in the platform's coordinates (`mca_drake.platforms.leg_platform`), whose box
is each coordinate's reach alone: a combined motion (surge with pitch, heave with roll) runs
a leg to its stroke's end well inside every coordinate's box. The legs' lengths l and speeds
l' are nonlinear in the coordinates' states; each QP bounds them linearised about the plan
U it steps from (exact derivatives, `LegPlatform.actuator_linearisation`), at the nodes
k = 2..N, in the plan's step d (dq_k = Gq_k d, dqd_k = Gqd_k d: the condensing's rows):

    l_lo <= l(q_k) + J_k dq_k <= l_hi                                     (stroke)
    -v_max <= l'(q_k, qd_k) + J_k dqd_k + S_k dq_k <= v_max                (speed)
    l_lo - v^2/(2a) <= (l + (v/a) l')(linearised) <= l_hi + v^2/(2a)      (stoppability)

one row of each per leg and node, the last for each tangent speed v = v_max i / n of the
legs' stopping parabola (n = `NmpcConfig.stoppability_tangents`, as the joints' tangents;
a = the share of the legs' acceleration the viability clamp brakes with): a leg's stroke
end is planned for, not met at speed. Node 1 (one control period ahead) depends on u_0 alone
and is the viability clamp's: it holds every leg exactly on the command the plan starts with
(`mca_drake.platforms.leg_clamp`), and rows there would only repeat u_0's box in other
combinations. The legs' accelerations are not planned: the coordinates' box bounds them
near home and the clamp holds them.

Reserves: the clamp's (`POSITION_RESERVE` of stroke, `RATE_RESERVE` of speed) plus the
NMPC's `limit_margin` of the stroke and speed, so that the plan stays where the clamp lets
it through unchanged.

Because the rows are a linearisation, a plan that satisfies them may miss a leg's bound by
the second-order remainder (micrometres on a step of the rti's size); the next solve's rows
are linearised about that plan and pull it back, and the clamp holds the command.
"""

import math

import numpy as np

from mca_drake.platforms.leg_clamp import ACCELERATION_SHARE, POSITION_RESERVE, RATE_RESERVE
from mca_drake.platforms.leg_platform import LegPlatform

# The first node with leg rows (node 1 is the viability clamp's: module docstring).
FIRST_NODE = 2


class LegRows:
    """The linearised leg rows of a `MotionCueingOcp` on a legged platform.

    Args:
        platform: the legged platform (k coordinates).
        Gq, Gqd: the condensing's maps d q_k / d U and d qd_k / d U for nodes 0..N, each
            (k (N + 1), k N).
        margin: the NMPC's `limit_margin` (share of the stroke and of the speed kept back).
        tangents: how many stoppability tangents per leg and node.
    """

    def __init__(
        self,
        platform: LegPlatform,
        Gq: np.ndarray,
        Gqd: np.ndarray,
        margin: float,
        tangents: int,
    ):
        self.platform = platform
        k = platform.num_joints
        nodes = Gq.shape[0] // k  # N + 1
        self._Gq = Gq.reshape(nodes, k, -1)[FIRST_NODE:]  # (K, k, kN)
        self._Gqd = Gqd.reshape(nodes, k, -1)[FIRST_NODE:]
        g = platform.actuators
        legs = len(platform.actuator_names)
        reserve = POSITION_RESERVE + margin * (g.max_position - g.min_position)
        self.length_range = (g.min_position + reserve, g.max_position - reserve)
        self.max_speed = g.max_speed * (1.0 - RATE_RESERVE) * (1.0 - margin)
        braking = g.max_acceleration * ACCELERATION_SHARE * (1.0 - margin)
        speeds = [self.max_speed * i / tangents for i in range(1, tangents + 1)]
        # (slope v / a, offset v^2 / (2 a)) per tangent
        self._tangents = [(v / braking, v * v / (2 * braking)) for v in speeds]
        self.num_rows = self._Gq.shape[0] * legs * (2 + tangents)

    def rows(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The rows about the plan whose node states are q, qd (each (N + 1, k)): (C, lo, hi)
        with lo <= C d <= hi the linearised bounds on the plan's step d (kN,); C
        (`num_rows`, kN), row order: stroke, speed, then each tangent, each node by node and
        leg by leg."""
        lengths, speeds, J, S = self.platform.actuator_linearisation(
            q[FIRST_NODE:], qd[FIRST_NODE:]
        )
        position = J @ self._Gq  # (K, legs, kN)
        speed = J @ self._Gqd + S @ self._Gq
        l_lo, l_hi = self.length_range
        blocks = [position, speed]
        lower = [l_lo - lengths, -self.max_speed - speeds]
        upper = [l_hi - lengths, self.max_speed - speeds]
        for slope, offset in self._tangents:
            blocks.append(position + slope * speed)
            value = lengths + slope * speeds
            lower.append(l_lo - offset - value)
            upper.append(l_hi + offset - value)
        size = position.shape[-1]
        C = np.concatenate([b.reshape(-1, size) for b in blocks])
        lo = np.concatenate([b.reshape(-1) for b in lower])
        hi = np.concatenate([b.reshape(-1) for b in upper])
        # A node the plan takes beyond a crank's reach has no arm angle to linearise: its
        # rows are dropped this iteration (`violation` counts the node as infinitely far
        # out, and the clamp holds the command executed).
        lost = ~(np.isfinite(lo) & np.isfinite(hi) & np.all(np.isfinite(C), axis=1))
        if np.any(lost):
            C[lost], lo[lost], hi[lost] = 0.0, -np.inf, np.inf
        return C, lo, hi

    def violation(self, q: np.ndarray, qd: np.ndarray) -> float:
        """How far the node states q, qd (each (N + 1, k)) are beyond the legs' planned stroke
        and speed (nodes 2..N), m or m/s: 0.0 where within."""
        lengths, speeds, _, _ = self.platform.actuator_linearisation(
            q[FIRST_NODE:], qd[FIRST_NODE:]
        )
        l_lo, l_hi = self.length_range
        beyond = np.concatenate(
            [
                (l_lo - lengths).reshape(-1),
                (lengths - l_hi).reshape(-1),
                (np.abs(speeds) - self.max_speed).reshape(-1),
            ]
        )
        if np.isnan(beyond).any():
            return math.inf  # a node beyond a crank's reach
        return float(max(0.0, beyond.max(initial=0.0)))
