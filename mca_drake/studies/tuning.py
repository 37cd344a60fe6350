"""MCA tuning: Ray Tune with Optuna's TPE searcher over an MCA's typed config.

A trial is one MCA config (`NmpcConfig` in rti mode, or `WashoutConfig`) run in closed loop
on the analytical plant over a set of training flights; its objective is the median PI, or
the median perceived PI (`TuningConfig.score`: the vestibular models of `mca_drake.perception`).
Any limit violation or solver failure makes a trial infeasible: it then scores its median
PI plus `INFEASIBLE_PENALTY`, so the searcher learns to avoid it. Optionally a trial whose
99th-percentile step time exceeds a budget is infeasible too, and so is one whose false
rotation cues (`mca_drake.metrics.false_rotation`) exceed `max_false_rotation_deg_s`.

Flights are built-in JSBSim flights of the training range (seeds below 1000: evaluation
uses 1000 on) and never a reserved aircraft (only `mca_drake.references.jsbsim.VEHICLES`
fly); a car in their place drives (`mca_drake.references.drives.training_spec`), which is
how ground profiles are tuned. Every trial is a Ray task that builds its own diagrams; Ray
Tune keeps the study's state in `out_dir/ray`, so a killed tune resumes with `resume=True`.

Outputs in `out_dir`: `best.yaml` (the best config as a scenario override,
`mca: !NmpcConfig {...}`, with where it came from), `trials.csv` (every trial's parameters
and results), `report.md` (the best trials; per flight, the best config's PI against the
paper's config and zero motion), `convergence.png` and `importance.png`.
"""

from __future__ import annotations

import dataclasses
import datetime
import io
import json
import math
import time
import uuid
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from mca_drake.atomic_io import (
    atomic_write_json,
    atomic_write_text,
    check_writable,
)
from mca_drake.cueing import NmpcConfig, WashoutConfig, mca_config_record
from mca_drake.input_checks import MAX_DURATION_S, check_config_numbers, check_range
from mca_drake.platforms.files import (
    DEFAULT_PLATFORM,
    load_platform,
    packaged_platforms,
    platform_file,
)
from mca_drake.plotting import save_figure
from mca_drake.references.drives import motion_reference, training_spec
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.parallel import ray_address, ray_session

# Added to an infeasible trial's median PI (the PI's range is about -6 to +10).
INFEASIBLE_PENALTY = 10.0
# Added on top, per limit's worth of false rotation above the limit (a trial at twice the
# limit scores INFEASIBLE_PENALTY + 2): graded, so that TPE, whose "good" trials are the best
# quantile, learns the way to feasibility while every trial is still over the limit (under a
# flat penalty the best infeasible trials are those that bought PI with the most rotation).
FALSE_ROTATION_PENALTY_PER_LIMIT = 2.0
TUNABLE_MCAS = ("nmpc-rti", "washout")
# What a trial is scored on: the median over the flights of the PI or of the perceived PI.
SCORES = ("pi", "perceived_pi")
CHANNELS_WEIGHTED = ("w_x", "w_y", "w_z", "f_x", "f_y", "a_z")


