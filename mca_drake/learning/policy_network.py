"""The DPC motion-cueing policy network (paper eq. 11).

    [u_t, x_hat_(t+1)] = sat_lb^ub( f_pi(y_t, x_t, Y_t) )

    y_t       (B, 6)   the measured plant output (rad/s, m/s^2)
    x_t       (B, 12)  the measured state [q, qd] (rad, rad/s)
    Y_t       (B, 6)   the target output
    u_t       (B, 6)   joint accelerations (rad/s^2), within +-qdd_max
    x_hat     (B, 12)  the policy's prediction of the next state, within the state limits

f_pi is two bias-free linear layers of 128 with a GELU between; sat is the ReLU clamp
lb + relu(z - lb) - relu(z - ub) = min(max(z, lb), ub) with lb = [qdd-, q-, qd-] and
ub = [qdd+, q+, qd+] (Table I). One addition to the paper: the inputs are divided by fixed
scales (the joint limits for x, `OUTPUT_SCALE` for y and Y) so that every input is of order
one; the scales are constants of the network, exported with its weights (a file keeps its own:
the policy_v6 file carries `OUTPUT_SCALE_V6`).
"""

from __future__ import annotations

import json

import numpy as np
import torch
from torch import nn

from mca_drake.atomic_io import atomic_write_npz
from mca_drake.cueing.dpc import (
    OUTPUT_SIZE,
    POLICY_FORMAT,
    PREVIEW_POINTS,
    input_size,
    load_policy_arrays,
    policy_preview_steps,
)
from mca_drake.learning.blocks import Mlp
from mca_drake.learning.configs import OUTPUT_SCALE
from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform
from mca_drake.platforms.serial import NUM_JOINTS, SerialChain


def relu_clamp(z: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
    """The paper's ReLU-clamp saturation, lower + relu(z - lower) - relu(z - upper), computed
    as min(max(z, lower), upper): the same function and gradient, but exact in floating point
    (the ReLU form can overshoot a bound by a rounding error)."""
    return torch.minimum(torch.maximum(z, lower), upper)


class PolicyNetwork(nn.Module):
    """Bounded policy network; see the module docstring for shapes and units.

    Args:
        robot: the KR500 description (limits of the saturation, input scales).
        hidden: neurons of the hidden layer (paper: 128).
        output_scale: the scales of y and Y (6; default `OUTPUT_SCALE`).
        preview_steps: reference preview, control periods (0: causal); with one the network
            also reads the reference at `mca_drake.cueing.dpc.preview_offsets`.
    """

    def __init__(
        self,
        robot: SerialChain | None = None,
        hidden: int = 128,
        output_scale: tuple[float, ...] | np.ndarray = OUTPUT_SCALE,
        preview_steps: int = 0,
    ):
        super().__init__()
        robot = robot if robot is not None else load_platform(DEFAULT_PLATFORM)
        self.hidden = int(hidden)
        self.preview_steps = int(preview_steps)
        if self.preview_steps < 0:
            raise ValueError(f"preview_steps must be >= 0; got {preview_steps}")
        self.f_pi = Mlp(input_size(self.preview_steps), OUTPUT_SIZE, hidden)
        lower = np.concatenate([-robot.qdd_max, robot.q_min, -robot.qd_max])
        upper = np.concatenate([robot.qdd_max, robot.q_max, robot.qd_max])
        output_scale = np.asarray(output_scale, float)
        if output_scale.shape != (6,) or not np.all(output_scale > 0):
            raise ValueError(f"output_scale must be six positive values; got {output_scale}")
        input_scale = np.concatenate(
            [output_scale, np.maximum(-robot.q_min, robot.q_max), robot.qd_max, output_scale]
            + [output_scale] * (PREVIEW_POINTS if self.preview_steps else 0)
        )

        def buffer(name, value):
            self.register_buffer(name, torch.tensor(np.asarray(value), dtype=torch.float32))

        buffer("lower", lower)
        buffer("upper", upper)
        buffer("input_scale", input_scale)

    def forward(
        self,
        y: torch.Tensor,
        x: torch.Tensor,
        target: torch.Tensor,
        preview: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(u (B, 6), x_hat (B, 12)) for y (B, 6), x (B, 12), target (B, 6) and, with a
        preview, the reference at the preview offsets (B, 24)."""
        parts = [y, x, target] if preview is None else [y, x, target, preview]
        features = torch.cat(parts, dim=-1) / self.input_scale
        out = relu_clamp(self.f_pi(features), self.lower, self.upper)
        return out[..., :NUM_JOINTS], out[..., NUM_JOINTS:]

    def export(self) -> dict[str, np.ndarray]:
        """float64 numpy arrays for inference without torch: W1 (hidden, 24), W2 (18, hidden),
        input_scale (24), lower (18), upper (18)."""
        return {
            "W1": self.f_pi.net[0].weight.detach().cpu().double().numpy(),
            "W2": self.f_pi.net[2].weight.detach().cpu().double().numpy(),
            "input_scale": self.input_scale.cpu().double().numpy(),
            "lower": self.lower.cpu().double().numpy(),
            "upper": self.upper.cpu().double().numpy(),
        }


def save_policy(path, policy: PolicyNetwork, metadata: dict) -> None:
    """Writes the exported weights as .npz with JSON metadata inside, atomically (no pickle),
    in the format that `mca_drake.cueing.dpc.load_policy_arrays` reads.

    `metadata` should say how the policy was made (command, config, dataset, versions)."""
    meta = {
        **metadata,
        "format": POLICY_FORMAT,
        "hidden": policy.hidden,
        "preview_steps": policy.preview_steps,
    }
    atomic_write_npz(path, {"metadata_json": np.array(json.dumps(meta)), **policy.export()})


def load_policy_network(path, robot: SerialChain | None = None) -> PolicyNetwork:
    """A PolicyNetwork holding the weights and input scales of a policy file (for further
    training or torch inference). Raises ValueError if the file's bounds or joint scales are
    not this robot's limits."""
    arrays, metadata = load_policy_arrays(path)
    policy = PolicyNetwork(
        robot,
        hidden=arrays["W1"].shape[0],
        output_scale=arrays["input_scale"][:6],
        preview_steps=policy_preview_steps(metadata),
    )
    for name in ("lower", "upper", "input_scale"):
        if not np.allclose(arrays[name], getattr(policy, name).double().numpy(), atol=1e-6):
            raise ValueError(f"{path}: {name} of the policy does not match this robot's limits")
    with torch.no_grad():
        policy.f_pi.net[0].weight.copy_(torch.tensor(arrays["W1"]))
        policy.f_pi.net[2].weight.copy_(torch.tensor(arrays["W2"]))
    return policy
