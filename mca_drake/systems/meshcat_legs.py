"""MeshcatLegs: a legged platform's legs drawn in Meshcat, coloured by how much of their
actuators' range they use."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, Rgba
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from mca_drake.platforms.leg_platform import LegPlatform
from mca_drake.platforms.legs import arm_tips, rotation

# An actuator mid-range is drawn in the first colour, one at a range's end in the second.
_MIDDLE = np.array([0.2, 0.6, 0.25])
_END = np.array([0.9, 0.15, 0.1])


def leg_segments(platform: LegPlatform, q) -> np.ndarray:
    """Each leg as a polyline of joint centres in the world (the base frame) at coordinates
    q (k,), base first: (legs, 2, 3) for linear legs (base and platform joints), (legs, 3,
    3) for cranks (the arm's pivot, its tip, the platform joint)."""
    pose = platform.pose(np.asarray(q, dtype=float))
    x, y, z, roll, pitch, yaw = pose
    geometry = platform.actuators
    R = rotation(roll, pitch, yaw)
    t = np.array([x, y, geometry.neutral_height + z])
    top = t + np.asarray(geometry.platform_joints, dtype=float) @ R.T
    base = np.asarray(geometry.base_joints, dtype=float)
    if geometry.cranks is None:
        return np.stack([base, top], axis=1)
    return np.stack([base, arm_tips(pose, geometry), top], axis=1)


def stroke_used(platform: LegPlatform, positions: np.ndarray) -> np.ndarray:
    """Each actuator's distance from the middle of its range as a share of half the range:
    0 in the middle, 1 at an end, shape (legs,), of positions (legs,) (m; rad for cranks)."""
    geometry = platform.actuators
    middle = 0.5 * (geometry.min_position + geometry.max_position)
    half = 0.5 * (geometry.max_position - geometry.min_position)
    return np.abs(positions - middle) / half


class MeshcatLegs(LeafSystem):
    """Draws a legged platform's legs in Meshcat as lines between their joint centres (a
    crank's arm and rod), green at mid-range turning red towards a range's end (the
    virtual chain's URDF draws only the base and the moving platform).

    .. pydrake_system::

        name: MeshcatLegs
        input_ports:
        - state

    `state` (2k): [q, qd] of the platform. Drawn in a periodic publish every
    `publish_period` s under `prefix/leg_i`.
    """

    def __init__(
        self,
        meshcat: Meshcat,
        platform: LegPlatform,
        publish_period: float = 1 / 30,
        line_width: float = 6.0,
        prefix: str = "legs",
    ):
        super().__init__()
        if not publish_period > 0:
            raise ValueError(f"publish_period must be positive; got {publish_period}")
        self._meshcat, self._platform = meshcat, platform
        self._width, self._prefix = float(line_width), prefix
        self._state = self.DeclareVectorInputPort("state", 2 * platform.num_joints)
        self.DeclarePeriodicPublishEvent(publish_period, 0.0, self._draw)
        self.DeclareInitializationPublishEvent(self._draw)

    def _draw(self, context: Context) -> EventStatus:
        q = self._state.Eval(context)[: self._platform.num_joints]
        segments = leg_segments(self._platform, q)
        positions = self._platform.actuator_positions(q)
        for i, (segment, used) in enumerate(
            zip(segments, stroke_used(self._platform, positions), strict=True)
        ):
            r, g, b = _MIDDLE + min(float(used), 1.0) * (_END - _MIDDLE)
            self._meshcat.SetLine(
                f"{self._prefix}/leg_{i + 1}", segment.T, self._width, Rgba(r, g, b, 1.0)
            )
        return EventStatus.Succeeded()


__all__ = ["MeshcatLegs", "leg_segments", "stroke_used"]
