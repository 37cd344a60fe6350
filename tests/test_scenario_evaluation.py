"""Scenario-set evaluation: runs, resume, report with the rank-sum test and the box plot."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from mca_drake.cueing import DpcConfig, NmpcConfig, mca_config_from_name, mca_config_record
from mca_drake.cueing.dpc import for_vehicle
from mca_drake.cueing.optimal import OptimalConfig
from mca_drake.platforms.files import load_platform
from mca_drake.studies.evaluation import (
    EvaluationCase,
    EvaluationConfig,
    policy_fingerprint,
    run_evaluation,
)

KR500 = load_platform("kr500")


def test_small_suite_report_and_resume(tmp_path):
    config = EvaluationConfig(
        mcas=("nmpc-rti", "washout"),
        cases=(EvaluationCase("A", "light", (1000, 1001)),),
        duration_s=3.0,
    )
    report = run_evaluation(config, tmp_path, progress=False)
    case = report["cases"]["A"]
    assert set(case["mcas"]) == {"nmpc-rti", "washout"}
    for m in case["mcas"].values():
        assert m["runs"] == 2 and m["violations"] == 0 and len(m["pi"]) == 2
    assert (tmp_path / "evaluation.png").stat().st_size > 1000
    assert (tmp_path / "evaluation_perceived.png").stat().st_size > 1000
    assert "Case A" in (tmp_path / "evaluation.md").read_text()
    run = json.loads((tmp_path / "runs" / "A_washout_1001.json").read_text())
    assert run["mca"] == "washout" and run["seed"] == 1001
    # the false rotation of every run, and its median per MCA in the report
    false = [
        json.loads((tmp_path / "runs" / f"A_washout_{s}.json").read_text())["false_rotation"]
        for s in (1000, 1001)
    ]
    assert all(f["rms_deg_s"] >= 0 and 0 <= f["share_felt"] <= 1 for f in false)
    assert case["mcas"]["washout"]["false_rotation_median_deg_s"] == pytest.approx(
        np.median([f["rms_deg_s"] for f in false])
    )
    assert "deg/s |" in (tmp_path / "evaluation.md").read_text()
    # each channel's median RMSE and CC over the runs, as the PI's parts
    washout_runs = [
        json.loads((tmp_path / "runs" / f"A_washout_{s}.json").read_text()) for s in (1000, 1001)
    ]
    for key in ("rmse", "cc"):
        expected = np.median([r[key] for r in washout_runs], axis=0)
        np.testing.assert_allclose(case["mcas"]["washout"][f"{key}_median"], expected)
    for r in washout_runs:  # the parts add up to each run's PI
        assert sum(r["rmse"]) - sum(r["cc"]) == pytest.approx(r["pi"])
    m = case["mcas"]["washout"]
    w_x = f"| washout | {m['rmse_median'][0]:.3f} / {m['cc_median'][0]:.2f} |"
    assert w_x in (tmp_path / "evaluation.md").read_text()
    # a re-run reads every finished run back: same report, nothing simulated again
    stamp = (tmp_path / "runs" / "A_washout_1001.json").stat().st_mtime_ns
    again = run_evaluation(config, tmp_path, progress=False)
    assert again == json.loads(json.dumps(report))
    assert (tmp_path / "runs" / "A_washout_1001.json").stat().st_mtime_ns == stamp
    # runs of another MCA config (same name) or another duration are made again
    other = dataclasses.replace(
        config, mcas=(NmpcConfig(mode="rti", washout_weight=0.2), "washout"), duration_s=2.0
    )
    changed = run_evaluation(other, tmp_path, progress=False)
    assert "2 s per flight" in (tmp_path / "evaluation.md").read_text()
    assert (tmp_path / "runs" / "A_washout_1001.json").stat().st_mtime_ns != stamp
    run = json.loads((tmp_path / "runs" / "A_nmpc-rti_1000.json").read_text())
    assert run["mca_config"]["washout_weight"] == 0.2 and run["duration_s"] == 2.0
    assert changed["cases"]["A"]["mcas"]["nmpc-rti"]["pi"] != case["mcas"]["nmpc-rti"]["pi"]


def _write_runs(runs, pis: dict, perceived_pis: dict, seeds=(1000, 1001, 1002)) -> None:
    """Run files of case A's light flights `seeds`: per MCA name its PIs and perceived PIs
    (the DPC's steps 1000 times shorter than the others')."""
    runs.mkdir(exist_ok=True)
    base = {
        "duration_s": 300.0,
        "pi_zero_motion": 1.5,
        "joint_range_used": [0.1, 0.2, 0.05, 0.0, 0.3, 0.0],
        "violations": {"q": 0, "qd": 0, "qdd": 0},
        "safety_interventions": 0,
        "solver_failures": 0,
    }
    for mca, values in pis.items():
        config = for_vehicle(mca_config_from_name(mca), "light")  # as the suite runs it
        for seed, pi, felt in zip(seeds, values, perceived_pis[mca], strict=True):
            step = {"median": 5e-5 if mca == "dpc" else 5e-2, "max": 1e-1}
            run = {**base, "pi": pi, "step_time_s": step, "mca_config": mca_config_record(config)}
            run["perceived"] = {
                "pi": felt,
                "pi_zero_motion": 1.0,
                "false_cue_share": [0.1 * seed % 7] * 6,
                "sickness": {
                    "simulator": {"conflict_rms_m_s2": 0.1, "msi_final_percent": 0.5},
                    "reference": {"conflict_rms_m_s2": 0.2, "msi_final_percent": 0.7},
                },
            }
            if mca == "dpc":
                run["policy_sha256"] = policy_fingerprint(config, "kr500")
            (runs / f"A_{mca}_{seed}.json").write_text(json.dumps(run))


def test_rank_sum_is_reported_between_dpc_and_converged(tmp_path):
    from mca_drake.studies.evaluation import write_report

    pis = {"dpc": [-1.0, -1.1, -0.9], "nmpc-converged": [-1.2, -1.0, -1.1]}
    perceived_pis = {"dpc": [-2.0, -2.3, -2.1], "nmpc-converged": [-1.9, -2.0, -1.5]}
    _write_runs(tmp_path / "runs", pis, perceived_pis)
    config = EvaluationConfig(
        mcas=("dpc", "nmpc-converged"), cases=(EvaluationCase("A", "light", (1000, 1001, 1002)),)
    )
    report = write_report(config, tmp_path)
    test = report["cases"]["A"]["dpc_vs_nmpc_converged"]
    from scipy.stats import ranksums

    z, p = ranksums(pis["dpc"], pis["nmpc-converged"])
    assert test["z"] == pytest.approx(z) and test["p"] == pytest.approx(p)
    assert test["significant"] == (p < 0.05)
    assert test["median_gap"] == pytest.approx(-1.0 - (-1.1))
    assert test["step_time_ratio"] == pytest.approx(1000.0)
    # paired on the same three flights: differences +0.2, -0.1, +0.2 (DPC better once)
    from scipy.stats import wilcoxon

    paired = test["paired"]
    assert paired["seeds"] == [1000, 1001, 1002] and paired["dpc_better"] == 1
    assert paired["median_difference"] == pytest.approx(0.2)
    assert paired["p"] == pytest.approx(wilcoxon(pis["dpc"], pis["nmpc-converged"]).pvalue)
    # DPC's worst flight: +0.2 on two flights (1000 and 1002, equal but for rounding)
    assert paired["worst_difference"] == pytest.approx(0.2)
    assert paired["worst_seed"] in (1000, 1002)
    # the same tests on the perceived PI
    felt = test["perceived"]
    z, p = ranksums(perceived_pis["dpc"], perceived_pis["nmpc-converged"])
    assert felt["z"] == pytest.approx(z) and felt["p"] == pytest.approx(p)
    assert felt["median_gap"] == pytest.approx(-2.1 - (-1.9))
    assert felt["paired"]["dpc_better"] == 3
    # perceived differences -0.1, -0.3, -0.6: DPC better everywhere, least on 1000
    assert felt["paired"]["worst_seed"] == 1000
    assert felt["paired"]["worst_difference"] == pytest.approx(-0.1)
    expected = wilcoxon(perceived_pis["dpc"], perceived_pis["nmpc-converged"]).pvalue
    assert felt["paired"]["p"] == pytest.approx(expected)
    dpc = report["cases"]["A"]["mcas"]["dpc"]
    assert dpc["perceived_pi_median"] == pytest.approx(-2.1)
    assert dpc["false_cue_share_median"] == pytest.approx([0.1 * 1001 % 7] * 6)
    markdown = (tmp_path / "evaluation.md").read_text()
    assert "Paired on the 3 flights both ran: DPC better on 1" in markdown
    assert "Paired on the 3 flights both ran: DPC better on 3" in markdown
    assert "DPC's worst flight against it: 1000, -0.100." in markdown
    assert "Perceived PI: rank-sum" in markdown
    assert "Incomplete" not in markdown
    # a fourth flight that neither has run: the report says so and how to resume
    four = dataclasses.replace(
        config, cases=(EvaluationCase("A", "light", (1000, 1001, 1002, 1003)),)
    )
    write_report(four, tmp_path)
    markdown = (tmp_path / "evaluation.md").read_text()
    assert "| dpc | 3 of 4 |" in markdown and "Incomplete: dpc, nmpc-converged" in markdown
    # an MCA with no finished run at all is named as well
    more = dataclasses.replace(config, mcas=("dpc", "nmpc-converged", "washout"))
    write_report(more, tmp_path)
    assert "Incomplete: washout" in (tmp_path / "evaluation.md").read_text()


def test_dpc_runs_of_another_policy_are_run_again(tmp_path):
    import hashlib

    import torch

    from mca_drake.learning.policy_network import PolicyNetwork, save_policy

    torch.manual_seed(3)
    other = tmp_path / "other_policy.npz"
    save_policy(other, PolicyNetwork(KR500), {"model": "dpc-policy"})
    case = EvaluationCase("A", "light", (1000,))
    out = tmp_path / "eval"
    shipped = EvaluationConfig(mcas=("dpc",), cases=(case,), duration_s=2.0)
    first = run_evaluation(shipped, out, progress=False)
    run_file = out / "runs" / "A_dpc_1000.json"
    # the light aircraft's flight ran the policy of its envelope
    light = policy_fingerprint(DpcConfig(vehicle="light"), "kr500")
    assert (
        json.loads(run_file.read_text())["policy_sha256"]
        == light
        != policy_fingerprint(DpcConfig(), "kr500")
    )
    # the report records the default policy's (an unnamed reference's DPC starts with it)
    assert first["policy_sha256"] == policy_fingerprint(DpcConfig(unnamed="default"), "kr500")
    # the other policy's evaluation re-runs the flight and records the other file's hash
    second = run_evaluation(
        EvaluationConfig(mcas=(DpcConfig(policy=str(other)),), cases=(case,), duration_s=2.0),
        out,
        progress=False,
    )
    digest = hashlib.sha256(other.read_bytes()).hexdigest()
    assert json.loads(run_file.read_text())["policy_sha256"] == digest
    assert second["cases"]["A"]["mcas"]["dpc"]["pi"] != first["cases"]["A"]["mcas"]["dpc"]["pi"]
    # a report for the shipped policy now has no DPC run to show, rather than a stale one
    from mca_drake.studies.evaluation import write_report

    assert "dpc" not in write_report(shipped, out)["cases"]["A"]["mcas"]


def test_a_kept_report_stands_in_for_the_runs_not_on_disk(tmp_path):
    """With the previous report, an NMPC without runs keeps its entry (same duration and
    config) and the DPC's tests against it are those of its per-flight figures (scipy);
    its bound is kept and the re-run DPC's share is computed against it."""
    from scipy.stats import ranksums, wilcoxon

    from mca_drake.studies.evaluation import load_report, write_report

    pis = {"dpc": [-1.0, -1.1, -0.9], "nmpc-converged": [-1.2, -1.0, -1.1]}
    perceived_pis = {"dpc": [-2.0, -2.3, -2.1], "nmpc-converged": [-1.9, -2.0, -1.5]}
    _write_runs(tmp_path / "runs", pis, perceived_pis)
    case = EvaluationCase("A", "light", (1000, 1001, 1002))
    bound = OptimalConfig()  # its runs are not on disk either
    config = EvaluationConfig(mcas=("dpc", "nmpc-converged"), cases=(case,), bound=bound)
    previous = write_report(config, tmp_path)
    previous["cases"]["A"]["bound"] = {
        "runs": 3,
        "seeds": [1000, 1001, 1002],
        "pi": [-2.5, -3.0, -2.0],
        "pi_median": -2.5,
        "kkt_residual_max": 1e-4,
        "solve_time_median_s": 400.0,
    }
    previous["cases"]["A"]["shares"] = {"nmpc-converged": {"share": [0.7], "share_median": 0.7}}
    (tmp_path / "evaluation.json").write_text(json.dumps(previous))
    # the DPC is run again with a better policy; the NMPC's runs are gone
    for seed in (1000, 1001, 1002):
        (tmp_path / "runs" / f"A_nmpc-converged_{seed}.json").unlink()
    new_dpc = {"dpc": [-1.3, -1.4, -1.2]}
    _write_runs(tmp_path / "runs", new_dpc, {"dpc": [-2.2, -2.4, -2.3]})
    report = write_report(config, tmp_path, load_report(tmp_path / "evaluation.json"))
    a = report["cases"]["A"]
    kept = a["mcas"]["nmpc-converged"]
    assert json.dumps(kept) == json.dumps(previous["cases"]["A"]["mcas"]["nmpc-converged"])
    assert a["mcas"]["dpc"]["pi"] == new_dpc["dpc"]
    test = a["dpc_vs_nmpc_converged"]
    z, p = ranksums(new_dpc["dpc"], pis["nmpc-converged"])
    assert test["z"] == pytest.approx(z) and test["p"] == pytest.approx(p)
    paired = wilcoxon(new_dpc["dpc"], pis["nmpc-converged"]).pvalue
    assert test["paired"]["p"] == pytest.approx(paired) and test["paired"]["dpc_better"] == 3
    felt = wilcoxon([-2.2, -2.4, -2.3], perceived_pis["nmpc-converged"]).pvalue
    assert test["perceived"]["paired"]["p"] == pytest.approx(felt)
    assert a["bound"] == previous["cases"]["A"]["bound"]
    assert a["shares"]["nmpc-converged"]["share"] == [0.7]
    bound = [-2.5, -3.0, -2.0]
    expected = [(1.5 - pi) / (1.5 - b) for pi, b in zip(new_dpc["dpc"], bound, strict=True)]
    assert a["shares"]["dpc"]["share"] == pytest.approx(expected)
    # an MCA of another config is not stood in for; nor is any report of another duration
    other = dataclasses.replace(
        config, mcas=("dpc", NmpcConfig(mode="converged", washout_weight=0.2))
    )
    assert "nmpc-converged" not in write_report(other, tmp_path, previous)["cases"]["A"]["mcas"]
    with pytest.raises(ValueError, match="not one of 60 s flights"):
        write_report(dataclasses.replace(config, duration_s=60.0), tmp_path, previous)
    (tmp_path / "broken.json").write_text("[1, 2]")
    with pytest.raises(ValueError, match="not a suite report"):
        load_report(tmp_path / "broken.json")


