"""A closed-loop dataset re-cued by the offline-optimal bound: each flight's segments carry
the bound's trajectory (exact steps across segment boundaries, the plant's outputs), the
references and split labels stay, no flight costs more than its MCA's, a killed run
resumes, bad datasets are refused, and none of it needs pydrake."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hidden_drake import PYDRAKE_LOADED, run_without_drake

from mca_drake.cueing.optimal import OptimalConfig, OptimalCueing
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.kinematics import plant_output
from mca_drake.segments import SOURCE_COLUMNS, SegmentDataset
from mca_drake.studies.bound_dataset import (
    bound_key,
    bound_path,
    flight_arrays,
    flight_rows,
    generate_bound_dataset,
    keep_flight_bound,
    solve_bound,
)

KR500 = load_platform("kr500")
N_P, SEGMENTS = 16, 3
REPO = Path(__file__).resolve().parents[1]


def _closed_loop_dataset(robot, seeds=(5, 6)) -> SegmentDataset:
    """Flights of SEGMENTS segments of N_P steps: a causal trajectory (slow sines in the
    joints' accelerations, from rest) and a reference it does not meet (its own outputs
    scaled up), cut as `dataset closed-loop` cuts them, rows of the flights interleaved."""
    T = N_P * SEGMENTS
    ocp = OptimalCueing(T, OptimalConfig(), robot)
    parts = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        t = 0.01 * np.arange(T)
        U = 0.05 * robot.qdd_max * np.sin(np.outer(t, rng.uniform(2, 6, 6)))
        x = ocp.states(np.zeros(12), U)[:-1]
        y = plant_output(x[:, :6], x[:, 6:], U, robot)
        rest = plant_output(np.zeros((1, 6)), np.zeros((1, 6)), np.zeros((1, 6)), robot)
        R = rest + 1.5 * (y - rest) + 0.2 * np.sin(3 * t)[:, None]
        zeros = np.zeros((T, 4, 4))
        arrays = {"U": U, "X": x, "Y": y, "F": zeros, "dF": zeros, "ddF": zeros, "R": R}
        cut = {
            k: v.reshape(SEGMENTS, N_P, *v.shape[1:]).astype(np.float32) for k, v in arrays.items()
        }
        source = np.column_stack(
            [np.full(SEGMENTS, seed), N_P * np.arange(SEGMENTS), np.arange(SEGMENTS) % 3]
        )
        parts.append(SegmentDataset(cut, source, {}))
    merged = SegmentDataset.concatenate(parts)
    order = np.random.default_rng(0).permutation(len(merged))  # rows out of time order
    merged = merged.subset(order)
    merged.metadata = {
        "kind": "closed-loop MCA dataset",
        "source_columns": list(SOURCE_COLUMNS),
        "config": {"mca": {"time_step": 0.01}},
    }
    return merged


def test_each_flight_carries_its_bound_and_keeps_its_segments(tmp_path, robot):
    source = _closed_loop_dataset(robot)
    path = source.save(tmp_path / "closed_loop.npz")
    config = OptimalConfig(max_iterations=4)
    out = generate_bound_dataset(path, tmp_path / "bound", config, progress=False)
    bound = SegmentDataset.load(out)
    np.testing.assert_array_equal(bound.source, source.source)
    np.testing.assert_array_equal(bound.arrays["R"], source.arrays["R"])
    ocp = OptimalCueing(N_P * SEGMENTS, config, robot)
    for seed, rows in flight_rows(bound).items():
        U = bound.arrays["U"][rows].reshape(-1, 6).astype(float)
        X = bound.arrays["X"][rows].reshape(-1, 12).astype(float)
        R = bound.arrays["R"][rows].reshape(-1, 6).astype(float)
        # the states are the exact steps of the inputs, across the segments' boundaries
        np.testing.assert_allclose(X, ocp.states(np.zeros(12), U)[:-1], atol=1e-5)
        y = plant_output(X[:, :6], X[:, 6:], U, robot)
        np.testing.assert_allclose(bound.arrays["Y"][rows].reshape(-1, 6), y, atol=1e-4)
        assert ocp.within_limits(np.zeros(12), U, tol=1e-6)
        figures = bound.metadata["bounds"][str(seed)]
        causal_U = source.arrays["U"][rows].reshape(-1, 6).astype(float)
        causal_cost = ocp.cost(np.zeros(12), causal_U, R)
        assert figures["start"] == "mca"
        assert figures["start_costs"]["mca"] == pytest.approx(causal_cost)
        assert figures["cost"] < causal_cost
        assert ocp.cost(np.zeros(12), U, R) == pytest.approx(figures["cost"], rel=1e-4)
    assert bound.metadata["kind"] == "offline-optimal bound dataset"
    assert bound.metadata["bound_config"]["max_iterations"] == 4


def test_a_killed_run_resumes_from_the_flights_it_finished(tmp_path, robot):
    path = _closed_loop_dataset(robot).save(tmp_path / "closed_loop.npz")
    config = OptimalConfig(max_iterations=2)
    out_dir = tmp_path / "bound"
    generate_bound_dataset(path, out_dir, config, progress=False)
    kept = bound_path(out_dir, 5)
    stamp = kept.stat().st_mtime_ns
    bound_path(out_dir, 6).unlink()  # as if killed before the second flight ended
    again = generate_bound_dataset(path, out_dir, config, progress=False)
    assert kept.stat().st_mtime_ns == stamp and bound_path(out_dir, 6).is_file()
    # other settings: solved again
    generate_bound_dataset(path, out_dir, OptimalConfig(max_iterations=1), progress=False)
    assert kept.stat().st_mtime_ns != stamp
    assert SegmentDataset.load(again).arrays["U"].shape == (2 * SEGMENTS, N_P, 6)


def test_a_flight_solved_from_its_arrays_elsewhere_is_kept_from_its_inputs(tmp_path, robot):
    dataset = _closed_loop_dataset(robot)
    path = dataset.save(tmp_path / "closed_loop.npz")
    config = OptimalConfig(max_iterations=3)
    out_dir = tmp_path / "bound"
    # "elsewhere": only the flight's arrays, through a plain npz, and only U comes back
    flight = flight_arrays(dataset, flight_rows(dataset)[5])
    np.savez(tmp_path / "flight.npz", **flight)
    with np.load(tmp_path / "flight.npz") as carried:
        result, figures = solve_bound(carried["R"], carried["U"], carried["x0"], config, KR500)
    key = bound_key(path, config)
    keep_flight_bound(dataset, 5, result.U, figures, config, key, out_dir, 1.0)
    kept = bound_path(out_dir, 5)
    stamp = kept.stat().st_mtime_ns
    merged = SegmentDataset.load(generate_bound_dataset(path, out_dir, config, progress=False))
    assert kept.stat().st_mtime_ns == stamp  # used, not solved again
    # the same as solving it here: a second folder solves both flights itself
    direct = SegmentDataset.load(
        generate_bound_dataset(path, tmp_path / "direct", config, progress=False)
    )
    for name in ("U", "X", "Y", "F", "R"):
        np.testing.assert_array_equal(merged.arrays[name], direct.arrays[name])
    assert merged.metadata["bounds"]["5"]["cost"] == pytest.approx(figures["cost"])
    assert merged.metadata["bounds"]["5"]["cost"] == direct.metadata["bounds"]["5"]["cost"]


def test_bound_inputs_that_do_not_fit_the_flight_are_refused(tmp_path, robot):
    dataset = _closed_loop_dataset(robot)
    config = OptimalConfig(max_iterations=1)
    T = N_P * SEGMENTS
    keep = (dataset, 5)
    for U, match in (
        (np.zeros((T - 1, 6)), "shape"),
        (np.full((T, 6), np.nan), "finite"),
        (np.tile(2 * robot.qdd_max, (T, 1)), "leave a joint limit"),
    ):
        with pytest.raises(ValueError, match=match):
            keep_flight_bound(*keep, U, {}, config, "key", tmp_path / "bound", 0.0)
    assert not bound_path(tmp_path / "bound", 5).exists()


def test_datasets_that_are_not_closed_loop_ones_are_refused(tmp_path, robot):
    dataset = _closed_loop_dataset(robot)
    no_references = SegmentDataset(
        {k: v for k, v in dataset.arrays.items() if k != "R"}, dataset.source, dataset.metadata
    )
    with pytest.raises(ValueError, match="no references R"):
        generate_bound_dataset(no_references.save(tmp_path / "a.npz"), tmp_path / "a")
    gap = dataset.subset(np.flatnonzero(dataset.source[:, 1] != N_P))
    with pytest.raises(ValueError, match="do not follow one another"):
        generate_bound_dataset(gap.save(tmp_path / "b.npz"), tmp_path / "b")
    other_step = SegmentDataset(dataset.arrays, dataset.source, dict(dataset.metadata))
    other_step.metadata["config"] = {"mca": {"time_step": 0.02}}
    with pytest.raises(ValueError, match="time step"):
        generate_bound_dataset(other_step.save(tmp_path / "c.npz"), tmp_path / "c")


# The bound dataset, made in a fresh interpreter without pydrake.
WITHOUT_DRAKE = f"""
from mca_drake.cueing.optimal import OptimalConfig
from mca_drake.studies.bound_dataset import generate_bound_dataset

