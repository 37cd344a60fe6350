"""The DPC on any serial platform: policies sized by the platform's joints, trained on a
dataset made on it, started from another platform's policy, and refused elsewhere."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from dataset_helpers import rest_segments

from mca_drake.cueing.dpc import (
    DpcConfig,
    PolicyInference,
    default_policy_path,
    load_policy_arrays,
    policy_platform,
    shipped_policy_path,
)
from mca_drake.cueing.recognition import RECOGNIZED_POLICIES
from mca_drake.learning.configs import DpcTrainingConfig, TrainConfig
from mca_drake.learning.dpc_training import train_policy
from mca_drake.learning.policy_network import (
    PolicyNetwork,
    save_policy,
    transfer_policy_network,
)
from mca_drake.platforms.files import load_platform

KR500 = load_platform("kr500")
RAIL = load_platform("kr500-rail")


def test_a_transferred_policy_commands_the_shared_joints_as_its_file_does(rng):
    """The KR500's default policy moved onto the rail: for any rail position and speed the
    KR500's joints get what the file's own numpy inference gives for the KR500's state, and
    the rail gets nothing."""
    arrays, _ = load_policy_arrays(default_policy_path())
    original = PolicyInference(arrays)
    rail = PolicyInference(transfer_policy_network(default_policy_path(), RAIL).double().export())
    assert rail.joints == 7
    for _ in range(20):
        y, target = rng.normal(size=6) * 0.5, rng.normal(size=6) * 0.5
        q, qd = rng.uniform(-0.5, 0.5, 6), rng.uniform(-0.3, 0.3, 6)
        s, sd = rng.uniform(-4, 4), rng.uniform(-1, 1)
        u_kr500, x_hat = original(y, np.concatenate([q, qd]), target)
        u, x_hat_rail = rail(y, np.concatenate([[s], q, [sd], qd]), target)
        np.testing.assert_allclose(u[1:], u_kr500, atol=1e-6)
        assert u[0] == 0.0
        np.testing.assert_allclose(x_hat_rail[1:7], x_hat[:6], atol=1e-6)
        np.testing.assert_allclose(x_hat_rail[8:], x_hat[6:], atol=1e-6)


def test_a_transferred_policy_turns_the_joints_another_maker_turns_the_other_way(rng):
    """The FANUC's joints 3 to 6 turn about -y and -x where the KR500's move the cabin the
    other way at home (their columns of the output Jacobian at home point apart, read off
    `plant_output` of a unit acceleration): at home the KR500's policy moved onto the FANUC
    commands those joints with the other sign, and the first two as the file does."""
    from mca_drake.platforms.kinematics import plant_output

    fanuc = load_platform("fanuc-m900ib700")
    at_home = lambda r, k: plant_output(r.home, np.zeros(6), np.eye(6)[k], r)  # noqa: E731
    expected = np.array([np.sign(at_home(KR500, k) @ at_home(fanuc, k)) for k in range(6)])
    np.testing.assert_array_equal(expected, [1, 1, -1, -1, -1, -1])
    arrays, _ = load_policy_arrays(default_policy_path())
    original = PolicyInference(arrays)
    moved = PolicyInference(transfer_policy_network(default_policy_path(), fanuc).double().export())
    for _ in range(10):
        y, target = rng.normal(size=6) * 0.5, rng.normal(size=6) * 0.5
        q, qd = rng.uniform(-0.3, 0.3, 6), rng.uniform(-0.2, 0.2, 6)
        u_kr500, _ = original(y, np.concatenate([q, qd]), target)
        u, _ = moved(y, np.concatenate([expected * q, expected * qd]), target)
        np.testing.assert_allclose(u, expected * u_kr500, atol=1e-6)


def test_a_policy_transfers_only_to_a_platform_with_all_its_joints(tmp_path):
    rail_policy = tmp_path / "rail.npz"
    save_policy(rail_policy, PolicyNetwork(RAIL, hidden=8), {"platform": RAIL.summary()})
    with pytest.raises(ValueError, match=r"joints \['rail_axis'\].*'kr500' does not"):
        transfer_policy_network(rail_policy, KR500)


def _rail_targets(n=20, horizon=32, seed=0):
    rng = np.random.default_rng(seed)
    t = 0.01 * np.arange(horizon)
    R = np.zeros((n, horizon, 6))
    R[..., 4] = rng.uniform(0.5, 1.5, (n, 1)) * np.sin(2 * np.pi * 0.3 * t)  # sway force
    return R


def test_a_policy_trains_on_the_rail_from_the_kr500s_and_records_it(tmp_path):
    """train-policy --platform kr500-rail on a dataset made on the rail, started from the
    KR500's default policy: the file records the rail and runs there; the KR500 and a
    KR500 dataset are refused, naming both platforms."""
    data = rest_segments(_rail_targets(), RAIL.summary()).save(tmp_path / "rail.npz")
    config = DpcTrainingConfig(
        platform="kr500-rail",
        initial_policy=str(default_policy_path()),
        compile=False,
        window_segments=1,
        own_start_fraction=0.0,
        train=TrainConfig(batch_size=8, max_epochs=2, horizons=(32,), device="cpu"),
    )
    _, path = train_policy(config, data, tmp_path / "out", progress=False)
    arrays, metadata = load_policy_arrays(path)
    assert policy_platform(metadata) == "kr500-rail" and metadata["platform"]["dof"] == 7
    assert arrays["W2"].shape == (21, 128) and arrays["W1"].shape == (128, 26)
    from mca_drake.systems.dpc import DpcPolicy

    DpcPolicy(path, RAIL)
    with pytest.raises(ValueError, match="'kr500-rail', not for 'kr500'"):
        DpcPolicy(path, KR500)
    kr500_data = rest_segments(_rail_targets()).save(tmp_path / "kr500.npz")
    with pytest.raises(ValueError, match="made on platform 'kr500', not on 'kr500-rail'"):
        train_policy(config, kr500_data, tmp_path / "out2", progress=False)


def test_each_platform_picks_its_own_shipped_policy():
    """Each packaged platform runs the KR500's choice of policy (by envelope, by profile)
    moved onto its joints, or those trained on it (the hexapod, the rigs); a platform that
    ships none says how to make one."""
    assert DpcConfig().policy_path("kr500") == default_policy_path()
    for name in ("kr500-rail", "fanuc-m900ib700"):
        for config, kr500_policy in (
            (DpcConfig(), "default_policy"),
            (DpcConfig(vehicle="light"), "light_policy"),
            (DpcConfig(vehicle="787-8"), "transport_policy"),
            (DpcConfig(profile="ground"), "ground_policy"),
        ):
            assert config.policy_path("kr500").name == f"{kr500_policy}.npz"
            path = config.policy_path(name)
            assert path.name == f"{name}_{kr500_policy}.npz"
            assert policy_platform(load_policy_arrays(path)[1]) == name
    # a legged platform's joints are its pose coordinates: policies trained on it; the
    # hexapod's default stands for the flight envelopes, its ground policy for cars, and a
    # rig's one policy (trained on flights and drives) for all
    own = (
        ("hexapod", DpcConfig(), "default_policy", 6),
        ("hexapod", DpcConfig(vehicle="light"), "default_policy", 6),
        ("hexapod", DpcConfig(vehicle="787-8"), "default_policy", 6),
        ("hexapod", DpcConfig(profile="ground"), "ground_policy", 6),
        ("hexapod", DpcConfig(vehicle="ford-escort"), "ground_policy", 6),
        *(
            (rig, config, "default_policy", dof)
            for rig, dof in (("rig-2dof", 2), ("rig-3dof", 3))
            for config in (DpcConfig(), DpcConfig(vehicle="jet"), DpcConfig(profile="ground"))
        ),
    )
    for platform, config, name, dof in own:
        path = config.policy_path(platform)
        assert path.name == f"{platform}_{name}.npz"
        arrays, metadata = load_policy_arrays(path)
        assert policy_platform(metadata) == platform and arrays["W2"].shape[0] == 3 * dof
        assert f"train-policy --platform {platform}" in metadata["command"]
    # an unnamed reference on the hexapod: the recognizer hands a car to its ground policy
    recognized = [p.name for p in DpcConfig().recognized_policy_paths("hexapod")]
    assert recognized == [
        f"hexapod_{name if name == 'ground_policy' else 'default_policy'}.npz"
        for name in RECOGNIZED_POLICIES
    ]
    with pytest.raises(FileNotFoundError, match=r"transfer-policy .* --platform my-robot"):
        DpcConfig().policy_path("my-robot")


def test_a_policy_network_is_sized_by_its_platform():
    policy = PolicyNetwork(RAIL, hidden=4)
    u, x_hat = policy(torch.zeros(3, 6), torch.zeros(3, 14), torch.zeros(3, 6))
    assert u.shape == (3, 7) and x_hat.shape == (3, 14)
    np.testing.assert_allclose(policy.upper[:7].numpy(), RAIL.qdd_max, rtol=1e-6)


def test_the_suite_runs_on_the_platform_it_names_and_keeps_runs_apart(tmp_path):
    """The suite on the rail records the rail in every run and its report; a KR500 run of
    the same flight on disk is not taken for the rail's, and the rail's washout washes out
    about the rail's own washout home (its summary's joint use has seven joints)."""
    from mca_drake.studies.evaluation import EvaluationCase, EvaluationConfig, run_evaluation

    case = EvaluationCase("A", "light", (1000,))
    kr500 = EvaluationConfig(mcas=("washout",), cases=(case,), duration_s=2.0)
    run_evaluation(kr500, tmp_path, progress=False)
    run_file = tmp_path / "runs" / "A_washout_1000.json"
    import json

    assert json.loads(run_file.read_text())["platform"]["name"] == "kr500"
    rail = EvaluationConfig(mcas=("washout",), cases=(case,), duration_s=2.0, platform="kr500-rail")
    report = run_evaluation(rail, tmp_path, progress=False)
    run = json.loads(run_file.read_text())
    assert run["platform"]["name"] == "kr500-rail" and len(run["joint_range_used"]) == 7
    assert report["platform"]["name"] == "kr500-rail"
    assert report["cases"]["A"]["mcas"]["washout"]["violations"] == 0
    from mca_drake.studies.evaluation import kept_entries

    with pytest.raises(ValueError, match="ran on platform 'kr500-rail', not on 'kr500'"):
        kept_entries(kr500, {}, report)


def test_a_platforms_tuned_settings_are_the_defaults_of_the_names_there(tmp_path, monkeypatch):
    """A settings file shipped for a platform makes `--mca nmpc-rti` and `washout` mean its
    tuned settings there; a config the user set differently, the DPC, and another
    platform keep theirs."""
    from mca_drake.cueing import NmpcConfig, WashoutConfig, as_mca_config, on_platform, profiles

    settings = tmp_path / "kr500-rail.yaml"
    settings.write_text("nmpc:\n  washout_weight: 0.7\nwashout:\n  tilt_limit: 0.2\n")
    monkeypatch.setattr(
        profiles,
        "platform_settings_path",
        lambda name: settings if name == "kr500-rail" else tmp_path / "none.yaml",
    )
    nmpc = as_mca_config("nmpc-converged", "kr500-rail")
    assert nmpc.washout_weight == 0.7 and nmpc.mode == "converged"
    assert as_mca_config("washout", "kr500-rail").tilt_limit == 0.2
    assert on_platform(NmpcConfig(mode="rti"), "kr500-rail").washout_weight == 0.7
    mine = NmpcConfig(mode="rti", input_weight=0.5)
    assert on_platform(mine, "kr500-rail") is mine
    assert on_platform(NmpcConfig(), "kr500") == NmpcConfig()
    assert on_platform(WashoutConfig(), "") == WashoutConfig()
    assert as_mca_config("dpc", "kr500-rail") == DpcConfig()


def test_the_default_dpc_on_the_rail_runs_the_rails_policy_within_its_limits():
    """`mca: dpc` on the rail: its shipped policy runs (the summary names its file) and no
    limit is left, on the analytical plant and the station alike; that policy is the
    KR500's moved onto the rail, which leaves the carriage where it stands."""
    from mca_drake.references.flights import FlightSpec, flight_reference
    from mca_drake.simulation.closed_loop import run_closed_loop

    reference = flight_reference(FlightSpec(vehicle="light", seed=704), 6.0)
    for plant in ("analytical", "multibody"):
        result = run_closed_loop(
            mca="dpc", reference=reference, plant=plant, robot=RAIL, progress=False
        )
        summary = result.summary
        assert summary["policy_file"] == "kr500-rail_light_policy.npz"
        assert summary["platform"]["name"] == "kr500-rail"
        assert sum(summary["violations"].values()) == 0
        assert np.ptp(result.states[:, 0]) < 1e-6  # the carriage stays


