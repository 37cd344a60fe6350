"""MeshcatLegs: a legged platform's legs drawn in Meshcat, coloured by how much of their
stroke they use."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, Rgba
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from mca_drake.platforms.leg_platform import LegPlatform
from mca_drake.platforms.legs import rotation

# A leg at mid-stroke is drawn in the first colour, one at a stroke's end in the second.
_MIDDLE = np.array([0.2, 0.6, 0.25])
_END = np.array([0.9, 0.15, 0.1])


def leg_segments(platform: LegPlatform, q) -> np.ndarray:
    """Each leg's two joint centres in the world (the base frame) at coordinates q (k,):
    shape (legs, 2, 3), base joint first."""
    x, y, z, roll, pitch, yaw = platform.pose(np.asarray(q, dtype=float))
    geometry = platform.actuators
    R = rotation(roll, pitch, yaw)
    t = np.array([x, y, geometry.neutral_height + z])
    top = t + np.asarray(geometry.platform_joints, dtype=float) @ R.T
    return np.stack([np.asarray(geometry.base_joints, dtype=float), top], axis=1)


def stroke_used(platform: LegPlatform, lengths: np.ndarray) -> np.ndarray:
    """Each leg's distance from mid-stroke as a share of half the stroke: 0 in the middle,
    1 at an end, shape (legs,)."""
    geometry = platform.actuators
    middle = 0.5 * (geometry.min_length + geometry.max_length)
    half = 0.5 * (geometry.max_length - geometry.min_length)
    return np.abs(lengths - middle) / half


class MeshcatLegs(LeafSystem):
    """Draws a legged platform's legs in Meshcat as lines between their joint centres,
    green at mid-stroke turning red towards a stroke's end (the virtual chain's URDF draws
    only the base and the moving platform).

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
        lengths = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
        for i, (segment, used) in enumerate(
            zip(segments, stroke_used(self._platform, lengths), strict=True)
        ):
            r, g, b = _MIDDLE + min(float(used), 1.0) * (_END - _MIDDLE)
            self._meshcat.SetLine(
                f"{self._prefix}/leg_{i + 1}", segment.T, self._width, Rgba(r, g, b, 1.0)
            )
        return EventStatus.Succeeded()


__all__ = ["MeshcatLegs", "leg_segments", "stroke_used"]
