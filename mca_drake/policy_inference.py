"""Numpy inference of the DPC policy network (no torch at run time: a few microseconds).

Equal to `mca_drake.learning.policy.PolicyNetwork` (tested to 1e-6): the same scaled inputs,
two bias-free layers with the exact (erf) GELU between, and the saturation to the limits.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.special import erf

from mca_drake.robot import NUM_JOINTS

_SQRT_HALF = np.sqrt(0.5)


def default_policy_path() -> Path:
    """The policy shipped with the package (mca_drake/data/default_policy.npz); raises
    FileNotFoundError with the command that makes one if it is missing."""
    path = Path(__file__).resolve().parent / "data" / "default_policy.npz"
    if not path.is_file():
        raise FileNotFoundError(
            f"no default policy at {path}; train one with `mca-drake train-policy` and pass "
            "--policy, or reinstall the package"
        )
    return path


class PolicyInference:
    """u, x_hat = policy(y, x, target) in numpy from the arrays of a policy file.

    Args:
        arrays: W1 (hidden, 24), W2 (18, hidden), input_scale (24), lower, upper (18), as
            written by `mca_drake.learning.policy.save_policy` (see `load_policy_arrays`).
    """

    def __init__(self, arrays: dict[str, np.ndarray]):
        # Fold the input scaling into the first layer: W1 (v / s) = (W1 / s) v.
        self._W1 = np.ascontiguousarray(arrays["W1"] / arrays["input_scale"][None, :])
        self._W2 = np.ascontiguousarray(arrays["W2"])
        self._lower, self._upper = arrays["lower"].copy(), arrays["upper"].copy()
        self._features = np.empty(self._W1.shape[1])

    def __call__(self, y, x, target) -> tuple[np.ndarray, np.ndarray]:
        """(u (6), x_hat (12)) for y (6), x (12), target (6); 1-D numpy arrays."""
        f = self._features
        f[:6], f[6:18], f[18:] = y, x, target
        a = self._W1 @ f
        a = 0.5 * a * (1.0 + erf(a * _SQRT_HALF))
        z = np.minimum(np.maximum(self._W2 @ a, self._lower), self._upper)
        return z[:NUM_JOINTS], z[NUM_JOINTS:]
