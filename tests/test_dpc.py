"""DPC policy: bounds, numpy inference equal to torch, the safety filter, the Drake system,
and training that beats doing nothing."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from dataset_helpers import rest_segments
from hypothesis import given, settings
from hypothesis import strategies as st
from loss_helpers import loss_weights_only
from pydrake.systems.analysis import Simulator

from mca_drake.cueing.dpc import DpcConfig, PolicyInference, default_policy_path, policy_platform
from mca_drake.learning.dpc_training import (
    DpcTrainingConfig,
    RolloutPlant,
    closed_loop_rollout,
    train_policy,
)
from mca_drake.learning.policy_network import (
    PolicyNetwork,
    load_policy_arrays,
    load_policy_network,
    save_policy,
)
from mca_drake.learning.trainer import TrainConfig
from mca_drake.platforms.files import load_platform
from mca_drake.safety import ViabilityClamp, is_stoppable
from mca_drake.segments import SegmentDataset
from mca_drake.systems.dpc import DpcPolicy

KR500 = load_platform("kr500")


def _random_policy(seed: int, gain: float = 3.0) -> PolicyNetwork:
    torch.manual_seed(seed)
    policy = PolicyNetwork(KR500)
    with torch.no_grad():
        for p in policy.parameters():
            p.mul_(gain)  # large weights: outputs reach the saturation often
    return policy


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 1000), scale=st.floats(0.1, 1e3))
def test_policy_output_is_always_inside_bounds(seed, scale, robot):
    policy = _random_policy(seed)
    g = torch.Generator().manual_seed(seed)
    y, x, r = (scale * torch.randn(64, n, generator=g) for n in (6, 12, 6))
    u, x_hat = policy(y, x, r)
    lower, upper = policy.lower, policy.upper
    assert torch.all(u >= lower[:6]) and torch.all(u <= upper[:6])
    assert torch.all(x_hat >= lower[6:]) and torch.all(x_hat <= upper[6:])
    assert torch.all(upper[:6] == torch.tensor(robot.qdd_max, dtype=torch.float32))


def test_a_policy_file_keeps_its_own_input_scales(tmp_path, rng):
    """The output scales at the network's input are constants of each file: v6's file loads
    with v6's (0.5 rad/s) into a network that computes what its numpy inference computes,
    a new network gets `OUTPUT_SCALE` (0.1 rad/s), and a bad scale is refused."""
    from mca_drake.cueing.dpc import shipped_policy_path
    from mca_drake.learning.configs import OUTPUT_SCALE, OUTPUT_SCALE_V6

    v6_path = shipped_policy_path("policy_v6")
    v6 = load_policy_network(v6_path, KR500).double()
    np.testing.assert_allclose(v6.export()["input_scale"][:6], OUTPUT_SCALE_V6)
    inference = PolicyInference(load_policy_arrays(v6_path)[0])
    y, x, r = rng.normal(size=6) * 0.3, rng.normal(size=12) * 0.3, rng.normal(size=6) * 0.3
    u_torch, _ = v6(*(torch.tensor(v)[None] for v in (y, x, r)))
    np.testing.assert_allclose(inference(y, x, r)[0], u_torch[0].detach().numpy(), atol=1e-9)
    fresh = PolicyNetwork(KR500)
    np.testing.assert_allclose(fresh.export()["input_scale"][18:], OUTPUT_SCALE, rtol=1e-6)
    save_policy(tmp_path / "fresh.npz", fresh, {"model": "dpc-policy"})
    again = load_policy_network(tmp_path / "fresh.npz", KR500)
    np.testing.assert_allclose(again.export()["input_scale"], fresh.export()["input_scale"])
    with pytest.raises(ValueError, match="output_scale"):
        PolicyNetwork(KR500, output_scale=(0.1, 0.1, 0.0, 2.0, 2.0, 2.0))
    with pytest.raises(ValueError, match="output_scale"):
        DpcTrainingConfig(output_scale=(1.0,) * 5).validate()


def test_numpy_inference_equals_torch(rng):
    policy = _random_policy(1, gain=2.0).double()
    inference = PolicyInference(policy.export())
    for _ in range(200):
        y, x, r = rng.normal(size=6) * 3, rng.normal(size=12), rng.normal(size=6) * 3
        u_t, xh_t = policy(*(torch.tensor(v)[None] for v in (y, x, r)))
        u, xh = inference(y, x, r)
        np.testing.assert_allclose(u, u_t[0].detach().numpy(), rtol=0, atol=1e-6)
        np.testing.assert_allclose(xh, xh_t[0].detach().numpy(), rtol=0, atol=1e-6)
        command = inference.command(y, x, r)  # the live loop's u alone, in floats
        assert all(type(v) is float for v in command)
        np.testing.assert_allclose(command, u, rtol=0, atol=1e-12)


def test_the_command_alone_is_nan_for_any_non_finite_input(rng):
    """`command` bounds u like the full inference, so it must not let the bounds turn a
    non-finite input into a finite command: any NaN or inf among the 24 inputs gives NaN."""
    inference = PolicyInference(_random_policy(3).double().export())
    for position in range(24):
        for bad in (np.nan, np.inf, -np.inf):
            v = rng.normal(size=24)
            v[position] = bad
            assert np.all(np.isnan(inference.command(v[:6], v[6:18], v[18:])))


def test_policy_file_round_trip_and_bad_files(tmp_path, rng):
    policy = _random_policy(2)
    path = tmp_path / "p.npz"
    save_policy(path, policy, {"command": "test"})
    arrays, meta = load_policy_arrays(path)
    assert meta["command"] == "test" and arrays["W1"].shape == (128, 24)
    back = load_policy_network(path, KR500)
    y, x, r = (torch.randn(5, n) for n in (6, 12, 6))
    torch.testing.assert_close(back(y, x, r)[0], policy(y, x, r)[0])
    bad = dict(arrays)
    bad["W2"] = bad["W2"][:, :10]
    np.savez(
        tmp_path / "bad.npz", metadata_json=np.array('{"format": "mca-drake-policy-1"}'), **bad
    )
    with pytest.raises(ValueError, match="W2 has shape"):
        load_policy_arrays(tmp_path / "bad.npz")
    np.savez(
        tmp_path / "newer.npz",
        metadata_json=np.array('{"format": "mca-drake-policy-1"}'),
        target_highpass_s=np.ones(6),
        **arrays,
    )
    with pytest.raises(ValueError, match="target_highpass_s"):
        load_policy_arrays(tmp_path / "newer.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(ValueError, match="not a policy file"):
        load_policy_arrays(tmp_path / "junk.npz")
    with pytest.raises(FileNotFoundError):
        DpcPolicy(tmp_path / "missing.npz", load_platform("kr500"))


def _simulate_with_clamp(robot, x0, commands, h=0.01):
    """Exact zero-order-hold steps of the commands after the clamp; returns states."""
    clamp = ViabilityClamp.for_robot(robot, h)
    x, states, count = x0.copy(), [x0.copy()], 0
    for k in range(commands.shape[0]):
        u = commands[k](x) if callable(commands[k]) else commands[k]
        u, hit = clamp(x, u)
        count += hit
        q, qd = x[:6], x[6:]
        x = np.concatenate([q + h * qd + 0.5 * h * h * u, qd + h * u])
        states.append(x.copy())
    return np.array(states), count


@pytest.mark.parametrize("kind", ["random", "bang-bang", "push-to-limit", "nan"])
def test_safety_filter_keeps_the_plant_inside_its_limits(kind, robot, rng):
    n = 1500
    lim = robot.qdd_max
    for _ in range(4):
        q0 = rng.uniform(0.8 * robot.q_min, 0.8 * robot.q_max)
        x0 = np.concatenate([q0, np.zeros(6)])
        if kind == "random":
            commands = rng.uniform(-5 * lim, 5 * lim, size=(n, 6))
        elif kind == "bang-bang":
            signs = np.sign(np.sin(np.arange(n)[:, None] * rng.uniform(0.001, 0.05, 6)))
            commands = 10 * lim * signs
        elif kind == "push-to-limit":
            # adversarial: always accelerate towards the nearer limit as hard as possible
            side = np.where(rng.random(6) < 0.5, -1.0, 1.0)
            commands = np.tile(side * 100 * lim, (n, 1))
        else:
            commands = np.full((n, 6), np.nan)
        X, count = _simulate_with_clamp(robot, x0, commands)
        tol = 1e-9
        assert np.all(X[:, :6] <= robot.q_max + tol) and np.all(X[:, :6] >= robot.q_min - tol)
        assert np.all(np.abs(X[:, 6:]) <= robot.qd_max + tol)
        assert np.all(is_stoppable(X[:, :6], X[:, 6:], robot.q_min, robot.q_max, robot.qdd_max))
        assert count > 0


def test_dpc_policy_system_matches_torch_and_clamps(tmp_path, robot, rng):
    policy = _random_policy(4)
    path = tmp_path / "p.npz"
    save_policy(path, policy, {})
    system = DpcPolicy(path, robot)
    context = system.CreateDefaultContext()
    clamp = ViabilityClamp.for_robot(robot, 0.01)
    for _ in range(20):
        q = rng.uniform(robot.q_min, robot.q_max)
        qd = rng.uniform(-robot.qd_max, robot.qd_max)
        x, y, r = np.concatenate([q, qd]), rng.normal(size=6), rng.normal(size=6)
        system.GetInputPort("state").FixValue(context, x)
        system.GetInputPort("inertial_output").FixValue(context, y)
        system.GetInputPort("reference").FixValue(context, r)
        context.SetTime(0.0)
        Simulator(system, context).AdvanceTo(0.005)  # runs the update at t = 0
        command = system.GetOutputPort("joint_acceleration").Eval(context)
        with torch.no_grad():
            u = policy(*(torch.tensor(v, dtype=torch.float32)[None] for v in (y, x, r)))[0]
        expected, _ = clamp(x, u[0].double().numpy())
        np.testing.assert_allclose(command, expected, rtol=0, atol=1e-5)


@pytest.mark.parametrize("update_event", ["unrestricted", "discrete"])
def test_dpc_policy_system_counts_the_clamps_interventions(tmp_path, robot, rng, update_event):
    """The statistics' intervention count goes on from the value each update finds: over
    five updates near joint 2's upper limit it equals the clamp's hits counted by hand on the
    torch network's commands, in either update phase."""
    policy = _random_policy(6, gain=1.0)
    path = tmp_path / "p.npz"
    save_policy(path, policy, {})
    system = DpcPolicy(path, robot, update_event=update_event)
    context = system.CreateDefaultContext()
    clamp = ViabilityClamp.for_robot(robot, 0.01)
    x = np.concatenate([0.3 * rng.uniform(robot.q_min, robot.q_max), np.zeros(6)])
    x[1], x[7] = robot.q_max[1] - 0.01, 0.5 * robot.qd_max[1]  # moving up to the limit
    simulator = Simulator(system, context)
    hits = 0
    for k in range(5):
        y, r = 2.0 * rng.normal(size=6), 2.0 * rng.normal(size=6)
        for port, value in (("state", x), ("inertial_output", y), ("reference", r)):
            system.GetInputPort(port).FixValue(context, value)
        simulator.AdvanceTo(0.01 * k + 0.005)  # runs the update at t = 0.01 k
        with torch.no_grad():
            u = policy(*(torch.tensor(v, dtype=torch.float32)[None] for v in (y, x, r)))[0]
        expected, hit = clamp(x, u[0].double().numpy())
        command = system.GetOutputPort("joint_acceleration").Eval(context)
        np.testing.assert_allclose(command, expected, rtol=0, atol=1e-4)
        hits += hit
    assert system.statistics(context)["safety_interventions"] == hits > 0


