"""The `mca-drake` command. Each subcommand parses arguments and calls one library function."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from mca_drake import __version__
from mca_drake.app.jobs import (
    closed_loop_outputs,
    run_closed_loop_scenario,
    run_live_scenario,
    run_scenario,
    start_meshcat,
)
from mca_drake.app.scenarios import (
    ClosedLoopScenario,
    DatasetScenario,
    EvaluationScenario,
    LiveScenario,
    load_scenario,
)
from mca_drake.atomic_io import check_writable
from mca_drake.conventions import CHANNELS
from mca_drake.cueing import MCA_NAMES, DpcConfig, mca_config_from_name, mca_name
from mca_drake.plotting import plot_recording, save_figure
from mca_drake.references.excitation import ExcitationConfig, generate_excitation_dataset
from mca_drake.references.jsbsim import TRAINING_VEHICLES, VEHICLES, fly
from mca_drake.references.recording import load_recording, save_recording
from mca_drake.simulation.builders import default_visualization
from mca_drake.simulation.closed_loop import PLANTS
from mca_drake.simulation.plots import tracking_figure
from mca_drake.studies.closed_loop_dataset import (
    DEFAULT_DATASET,
    ClosedLoopDatasetConfig,
    generate_closed_loop_dataset,
    join_datasets,
)
from mca_drake.studies.evaluation import default_cases
from mca_drake.studies.tuning import TUNABLE_MCAS, TuningConfig, run_tuning


def _check_outputs(*paths) -> None:
    """Refuses, before any work, output files that cannot be written (None: not asked)."""
    for path in paths:
        if path:
            check_writable(path)


def _given(args: argparse.Namespace, **names: str) -> dict:
    """{field: value} of the flags that were given (flag attribute -> field name): the CLI's
    flags default to None and only override the defaults of the config they fill."""
    return {
        field: getattr(args, flag)
        for flag, field in names.items()
        if getattr(args, flag) is not None
    }


def _mca_from_flags(args: argparse.Namespace, default):
    """The MCA config of --mca NAME and --policy FILE (a DPC policy), or `default`."""
    mca = mca_config_from_name(args.mca) if args.mca is not None else default
    if args.policy is not None:
        if not isinstance(mca, DpcConfig):
            raise ValueError("--policy is the policy file of --mca dpc")
        mca = DpcConfig(policy=args.policy)
    return mca


def _print_outputs_table(result, every_s: float = 1.0) -> None:
    step = max(round(every_s / (result.times[1] - result.times[0])), 1)
    print(f"{'t [s]':>7} " + " ".join(f"{c:>9}" for c in CHANNELS))
    for k in range(0, result.times.size, step):
        print(f"{result.times[k]:7.2f} " + " ".join(f"{v:9.4f}" for v in result.outputs[k]))


def _print_pi(summary: dict) -> None:
    print(
        f"PI {summary['pi']:.3f} (zero motion {summary['pi_zero_motion']:.3f}; lower is "
        "better, minimum -6)"
    )


def _hold_meshcat(meshcat) -> None:
    """Keeps the Meshcat server (and its recording) alive until the user is done."""
    if meshcat is None or not sys.stdin.isatty():
        return
    try:
        input(f"replay the recording at {meshcat.web_url()}; press Enter to exit ")
    except (EOFError, KeyboardInterrupt):
        pass


def _closed_loop_scenario_from_flags(args: argparse.Namespace, **fixed) -> ClosedLoopScenario:
    """A ClosedLoopScenario: its defaults, overridden by the flags that were given."""
    scenario = ClosedLoopScenario(**fixed)
    scenario.mca = _mca_from_flags(args, scenario.mca)
    if args.reference is not None:
        scenario.flight.recording = args.reference
    if args.duration is not None:
        scenario.duration_s = args.duration
    return scenario


def _cmd_simulate(args: argparse.Namespace) -> int:
    scenario = _closed_loop_scenario_from_flags(args)
    if args.plant is not None:
        scenario.plant = args.plant
    if args.meshcat:
        scenario.visualization = default_visualization()
    if args.realtime:
        scenario.simulator_config.target_realtime_rate = 1.0
    if args.seed is not None:
        scenario.random_seed = args.seed
    scenario.validate()
    meshcat = start_meshcat() if scenario.visualization is not None else None
    result = run_closed_loop_scenario(
        scenario,
        progress=not args.quiet,
        meshcat=meshcat,
        json_path=args.json,
        plot_dir=args.plots,
    )
    _print_outputs_table(result, every_s=max(result.times[-1] / 20, 0.1))
    print(json.dumps(result.summary, indent=2))
    _print_pi(result.summary)
    _, plots = closed_loop_outputs(scenario, args.json, args.plots)
    if plots:
        print(f"plots written to {plots}/tracking.png and {plots}/joint_usage.png")
    _hold_meshcat(meshcat)
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario, args.set)
    summary = run_scenario(scenario, progress=not args.quiet, json_path=args.json)
    print(json.dumps(summary, indent=2, default=str))
    return 0


def _cmd_flight(args: argparse.Namespace) -> int:
    _check_outputs(args.out, args.plot)
    recording = fly(args.vehicle, args.minutes * 60.0, args.seed, progress=not args.quiet)
    save_recording(args.out, recording)
    print(
        f"{args.vehicle} flight, seed {args.seed}: {recording.duration_s:.0f} s at "
        f"{recording.rate_hz:.0f} Hz written to {args.out}"
    )
    if args.plot:
        save_figure(plot_recording(recording), args.plot)
        print(f"plot written to {args.plot}")
    return 0


def _cmd_plot_recording(args: argparse.Namespace) -> int:
    out = args.out or str(args.recording).rsplit(".", 1)[0] + ".png"
    _check_outputs(out)
    recording = load_recording(args.recording)
    save_figure(plot_recording(recording, title=str(args.recording)), out)
    print(f"plot written to {out}")
    return 0


def _cmd_dataset_open_loop(args: argparse.Namespace) -> int:
    config = ExcitationConfig(
        **_given(
            args,
            repetitions="repetitions",
            duration="duration_s",
            horizon="horizon",
            seed="seed",
            initial_state_fraction="initial_state_fraction",
        )
    )
    config.validate()
    _check_outputs(args.out)
    dataset = generate_excitation_dataset(config, progress=not args.quiet)
    dataset.save(args.out)
    print(
        f"{len(dataset)} segments of {config.horizon} steps "
        f"({dataset.metadata['kept_steps']} of {dataset.metadata['simulated_steps']} simulated "
        f"steps kept) in {dataset.metadata['generation_wall_s']:.1f} s, written to {args.out}"
    )
    return 0


def _cmd_dataset_closed_loop(args: argparse.Namespace) -> int:
    scenario = DatasetScenario(
        **_given(
            args,
            vehicle="vehicle",
            horizon="horizon",
            workers="workers",
            out_dir="output_dir",
            address="address",
        )
    )
    if args.vehicles is not None:
        scenario.vehicles = [v.strip() for v in args.vehicles.split(",") if v.strip()]
    if args.mca is not None:
        scenario.mca = mca_config_from_name(args.mca)
    if args.minutes is not None:
        scenario.flight_duration_s = args.minutes * 60.0
    if args.flights is not None or args.first_seed is not None:
        first = args.first_seed if args.first_seed is not None else scenario.flight_seeds[0]
        count = args.flights if args.flights is not None else len(scenario.flight_seeds)
        scenario.flight_seeds = list(range(first, first + count))
    summary = run_scenario(scenario, progress=not args.quiet)
    print(f"closed-loop dataset written to {summary['dataset']}")
    return 0


def _cmd_dataset_join(args: argparse.Namespace) -> int:
    path = join_datasets(args.datasets, args.out)
    print(f"joined dataset written to {path}")
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    if args.suite:
        return _evaluate_suite(args)
    if not args.reference:
        raise ValueError("give --reference flight.csv (one recording) or --suite (scenario set)")
    scenario = _closed_loop_scenario_from_flags(args, plant="analytical")
    _check_outputs(args.plot)
    if args.duration is None:
        scenario.duration_s = load_recording(args.reference).duration_s
    result = run_closed_loop_scenario(
        scenario, progress=not args.quiet, json_path=args.json or "", plot_dir=""
    )
    if args.plot:
        save_figure(tracking_figure(result), args.plot)
    print(json.dumps(result.summary, indent=2))
    _print_pi(result.summary)
    return 0


def _evaluate_suite(args: argparse.Namespace) -> int:
    scenario = EvaluationScenario(
        **_given(
            args, duration="duration_s", workers="workers", out_dir="output_dir", address="address"
        )
    )
    if args.mcas is not None:
        scenario.mcas = [mca_config_from_name(n) for n in args.mcas.split(",")]
    if args.policy is not None:
        if not any(isinstance(m, DpcConfig) for m in scenario.mcas):
            raise ValueError("--policy is the policy file of dpc, which --mcas leaves out")
        scenario.mcas = [
            DpcConfig(policy=args.policy) if isinstance(m, DpcConfig) else m for m in scenario.mcas
        ]
    if args.flights is not None and args.flights < 1:
        raise ValueError(f"--flights must be at least 1; got {args.flights}")
    cases = {c.name: c for c in default_cases()}  # A: light, B: jet, C: unseen seeds
    wanted = args.cases.split(",") if args.cases is not None else list(cases)
    unknown = [c for c in wanted if c not in cases]
    if unknown:
        raise ValueError(f"--cases: unknown case {unknown}; valid: {', '.join(cases)}")
    flights = args.flights
    scenario.light_seeds = list(cases["A"].seeds[:flights]) if "A" in wanted else []
    scenario.jet_seeds = list(cases["B"].seeds[:flights]) if "B" in wanted else []
    scenario.unseen_seeds = list(cases["C"].seeds[:flights]) if "C" in wanted else []
    run_scenario(scenario, progress=not args.quiet)
    print((Path(scenario.output_dir) / "evaluation.md").read_text())
    return 0


def _flights(args: argparse.Namespace, default: tuple) -> tuple[tuple[str, int], ...]:
    """--flights vehicle:seed,... or the product of --vehicles and --seeds (each defaulting
    to the vehicles and seeds of `default`)."""
    if args.flights is not None:
        flights = []
        for item in args.flights.split(","):
            vehicle, _, seed = item.partition(":")
            if not seed.strip().lstrip("-").isdigit():
                raise ValueError(f"--flights: '{item}' is not vehicle:seed (e.g. light:100)")
            flights.append((vehicle.strip(), int(seed)))
        return tuple(flights)
    vehicles = (
        args.vehicles.split(",") if args.vehicles else list(dict.fromkeys(v for v, _ in default))
    )
    try:
        seeds = [int(s) for s in args.seeds.split(",")] if args.seeds else None
    except ValueError:
        raise ValueError(
            f"--seeds: whole numbers separated by commas, not '{args.seeds}'"
        ) from None
    seeds = seeds or list(dict.fromkeys(s for _, s in default))
    return tuple((v, s) for v in vehicles for s in seeds)


def _cmd_tune(args: argparse.Namespace) -> int:
    defaults = TuningConfig()
    tuning = TuningConfig(
        **_given(args, mca="mca", trials="trials", duration="duration_s", seed="seed"),
        flights=_flights(args, defaults.flights),
    )
    if args.budget_ms is not None:
        tuning.step_time_budget_s = args.budget_ms / 1e3
    if args.max_false_rotation is not None:
        tuning.max_false_rotation_deg_s = args.max_false_rotation
    command = "mca-drake " + " ".join(sys.argv[1:]) if sys.argv[0].endswith("mca-drake") else ""
    report = run_tuning(
        tuning,
        args.out_dir,
        workers=args.workers if args.workers is not None else 1,
        address=args.address,
        resume=args.resume,
        command=command,
        progress=not args.quiet,
    )
    out = Path(args.out_dir)
    print((out / "report.md").read_text())
    print(f"best config: {out / 'best.yaml'}; all trials: {out / 'trials.csv'}")
    return 0 if report else 1


def _cmd_live(args: argparse.Namespace) -> int:
    scenario = LiveScenario(
        host=args.host,
        port=args.port,
        mca=mca_config_from_name(args.mca),
        robot=args.robot or "",
        rsi_cycle_ms=args.rsi_cycle_ms,
        output_json=args.json or "",
    )
    sender = []
    if args.demo:
        # a JSBSim process flies the light aircraft and streams FGNetFDM packets to us; the
        # station in Meshcat unless told otherwise (or a robot is driven)
        from mca_drake.live.demo import DEMO_TIME_RESOLUTION_S, start_demo_sender

        scenario.protocol, scenario.port = "fgnetfdm", 0
        scenario.fgnetfdm_time_resolution_s = DEMO_TIME_RESOLUTION_S
        args.plant = args.plant or ("analytical" if args.robot else "multibody")
        args.meshcat = args.meshcat or args.plant == "multibody"
        args.duration = args.duration or 60.0
    elif args.protocol is None or args.duration is None:
        raise ValueError("live needs --protocol and --duration (or --demo)")
    else:
        scenario.protocol, scenario.xplane_version = args.protocol, args.xplane_version or 0
    scenario.plant = args.plant or "analytical"
    scenario.duration_s = args.duration
    if args.meshcat and scenario.plant != "multibody":
        raise ValueError("--meshcat draws the KR500 station: add --plant multibody")
    scenario.validate()
    meshcat = start_meshcat() if args.meshcat else None

    def listening(address):
        print(f"listening on udp://{address[0]}:{address[1]}", flush=True)
        if args.demo:
            # a little longer than the loop, so that the stream does not stop before it
            sender.append(start_demo_sender(address[1], args.duration + 2.0))

    try:
        summary = run_live_scenario(scenario, on_listening=listening, meshcat=meshcat)
    finally:
        for process in sender:
            process.terminate()
            process.wait(timeout=10)
    live = summary["live"]
    latency = {k: f"{v * 1e3:.3f} ms" for k, v in live["latency_s"].items()}
    wait = {k: f"{v * 1e3:.3f} ms" for k, v in live["wait_s"].items()}
    print(
        f"{live['packets']} packets ({live['bad']} bad, {live['dropped']} dropped, "
        f"{live['out_of_order']} out of order), {live['stale_events']} stale events; "
        f"latency {latency} (of which waiting for the poll {wait}); "
        f"health {live['health']}; PI {summary['pi']:.3f} "
        f"(zero motion {summary['pi_zero_motion']:.3f}); violations {summary['violations']}"
    )
    if "rsi" in summary:
        r = summary["rsi"]
        reply = {k: f"{v * 1e3:.3f} ms" for k, v in r.get("reply_latency_s", {}).items()}
        print(
            f"robot {r['address']}: {r.get('cycles', 0)} cycles, {r.get('late_replies', 0)} "
            f"late, {r.get('missed_cycles', 0)} missed, {r.get('bad_state', 0)} bad state "
            f"packets; reply latency {reply}; ended {r.get('mode')} ({r.get('reason')})"
        )
    _hold_meshcat(meshcat)
    return 0


def _cmd_table2(args: argparse.Namespace) -> int:
    # torch: loaded by the training commands only, so the others start fast
    from mca_drake.studies.table2 import Table2Config, quick_config, run_table2

    out = Path(args.out_dir)
    closed, open_loop = args.closed_loop_dataset, args.open_loop_dataset
    defaults = Table2Config()
    if args.quick:
        closed = closed or str(_quick_closed_loop_dataset(out / "data", not args.quiet))
        open_loop = open_loop or str(_quick_open_loop_dataset(out / "data"))
        config = quick_config(closed, open_loop)
    else:
        config = Table2Config(
            closed_loop_dataset=closed or defaults.closed_loop_dataset,
            open_loop_dataset=open_loop or defaults.open_loop_dataset,
        )
        for path, command in (
            (config.closed_loop_dataset, "mca-drake dataset closed-loop"),
            (config.open_loop_dataset, "mca-drake dataset open-loop --out datasets/open_loop.npz"),
        ):
            if not Path(path).is_file():
                raise FileNotFoundError(f"dataset {path} not found; make it with `{command}`")
    config.train = dataclasses.replace(
        config.train, **_given(args, device="device", max_epochs="max_epochs")
    )
    if args.only:
        wanted = set(args.only.split(","))
        config.state_models = tuple(n for n in config.state_models if f"state_{n}" in wanted)
        config.output_models = tuple(n for n in config.output_models if f"output_{n}" in wanted)
    report = run_table2(
        config,
        out,
        resume=args.resume,
        progress=not args.quiet,
        workers=args.workers if args.workers is not None else 1,
        address=args.address,
    )
    print((out / "table2.md").read_text())
    print(f"written to {out / 'table2.md'} and table2.json ({report['wall_s'] / 60:.1f} min)")
    return 0


def _channel_weights(text: str) -> str | tuple[float, ...]:
    """--channel-weights: 'uniform', 'normalized' or six comma-separated numbers."""
    if text in ("uniform", "normalized"):
        return text
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise SystemExit(
            f"--channel-weights: 'uniform', 'normalized' or six numbers, not '{text}'"
        ) from None


def _cmd_train_policy(args: argparse.Namespace) -> int:
    # torch: loaded by the training commands only, so the others start fast
    from mca_drake.learning.dpc import DpcTrainingConfig, train_policy

    base = DpcTrainingConfig.paper() if args.objective == "paper" else DpcTrainingConfig()
    config = dataclasses.replace(
        base,
        **_given(
            args,
            targets="targets",
            plant="plant",
            learned_output_weights="learned_output_weights",
            seed="seed",
            window_segments="window_segments",
            init_policy="initial_policy",
            washout_weight="washout_weight",
            input_weight="input_weight",
            perturbed_fraction="perturbed_fraction",
            initial_state_noise="initial_state_noise",
            max_start_position="max_start_position_rad",
            mirror_fraction="mirror_fraction",
            yaw_shift_fraction="yaw_shift_fraction",
            time_stretch_fraction="time_stretch_fraction",
            time_stretch_max="time_stretch_max",
            correlation_weight="correlation_weight",
            terminal_weight_horizon="terminal_weight_horizon",
            hidden="hidden",
        ),
    )
    if args.no_compile:
        config.compile = False
    if args.channel_weights is not None:
        config.tracking_channel_weights = _channel_weights(args.channel_weights)
    train = _given(
        args,
        device="device",
        max_epochs="max_epochs",
        patience="early_stopping_patience",
        learning_rate="learning_rate",
        batch_size="batch_size",
    )
    if args.horizons is not None:
        train["horizons"] = tuple(int(h) for h in args.horizons.split(","))
    config.train = dataclasses.replace(config.train, **train)
    command = "mca-drake " + " ".join(sys.argv[1:]) if sys.argv[0].endswith("mca-drake") else ""
    _, path = train_policy(
        config,
        args.dataset,
        args.out_dir,
        resume=args.resume,
        progress=not args.quiet,
        command=command,
    )
    print(f"policy written to {path}")
    return 0


def _cmd_export_policy(args: argparse.Namespace) -> int:
    _check_outputs(args.out)
    # torch: loaded by the training commands only, so the others start fast
    from mca_drake.learning.dpc import export_checkpoint_policy

    print(f"policy written to {export_checkpoint_policy(args.checkpoint, args.out)}")
    return 0


def _quick_closed_loop_dataset(folder: Path, progress: bool) -> Path:
    config = ClosedLoopDatasetConfig(flight_seeds=(100,), flight_duration_s=60.0, horizon=32)
    return generate_closed_loop_dataset(config, folder / "closed_loop", progress=progress)


def _quick_open_loop_dataset(folder: Path) -> Path:
    path = folder / "open_loop_quick.npz"
    if not path.is_file():
        config = ExcitationConfig(repetitions=3, duration_s=4.0, horizon=32)
        generate_excitation_dataset(config, progress=False).save(path)
    return path


ADDRESS_HELP = (
    "run the tasks on this Ray cluster ('auto', 'ray://host:10001'; default: RAY_ADDRESS, "
    "else a local Ray with --workers CPUs); its nodes need mca-drake installed"
)


def build_parser() -> argparse.ArgumentParser:
    """The ``mca-drake`` argument parser: one sub-command per job (see ``--help``)."""
    parser = argparse.ArgumentParser(
        prog="mca-drake", description="Motion cueing for a KUKA KR500 motion simulator, on Drake."
    )
    parser.add_argument("--version", action="version", version=f"mca-drake {__version__}")
    parser.add_argument(
        "--debug", action="store_true", help="show the traceback of an error (for reports)"
    )
    sub = parser.add_subparsers(dest="command", required=True)
    # Defaults shown in the help come from the configs they fill: one home for each.
    closed_loop, dataset_defaults, suite = (
        ClosedLoopScenario(),
        DatasetScenario(),
        EvaluationScenario(),
    )

    simulate = sub.add_parser(
        "simulate",
        help="the main job: closed-loop motion cueing (default: the shipped DPC policy) on a "
        "built-in flight or a recording; prints the outputs and the result summary, plots",
    )
    simulate.add_argument(
        "--duration", type=float, help=f"simulated seconds (default {closed_loop.duration_s:g})"
    )
    simulate.add_argument(
        "--mca",
        help=f"{', '.join(MCA_NAMES)}, each at its default config (default "
        f"{mca_name(closed_loop.mca)})",
    )
    simulate.add_argument(
        "--seed", type=int, help=f"seed of the IMU noise (default {closed_loop.random_seed})"
    )
    simulate.add_argument("--reference", help="recording CSV (default: the built-in flight)")
    simulate.add_argument("--policy", help="policy file for dpc (default: the shipped one)")
    simulate.add_argument("--json", help="write the result summary to this JSON file")
    simulate.add_argument(
        "--plant",
        choices=PLANTS,
        help="multibody: the KR500 MultibodyPlant with inverse-dynamics control and head IMU; "
        f"analytical: the ideal joint-space plant of the paper (default {closed_loop.plant})",
    )
    simulate.add_argument("--meshcat", action="store_true", help="watch it in Meshcat")
    simulate.add_argument("--realtime", action="store_true", help="run at real-time rate 1")
    simulate.add_argument(
        "--plots",
        help="folder for tracking.png (Fig. 4) and joint_usage.png (Fig. 5) (default: the "
        f"scenario's output_dir, {closed_loop.output_dir}); '' for none",
    )
    simulate.add_argument("--quiet", action="store_true", help="no progress bar")
    simulate.set_defaults(func=_cmd_simulate)

    run = sub.add_parser("run", help="run a scenario file from diagrams/")
    run.add_argument("scenario", help="YAML scenario file, e.g. diagrams/plant_demo.yaml")
    run.add_argument(
        "--set",
        action="append",
        help="YAML override of the scenario (repeatable, applied in order), e.g. "
        "'{duration_s: 5, station: {torque_limits: true}}' or "
        "'{mca: !NmpcConfig {mode: rti, washout_weight: 0.3}}'",
    )
    run.add_argument("--json", help="write the result summary to this JSON file")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_run)

    flight = sub.add_parser("flight", help="fly a JSBSim aircraft and record the pilot's IMU")
    flight.add_argument(
        "--vehicle",
        default="light",
        help=f"light (c172p), jet (global5000) or a JSBSim model: {', '.join(VEHICLES[2:])}",
    )
    flight.add_argument("--minutes", type=float, default=15.0, help="flight length, min")
    flight.add_argument("--seed", type=int, default=0, help="seed of the scripted pilot")
    flight.add_argument("--out", default="flight.csv", help="recording CSV to write")
    flight.add_argument("--plot", help="also write a PNG of the six channels")
    flight.add_argument("--quiet", action="store_true", help="no progress bar")
    flight.set_defaults(func=_cmd_flight)

    plot = sub.add_parser("plot-recording", help="plot a recording CSV (six channels, PNG)")
    plot.add_argument("recording", help="recording CSV (t, omega_x..z, f_x..z)")
    plot.add_argument("--out", help="PNG to write (default: next to the recording)")
    plot.set_defaults(func=_cmd_plot_recording)

    dataset = sub.add_parser("dataset", help="generate training and test datasets")
    dataset_sub = dataset.add_subparsers(dest="dataset_kind", required=True)
    open_loop = dataset_sub.add_parser(
        "open-loop", help="open-loop excitation dataset (Algorithm 1; defaults: paper size)"
    )
    open_loop.add_argument("--repetitions", type=int)
    open_loop.add_argument("--duration", type=float, help="s per simulation")
    open_loop.add_argument("--horizon", type=int, help="n_p, steps per segment")
    open_loop.add_argument("--seed", type=int)
    open_loop.add_argument(
        "--initial-state-fraction",
        type=float,
        help="draw initial states from this fraction of the limits (default "
        f"{ExcitationConfig.initial_state_fraction:g})",
    )
    open_loop.add_argument("--out", default="open_loop.npz")
    open_loop.add_argument("--quiet", action="store_true")
    open_loop.set_defaults(func=_cmd_dataset_open_loop)
    closed = dataset_sub.add_parser(
        "closed-loop", help="MCA closed loops over JSBSim flights (defaults: paper size)"
    )
    closed.add_argument(
        "--vehicle", help=f"one vehicle (default {dataset_defaults.vehicle}); see --vehicles"
    )
    closed.add_argument(
        "--vehicles",
        help="a mixed set: comma-separated vehicles, dealt to the seeds in turn (seed i flies "
        f"vehicle i mod n); training aircraft: {', '.join(TRAINING_VEHICLES)}",
    )
    closed.add_argument(
        "--flights", type=int, help=f"flights (default {len(dataset_defaults.flight_seeds)})"
    )
    closed.add_argument(
        "--first-seed",
        type=int,
        help=f"seed of the first flight (default {dataset_defaults.flight_seeds[0]})",
    )
    closed.add_argument(
        "--minutes",
        type=float,
        help=f"per flight (default {dataset_defaults.flight_duration_s / 60:g})",
    )
    closed.add_argument("--horizon", type=int, help=f"n_p (default {dataset_defaults.horizon})")
    closed.add_argument(
        "--mca", help=f"MCA that generates the data (default {mca_name(dataset_defaults.mca)})"
    )
    closed.add_argument(
        "--workers",
        type=int,
        help=f"CPUs of a local Ray, one flight each (default {dataset_defaults.workers}: here)",
    )
    closed.add_argument("--address", help=ADDRESS_HELP)
    closed.add_argument("--out-dir", help=f"default {dataset_defaults.output_dir}")
    closed.add_argument("--quiet", action="store_true")
    closed.set_defaults(func=_cmd_dataset_closed_loop)
    join = dataset_sub.add_parser(
        "join", help="join closed-loop datasets of different flights into one file"
    )
    join.add_argument("datasets", nargs="+", help="dataset.npz files (two or more)")
    join.add_argument("--out", required=True, help="the joined file (.npz)")
    join.set_defaults(func=_cmd_dataset_join)

    evaluate = sub.add_parser(
        "evaluate", help="run one recording through an MCA on the analytical plant"
    )
    evaluate.add_argument(
        "--mca",
        help=f"{', '.join(MCA_NAMES)}, each at its default config (default "
        f"{mca_name(closed_loop.mca)})",
    )
    evaluate.add_argument("--policy", help="policy file for --mca dpc (default: the shipped one)")
    evaluate.add_argument("--reference", help="recording CSV (one run)")
    evaluate.add_argument(
        "--suite", action="store_true", help="the scenario set: cases A, B and C, report, box plot"
    )
    evaluate.add_argument(
        "--cases",
        help=f"suite: cases to run (default {','.join(c.name for c in default_cases())})",
    )
    evaluate.add_argument(
        "--flights", type=int, help="suite: the first N flights of each case (default all)"
    )
    evaluate.add_argument(
        "--mcas",
        help=f"suite: MCAs to compare (default {','.join(mca_name(m) for m in suite.mcas)})",
    )
    evaluate.add_argument(
        "--workers",
        type=int,
        help=f"suite: CPUs of a local Ray (default {suite.workers}: runs here, in turn)",
    )
    evaluate.add_argument("--address", help=ADDRESS_HELP)
    evaluate.add_argument("--out-dir", help=f"suite: output folder (default {suite.output_dir})")
    evaluate.add_argument(
        "--duration",
        type=float,
        help=f"simulated seconds (default: all; suite: {suite.duration_s:g})",
    )
    evaluate.add_argument("--json", help="write the result summary here")
    evaluate.add_argument("--plot", help="PNG of target versus achieved outputs")
    evaluate.add_argument("--quiet", action="store_true")
    evaluate.set_defaults(func=_cmd_evaluate)

    tuning_defaults = TuningConfig()
    tune = sub.add_parser(
        "tune",
        help="tune an MCA's config (Ray Tune, Optuna TPE) on training flights; writes "
        "best.yaml, trials.csv and a report",
    )
    tune.add_argument("--mca", help=f"{', '.join(TUNABLE_MCAS)} (default {tuning_defaults.mca})")
    tune.add_argument("--trials", type=int, help=f"default {tuning_defaults.trials}")
    tune.add_argument(
        "--duration", type=float, help=f"s per flight (default {tuning_defaults.duration_s:g})"
    )
    tune.add_argument(
        "--flights", help="vehicle:seed list, e.g. light:100,jet:101 (seeds below 1000)"
    )
    tune.add_argument("--vehicles", help="with --seeds: every vehicle on every seed")
    tune.add_argument("--seeds", help="e.g. 100,101,102 (the training range: below 1000)")
    tune.add_argument("--budget-ms", type=float, help="step-time p99 budget, ms (default none)")
    tune.add_argument(
        "--max-false-rotation",
        type=float,
        help="false rotation limit, deg/s RMS, median over the flights (default "
        f"{tuning_defaults.max_false_rotation_deg_s:g}; 0: none)",
    )
    tune.add_argument("--workers", type=int, help="trials at once, on a local Ray (default 1)")
    tune.add_argument("--address", help=ADDRESS_HELP)
    tune.add_argument("--out-dir", default="results/tune")
    tune.add_argument("--resume", action="store_true", help="continue the tune in --out-dir")
    tune.add_argument("--seed", type=int, help="seed of the TPE sampler")
    tune.add_argument("--quiet", action="store_true")
    tune.set_defaults(func=_cmd_tune)

    live = sub.add_parser(
        "live",
        help="cue a running flight simulator's UDP telemetry in real time",
    )
    live.add_argument("--protocol", help="fgnetfdm, xplane or csv")
    live.add_argument("--xplane-version", type=int, help="11 or 12 (protocol xplane)")
    live.add_argument("--host", default="127.0.0.1", help="address to listen on")
    live.add_argument("--port", type=int, default=5500, help="UDP port (0: any free one)")
    live.add_argument("--duration", type=float, help="s of live cueing (demo: 60)")
    live.add_argument("--mca", default="dpc", help=", ".join(MCA_NAMES))
    live.add_argument("--realtime-rate", type=float, default=1.0, help="1: real time")
    live.add_argument(
        "--plant", help="analytical (default) or multibody (the KR500 station; demo default)"
    )
    live.add_argument("--meshcat", action="store_true", help="draw the station in Meshcat")
    live.add_argument("--json", help="result summary with its live block")
    live.add_argument(
        "--robot",
        help="rsi://HOST:PORT: drive a KUKA robot over RSI (the driver listens there for the "
        "controller's state packets; analytical plant)",
    )
    live.add_argument(
        "--rsi-cycle-ms", type=int, default=4, choices=(4, 12), help="the robot's RSI cycle"
    )
    live.add_argument(
        "--demo",
        action="store_true",
        help="JSBSim flies the light aircraft and streams FlightGear packets to this loop, "
        "cued on the KR500 station in Meshcat",
    )
    live.set_defaults(func=_cmd_live)

    table2 = sub.add_parser(
        "table2", help="train and score every plant-model candidate (the paper's Table II)"
    )
    table2.add_argument("--quick", action="store_true", help="a few minutes: small data, epochs")
    table2.add_argument("--closed-loop-dataset", help=f"default {DEFAULT_DATASET}")
    table2.add_argument("--open-loop-dataset", help="default datasets/open_loop.npz")
    table2.add_argument("--out-dir", default="results/table2")
    table2.add_argument("--resume", action="store_true", help="continue a killed run")
    table2.add_argument(
        "--workers", type=int, help="candidates at once, on a local Ray (default 1: here)"
    )
    table2.add_argument("--address", help=ADDRESS_HELP)
    table2.add_argument("--device", help="auto (CUDA if present), cpu, cuda")
    table2.add_argument("--max-epochs", type=int, help="override epochs per curriculum step")
    table2.add_argument(
        "--only", help="comma-separated candidates, e.g. state_node1,output_mixed (default all)"
    )
    table2.add_argument("--quiet", action="store_true")
    table2.set_defaults(func=_cmd_table2)

    policy = sub.add_parser(
        "train-policy",
        help="train the DPC policy on a closed-loop dataset (unset flags: the defaults of "
        "mca_drake.learning.dpc.DpcTrainingConfig: the shipped NMPC's objective)",
    )
    policy.add_argument(
        "--objective",
        choices=("tuned", "paper"),
        default="tuned",
        help="loss weights: tuned (the shipped NMPC's weights, tracking the references; "
        "default) or paper (equation 9, tracking the NMPC-achieved outputs: v5 and v6)",
    )
    policy.add_argument("--dataset", default=DEFAULT_DATASET)
    policy.add_argument("--out-dir", default="results/policy")
    policy.add_argument("--targets", help="achieved (NMPC outputs) or reference")
    policy.add_argument("--plant", help="exact or learned (NODE 2 + mixed)")
    policy.add_argument("--learned-output-weights", help="output_mixed_n256.pt of a table2 run")
    policy.add_argument(
        "--horizons", help="curriculum of rollout lengths n_c, steps, e.g. 256,1024"
    )
    policy.add_argument("--window-segments", type=int, help="dataset segments joined per window")
    policy.add_argument(
        "--channel-weights",
        help="tracking weights per output channel: six numbers (default the objective's), "
        "uniform, or normalized (1 / target variance)",
    )
    policy.add_argument("--init-policy", help="start from this policy file's weights")
    policy.add_argument(
        "--washout-weight", type=float, help="weight of ||q||^2 (default the objective's)"
    )
    policy.add_argument(
        "--input-weight", type=float, help="weight of ||u||^2 (default the objective's)"
    )
    policy.add_argument(
        "--max-start-position",
        type=float,
        help="train only on windows starting with every |q| within this many rad of neutral "
        "(default 0.6; inf: all)",
    )
    policy.add_argument(
        "--perturbed-fraction",
        type=float,
        help="fraction of training rollouts from perturbed initial positions (default 0)",
    )
    policy.add_argument(
        "--initial-state-noise",
        type=float,
        help="perturbed starts move each joint by uniform noise up to this share of its "
        "half-range (default 0.1)",
    )
    policy.add_argument(
        "--mirror-fraction",
        type=float,
        help="fraction of training rollouts that fly their window's mirror image (default 0.5; "
        "0: v9)",
    )
    policy.add_argument(
        "--yaw-shift-fraction",
        type=float,
        help="fraction of training rollouts that start with joint 1 (vertical axis, which the "
        "outputs do not depend on) at a random angle within 90%% of its range (default 0.5; "
        "0: v10)",
    )
    policy.add_argument(
        "--time-stretch-fraction",
        type=float,
        help="fraction of training rollouts that track their window slowed down by a random "
        "factor in [1, --time-stretch-max] (default 0.5; 0: v10)",
    )
    policy.add_argument(
        "--time-stretch-max",
        type=float,
        help="the largest slow-down factor of stretched windows (default 3)",
    )
    policy.add_argument(
        "--correlation-weight",
        type=float,
        help="weight of the correlation term, sum over channels of 1 - CC of the rollouts' "
        "outputs with their targets (the PI's CC part; default 0)",
    )
    policy.add_argument(
        "--terminal-weight-horizon",
        type=int,
        help="rollouts of n_c steps carry the terminal weights times this / n_c (default the "
        "NMPC's horizon, 256; 0: unscaled, v9)",
    )
    policy.add_argument("--max-epochs", type=int, help="epochs per curriculum step")
    policy.add_argument("--patience", type=int, help="early stopping, epochs")
    policy.add_argument("--learning-rate", type=float, help="the optimiser's (default 1e-3)")
    policy.add_argument("--hidden", type=int, help="hidden neurons of the policy (default 128)")
    policy.add_argument(
        "--batch-size", type=int, help="training windows per gradient step (default 256)"
    )
    policy.add_argument("--seed", type=int, help="seed of the weight initialisation")
    policy.add_argument("--device", help="auto (CUDA if present), cpu, cuda")
    policy.add_argument("--no-compile", action="store_true", help="eager torch (slower)")
    policy.add_argument("--resume", action="store_true", help="continue a killed run")
    policy.add_argument("--quiet", action="store_true")
    policy.set_defaults(func=_cmd_train_policy)

    export = sub.add_parser(
        "export-policy", help="best weights so far of a training checkpoint as a policy file"
    )
    export.add_argument("checkpoint", help="policy.pt of a train-policy run")
    export.add_argument("--out", default="policy.npz")
    export.set_defaults(func=_cmd_export_policy)
    return parser


# Errors a user can act on from the message alone (bad input, a missing or unwritable file,
# a run that cannot go on); anything else is a bug, reported with a pointer to --debug.
_USER_ERRORS = (ValueError, OSError, RuntimeError)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `mca-drake` console script.

    Every error ends as one line on stderr and exit status 2 (130 when interrupted), never a
    traceback; `--debug` shows the traceback instead.
    """
    args = build_parser().parse_args(argv)
    np.set_printoptions(precision=4, suppress=True)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("mca-drake: interrupted (finished result files are kept)", file=sys.stderr)
        return 130
    except Exception as err:
        if args.debug:
            raise
        message = " ".join(str(err).split()) or type(err).__name__
        if not isinstance(err, _USER_ERRORS):
            message = (
                f"{type(err).__name__}: {message} (unexpected: rerun with --debug for the "
                "traceback and report it)"
            )
        print(f"mca-drake: error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
