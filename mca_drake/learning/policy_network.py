"""The DPC motion-cueing policy network (paper eq. 11).

    [u_t, x_hat_(t+1)] = sat_lb^ub( f_pi(y_t, x_t, Y_t) )

    y_t       (B, 6)   the measured plant output (rad/s, m/s^2)
    x_t       (B, 2n)  the measured state [q, qd] of the platform's n joints (rad or m, /s)
    Y_t       (B, 6)   the target output
    u_t       (B, n)   joint accelerations (rad/s^2 or m/s^2), within +-qdd_max
    x_hat     (B, 2n)  the policy's prediction of the next state, within the state limits

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
    POLICY_FORMAT,
    PREVIEW_POINTS,
    check_policy_platform,
    input_size,
    load_policy_arrays,
    output_size,
    policy_platform_record,
    policy_preview_steps,
)
from mca_drake.learning.blocks import Mlp
from mca_drake.learning.configs import OUTPUT_SCALE
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.kinematics import plant_output
from mca_drake.platforms.serial import SerialChain


def relu_clamp(z: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
    """The paper's ReLU-clamp saturation, lower + relu(z - lower) - relu(z - upper), computed
    as min(max(z, lower), upper): the same function and gradient, but exact in floating point
    (the ReLU form can overshoot a bound by a rounding error)."""
    return torch.minimum(torch.maximum(z, lower), upper)


class PolicyNetwork(nn.Module):
    """Bounded policy network; see the module docstring for shapes and units.

    Args:
        robot: the platform whose joints the policy commands (limits of the saturation,
            input scales).
        hidden: neurons of the hidden layer (paper: 128).
        output_scale: the scales of y and Y (6; default `OUTPUT_SCALE`).
        preview_steps: reference preview, control periods (0: causal); with one the network
            also reads the reference at `mca_drake.cueing.dpc.preview_offsets`.
    """

    def __init__(
        self,
        robot: SerialChain,
        hidden: int = 128,
        output_scale: tuple[float, ...] | np.ndarray = OUTPUT_SCALE,
        preview_steps: int = 0,
    ):
        super().__init__()
        self.joints = robot.num_joints
        self.hidden = int(hidden)
        self.preview_steps = int(preview_steps)
        if self.preview_steps < 0:
            raise ValueError(f"preview_steps must be >= 0; got {preview_steps}")
        self.f_pi = Mlp(
            input_size(self.preview_steps, self.joints), output_size(self.joints), hidden
        )
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
        """(u (B, n), x_hat (B, 2n)) for y (B, 6), x (B, 2n), target (B, 6) and, with a
        preview, the reference at the preview offsets (B, 24)."""
        parts = [y, x, target] if preview is None else [y, x, target, preview]
        features = torch.cat(parts, dim=-1) / self.input_scale
        out = relu_clamp(self.f_pi(features), self.lower, self.upper)
        return out[..., : self.joints], out[..., self.joints :]

    def export(self) -> dict[str, np.ndarray]:
        """float64 numpy arrays for inference without torch (n joints, without a preview):
        W1 (hidden, 12 + 2n), W2 (3n, hidden), input_scale (12 + 2n), lower (3n), upper (3n)."""
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


def load_policy_network(path, robot: SerialChain) -> PolicyNetwork:
    """A PolicyNetwork holding the weights and input scales of a policy file (for further
    training or torch inference). Raises ValueError, naming both, if the file was trained
    for another platform, or if its bounds or joint scales are not this robot's limits."""
    arrays, metadata = load_policy_arrays(path)
    check_policy_platform(path, metadata, robot.name)
    policy = PolicyNetwork(
        robot,
        hidden=arrays["W1"].shape[0],
        output_scale=arrays["input_scale"][:6],
        preview_steps=policy_preview_steps(metadata),
    )
    for name in ("lower", "upper", "input_scale"):
        if getattr(policy, name).shape != arrays[name].shape or not np.allclose(
            arrays[name], getattr(policy, name).double().numpy(), atol=1e-6
        ):
            raise ValueError(f"{path}: {name} of the policy does not match this robot's limits")
    with torch.no_grad():
        policy.f_pi.net[0].weight.copy_(torch.tensor(arrays["W1"]))
        policy.f_pi.net[2].weight.copy_(torch.tensor(arrays["W2"]))
    return policy


def with_preview(policy: PolicyNetwork, robot: SerialChain, preview_steps: int) -> PolicyNetwork:
    """A network reading a reference preview of `preview_steps` periods that acts exactly
    as the causal `policy` (for `robot`'s platform) does: its weights, with zero weights on
    the preview's inputs, so that fine-tuning starts from what the causal policy does and
    learns what the preview adds."""
    if policy.preview_steps:
        raise ValueError(f"the policy reads a preview of {policy.preview_steps} steps already")
    if preview_steps < 1:
        raise ValueError(f"preview_steps must be at least 1; got {preview_steps}")
    wider = PolicyNetwork(
        robot,
        hidden=policy.hidden,
        output_scale=policy.input_scale[:6].double().numpy(),
        preview_steps=preview_steps,
    )
    with torch.no_grad():
        first = wider.f_pi.net[0].weight
        first.zero_()
        first[:, : policy.f_pi.net[0].weight.shape[1]] = policy.f_pi.net[0].weight
        wider.f_pi.net[2].weight.copy_(policy.f_pi.net[2].weight)
    return wider


