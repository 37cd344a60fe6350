"""The torch twin of `mca_drake.platforms.legs`: a legged platform's leg lengths from its
pose, differentiable, for training a policy through the legs, and the legs' limits as the
penalty a DPC rollout pays (`LegLimits`)."""

import torch
from torch import nn

from mca_drake.platforms.leg_clamp import RATE_RESERVE, STROKE_RESERVE_M
from mca_drake.platforms.leg_platform import POSE_INDEX, LegPlatform
from mca_drake.platforms.legs import LegGeometry


def rotation(roll: torch.Tensor, pitch: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """Rz(yaw) Ry(pitch) Rx(roll), batched: angles (...), result (..., 3, 3)."""
    cr, sr = torch.cos(roll), torch.sin(roll)
    cp, sp = torch.cos(pitch), torch.sin(pitch)
    cy, sy = torch.cos(yaw), torch.sin(yaw)
    rows = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)


def leg_lengths(pose: torch.Tensor, geometry: LegGeometry) -> torch.Tensor:
    """The leg lengths (m) of `pose` (..., 6: x, y, z, roll, pitch, yaw relative to the
    neutral pose; m, rad), as `platforms.legs.leg_lengths`: (..., legs)."""
    if pose.shape[-1] != 6:
        raise ValueError(f"a pose is six numbers (x, y, z, roll, pitch, yaw); got {pose.shape}")
    p = torch.as_tensor(geometry.platform_joints, dtype=pose.dtype, device=pose.device)
    b = torch.as_tensor(geometry.base_joints, dtype=pose.dtype, device=pose.device)
    R = rotation(pose[..., 3], pose[..., 4], pose[..., 5])
    lift = torch.zeros(3, dtype=pose.dtype, device=pose.device)
    lift[2] = geometry.neutral_height
    t = pose[..., :3] + lift
    legs = t[..., None, :] + torch.einsum("...jk,ik->...ij", R, p) - b
    return torch.linalg.vector_norm(legs, dim=-1)


class LegLimits(nn.Module):
    """How far a legged platform's rollout takes its legs past their stroke and speed: the
    DPC loss's limit term for the legs (the coordinates' box is the policy's own).

    The legs' lengths are exact (`leg_lengths` of each state's pose); their speeds are the
    lengths' differences over a control period (what the rollout's steps move them by), so
    the term needs no derivatives of the kinematics beyond autograd's. The limits keep the
    viability clamp's reserves (`platforms.leg_clamp`), so that a policy trained inside them
    is one the deployed clamp lets through unchanged.

    Args:
        platform: the legged platform (k coordinates).
        dt: the rollout's control period, s.
    """

    def __init__(self, platform: LegPlatform, dt: float):
        super().__init__()
        self.geometry = geometry = platform.actuators
        self.dt = float(dt)
        k = platform.num_joints
        to_pose = torch.zeros(k, 6)
        for i, coordinate in enumerate(platform.coordinates):
            to_pose[i, POSE_INDEX[coordinate]] = 1.0
        self.register_buffer("to_pose", to_pose, persistent=False)
        self.low = geometry.min_length + STROKE_RESERVE_M
        self.high = geometry.max_length - STROKE_RESERVE_M
        self.max_speed = geometry.max_speed * (1.0 - RATE_RESERVE)

    def lengths(self, X: torch.Tensor) -> torch.Tensor:
        """The leg lengths (m) of states X (..., 2k): (..., legs)."""
        k = self.to_pose.shape[0]
        return leg_lengths(X[..., :k] @ self.to_pose.to(X), self.geometry)

    def excess(self, X: torch.Tensor) -> torch.Tensor:
        """Per step of a rollout X (B, T + 1, 2k): the sum over legs of the squared excess
        beyond the stroke at the step's end (m^2) and beyond the speed over the step
        ((m/s)^2), shape (B, T)."""
        lengths = self.lengths(X)
        after = lengths[:, 1:]
        stroke = torch.relu(after - self.high) + torch.relu(self.low - after)
        speed = torch.relu((lengths[:, 1:] - lengths[:, :-1]).abs() / self.dt - self.max_speed)
        return (stroke**2 + speed**2).sum(-1)


__all__ = ["LegLimits", "leg_lengths", "rotation"]