def test_dpc_policy_system_rejects_non_finite_state_and_bridges_a_dropped_imu(tmp_path, robot):
    """NaN or inf in the state or reference stops the simulation with the time; a
    non-finite measured output is replaced by zeros (state and target still drive it)."""
    path = tmp_path / "p.npz"
    save_policy(path, _random_policy(2), {})
    system = DpcPolicy(path, robot)

    def command(x, y, r):
        context = system.CreateDefaultContext()
        for name, value in (("state", x), ("inertial_output", y), ("reference", r)):
            system.GetInputPort(name).FixValue(context, value)
        Simulator(system, context).AdvanceTo(0.005)
        return system.GetOutputPort("joint_acceleration").Eval(context)

    x, y, r = np.full(12, 0.01), np.full(6, 0.2), np.full(6, 0.3)
    for bad in (np.nan, np.inf, -np.inf):
        for which in ("x", "r"):
            xb, rb = x.copy(), r.copy()
            (xb if which == "x" else rb)[3] = bad
            with pytest.raises(RuntimeError, match="non-finite state or reference at t = 0"):
                command(xb, y, rb)
    dropped = y.copy()
    dropped[1] = np.nan
    np.testing.assert_array_equal(command(x, dropped, r), command(x, np.zeros(6), r))
    # huge but finite values are not mistaken for non-finite ones (their sum overflows)
    huge = np.full(6, 1e308)
    with np.errstate(over="ignore", invalid="ignore"):  # the network overflows; the clamp brakes
        assert np.all(np.isfinite(command(x, huge, r)))


