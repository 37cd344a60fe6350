"""The validation benchmark's comparison of two MCAs: the worst flight and where a PI
difference comes from, per channel, on run summaries built by hand."""

from __future__ import annotations

import numpy as np
import pytest
from benchmark_scripts import load_benchmark

from mca_drake.conventions import CHANNELS


def _run(pi: float, rmse, cc) -> dict:
    return {"pi": pi, "rmse": list(rmse), "cc": list(cc), "safety_interventions": 0}


def _runs():
    # flights a (PI -1.0 and -2.0) and b: the first MCA tracks f_y perfectly, the second
    # misses it by RMSE 0.1 and CC 0.3 on flight 1 and RMSE 0.2, CC 0.5 on flight 2 and
    # gains CC 0.1 on w_x on both
    zero, one = [0.0] * 6, [1.0] * 6
    first = {("A4", 1): _run(-1.0, zero, one), ("A4", 2): _run(-2.0, zero, one)}
    second = {
        ("A4", 1): _run(-0.6, [0, 0, 0, 0, 0.1, 0], [1.1, 1, 1, 1, 0.7, 1]),
        ("A4", 2): _run(-1.4, [0, 0, 0, 0, 0.2, 0], [1.1, 1, 1, 1, 0.5, 1]),
    }
    return {"first": first, "second": second}


def test_channel_differences_are_the_median_rmse_minus_cc_differences():
    bench = load_benchmark("bench_validation")
    runs = _runs()
    flights = list(runs["first"])
    split = bench.channel_differences(
        [runs["second"][k] for k in flights], [runs["first"][k] for k in flights]
    )
    assert list(split) == list(CHANNELS)
    # f_y: (0.1 + 0.3) and (0.2 + 0.5): median 0.55; w_x: -0.1 on both; the rest 0
    assert split["f_y"] == pytest.approx(0.55)
    assert split["w_x"] == pytest.approx(-0.1)
    for channel in ("w_y", "w_z", "f_x", "a_z"):
        assert split[channel] == pytest.approx(0.0)


def test_the_report_names_the_worst_flight_against_the_first_mca(capsys):
    bench = load_benchmark("bench_validation")
    runs = _runs()
    flights = list(runs["first"])
    figures = bench.report(runs, flights)
    paired = figures["second"]["paired_vs_first"]
    # differences +0.4 (flight 1) and +0.6 (flight 2)
    assert paired["worst_flight"] == "A4 2"
    assert paired["worst_difference"] == pytest.approx(0.6)
    assert paired["median_difference"] == pytest.approx(np.median([0.4, 0.6]))
    assert paired["better_on"] == 0
    assert paired["channel_differences"]["f_y"] == pytest.approx(0.55)
    printed = capsys.readouterr().out
    assert "worst flight A4 2 +0.600" in printed
    assert "f_y +0.550" in printed
