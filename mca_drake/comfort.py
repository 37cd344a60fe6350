"""Cabin comfort: how fast the cabin's specific force may change, whatever the MCA commands.

A cue inside every joint limit can still be a jolt: the occupant feels the change of the
specific force at the head between two control periods. `ComfortConfig.max_force_change`
bounds it (m/s^2 per control period h; a head jerk of max_force_change / h). The force is
affine in the joint accelerations (`platforms.kinematics.plant_output`):
f(x, u) = f(x, u_prev) + a, with a = f(x, u) - f(x, u_prev) exact. Against the force of
the last period f_prev, the change of a command u_prev + alpha (u - u_prev) is

    df(alpha) = alpha a + c,    c = f(x, u_prev) - f_prev   (the state's own drift),

and `comfort_fraction` gives the largest alpha in [0, 1] with |df| <= max_force_change
(closed form: a quadratic in alpha). Where even alpha = 0 exceeds it (the drift alone), it
takes the alpha that changes the force least. The viability clamp has the last word: a
command the joint limits need passes whatever the jolt, and the periods over the bound are
counted (`force_changes`, the summary's `comfort` block). The f rows are (f_x, f_y, a_z) of
the plant output y; rotating them into the head frame keeps their norm, so the bound holds
the head's linear jerk and the felt force change alike.
"""

import dataclasses
import math

import numpy as np

from mca_drake.input_checks import check_config_numbers

# The rows of the plant output y that are the cabin's specific force (f_x, f_y, a_z).
FORCE_ROWS = slice(3, 6)
# A period whose force change exceeds the bound by more than this (m/s^2) is counted.
COMFORT_TOLERANCE = 1e-6


@dataclasses.dataclass
class ComfortConfig:
    """The cabin comfort bound (module docstring)."""

    # Largest change of the cabin's specific force (f_x, f_y, a_z; vector norm) from one
    # control period to the next, m/s^2; 0: no bound (the default, as the suite's figures
    # are measured).
    max_force_change: float = 0.0

    @property
    def enabled(self) -> bool:
        """Whether the bound acts (a positive `max_force_change`)."""
        return self.max_force_change > 0

    def validate(self) -> None:
        """Raises ValueError for a bound that cannot hold, naming the field."""
        check_config_numbers(self)
        if not self.max_force_change >= 0:
            raise ValueError("ComfortConfig.max_force_change must be >= 0 (0: no bound)")


def comfort_fraction(a, c, limit: float) -> float:
    """The largest alpha in [0, 1] with |alpha a + c| <= limit (3-vectors a, c, m/s^2),
    or, where alpha = 0 already exceeds it, the alpha in [0, 1] minimizing |alpha a + c|."""
    aa = sum(v * v for v in a)
    ac = sum(p * q for p, q in zip(a, c, strict=True))
    cc = sum(v * v for v in c)
    if aa == 0.0:
        return 1.0
    if cc > limit * limit:
        return min(max(-ac / aa, 0.0), 1.0)
    # aa alpha^2 + 2 ac alpha + (cc - limit^2) <= 0 holds on [lower, upper] with lower <= 0
    upper = (-ac + math.sqrt(max(ac * ac - aa * (cc - limit * limit), 0.0))) / aa
    return min(max(upper, 0.0), 1.0)


def force_changes(outputs: np.ndarray) -> np.ndarray:
    """|f_k - f_(k-1)| of a run's outputs y (T, 6), m/s^2 per period, shape (T - 1,)."""
    forces = np.asarray(outputs, dtype=float)[:, FORCE_ROWS]
    return np.linalg.norm(np.diff(forces, axis=0), axis=1)


def comfort_block(outputs: np.ndarray, config: ComfortConfig, bounded_periods: int) -> dict:
    """The summary's `comfort` block: the bound, the periods whose force change exceeded
    it (the clamp's precedence, or the drift) and the periods the bound scaled a command."""
    changes = force_changes(outputs)
    return {
        "max_force_change_m_s2": config.max_force_change,
        "exceeded_periods": int(np.sum(changes > config.max_force_change + COMFORT_TOLERANCE)),
        "bounded_periods": int(bounded_periods),
        "largest_force_change_m_s2": float(changes.max()) if changes.size else 0.0,
    }


__all__ = [
    "COMFORT_TOLERANCE",
    "FORCE_ROWS",
    "ComfortConfig",
    "comfort_block",
    "comfort_fraction",
    "force_changes",
]
