"""Input validation shared by the plants, the metrics and every config's `validate`.

Every public function that takes arrays checks them here, so a wrong shape or a NaN is
reported with the argument's name instead of failing deep inside a matrix product.
"""

from __future__ import annotations

import dataclasses
import typing

import numpy as np
import yaml

# A scenario or override is a few kilobytes; these bounds stop a file that expands (YAML
# aliases: 461 bytes can stand for gigabytes) before anything is expanded.
MAX_YAML_BYTES = 1_000_000
MAX_YAML_NODES = 100_000
# Error messages quote at most this many characters of what a user gave.
MAX_QUOTED_CHARS = 200


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
            if isinstance(item, int) and not -(2**63) <= item < 2**63:
                raise ValueError(f"{name}.{field.name} must fit in 64 bits; got {quoted(item)}")
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


def quoted(value: object, limit: int = MAX_QUOTED_CHARS) -> str:
    """`repr(value)`, cut to `limit` characters with the length said: error messages quote a
    user's input without repeating a huge one."""
    text = repr(value)
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text)} characters)"


def check_yaml_size(text: str, where: str) -> None:
    """Raises ValueError, naming `where`, for YAML text too large to be a scenario: over
    MAX_YAML_BYTES, or more than MAX_YAML_NODES nodes once its aliases are expanded. The
    count walks the node graph without expanding it (each shared node counted once per use
    by memoised sums), so an alias bomb is refused in microseconds.

    Raises:
        ValueError: too large, or not YAML at all (the parser's message, one line).
    """
    if len(text.encode("utf-8", errors="replace")) > MAX_YAML_BYTES:
        raise ValueError(f"{where}: over {MAX_YAML_BYTES} bytes, too large for a scenario")
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as err:
        raise ValueError(f"{where}: not valid YAML: {' '.join(str(err).split())}") from None
    sizes: dict[int, int] = {}

    def expanded(node) -> int:
        key = id(node)
        if key not in sizes:
            sizes[key] = 0  # a node that contains itself counts once
            if isinstance(node, yaml.SequenceNode):
                total = 1 + sum(expanded(child) for child in node.value)
            elif isinstance(node, yaml.MappingNode):
                total = 1 + sum(expanded(k) + expanded(v) for k, v in node.value)
            else:
                total = 1
            sizes[key] = min(total, MAX_YAML_NODES + 1)
        return sizes[key]

    if root is not None and expanded(root) > MAX_YAML_NODES:
        raise ValueError(
            f"{where}: more than {MAX_YAML_NODES} YAML nodes once its aliases are expanded; "
            "refusing it (a scenario holds a few hundred)"
        )
