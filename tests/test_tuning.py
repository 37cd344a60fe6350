"""MCA tuning on Ray Tune with Optuna: a tiny tune runs, resumes after a kill, and its
best config loads into a scenario and runs."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mca_drake.app.jobs import run_scenario
from mca_drake.app.scenarios import load_scenario
from mca_drake.cueing import NmpcConfig, WashoutConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.drives import training_spec
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.tuning import (
    TuningConfig,
    config_from_parameters,
    load_trials,
    run_tuning,
    search_space,
    starting_point,
)

KR500 = load_platform("kr500")

REPO = Path(__file__).resolve().parents[1]
# no false-rotation limit: what is tested here is the tune's machinery, whatever 2 s show
TINY = dict(trials=3, duration_s=2.0, flights=(("light", 100),), max_false_rotation_deg_s=0.0)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (dict(flights=(("light", 1000),)), "never trained or tuned on"),
        (dict(flights=(("bmw-320i", 4000),)), "never trained or tuned on"),
        (dict(flights=(("boeing", 100),)), "unknown vehicle 'boeing'"),
        (dict(flights=(("737", 100),)), "reserved for unseen-vehicle checks"),
        (dict(flights=(("T38", 100),)), "kept for evaluation case C"),
        (dict(mca="dpc"), "cannot tune 'dpc'"),
        (dict(trials=0), "trials must be at least 1"),
        (dict(flights=()), "flights is empty"),
        (dict(max_false_rotation_deg_s=-1.0), "max_false_rotation_deg_s"),
        (dict(score="felt"), "unknown score 'felt'"),
        (dict(nmpc_objective="felt"), "unknown NMPC objective 'felt'"),
    ],
)
def test_bad_tuning_settings_are_refused(change, match):
    with pytest.raises(ValueError, match=match):
        TuningConfig(**change).validate()


@pytest.mark.parametrize("mca", ["nmpc-rti", "washout"])
def test_every_point_of_the_space_is_a_valid_config(mca):
    """Corners of the search space build configs that validate."""
    space = search_space(mca)
    for corner in ("lower", "upper"):
        parameters = {name: getattr(domain, corner) for name, domain in space.items()}
        config = config_from_parameters(mca, parameters)
        config.validate()
        assert isinstance(config, NmpcConfig if mca == "nmpc-rti" else WashoutConfig)


@pytest.mark.parametrize("mca", ["nmpc-rti", "washout"])
def test_a_new_tune_starts_at_the_shipped_defaults(mca):
    """The first point of a new tune is the default config (inside the space, unchanged)."""
    config = config_from_parameters(mca, starting_point(mca))
    default = NmpcConfig(mode="rti") if mca == "nmpc-rti" else WashoutConfig()
    assert config == default


def test_a_config_over_the_false_rotation_limit_is_infeasible(tmp_path):
    """The limit reads the runs' false rotation (median RMS over the flights): the same
    config is feasible under a loose limit and infeasible, penalised and named, under one
    below what it made, whose figures the score reports per flight."""
    from mca_drake.studies.tuning import (
        FALSE_ROTATION_PENALTY_PER_LIMIT,
        INFEASIBLE_PENALTY,
        score_config,
    )

    flights = (("light", 100), ("jet", 100))
    config = NmpcConfig(mode="rti")
    loose = score_config(
        config,
        TuningConfig(duration_s=3.0, flights=flights, max_false_rotation_deg_s=1e3),
        tmp_path,
    )
    assert loose["feasible"] and loose["objective"] == loose["pi_median"]
    made = float(np.median(loose["false_rotation_deg_s"]))
    assert len(loose["false_rotation_deg_s"]) == 2 and made > 0
    tight = score_config(
        config,
        TuningConfig(duration_s=3.0, flights=flights, max_false_rotation_deg_s=0.5 * made),
        tmp_path,
    )
    assert not tight["feasible"] and "false rotation" in tight["why"]
    # at twice the limit: the flat penalty plus one limit's worth of the graded one
    assert tight["objective"] == pytest.approx(
        tight["pi_median"] + INFEASIBLE_PENALTY + FALSE_ROTATION_PENALTY_PER_LIMIT
    )
    assert tight["false_rotation_deg_s"] == pytest.approx(loose["false_rotation_deg_s"])


def test_trials_can_be_scored_on_the_perceived_pi(tmp_path):
    """score "perceived_pi": the objective is the median over the flights of the runs'
    perceived PI (their summaries' `perceived` block), which the score reports per flight;
    the NMPC of the trials takes the tune's objective."""
    from mca_drake.studies.tuning import score_config

    flights = (("light", 100), ("jet", 100), ("light", 101))
    tuning = TuningConfig(
        duration_s=3.0, flights=flights, score="perceived_pi", max_false_rotation_deg_s=0.0
    )
    scores = score_config(NmpcConfig(mode="rti"), tuning, tmp_path)
    assert scores["feasible"]
    assert scores["objective"] == pytest.approx(np.median(scores["perceived_pi"]))
    assert scores["objective"] == scores["perceived_pi_median"] != scores["pi_median"]
    assert len(scores["perceived_pi"]) == 3
    config = config_from_parameters("nmpc-rti", starting_point("nmpc-rti"), "perceived")
    assert config.objective == "perceived"


def test_a_car_in_the_flights_is_tuned_on_its_training_drive(tmp_path):
    """A car where an aircraft would be drives the manoeuvre its seed deals
    (`training_spec`): the trial scores the same run as the drive's reference through the
    closed loop directly, and the drive is kept in the study's folder."""
    from mca_drake.references.drives import motion_reference
    from mca_drake.studies.tuning import score_config

    tuning = TuningConfig(
        mca="washout", duration_s=4.0, flights=(("bmw-320i", 100),), max_false_rotation_deg_s=0
    )
    tuning.validate()
    scores = score_config(WashoutConfig(), tuning, tmp_path)
    spec = training_spec("bmw-320i", 100)
    assert spec.manoeuvre == "lap" and spec.car == "bmw-320i"
    assert training_spec("bmw-320i", 101).manoeuvre == "proving-ground"
    direct = run_closed_loop(
        mca=WashoutConfig(),
        reference=motion_reference(spec, 4.0),
        duration_s=4.0,
        progress=False,
        robot=KR500,
    ).summary
    assert scores["pi"] == [pytest.approx(direct["pi"])]
    assert scores["pi_zero_motion"] == [pytest.approx(direct["pi_zero_motion"])]
    assert list(tmp_path.glob("drive_lap_bmw-320i_*.csv"))


def _trial_results(out: Path) -> list[Path]:
    return list((out / "trials").glob("*.json"))


def test_a_killed_tune_resumes_and_its_best_config_runs(tmp_path):
    out = tmp_path / "tune"
    code = (
        "from mca_drake.studies.tuning import TuningConfig, run_tuning\n"
        f"run_tuning(TuningConfig(**{TINY!r}), {str(out)!r}, progress=False)\n"
    )
    job = subprocess.Popen([sys.executable, "-c", code], stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline and not _trial_results(out) and job.poll() is None:
        time.sleep(0.2)
    job.send_signal(signal.SIGKILL)
    job.wait(timeout=30)
    finished_before = len(_trial_results(out))
    assert 1 <= finished_before < 3, "the kill came too late to test a resume"
    with pytest.raises(ValueError, match="a tune exists"):
        run_tuning(TuningConfig(**TINY), out, progress=False)
    with pytest.raises(ValueError, match=r"other settings \(duration_s\)"):
        run_tuning(TuningConfig(**{**TINY, "duration_s": 3.0}), out, resume=True, progress=False)
    report = run_tuning(TuningConfig(**TINY), out, resume=True, progress=False)
    assert report["trials"] == 3
    assert not list(out.rglob("*.pkl")) or all(
        "ray" in p.relative_to(out).parts for p in out.rglob("*.pkl")
    )  # Ray's own pickles stay in its run folder and are never loaded
    table = (out / "trials.csv").read_text().splitlines()
    assert len(table) == 1 + 3
    for name in ("best.yaml", "report.md", "convergence.png", "importance.png"):
        assert (out / name).stat().st_size > 100
    # the best config is a scenario override that loads and runs
    scenario = load_scenario(
        REPO / "diagrams" / "closed_loop_dpc.yaml",
        [
            (out / "best.yaml").read_text(),
            f"{{plant: analytical, duration_s: 0.5, output_dir: {tmp_path}/run}}",
        ],
    )
    assert isinstance(scenario.mca, NmpcConfig)
    assert scenario.mca.output_weights == report["best_config"]["output_weights"]
    summary = run_scenario(scenario, progress=False)
    assert summary["mca_config"]["washout_weight"] == report["best_config"]["washout_weight"]


@pytest.mark.slow  # 37 s on 2 cores; the killed-tune test above covers resuming by default
def test_a_resumed_tune_draws_the_trials_of_an_uninterrupted_one(tmp_path):
    """Two trials, then a resume to three, against three in one go (one trial at a time):
    the same parameters, trial by trial; the sampler's state is replayed, not reseeded."""
    whole = run_tuning(TuningConfig(**TINY), tmp_path / "whole", progress=False)
    run_tuning(TuningConfig(**{**TINY, "trials": 2}), tmp_path / "split", progress=False)
    split = run_tuning(TuningConfig(**TINY), tmp_path / "split", resume=True, progress=False)
    assert whole and split
    drawn = [
        [r["parameters"] for r in load_trials(tmp_path / name / "trials")]
        for name in ("whole", "split")
    ]
    assert len(drawn[0]) == len(drawn[1]) == 3
    assert drawn[0] == drawn[1]


def test_a_tune_on_a_platform_scores_its_closed_loops_there(tmp_path):
    """Oracle: the closed loop run directly on the rail: a trial of a tune with
    platform kr500-rail scores exactly that run, not the KR500's."""
    from mca_drake.references.drives import motion_reference
    from mca_drake.studies.tuning import score_config

    tuning = TuningConfig(
        mca="washout",
        duration_s=3.0,
        flights=(("light", 100),),
        max_false_rotation_deg_s=0,
        platform="kr500-rail",
    )
    tuning.validate()
    scores = score_config(WashoutConfig(), tuning, tmp_path)
    reference = motion_reference(training_spec("light", 100), 3.0)
    on = {
        name: run_closed_loop(
            mca=WashoutConfig(),
            reference=reference,
            duration_s=3.0,
            progress=False,
            robot=load_platform(name),
        ).summary["pi"]
        for name in ("kr500-rail", "kr500")
    }
    assert scores["pi"] == [pytest.approx(on["kr500-rail"])]
    assert on["kr500-rail"] != on["kr500"]
    with pytest.raises(FileNotFoundError, match="kr5000"):
        TuningConfig(platform="kr5000").validate()


def test_a_platform_file_named_by_a_relative_path_is_tuned(tmp_path, monkeypatch):
    """Ray Tune runs each trial in a folder of its own: a platform file given relative to
    the folder the tune was started in must still be found (as `mca-drake tune --platform
    my-rig.yaml` in the rig guide)."""
    import shutil

    shutil.copy(REPO / "models" / "rig-3dof.yaml", tmp_path / "my-rig.yaml")
    monkeypatch.chdir(tmp_path)
    tuning = TuningConfig(**{**TINY, "trials": 1, "mca": "washout", "platform": "my-rig.yaml"})
    report = run_tuning(tuning, "tune", progress=False)
    assert report["platform"] == str(tmp_path / "my-rig.yaml")
    assert len(load_trials(tmp_path / "tune" / "trials")) == 1
