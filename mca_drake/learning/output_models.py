"""Output candidates (paper Section III-B): the plant output y from states and inputs.

Every model maps a state trajectory, its inputs and the output one period before it to the
outputs along it:

    forward(X (B, T, 12), U (B, T, 6), y_prev (B, 6)) -> Y (B, T, 6),  Y[:, t] ~ y(X[:, t], U[:, t])

with y = [w_x, w_y, w_z, f_x, f_y, a_z] in the head frame (rad/s, m/s^2; `mca_drake.conventions`).
(The paper writes y_(t+1) for the output produced while u_t acts; here it is Y[:, t].)
Only the latent model uses y_prev, recursively.

    nssm     eq. (5): y = f3(x) + f4(u)
    latent   eq. (7): y_t = f4(f3(y_(t-1), x_t, u_t)), latent size 12
    mixed    eq. (8): F = F(q) exact, dF = f3(g(qd), F), ddF = f4(g(qd), dF) + f5(g(u), F),
             g(v) = [sin v, cos v]; y from (F, dF, ddF) by the exact output equations
    exact    the exact analytical output (`mca_drake.learning.torch_plant.TorchPlant`)

`training_loss` is each model's own objective (equations 6-8): MSE on y for nssm and
latent, MSE on dF and ddF for mixed.
"""

from __future__ import annotations

import torch
from torch import nn

from mca_drake.conventions import CONTROL_PERIOD_S, GRAVITY
from mca_drake.learning.blocks import Mlp, pose_top, sin_cos_features
from mca_drake.learning.torch_plant import TorchPlant
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.serial import NUM_JOINTS

# The robot of the paper's plant models (Table II): the candidates are sized and their
# analytical parts built for its six joints.
PAPER_PLATFORM = "kr500"
STATE_SIZE, INPUT_SIZE, OUTPUT_SIZE = 2 * NUM_JOINTS, NUM_JOINTS, 6
POSE_SIZE = 12  # top 3x4 block of a pose matrix or its derivative


def _check(X: torch.Tensor, U: torch.Tensor, y_prev: torch.Tensor | None) -> None:
    if X.ndim != 3 or X.shape[-1] != STATE_SIZE:
        raise ValueError(f"X must have shape (B, T, {STATE_SIZE}); got {tuple(X.shape)}")
    if U.shape != (*X.shape[:2], INPUT_SIZE):
        raise ValueError(f"U must have shape {(*X.shape[:2], INPUT_SIZE)}; got {tuple(U.shape)}")
    if y_prev is not None and y_prev.shape != (X.shape[0], OUTPUT_SIZE):
        raise ValueError(
            f"y_prev must have shape {(X.shape[0], OUTPUT_SIZE)}; got {tuple(y_prev.shape)}"
        )


def output_from_pose_derivatives(F: torch.Tensor, dF: torch.Tensor, ddF: torch.Tensor):
    """y from the head pose F and its time derivatives (each (..., 4, 4)): (..., 6).

    R^T dR/dt = [omega_H]x gives the angular velocity in H; the translation part of ddF is
    the head acceleration a_W, so f = R^T (a_W - g_W) and a_z = (R^T a_W)_z.
    """
    R, R_dot, a_W = F[..., :3, :3], dF[..., :3, :3], ddF[..., :3, 3]
    S = R.transpose(-1, -2) @ R_dot
    omega = 0.5 * torch.stack(
        [S[..., 2, 1] - S[..., 1, 2], S[..., 0, 2] - S[..., 2, 0], S[..., 1, 0] - S[..., 0, 1]],
        dim=-1,
    )
    a_H = (R.transpose(-1, -2) @ a_W[..., None])[..., 0]
    # R^T (a_W - g_W) = a_H + g R^T e_z = a_H + g (third row of R)
    f_H = a_H + GRAVITY * R[..., 2, :]
    return torch.cat([omega, f_H[..., :2], a_H[..., 2:]], dim=-1)


class OutputModel(nn.Module):
    """Base class (see the module docstring for shapes)."""

    learnable = True

    def forward(self, X, U, y_prev=None):
        raise NotImplementedError

    def training_loss(self, X, U, y_prev, targets: dict[str, torch.Tensor]) -> torch.Tensor:
        """The model's objective on predicted states X (B, T, 12) and inputs U, against
        dataset targets (Y (B, T, 6) and, for mixed, dF, ddF (B, T, 4, 4))."""
        return torch.mean((self(X, U, y_prev) - targets["Y"]) ** 2)


class NssmOutput(OutputModel):
    """Equation (5): y = f3(x) + f4(u)."""

    def __init__(self, hidden: int = 64):
        super().__init__()
        self.f3 = Mlp(STATE_SIZE, OUTPUT_SIZE, hidden)
        self.f4 = Mlp(INPUT_SIZE, OUTPUT_SIZE, hidden)

    def forward(self, X, U, y_prev=None):
        _check(X, U, y_prev)
        return self.f3(X) + self.f4(U)


