"""Which controller axis moves each platform joint, in the controller's units.

A KUKA controller running RSI moves its robot's six axes A1-A6 and up to six external axes
E1-E6 of the same controller (a linear track, a turntable). A platform of n joints (6 to 12)
is driven as one such controller: the chain's last six joints are the robot's A1-A6 and the
first n - 6, the axes that carry the robot (the rail under a KR500 is the chain's first
joint), are E1, E2, ... in chain order, as KUKA numbers a track E1.

The controller's units are degrees for a revolute joint and millimetres for a prismatic
one (KUKA's unit for a linear external axis); the model's are rad and m. Each axis has a
sign (the controller's direction against the model's joint) and a home value (what the
controller reads at the model's home pose; by default the model's zero is the controller's,
so home = sign * scale * q_home). The controller's values are those of the RSI messages
(`rsi.xml`): actual positions in the state, corrections relative to the pose at the start
of the RSI motion (the home) in the reply.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

# Controller units per model unit: degrees per radian, millimetres per metre.
DEG_PER_RAD = 180.0 / math.pi
MM_PER_M = 1000.0
# The controller's unit of each kind of joint.
UNITS = {"revolute": "deg", "prismatic": "mm"}
# The robot's own axes: a platform over RSI has at least these.
ROBOT_AXES = 6


@dataclasses.dataclass(frozen=True)
class RsiAxisMap:
    """The controller axis of every platform joint (module docstring), in chain order.

    Attributes:
        names: the controller's name of each joint's axis ("E1", "A1", ...), shape (n,).
        units: "deg" or "mm" per joint.
        scales: controller units per model unit, with the axis's sign, per joint.
        home: the controller's value at the model's home pose, per joint.
        home_q: the model's home pose, rad or m, per joint.
        external: how many joints (the chain's first) are external axes.
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    scales: tuple[float, ...]
    home: tuple[float, ...]
    home_q: tuple[float, ...]
    external: int

    @classmethod
    def build(
        cls,
        joint_kinds: Sequence[str],
        home_q: Sequence[float],
        robot_axes: Sequence[str],
        external_axes: Sequence[str],
        axis_signs: Sequence[float] = (),
        external_signs: Sequence[float] = (),
        home_deg: Sequence[float] = (),
        external_home: Sequence[float] = (),
    ) -> RsiAxisMap:
        """The map of a platform with these joints onto a controller's axes.

        Args:
            joint_kinds: "revolute" or "prismatic" per joint, base to tip (n of them).
            home_q: the model's home pose, rad or m (n).
            robot_axes: the controller's robot axis names (six: A1..A6).
            external_axes: its external axis names, E1 first (the first n - 6 are used).
            axis_signs: +1 or -1 per robot axis (empty: all +1).
            external_signs: +1 or -1 per external axis (empty: all +1).
            home_deg: the controller's reading of the robot axes at the model's home, deg
                (empty: sign * scale * home_q).
            external_home: the same of the external axes, mm or deg (empty: likewise).

        Raises:
            ValueError: a joint count the controller cannot drive, or signs and homes of
                the wrong length, naming the setting.
        """
        kinds, home_q = tuple(joint_kinds), tuple(float(v) for v in home_q)
        n, robot = len(kinds), len(robot_axes)
        external = n - robot
        if not 0 <= external <= len(external_axes) or len(home_q) != n:
            raise ValueError(
                f"an RSI controller drives {robot} robot axes ({robot_axes[0]}-{robot_axes[-1]})"
                f" and up to {len(external_axes)} external axes: a platform of {robot} to "
                f"{robot + len(external_axes)} joints; this one has {n}"
            )
        if any(kind not in UNITS for kind in kinds):
            raise ValueError(f"joint kinds must be revolute or prismatic; got {kinds}")
        signs = _settings("RsiDriverConfig.external_signs", external_signs, external, 1.0)
        signs += _settings("RsiDriverConfig.axis_signs", axis_signs, robot, 1.0)
        if any(s not in (1.0, -1.0) for s in signs):
            raise ValueError(f"axis signs must be +1 or -1; got {signs}")
        scales = tuple(
            sign * (DEG_PER_RAD if kind == "revolute" else MM_PER_M)
            for sign, kind in zip(signs, kinds, strict=True)
        )
        default = [scale * q for scale, q in zip(scales, home_q, strict=True)]
        home = _settings("RsiDriverConfig.external_home", external_home, external, None)
        home += _settings("RsiDriverConfig.home_deg", home_deg, robot, None)
        home = [d if h is None else h for h, d in zip(home, default, strict=True)]
        names = tuple(external_axes[:external]) + tuple(robot_axes)
        return cls(names, tuple(UNITS[k] for k in kinds), scales, tuple(home), home_q, external)

    @property
    def robot_names(self) -> tuple[str, ...]:
        """The robot axes' names, A1 first."""
        return self.names[self.external :]

    @property
    def external_names(self) -> tuple[str, ...]:
        """The external axes' names, E1 first."""
        return self.names[: self.external]

    def corrections(self, q: Sequence[float]) -> tuple[list[float], list[float]]:
        """The reply's corrections for joint positions q (rad or m, n): the robot axes'
        (deg, six) and the external axes' (mm or deg, E1 first), relative to the home."""
        values = [s * (v - h) for s, v, h in zip(self.scales, q, self.home_q, strict=True)]
        return values[self.external :], values[: self.external]

    def chain_order(self, robot_values: Sequence[float], external_values: Sequence[float]):
        """Controller values given as the messages hold them (robot axes, then external
        ones) in chain order (per joint)."""
        return [*external_values[: self.external], *robot_values]

    def in_message_order(self, per_joint: Sequence) -> list:
        """Values per joint (chain order) in the messages' order: A1..A6, then E1.. (the
        inverse of `chain_order`)."""
        return [*per_joint[self.external :], *per_joint[: self.external]]


def _settings(name: str, values: Sequence[float], count: int, default) -> list:
    """`values` as floats, or `count` of `default` where none are given."""
    if not values:
        return [default] * count
    if len(values) != count:
        raise ValueError(f"{name} must hold {count} values for this platform; got {list(values)}")
    return [float(v) for v in values]


__all__ = ["DEG_PER_RAD", "MM_PER_M", "ROBOT_AXES", "UNITS", "RsiAxisMap"]
