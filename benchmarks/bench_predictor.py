"""The reference predictors: fit the linear model, choose its ridge on validation flights,
train the learned correction on top of it, and measure their forecast errors against the
constant forecast.

    python benchmarks/bench_predictor.py [--duration 300] [--cache DIR] [--ship]

Training references (nothing here trains on validation seeds 700+ or evaluation seeds
1000+): every training aircraft flown by the scripted pilot (seeds 100-103) and by
random-style pilots (seeds 300-301), synthetic motion in each flight envelope (seeds
100-103) and the cars' training drives (seeds 100-103). The recipe (every source, all but
the synthetic motion, or the flights alone; the ridge) is the one that forecasts best on the
validation references, which also give the figures: the training and the validation
aircraft flown by the scripted and the human-operator pilots (seeds 700-701) and the cars'
drives (seeds 700-701).
The learned predictor trains on the chosen recipe's references and keeps the epoch that
forecasts the validation references best (`mca_drake.learning.predictor_training`).
The flights and drives carry their pilots' and drivers' controls and the vehicle's speed
and attitude (`Reference.signals`): the learned forecast reads them where given, and is
scored both ways, with the validation references' signals and with none (a source that
sends the motion alone).
Writes `results/predictor.json` (forecast RMSE per channel at 0.5, 1 and 2.5 s ahead, every
predictor, each ridge tried, the learned one's training time and loss curve) and, with
--ship, the packaged models `mca_drake/data/linear_predictor.npz` and
`mca_drake/data/learned_predictor.npz`.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import default_result_path, print_calibration, result_header, time_calls

from mca_drake.atomic_io import atomic_write_json
from mca_drake.conventions import CHANNELS, CONTROL_PERIOD_S
from mca_drake.cueing.learned_predictor import save_learned_predictor
from mca_drake.cueing.predictor import (
    DEFAULT_LAGS,
    PACKAGED_LEARNED_PREDICTOR,
    PACKAGED_LINEAR_PREDICTOR,
    constant_forecast,
    fit_linear_predictor,
    forecast_errors,
    history_samples,
    save_linear_predictor,
)
from mca_drake.learning.predictor_training import (
    LearnedPredictorConfig,
    train_learned_predictor,
)
from mca_drake.references.drives import TRAINING_MANOEUVRES, DriveSpec, motion_reference
from mca_drake.references.driving.car import CARS
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.references.jsbsim import TRAINING_VEHICLES, VALIDATION_VEHICLES
from mca_drake.references.reference import Reference
from mca_drake.references.synthetic import ENVELOPES, SyntheticConfig, synthetic_reference
from mca_drake.resources import data_dir

HORIZONS_S = (0.5, 1.0, 2.5)
STEPS = 256  # the NMPC's horizon, 2.56 s
RIDGES = (1e-2, 1e-1, 1.0)


def training_references(duration: float, cache=None) -> dict[str, Reference]:
    """{name: reference} of the training sources (module docstring); flights and drives
    kept in `cache` (a folder; None: none)."""
    found = {}
    for vehicle in TRAINING_VEHICLES:
        for seed in range(100, 104):
            spec = FlightSpec(vehicle=vehicle, seed=seed)
            found[f"{vehicle} {seed}"] = flight_reference(spec, duration, cache_dir=cache)
        for seed in (300, 301):
            spec = FlightSpec(vehicle=vehicle, seed=seed, pilot="random-style")
            found[f"{vehicle} {seed} random-style"] = flight_reference(
                spec, duration, cache_dir=cache
            )
    for envelope in ENVELOPES:
        for seed in range(100, 104):
            config = SyntheticConfig(envelope=envelope, duration_s=duration, seed=seed)
            found[f"synthetic {envelope} {seed}"] = synthetic_reference(config)
    for car in CARS:
        for seed in range(100, 104):
            spec = DriveSpec(manoeuvre=TRAINING_MANOEUVRES[seed % 2], seed=seed, car=car)
            found[f"{car} {seed}"] = motion_reference(spec, duration, cache_dir=cache)
    return found


def training_sets(training: dict) -> dict[str, list[str]]:
    """The training sets the recipe is chosen from: every source, every source but the
    synthetic motion, and the flights alone (scripted and random-style)."""
    every = sorted(training)
    return {
        "every source": every,
        "flights and drives": [n for n in every if not n.startswith("synthetic")],
        "flights": [n for n in every if n.split()[0] not in (*CARS, "synthetic")],
    }


def validation_references(duration: float, cache=None) -> dict[str, Reference]:
    """{name: reference} of the validation sources (module docstring), kept in `cache`."""
    found = {}
    for vehicle in (*TRAINING_VEHICLES, *VALIDATION_VEHICLES):
        for pilot in ("scripted", "human"):
            for seed in (700, 701):
                spec = FlightSpec(vehicle=vehicle, seed=seed, pilot=pilot)
                found[f"{vehicle} {seed} {pilot}"] = flight_reference(
                    spec, duration, cache_dir=cache
                )
    for car in CARS:
        for seed in (700, 701):
            spec = DriveSpec(manoeuvre="lap", seed=seed, car=car)
            found[f"{car} {seed}"] = motion_reference(spec, duration, cache_dir=cache)
    return found


def errors_table(errors: np.ndarray) -> dict:
    """{horizon s: {channel: RMSE}} of `forecast_errors` at HORIZONS_S."""
    return {
        f"{h:g}": {c: float(v) for c, v in zip(CHANNELS, row, strict=True)}
        for h, row in zip(HORIZONS_S, errors, strict=True)
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=300.0, help="s per reference")
    parser.add_argument("--ship", action="store_true", help="write the packaged model")
    parser.add_argument("--json", default=default_result_path("predictor.json"))
    parser.add_argument("--cache", help="folder that keeps the flights and drives for reruns")
    args = parser.parse_args()
    calibration = print_calibration()
    start = time.perf_counter()
    training = training_references(args.duration, args.cache)
    validation = validation_references(args.duration, args.cache)
    print(
        f"{len(training)} training and {len(validation)} validation references "
        f"({time.perf_counter() - start:.0f} s)",
        flush=True,
    )
    horizons = [round(h / CONTROL_PERIOD_S) for h in HORIZONS_S]
    history = history_samples(DEFAULT_LAGS)
    motion = [reference.y for reference in validation.values()]
    constant = forecast_errors(
        lambda h: constant_forecast(h, max(horizons)), motion, horizons, history=history
    )
    tried = {}
    best = None
    for sources, names in training_sets(training).items():
        for ridge in RIDGES:
            fit_start = time.perf_counter()
            model = fit_linear_predictor(
                [training[name].y for name in names],
                STEPS,
                ridge=ridge,
                metadata={
                    "training": names,
                    "sources": sources,
                    "command": "python benchmarks/bench_predictor.py --ship",
                },
            )
            fit_s = time.perf_counter() - fit_start
            errors = forecast_errors(model.forecast, motion, horizons, history=history)
            # the recipe that forecasts best relative to holding the sample, over every
            # channel and horizon (each channel counts alike, as in the PI)
            score = float(np.mean(errors / constant))
            tried[f"{sources}, ridge {ridge:g}"] = {
                "sources": sources,
                "ridge": ridge,
                "relative_rmse": score,
                "fit_s": fit_s,
                "rmse": errors_table(errors),
            }
            print(
                f"{sources}, ridge {ridge:g}: RMSE relative to constant {score:.3f} "
                f"(fit {fit_s:.1f} s)",
                flush=True,
            )
            if best is None or score < best[0]:
                best = (score, ridge, model, errors, sources)
    score, ridge, model, errors, sources = best
    learned, report = train_learned_predictor(
        model,
        [training[name] for name in model.metadata["training"]],
        list(validation.values()),
        LearnedPredictorConfig(),
        metadata={"command": "python benchmarks/bench_predictor.py --ship"},
        progress=lambda epoch, train, valid: print(
            f"learned, epoch {epoch}: loss {train:.4f} training, {valid:.4f} validation",
            flush=True,
        ),
    )
    print(
        f"learned: best epoch {report['best_epoch']} of {report['epochs_run']}, "
        f"{report['seconds']:.0f} s",
        flush=True,
    )
    ahead = max(horizons)
    learned_errors = forecast_errors(
        lambda h, s: learned.forecast(h, ahead, s),
        validation.values(),
        horizons,
        history=learned.history,
        signals=learned.signals,
        signal_history=learned.signal_history,
    )
    # the same forecast where the source sends the motion alone
    motion_only_errors = forecast_errors(
        lambda h: learned.forecast(h, ahead), motion, horizons, history=learned.history
    )
    # the linear and constant forecasts scored on the same samples as the learned one
    # (its longer history starts later in each reference)
    same_samples = {
        name: forecast_errors(f, motion, horizons, history=learned.history)
        for name, f in (
            ("constant", lambda h: constant_forecast(h, ahead)),
            ("linear", model.forecast),
        )
    }
    if args.ship:
        path = save_linear_predictor(data_dir() / PACKAGED_LINEAR_PREDICTOR, model)
        print(f"packaged model: {path}")
        path = save_learned_predictor(data_dir() / PACKAGED_LEARNED_PREDICTOR, learned)
        print(f"packaged model: {path}")
    result = {
        "provenance": result_header(calibration),
        "training": sorted(model.metadata["training"]),
        "chosen_sources": sources,
        "validation": sorted(validation),
        "duration_s": args.duration,
        "lags": list(DEFAULT_LAGS),
        "steps": STEPS,
        "chosen_ridge": ridge,
        "constant": {"rmse": errors_table(constant)},
        "linear": {
            "relative_rmse": score,
            "rmse": errors_table(errors),
            "forecast_time": forecast_time(model),
        },
        "learned": {
            "relative_rmse": float(np.mean(learned_errors / same_samples["constant"])),
            # the linear forecast's on the learned one's samples, to compare like with like
            "linear_relative_rmse": float(
                np.mean(same_samples["linear"] / same_samples["constant"])
            ),
            "rmse": errors_table(learned_errors),
            "signals": list(learned.signals),
            # reading no signals: where a source sends the motion alone
            "motion_only_relative_rmse": float(
                np.mean(motion_only_errors / same_samples["constant"])
            ),
            "motion_only_rmse": errors_table(motion_only_errors),
            "forecast_time": forecast_time(learned),
            "training_s": report["seconds"],
            "best_epoch": report["best_epoch"],
            "epochs_run": report["epochs_run"],
            "training_samples": report["training_samples"],
            "loss": report["loss"],
            "history_s": learned.history * CONTROL_PERIOD_S,
        },
        "ridges": tried,
    }
    atomic_write_json(args.json, result)
    for h, row_c, row_l in zip(HORIZONS_S, constant, errors, strict=True):
        cells = "  ".join(
            f"{c} {l:.3f}/{k:.3f}" for c, l, k in zip(CHANNELS, row_l, row_c, strict=True)
        )
        print(f"{h:g} s ahead, linear/constant RMSE: {cells}")
    print(
        f"relative RMSE on the learned one's samples: learned "
        f"{result['learned']['relative_rmse']:.3f} "
        f"({result['learned']['motion_only_relative_rmse']:.3f} reading no signals), linear "
        f"{result['learned']['linear_relative_rmse']:.3f}"
    )
    return 0


def forecast_time(model) -> dict:
    """A forecast's cost per control step (what a predictive MCA adds to its step), s."""
    history = np.zeros((model.history, len(CHANNELS)))
    if getattr(model, "signals", ()):  # with every signal it reads given
        signals = np.zeros((model.signal_history, len(model.signals)))
        timings = time_calls(lambda: model.forecast(history, STEPS - 1, signals), repeats=2000)
    else:
        timings = time_calls(lambda: model.forecast(history, STEPS - 1), repeats=2000)
    found = {"median_s": float(np.median(timings)), "p99_s": float(np.percentile(timings, 99))}
    print(
        f"forecast per step: median {found['median_s'] * 1e6:.0f} us, "
        f"p99 {found['p99_s'] * 1e6:.0f} us",
        flush=True,
    )
    return found


if __name__ == "__main__":
    raise SystemExit(main())
