"""Closed-loop dataset generation at a tiny size: contents, resume, split."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.platforms import kinematics
from mca_drake.segments import SegmentDataset, split_of
from mca_drake.studies.closed_loop_dataset import (
    ClosedLoopDatasetConfig,
    flight_path,
    generate_closed_loop_dataset,
    join_datasets,
)

TINY = ClosedLoopDatasetConfig(flight_seeds=(1, 2), flight_duration_s=4.0, horizon=50)


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    out = tmp_path_factory.mktemp("closed_loop")
    return out, SegmentDataset.load(generate_closed_loop_dataset(TINY, out, progress=False))


def test_segments_are_the_plant_under_the_mca(generated, robot):
    _, data = generated
    assert len(data) == 2 * 8  # 400 steps per flight / 50
    X, U = data.X.astype(float), data.U.astype(float)
    h = 0.01
    np.testing.assert_allclose(X[:, 1:, 6:], X[:, :-1, 6:] + h * U[:, :-1], atol=1e-5)
    y = kinematics.plant_output(X[..., :6], X[..., 6:], U, robot)
    np.testing.assert_allclose(data.Y, y, atol=1e-4)
    assert data.R.shape == data.Y.shape
    assert np.all(np.abs(U) <= robot.qdd_max + 1e-6)
    assert data.metadata["config"]["mca"]["type"] == "NmpcConfig"
    assert data.metadata["config"]["mca"]["mode"] == "rti"


def test_rerun_skips_finished_flights(generated):
    out, _ = generated
    stamp = flight_path(out, 1).stat().st_mtime_ns
    flight_path(out, 2).unlink()  # as if the run had been killed before flight 2 finished
    generate_closed_loop_dataset(TINY, out, progress=False)
    assert flight_path(out, 1).stat().st_mtime_ns == stamp
    assert flight_path(out, 2).is_file()


def test_split_is_70_20_10_and_seeded(generated):
    _, data = generated
    parts = split_of(data)
    sizes = [len(parts[k]) for k in ("train", "validation", "test")]
    assert sum(sizes) == len(data)
    assert sizes == [11, 3, 2]  # round(0.7 * 16), round(0.9 * 16) - 11, rest


def test_bad_config():
    with pytest.raises(ValueError, match="unknown MCA"):
        generate_closed_loop_dataset(ClosedLoopDatasetConfig(mca="magic"), progress=False)


def test_long_windows_join_consecutive_segments_of_one_flight():
    from mca_drake.segments import SOURCE_COLUMNS, SegmentDataset, consecutive_runs, long_windows

    n_p, rows = 4, []
    # flight 7: steps 0, 4, 8, 12, 16 (one run of 5); flight 9: 0, 4, then a gap, 12, 16
    for flight, starts in ((7, (0, 4, 8, 12, 16)), (9, (0, 4, 12, 16))):
        rows += [(flight, s) for s in starts]
    J = len(rows)
    t = np.array([s for _, s in rows])[:, None] + np.arange(n_p)[None, :]
    U = np.repeat(t[..., None], 6, axis=2).astype(float)  # U encodes the time step
    zeros = {
        k: np.zeros((J, n_p, *s))
        for k, s in (("X", (12,)), ("Y", (6,)), ("F", (4, 4)), ("dF", (4, 4)), ("ddF", (4, 4)))
    }
    source = np.array([(f, s, 0) for f, s in rows])
    data = SegmentDataset({"U": U, **zeros}, source, {"source_columns": list(SOURCE_COLUMNS)})
    parts = long_windows(data, 2, fractions=(1.0, 0.0, 0.0))
    windows = parts["train"]
    # flight 7 gives 2 windows (segments 0-1, 2-3; the fifth is left over), flight 9 gives 2
    assert len(windows) == 4 and windows.horizon == 8
    for w in range(4):
        np.testing.assert_array_equal(np.diff(windows.U[w, :, 0]), 1.0)  # contiguous in time
    with pytest.raises(ValueError, match="no run of 9"):
        long_windows(data, 9)
    # the runs behind them, rows shuffled: flight 7 whole, flight 9 cut at its gap
    order = np.random.default_rng(0).permutation(J)
    shuffled = data.subset(order)
    runs = consecutive_runs(shuffled)
    starts = [shuffled.source[run, 1].tolist() for run in runs]
    flights = [set(shuffled.source[run, 0].tolist()) for run in runs]
    assert starts == [[0, 4, 8, 12, 16], [0, 4], [12, 16]]
    assert flights == [{7}, {9}, {9}]


def test_mixed_vehicle_sets_deal_seeds_and_keep_evaluation_seeds_out():
    config = ClosedLoopDatasetConfig(vehicles=("light", "f16"), flight_seeds=(5, 6, 7))
    config.validate()
    assert config.flights() == [("light", 5), ("f16", 6), ("light", 7)]
    # a flight's file is keyed by its own vehicle, not by the rest of the list
    other = ClosedLoopDatasetConfig(vehicles=("light", "A320"), flight_seeds=(5, 6, 7))
    assert config.flight_key("light") == other.flight_key("light")
    assert config.flight_key("light") != config.flight_key("f16")
    with pytest.raises(ValueError, match="evaluation flights"):
        ClosedLoopDatasetConfig(flight_seeds=(100, 1000)).validate()
    with pytest.raises(ValueError, match="repeat"):
        ClosedLoopDatasetConfig(flight_seeds=(100, 100)).validate()
    with pytest.raises(ValueError, match="reserved"):
        ClosedLoopDatasetConfig(vehicles=("light", "pa28")).validate()
    with pytest.raises(ValueError, match="kept for evaluation case C"):
        ClosedLoopDatasetConfig(vehicles=("light", "B747")).validate()


def test_join_keeps_every_segment_its_split_and_vehicle(generated, tmp_path):
    """The tiny set cut by flight into two files, joined again: the same segments, splits
    and flight_vehicles; a repeated flight or a file without vehicles is refused."""
    _, data = generated
    paths = []
    for seed in (1, 2):
        keep = data.source[:, 0] == seed
        meta = {
            **data.metadata,
            "flights": {str(seed): data.metadata["flights"][str(seed)]},
            "flight_vehicles": {str(seed): data.metadata["flight_vehicles"][str(seed)]},
        }
        part = SegmentDataset({k: v[keep] for k, v in data.arrays.items()}, data.source[keep], meta)
        paths.append(part.save(tmp_path / f"part{seed}.npz"))
    joined = SegmentDataset.load(join_datasets(paths, tmp_path / "joined.npz"))
    order = np.argsort(data.source[:, 0], kind="stable")
    np.testing.assert_array_equal(joined.source, data.source[order])
    for name, array in data.arrays.items():
        np.testing.assert_array_equal(joined.arrays[name], array[order], err_msg=name)
    assert joined.metadata["flight_vehicles"] == data.metadata["flight_vehicles"]
    assert set(joined.metadata["flights"]) == {"1", "2"}
    assert [j["path"] for j in joined.metadata["joined_from"]] == [str(p) for p in paths]
    with pytest.raises(ValueError, match="repeats flights"):
        join_datasets([paths[0], paths[0]], tmp_path / "twice.npz")
    bare = SegmentDataset(data.arrays, data.source, {})
    with pytest.raises(ValueError, match="flight_vehicles"):
        join_datasets([paths[0], bare.save(tmp_path / "bare.npz")], tmp_path / "bad.npz")
    with pytest.raises(ValueError, match="at least two"):
        join_datasets([paths[0]], tmp_path / "one.npz")


def test_each_flight_draws_its_source_with_the_configured_shares():
    """Over many seeds the sources come in the configured shares (binomial, 4 standard
    errors); a seed keeps its source whatever the other seeds; the defaults are all the
    scripted pilot's."""
    config = ClosedLoopDatasetConfig(random_style_share=0.3, synthetic_share=0.2)
    seeds = range(2000)
    sources = [config.flight_source(s) for s in seeds]
    for source, share in (("random-style", 0.3), ("synthetic", 0.2), ("scripted", 0.5)):
        count = sources.count(source)
        assert abs(count / len(seeds) - share) < 4 * np.sqrt(share * (1 - share) / len(seeds))
    assert {ClosedLoopDatasetConfig().flight_source(s) for s in seeds} == {"scripted"}
    with pytest.raises(ValueError, match="sum to at most 1"):
        ClosedLoopDatasetConfig(random_style_share=0.7, synthetic_share=0.4).validate()
    with pytest.raises(ValueError, match="non-negative"):
        ClosedLoopDatasetConfig(synthetic_share=-0.1).validate()