def test_training_seeds_are_refused():
    with pytest.raises(ValueError, match="must be evaluation seeds"):
        EvaluationConfig(cases=(EvaluationCase("A", "light", (100, 1000)),)).validate()
    with pytest.raises(ValueError, match="a flight seed repeats"):
        EvaluationConfig(cases=(EvaluationCase("A", "light", (1000, 1000)),)).validate()
    with pytest.raises(ValueError, match="reserved"):
        EvaluationConfig(cases=(EvaluationCase("C", "", (3000,), vehicles=("737",)),)).validate()
    with pytest.raises(ValueError, match="unknown MCA"):
        EvaluationConfig(mcas=("lqr",)).validate()
    with pytest.raises(ValueError, match="share a name"):
        EvaluationConfig(mcas=("nmpc-rti", NmpcConfig(washout_weight=0.3))).validate()


def test_report_wording_of_p_values_and_verdicts():
    from mca_drake.studies.evaluation import format_p, rank_sum_verdict

    assert format_p(0.0004) == "p < 0.001"
    # three figures, so a p just under 0.05 does not print as 0.050
    assert format_p(0.0499) == "p = 0.0499" and format_p(0.745) == "p = 0.745"
    apart = {"alpha": 0.05, "significant": True}
    assert (
        rank_sum_verdict({"z": -0.3, "alpha": 0.05, "significant": False})
        == "no significant difference at 0.05"
    )
    # lower PI is better: DPC ranked lower (z < 0) is the better side
    assert rank_sum_verdict({**apart, "z": -2.2}) == "significant at 0.05: DPC better"
    assert rank_sum_verdict({**apart, "z": 2.2}) == "significant at 0.05: DPC worse"