config = OptimalConfig(max_iterations=1)
out = generate_bound_dataset(sys.argv[1], sys.argv[2], config, progress=False)
print(json.dumps({{"out": str(out), "pydrake_loaded": {PYDRAKE_LOADED}}}))
"""


def test_the_bound_dataset_is_made_without_pydrake(tmp_path, robot):
    path = _closed_loop_dataset(robot).save(tmp_path / "closed_loop.npz")
    result = run_without_drake(WITHOUT_DRAKE, [str(path), str(tmp_path / "bound")], REPO)
    assert result["pydrake_loaded"] == []
    assert len(SegmentDataset.load(result["out"])) == 2 * SEGMENTS


def test_the_command_writes_the_bound_dataset(tmp_path, robot, capsys):
    from mca_drake.app.cli import main  # the command line: pydrake's (dataset commands)

    path = _closed_loop_dataset(robot).save(tmp_path / "closed_loop.npz")
    out_dir = tmp_path / "bound"
    argv = ["dataset", "bound", str(path), "--out-dir", str(out_dir), "--max-iterations", "1"]
    assert main([*argv, "--quiet"]) == 0
    assert "bound dataset written to" in capsys.readouterr().out
    bound = SegmentDataset.load(out_dir / "dataset.npz")
    assert bound.metadata["bound_config"]["max_iterations"] == 1
    argv[-1] = "0"
    assert main(argv) != 0
    assert "max_iterations and qp_iterations must be at least 1" in capsys.readouterr().err