# ----------------------------------------------------------------- training
AMPLITUDE = np.array([0.05, 0.08, 0.08, 0.0, 0.1, 0.0])  # rad
OMEGA = 2 * np.pi * 0.4  # rad/s


def _sine_motion(t):
    """A smooth joint motion about the neutral pose and its plant output (all channels vary):
    an achievable target. Returns x (T, 12), y (T, 6)."""
    from mca_drake.platforms.kinematics import plant_output

    s, c = np.sin(OMEGA * t)[:, None], np.cos(OMEGA * t)[:, None]
    q, qd, qdd = AMPLITUDE * s, AMPLITUDE * OMEGA * c, -AMPLITUDE * OMEGA**2 * s
    return np.concatenate([q, qd], 1), plant_output(q, qd, qdd, load_platform("kr500"))


def _sine_target_dataset(n_segments=48, horizon=32, seed=0) -> SegmentDataset:
    """Segments starting at rest at the neutral pose, targets: the sine motion's outputs
    from a random phase on."""
    rng = np.random.default_rng(seed)
    R = np.stack(
        [_sine_motion(rng.uniform(0, 3) + 0.01 * np.arange(horizon))[1] for _ in range(n_segments)]
    )
    return rest_segments(R)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dpc")
    path = _sine_target_dataset().save(folder / "data.npz")
    # The paper's weights (washout 1): with the tuned objective's weak washout (0.04) a
    # policy stays near neutral only when trained over horizons of seconds, not 0.32 s.
    config = DpcTrainingConfig.paper(
        targets="reference",
        compile=False,
        window_segments=1,
        train=TrainConfig(
            learning_rate=1e-2, batch_size=16, max_epochs=20, horizons=(32,), device="cpu"
        ),
    )
    policy, policy_path = train_policy(config, path, folder, progress=False)
    history = (folder / "policy_loss.csv").read_text().splitlines()[1:]
    return policy, policy_path, history


