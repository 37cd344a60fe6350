"""The torch twin of `mca_drake.platforms.legs`: a legged platform's leg lengths from its
pose, differentiable, for training a policy through the legs."""

import torch

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


__all__ = ["leg_lengths", "rotation"]
