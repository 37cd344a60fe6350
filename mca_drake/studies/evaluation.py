"""Evaluation over a scenario set (the paper's Section VI-B, Fig. 3), with more MCAs:
running it.

For every case (`evaluation_cases`: Case A light-aircraft flights with seeds never used in
training, B jet flights, C aircraft used in neither training nor tuning, D drives, E the
route pilot) and every MCA config, the closed loop on the analytical plant of the suite's
platform is run over each flight (and, with a bound, the flight's offline-optimal bound);
per run the result summary is written as one JSON file, atomically. A re-run skips finished
runs of the same MCA config, duration, policy and platform, so a killed evaluation resumes.
The report (`evaluation_report.write_report`) is written from the run files at the end.
This module also gives the suite's public names of both.
"""

from __future__ import annotations

from pathlib import Path

from mca_drake.atomic_io import (
    atomic_write_json,
    check_writable,
)
from mca_drake.cueing import (
    McaConfig,
    mca_name,
)
from mca_drake.cueing.dpc import for_vehicle
from mca_drake.cueing.optimal import OptimalConfig
from mca_drake.platforms.files import PlatformField, load_platform
from mca_drake.references.drives import motion_reference
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.simulation.optimal_bound import run_optimal_bound
from mca_drake.studies.evaluation_cases import (
    BOUND,
    DEFAULT_MCAS,
    DRIVE_CARS,
    DRIVE_MANOEUVRES,
    ROUTE_VEHICLES,
    EvaluationCase,
    EvaluationConfig,
    default_cases,
    finished_bound,
    finished_run,
    policy_fingerprint,
    run_path,
    run_platform,
    same_config,
)
from mca_drake.studies.evaluation_report import (
    SIGNIFICANCE_LEVEL,
    dpc_test_key,
    evaluation_markdown,
    format_p,
    improvement_share,
    is_dpc_test,
    kept_entries,
    load_report,
    rank_sum_verdict,
    write_report,
)
from mca_drake.studies.parallel import run_tasks


def _run_one(
    config: McaConfig | OptimalConfig,
    case: EvaluationCase,
    seed: int,
    duration_s: float,
    out: str,
    platform: PlatformField,
) -> dict:
    """One flight of a case through an MCA, or its offline-optimal bound, on `platform`;
    its summary is written to the run's file."""
    out_dir = Path(out)
    robot = load_platform(platform)
    vehicle = case.vehicle_of(seed)
    reference = motion_reference(case.spec_of(seed), duration_s, cache_dir=out_dir / "flights")
    if isinstance(config, OptimalConfig):
        result = run_optimal_bound(
            reference=reference, config=config, duration_s=duration_s, robot=robot, progress=False
        )
    else:
        result = run_closed_loop(
            mca=config, reference=reference, duration_s=duration_s, robot=robot, progress=False
        )
    summary = {**result.summary, "case": case.name, "seed": seed, "vehicle": vehicle}
    summary["platform"] = robot.summary()
    fingerprint = policy_fingerprint(for_vehicle(config, vehicle), robot.name)
    if fingerprint:
        summary["policy_sha256"] = fingerprint
    atomic_write_json(run_path(out_dir, case.name, summary["mca"], seed), summary)
    return summary


def run_evaluation(
    config: EvaluationConfig,
    out_dir: str | Path,
    *,
    workers: int = 1,
    address: str | None = None,
    progress: bool = True,
    previous: dict | None = None,
) -> dict:
    """Runs every (case, MCA, flight) not yet on disk, then writes the report.

    Args:
        workers: CPUs of a local Ray (1: in this process).
        address: a Ray cluster to run on (`mca_drake.studies.parallel.run_tasks`).
        previous: an earlier report whose entries stand in for runs not on disk
            (`write_report`): a case's MCA it keeps, or its bound, is not run.
    """
    config.validate()
    platform = load_platform(config.platform).name
    out = Path(out_dir).resolve()  # a cluster's workers write here from folders of their own
    check_writable(out / "runs", folder=True)
    unfinished = {
        (c.name, mca_name(m)): [
            s for s in c.seeds if finished_run(out, c, m, s, config.duration_s, platform) is None
        ]
        for c in config.cases
        for m in config.mcas
    }
    kept: dict = {}
    if previous is not None:
        on_disk = {
            (c.name, mca_name(m)): set(c.seeds) - set(unfinished[(c.name, mca_name(m))])
            for c in config.cases
            for m in config.mcas
        }
        kept = kept_entries(config, on_disk, previous)
    tasks = [
        (mca, case, seed, config.duration_s, str(out), config.platform)
        for case in config.cases
        for seed in case.seeds
        for mca in config.mcas
        if (case.name, mca_name(mca)) not in kept and seed in unfinished[(case.name, mca_name(mca))]
    ]
    if config.bound is not None:
        tasks += [
            (config.bound, case, seed, config.duration_s, str(out), config.platform)
            for case in config.cases
            for seed in case.seeds
            if "bound" not in (previous or {}).get("cases", {}).get(case.name, {})
            and finished_bound(out, case.name, config.bound, seed, config.duration_s, platform)
            is None
        ]
    per_flight = len(config.mcas) + (config.bound is not None)
    total = sum(len(c.seeds) for c in config.cases) * per_flight
    run_tasks(
        _run_one,
        tasks,
        workers=workers,
        address=address,
        total=total,
        description="evaluation runs",
        unit="run",
        progress=progress,
    )
    return write_report(config, out, previous)


__all__ = [
    "BOUND",
    "DEFAULT_MCAS",
    "DRIVE_CARS",
    "DRIVE_MANOEUVRES",
    "ROUTE_VEHICLES",
    "SIGNIFICANCE_LEVEL",
    "EvaluationCase",
    "EvaluationConfig",
    "default_cases",
    "dpc_test_key",
    "evaluation_markdown",
    "finished_bound",
    "finished_run",
    "format_p",
    "improvement_share",
    "is_dpc_test",
    "kept_entries",
    "load_report",
    "policy_fingerprint",
    "rank_sum_verdict",
    "run_evaluation",
    "run_path",
    "run_platform",
    "same_config",
    "write_report",
]