def test_short_training_lowers_the_loss(trained):
    _, _, history = trained
    val = [float(line.split(",")[4]) for line in history]
    assert min(val[-5:]) < 0.7 * val[0], (val[0], val[-5:])


def test_trained_policy_tracks_better_than_doing_nothing(trained, robot):
    from mca_drake.metrics import performance_index
    from mca_drake.references.reference import Reference
    from mca_drake.simulation.closed_loop import run_closed_loop

    _, policy_path, _ = trained
    _, y_ref = _sine_motion(1.0 + 0.01 * np.arange(150))
    reference = Reference(y_ref, 0.01, "sine motion")
    result = run_closed_loop(
        mca=DpcConfig(policy=str(policy_path)), reference=reference, progress=False, robot=KR500
    )
    zero_pi = performance_index(result.reference, np.zeros_like(result.reference))
    assert result.summary["pi"] < zero_pi - 0.5, (result.summary["pi"], zero_pi)
    assert result.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}


def test_a_trained_policy_records_the_range_of_its_training_targets(trained):
    """The guard for the unseen reads it (`cueing.reference_range`): almost every target of
    the dataset it learned on lies inside (its training split by construction)."""
    from mca_drake.cueing.reference_range import ReferenceRange, outside
    from mca_drake.segments import SegmentDataset

    _, policy_path, _ = trained
    _, metadata = load_policy_arrays(policy_path)
    ranges = ReferenceRange.from_record(metadata["reference_range"])
    dataset = SegmentDataset.load(policy_path.parent / "data.npz")
    targets = dataset.arrays["R"].reshape(-1, 6)
    assert outside(targets, ranges).any(axis=1).mean() < 0.05
    assert "data.npz" in ranges.source


