"""The torch twin of `mca_drake.platforms.legs`: a legged platform's actuator positions
(leg lengths; crank angles) from its pose, differentiable, for training a policy through
the legs, and the legs' limits as the penalty a DPC rollout pays (`LegLimits`)."""

import torch
from torch import nn

from mca_drake.platforms.leg_clamp import POSITION_RESERVE, RATE_RESERVE
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


def _leg_vectors(pose: torch.Tensor, geometry: LegGeometry) -> torch.Tensor:
    """The leg vectors t + R p_i - b_i (..., legs, 3) of poses (..., 6), as
    `platforms.legs`."""
    if pose.shape[-1] != 6:
        raise ValueError(f"a pose is six numbers (x, y, z, roll, pitch, yaw); got {pose.shape}")
    p = torch.as_tensor(geometry.platform_joints, dtype=pose.dtype, device=pose.device)
    b = torch.as_tensor(geometry.base_joints, dtype=pose.dtype, device=pose.device)
    R = rotation(pose[..., 3], pose[..., 4], pose[..., 5])
    lift = torch.zeros(3, dtype=pose.dtype, device=pose.device)
    lift[2] = geometry.neutral_height
    t = pose[..., :3] + lift
    return t[..., None, :] + torch.einsum("...jk,ik->...ij", R, p) - b


def leg_lengths(pose: torch.Tensor, geometry: LegGeometry) -> torch.Tensor:
    """The distances (m) between each leg's joints at `pose` (..., 6: x, y, z, roll, pitch,
    yaw relative to the neutral pose; m, rad), as `platforms.legs.leg_lengths`:
    (..., legs)."""
    return torch.linalg.vector_norm(_leg_vectors(pose, geometry), dim=-1)


def actuator_positions(pose: torch.Tensor, geometry: LegGeometry) -> torch.Tensor:
    """The actuators' positions at `pose` (..., 6), as
    `platforms.legs.actuator_positions`: leg lengths (m), or where cranks turn the legs the
    arms' angles (rad) by the same closed form; (..., legs). Past a crank's reach the
    angle is clipped to the nearest reachable one (the limit term then sees the arm at
    its extreme, with a gradient towards reach)."""
    legs = _leg_vectors(pose, geometry)
    cranks = geometry.cranks
    if cranks is None:
        return torch.linalg.vector_norm(legs, dim=-1)
    options = {"dtype": pose.dtype, "device": pose.device}
    e = torch.as_tensor(cranks.arm_directions, **options)
    f = torch.as_tensor(cranks.turn_directions(), **options)
    arm, rod = cranks.arm_length, cranks.rod_length
    M, N = (legs * e).sum(-1), (legs * f).sum(-1)
    K = ((legs * legs).sum(-1) + arm**2 - rod**2) / (2.0 * arm)
    # the reach's edge clipped inside +-1, where acos's derivative is still finite
    ratio = (K / torch.hypot(M, N)).clamp(-1.0 + 1e-9, 1.0 - 1e-9)
    branch = torch.where(N >= 0, 1.0, -1.0).to(pose.dtype)
    return torch.atan2(N, M) - branch * torch.acos(ratio)


class LegLimits(nn.Module):
    """How far a legged platform's rollout takes its actuators past their range and speed:
    the DPC loss's limit term for the legs (the coordinates' box is the policy's own).

    The actuators' positions are exact (`actuator_positions` of each state's pose: leg
    lengths, or crank angles); their speeds are the positions' differences over a control
    period (what the rollout's steps move them by), so
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
        self.low = geometry.min_position + POSITION_RESERVE
        self.high = geometry.max_position - POSITION_RESERVE
        self.max_speed = geometry.max_speed * (1.0 - RATE_RESERVE)

    def lengths(self, X: torch.Tensor) -> torch.Tensor:
        """The actuators' positions (m; rad for cranks) of states X (..., 2k): (..., legs)."""
        k = self.to_pose.shape[0]
        return actuator_positions(X[..., :k] @ self.to_pose.to(X), self.geometry)

    def excess(self, X: torch.Tensor) -> torch.Tensor:
        """Per step of a rollout X (B, T + 1, 2k): the sum over legs of the squared excess
        beyond the range at the step's end (m^2; rad^2) and beyond the speed over the step
        ((m/s)^2; (rad/s)^2), shape (B, T)."""
        lengths = self.lengths(X)
        after = lengths[:, 1:]
        stroke = torch.relu(after - self.high) + torch.relu(self.low - after)
        speed = torch.relu((lengths[:, 1:] - lengths[:, :-1]).abs() / self.dt - self.max_speed)
        return (stroke**2 + speed**2).sum(-1)


__all__ = ["LegLimits", "actuator_positions", "leg_lengths", "rotation"]