def test_a_mixed_set_cues_each_flights_own_reference(tmp_path):
    """A set with every source: each flight's segments carry the reference its source
    gives (the random-style pilot's flight, the synthetic motion), scaled as flights are."""
    from mca_drake.references.flights import FlightSpec, flight_recording
    from mca_drake.references.reference import reference_from_recording
    from mca_drake.references.synthetic import SyntheticConfig, synthetic_recording

    config = ClosedLoopDatasetConfig(
        flight_seeds=(1, 2, 3, 4, 5, 6),
        flight_duration_s=2.0,
        horizon=50,
        random_style_share=0.4,
        synthetic_share=0.4,
    )
    sources = {s: config.flight_source(s) for s in config.flight_seeds}
    assert set(sources.values()) == {"scripted", "random-style", "synthetic"}
    data = SegmentDataset.load(generate_closed_loop_dataset(config, tmp_path, progress=False))
    for seed, source in sources.items():
        if source == "synthetic":
            recording = synthetic_recording(SyntheticConfig(duration_s=2.0, seed=seed))
        else:
            recording = flight_recording(FlightSpec(seed=seed, pilot=source), 2.0)
        expected = reference_from_recording(recording, config.scaling).y[:200]
        mine = data.source[:, 0] == seed
        np.testing.assert_allclose(data.R[mine].reshape(-1, 6), expected, atol=1e-5)
        part = SegmentDataset.load(flight_path(tmp_path, seed))
        assert part.metadata["reference_source"] == source