@dataclasses.dataclass
class TuningConfig:
    """What to tune, on which flights, with what budget."""

    # The MCA: "nmpc-rti" (NmpcConfig weights) or "washout" (WashoutConfig filters).
    mca: str = "nmpc-rti"
    # Trials (MCA configs tried).
    trials: int = 40
    # Simulated seconds of each training flight.
    duration_s: float = 120.0
    # Training flights as (vehicle, seed); seeds below 1000 (evaluation uses 1000 on). A car
    # (`references.driving.CARS`) drives instead (`references.drives.training_spec`).
    flights: tuple[tuple[str, int], ...] = (
        ("light", 100),
        ("light", 101),
        ("light", 102),
        ("jet", 100),
        ("jet", 101),
        ("jet", 102),
    )
    # A trial whose 99th-percentile MCA step time exceeds this is infeasible, s (0: none).
    step_time_budget_s: float = 0.0
    # A trial whose false rotation (`mca_drake.metrics.false_rotation`: RMS rate of the
    # rotation the occupant feels that the vehicle did not make), median over the flights,
    # exceeds this is infeasible, deg/s (0: none). The PI prices rotation errors in rad/s
    # beside specific-force errors in m/s^2: tuned on the PI alone, the NMPC swings the cabin
    # at 16-58 deg/s RMS of false rotation (felt 80-90 % of the time) to sustain heave by
    # centripetal acceleration. 5 deg/s, about twice the vestibular thresholds, leaves room
    # for tilt coordination at its usual rate limits (the policy_v6 DPC and the washout:
    # 1-4 deg/s); docs/decisions/0007-nmpc-tuning-limits-false-rotation.md.
    max_false_rotation_deg_s: float = 5.0
    # The figure a trial is scored on, median over the flights: "pi" or "perceived_pi" (the
    # PI of the vestibular models' outputs, `mca_drake.perception`).
    score: str = "pi"
    # The objective of the tuned NMPC (nmpc-rti only): "inertial" or "perceived".
    nmpc_objective: str = "inertial"
    # Seed of the TPE sampler.
    seed: int = 0
    # The motion platform the trials cue on: a packaged name (`mca-drake platforms`) or a
    # platform file.
    platform: str = DEFAULT_PLATFORM

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run or that would tune on evaluation
        flights."""
        check_config_numbers(self)
        if self.mca not in TUNABLE_MCAS:
            raise ValueError(f"cannot tune '{self.mca}'; valid: {', '.join(TUNABLE_MCAS)}")
        if self.score not in SCORES:
            raise ValueError(f"unknown score '{self.score}'; valid: {', '.join(SCORES)}")
        NmpcConfig(objective=self.nmpc_objective).validate()
        if self.trials < 1:
            raise ValueError(f"trials must be at least 1; got {self.trials}")
        check_range(
            "TuningConfig", "duration_s", self.duration_s, 0.0, MAX_DURATION_S, low_open=True
        )
        if not self.flights:
            raise ValueError("flights is empty: nothing to tune on")
        for vehicle, seed in self.flights:
            training_spec(vehicle, seed)
        load_platform(self.platform)  # ValueError or FileNotFoundError naming the problem
        if self.step_time_budget_s < 0:
            raise ValueError("step_time_budget_s must be >= 0")
        if self.max_false_rotation_deg_s < 0:
            raise ValueError("max_false_rotation_deg_s must be >= 0 (0: no limit)")


def search_space(mca: str) -> dict:
    """Ray Tune's search space of `mca`'s tunable fields (log-uniform for weights and gains
    that span decades, uniform for frequencies, damping and angles)."""
    from ray import tune  # ray (heavy) only where a tune runs

    if mca == "nmpc-rti":
        space = {f"weight_{c}": tune.loguniform(0.1, 10.0) for c in CHANNELS_WEIGHTED}
        # Rotation errors are in rad/s beside specific force in m/s^2: a false rotation at
        # the vestibular threshold (0.05 rad/s) costs a 400th of a 1 m/s^2 force error at
        # equal weights. Rotation weights up to 300 let the tune price it near the force
        # channels' (x100 on the 2026-11-23 weights: 2.2 deg/s RMS false rotation on a
        # 120 s jet flight against 26.6, PI -1.62 against -1.79).
        space |= {f"weight_{c}": tune.loguniform(0.1, 300.0) for c in ("w_x", "w_y", "w_z")}
        space |= {
            # down to 1e-3: the 23-trial tune of 2026-11-23 put its best at 0.01, the bound
            # then (the exact QPs of the dual active-set method keep such weights real-time)
            "input_weight": tune.loguniform(0.001, 1.0),
            "washout_weight": tune.loguniform(0.01, 10.0),
            "terminal_position_weight": tune.loguniform(0.1, 10.0),
            "terminal_velocity_weight": tune.loguniform(0.1, 10.0),
        }
        return space
    if mca == "washout":
        return {
            "translation_frequency": tune.uniform(0.5, 5.0),
            "translation_damping": tune.uniform(0.5, 1.5),
            "translation_washout_frequency": tune.uniform(0.1, 2.0),
            "translation_gain": tune.uniform(0.2, 1.5),
            "tilt_frequency": tune.uniform(1.0, 10.0),
            "tilt_damping": tune.uniform(0.5, 1.5),
            "tilt_rate_limit": tune.uniform(math.radians(1.0), math.radians(8.0)),
            "tilt_limit": tune.uniform(math.radians(5.0), math.radians(30.0)),
            "rotation_frequency": tune.uniform(0.2, 3.0),
            "rotation_damping": tune.uniform(0.5, 1.5),
            "rotation_gain": tune.uniform(0.2, 1.5),
            "pose_feedback_gain": tune.uniform(2.0, 20.0),
        }
    raise ValueError(f"cannot tune '{mca}'; valid: {', '.join(TUNABLE_MCAS)}")


def config_from_parameters(
    mca: str, parameters: dict, nmpc_objective: str = "inertial"
) -> NmpcConfig | WashoutConfig:
    """The MCA config a trial's parameters stand for (fields not tuned at their defaults;
    an NMPC with the objective `nmpc_objective`)."""
    if mca == "nmpc-rti":
        weights = [float(parameters[f"weight_{c}"]) for c in CHANNELS_WEIGHTED]
        rest = {k: float(v) for k, v in parameters.items() if not k.startswith("weight_")}
        return NmpcConfig(mode="rti", output_weights=weights, objective=nmpc_objective, **rest)
    return WashoutConfig(**{k: float(v) for k, v in parameters.items()})


def parameters_of(mca: str, config: NmpcConfig | WashoutConfig) -> dict[str, float]:
    """The inverse of `config_from_parameters`: `config`'s values of the tuned fields."""
    if mca == "nmpc-rti":
        parameters = {
            f"weight_{c}": float(w)
            for c, w in zip(CHANNELS_WEIGHTED, config.output_weights, strict=True)
        }
        names = [k for k in search_space(mca) if not k.startswith("weight_")]
        return parameters | {k: float(getattr(config, k)) for k in names}
    return {k: float(getattr(config, k)) for k in search_space(mca)}


