"""The legs' limits in the offline-optimal bound: a legged platform's stroke, speed and
acceleration, linearised about the trajectory at every SQP iteration.

The bound's QP (`mca_drake.cueing.optimal`) is stage-wise: each stage's variables are
boxed and tied to the next stage's states by linear dynamics (`cueing.stagewise_qp`). The
legs' limits are not boxes on those variables: a leg's length and speed are nonlinear in
the state x = (q, qd), its acceleration in the state and the command u. Linearised about
the current trajectory they are linear in (dx_k, du_k), and so is everything about stage
k + 1 that depends on them. So each stage carries the legs' values as extra states,

    z_(k+1) = (l(x_(k+1)), l'(x_(k+1)), l''(x_k, u_k))        (3 per leg)

linearised: dz_(k+1) = [J_(k+1) Phi_q, ...] (dx_k, du_k) through x_(k+1) = Phi x_k + Gamma u_k
(J = dl/dq, S = dl'/dq, exact: `LegPlatform.actuator_linearisation`) and, for the
acceleration, its derivatives in x_k (central differences of the legs' exact motion,
`LegPlatform.actuator_motion`) and in u_k (J_k). Their boxes are the legs' limits less the
current values: the stage-wise solver bounds them as it bounds the joints, in O(T).

A step of the linearised QP may break a leg's limit by its second-order remainder; the
bound's line search judges every iterate by the legs' exact motion (as summaries count
violations), so the bound never keeps an iterate outside any limit. The reserve keeps the
QP's solution that far inside (`LEG_RESERVE`), so that the full step is usually taken.
"""

import numpy as np

from mca_drake.platforms.leg_platform import LegPlatform

# The share of each leg limit's half-range the QP keeps in reserve (the line search judges
# the exact limits).
LEG_RESERVE = 1e-6
# Central-difference step of the legs' acceleration's derivatives in the state (m, rad; m/s,
# rad/s): its truncation error (order step^2) is far below the QP's tolerance.
DIFFERENCE_STEP = 1e-6


class BoundLegRows:
    """The legs' rows of an `OptimalCueing` on a legged platform.

    Args:
        platform: the legged platform (k coordinates, L legs).
        Phi, Gamma: the exact double-integrator step of one control period, (2k, 2k) and
            (2k, k).
    """

    def __init__(self, platform: LegPlatform, Phi: np.ndarray, Gamma: np.ndarray):
        self.platform = platform
        self.k = platform.num_joints
        self.legs = legs = len(platform.actuator_names)
        self.size = 3 * legs  # z: lengths, speeds, accelerations
        self._Phi, self._Gamma = Phi, Gamma
        g = platform.actuators
        half = 0.5 * (g.max_position - g.min_position)
        reserve = LEG_RESERVE * np.array([half, g.max_speed, g.max_acceleration])
        lo = np.array([g.min_position, -g.max_speed, -g.max_acceleration]) + reserve
        hi = np.array([g.max_position, g.max_speed, g.max_acceleration]) - reserve
        self.lower, self.upper = np.repeat(lo, legs), np.repeat(hi, legs)

    def rows(self, x: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """About the trajectory x (T + 1, 2k), U (T, k): (Fz (T, 3L, 3k), z (T, 3L)) with
        Fz_k the map from (dx_k, du_k) to dz_(k+1) and z_k the values z_(k+1) there (module
        docstring's order: lengths, speeds, accelerations, each leg by leg)."""
        k, p = self.k, self.platform
        # lengths, speeds, J and S at every state (T + 1, L[, k]), in one pass: those at the
        # steps' ends bound the legs there; J at the steps' starts is the derivative of the
        # legs' accelerations in the command
        lengths, speeds, J, S = p.actuator_linearisation(x[:, :k], x[:, k:])
        before = x[:-1]
        _, _, accelerations = p.actuator_motion(before[:, :k], before[:, k:], U)
        values = np.concatenate([lengths[1:], speeds[1:], accelerations], axis=1)
        # d(l, l')_(k+1) / dx_(k+1): [[J, 0], [S, J]], (T, 2L, 2k)
        J_after, S_after = J[1:], S[1:]
        state_map = np.concatenate(
            [
                np.concatenate([J_after, np.zeros_like(J_after)], axis=2),
                np.concatenate([S_after, J_after], axis=2),
            ],
            axis=1,
        )
        step = np.concatenate([self._Phi, self._Gamma], axis=1)  # (2k, 3k)
        T = U.shape[0]
        Fz = np.empty((T, self.size, 3 * k))
        Fz[:, : 2 * self.legs] = state_map @ step
        Fz[:, 2 * self.legs :, : 2 * k] = self._acceleration_state_jacobian(before, U)
        Fz[:, 2 * self.legs :, 2 * k :] = J[:-1]  # l'' = J u + c is linear in u
        return Fz, values

    def values(self, x: np.ndarray, U: np.ndarray) -> np.ndarray:
        """The legs' exact z_(k+1) along x (T + 1, 2k), U (T, k): (T, 3L)."""
        k, p = self.k, self.platform
        after, before = x[1:], x[:-1]
        lengths, speeds, _ = p.actuator_motion(after[:, :k], after[:, k:], np.zeros_like(U))
        _, _, accelerations = p.actuator_motion(before[:, :k], before[:, k:], U)
        return np.concatenate([lengths, speeds, accelerations], axis=1)

    def remainder(self, x, U, x_try, U_try, rows) -> np.ndarray:
        """What the linearisation `rows` (`rows(x, U)`'s (Fz, z)) misses at the trial
        trajectory (x_try, U_try): the legs' exact z there minus z + Fz (dx_k, du_k),
        shape (T, 3L)."""
        Fz, z = rows
        step = np.concatenate([x_try[:-1] - x[:-1], U_try - U], axis=1)  # (T, 3k)
        return self.values(x_try, U_try) - (z + np.einsum("tij,tj->ti", Fz, step))

    def _acceleration_state_jacobian(self, x: np.ndarray, U: np.ndarray) -> np.ndarray:
        """d l''(x_k, u_k) / dx_k, (T, L, 2k), by central differences."""
        k, p = self.k, self.platform
        out = np.empty((U.shape[0], self.legs, 2 * k))
        for i in range(2 * k):
            e = np.zeros(2 * k)
            e[i] = DIFFERENCE_STEP
            up = p.actuator_motion((x + e)[:, :k], (x + e)[:, k:], U)[2]
            down = p.actuator_motion((x - e)[:, :k], (x - e)[:, k:], U)[2]
            out[:, :, i] = (up - down) / (2 * DIFFERENCE_STEP)
        return out
