"""Input validation shared by the plants, the metrics and every config's `validate`.

Every public function that takes arrays checks them here, so a wrong shape or a NaN is
reported with the argument's name instead of failing deep inside a matrix product.
"""

from __future__ import annotations

import dataclasses
import typing

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


# Longest simulated run, s: the logs of a 1 kHz station over 3 h already take about 0.5 GB.
MAX_DURATION_S = 3 * 3600.0


def check_config_numbers(config) -> None:
    """Raises ValueError naming the class and field of the first number in a config
    dataclass (lists and nested dataclasses included) that is NaN or infinite, or a
    non-integer where an int is declared: every config's `validate` starts here, so no
    setting reaches a simulation as NaN, inf or 2.5 flights."""
    name = type(config).__name__
    hints = typing.get_type_hints(type(config))
    for field in dataclasses.fields(config):
        declared = hints.get(field.name)
        whole = declared is int or (
            typing.get_origin(declared) in (list, tuple) and typing.get_args(declared)[:1] == (int,)
        )
        value = getattr(config, field.name)
        if dataclasses.is_dataclass(value):
            check_config_numbers(value)
            continue
        values = value if isinstance(value, list | tuple) else [value]
        for item in values:
            if isinstance(item, bool) or not isinstance(item, int | float | np.number):
                continue
            if not np.isfinite(item):
                raise ValueError(f"{name}.{field.name} must be a finite number; got {value}")
            if whole and float(item) != int(item):
                raise ValueError(f"{name}.{field.name} must be a whole number; got {value}")


def check_range(
    owner: str, name: str, value, low: float, high: float, *, low_open: bool = False
) -> None:
    """Raises ValueError unless low <= value <= high (low < value with `low_open`), with a
    message naming `owner.name` and the range."""
    ok = (low < value if low_open else low <= value) and value <= high
    if not ok:
        opening = "(" if low_open else "["
        raise ValueError(f"{owner}.{name} must be in {opening}{low:g}, {high:g}]; got {value}")