def policy_joint_names(metadata: dict) -> tuple[str, ...]:
    """The joint names, base to tip, of the platform a policy file was trained for: its
    platform record's `joints`, or, for a record without them, those of the packaged
    platform it names (KeyError-free: ValueError if that platform is not packaged)."""
    record = policy_platform_record(metadata)
    if "joints" in record:
        return tuple(str(name) for name in record["joints"])
    return load_platform(record["name"]).joint_names


def joint_directions(source: SerialChain, robot: SerialChain) -> np.ndarray:
    """Per joint of `source`, +1 where `robot`'s joint of the same name moves the cabin the
    same way at home and -1 where it moves it the other way (makers turn their axes either
    way: the FANUC M-900iB/700's joints 3 to 6 against the KR500's), shape (m,): the sign of
    the dot product of the two joints' columns of the output's acceleration Jacobian at home
    (`platforms.kinematics.plant_output` of a unit acceleration)."""
    signs = np.ones(source.num_joints)
    for k, name in enumerate(source.joint_names):
        j = robot.joint_names.index(name)
        theirs = plant_output(
            source.home, np.zeros(source.num_joints), np.eye(source.num_joints)[k], source
        )
        ours = plant_output(
            robot.home, np.zeros(robot.num_joints), np.eye(robot.num_joints)[j], robot
        )
        signs[k] = -1.0 if float(theirs @ ours) < 0 else 1.0
    return signs


def transfer_policy_network(path, robot: SerialChain) -> PolicyNetwork:
    """A PolicyNetwork for `robot` started from the policy file at `path`, trained for a
    platform whose joints `robot` has too, by name (the KR500's policy for the KR500 on a
    rail, or for another maker's six-axis robot with the same joint names): each shared
    joint keeps its weights (its position and velocity inputs, its acceleration and
    predicted-state outputs), turned round where the joint moves the cabin the other way
    (`joint_directions`); a joint the file lacks starts with zero weights, so the network
    commands it nothing and ignores it, and with `robot` at rest in that joint the
    transferred policy is the file's. A warm start for training, not a policy to run.

    Raises:
        ValueError: `robot` lacks a joint of the file's platform, or the file's platform is
            not a packaged one (its kinematics are needed); the file is not a policy file.
    """
    arrays, metadata = load_policy_arrays(path)
    source = policy_joint_names(metadata)
    if len(source) != arrays["W2"].shape[0] // 3:
        raise ValueError(
            f"{path}: its platform names {len(source)} joints, its arrays fit another count"
        )
    missing = [name for name in source if name not in robot.joint_names]
    if missing:
        raise ValueError(
            f"policy {path} commands joints {missing} that platform '{robot.name}' does not "
            f"have (its joints: {', '.join(robot.joint_names)})"
        )
    policy = PolicyNetwork(
        robot,
        hidden=arrays["W1"].shape[0],
        output_scale=arrays["input_scale"][:6],
        preview_steps=policy_preview_steps(metadata),
    )
    m, n = len(source), robot.num_joints
    at = [robot.joint_names.index(name) for name in source]
    signs = joint_directions(load_platform(policy_platform_record(metadata)["name"]), robot)
    # rows of the outputs [u, q_hat, qd_hat] and columns of the inputs [y, q, qd, target, ...]
    rows = np.concatenate([np.asarray(at) + k * n for k in range(3)])
    columns = np.concatenate([np.arange(6), 6 + np.asarray(at), 6 + n + np.asarray(at)])
    old_rest = np.arange(6 + 2 * m, arrays["W1"].shape[1])  # target and preview inputs
    new_rest = np.arange(6 + 2 * n, 6 + 2 * n + old_rest.size)
    W1 = np.zeros((policy.hidden, 6 + 2 * n + old_rest.size))
    W1[:, np.concatenate([columns, new_rest])] = arrays["W1"]
    W2 = np.zeros((3 * n, policy.hidden))
    W2[rows] = arrays["W2"] * np.tile(signs, 3)[:, None]
    # a joint turned round reads its position and velocity with the other sign
    W1[:, columns[6:]] *= np.tile(signs, 2)
    # the file's weights act on its own input scales: rescale where the scales differ
    old_scale = arrays["input_scale"]
    new_scale = policy.input_scale.double().numpy()
    W1[:, np.concatenate([columns, new_rest])] *= (
        new_scale[np.concatenate([columns, new_rest])] / old_scale
    )
    with torch.no_grad():
        policy.f_pi.net[0].weight.copy_(torch.tensor(W1))
        policy.f_pi.net[2].weight.copy_(torch.tensor(W2))
    return policy
