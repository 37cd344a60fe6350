"""The `mca-drake` command end to end on short runs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mca_drake.app import cli
from mca_drake.app.jobs import run_plant_demo
from mca_drake.app.scenarios import PlantDemoScenario, load_scenario
from mca_drake.cueing import NmpcConfig
from mca_drake.platforms.demo_motion import demo_joint_motion
from mca_drake.platforms.kinematics import plant_output

REPO = Path(__file__).resolve().parent.parent


def test_plant_demo_follows_the_demo_motion(robot):
    """The discrete plant under the sampled demo accelerations tracks the analytic demo
    trajectory, stays in limits, and its logged outputs are y of its logged states.

    Sampling qdd at the start of each step (left Riemann sum) bounds the velocity error by
    h * max|qdd| (about 0.014 rad/s here) and the position error by t times that."""
    duration, h = 4.0, 0.01
    result = run_plant_demo(scenario=PlantDemoScenario(duration_s=duration), progress=False)
    q, qd, _ = demo_joint_motion(result.times, robot)
    qd_bound = h * robot.qdd_max.max()
    np.testing.assert_allclose(result.states[:, 6:], qd, atol=qd_bound)
    np.testing.assert_allclose(result.states[:, :6], q, atol=duration * qd_bound)
    np.testing.assert_allclose(
        result.outputs,
        plant_output(result.states[:, :6], result.states[:, 6:], result.accelerations, robot),
        atol=1e-12,
    )
    assert result.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert result.times[-1] == pytest.approx(4.0)


def test_simulate_command_runs_the_multibody_closed_loop(tmp_path, capsys):
    out_json, plots = tmp_path / "out.json", tmp_path / "plots"
    code = cli.main(
        ["simulate", "--duration", "1", "--json", str(out_json), "--plots", str(plots), "--quiet"]
    )
    assert code == 0
    summary = json.loads(out_json.read_text())
    assert summary["plant"] == "multibody" and summary["mca"] == "dpc"
    assert summary["duration_s"] == 1.0 and summary["realtime_factor"] > 0
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    for name in ("tracking.png", "perceived.png", "joint_usage.png"):
        assert (plots / name).stat().st_size > 10_000
    # The terminal gets a result table, not the JSON; its figures are the summary's.
    printed = capsys.readouterr().out
    assert not printed.lstrip().startswith("{") and "f_x" in printed
    rows = {line[:18].strip(): line[18:].split() for line in printed.splitlines()}
    np.testing.assert_allclose([float(v) for v in rows["RMSE"]], summary["rmse"], atol=6e-4)
    np.testing.assert_allclose([float(v) for v in rows["CC"]], summary["cc"], atol=6e-4)
    # zero motion's PI is the sum of its RMSEs (its CC is 0): the row adds up to it
    zero = [float(v) for v in rows["RMSE zero motion"]]
    assert sum(zero) == pytest.approx(summary["pi_zero_motion"], abs=4e-3)
    assert f"PI {summary['pi']:.3f}" in printed and str(out_json) in printed
    # the perceived block beside it
    perceived = summary["perceived"]
    for name, key in (("perceived RMSE", "rmse"), ("perceived CC", "cc")):
        np.testing.assert_allclose([float(v) for v in rows[name]], perceived[key], atol=6e-4)
    assert f"perceived PI {perceived['pi']:.3f}" in printed


def test_simulate_command_on_the_analytical_plant(tmp_path):
    out_json = tmp_path / "out.json"
    args = ["simulate", "--plant", "analytical", "--mca", "washout", "--duration", "1"]
    code = cli.main([*args, "--json", str(out_json), "--plots", "", "--quiet"])
    assert code == 0
    summary = json.loads(out_json.read_text())
    assert summary["plant"] == "analytical" and summary["mca"] == "washout"


# Per scenario type: an override that makes the file's job a smoke run.
SMOKE_OVERRIDES = {
    "PlantDemoScenario": "{duration_s: 0.2}",
    "ClosedLoopScenario": "{duration_s: 0.3, output_dir: OUT}",
    "EvaluationScenario": (
        "{duration_s: 0.5, cases: [{name: A, vehicle: light, seeds: [1000]},"
        " {name: B, vehicle: jet, seeds: [2000]},"
        " {name: D, vehicles: [bmw-320i], manoeuvres: [lap], seeds: [4000]},"
        " {name: E, vehicles: [light], pilot: route, seeds: [5000]}],"
        " mcas: [dpc, washout], output_dir: OUT}"
    ),
    "DatasetScenario": (
        "{flight_seeds: [100], flight_duration_s: 3.0, horizon: 32, output_dir: OUT}"
    ),
    # no sender and no robot: the loop listens 0.3 s and holds the robot at home
    "LiveScenario": '{duration_s: 0.3, port: 0, robot: "", output_json: OUT/summary.json}',
}


@pytest.mark.parametrize("path", sorted((REPO / "diagrams").glob("*.yaml")), ids=lambda p: p.stem)
def test_every_scenario_file_loads_and_runs(path, tmp_path):
    from mca_drake.app.jobs import run_scenario

    kind = type(load_scenario(path)).__name__
    override = SMOKE_OVERRIDES[kind].replace("OUT", str(tmp_path / "out"))
    scenario = load_scenario(path, override)
    summary = run_scenario(scenario, progress=False, json_path=tmp_path / "summary.json")
    # the file holds null where the summary has NaN (a live run without packets has no
    # latency): compare with NaN read as null
    expected = json.loads(json.dumps(summary, default=str), parse_constant=lambda _: None)
    assert json.loads((tmp_path / "summary.json").read_text()) == expected
    if kind == "ClosedLoopScenario":
        assert summary["duration_s"] == pytest.approx(0.3)
        assert (tmp_path / "out" / "tracking.png").is_file()
    if kind == "DatasetScenario":
        assert summary["segments"] > 0 and summary["horizon"] == 32
    if kind == "EvaluationScenario":
        assert (tmp_path / "out" / "evaluation.md").is_file()
    if kind == "LiveScenario":
        assert summary["live"]["packets"] == 0 and summary["violations"]["q"] == 0
        assert (tmp_path / "out" / "summary.json").is_file()


def test_diagrams_folder_has_every_job():
    kinds = {type(load_scenario(p)).__name__ for p in (REPO / "diagrams").glob("*.yaml")}
    assert kinds == set(SMOKE_OVERRIDES)


@pytest.mark.parametrize(
    ("override", "match"),
    [
        ("{scenario: {durration_s: 2}}", "unknown field 'durration_s' of PlantDemoScenario"),
        ("{durration_s: 2}", "unknown field 'durration_s' of PlantDemoScenario"),
        ("{scenario: {duration_s: abc}}", "could not convert"),
        ("{scenario: {duration_s: -1}}", "duration_s must be positive"),
    ],
)
def test_bad_scenario_values_fail_clearly(override, match):
    with pytest.raises(ValueError, match=match):
        load_scenario(REPO / "diagrams" / "plant_demo.yaml", override)


def test_console_script_reports_errors_without_traceback():
    result = subprocess.run(
        [sys.executable, "-m", "mca_drake.app.cli", "run", "no/such/file.yaml"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 2
    assert "scenario file not found" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize(
    ("override", "match"),
    [
        ("{station: {torque_limit: true}}", "unknown field 'torque_limit' of StationConfig"),
        ("{mca: foo}", "unknown MCA 'foo'"),
        ("{plant: mujoco}", "plant must be one of analytical, multibody"),
        ("{station: {measurement_delay_s: -1}}", "measurement_delay_s"),
        ("{flight: {recording: no/such.csv}}", "not found"),
        ("{perception: {model: young}}", "unknown vestibular model 'young'"),
        ("{mca: !NmpcConfig {objective: felt}}", "unknown NMPC objective 'felt'"),
    ],
)
def test_bad_closed_loop_scenario_values_fail_clearly(override, match):
    with pytest.raises(ValueError, match=match):
        load_scenario(REPO / "diagrams" / "closed_loop_dpc.yaml", override)


@pytest.mark.parametrize(
    ("override", "match"),
    [
        (
            "{mca: !NmpcConfig {washout_wieght: 0.1}}",
            "unknown field 'washout_wieght' of NmpcConfig",
        ),
        ("{mca: {polcy: x.npz}}", "unknown field 'polcy' of DpcConfig"),
        ("{mca: !LqrConfig {}}", "unknown type !LqrConfig"),
        ("{mca: !DpcConfig {policy: no/such.npz}}", "policy file 'no/such.npz' not found"),
        ("{mca: !NmpcConfig {mode: fast}}", "unknown NMPC mode 'fast'"),
        ("{mca: null}", "mca: give a tagged value"),
        ("{mca: 3}", "mca: give a tagged value"),
        ("{random_seed: -1}", "random_seed must be in"),
        (
            "{simulator_config: {target_realtime_rat: 1}}",
            "'target_realtime_rat' of SimulatorConfig",
        ),
        ("{flight: null}", "flight: a FlightSpec or DriveSpec is required, not null"),
        ("{duration_s: [1", "not valid YAML"),
    ],
)
def test_bad_mca_configs_fail_naming_field_and_class(override, match):
    with pytest.raises(ValueError, match=match):
        load_scenario(REPO / "diagrams" / "closed_loop_dpc.yaml", override)


def test_typed_mca_config_from_set_changes_the_run(tmp_path):
    """`--set` replaces the MCA with a typed config: the paper's washout weight (1.0, ten
    times the tuned default) moves the PI, and the summary records the config that ran."""
    base = "{plant: analytical, duration_s: 4.0, output_dir: OUT}".replace("OUT", str(tmp_path))
    summaries = {}
    for label, mca in (
        ("default", "{mca: nmpc-rti}"),
        ("tuned", "{mca: !NmpcConfig {mode: rti, washout_weight: 1.0}}"),
    ):
        path = tmp_path / f"{label}.json"
        code = cli.main(
            [
                *("run", str(REPO / "diagrams" / "closed_loop_dpc.yaml"), "--quiet"),
                *("--set", base, "--set", mca, "--json", str(path)),
            ]
        )
        assert code == 0
        summaries[label] = json.loads(path.read_text())
    default, tuned = summaries["default"], summaries["tuned"]
    assert default["mca_config"]["type"] == tuned["mca_config"]["type"] == "NmpcConfig"
    assert default["mca_config"]["washout_weight"] == NmpcConfig().washout_weight != 1.0
    assert tuned["mca_config"]["washout_weight"] == 1.0
    assert tuned["mca_config"]["mode"] == "rti" and tuned["mca"] == "nmpc-rti"
    assert abs(tuned["pi"] - default["pi"]) > 1e-3


def test_an_untagged_override_keeps_the_mca_type():
    scenario = load_scenario(
        REPO / "diagrams" / "closed_loop_dpc.yaml",
        ["{mca: !NmpcConfig {mode: converged, washout_weight: 0.5}}", "{mca: {input_weight: 0.2}}"],
    )
    assert type(scenario.mca).__name__ == "NmpcConfig"
    assert scenario.mca.mode == "converged" and scenario.mca.washout_weight == 0.5
    assert scenario.mca.input_weight == 0.2


def test_a_tag_of_the_same_class_replaces_the_config():
    """A tagged MCA is a fresh config of that class; only an untagged mapping edits the one
    there."""
    path = REPO / "diagrams" / "closed_loop_dpc.yaml"
    first = "{mca: !NmpcConfig {mode: converged, nodes: 10}}"
    scenario = load_scenario(path, [first, "{mca: !NmpcConfig {washout_weight: 0.1}}"])
    assert (scenario.mca.mode, scenario.mca.nodes) == ("rti", 20)  # NmpcConfig's defaults
    assert scenario.mca.washout_weight == 0.1
    edited = load_scenario(path, [first, "{mca: {washout_weight: 0.1}}"])
    assert (edited.mca.mode, edited.mca.nodes, edited.mca.washout_weight) == (
        "converged",
        10,
        0.1,
    )


def test_an_untagged_scenario_file_is_refused(tmp_path):
    path = tmp_path / "untagged.yaml"
    path.write_text("scenario: {duration_s: 5}\n")
    with pytest.raises(ValueError, match="scenario: give a tagged value"):
        load_scenario(path)


def test_scenarios_take_mca_names_in_python():
    from mca_drake.app.scenarios import ClosedLoopScenario, EvaluationScenario

    assert ClosedLoopScenario(mca="nmpc-rti").mca.mode == "rti"
    assert [type(m).__name__ for m in EvaluationScenario(mcas=["dpc", "washout"]).mcas] == [
        "DpcConfig",
        "WashoutConfig",
    ]


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (
            ["run", "diagrams/closed_loop_dpc.yaml", "--set", "{mca: !NmpcConfig {nodez: 3}}"],
            "unknown field 'nodez' of NmpcConfig",
        ),
        (["evaluate", "--suite", "--cases", "Z"], "unknown case"),
        (["evaluate", "--suite", "--flights", "0"], "--flights must be at least 1"),
        (["evaluate", "--suite", "--mcas", "washout", "--policy", "p.npz"], "--policy"),
        (["simulate", "--mca", "lqr"], "unknown MCA 'lqr'"),
    ],
)
def test_cli_misuse_is_one_line_and_exit_2(argv, match, capsys, monkeypatch):
    monkeypatch.chdir(REPO)
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert match in err and "Traceback" not in err and err.count("\n") == 1


def test_train_policy_flags_reach_the_training_config(tmp_path, monkeypatch, capsys):
    """`train-policy`'s options land in DpcTrainingConfig (training itself is tested in
    test_dpc.py): the recorded config is what the command hands over, and a bad value is
    refused by the config's own validation."""
    import mca_drake.learning.dpc_training as dpc

    seen = []

    def fake_train_policy(config, dataset, out_dir, **_):
        config.validate()
        seen.append(config)
        return None, Path(out_dir) / "policy.npz"

    monkeypatch.setattr(dpc, "train_policy", fake_train_policy)
    args = ["train-policy", "--dataset", "d.npz", "--out-dir", str(tmp_path), "--quiet"]
    flags = ["--hidden", "64", "--batch-size", "32", "--max-start-position", "1.0", "--seed", "3"]
    assert cli.main(args + flags) == 0
    config = seen[-1]
    assert (config.hidden, config.train.batch_size) == (64, 32)
    assert (config.max_start_position_rad, config.seed) == (1.0, 3)
    more = ["--initial-state-noise", "0.4", "--yaw-shift-fraction", "0.3"]
    more += ["--time-stretch-fraction", "0.2", "--time-stretch-max", "2.5"]
    more += ["--correlation-weight", "0.7"]
    assert cli.main(args + more) == 0
    config = seen[-1]
    assert (config.initial_state_noise, config.yaw_shift_fraction) == (0.4, 0.3)
    assert (config.time_stretch_fraction, config.time_stretch_max) == (0.2, 2.5)
    assert config.correlation_weight == 0.7
    # untouched options keep the defaults
    assert config.train.horizons == dpc.DpcTrainingConfig().train.horizons
    for flag, name, bad in (
        ("--hidden", "hidden", "0"),
        ("--batch-size", "batch_size", "0"),
        ("--yaw-shift-fraction", "yaw_shift_fraction", "1.5"),
        ("--time-stretch-max", "time_stretch_max", "0.5"),
        ("--correlation-weight", "correlation_weight", "-1"),
    ):
        capsys.readouterr()
        assert cli.main([*args, flag, bad]) != 0
        assert name in capsys.readouterr().err