def test_rollout_on_exact_plant_is_the_plant(robot):
    """The rollout's states and outputs are the exact plant's for the commands it issued."""
    from mca_drake.platforms.kinematics import plant_output

    torch.manual_seed(5)
    policy = PolicyNetwork(KR500)
    plant = RolloutPlant(DpcTrainingConfig(compile=False), KR500)
    targets = torch.randn(3, 20, 6)
    with torch.no_grad():
        roll = closed_loop_rollout(policy, plant, torch.zeros(3, 12), torch.zeros(3, 6), targets)
    X, U = roll.X.double().numpy(), roll.U.double().numpy()
    y = plant_output(X[:, :-1, :6], X[:, :-1, 6:], U, robot)
    np.testing.assert_allclose(roll.Y.numpy(), y, rtol=0, atol=2e-4)


def test_export_checkpoint_policy_gives_the_best_weights(trained, tmp_path):
    from mca_drake.learning.dpc_training import export_checkpoint_policy

    policy, policy_path, _ = trained
    out = export_checkpoint_policy(policy_path.with_name("policy.pt"), tmp_path / "e.npz")
    back = load_policy_network(out, KR500)
    y, x, r = (torch.randn(4, n) for n in (6, 12, 6))
    torch.testing.assert_close(back(y, x, r)[0], policy(y, x, r)[0])
    with pytest.raises(ValueError, match="not a DPC policy checkpoint"):
        from mca_drake.learning.checkpoint import save_checkpoint

        save_checkpoint(tmp_path / "other.pt", {"model": {}}, {"model": "nssm"})
        export_checkpoint_policy(tmp_path / "other.pt", tmp_path / "x.npz")


def test_perturbed_initial_states_stay_inside_the_limits(robot):
    from mca_drake.learning.dpc_training import perturb_initial_states

    torch.manual_seed(0)
    policy = PolicyNetwork(KR500)
    x0 = torch.zeros(4000, 12)
    x0[:, :6] = torch.tensor(robot.q_max, dtype=torch.float32) * 0.85
    out = perturb_initial_states(x0, policy, DpcTrainingConfig(perturbed_fraction=0.5))
    moved = (out != x0).any(dim=1).float().mean().item()
    assert 0.45 < moved < 0.55
    assert torch.equal(out[:, 6:], x0[:, 6:])  # velocities untouched
    assert torch.all(out[:, :6] <= 0.9 * policy.upper[6:12] + 1e-6)
    assert torch.all(out[:, 6:].abs() <= 0.9 * policy.upper[12:] + 1e-6)


def test_channel_weights_make_every_channel_count_alike():
    """'normalized': c_k var_k is the same for all k and sum_k c_k var_k = sum_k var_k, so
    doing nothing costs what it costs with uniform weights; the loss uses them per channel."""
    from mca_drake.learning.dpc_training import dpc_loss_terms, tracking_channel_weights

    g = torch.Generator().manual_seed(0)
    scales = torch.tensor([0.05, 0.02, 0.03, 0.5, 0.14, 0.7], dtype=torch.float64)
    targets = torch.randn(40, 50, 6, generator=g, dtype=torch.float64) * scales
    weights = tracking_channel_weights(
        DpcTrainingConfig(tracking_channel_weights="normalized"), targets
    )
    variance = targets.reshape(-1, 6).var(0)
    product = (weights.double() * variance).numpy()
    np.testing.assert_allclose(product, product.mean(), rtol=1e-5)
    assert product.sum() == pytest.approx(variance.sum().item(), rel=1e-5)
    uniform = DpcTrainingConfig(tracking_channel_weights="uniform")
    assert tracking_channel_weights(uniform, targets) is None
    given = DpcTrainingConfig(tracking_channel_weights=(1, 2, 3, 4, 5, 6))
    fixed = tracking_channel_weights(given, targets)
    assert fixed.tolist() == [1, 2, 3, 4, 5, 6]
    # the tracking term weights each channel's squared error
    policy = PolicyNetwork(KR500)
    T = 7
    roll = type("R", (), {})()
    roll.Y = torch.randn(2, T, 6, generator=g)
    roll.U, roll.X_hat = torch.zeros(2, T, 6), torch.zeros(2, T, 12)
    roll.X = torch.zeros(2, T + 1, 12)
    tgt = torch.randn(2, T, 6, generator=g)
    c = torch.tensor([1.0, 0.0, 2.0, 0.0, 0.5, 3.0])
    expected = sum(c[k] * ((roll.Y[..., k] - tgt[..., k]) ** 2).mean() for k in range(6))
    got = dpc_loss_terms(roll, tgt, policy, c)["tracking"]
    torch.testing.assert_close(got, expected)
    for bad in ("loud", (1.0, 2.0), (1, 1, 1, 1, 1, float("nan"))):
        with pytest.raises(ValueError, match="tracking_channel_weights"):
            DpcTrainingConfig(tracking_channel_weights=bad).validate()


