"""The DPC policy's target high-pass (`TargetHighPass`, `highpass_targets`,
`DpcTrainingConfig.target_highpass_s`): the filter against scipy's, the policy file, the
Drake system and the training objective."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from pydrake.systems.analysis import Simulator
from scipy.signal import lfilter

from mca_drake.atomic_io import load_npz_with_metadata
from mca_drake.cueing.dpc import HIGHPASS_ARRAY, TargetHighPass, load_policy_arrays
from mca_drake.learning.dpc import (
    DpcTrainingConfig,
    RolloutPlant,
    closed_loop_rollout,
    dpc_loss_terms,
    dpc_objective,
    highpass_targets,
)
from mca_drake.learning.policy import PolicyNetwork, load_policy_network, save_policy
from mca_drake.safety import ViabilityClamp
from mca_drake.systems.dpc_policy import DpcPolicy

H = 0.01
PITCH_ONLY = (0.0, 5.0, 0.0, 0.0, 0.0, 0.0)


def _scipy_highpass(signal: np.ndarray, tau: float) -> np.ndarray:
    """The first-order high-pass f_n = a (f_(n-1) + x_n - x_(n-1)), f_0 = 0, along axis 0,
    as scipy's IIR filter (b = [a, -a], a = [1, -a]) of the signal less its first value."""
    a = tau / (tau + H)
    return lfilter([a, -a], [1.0, -a], signal - signal[:1], axis=0)


def _walks(seed: int, shape) -> np.ndarray:
    return 0.05 * np.cumsum(np.random.default_rng(seed).normal(size=shape), axis=-2)


def test_windows_are_filtered_as_scipys_first_order_highpass():
    """Each filtered channel of each window equals scipy's filter from the window's first
    step (tau 0.05 s, the smallest allowed, to 30 s over 1024 steps); the others pass
    bit for bit."""
    taus = (0.0, 5.0, 0.0, 0.05, 30.0, 0.0)
    targets = _walks(0, (3, 1024, 6))
    out = highpass_targets(torch.tensor(targets), taus, H).numpy()
    for k, tau in enumerate(taus):
        if tau == 0:
            np.testing.assert_array_equal(out[..., k], targets[..., k])
        else:
            expected = _scipy_highpass(np.moveaxis(targets[..., k], 1, 0), tau)
            np.testing.assert_allclose(out[..., k], expected.T, atol=1e-10)
    unfiltered = torch.tensor(targets)
    assert highpass_targets(unfiltered, (0.0,) * 6, H) is unfiltered


def test_a_held_target_fades_and_the_step_recursion_is_the_same_filter():
    """Closed form: a step of 0.1 held decays as 0.1 a^n (about e^-t/tau); the live step
    recursion over a sequence equals scipy's filter, and keeps 2 floats per filtered channel
    and a started flag."""
    highpass = TargetHighPass(PITCH_ONLY, H)
    assert highpass.channels == [1] and highpass.memory_size() == 3
    targets = np.zeros((1501, 6))
    targets[1:, 1] = 0.1
    seen = targets.copy()
    memory = np.zeros(highpass.memory_size())
    for row in seen:
        highpass.step(row, memory)
    a = 5.0 / (5.0 + H)
    np.testing.assert_allclose(seen[1:, 1], 0.1 * a ** np.arange(1, 1501), rtol=1e-12)
    assert seen[-1, 1] == pytest.approx(0.1 * np.exp(-15.0 / 5.0), rel=0.01)  # 15 s: e^-3
    walk = _walks(1, (400, 6))
    seen = walk.copy()
    memory = np.zeros(highpass.memory_size())
    for row in seen:
        highpass.step(row, memory)
    np.testing.assert_allclose(seen[:, 1], _scipy_highpass(walk[:, 1], 5.0), atol=1e-12)
    np.testing.assert_array_equal(seen[:, [0, 2, 3, 4, 5]], walk[:, [0, 2, 3, 4, 5]])


@pytest.mark.parametrize("taus", [(0.0,) * 5, (0.0, -1.0, 0, 0, 0, 0), (np.nan,) + (0.0,) * 5])
def test_bad_time_constants_are_refused(taus):
    with pytest.raises(ValueError, match="time constants"):
        TargetHighPass(taus, H)


def test_training_refuses_time_constants_too_short_for_the_vectorized_filter():
    with pytest.raises(ValueError, match=r"0\.05"):
        DpcTrainingConfig(target_highpass_s=(0.0, 0.01, 0, 0, 0, 0)).validate()
    DpcTrainingConfig(target_highpass_s=PITCH_ONLY).validate()