def test_case_c_deals_unseen_aircraft_to_its_seeds():
    from mca_drake.references.jsbsim import TRAINING_VEHICLES, UNSEEN_VEHICLES
    from mca_drake.studies.evaluation import default_cases

    case = {c.name: c for c in default_cases()}["C"]
    flown = [case.vehicle_of(seed) for seed in case.seeds]
    assert flown[:4] == list(UNSEEN_VEHICLES) and flown[4] == UNSEEN_VEHICLES[0]
    assert not set(flown) & set(TRAINING_VEHICLES)
    assert case.label() == ", ".join(UNSEEN_VEHICLES)


@pytest.mark.parametrize("text", ["[1, 2]", "3.5", '"summary"', "null"])
def test_a_run_file_that_is_not_an_object_is_run_again(tmp_path, text):
    """Valid JSON that is no summary (a list, a number, a string) does not stop the suite:
    the run counts as not finished, so it is simulated again and the file overwritten."""
    from mca_drake.cueing import WashoutConfig
    from mca_drake.studies.evaluation import finished_run, run_path

    path = run_path(tmp_path, "A", "washout", 1000)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    assert (
        finished_run(
            tmp_path, EvaluationCase("A", "light", (1000,)), WashoutConfig(), 1000, 5.0, "kr500"
        )
        is None
    )


