"""Input validation shared by the numpy plant, the torch plant and the metrics.

Every public function that takes arrays checks them here, so a wrong shape or a NaN is
reported with the argument's name instead of failing deep inside a matrix product.
"""

from __future__ import annotations

import numpy as np


def as_float_array(name: str, value, *, last_dim: int | None = None) -> np.ndarray:
    """`value` as a float64 array with finite entries (and last dimension `last_dim`).

    Raises:
        ValueError: not numeric, wrong last dimension, or NaN/inf entries.
    """
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name} must be numeric: {err}") from err
    if last_dim is not None and (array.ndim == 0 or array.shape[-1] != last_dim):
        raise ValueError(f"{name} must have shape (..., {last_dim}); got shape {array.shape}")
    check_finite(name, array)
    return array


def check_finite(name: str, array: np.ndarray) -> None:
    """Raises ValueError naming the first non-finite entry of `array`."""
    if not np.all(np.isfinite(array)):
        bad = np.argwhere(~np.isfinite(array))[0]
        raise ValueError(
            f"{name} has non-finite entries (first at index {tuple(int(i) for i in bad)}: "
            f"{array[tuple(bad)]})"
        )


def same_shapes(**arrays: np.ndarray) -> None:
    """Raises ValueError unless all arrays have the same shape."""
    shapes = {name: a.shape for name, a in arrays.items()}
    if len(set(shapes.values())) > 1:
        listed = ", ".join(f"{n} {s}" for n, s in shapes.items())
        raise ValueError(f"shapes must match: {listed}")
