"""The selection benchmark: every selection names files that exist and flights that
selection may fly, and says whether the shipped policy holds its place, on run summaries
built by hand."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest
from benchmark_scripts import load_benchmark

from mca_drake.cueing.dpc import DpcConfig
from mca_drake.references.drives import is_car
from mca_drake.references.jsbsim import UNSEEN_VEHICLES, check_vehicle


def test_every_selection_names_existing_policies_and_validation_vehicles():
    bench = load_benchmark("bench_selection")
    found = bench.selections()
    assert {"default", "light", "transport", "ground", "recognizer"} <= set(found)
    for name, selection in found.items():
        assert Path(bench.ROOT / selection.decision.split("#")[0]).is_file(), name
        for label, config in selection.mcas:
            assert isinstance(config, DpcConfig), label
            if config.policy:
                assert Path(config.policy).is_file(), (name, label)
        for vehicle in selection.vehicles:
            assert vehicle not in UNSEEN_VEHICLES  # kept for evaluation case C
            assert is_car(vehicle) or check_vehicle(vehicle) == vehicle


def _run(pi: float) -> dict:
    return {"pi": pi, "rmse": [0.0] * 6, "cc": [1.0] * 6, "safety_interventions": 0}


@pytest.mark.parametrize(("rival_pis", "holds"), [((-0.5, -0.7), True), ((-1.5, -0.7), False)])
def test_the_shipped_policy_holds_unless_an_alternative_is_better_by_median(
    monkeypatch, rival_pis, holds
):
    bench = load_benchmark("bench_selection")
    selection = bench.Selection(
        "docs/index.md", ("A4",), (("shipped", DpcConfig()), ("rival", DpcConfig()))
    )
    flights = [("A4", 700), ("A4", 701)]
    made = {
        "shipped": {flights[0]: _run(-1.0), flights[1]: _run(-1.0)},
        "rival": {f: _run(pi) for f, pi in zip(flights, rival_pis, strict=True)},
    }
    monkeypatch.setattr(bench, "run_flights", lambda *a, **k: made)
    args = argparse.Namespace(
        nmpc=False, seeds=2, out_dir="unused", duration=300.0, flights_dir="unused"
    )
    figures = bench.run_selection(selection, "human", args)
    assert figures["holds"] is holds
    assert figures["beaten_by"] == ([] if holds else ["rival"])
    assert figures["flights"] == ["A4 700", "A4 701"]


def test_keep_others_joins_the_files_other_selections_and_names_what_was_flown(tmp_path):
    """The file's selections this run did not fly are kept, each with the provenance of the
    run that flew it, never nested however often --keep-others runs; the ones flown replace
    theirs; a file of another flight duration, or none, is refused."""
    bench = load_benchmark("bench_selection")
    path = tmp_path / "selection.json"
    old = {"provenance": {"date": "then"}, "duration_s": 300.0}
    old["selections"] = {"light": {"holds": True}, "recognizer": {"holds": False}}
    path.write_text(json.dumps(old))
    figures, header = bench.kept_with(path, {"recognizer": {"holds": True}}, {"date": "now"}, 300)
    assert figures == {"light": {"holds": True}, "recognizer": {"holds": True}}
    assert header["flown_now"] == ["recognizer"] and header["date"] == "now"
    assert header["kept"] == {"light": {"date": "then"}}
    assert list(bench.kept_with(path, {"new": {}, "light": {}}, {}, 300)[0]) == [
        "light",
        "recognizer",
        "new",
    ]
    # a second run keeps light's first provenance and recognizer's from the second run
    path.write_text(json.dumps({"provenance": header, "duration_s": 300.0, "selections": figures}))
    _, again = bench.kept_with(path, {"new": {}}, {"date": "later"}, 300)
    assert again["kept"] == {"light": {"date": "then"}, "recognizer": {"date": "now"}}
    with pytest.raises(SystemExit, match="120"):
        bench.kept_with(path, {}, {}, 120.0)
    with pytest.raises(SystemExit, match="cannot read"):
        bench.kept_with(tmp_path / "none.json", {}, {}, 300.0)
