"""The viability clamp of any platform: the safety filter every MCA, the station and the
live supervisor put between a command and the machine."""

from __future__ import annotations

from mca_drake.platforms.leg_clamp import LegClamp
from mca_drake.platforms.leg_platform import LegPlatform
from mca_drake.safety import ViabilityClamp


def platform_clamp(robot, h: float, position_coefficient: float = 0.5):
    """The viability clamp of `robot` at control period h (s): for a `LegPlatform` its
    legs' and coordinates' (`LegClamp`), for a serial chain its joints'
    (`ViabilityClamp.for_robot`). Both map `(x, u)` to `(u_safe, intervened)` and answer
    `is_viable(x)`.

    Args:
        robot: the platform.
        h: control period, s.
        position_coefficient: c of the step q' = q + h qd + c h^2 u (`mca_drake.safety`).
    """
    if isinstance(robot, LegPlatform):
        return LegClamp(robot, h, position_coefficient=position_coefficient)
    return ViabilityClamp.for_robot(robot, h, position_coefficient=position_coefficient)


__all__ = ["platform_clamp"]