def test_perceived_tracking_term_is_the_vestibular_model_of_the_errors():
    """tracking_signals "perceived": the tracking term compares the vestibular model's
    outputs, here against numpy's model of each rollout's outputs and targets from rest;
    the config follows a perceived NMPC's objective and refuses an unknown one."""
    from mca_drake.cueing import NmpcConfig
    from mca_drake.learning.dpc_training import dpc_loss_terms
    from mca_drake.learning.perception import TorchVestibularFilter
    from mca_drake.perception import perceive

    g = torch.Generator().manual_seed(3)
    policy, T = PolicyNetwork(KR500), 60
    roll = type("R", (), {})()
    roll.Y = torch.randn(3, T, 6, generator=g, dtype=torch.float64)
    roll.U, roll.X_hat = torch.zeros(3, T, 6), torch.zeros(3, T, 12)
    roll.X = torch.zeros(3, T + 1, 12)
    tgt = torch.randn(3, T, 6, generator=g, dtype=torch.float64)
    c = torch.tensor([1.0, 0.5, 2.0, 0.3, 0.5, 3.0], dtype=torch.float64)
    got = dpc_loss_terms(roll, tgt, policy, c, perception=TorchVestibularFilter())["tracking"]
    errors = [perceive(y) - perceive(t) for y, t in zip(roll.Y.numpy(), tgt.numpy(), strict=True)]
    expected = np.mean([(e**2 @ c.numpy()) for e in errors])
    assert got.item() == pytest.approx(expected, rel=1e-10)
    matched = DpcTrainingConfig.matching(NmpcConfig(objective="perceived"))
    assert matched.tracking_signals == "perceived"
    assert DpcTrainingConfig().tracking_signals == NmpcConfig().objective
    with pytest.raises(ValueError, match="tracking_signals"):
        DpcTrainingConfig(tracking_signals="felt").validate()


def test_training_can_start_from_a_policy_file(trained, tmp_path):
    """initial_policy: with a vanishing learning rate the result is the starting policy."""
    policy, policy_path, _ = trained
    data = _sine_target_dataset().save(tmp_path / "data.npz")
    config = DpcTrainingConfig(
        targets="reference",
        compile=False,
        window_segments=1,
        initial_policy=str(policy_path),
        train=TrainConfig(
            learning_rate=1e-12,
            weight_decay=0.0,
            batch_size=16,
            max_epochs=1,
            horizons=(32,),
            device="cpu",
        ),
    )
    started, fine_path = train_policy(config, data, tmp_path / "fine", progress=False)
    y, x, r = (torch.randn(4, n) for n in (6, 12, 6))
    torch.testing.assert_close(started(y, x, r)[0], policy(y, x, r)[0])
    # the fine-tuned file says where it started and sums both runs' training time
    import hashlib

    _, meta = load_policy_arrays(fine_path)
    _, first = load_policy_arrays(policy_path)
    provenance = meta["initial_policy_provenance"]
    assert provenance["sha256"] == hashlib.sha256(policy_path.read_bytes()).hexdigest()
    assert meta["training_wall_s_total"] == pytest.approx(
        meta["training_wall_s"] + first["training_wall_s"]
    )
    # what it learned covers what its initial policy had learned (the hull of both)
    learned, initial = meta["reference_range"], first["reference_range"]
    assert all(a <= b for a, b in zip(learned["low"], initial["low"], strict=True))
    assert all(a >= b for a, b in zip(learned["high"], initial["high"], strict=True))
    assert "initial policy" in learned["source"]
    with pytest.raises(ValueError, match="initial_policy file not found"):
        DpcTrainingConfig(initial_policy=str(tmp_path / "missing.npz")).validate()