def test_a_car_among_the_vehicles_drives_its_training_drive(tmp_path):
    """A car in `vehicles` drives the manoeuvre its seed deals (`training_spec`); its
    segments carry that drive's reference and its source is "drive", while the aircraft
    beside it fly as before."""
    from mca_drake.references.drives import drive_recording, training_spec
    from mca_drake.references.flights import FlightSpec, flight_recording
    from mca_drake.references.reference import reference_from_recording

    config = ClosedLoopDatasetConfig(
        vehicles=("light", "ford-escort"), flight_seeds=(10, 11), flight_duration_s=2.0, horizon=50
    )
    config.validate()
    assert [config.flight_source(s, v) for v, s in config.flights()] == ["scripted", "drive"]
    data = SegmentDataset.load(generate_closed_loop_dataset(config, tmp_path, progress=False))
    recordings = {
        10: flight_recording(FlightSpec(vehicle="light", seed=10), 2.0),
        11: drive_recording(training_spec("ford-escort", 11), 2.0),
    }
    for seed, recording in recordings.items():
        expected = reference_from_recording(recording, config.scaling).y[:200]
        mine = data.source[:, 0] == seed
        np.testing.assert_allclose(data.R[mine].reshape(-1, 6), expected, atol=1e-5)
    part = SegmentDataset.load(flight_path(tmp_path, 11))
    assert part.metadata["reference_source"] == "drive"
    assert part.metadata["vehicle"] == "ford-escort"
    with pytest.raises(ValueError, match="unknown vehicle 'trabant'"):
        ClosedLoopDatasetConfig(vehicles=("trabant",)).validate()
