"""Training data from the offline-optimal bound: a closed-loop dataset's flights re-cued by
the bound, for a DPC that learns what the best cue with hindsight does.

A closed-loop dataset (`mca-drake dataset closed-loop`) holds each flight as consecutive
segments of its causal MCA's trajectory and the reference it tracked (R). Here each flight
is put back together, its offline-optimal bound solved (`mca_drake.cueing.optimal`: the
whole flight known, every joint limit, the NMPC's tracking objective) from the MCA's own
trajectory (so never at a higher cost than the MCA's), and cut again into the same
segments: U, X, Y and the head pose (F, dF, ddF) are the bound's, R and the source table
(flight seed, start step, split label) are kept. `train-policy --targets achieved` on the
result tracks the bound's outputs, what the robot can render of the reference, instead of
the reference.

The flights are solved one per task (`studies.parallel`: in this process or on Ray), each
kept in `out_dir/bound_XXXXX.npz` as it finishes, so a killed run resumes; then merged into
`out_dir/dataset.npz`. Nothing here needs pydrake: the bound runs where only numpy, scipy
and the package are installed (a GPU machine's CPUs, say). A machine without the dataset
can solve flights from their arrays alone (`flight_arrays` here, `solve_bound` there); only
each bound's inputs U come back, and `keep_flight_bound` keeps them as a resumed run would.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import check_writable, file_sha256
from mca_drake.cueing.optimal import OptimalConfig, OptimalCueing, OptimalResult
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.kinematics import cut_trajectory
from mca_drake.platforms.serial import SerialChain
from mca_drake.segments import SOURCE_COLUMNS, SegmentDataset, dataset_platform, kept_file
from mca_drake.studies.parallel import run_tasks

KIND = "offline-optimal bound dataset"


def flight_rows(dataset: SegmentDataset) -> dict[int, np.ndarray]:
    """Each flight's segment rows in time order: seed -> row indices.

    Raises:
        ValueError: a dataset without references R or the closed-loop source table, or a
            flight whose segments do not follow one another from step 0.
    """
    if "R" not in dataset.arrays:
        raise ValueError("the dataset has no references R: not a closed-loop dataset")
    if list(dataset.metadata.get("source_columns", [])) != list(SOURCE_COLUMNS):
        raise ValueError(f"the dataset's source columns are not {list(SOURCE_COLUMNS)}")
    seeds, starts = dataset.source[:, 0], dataset.source[:, 1]
    n_p = dataset.horizon
    flights = {}
    for seed in np.unique(seeds):
        rows = np.flatnonzero(seeds == seed)
        rows = rows[np.argsort(starts[rows], kind="stable")]
        if not np.array_equal(starts[rows], n_p * np.arange(rows.size)):
            raise ValueError(
                f"flight {seed}'s segments do not follow one another from step 0 "
                f"(starts {starts[rows][:4].tolist()}...)"
            )
        flights[int(seed)] = rows
    return flights


def solve_bound(
    reference: np.ndarray,
    causal: np.ndarray,
    x0: np.ndarray,
    config: OptimalConfig,
    robot: SerialChain,
) -> tuple[OptimalResult, dict]:
    """The offline-optimal bound of one whole flight, from its arrays alone.

    The bound starts from `x0` and from the better (by the bound's cost) of the causal
    MCA's inputs and not moving. Needs only numpy, scipy and the package, so a flight can
    be solved on a machine that has no copy of the dataset.

    Args:
        reference: the flight's reference, shape (T, 6) (specific force m/s^2, angular
            velocity rad/s).
        causal: the causal MCA's joint accelerations, shape (T, 6), rad/s^2.
        x0: the first state [q, qd], shape (12,).
        config: the bound's settings.

    Returns:
        The solver's result (U (T, 6), states (T + 1, 12), ...) and its figures (start,
        start costs, cost, KKT residual, convergence, iterations, solve time) for the
        dataset's metadata.
    """
    reference = np.asarray(reference, dtype=float)
    causal = np.asarray(causal, dtype=float)
    x0 = np.asarray(x0, dtype=float)
    ocp = OptimalCueing(reference.shape[0], config, robot)
    starts = {"mca": causal, "no motion": np.zeros_like(causal)}
    costs = {}
    for name, U in starts.items():
        # the dataset's float32 inputs may leave a limit by round-off: such a start is
        # not used
        costs[name] = ocp.cost(x0, U, reference) if ocp.within_limits(x0, U) else np.inf
    start = min(costs, key=costs.get)
    result = ocp.solve(reference, U_start=starts[start], x0=x0)
    figures = {
        "start": start,
        "start_costs": {k: (None if not np.isfinite(v) else float(v)) for k, v in costs.items()},
        "cost": result.cost,
        "kkt_residual": result.kkt_residual,
        "converged": result.converged,
        "iterations": result.iterations,
        "solve_time_s": result.solve_time_s,
    }
    return result, figures


def flight_arrays(dataset: SegmentDataset, rows: np.ndarray) -> dict[str, np.ndarray]:
    """The flight made of `rows`, put back together: its reference R and causal inputs U,
    shape (T, 6) and (T, n) (float32, as stored), and its first state x0, shape (2n,), for
    a platform of n joints."""
    return {
        "R": dataset.arrays["R"][rows].reshape(-1, 6),
        "U": dataset.arrays["U"][rows].reshape(-1, dataset.arrays["U"].shape[-1]),
        "x0": dataset.arrays["X"][rows[0], 0],
    }


def bound_path(out_dir: Path, seed: int) -> Path:
    """Where one flight's bound is kept while the dataset is built."""
    return Path(out_dir) / f"bound_{seed:05d}.npz"