def test_scenario_chooses_the_perceived_objective_and_the_vestibular_model(tmp_path):
    """A scenario's `perception` sets the summary's vestibular model and the NMPC's
    `objective` its cost; the summary's perceived figures are those of that model."""
    from mca_drake.app.jobs import run_closed_loop_scenario
    from mca_drake.perception import PerceptionConfig, perceive

    override = (
        "{plant: analytical, duration_s: 3.0, perception: {model: ormsby}, "
        "mca: !NmpcConfig {objective: perceived, perception_model: ormsby}}"
    )
    scenario = load_scenario(REPO / "diagrams" / "closed_loop_dpc.yaml", override)
    result = run_closed_loop_scenario(scenario, progress=False, json_path="", plot_dir="")
    s = result.summary
    assert s["mca"] == "nmpc-rti-perceived" and s["mca_config"]["perception_model"] == "ormsby"
    assert s["perceived"]["model"] == "ormsby"
    config = PerceptionConfig(model="ormsby")
    errors = perceive(result.outputs, config) - perceive(result.reference, config)
    np.testing.assert_allclose(s["perceived"]["rmse"], np.sqrt(np.mean(errors**2, axis=0)))


def test_optimal_command_prints_the_bound_and_writes_its_summary(tmp_path, capsys):
    out_json = tmp_path / "bound.json"
    args = ["optimal", "--duration", "1", "--max-iterations", "3", "--json", str(out_json)]
    assert cli.main([*args, "--quiet"]) == 0
    summary = json.loads(out_json.read_text())
    assert summary["mca"] == "optimal" and summary["solver"]["iterations"] <= 3
    assert summary["step_time_s"] is None and summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    printed = capsys.readouterr().out
    assert f"PI {summary['pi']:.3f}" in printed and "SQP iterations" in printed