def test_a_highpass_policy_file_round_trips_and_older_files_have_none(tmp_path):
    """The time constants travel in the file and back into a network; a file without them
    (v11 and earlier) reads as all 0; a negative one is refused."""
    torch.manual_seed(0)
    policy = PolicyNetwork(target_highpass_s=PITCH_ONLY)
    save_policy(tmp_path / "p.npz", policy, {})
    arrays, _ = load_policy_arrays(tmp_path / "p.npz")
    np.testing.assert_array_equal(arrays[HIGHPASS_ARRAY], PITCH_ONLY)
    assert load_policy_network(tmp_path / "p.npz").target_highpass_s == PITCH_ONLY
    stored, meta = load_npz_with_metadata(tmp_path / "p.npz", "policy")
    for name, value in (("old", None), ("negative", np.array([0, -5.0, 0, 0, 0, 0]))):
        kept = {k: v for k, v in stored.items() if k != HIGHPASS_ARRAY}
        if value is not None:
            kept[HIGHPASS_ARRAY] = value
        np.savez(tmp_path / f"{name}.npz", metadata_json=np.array(json.dumps(meta)), **kept)
    np.testing.assert_array_equal(load_policy_arrays(tmp_path / "old.npz")[0][HIGHPASS_ARRAY], 0)
    with pytest.raises(ValueError, match="high-pass"):
        load_policy_arrays(tmp_path / "negative.npz")


def test_the_dpc_system_sees_the_reference_through_the_filter(tmp_path, robot, rng):
    """Over a sequence of updates with a changing reference, the system's command is the
    clamped torch network's on the reference with its pitch rate through scipy's filter;
    a policy without a high-pass declares no filter memory."""
    torch.manual_seed(3)
    policy = PolicyNetwork(target_highpass_s=(0.0, 0.5, 0.0, 0.0, 0.0, 0.0))
    save_policy(tmp_path / "p.npz", policy, {})
    system = DpcPolicy(tmp_path / "p.npz", robot)
    context = system.CreateDefaultContext()
    assert context.num_discrete_state_groups() == 3
    clamp = ViabilityClamp.for_robot(robot, H)
    x = np.concatenate([0.2 * rng.uniform(robot.q_min, robot.q_max), np.zeros(6)])
    y = rng.normal(size=6)
    references = _walks(4, (30, 6)) + 0.3
    filtered = references.copy()
    filtered[:, 1] = _scipy_highpass(references[:, 1], 0.5)
    assert np.abs(filtered[:, 1] - references[:, 1]).min() > 0.1  # the filter matters here
    system.GetInputPort("state").FixValue(context, x)
    system.GetInputPort("inertial_output").FixValue(context, y)
    simulator = Simulator(system, context)
    for n, reference in enumerate(references):
        system.GetInputPort("reference").FixValue(context, reference)
        simulator.AdvanceTo(H * n + 0.5 * H)  # runs the update at t = n h
        with torch.no_grad():
            u = policy(*(torch.tensor(v, dtype=torch.float32)[None] for v in (y, x, filtered[n])))
        expected, _ = clamp(x, u[0][0].double().numpy())
        command = system.GetOutputPort("joint_acceleration").Eval(context)
        np.testing.assert_allclose(command, expected, rtol=0, atol=1e-5)
    save_policy(tmp_path / "plain.npz", PolicyNetwork(), {})
    plain = DpcPolicy(tmp_path / "plain.npz", robot).CreateDefaultContext()
    assert plain.num_discrete_state_groups() == 2


def test_the_objective_feeds_the_policy_filtered_targets_and_scores_the_raw_ones():
    """With target_highpass_s the objective is the loss of the rollout on the filtered
    targets against the unfiltered ones; it differs from the unfiltered objective."""
    torch.manual_seed(7)
    T = 64
    batch = {
        "X": 0.3 * torch.randn(6, T, 12),
        "Y": torch.randn(6, T, 6),
        "R": torch.tensor(_walks(5, (6, T, 6)) + 0.5, dtype=torch.float32),
    }
    policy = PolicyNetwork().eval()
    off = dict(mirror_fraction=0.0, yaw_shift_fraction=0.0, time_stretch_fraction=0.0)
    taus = (0.0, 0.2, 0.0, 0.0, 0.0, 0.0)
    loss = {}
    for name, highpass in (("plain", (0.0,) * 6), ("filtered", taus)):
        config = DpcTrainingConfig(**off, target_highpass_s=highpass, compile=False)
        with torch.no_grad():
            loss[name] = float(dpc_objective(config, RolloutPlant(config))(policy, batch))
    config = DpcTrainingConfig(**off, compile=False)
    plant = RolloutPlant(config)
    seen = highpass_targets(batch["R"], taus, H)
    with torch.no_grad():
        rollout = closed_loop_rollout(policy, plant, batch["X"][:, 0], batch["Y"][:, 0], seen)
        terms = dpc_loss_terms(rollout, batch["R"], policy)
    weights = {
        "tracking": config.tracking_weight,
        "state_estimate": config.state_estimate_weight,
        "input": config.input_weight,
        "washout": config.washout_weight,
        "limits": config.limit_weight,
        "terminal_position": config.terminal_position_weight,
        "terminal_velocity": config.terminal_velocity_weight,
    }
    scale = config.terminal_weight_horizon / T
    expected = sum(
        weights[k] * (scale if k.startswith("terminal") else 1.0) * float(v)
        for k, v in terms.items()
    )
    assert loss["filtered"] == pytest.approx(expected, rel=1e-5)
    assert abs(loss["filtered"] - loss["plain"]) > 1e-4 * abs(loss["plain"])