def keep_flight_bound(
    dataset: SegmentDataset,
    seed: int,
    U: np.ndarray,
    figures: dict,
    config: OptimalConfig,
    key: str,
    out_dir: str | Path,
    wall_time_s: float,
) -> Path:
    """Keeps flight `seed`'s bound in `out_dir` (`bound_path`), marked with `key`
    (`bound_key`) so that `generate_bound_dataset` uses it instead of solving it again.

    Only the bound's inputs cross from the solver: the states are the exact steps of `U`
    from the flight's first state, and the segments are cut as the flight's rows are (U,
    X, Y, F, dF, ddF, R; float32). So a flight solved elsewhere (`solve_bound` on a machine
    with the flight's arrays alone) is kept from its U and figures.

    Args:
        dataset: the closed-loop dataset the flight comes from.
        seed: the flight's seed.
        U: the bound's joint accelerations, rad/s^2, shape (T, 6) (T: the flight's steps).
        figures: `solve_bound`'s figures.
        config: the bound's settings it was solved with (its time step and limits).
        key: `bound_key` of the dataset file and the bound's settings.
        out_dir: the bound dataset's folder.
        wall_time_s: the solve's wall time, kept in the metadata.

    Raises:
        ValueError: U of the wrong shape, not finite, or leaving a joint limit.
    """
    rows = flight_rows(dataset)[seed]
    flight = flight_arrays(dataset, rows)
    U = np.asarray(U, dtype=float)
    if U.shape != flight["U"].shape or not np.all(np.isfinite(U)):
        raise ValueError(
            f"flight {seed}'s bound inputs must be finite, shape {flight['U'].shape}; "
            f"got shape {U.shape}"
        )
    robot = load_platform(dataset_platform(dataset.metadata))
    ocp = OptimalCueing(U.shape[0], config, robot)
    x0 = flight["x0"].astype(float)
    # the solver's own tolerance on the limits, with float32 round-off of x0
    if not ocp.within_limits(x0, U, tol=1e-6):
        raise ValueError(f"flight {seed}'s bound inputs leave a joint limit")
    states = ocp.states(x0, U)
    arrays = cut_trajectory(states[:-1], U, flight["R"].astype(float), robot, dataset.horizon)
    metadata = {
        "kind": f"{KIND}, one flight",
        "bound_key": key,
        "flight_seed": seed,
        "solver": figures,
        "wall_time_s": wall_time_s,
        "source_columns": list(SOURCE_COLUMNS),
    }
    part = SegmentDataset(arrays, dataset.source[rows].copy(), metadata)
    return part.save(bound_path(Path(out_dir), seed))


