"""Reference coverage statistics (`mca_drake.studies.coverage`) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.segments import SegmentDataset
from mca_drake.studies.coverage import dataset_reference_spread, spread, spread_markdown


def test_spread_of_a_sine_and_a_square_wave():
    t = np.arange(60_000) * 0.01  # 10 minutes at 100 Hz, whole periods
    y = np.zeros((t.size, 6))
    y[:, 0] = 0.2 * np.sin(2 * np.pi * 0.5 * t)  # std A / sqrt(2)
    y[:, 5] = np.where(np.sin(2 * np.pi * 0.25 * t) >= 0, 3.0, -3.0)  # |a_z| = 3 throughout
    s = spread(y, flights=2)
    assert s["flights"] == 2 and s["minutes"] == pytest.approx(10.0)
    assert s["std"][0] == pytest.approx(0.2 / np.sqrt(2), abs=1e-4)
    assert s["std"][5] == pytest.approx(3.0, abs=1e-3)
    assert s["a_z_p99"] == pytest.approx(3.0)
    assert s["std"][1:5] == [0.0] * 4


def test_dataset_spread_is_per_vehicle_of_the_flight_seeds():
    R = np.zeros((4, 10, 6))
    R[:2, :, 5] = np.array([1.0, -1.0] * 5)  # seed 7 (light): a_z std 1
    R[2:, :, 5] = np.array([2.0, -2.0] * 5)  # seed 8 (f16): a_z std 2
    zeros = lambda *s: np.zeros((4, 10, *s))  # noqa: E731
    arrays = {"U": zeros(6), "X": zeros(12), "Y": zeros(6), "R": R}
    arrays.update({k: zeros(4, 4) for k in ("F", "dF", "ddF")})
    source = np.array([[7, 0, 0], [7, 10, 0], [8, 0, 0], [8, 10, 1]])
    meta = {
        "source_columns": ["flight_seed", "start_step", "split"],
        "split_names": ["train", "validation", "test"],
        "flight_vehicles": {"7": "light", "8": "f16"},
    }
    table = dataset_reference_spread(SegmentDataset(arrays, source, meta))
    assert table["light"]["std"][5] == pytest.approx(1.0)
    assert table["f16"]["std"][5] == pytest.approx(2.0)
    assert table["all"]["flights"] == 2
    assert table["all"]["std"][5] == pytest.approx(np.sqrt(2.5), abs=1e-4)
    text = spread_markdown({"set": table})
    assert "| set | f16 | 1 |" in text
    del arrays["R"]
    with pytest.raises(ValueError, match="no references R"):
        dataset_reference_spread(SegmentDataset(arrays, source, meta))


def test_inside_share_counts_the_evaluation_samples_in_the_training_range():
    """Closed form: training uniform on [0, 1] (its 0.5-99.5 percentiles 0.005 and 0.995),
    evaluation uniform on [0.5, 1.5]: 49.5 % of it inside; a channel both span alike: all."""
    from mca_drake.studies.coverage import inside_share

    grid = np.linspace(0.0, 1.0, 100001)
    training = np.column_stack([grid] * 6)
    evaluation = training.copy()
    evaluation[:, 0] += 0.5
    shares = inside_share(training, evaluation)
    assert shares[0] == pytest.approx(0.495, abs=1e-3)
    assert shares[1:] == pytest.approx([0.99] * 5, abs=1e-3)  # both tails left out


def test_source_references_are_each_sources_training_recordings():
    from mca_drake.references.flights import training_recording
    from mca_drake.references.reference import reference_from_recording
    from mca_drake.studies.coverage import grouped_spread, source_references

    flights = [("light", 11), ("jet", 12)]
    for source in ("random-style", "synthetic"):
        grouped = source_references(source, flights, 5.0)
        assert set(grouped) == {"light", "jet"}
        expected = reference_from_recording(training_recording(source, "jet", 12, 5.0)).y
        np.testing.assert_array_equal(grouped["jet"][0], expected)
        assert grouped_spread(grouped)["all"]["flights"] == 2
    with pytest.raises(ValueError, match="unknown source"):
        training_recording("route", "light", 11, 5.0)