def test_a_run_older_than_a_config_field_matches_that_fields_default():
    """A run file whose record lacks a field (made before it existed) counts as made with
    its default: it is reused for a config at the default, run again for any other value;
    a record with a field the config no longer has is another config."""
    from mca_drake.studies.evaluation import same_config

    config = NmpcConfig(mode="rti")
    older = mca_config_record(config)
    del older["preview_steps"]
    assert same_config(older, config)
    assert not same_config(older, NmpcConfig(mode="rti", preview_steps=10))
    assert not same_config({**older, "horizon_seconds": 2.56}, config)
    assert not same_config(older, NmpcConfig(mode="converged"))
    assert not same_config(None, config)


def test_the_suite_reports_the_bound_and_each_mcas_share(tmp_path):
    """With a bound, each flight's offline-optimal bound is solved, cached like the runs
    (a resumed suite reuses it), and every MCA's share of the achievable improvement is
    (PI_zero - PI) / (PI_zero - PI_bound) on its flights."""
    from mca_drake.cueing.optimal import OptimalConfig

    config = EvaluationConfig(
        mcas=("nmpc-rti", "washout"),
        cases=(EvaluationCase("A", "light", (1000, 1001)),),
        duration_s=1.0,
        bound=OptimalConfig(max_iterations=4),
    )
    report = run_evaluation(config, tmp_path, progress=False)
    case = report["cases"]["A"]
    bound = case["bound"]
    assert bound["runs"] == 2 and len(bound["pi"]) == 2
    for mca in ("nmpc-rti", "washout"):
        runs = {
            seed: json.loads((tmp_path / "runs" / f"A_{mca}_{seed}.json").read_text())
            for seed in (1000, 1001)
        }
        expected = [
            (runs[s]["pi_zero_motion"] - runs[s]["pi"]) / (runs[s]["pi_zero_motion"] - b)
            for s, b in zip((1000, 1001), bound["pi"], strict=True)
        ]
        assert case["shares"][mca]["share"] == pytest.approx(expected)
    assert "Offline-optimal bound" in (tmp_path / "evaluation.md").read_text()
    path = tmp_path / "runs" / "A_optimal_1000.json"
    stamp = path.stat().st_mtime_ns
    run_evaluation(config, tmp_path, progress=False)  # resumed: nothing solved again
    assert path.stat().st_mtime_ns == stamp
    # the washout's runs gone, the report kept: it is not run again, its entry and share
    # stand, and the bound solved on disk serves the others' shares
    for seed in (1000, 1001):
        (tmp_path / "runs" / f"A_washout_{seed}.json").unlink()
    again = run_evaluation(config, tmp_path, progress=False, previous=report)
    assert not list((tmp_path / "runs").glob("A_washout_*.json"))
    assert path.stat().st_mtime_ns == stamp
    kept = again["cases"]["A"]
    assert json.dumps(kept["mcas"]["washout"]) == json.dumps(case["mcas"]["washout"])
    assert kept["shares"] == case["shares"] and kept["bound"] == bound