def test_default_loss_is_the_shipped_nmpc_objective_and_paper_is_v6s():
    """The default DPC loss carries the shipped NMPC's weights (tracking the references);
    `paper()` is the loss the v6 policy recorded in its own file when it was trained."""
    import json

    from mca_drake.cueing import NmpcConfig
    from mca_drake.cueing.dpc import load_policy_arrays, shipped_policy_path

    nmpc = NmpcConfig()
    config = DpcTrainingConfig()
    assert config.targets == "reference"
    assert list(config.tracking_channel_weights) == list(nmpc.output_weights)
    assert (config.input_weight, config.washout_weight) == (nmpc.input_weight, nmpc.washout_weight)
    assert config.terminal_position_weight == nmpc.terminal_position_weight
    assert config.terminal_velocity_weight == nmpc.terminal_velocity_weight
    assert config.terminal_weight_horizon == nmpc.horizon_steps
    other = NmpcConfig(input_weight=0.5, output_weights=[2.0] * 6, horizon_steps=128)
    assert DpcTrainingConfig.matching(other).input_weight == 0.5
    assert DpcTrainingConfig.matching(other).terminal_weight_horizon == 128
    _, meta = load_policy_arrays(shipped_policy_path("policy_v6"))
    recorded = meta["dpc_config"]
    if isinstance(recorded, str):
        recorded = json.loads(recorded)
    paper = DpcTrainingConfig.paper()
    for name in (
        "targets",
        "input_weight",
        "washout_weight",
        "terminal_position_weight",
        "terminal_velocity_weight",
        "tracking_weight",
        "limit_weight",
    ):
        assert getattr(paper, name) == recorded[name], name
    assert set(paper.tracking_channel_weights) == {1.0}
    # the paper's recipe scales no terminal weights and mirrors no windows
    assert (paper.terminal_weight_horizon, paper.mirror_fraction) == (0, 0.0)


def test_bad_loss_weights_are_refused():
    with pytest.raises(ValueError, match="washout_weight must be a finite number >= 0"):
        DpcTrainingConfig(washout_weight=-0.1).validate()
    with pytest.raises(ValueError, match="input_weight"):
        DpcTrainingConfig(input_weight=float("nan")).validate()
    with pytest.raises(ValueError, match="perturbed_fraction"):
        DpcTrainingConfig(perturbed_fraction=1.5).validate()
    DpcTrainingConfig(washout_weight=0.5, input_weight=0.0).validate()


def test_clamp_bounds_are_constants_of_the_step_unless_asked(robot):
    """Near a limit the clamp's bound moves with the state at about 1/(c h^2) per rad: by
    default training treats it as a constant (gradient zero through it), `bound_gradients`
    lets it through, and then it matches a finite difference of the bound."""
    from mca_drake.learning.dpc_training import RolloutPlant

    x = torch.zeros(1, 12, dtype=torch.float32)
    x[0, 0] = float(robot.q_max[0]) - 1e-4  # joint 1 just below its upper limit, at rest
    u = torch.full((1, 6), float(robot.qdd_max[0]))  # full acceleration towards it

    def clamped(config, state):
        state = state.clone().requires_grad_(True)
        out = RolloutPlant(config, KR500).clamp(state, u)
        if not out.requires_grad:  # no path from the state to the command at all
            return out, torch.zeros_like(state)
        (grad,) = torch.autograd.grad(out[0, 0], state)
        return out.detach(), grad

    out, grad = clamped(DpcTrainingConfig(), x)
    assert out[0, 0] < u[0, 0]  # it was clamped
    assert torch.all(grad == 0)
    _, grad = clamped(DpcTrainingConfig(bound_gradients=True), x)
    step = 2e-5
    shifted = x.clone()
    shifted[0, 0] -= step
    out_shifted, _ = clamped(DpcTrainingConfig(bound_gradients=True), shifted)
    slope = (out[0, 0] - out_shifted[0, 0]) / step
    assert grad[0, 0] == pytest.approx(float(slope), rel=0.1)
    assert abs(float(grad[0, 0])) > 100.0