def starting_point(mca: str) -> dict[str, float]:
    """The first trial of a new tune: the shipped defaults, clipped into the search space, so
    that a tune never ends worse than the defaults on its own objective. (Where the defaults
    are over the false-rotation limit, the graded penalty leads the searcher back under it.)"""
    space = search_space(mca)
    default = NmpcConfig(mode="rti") if mca == "nmpc-rti" else WashoutConfig()
    return {
        k: float(np.clip(v, space[k].lower, space[k].upper))
        for k, v in parameters_of(mca, default).items()
    }


def baseline_config(mca: str, nmpc_objective: str = "inertial") -> NmpcConfig | WashoutConfig:
    """What a tuned config is compared with: the paper's NMPC weights (with the objective
    `nmpc_objective`), or the washout's textbook cut-offs."""
    if mca == "nmpc-rti":
        return dataclasses.replace(NmpcConfig.paper(), objective=nmpc_objective)
    return WashoutConfig.classic()


def score_config(config, tuning: TuningConfig, flights_dir: str | Path) -> dict:
    """Runs `config` over the training flights: {"objective", "pi_median", "feasible",
    "pi" (per flight), "pi_zero_motion" (per flight), "perceived_pi" (per flight),
    "perceived_pi_median", "false_rotation_deg_s" (per flight, RMS), "step_time_p99_s",
    "why"}; the objective is the median of `tuning.score`, plus the penalties."""
    pis, zero, perceived, false, p99, why = [], [], [], [], 0.0, ""
    robot = load_platform(tuning.platform)
    for vehicle, seed in tuning.flights:
        reference = motion_reference(
            training_spec(vehicle, seed), tuning.duration_s, cache_dir=flights_dir
        )
        result = run_closed_loop(
            mca=config,
            reference=reference,
            duration_s=tuning.duration_s,
            robot=robot,
            progress=False,
        )
        s = result.summary
        pis.append(s["pi"])
        zero.append(s["pi_zero_motion"])
        perceived.append(s["perceived"]["pi"])
        false.append(s["false_rotation"]["rms_deg_s"])
        p99 = max(p99, s["step_time_s"]["p99"])
        if sum(s["violations"].values()):
            why = why or f"limit violations on {vehicle} {seed}"
        if s["solver_failures"]:
            why = why or f"solver failures on {vehicle} {seed}"
    if tuning.step_time_budget_s and p99 > tuning.step_time_budget_s:
        why = why or f"step p99 {p99 * 1e3:.2f} ms over the budget"
    limit = tuning.max_false_rotation_deg_s
    excess = 0.0
    if limit and np.median(false) > limit:
        why = why or f"false rotation {np.median(false):.1f} deg/s RMS over {limit:g}"
        excess = FALSE_ROTATION_PENALTY_PER_LIMIT * (float(np.median(false)) / limit - 1.0)
    median = float(np.median(pis))
    scored = median if tuning.score == "pi" else float(np.median(perceived))
    return {
        "objective": scored + (INFEASIBLE_PENALTY + excess if why else 0.0),
        "pi_median": median,
        "perceived_pi": perceived,
        "perceived_pi_median": float(np.median(perceived)),
        "feasible": not why,
        "why": why,
        "pi": pis,
        "pi_zero_motion": zero,
        "false_rotation_deg_s": false,
        "step_time_p99_s": p99,
    }