def test_case_d_drives_cars_through_its_manoeuvres(tmp_path):
    """Case D deals cars and manoeuvres to its seeds; its runs cue drives (cached like
    flights) and report like every case."""
    from mca_drake.references.drives import DriveSpec
    from mca_drake.studies.evaluation import DRIVE_CARS, DRIVE_MANOEUVRES, default_cases

    case = {c.name: c for c in default_cases()}["D"]
    specs = [case.spec_of(seed) for seed in case.seeds]
    assert all(isinstance(s, DriveSpec) for s in specs)
    assert [s.car for s in specs[:3]] == list(DRIVE_CARS)
    assert [s.manoeuvre for s in specs[:2]] == list(DRIVE_MANOEUVRES)
    assert "drives" in case.label()
    small = EvaluationCase("D", "", (4000, 4001), vehicles=DRIVE_CARS, manoeuvres=DRIVE_MANOEUVRES)
    config = EvaluationConfig(mcas=("washout",), cases=(small,), duration_s=2.0)
    report = run_evaluation(config, tmp_path, progress=False)
    assert report["cases"]["D"]["mcas"]["washout"]["runs"] == 2
    cached = sorted(p.name for p in (tmp_path / "flights").iterdir())
    assert cached == [
        "drive_lap_ford-escort_B_0.1_0.37_0.55_4001_2s.csv",
        "drive_proving-ground_bmw-320i_B_0.1_0.37_0.55_4000_2s.csv",
    ]


