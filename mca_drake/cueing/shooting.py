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

from mca_drake.platforms.serial import NUM_JOINTS

NU, NX = NUM_JOINTS, 2 * NUM_JOINTS


def double_integrator_step(duration: float) -> tuple[np.ndarray, np.ndarray]:
    """(Phi (12, 12), Gamma (12, 6)) of the exact step of `duration` s."""
    eye = np.eye(NU)
    Phi = np.block([[eye, duration * eye], [np.zeros((NU, NU)), eye]])
    Gamma = np.vstack([0.5 * duration * duration * eye, duration * eye])
    return Phi, Gamma


def shooting_dynamics(durations) -> tuple[sp.csc_matrix, list[np.ndarray]]:
    """The dynamics of N intervals as one sparse equality A z = b over z = (u_0..u_(N-1),
    x_1..x_N) (6N then 12N columns): row block k is x_(k+1) - Phi_k x_k - Gamma_k u_k, whose
    right-hand side is 0 except for block 0's, Phi_0 x_0 (x_0 is data). Returns (A (12N,
    18N), [Phi_k]).

    Args:
        durations: the intervals' lengths T_k, s, shape (N,).
    """
    steps = [double_integrator_step(float(T)) for T in np.asarray(durations, dtype=float)]
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