class LatentOutput(OutputModel):
    """Equation (7): encoder f3 (y_prev, x, u) -> latent (12), decoder f4 latent -> y."""

    def __init__(self, hidden: int = 64, latent_size: int = 12):
        super().__init__()
        self.f3 = Mlp(OUTPUT_SIZE + STATE_SIZE + INPUT_SIZE, latent_size, hidden)
        self.f4 = Mlp(latent_size, OUTPUT_SIZE, hidden)

    def forward(self, X, U, y_prev=None):
        _check(X, U, y_prev)
        if y_prev is None:
            raise ValueError("the latent output model needs y_prev, the output before X[:, 0]")
        # The state and input parts of the encoder's first layer do not depend on the
        # recursion: compute them for all steps at once, loop only over the y part.
        W = self.f3.net[0].weight  # (hidden, 6 + 12 + 6)
        W_y, W_xu = W[:, :OUTPUT_SIZE], W[:, OUTPUT_SIZE:]
        pre_xu = torch.cat([X, U], dim=-1) @ W_xu.T  # (B, T, hidden)
        act, out_layer, decoder = self.f3.net[1], self.f3.net[2], self.f4
        y, outputs = y_prev, []
        for t in range(X.shape[1]):
            latent = out_layer(act(pre_xu[:, t] + y @ W_y.T))
            y = decoder(latent)
            outputs.append(y)
        return torch.stack(outputs, dim=1)


class MixedAnalyticalOutput(OutputModel):
    """Equation (8): exact F(q); learned dF and ddF; exact y(F, dF, ddF)."""

    def __init__(
        self, hidden: int = 64, dt: float = CONTROL_PERIOD_S, dtype: torch.dtype = torch.float32
    ):
        super().__init__()
        # Pass dtype rather than converting later: a float32 module converted to float64
        # keeps its float32-rounded kinematic constants.
        self.kinematics = TorchPlant(load_platform(PAPER_PLATFORM), dt, dtype, check_inputs=False)
        self.f3 = Mlp(2 * NUM_JOINTS + POSE_SIZE, POSE_SIZE, hidden)
        self.f4 = Mlp(2 * NUM_JOINTS + POSE_SIZE, POSE_SIZE, hidden)
        self.f5 = Mlp(2 * NUM_JOINTS + POSE_SIZE, POSE_SIZE, hidden)
        self.to(dtype)

    def pose_derivatives(self, X, U) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """F exact, dF and ddF learned; each (B, T, 4, 4) (bottom rows: F's [0 0 0 1], 0)."""
        q, qd = X[..., :NUM_JOINTS], X[..., NUM_JOINTS:]
        F = self.kinematics.head_pose(q.to(self.kinematics.R_prev.dtype)).to(X.dtype)
        g_qd = sin_cos_features(qd)
        F_top = pose_top(F)
        dF_top = self.f3(torch.cat([g_qd, F_top], dim=-1))
        ddF_top = self.f4(torch.cat([g_qd, dF_top], dim=-1)) + self.f5(
            torch.cat([sin_cos_features(U), F_top], dim=-1)
        )

        def full(top: torch.Tensor) -> torch.Tensor:
            top = top.unflatten(-1, (3, 4))
            return torch.cat([top, torch.zeros_like(top[..., :1, :])], dim=-2)

        return F, full(dF_top), full(ddF_top)

    def forward(self, X, U, y_prev=None):
        _check(X, U, y_prev)
        return output_from_pose_derivatives(*self.pose_derivatives(X, U))

    def training_loss(self, X, U, y_prev, targets):
        """Mean squared error of the head pose's first and second derivatives."""
        _, dF, ddF = self.pose_derivatives(X, U)
        return torch.mean((pose_top(dF) - pose_top(targets["dF"])) ** 2) + torch.mean(
            (pose_top(ddF) - pose_top(targets["ddF"])) ** 2
        )


class ExactOutput(OutputModel):
    """The exact analytical output of equation (1) (no parameters)."""

    learnable = False

    def __init__(self, dt: float = CONTROL_PERIOD_S, dtype: torch.dtype = torch.float32):
        super().__init__()
        self.plant = TorchPlant(load_platform(PAPER_PLATFORM), dt, dtype, check_inputs=False)

    def forward(self, X, U, y_prev=None):
        _check(X, U, y_prev)
        dtype = self.plant.R_prev.dtype
        return self.plant.output(X.to(dtype), U.to(dtype)).to(X.dtype)


OUTPUT_MODELS: dict[str, type[OutputModel]] = {
    "nssm": NssmOutput,
    "latent": LatentOutput,
    "mixed": MixedAnalyticalOutput,
    "exact": ExactOutput,
}