def test_transfer_policy_writes_a_policy_for_the_platform(tmp_path, capsys):
    """`mca-drake transfer-policy`: the file records the platform and where its weights came
    from, runs there, and commands what `transfer_policy_network` gives."""
    from mca_drake.app.cli import main

    out = tmp_path / "fanuc.npz"
    argv = ["transfer-policy", str(default_policy_path()), "--platform", "fanuc-m900ib700"]
    assert main([*argv, "--out", str(out)]) == 0
    arrays, metadata = load_policy_arrays(out)
    assert policy_platform(metadata) == "fanuc-m900ib700"
    assert metadata["transferred_from"]["path"] == str(default_policy_path())
    expected = transfer_policy_network(default_policy_path(), load_platform("fanuc-m900ib700"))
    np.testing.assert_allclose(arrays["W2"], expected.export()["W2"], rtol=1e-6)
    capsys.readouterr()
    rail = str(shipped_policy_path("kr500-rail_default_policy"))
    assert main(["transfer-policy", rail, "--platform", "kr500", "--out", str(tmp_path / "x")]) == 2
    assert "['rail_axis'] that platform 'kr500' does not have" in capsys.readouterr().err


def test_a_policy_trains_on_the_hexapod_with_its_legs_in_the_loss(tmp_path):
    """train-policy --platform hexapod from scratch: the rollout's limit term holds the
    legs (a rollout beyond the stroke pays for it), and the file records the hexapod and
    runs there."""
    from mca_drake.learning.dpc_training import RolloutPlant

    hexapod = load_platform("hexapod")
    data = rest_segments(_rail_targets(), hexapod.summary()).save(tmp_path / "hexapod.npz")
    config = DpcTrainingConfig(
        platform="hexapod",
        compile=False,
        window_segments=1,
        own_start_fraction=0.0,
        mirror_fraction=0.0,
        yaw_shift_fraction=0.0,
        train=TrainConfig(batch_size=8, max_epochs=2, horizons=(32,), device="cpu"),
    )
    plant = RolloutPlant(config, hexapod)
    assert plant.legs is not None
    # heave 0.25 m (inside no stroke: the legs reach 0.18 m) costs; the neutral pose not
    X = torch.zeros(1, 2, 12)
    X[0, 1, 2] = 0.25
    assert plant.legs.excess(X).item() > 0 and plant.legs.excess(torch.zeros(1, 2, 12)) == 0
    _, path = train_policy(config, data, tmp_path / "out", progress=False)
    _, metadata = load_policy_arrays(path)
    assert policy_platform(metadata) == "hexapod" and metadata["platform"]["dof"] == 6
    from mca_drake.systems.dpc import DpcPolicy

    DpcPolicy(path, hexapod)


def test_train_policy_learns_the_nmpc_objective_tuned_for_its_platform():
    """--objective tuned (the default) on a platform that ships tuned NMPC weights trains
    with those (read here from the shipped file itself); elsewhere the KR500's defaults."""
    import yaml

    from mca_drake.app.cli.training import objective_config
    from mca_drake.resources import data_dir

    shipped = yaml.safe_load((data_dir() / "platforms" / "hexapod.yaml").read_text())["nmpc"]
    config = objective_config("tuned", "hexapod")
    assert config.washout_weight == shipped["washout_weight"]
    assert list(config.tracking_channel_weights) == shipped["output_weights"]
    assert config.terminal_velocity_weight == shipped["terminal_velocity_weight"]
    assert objective_config("tuned", "kr500-rail") == DpcTrainingConfig()
    assert objective_config("tuned") == DpcTrainingConfig()