def test_a_scenario_spells_the_suites_cases_as_one_list(tmp_path):
    """The packaged suite scenario's `cases` are the study's default cases A-E, field by
    field; a scenario file of its own cases (one the suite does not have) gives those; the
    old per-case fields are refused with the new spelling named."""
    from mca_drake.app.scenarios import EvaluationScenario, load_scenario
    from mca_drake.studies.evaluation_cases import EvaluationCase, default_cases

    assert load_scenario("evaluation").to_config().cases == default_cases()
    assert EvaluationScenario().to_config().cases == default_cases()
    path = tmp_path / "mine.yaml"
    path.write_text(
        "scenario: !EvaluationScenario\n"
        "  mcas: [washout]\n"
        "  cases:\n"
        "    - {name: F, vehicles: [f16, DHC6], seeds: [6000, 6001, 6002]}\n"
        "    - {name: E, vehicle: jet, pilot: route, seeds: []}\n"
    )
    (case,) = load_scenario(path).to_config().cases  # the empty case is skipped
    assert case == EvaluationCase("F", "", (6000, 6001, 6002), vehicles=("f16", "DHC6"))
    assert [case.vehicle_of(s) for s in case.seeds] == ["f16", "DHC6", "f16"]
    with pytest.raises(ValueError, match=r"unknown field 'jet_seeds'.*cases: \[\{name: A"):
        load_scenario("evaluation", "{jet_seeds: [2000]}")


def test_a_recorded_config_is_the_same_one_across_fields_added_at_their_defaults():
    """A report written before a config field existed still stands in for that MCA while
    the field is at its default; not once it is set, nor for a changed value or pose."""
    from mca_drake.cueing import WashoutConfig
    from mca_drake.studies.evaluation_report import same_config

    home = load_platform("kr500").washout_home
    nmpc = NmpcConfig(mode="rti")
    older = {k: v for k, v in mca_config_record(nmpc).items() if k != "predictor"}
    assert same_config(older, nmpc, home)
    assert not same_config(older, dataclasses.replace(nmpc, predictor="linear"), home)
    assert not same_config({**older, "washout_weight": 0.123}, nmpc, home)
    assert not same_config({**older, "retired_field": 1}, nmpc, home)
    assert not same_config(None, nmpc, home)
    washout = WashoutConfig()
    written_out = {**mca_config_record(washout), "home_position": [float(v) for v in home]}
    assert same_config(written_out, washout, home)
    moved = {**written_out, "home_position": [0.0] * len(home)}
    assert not same_config(moved, washout, home)