def _optional_float(value) -> float | None:
    """`value` as a float, None where it is missing or NaN (JSON has no NaN)."""
    return None if value is None or math.isnan(float(value)) else float(value)


def _trial(parameters: dict, *, tuning: TuningConfig, flights_dir: str, trials_dir: str) -> None:
    """A Ray Tune trial: score one config, keep it as a JSON file, report its objective."""
    from ray import tune  # ray (heavy) only where a tune runs

    config = config_from_parameters(tuning.mca, parameters, tuning.nmpc_objective)
    scores = score_config(config, tuning, flights_dir)
    record = {
        "parameters": {k: float(v) for k, v in parameters.items()},
        **scores,
        "finished_at": time.time(),
    }
    atomic_write_json(Path(trials_dir) / f"{uuid.uuid4().hex}.json", record)
    tune.report({"objective": scores["objective"]})


def load_trials(trials_dir: Path) -> list[dict]:
    """The finished trials of a tune (JSON files, never pickles), oldest first; a file that
    does not read (a trial killed while writing cannot leave one: writes are atomic) is an
    error naming it."""
    records = []
    for path in sorted(Path(trials_dir).glob("*.json")):
        try:
            record = json.loads(path.read_text())
            record["trial"] = path.stem
            float(record["objective"])
            dict(record["parameters"])
        except (OSError, ValueError, KeyError, TypeError) as err:
            raise ValueError(f"{path} is not a trial record: {err}") from err
        records.append(record)
    return sorted(records, key=lambda r: r.get("finished_at", 0.0))


def replayed_sampler(seed: int, done: list[dict], space: dict):
    """The TPE sampler of seed `seed` in the state a tune leaves it in after the trials
    `done` (oldest first), so that a resumed tune draws what an uninterrupted one would.

    The sampler's random state advances with every trial it draws: each finished trial is
    asked again in order (the first, the starting point, enqueued as a new tune enqueues
    it, which draws nothing) and told its score. With one trial at a time (`workers` 1) the
    tune is then the uninterrupted one; with several, trials finish in the order the
    machines give, and no two runs are alike anyway.

    Args:
        seed: the tune's `TuningConfig.seed`.
        done: the finished trials' records (`load_trials`).
        space: the Optuna distributions of the search space (as Ray's OptunaSearch has them).
    """
    # optuna (heavy) only where a tune runs
    import optuna

    sampler = optuna.samplers.TPESampler(seed=seed)
    if not done:
        return sampler
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(sampler=sampler, direction="minimize")
    for index, record in enumerate(done):
        if index == 0:
            study.enqueue_trial(record["parameters"])
        trial = study.ask(fixed_distributions=space)
        study.tell(trial, float(record["objective"]))
    return sampler


