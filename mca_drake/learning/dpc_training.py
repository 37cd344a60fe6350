"""Differentiable predictive control training of the motion-cueing policy (paper eq. 9).

Closed-loop rollouts of n_c steps: from a dataset segment's first state x_0 and output y_0,
the policy and a frozen plant run in a cycle,

    u_t, x_hat_(t+1) = policy(y_t, x_t, Y_t)
    y_(t+1) = output(x_t, u_t)           (the output while u_t acts; tracked against Y_t)
    x_(t+1) = step(x_t, u_t)

and the loss per step is, summed over vector components and averaged over steps and
segments (the NMPC's cost terms, `mca_drake.cueing.nmpc`, and w_1 on the base joint alone,
`base_washout_weight`, default 0):

    w_y ||y_(t+1) - Y_t||^2 + w_x ||x_hat_(t+1) - x_(t+1)||^2 + 0.1 ||u_t||^2 + ||q_t||^2
      + w_1 q_(1,t)^2 + w_b ||violation of the state limits by x_(t+1)||^2

plus, beyond the paper, the NMPC's terminal cost ||q_n||^2 + ||qd_n||^2 on the last state
(without it a policy trained on 2.56 s rollouts drifts to the limits within seconds of a
long flight), its weights scaled by the NMPC's horizon / n_c (`terminal_weight_horizon`),
and the rollout runs behind the viability clamp the deployed policy runs behind
(`safety_filter`), so that training and deployment see the same closed loop. On a legged
platform (a hexapod, a small rig) the limit term also holds its legs' stroke and speed
(`learning.legs.LegLimits`; the deployed clamp holds them exactly). Half of each
training batch flies its window's mirror image (`mirror_fraction`), half starts with the base
joint turned (`yaw_shift_fraction`) and half tracks its window slowed down
(`time_stretch_fraction`), each drawn independently. Optionally the loss adds the PI's
correlation part, sum_k (1 - CC_k) over the batch's rollouts (`correlation_weight`), and the
training windows are joined by copies that start where the initial policy's own closed loop
was at their start instead of where the NMPC was (`own_start_fraction`).

The weights default to the shipped NMPC's (`NmpcConfig`'s tuned defaults, carried over by
`DpcTrainingConfig.matching`): the policy learns the objective the tuned NMPC minimises,
tracking the references the NMPC was given (`targets="reference"`); `DpcTrainingConfig.paper()`
gives the paper's loss (uniform tracking of the NMPC-achieved outputs, input 0.1, washout
1). The plant is the exact analytical torch plant by default, or the paper's learned NODE 2 +
mixed analytical model (`plant="learned"`, weights from a Table II run).
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from mca_drake.atomic_io import check_writable, file_sha256
from mca_drake.conventions import CONTROL_PERIOD_S, MIRROR_CHANNEL_SIGNS
from mca_drake.cueing.dpc import (
    UNNAMED_POLICY_PLATFORM,
    load_policy_arrays,
    policy_platform,
    preview_offsets,
)
from mca_drake.cueing.reference_range import (
    ReferenceRange,
    policy_reference_range,
    reference_range,
)
from mca_drake.learning.checkpoint import CheckpointError, load_checkpoint, load_state_into
from mca_drake.learning.configs import DpcTrainingConfig
from mca_drake.learning.forecast_previews import FORECAST_PREVIEW_ARRAY, forecast_preview_array
from mca_drake.learning.legs import LegLimits
from mca_drake.learning.output_models import PAPER_PLATFORM, MixedAnalyticalOutput
from mca_drake.learning.perception import TorchVestibularFilter
from mca_drake.learning.policy_network import (
    PolicyNetwork,
    load_policy_network,
    save_policy,
    transfer_policy_network,
    with_preview,
)
from mca_drake.learning.state_models import Node2State
from mca_drake.learning.torch_plant import TorchPlant, viable_acceleration_bounds_torch
from mca_drake.learning.trainer import CurriculumTrainer
from mca_drake.metrics import STILL_TOLERANCE
from mca_drake.perception.models import PerceptionConfig
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.leg_platform import LegPlatform
from mca_drake.platforms.serial import SerialChain
from mca_drake.segments import (
    SOURCE_COLUMNS,
    SegmentDataset,
    consecutive_runs,
    dataset_platform,
    long_windows,
    package_versions,
    split_of,
)


class RolloutPlant(nn.Module):
    """The frozen plant of the DPC rollouts: step(x, u) -> x_next, output(x, u) -> y, and
    the safety filter `clamp(x, u)` of the deployed robot (identity if switched off)."""

    def __init__(self, config: DpcTrainingConfig, robot: SerialChain):
        super().__init__()
        self.robot = robot
        self.kind = config.plant
        self.safety_filter = config.safety_filter
        self.bound_gradients = config.bound_gradients
        self.dt = CONTROL_PERIOD_S
        for name in ("q_min", "q_max", "qd_max", "qdd_max"):
            self.register_buffer(
                name, torch.tensor(getattr(robot, name), dtype=torch.float32), persistent=False
            )
        if config.plant == "exact":
            self.exact = TorchPlant(robot, check_inputs=False)
        elif robot.name != PAPER_PLATFORM:
            raise ValueError(
                f"the learned plant models the {PAPER_PLATFORM} (the paper's Table II); "
                f"train for platform '{robot.name}' on the exact plant (plant='exact')"
            )
        else:
            self.state_model = Node2State()
            self.output_model = MixedAnalyticalOutput()
            state = torch.load(config.learned_output_weights, map_location="cpu", weights_only=True)
            load_state_into(self.output_model, state, config.learned_output_weights)
        # a legged platform's legs: their stroke and speed join the loss's limit term (the
        # deployed viability clamp holds them exactly; the box clamp here is the joints')
        self.legs = LegLimits(robot, self.dt) if isinstance(robot, LegPlatform) else None
        for p in self.parameters():
            p.requires_grad_(False)

    def clamp(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """The viability clamp of ``u`` (B, n) [rad/s^2, m/s^2] at state ``x`` (B, 2n), if
        enabled."""
        if not self.safety_filter:
            return u
        lo, hi = viable_acceleration_bounds_torch(
            x, self.q_min, self.q_max, self.qd_max, self.qdd_max, self.dt
        )
        if not self.bound_gradients:
            lo, hi = lo.detach(), hi.detach()
        return torch.minimum(torch.maximum(u, lo), hi)

    def step(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Next state (B, 2n) after one time step of ``u`` (B, n) from ``x`` (B, 2n)."""
        if self.kind == "exact":
            return self.exact.step(x, u)
        return self.state_model.step(x, u)

    def output(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Inertial output (B, 6) [m/s^2, rad/s] while ``u`` (B, n) acts at ``x`` (B, 2n)."""
        if self.kind == "exact":
            return self.exact.output(x, u)
        return self.output_model(x[:, None], u[:, None])[:, 0]


@dataclasses.dataclass
class Rollout:
    """A closed-loop rollout for n joints: U (B, T, n), X (B, T + 1, 2n), X_hat (B, T, 2n)
    predicting X[:, 1:], Y (B, T, 6) the outputs while U acts."""

    U: torch.Tensor
    X: torch.Tensor
    X_hat: torch.Tensor
    Y: torch.Tensor


def rollout_cell(policy: PolicyNetwork, plant: RolloutPlant):
    """One closed-loop step (y_t, x_t, Y_t, preview_t) -> (u_t, x_hat, y_(t+1), x_(t+1));
    preview_t is None for a causal policy."""

    def cell(y, x, target, preview=None):
        u, x_hat = policy(y, x, target, preview)
        u = plant.clamp(x, u)
        return u, x_hat, plant.output(x, u), plant.step(x, u)

    return cell


def closed_loop_rollout(
    policy: PolicyNetwork,
    plant: RolloutPlant,
    x0: torch.Tensor,
    y0: torch.Tensor,
    targets: torch.Tensor,
    cell=None,
    previews: torch.Tensor | None = None,
) -> Rollout:
    """Runs policy and plant in a cycle over targets (B, T, 6) from x0 (B, 2n), y0 (B, 6).

    `cell` may be a compiled `rollout_cell(policy, plant)`. A policy with a preview reads
    `previews` (B, T, 6 PREVIEW_POINTS; a forecast's, `learning.forecast_previews`) or, where
    None, the targets ahead (`rollout_previews`)."""
    cell = cell or rollout_cell(policy, plant)
    x, y = x0, y0
    U, X, X_hat, Y = [], [x0], [], []
    if previews is None or not policy.preview_steps:
        previews = rollout_previews(targets, policy.preview_steps)
    for t in range(targets.shape[1]):
        preview = None if previews is None else previews[:, t]
        u, x_hat, y, x = cell(y, x, targets[:, t], preview)
        U.append(u)
        X_hat.append(x_hat)
        Y.append(y)
        X.append(x)
    stack = lambda seq: torch.stack(seq, dim=1)  # noqa: E731
    return Rollout(stack(U), stack(X), stack(X_hat), stack(Y))


def rollout_previews(targets: torch.Tensor, preview_steps: int) -> torch.Tensor | None:
    """What a policy with a preview of `preview_steps` periods reads at each step of a
    rollout over `targets` (B, T, 6): the targets at `preview_offsets` ahead, the last held
    beyond the window, shape (B, T, 6 PREVIEW_POINTS); None for a causal policy."""
    if not preview_steps:
        return None
    T = targets.shape[1]
    ahead = torch.arange(T)[:, None] + torch.as_tensor(preview_offsets(preview_steps))[None, :]
    rows = torch.clamp(ahead, max=T - 1).to(targets.device)  # (T, points)
    return targets[:, rows].reshape(targets.shape[0], T, -1)


def pooled_correlation(outputs: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """Per channel, the Pearson correlation (C,) of outputs with targets, both (B, T, C):
    each window centred on its own mean over T, then the B windows pooled as one signal (a
    window counts by its targets' spread, as the parts of a flight do in its CC). A channel
    whose targets are still in every window scores 1 (nothing to correlate with; the
    tracking term keeps it still); an output still where its target moves scores 0 (its
    gradient stays finite: the output's variance is floored at STILL_TOLERANCE^2 of the
    target's)."""
    out = outputs - outputs.mean(dim=1, keepdim=True)
    tar = targets - targets.mean(dim=1, keepdim=True)
    covariance = (out * tar).sum(dim=(0, 1))
    out_var, tar_var = (out * out).sum(dim=(0, 1)), (tar * tar).sum(dim=(0, 1))
    cc = covariance / torch.sqrt(out_var * tar_var + (STILL_TOLERANCE * tar_var) ** 2)
    # still as the PI's CC takes it: spread within STILL_TOLERANCE (its square per sample)
    still = tar_var <= STILL_TOLERANCE**2 * tar.shape[0] * tar.shape[1]
    return torch.where(still, torch.ones_like(cc), cc)


def dpc_loss_terms(
    rollout: Rollout,
    targets: torch.Tensor,
    policy: PolicyNetwork,
    channel_weights: torch.Tensor | None = None,
    correlation: bool | torch.Tensor = False,
    perception: TorchVestibularFilter | None = None,
    legs: LegLimits | None = None,
    postures: torch.Tensor | None = None,
) -> dict[str, torch.Tensor]:
    """The loss terms (unweighted), each averaged over segments and steps; the tracking
    term's channels weighted by `channel_weights` if given (6, or per window (B, 1, 6) or
    (B, 1, 1)); with `perception`, the tracking term compares what the occupant perceives
    (the vestibular model of y - Y over the rollout, from rest); with `correlation` (True, or
    six channel weights c_k), also sum_k c_k (1 - CC_k) of `pooled_correlation` (0 to 12 with
    c_k = 1); with `legs` (a legged platform's),
    the limit term adds the legs' squared excess beyond their stroke and speed; with
    `postures` (B, T, n: the dataset MCA's joint positions at the same steps), also the
    posture term, the squared distance of joints 2..n from them (rad^2)."""
    X_next = rollout.X[:, 1:]
    n = policy.joints
    lower, upper = policy.lower[n:], policy.upper[n:]
    violation = torch.relu(X_next - upper) + torch.relu(lower - X_next)
    error = rollout.Y - targets
    if perception is not None:
        error = perception(error)
    squared_error = error**2
    if channel_weights is not None:
        squared_error = squared_error * channel_weights
    squared_angles = rollout.X[:, :-1, :n] ** 2  # the states the steps act from
    terms = {
        "tracking": squared_error.sum(-1).mean(),
        "state_estimate": ((rollout.X_hat - X_next) ** 2).sum(-1).mean(),
        "input": (rollout.U**2).sum(-1).mean(),
        "washout": squared_angles.sum(-1).mean(),
        "base_washout": squared_angles[..., 0].mean(),
        "limits": (violation**2).sum(-1).mean()
        + (0.0 if legs is None else legs.excess(rollout.X).mean()),
        "terminal_position": (rollout.X[:, -1, :n] ** 2).sum(-1).mean(),
        "terminal_velocity": (rollout.X[:, -1, n:] ** 2).sum(-1).mean(),
    }
    if postures is not None:
        away = rollout.X[:, :-1, 1:n] - postures[..., 1:n]
        terms["posture"] = (away**2).sum(-1).mean()
    if isinstance(correlation, torch.Tensor) or correlation:
        misses = 1.0 - pooled_correlation(rollout.Y, targets)
        if isinstance(correlation, torch.Tensor):
            misses = misses * correlation
        terms["correlation"] = misses.sum()
    return terms


def perturb_initial_states(x0: torch.Tensor, policy: PolicyNetwork, config: DpcTrainingConfig):
    """x0 (B, 2n) with the positions of a random `perturbed_fraction` of its rows moved by
    uniform noise (see DpcTrainingConfig), clipped to 90 % of the limits (torch's global
    generator)."""
    n = policy.joints
    lower, upper = policy.lower[n:], policy.upper[n:]
    half_range = 0.5 * (upper - lower)
    half_range[n:] = 0.0  # positions only
    noise = (2 * torch.rand_like(x0) - 1) * config.initial_state_noise * half_range
    chosen = (torch.rand(x0.shape[0], 1, device=x0.device) < config.perturbed_fraction).to(x0)
    return torch.clamp(x0 + chosen * noise, 0.9 * lower, 0.9 * upper)


def mirror_signs(
    robot: SerialChain, dtype: torch.dtype = torch.float32, device: torch.device | str = "cpu"
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The mirror image's signs of a command u (n), a state x = [q, qd] (2n) and an output y
    (6): the platform's `mirror_joint_signs` on joints, `conventions.MIRROR_CHANNEL_SIGNS` on
    outputs.

    Raises:
        ValueError: the platform has no mirror symmetry."""
    if robot.mirror_joint_signs.size == 0:
        raise ValueError(
            f"platform '{robot.name}' gives no mirror_joint_signs: train with "
            "mirror_fraction 0 (--mirror-fraction 0)"
        )
    joints = torch.tensor(robot.mirror_joint_signs, dtype=dtype, device=device)
    channels = torch.tensor(MIRROR_CHANNEL_SIGNS, dtype=dtype, device=device)
    return joints, torch.cat((joints, joints)), channels


def mirror_some_windows(
    x0: torch.Tensor,
    y0: torch.Tensor,
    targets: torch.Tensor,
    fraction: float,
    robot: SerialChain,
    previews: torch.Tensor | None = None,
    postures: torch.Tensor | None = None,
):
    """(x0 (B, 2n), y0 (B, 6), targets (B, T, 6)) with a random `fraction` of the windows
    replaced by their mirror images (torch's global generator; see `mirror_fraction`);
    given forecast `previews` (B, T, 6 P), also those, mirrored channel by channel with
    their windows, as a further element; given the dataset MCA's joint positions
    `postures` (B, T, n; `MCA_POSTURE`), those mirrored joint by joint as the last one."""
    chosen = torch.rand(x0.shape[0], 1, device=x0.device) < fraction
    joint_signs, state_signs, channel_signs = mirror_signs(robot, x0.dtype, x0.device)
    x_signs = torch.where(chosen, state_signs, torch.ones_like(state_signs))
    y_signs = torch.where(chosen, channel_signs, torch.ones_like(channel_signs))
    mirrored = x0 * x_signs, y0 * y_signs, targets * y_signs[:, None]
    if previews is not None:
        points = previews.shape[-1] // y_signs.shape[-1]
        mirrored = (*mirrored, previews * y_signs.repeat(1, points)[:, None])
    if postures is not None:
        q_signs = torch.where(chosen, joint_signs, torch.ones_like(joint_signs))
        mirrored = (*mirrored, postures * q_signs[:, None])
    return mirrored


def _symmetry_error(plant: RolloutPlant, map_x, map_u, map_y, samples: int = 64) -> float:
    """Largest error of plant.output / plant.step under the state, command and output maps
    (x -> map_x(x), u -> map_u(u), y -> map_y(y)) on random states and commands."""
    generator = torch.Generator().manual_seed(0)
    n = plant.robot.num_joints
    x = 0.5 * torch.randn(samples, 2 * n, generator=generator)
    u = torch.randn(samples, n, generator=generator)
    with torch.no_grad():
        output_error = plant.output(map_x(x), map_u(u)) - map_y(plant.output(x, u))
        step_error = plant.step(map_x(x), map_u(u)) - map_x(plant.step(x, u))
    return max(float(output_error.abs().max()), float(step_error.abs().max()))


def check_mirror_symmetry(plant: RolloutPlant) -> None:
    """Raises ValueError unless the rollout plant is left-right symmetric, as mirrored
    training windows assume: outputs and steps of mirrored random states and commands are the
    mirrored outputs and steps (a robot description with a lateral offset is not)."""
    u_signs, x_signs, y_signs = mirror_signs(plant.robot)
    worst = _symmetry_error(
        plant, lambda x: x * x_signs, lambda u: u * u_signs, lambda y: y * y_signs
    )
    if not worst <= 1e-4:
        raise ValueError(
            f"mirror_fraction > 0 needs a left-right symmetric plant; mirrored states are off "
            f"by up to {worst:.3g} (a robot with a lateral offset, or a learned plant): train "
            f"with mirror_fraction 0 (--mirror-fraction 0)"
        )


def shift_base_yaw(
    x0: torch.Tensor, fraction: float, q_min: torch.Tensor, q_max: torch.Tensor
) -> torch.Tensor:
    """x0 (B, 2n) with the first joint's position (the KR500's base yaw, rad; the rail's
    carriage, m) of a random `fraction` of the rows replaced by a uniform random position
    within 90 % of its range [q_min[0], q_max[0]] about the range's centre (torch's global
    generator; see `yaw_shift_fraction`)."""
    chosen = torch.rand(x0.shape[0], device=x0.device) < fraction
    centre, half_range = (q_max[0] + q_min[0]) / 2, (q_max[0] - q_min[0]) / 2
    angle = centre + 0.9 * half_range * (2 * torch.rand(x0.shape[0], device=x0.device) - 1)
    shifted = x0.clone()
    shifted[:, 0] = torch.where(chosen, angle.to(x0), x0[:, 0])
    return shifted


def stretch_some_targets(targets: torch.Tensor, fraction: float, max_factor: float) -> torch.Tensor:
    """targets (B, T, C) with a random `fraction` of the windows slowed down by a uniform
    random factor k in [1, max_factor]: row b becomes r_b(t / k), linearly interpolated
    between the window's samples (torch's global generator; see `time_stretch_fraction`)."""
    B, T, C = targets.shape
    chosen = torch.rand(B, device=targets.device) < fraction
    factor = 1 + (max_factor - 1) * torch.rand(B, device=targets.device)
    factor = torch.where(chosen, factor, torch.ones_like(factor)).to(targets)
    # fractional sample index of r(t / k) for each row and step (at most T - 1)
    position = torch.arange(T, device=targets.device, dtype=targets.dtype) / factor[:, None]
    below = position.floor().long()
    above = (below + 1).clamp(max=T - 1)
    index = torch.cat((below, above), dim=1)[..., None].expand(-1, -1, C)
    low, high = torch.gather(targets, 1, index).split(T, dim=1)
    weight = (position - below.to(targets))[..., None]
    # (1 - w) a + w b rather than torch.lerp: the default policy was trained with this
    # rounding, so that its command reproduces it
    return (1 - weight) * low + weight * high


def check_base_yaw_invariance(plant: RolloutPlant) -> None:
    """Raises ValueError unless the rollout plant's outputs and motion are independent of
    the first joint's position (the KR500's base yaw, a rail's carriage), as shifted
    training starts assume (a learned plant, or a robot whose first joint tilts the cabin,
    need not be)."""
    turn = torch.zeros(2 * plant.robot.num_joints)
    turn[0] = 1.3
    worst = _symmetry_error(plant, lambda x: x + turn, lambda u: u, lambda y: y)
    if not worst <= 1e-4:
        raise ValueError(
            f"yaw_shift_fraction > 0 needs a plant that does not depend on joint 1's position; "
            f"turned states are off by up to {worst:.3g}: train with --yaw-shift-fraction 0"
        )


def _learned_range(config: DpcTrainingConfig, dataset, train_targets) -> ReferenceRange:
    """The range of the references a policy trained now has learned: its training split's
    targets, and what its initial policy had learned where that records it (the hull)."""
    own = reference_range(
        [np.asarray(train_targets).reshape(-1, 6)],
        mirrored=config.mirror_fraction > 0,
        source=f"the training split of {dataset}",
    )
    if not config.initial_policy:
        return own
    initial = policy_reference_range(
        config.initial_policy, load_policy_arrays(config.initial_policy)[1]
    )
    if initial is None:
        return own
    return ReferenceRange(
        tuple(np.minimum(own.low, initial.low).tolist()),
        tuple(np.maximum(own.high, initial.high).tolist()),
        f"{own.source}, and its initial policy's: {initial.source}",
    )


def target_array(config: DpcTrainingConfig) -> str:
    """The dataset array the policy tracks: "Y" (NMPC-achieved outputs) or "R" (references)."""
    return "Y" if config.targets == "achieved" else "R"


def tracking_channel_weights(config: DpcTrainingConfig, targets) -> torch.Tensor | None:
    """The tracking term's channel weights (6) of `config` for training targets (..., 6)
    (None for uniform weights). "normalized": mean variance / channel variance."""
    weights = config.tracking_channel_weights
    if weights == "uniform":
        return None
    if weights == "normalized":
        variance = torch.as_tensor(targets, dtype=torch.float64).reshape(-1, 6).var(0)
        return (variance.mean() / torch.clamp(variance, min=1e-12)).float()
    return torch.tensor(weights, dtype=torch.float32)


# The dataset array of the recorded MCA's squared tracking errors (`recorded_squared_errors`),
# carried into every window as the other arrays are.
RECORDED_ERRORS = "E"
# The dataset MCA's joint positions at each step (J, n_p, n), the posture term's pull
# (`DpcTrainingConfig.posture_weight`); windows started from the policy's own states keep
# the MCA's.
MCA_POSTURE = "P"


def recorded_squared_errors(data: SegmentDataset, key: str) -> np.ndarray:
    """(J, n_p, 5) float64: the squared errors of the dataset's own MCA (its recorded outputs
    Y against the targets `key`) on w_x..f_y, step by step (a_z left out: its sustained
    part no MCA renders)."""
    return (np.asarray(data.arrays["Y"][..., :5], np.float64) - data.arrays[key][..., :5]) ** 2


def achievable_cost_weights(parts: dict[str, SegmentDataset], channel_weights, floor: float):
    """Adds "S" (J, n, 1) to each split of `parts`: each window's tracking weight
    1 / (L + floor), normalised to mean 1 over parts["train"].

    L is what the dataset's own MCA paid for tracking over the window: the mean over its
    steps of sum_k c_k e_k^2, e the recorded errors each window carries (`RECORDED_ERRORS`,
    from `recorded_squared_errors`), c the tracking channel weights (None: 1). A window the
    recorded MCA renders almost exactly then counts as much as one whose errors nobody
    avoids. Windows started from the policy's own states (`add_own_start_windows`) carry
    the recorded errors of the same segments.

    Raises:
        ValueError: if floor is not > 0 or a split lacks the recorded errors.
    """
    if not (math.isfinite(floor) and floor > 0):
        raise ValueError(f"the achievable cost floor must be a finite number > 0; got {floor}")
    if any(RECORDED_ERRORS not in part.arrays for part in parts.values()):
        raise ValueError("the windows lack the recorded errors (recorded_squared_errors)")
    c = np.ones(6) if channel_weights is None else np.asarray(channel_weights, dtype=np.float64)
    inverse = {
        name: 1.0 / ((part.arrays[RECORDED_ERRORS].mean(1) * c[:5]).sum(-1) + floor)
        for name, part in parts.items()
    }
    mean = inverse["train"].mean()
    for name, part in parts.items():
        weight = (inverse[name] / mean).astype(np.float32)
        part.arrays["S"] = np.repeat(weight[:, None, None], part.horizon, axis=1)


def dpc_objective(
    config: DpcTrainingConfig, plant: RolloutPlant, channel_weights: torch.Tensor | None = None
):
    """objective(policy, batch) for `CurriculumTrainer`: the weighted DPC loss of the
    closed-loop rollout from each segment's first state over its targets, with the
    tracking term's channels weighted by `channel_weights` (6; None: uniform) and, where the
    batch holds "S" (`achievable_cost_weights`), each window by its weight."""
    weights = {
        "tracking": config.tracking_weight,
        "state_estimate": config.state_estimate_weight,
        "input": config.input_weight,
        "washout": config.washout_weight,
        "base_washout": config.base_washout_weight,
        "limits": config.limit_weight,
        "terminal_position": config.terminal_position_weight,
        "terminal_velocity": config.terminal_velocity_weight,
        "correlation": config.correlation_weight,
        "posture": config.posture_weight,
    }
    key = target_array(config)
    correlation_weights = torch.tensor(config.correlation_channel_weights)
    cells = {}
    perception = None
    if config.tracking_signals == "perceived":
        model = PerceptionConfig(model=config.perception_model)
        perception = TorchVestibularFilter(model, CONTROL_PERIOD_S)

    def objective(policy: PolicyNetwork, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        if id(policy) not in cells:
            cell = rollout_cell(policy, plant)
            cells[id(policy)] = torch.compile(cell) if config.compile else cell
        targets, x0, y0 = batch[key], batch["X"][:, 0], batch["Y"][:, 0]
        previews = batch.get(FORECAST_PREVIEW_ARRAY)  # a forecast preview's, where trained on
        postures = None
        if config.posture_weight > 0:
            if MCA_POSTURE not in batch:
                raise ValueError(
                    f"posture_weight > 0 needs the dataset MCA's joint positions in each "
                    f"batch ('{MCA_POSTURE}', as train_policy adds them)"
                )
            postures = batch[MCA_POSTURE]
        if policy.training and config.mirror_fraction > 0:
            x0, y0, targets, *extras = mirror_some_windows(
                x0, y0, targets, config.mirror_fraction, plant.robot, previews, postures
            )
            previews = extras.pop(0) if previews is not None else None
            postures = extras.pop(0) if postures is not None else None
        if policy.training and config.yaw_shift_fraction > 0:
            x0 = shift_base_yaw(x0, config.yaw_shift_fraction, plant.q_min, plant.q_max)
        if policy.training and config.time_stretch_fraction > 0:
            if postures is None:
                targets = stretch_some_targets(
                    targets, config.time_stretch_fraction, config.time_stretch_max
                )
            else:  # the MCA's posture slowed down with its window's targets
                both = stretch_some_targets(
                    torch.cat((targets, postures), dim=-1),
                    config.time_stretch_fraction,
                    config.time_stretch_max,
                )
                targets, postures = both.split((targets.shape[-1], postures.shape[-1]), -1)
        if policy.training and config.perturbed_fraction > 0:
            x0 = perturb_initial_states(x0, policy, config)
        rollout = closed_loop_rollout(policy, plant, x0, y0, targets, cells[id(policy)], previews)
        weights_here = None if channel_weights is None else channel_weights.to(targets)
        if "S" in batch:  # the windows' achievable-cost weights, (B, 1, 1)
            window = batch["S"][:, :1]
            weights_here = window if weights_here is None else weights_here * window
        terms = dpc_loss_terms(
            rollout,
            targets,
            policy,
            weights_here,
            correlation=(
                correlation_weights.to(targets) if config.correlation_weight > 0 else False
            ),
            perception=perception,
            legs=plant.legs,
            postures=postures,
        )
        if config.terminal_weight_horizon > 0:
            scale = config.terminal_weight_horizon / targets.shape[1]
            terms["terminal_position"] = scale * terms["terminal_position"]
            terms["terminal_velocity"] = scale * terms["terminal_velocity"]
        return sum(weights[k] * v for k, v in terms.items())

    return objective


def flights_of_vehicles(data: SegmentDataset, vehicles, name="the dataset") -> SegmentDataset:
    """The segments of `data` from flights of `vehicles`, by its metadata's
    `flight_vehicles` ({flight seed: vehicle}, as `mca-drake dataset closed-loop` and
    `dataset join` write it).

    Raises:
        ValueError: the dataset does not say which vehicle flew each flight, or has no
            flight of `vehicles` (the message lists the vehicles it has).
    """
    flown = data.metadata.get("flight_vehicles")
    if not isinstance(flown, dict):
        raise ValueError(f"{name} does not record its flights' vehicles (flight_vehicles)")
    seeds = data.source[:, SOURCE_COLUMNS.index("flight_seed")]
    keep = np.array([flown.get(str(seed)) in vehicles for seed in seeds], dtype=bool)
    if not keep.any():
        raise ValueError(
            f"{name} has no flight of {', '.join(vehicles)}; its vehicles: "
            f"{', '.join(sorted(set(flown.values())))}"
        )
    return data.subset(keep)


def own_closed_loop_states(
    policy: PolicyNetwork, plant: RolloutPlant, data: SegmentDataset, key: str = "R", cell=None
) -> dict[str, np.ndarray]:
    """Where `policy` takes the robot on the flights of `data`: {"X": (N, n_p, 12),
    "Y": (N, n_p, 6)}, aligned with the segments of `data` as its own X and Y are.

    Each run of consecutive segments of a flight (`consecutive_runs`) is flown in one closed
    loop over its targets `key`, from the first segment's state and output, behind the
    plant's clamp; a gap in a flight starts a new run from the state after it. All runs fly
    in one batch (shorter ones hold their last target beyond their end; those steps are
    dropped). `cell` may be a compiled `rollout_cell(policy, plant)`. Where `data` holds
    forecast previews (`FORECAST_PREVIEW_ARRAY`), a preview policy reads those.
    """
    n_p = data.horizon
    runs = consecutive_runs(data)
    longest = max(len(run) for run in runs) * n_p
    targets = np.empty((len(runs), longest, 6), dtype=np.float32)
    forecasts = data.arrays.get(FORECAST_PREVIEW_ARRAY)
    previews = None
    if forecasts is not None:
        previews = np.empty((len(runs), longest, forecasts.shape[-1]), dtype=np.float32)
    for i, run in enumerate(runs):
        joined = data.arrays[key][run].reshape(-1, 6)
        targets[i, : len(joined)] = joined
        targets[i, len(joined) :] = joined[-1]
        if previews is not None:
            ahead = forecasts[run].reshape(len(joined), -1)
            previews[i, : len(joined)] = ahead
            previews[i, len(joined) :] = ahead[-1]
    first = np.array([run[0] for run in runs])
    as_tensor = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)  # noqa: E731
    was_training = policy.training
    policy.eval()
    with torch.no_grad():
        rollout = closed_loop_rollout(
            policy,
            plant,
            as_tensor(data.arrays["X"][first, 0]),
            as_tensor(data.arrays["Y"][first, 0]),
            as_tensor(targets),
            cell,
            None if previews is None else as_tensor(previews),
        )
    policy.train(was_training)
    states, outputs = rollout.X[:, :-1].numpy(), rollout.Y.numpy()
    X = np.empty_like(data.arrays["X"])
    Y = np.empty_like(data.arrays["Y"])
    for i, run in enumerate(runs):
        X[run] = states[i, : len(run) * n_p].reshape(len(run), n_p, -1)
        Y[run] = outputs[i, : len(run) * n_p].reshape(len(run), n_p, -1)
    return {"X": X, "Y": Y}


def with_own_starts(
    windows: SegmentDataset, own_windows: SegmentDataset, fraction: float, seed: int
) -> SegmentDataset:
    """`windows` plus a random `fraction` of `own_windows` (the same flights' windows with
    the policy's own states and outputs, `own_closed_loop_states`), drawn with `seed`."""
    count = round(fraction * len(own_windows))
    if count == 0:
        return windows
    chosen = np.sort(np.random.default_rng(seed).choice(len(own_windows), count, replace=False))
    return SegmentDataset.concatenate([windows, own_windows.subset(chosen)], windows.metadata)


def add_own_start_windows(
    config: DpcTrainingConfig,
    policy: PolicyNetwork,
    plant: RolloutPlant,
    data: SegmentDataset,
    train: SegmentDataset,
) -> SegmentDataset:
    """The training windows `train` plus `config.own_start_fraction` of all the training
    windows of `data`'s flights started from `policy`'s own closed loop
    (`own_closed_loop_states`), whether or not the NMPC started them near neutral: the
    policy's own state there is what it must come back from."""
    cell = rollout_cell(policy, plant)
    cell = torch.compile(cell) if config.compile else cell
    own = own_closed_loop_states(policy, plant, data, target_array(config), cell)
    own_data = SegmentDataset({**data.arrays, **own}, data.source, data.metadata)
    own_splits = (
        long_windows(own_data, config.window_segments)
        if config.window_segments > 1
        else split_of(own_data)
    )
    return with_own_starts(train, own_splits["train"], config.own_start_fraction, config.seed)


def near_neutral_windows(
    windows: SegmentDataset, max_position_rad: float, revolute: np.ndarray
) -> SegmentDataset:
    """The windows whose first positions of the revolute joints (`revolute`, bool (n,))
    are all within `max_position_rad` of neutral (rad): a cabin tilted far out starts
    them; a prismatic joint (a rail's carriage) away from its centre does not tilt it."""
    joints = np.flatnonzero(revolute)
    start = np.abs(windows.arrays["X"][:, 0, joints]).max(axis=1, initial=0.0)
    keep = start <= max_position_rad
    return SegmentDataset(
        {k: v[keep] for k, v in windows.arrays.items()}, windows.source[keep], windows.metadata
    )


def train_policy(
    config: DpcTrainingConfig,
    dataset: str | Path,
    out_dir: str | Path,
    *,
    resume: bool = False,
    progress: bool = True,
    command: str = "",
) -> tuple[PolicyNetwork, Path]:
    """Trains a policy on a closed-loop dataset and writes it to out_dir/policy.npz.

    The checkpoint (out_dir/policy.pt with its .json, loss log and curve) makes the run
    resumable. Returns the policy with the best validation weights and the policy file.
    """

    config.validate()
    robot = load_platform(config.platform)
    out = check_writable(out_dir, folder=True)
    data = SegmentDataset.load(dataset)
    check_dataset_platform(data, robot, dataset)
    if "R" not in data.arrays and config.targets == "reference":
        raise ValueError(f"{dataset} has no references R; use targets='achieved'")
    if config.vehicles:
        data = flights_of_vehicles(data, config.vehicles, dataset)
    if config.achievable_cost_floor > 0:
        data.arrays[RECORDED_ERRORS] = recorded_squared_errors(data, target_array(config))
    if config.posture_weight > 0:
        data.arrays[MCA_POSTURE] = data.arrays["X"][..., : robot.num_joints].copy()
    if config.preview_predictor:  # what the policy will read live, once for every segment
        data.arrays[FORECAST_PREVIEW_ARRAY] = forecast_preview_array(
            data, target_array(config), config.preview_predictor, config.preview_steps
        )
    if config.window_segments > 1:
        splits = long_windows(data, config.window_segments)
    else:
        splits = split_of(data)
    if math.isfinite(config.max_start_position_rad):
        splits = {
            name: near_neutral_windows(part, config.max_start_position_rad, ~robot.prismatic)
            for name, part in splits.items()
        }
    for name in ("train", "validation"):
        if len(splits[name]) == 0:
            raise ValueError(
                f"no {name} windows in {dataset} start within max_start_position_rad = "
                f"{config.max_start_position_rad} rad of neutral"
            )
    torch.manual_seed(config.seed)
    if config.initial_policy:
        policy = initial_policy_network(config.initial_policy, robot)
        if not policy.preview_steps and config.preview_steps:
            policy = with_preview(policy, robot, config.preview_steps)
        if (policy.hidden, policy.preview_steps) != (config.hidden, config.preview_steps):
            raise ValueError(
                f"initial_policy {config.initial_policy} has {policy.hidden} hidden neurons "
                f"and a preview of {policy.preview_steps} steps, the config {config.hidden} "
                f"and {config.preview_steps}"
            )
    else:
        policy = PolicyNetwork(
            robot,
            hidden=config.hidden,
            output_scale=config.output_scale,
            preview_steps=config.preview_steps,
        )
    plant = RolloutPlant(config, robot)
    if config.mirror_fraction > 0:
        check_mirror_symmetry(plant)
    if config.yaw_shift_fraction > 0:
        check_base_yaw_invariance(plant)
    own_states_wall_s = 0.0
    if config.own_start_fraction > 0:
        start = time.perf_counter()
        splits["train"] = add_own_start_windows(config, policy, plant, data, splits["train"])
        own_states_wall_s = time.perf_counter() - start
    # The rollouts run where the trainer puts the policy and the data (CUDA or CPU).
    plant = plant.to(config.train.resolved_device())
    train_targets = splits["train"].arrays[target_array(config)]
    channel_weights = tracking_channel_weights(config, train_targets)
    metadata = {
        "model": "dpc-policy",
        "model_kwargs": {"hidden": config.hidden, "preview_steps": config.preview_steps},
        "dataset": str(dataset),
        "dpc_config": json.loads(json.dumps(dataclasses.asdict(config))),
        "tracking_channel_weights": None if channel_weights is None else channel_weights.tolist(),
        # the platform whose joints the policy commands (`cueing.dpc.check_policy_platform`)
        "platform": plant.robot.summary(),
        # the targets it learned on, for the run summaries' out-of-distribution share
        "reference_range": _learned_range(config, dataset, train_targets).record(),
    }
    names = ("X", "Y", "U") + (("R",) if config.targets == "reference" else ())
    if config.preview_predictor:
        names += (FORECAST_PREVIEW_ARRAY,)
    if config.achievable_cost_floor > 0:
        achievable_cost_weights(splits, channel_weights, config.achievable_cost_floor)
        names += ("S",)
    if config.posture_weight > 0:
        names += (MCA_POSTURE,)
    trainer = CurriculumTrainer(
        policy,
        dpc_objective(config, plant, channel_weights),
        config.train,
        out / "policy.pt",
        metadata,
        arrays=names,
    )
    result = trainer.fit(splits["train"], splits["validation"], resume=resume, progress=progress)
    path = out / "policy.npz"
    provenance = initial_policy_provenance(config.initial_policy)
    save_policy(
        path,
        policy,
        {
            **metadata,
            "command": command,
            "stages": [dataclasses.asdict(s) for s in result.stages],
            # the trainer's and, with own starts, the own closed loops' (`own_states_wall_s`)
            "training_wall_s": result.wall_s + own_states_wall_s,
            "own_states_wall_s": own_states_wall_s,
            # this run plus every run the starting weights came from
            "training_wall_s_total": result.wall_s
            + own_states_wall_s
            + provenance.get("training_wall_s_total", 0.0),
            "initial_policy_provenance": provenance,
            "versions": package_versions(),
        },
    )
    return policy, path


def check_dataset_platform(data: SegmentDataset, robot: SerialChain, path) -> None:
    """Raises ValueError, naming both, unless the dataset at `path` was made on `robot`'s
    platform (its metadata's `platform`; a dataset that names none was made on
    `segments.UNNAMED_DATASET_PLATFORM`, the KR500) with its joint count."""
    made_on = dataset_platform(data.metadata)
    if made_on != robot.name:
        raise ValueError(
            f"dataset {path} was made on platform '{made_on}', not on '{robot.name}': make "
            f"one with `mca-drake dataset closed-loop --platform {robot.name}`"
        )
    n = robot.num_joints
    if data.arrays["U"].shape[-1] != n or data.arrays["X"].shape[-1] != 2 * n:
        raise ValueError(
            f"dataset {path} holds U {data.arrays['U'].shape} and X {data.arrays['X'].shape}, "
            f"not the {n} joints of platform '{robot.name}'"
        )


def initial_policy_network(path: str, robot: SerialChain) -> PolicyNetwork:
    """The network a training run starts from: the policy file at `path` as it is, when it
    was trained for `robot`'s platform, else transferred to `robot`'s joints by name
    (`transfer_policy_network`)."""
    _, metadata = load_policy_arrays(path)
    if policy_platform(metadata) == robot.name:
        return load_policy_network(path, robot)
    return transfer_policy_network(path, robot)


def initial_policy_provenance(path: str) -> dict:
    """Where a fine-tuned policy's starting weights came from: the file's SHA-256, its
    command, and its training wall time including its own starting weights' ({} for "")."""
    if not path:
        return {}
    _, meta = load_policy_arrays(path)
    return {
        "path": str(path),
        "sha256": file_sha256(path),
        "command": meta.get("command", ""),
        "training_wall_s": meta.get("training_wall_s"),
        "training_wall_s_total": meta.get(
            "training_wall_s_total", meta.get("training_wall_s", 0.0)
        ),
        "previous": meta.get("initial_policy_provenance", {}),
    }


def export_checkpoint_policy(checkpoint: str | Path, out: str | Path) -> Path:
    """Writes the best weights so far of a DPC training checkpoint (policy.pt) as a policy
    file, e.g. to evaluate a run that is still going or was stopped."""
    payload, meta = load_checkpoint(checkpoint)
    if meta.get("model") != "dpc-policy":
        raise ValueError(f"{checkpoint} is not a DPC policy checkpoint (model {meta.get('model')})")
    kwargs = meta.get("model_kwargs", {})
    platform = meta.get("dpc_config", {}).get("platform", UNNAMED_POLICY_PLATFORM)
    policy = PolicyNetwork(
        load_platform(platform),
        hidden=kwargs.get("hidden", 128),
        preview_steps=kwargs.get("preview_steps", 0),
    )
    if "best_model" not in payload:
        raise CheckpointError(f"{checkpoint} holds no best weights (best_model) to export")
    load_state_into(policy, payload["best_model"], str(checkpoint))
    epochs = meta.get("epochs_logged", 0)
    save_policy(out, policy, {**meta, "exported_from": str(checkpoint), "epochs": epochs})
    return Path(out)
