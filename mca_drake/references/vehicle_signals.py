"""What a recording may carry beside the motion: the driver's or pilot's controls and the
vehicle's state, as optional named columns.

Controls come before the motion they cause (a stick deflection before the roll, a brake
pedal before the deceleration), and the vehicle's state says what motion is possible (the
wheels on the ground, the speed); a predictor reads them where a source gives them
(`mca_drake.cueing.predictor`). A recording CSV may hold any of `SIGNALS` as columns named
in its header, in the units listed (or one of `SIGNAL_UNITS` in brackets); the loader keeps
them, converted to SI, and ignores other extra columns as before.

Signs follow the motion each control commands: aircraft controls as pilots count them
(aileron positive rolls right, elevator positive pitches the nose up, rudder positive yaws
the nose right), the steering as ISO 8855 counts it (positive turns left, towards +y of the
head frame). Normalised controls are -1 ... 1 (aileron, elevator, rudder, steering) or
0 ... 1 (throttle, brake).
"""

from __future__ import annotations

import math

import numpy as np

# name: (unit written in a header, what it is)
SIGNALS = {
    "aileron": ("1", "roll command, -1 ... 1, positive rolls right"),
    "elevator": ("1", "pitch command, -1 ... 1, positive pitches the nose up"),
    "rudder": ("1", "yaw command, -1 ... 1, positive yaws the nose right"),
    "throttle": ("1", "throttle, 0 (idle) ... 1 (full)"),
    "brake": ("1", "brake, 0 (off) ... 1 (full)"),
    "steering": ("1", "steering, -1 ... 1 of full lock, positive turns left"),
    "speed": ("m/s", "speed over ground (a car) or airspeed, calibrated or indicated"),
    "roll": ("rad", "roll angle, positive right side down"),
    "pitch": ("rad", "pitch angle, positive nose up"),
    "height": ("m", "height of the vehicle's reference point above the ground"),
    "on_ground": ("1", "1 with weight on the wheels, else 0"),
}
# Units a header may name in brackets for a signal of that SI unit, and the factor to SI.
SIGNAL_UNITS = {
    "1": {"1": 1.0, "": 1.0},
    "m/s": {"m/s": 1.0, "km/h": 1 / 3.6, "kt": 1852.0 / 3600.0, "mph": 0.44704},
    "rad": {"rad": 1.0, "deg": math.pi / 180.0},
    "m": {"m": 1.0, "ft": 0.3048},
}
# The bounds a normalised control must keep (a wider value is another unit: percent?).
CONTROL_BOUNDS = {
    "aileron": (-1.0, 1.0),
    "elevator": (-1.0, 1.0),
    "rudder": (-1.0, 1.0),
    "steering": (-1.0, 1.0),
    "throttle": (0.0, 1.0),
    "brake": (0.0, 1.0),
    "on_ground": (0.0, 1.0),
}
# Slack on those bounds (JSBSim's commands overshoot 1 by rounding).
BOUND_SLACK = 1e-6


def signal_factor(name: str, unit: str | None) -> float:
    """The factor from `unit` (None: the SI unit) to the SI unit of signal `name`.

    Raises:
        ValueError: an unknown signal or a unit it cannot be in.
    """
    if name not in SIGNALS:
        raise ValueError(f"unknown signal '{name}'; known: {', '.join(SIGNALS)}")
    si = SIGNALS[name][0]
    if unit is None:
        return 1.0
    if unit not in SIGNAL_UNITS[si]:
        valid = ", ".join(u for u in SIGNAL_UNITS[si] if u)
        raise ValueError(f"unknown unit '{unit}' for {name}; valid: {valid}")
    return SIGNAL_UNITS[si][unit]


def within_bounds(name: str, low: float, high: float | None = None) -> bool:
    """Whether values from `low` to `high` (default `low`: one value) fit signal `name`'s
    bounds (`CONTROL_BOUNDS`; a signal without bounds fits any)."""
    bounds = CONTROL_BOUNDS.get(name)
    high = low if high is None else high
    return bounds is None or (low >= bounds[0] - BOUND_SLACK and high <= bounds[1] + BOUND_SLACK)


def check_signal(name: str, values) -> str | None:
    """Why `values` (SI) cannot be signal `name`, or None: a normalised control outside its
    bounds (a column in percent, say)."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return None
    low, high = float(values.min()), float(values.max())
    bounds = CONTROL_BOUNDS.get(name)
    if not within_bounds(name, low, high):
        return (
            f"{name} spans {low:.6g} ... {high:.6g}, outside {bounds[0]:g} ... {bounds[1]:g} "
            "(a normalised control; is it in percent?)"
        )
    return None


def signal_matrix(signals: dict, names, length: int) -> np.ndarray:
    """(length, len(names)): the signals of a recording or reference (name -> (T,)) in the
    order `names`, NaN columns for those it does not carry."""
    out = np.full((length, len(names)), np.nan)
    for i, name in enumerate(names):
        if name in signals:
            out[:, i] = np.asarray(signals[name], dtype=float)
    return out