def run_tuning(
    tuning: TuningConfig,
    out_dir: str | Path,
    *,
    workers: int = 1,
    address: str | None = None,
    resume: bool = False,
    command: str = "",
    progress: bool = True,
) -> dict:
    """Tunes `tuning.mca` and writes best.yaml, trials.csv, report.md and the plots.

    Every finished trial is a JSON file in `out_dir/trials`. A resumed tune reads them,
    hands them to the TPE searcher as evaluated points (nothing Ray pickled is ever
    loaded) and runs only the trials still missing.

    Args:
        workers: trials run at once, on a local Ray with this many CPUs.
        address: a Ray cluster to run on (default RAY_ADDRESS, else a local Ray); its
            workers must see `out_dir` (a shared file system).
        resume: continue the tune in `out_dir`, which must have the same settings (the
            number of trials may grow); without it an existing tune there is an error.
        command: the command line, recorded in best.yaml.

    Returns:
        The report as a dict (best config, its scores, the baseline's).
    """
    # ray (heavy: seconds to import) only where a tune runs
    from ray import tune
    from ray.tune.search import ConcurrencyLimiter
    from ray.tune.search.optuna import OptunaSearch

    tuning.validate()
    if workers < 1:
        raise ValueError(f"workers must be at least 1; got {workers}")
    if tuning.platform not in packaged_platforms():
        # a platform file by its path: Ray Tune runs each trial in its own folder
        tuning = dataclasses.replace(tuning, platform=str(platform_file(tuning.platform).resolve()))
    out = check_writable(Path(out_dir).resolve(), folder=True)
    flights_dir, trials_dir, state = out / "flights", out / "trials", out / "tuning.json"
    identity = {k: v for k, v in dataclasses.asdict(tuning).items() if k != "trials"}
    identity = json.loads(json.dumps(identity))
    if state.exists() and not resume:
        raise ValueError(f"a tune exists in {out}: resume it (--resume) or choose another folder")
    if resume:
        if not state.exists():
            raise ValueError(f"no tune to resume in {out}")
        # a tune saved before platforms were named ran on the KR500
        saved = {"platform": DEFAULT_PLATFORM, **json.loads(state.read_text())}
        if saved != identity:
            changed = sorted(k for k in identity if saved.get(k) != identity[k])
            raise ValueError(f"the tune in {out} has other settings ({', '.join(changed)})")
    atomic_write_json(state, identity)
    done = load_trials(trials_dir)
    remaining = tuning.trials - len(done)
    if remaining > 0:
        # Fly every training flight once, before the trials share them.
        for vehicle, seed in tuning.flights:
            motion_reference(training_spec(vehicle, seed), tuning.duration_s, cache_dir=flights_dir)
        with ray_session(workers, ray_address(address)):
            space = OptunaSearch.convert_search_space(search_space(tuning.mca))
            searcher = OptunaSearch(
                metric="objective",
                mode="min",
                sampler=replayed_sampler(tuning.seed, done, space),
                # A resume hands over every finished trial with its score; a new tune
                # starts at the shipped defaults.
                points_to_evaluate=[d["parameters"] for d in done] or [starting_point(tuning.mca)],
                evaluated_rewards=[d["objective"] for d in done] or None,
            )
            trainable = tune.with_parameters(
                _trial, tuning=tuning, flights_dir=str(flights_dir), trials_dir=str(trials_dir)
            )
            tuner = tune.Tuner(
                tune.with_resources(trainable, {"cpu": 1}),
                param_space=search_space(tuning.mca),
                tune_config=tune.TuneConfig(
                    search_alg=ConcurrencyLimiter(searcher, max_concurrent=workers),
                    num_samples=remaining,
                ),
                run_config=tune.RunConfig(
                    storage_path=str(out / "ray"),
                    name=f"run-{time.strftime('%Y%m%d-%H%M%S')}",
                    verbose=1 if progress else 0,
                ),
            )
            tuner.fit()
    return write_tuning_report(tuning, load_trials(trials_dir), out, command)