def test_suite_cases_choose_exactly_their_flights(tmp_path, monkeypatch, capsys):
    """`--cases A,D`: only cases A and D's flights run (not the jet's of B, the unseen
    types' of C or the route flights of E); `--report-only` then runs nothing and reports
    the runs on disk, leaving out an MCA that has none."""
    import mca_drake.app.cli.evaluate as evaluate

    out = tmp_path / "suite"
    seen = []

    def fake_run(scenario, **_):
        seen.append(scenario)
        out.mkdir(exist_ok=True)
        (out / "evaluation.md").write_text("report")

    monkeypatch.setattr(evaluate, "run_scenario", fake_run)
    argv = ["evaluate", "--suite", "--cases", "A,D", "--flights", "2", "--out-dir", str(out)]
    assert cli.main(argv) == 0
    (scenario,) = seen
    assert [(c.name, c.seeds) for c in scenario.cases] == [
        ("A", [1000, 1001]),
        ("D", [4000, 4001]),
    ]
    assert scenario.cases[1].vehicles == ["bmw-320i", "ford-escort", "vw-vanagon"]
    monkeypatch.undo()

    base = ["evaluate", "--suite", "--cases", "A", "--flights", "1", "--duration", "2"]
    base += ["--out-dir", str(out), "--quiet"]
    assert cli.main([*base, "--mcas", "washout"]) == 0
    run = out / "runs" / "A_washout_1000.json"
    assert sorted(p.name for p in run.parent.iterdir()) == [run.name]
    written = run.read_bytes()

    def no_runs(*_, **__):
        raise AssertionError("--report-only ran the suite")

    monkeypatch.setattr(evaluate, "run_scenario", no_runs)
    assert cli.main([*base, "--mcas", "washout,nmpc-rti", "--report-only"]) == 0
    assert sorted(p.name for p in run.parent.iterdir()) == [run.name]
    assert run.read_bytes() == written
    report = json.loads((out / "evaluation.json").read_text())
    assert list(report["cases"]["A"]["mcas"]) == ["washout"]
    assert report["mcas"] == ["washout", "nmpc-rti"]
    capsys.readouterr()
    assert cli.main(["evaluate", "--report-only", "--reference", "x.csv"]) == 2
    assert "add --suite" in capsys.readouterr().err