def test_near_neutral_windows_keep_the_starts_inside_the_bound(tmp_path):
    from mca_drake.learning.dpc_training import near_neutral_windows

    data = _sine_target_dataset(n_segments=10, horizon=8)
    data.arrays["X"][3, 0, 2] = 0.5  # starts 0.5 rad out on joint 3
    data.arrays["X"][7, 0, 0] = -0.31
    data.arrays["X"][5, 4, 1] = 2.0  # far out later in the window: does not count
    revolute = np.ones(6, bool)
    kept = near_neutral_windows(data, 0.3, revolute)
    assert len(kept) == 8
    assert np.abs(kept.arrays["X"][:, 0, :6]).max() <= 0.3
    assert near_neutral_windows(data, 0.6, revolute).arrays["X"].shape[0] == 10
    # a prismatic joint (a rail's carriage, m) away from its centre tilts nothing
    rail_first = np.array([False, True, True, True, True, True])
    assert len(near_neutral_windows(data, 0.3, rail_first)) == 9
    with pytest.raises(ValueError, match="max_start_position_rad"):
        DpcTrainingConfig(max_start_position_rad=0.0).validate()
    path = data.save(tmp_path / "far.npz")
    data.arrays["X"][:, 0, 0] = 1.0  # every window starts far out
    far = data.save(tmp_path / "all_far.npz")
    config = DpcTrainingConfig(max_start_position_rad=0.3, compile=False, window_segments=1)
    with pytest.raises(ValueError, match="start within max_start_position_rad"):
        train_policy(config, far, tmp_path / "out", progress=False)
    assert path.is_file()


def test_terminal_weights_are_scaled_to_their_horizon():
    """With only the terminal position cost on, a rollout of T steps whose terminal weights
    belong to a horizon of 2T carries twice the cost of unscaled weights, and one of T the
    same."""
    from mca_drake.learning.dpc_training import dpc_objective

    torch.manual_seed(2)
    T = 12
    only_terminal = loss_weights_only(terminal_position_weight=1.0) | {"compile": False}
    batch = {"X": torch.randn(4, T, 12) * 0.3, "Y": torch.zeros(4, T, 6), "R": torch.randn(4, T, 6)}
    policy = PolicyNetwork(KR500).eval()
    cost = {}
    for horizon in (0, T, 2 * T):
        config = DpcTrainingConfig(terminal_weight_horizon=horizon, **only_terminal)
        with torch.no_grad():
            cost[horizon] = float(dpc_objective(config, RolloutPlant(config, KR500))(policy, batch))
    assert cost[0] > 0
    np.testing.assert_allclose([cost[T], cost[2 * T]], [cost[0], 2 * cost[0]], rtol=1e-6)
    with pytest.raises(ValueError, match="terminal_weight_horizon"):
        DpcTrainingConfig(terminal_weight_horizon=-1).validate()


def test_a_policy_trained_for_another_platform_is_refused_naming_both(tmp_path, robot):
    """A policy commands the joints it was trained on: the shipped default (a file that
    names no platform: the KR500's) is refused on the rail, and a file naming the rail is
    refused on the KR500, each error naming both platforms."""
    rail = load_platform("kr500-rail")
    with pytest.raises(ValueError, match=r"trained for platform 'kr500', not for 'kr500-rail'"):
        DpcPolicy(default_policy_path(), rail)
    arrays, metadata = load_policy_arrays(default_policy_path())
    assert policy_platform(metadata) == "kr500"
    path = tmp_path / "rail_policy.npz"
    save_policy(path, PolicyNetwork(rail, hidden=8), {"platform": rail.summary()})
    assert policy_platform(load_policy_arrays(path)[1]) == "kr500-rail"
    with pytest.raises(ValueError, match=r"trained for platform 'kr500-rail', not for 'kr500'"):
        DpcPolicy(path, robot)
    with pytest.raises(ValueError, match=r"trained for platform 'kr500-rail', not for 'kr500'"):
        load_policy_network(path, robot)
    # the KR500's arrays under a record of the rail's seven joints do not fit together
    lying = tmp_path / "lying.npz"
    np.savez(
        lying,
        metadata_json=np.array(json.dumps({**metadata, "platform": rail.summary()})),
        **arrays,
    )
    with pytest.raises(ValueError, match="has 6 joints, its platform record 7"):
        load_policy_arrays(lying)
    with pytest.raises(ValueError, match="record with a name"):
        policy_platform({"platform": "kr500"})