def write_tuning_report(
    tuning: TuningConfig, records: list[dict], out: Path, command: str = ""
) -> dict:
    """trials.csv, best.yaml, report.md, convergence.png and importance.png from the
    trial records (`load_trials`)."""
    import pandas as pd  # pandas (heavy; comes with ray[tune]) only for the report
    from pydrake.common.yaml import yaml_dump  # yaml writer of the scenario files

    if not records:
        raise RuntimeError(f"no finished trial in {out / 'trials'}")
    rows = []
    for r in records:
        row = {"trial": r["trial"]}
        row |= {f"config/{k}": v for k, v in r["parameters"].items()}
        row |= {k: r[k] for k in ("objective", "pi_median", "feasible", "why", "step_time_p99_s")}
        # (a trial file without the perceived measure has none)
        row["perceived_pi_median"] = r.get("perceived_pi_median", math.nan)
        row |= {"pi": json.dumps(r["pi"]), "pi_zero_motion": json.dumps(r["pi_zero_motion"])}
        # (a trial file without the false-rotation measure has none)
        row["false_rotation_deg_s"] = json.dumps(r.get("false_rotation_deg_s", []))
        rows.append(row)
    table = pd.DataFrame(rows)
    parameter_columns = sorted(c for c in table.columns if c.startswith("config/"))
    buffer = io.StringIO()
    table.to_csv(buffer, index=False)
    atomic_write_text(out / "trials.csv", buffer.getvalue())
    if not table["feasible"].any():
        raise RuntimeError(f"no feasible trial in {len(table)}: see {out / 'trials.csv'}")
    feasible = table[table["feasible"]].sort_values("objective")
    best_row = feasible.iloc[0]
    parameters = {c.removeprefix("config/"): float(best_row[c]) for c in parameter_columns}
    best = config_from_parameters(tuning.mca, parameters, tuning.nmpc_objective)
    baseline = baseline_config(tuning.mca, tuning.nmpc_objective)
    baseline_scores = score_config(baseline, tuning, out / "flights")
    best_pis = json.loads(best_row["pi"])
    zero = json.loads(best_row["pi_zero_motion"])
    date = datetime.date.today().isoformat()
    flights = ", ".join(f"{v} {s}" for v, s in tuning.flights)
    record = mca_config_record(best)
    raw = {"mca": {"_tag": f"!{record.pop('type')}", **record}}
    header = (
        f"# Tuned MCA config: {command or 'mca_drake.studies.tuning.run_tuning'}\n"
        f"# {date}; {len(table)} trials on platform {tuning.platform}; flights "
        f"({tuning.duration_s:g} s): {flights}\n"
        f"# median PI {best_row['pi_median']:.3f} (baseline "
        f"{np.median(baseline_scores['pi']):.3f}, zero motion {np.median(zero):.3f})\n"
        f'# Use: mca-drake run diagrams/closed_loop_dpc.yaml --set "$(cat best.yaml)"\n'
    )
    atomic_write_text(out / "best.yaml", header + yaml_dump(raw))
    report = {
        "mca": tuning.mca,
        "platform": tuning.platform,
        "date": date,
        "command": command,
        "trials": len(table),
        "feasible_trials": int(table["feasible"].sum()),
        "best_config": mca_config_record(best),
        "score": tuning.score,
        "best": {
            "pi_median": float(best_row["pi_median"]),
            "perceived_pi_median": _optional_float(best_row.get("perceived_pi_median")),
            "pi": best_pis,
            "false_rotation_deg_s": json.loads(best_row["false_rotation_deg_s"]),
        },
        "baseline": {
            "config": mca_config_record(baseline),
            "pi_median": float(np.median(baseline_scores["pi"])),
            "perceived_pi_median": baseline_scores["perceived_pi_median"],
            "pi": baseline_scores["pi"],
            "feasible": baseline_scores["feasible"],
            "false_rotation_deg_s": baseline_scores["false_rotation_deg_s"],
        },
        "zero_motion": {"pi_median": float(np.median(zero)), "pi": zero},
        "flights": [list(f) for f in tuning.flights],
        "duration_s": tuning.duration_s,
        "max_false_rotation_deg_s": tuning.max_false_rotation_deg_s,
    }
    atomic_write_json(out / "report.json", report)
    atomic_write_text(out / "report.md", _markdown(report, feasible, parameter_columns))
    save_figure(_convergence_figure(table), out / "convergence.png")
    save_figure(_importance_figure(feasible, parameter_columns), out / "importance.png")
    return report