def test_simulate_and_optimal_choose_the_built_in_flight(tmp_path, capsys):
    """--vehicle, --flight-seed and --pilot pick the flight the summary names; a recording
    cannot take them."""
    out = tmp_path / "run.json"
    args = ["simulate", "--plant", "analytical", "--mca", "washout", "--duration", "0.5"]
    flight = ["--vehicle", "jet", "--flight-seed", "2001", "--pilot", "route"]
    assert cli.main([*args, *flight, "--json", str(out), "--plots", "", "--quiet"]) == 0
    assert json.loads(out.read_text())["reference"] == "built-in jet flight, seed 2001, route pilot"
    bound = tmp_path / "bound.json"
    optimal = ["optimal", "--duration", "0.5", "--max-iterations", "2", "--json", str(bound)]
    assert cli.main([*optimal, "--vehicle", "jet", "--flight-seed", "2001", "--quiet"]) == 0
    assert json.loads(bound.read_text())["reference"] == "built-in jet flight, seed 2001"
    recording = tmp_path / "flight.csv"
    recording.write_text("t,omega_x,omega_y,omega_z,f_x,f_y,f_z\n")
    assert cli.main([*args, "--reference", str(recording), "--flight-seed", "3"]) == 2
    assert "--flight-seed choose a built-in flight" in capsys.readouterr().err
    # the IMU noise's seed has its own name; --seed is no flag of simulate
    assert cli.main([*args, "--noise-seed", "4", "--json", "", "--plots", "", "--quiet"]) == 0
    with pytest.raises(SystemExit):
        cli.main([*args, "--seed", "4"])