def bound_key(dataset_path: str | Path, config: OptimalConfig) -> str:
    """What a kept flight must have been made from: the source dataset file's content hash
    and the bound's settings."""
    record = json.dumps(dataclasses.asdict(config), sort_keys=True)
    return f"{file_sha256(dataset_path)}:{record}"


def _solve_one(dataset_path: str, seed: int, config: OptimalConfig, key: str, out: str) -> str:
    dataset = SegmentDataset.load(dataset_path)
    flight = flight_arrays(dataset, flight_rows(dataset)[seed])
    started = time.perf_counter()
    robot = load_platform(dataset_platform(dataset.metadata))
    result, figures = solve_bound(flight["R"], flight["U"], flight["x0"], config, robot)
    wall = time.perf_counter() - started
    return str(keep_flight_bound(dataset, seed, result.U, figures, config, key, out, wall))


def generate_bound_dataset(
    dataset_path: str | Path,
    out_dir: str | Path,
    config: OptimalConfig | None = None,
    *,
    workers: int = 1,
    address: str | None = None,
    progress: bool = True,
) -> Path:
    """Solves every flight's bound not yet kept in `out_dir`, then merges them.

    Args:
        dataset_path: a closed-loop dataset (.npz) with references R.
        out_dir: where the flights' bounds and the merged `dataset.npz` go.
        config: the bound's settings (default OptimalConfig(): the shipped NMPC's weights,
            30 Gauss-Newton iterations at most).
        workers: CPUs of a local Ray (1: one flight after the other, here).

    Returns:
        The merged file `out_dir/dataset.npz`: the source dataset's segments, split labels
        and references, with the bound's trajectories.

    Raises:
        ValueError: a dataset that is not a closed-loop one (see `flight_rows`) or whose
            time step is not the bound's.
    """
    config = config or OptimalConfig()
    config.validate()
    dataset_path = str(Path(dataset_path).resolve())
    dataset = SegmentDataset.load(dataset_path)
    flights = flight_rows(dataset)
    step = dataset.metadata.get("config", {}).get("mca", {}).get("time_step")
    if step is not None and abs(float(step) - config.time_step) > 1e-12:
        raise ValueError(
            f"the dataset's time step {step} s is not the bound's {config.time_step} s"
        )
    out_dir = check_writable(Path(out_dir).resolve(), folder=True)
    key = bound_key(dataset_path, config)
    todo = [
        (dataset_path, seed, config, key, str(out_dir))
        for seed in flights
        if not kept_file(bound_path(out_dir, seed), "bound_key", key)
    ]
    run_tasks(
        _solve_one,
        todo,
        workers=workers,
        address=address,
        total=len(flights),
        description="flight bounds",
        unit="flight",
        progress=progress,
    )
    parts = {seed: SegmentDataset.load(bound_path(out_dir, seed)) for seed in flights}
    # the source dataset's row order, so that each segment keeps its place and split label
    first = next(iter(parts.values())).arrays
    arrays = {name: np.empty((len(dataset), *a.shape[1:]), a.dtype) for name, a in first.items()}
    for seed, rows in flights.items():
        for name, array in arrays.items():
            array[rows] = parts[seed].arrays[name]
    metadata = {
        **{k: v for k, v in dataset.metadata.items() if k not in ("format",)},
        "kind": KIND,
        "bound_config": dataclasses.asdict(config),
        "bound_of": dataset_path,
        "bounds": {str(seed): part.metadata["solver"] for seed, part in parts.items()},
    }
    merged = SegmentDataset(arrays, dataset.source.copy(), metadata)
    return merged.save(out_dir / "dataset.npz")