def _perceived_line(report: dict) -> str:
    """The report's line on the perceived PI: what the trials were scored on and the best
    and baseline configs' median perceived PI."""
    best, base = report["best"]["perceived_pi_median"], report["baseline"]["perceived_pi_median"]
    scored = "the median perceived PI" if report["score"] == "perceived_pi" else "the median PI"
    figures = ""
    if best is not None:
        figures = f" Median perceived PI: best {best:.3f}, baseline {base:.3f}."
    return f"Trials scored on {scored}.{figures}"


def _markdown(report: dict, feasible, parameter_columns) -> str:
    lines = [
        f"# Tuning of {report['mca']} ({report['trials']} trials, {report['feasible_trials']} "
        f"feasible; {report['date']})",
        "",
        f"Command: `{report['command']}`" if report["command"] else "",
        "",
        f"Best median PI {report['best']['pi_median']:.3f}; baseline "
        f"{report['baseline']['pi_median']:.3f}; zero motion "
        f"{report['zero_motion']['pi_median']:.3f}.",
        _perceived_line(report),
        "",
        f"False rotation limit (median RMS over the flights): "
        f"{report['max_false_rotation_deg_s']:g} deg/s (0: none).",
        "",
        "| flight | best | baseline | zero motion | false rotation best, deg/s RMS | baseline |",
        "|---|---|---|---|---|---|",
    ]
    false_best = report["best"]["false_rotation_deg_s"] or [math.nan] * len(report["flights"])
    for (vehicle, seed), best, base, zero, false, false_base in zip(
        report["flights"],
        report["best"]["pi"],
        report["baseline"]["pi"],
        report["zero_motion"]["pi"],
        false_best,
        report["baseline"]["false_rotation_deg_s"],
        strict=True,
    ):
        lines.append(
            f"| {vehicle} {seed} | {best:.3f} | {base:.3f} | {zero:.3f} | {false:.1f} | "
            f"{false_base:.1f} |"
        )
    names = [c.removeprefix("config/") for c in parameter_columns]
    lines += [
        "",
        "Best trials:",
        "",
        "| objective | " + " | ".join(names) + " |",
        "|---" * (len(names) + 1) + "|",
    ]
    for _, row in feasible.head(5).iterrows():
        lines.append(
            f"| {row['objective']:.3f} | "
            + " | ".join(f"{row[c]:.4g}" for c in parameter_columns)
            + " |"
        )
    return "\n".join(lines) + "\n"


def _convergence_figure(table):
    import matplotlib.pyplot as plt  # matplotlib (heavy) only for the report

    fig, ax = plt.subplots(figsize=(7, 4))
    objective = table["objective"].to_numpy(dtype=float)
    ax.plot(np.arange(1, objective.size + 1), objective, "o", ms=3, label="trial")
    ax.plot(np.arange(1, objective.size + 1), np.minimum.accumulate(objective), label="best so far")
    ax.set_xlabel("trial")
    ax.set_ylabel("objective (median PI, + penalty if infeasible)")
    ax.legend()
    fig.tight_layout()
    return fig


def _importance_figure(feasible, parameter_columns):
    """|Spearman rank correlation| of each parameter with the objective over the feasible
    trials: a simple importance that needs no extra model."""
    import matplotlib.pyplot as plt  # matplotlib (heavy) only for the report

    names, values = [], []
    for column in parameter_columns:
        x = feasible[column].to_numpy(dtype=float)
        y = feasible["objective"].to_numpy(dtype=float)
        rho = spearmanr(x, y).statistic if x.size > 2 and np.ptp(x) > 0 else 0.0
        names.append(column.removeprefix("config/"))
        values.append(abs(float(np.nan_to_num(rho))))
    order = np.argsort(values)
    fig, ax = plt.subplots(figsize=(7, 0.35 * len(names) + 1.2))
    ax.barh([names[i] for i in order], [values[i] for i in order])
    ax.set_xlabel("|Spearman rho| with the objective (feasible trials)")
    fig.tight_layout()
    return fig
