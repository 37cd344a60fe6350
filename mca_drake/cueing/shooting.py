"""The joints' double integrator over the intervals of a multiple-shooting program.

Both the NMPC's fallback program and the offline-optimal bound keep the states as
variables beside the inputs (multiple shooting), so that their matrices stay sparse and
banded: per interval k of duration T_k, with u_k held over it,

    x_(k+1) = Phi_k x_k + Gamma_k u_k,   Phi_k = [[I, T_k I], [0, I]],
                                         Gamma_k = [[T_k^2 / 2 I], [T_k I]],

exactly (the plant's zero-order-hold step).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def double_integrator_step(duration: float, joints: int) -> tuple[np.ndarray, np.ndarray]:
    """(Phi (2n, 2n), Gamma (2n, n)) of the exact step of `duration` s for n `joints`."""
    eye = np.eye(joints)
    Phi = np.block([[eye, duration * eye], [np.zeros((joints, joints)), eye]])
    Gamma = np.vstack([0.5 * duration * duration * eye, duration * eye])
    return Phi, Gamma


def shooting_dynamics(durations, joints: int) -> tuple[sp.csc_matrix, list[np.ndarray]]:
    """The dynamics of N intervals as one sparse equality A z = b over z = (u_0..u_(N-1),
    x_1..x_N) (nN then 2nN columns for n joints): row block k is x_(k+1) - Phi_k x_k -
    Gamma_k u_k, whose right-hand side is 0 except for block 0's, Phi_0 x_0 (x_0 is data).
    Returns (A (2nN, 3nN), [Phi_k]).

    Args:
        durations: the intervals' lengths T_k, s, shape (N,).
        joints: the joint count n.
    """
    NX = 2 * joints
    durations = np.asarray(durations, dtype=float)
    steps = [double_integrator_step(float(T), joints) for T in durations]
    n = len(steps)
    inputs = -sp.block_diag([Gamma for _, Gamma in steps], format="csc")
    # Phi_k in row block k, column block k - 1 (k >= 1): x_k's coefficient in row block k
    shift = sp.csc_matrix((NX * n, NX * n))
    if n > 1:
        below = sp.block_diag([Phi for Phi, _ in steps[1:]], format="csc")
        shift = sp.bmat(
            [
                [sp.csc_matrix((NX, NX * (n - 1))), sp.csc_matrix((NX, NX))],
                [below, sp.csc_matrix((NX * (n - 1), NX))],
            ],
            format="csc",
        )
    states = sp.identity(NX * n, format="csc") - shift
    return sp.hstack([inputs, states], format="csc"), [Phi for Phi, _ in steps]
