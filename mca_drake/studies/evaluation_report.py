"""The evaluation suite's report, from the run files on disk.

Per case and MCA: the PI distribution beside the zero-motion PI, the same for the perceived
PI with the wrong cues felt and the sickness estimate, the false rotation cues, step times,
violations and safety interventions; the Wilcoxon rank-sum test of DPC against every other
MCA and the paired signed-rank test, on the PI and on the perceived PI; each MCA's share
of the improvement the offline-optimal bound achieves; box plots like the paper's Fig. 3;
markdown and JSON (`write_report`).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import (
    atomic_write_json,
    atomic_write_text,
    file_sha256,
)
from mca_drake.conventions import CHANNELS
from mca_drake.cueing import (
    DpcConfig,
    mca_config_record,
    mca_name,
)
from mca_drake.cueing.dpc import ENVELOPE_POLICIES, shipped_policy_path
from mca_drake.metrics import wilcoxon_rank_sum, wilcoxon_signed_rank
from mca_drake.platforms.files import load_platform
from mca_drake.plotting import plot_pi_boxes, save_figure
from mca_drake.resources import split_profile
from mca_drake.studies.evaluation_cases import (
    EvaluationCase,
    EvaluationConfig,
    finished_bound,
    finished_run,
    policy_fingerprint,
    run_platform,
)

# Level of the report's rank-sum tests (the paper's).
SIGNIFICANCE_LEVEL = 0.05


def write_report(config: EvaluationConfig, out: Path, previous: dict | None = None) -> dict:
    """Aggregates the run files of `config` into evaluation.json, evaluation.md and
    evaluation.png in `out`; returns the JSON dictionary. DPC runs of another policy
    than each DpcConfig's policy, and runs of another MCA config or duration, are left out.

    With `previous` (an earlier report of the same duration), a case's NMPC or washout
    with no run on disk keeps its entry from it where that report ran the same config, and
    a case without bound runs keeps its bound (`kept_entries`): the runs folder is not kept
    with the results, so a new DPC policy is measured by running the DPCs alone."""
    robot = load_platform(config.platform)
    runs = {}  # (case, mca name) -> {seed: run summary}, finished runs only
    for c in config.cases:
        for m in config.mcas:
            found = {s: finished_run(out, c, m, s, config.duration_s, robot.name) for s in c.seeds}
            runs[(c.name, mca_name(m))] = {s: r for s, r in found.items() if r is not None}
    kept = kept_entries(config, runs, previous) if previous is not None else {}
    report = {
        "duration_s": config.duration_s,
        "platform": robot.summary(),
        # the default policy's (an unnamed reference's DPC starts with it)
        "policy_sha256": next(
            filter(None, (policy_fingerprint(_unrecognized(m), robot.name) for m in config.mcas)),
            "",
        ),
        "envelope_policies_sha256": {
            envelope: file_sha256(shipped_policy_path(name))
            for envelope, name in ENVELOPE_POLICIES.items()
        },
        "mcas": config.names(),
        "mca_configs": {mca_name(m): mca_config_record(m) for m in config.mcas},
        "cases": {},
    }
    for case in config.cases:
        entry = {"vehicle": case.label(), "seeds": list(case.seeds), "mcas": {}}
        for mca in config.names():
            rs = list(runs[(case.name, mca)].values())
            if (case.name, mca) in kept:
                entry["mcas"][mca] = kept[(case.name, mca)]
                runs[(case.name, mca)] = _stand_in_runs(kept[(case.name, mca)])
                continue
            if not rs:
                continue
            pis = np.array([r["pi"] for r in rs])
            steps = np.array([r["step_time_s"]["median"] for r in rs])
            entry["mcas"][mca] = {
                "runs": len(rs),
                "seeds": list(runs[(case.name, mca)]),
                "pi": pis.tolist(),
                "pi_median": float(np.median(pis)),
                "pi_iqr": [float(np.percentile(pis, 25)), float(np.percentile(pis, 75))],
                "pi_zero_motion_median": float(np.median([r["pi_zero_motion"] for r in rs])),
                # flights whose PI is below (better than) not moving's
                "better_than_zero_motion": int(sum(r["pi"] < r["pi_zero_motion"] for r in rs)),
                # the most-used joint's share of its range, median over flights
                "joint_range_used_median": float(
                    np.median([max(r["joint_range_used"]) for r in rs])
                ),
                # rotation felt that the vehicle did not make (metrics.false_rotation),
                # median over flights of each run's RMS, deg/s (nan for run files without
                # the measure)
                "false_rotation_median_deg_s": float(
                    np.median([r.get("false_rotation", {}).get("rms_deg_s", np.nan) for r in rs])
                ),
                **_channel_medians(rs),
                **_perceived_medians(rs),
                "step_time_median_s": float(np.median(steps)),
                "step_time_max_s": float(max(r["step_time_s"]["max"] for r in rs)),
                "violations": int(sum(sum(r["violations"].values()) for r in rs)),
                "safety_interventions": int(sum(r["safety_interventions"] for r in rs)),
                "solver_failures": int(sum(r["solver_failures"] for r in rs)),
            }
        if config.bound is not None:
            kept_here = {mca for name, mca in kept if name == case.name}
            entry |= _bound_entry(config, out, case, runs, kept_here, previous)
        m = entry["mcas"]
        # each DPC (the default's, a profile's) against every other MCA (the paper: against
        # converged NMPC)
        for dpc in [d for d in m if split_profile(d)[0] == "dpc"]:
            for other in m:
                if other == dpc or min(m[dpc]["runs"], m[other]["runs"]) < 2:
                    continue
                entry[dpc_test_key(dpc, other)] = _dpc_test(
                    m[dpc], m[other], runs[(case.name, dpc)], runs[(case.name, other)]
                ) | {"dpc": dpc, "other": other}
        report["cases"][case.name] = entry
    atomic_write_json(out / "evaluation.json", report)
    atomic_write_text(out / "evaluation.md", evaluation_markdown(report))
    if any(e["mcas"] for e in report["cases"].values()):
        save_figure(plot_pi_boxes(report), out / "evaluation.png")
        save_figure(plot_pi_boxes(report, "perceived_pi"), out / "evaluation_perceived.png")
    return report


def load_report(path: str | Path) -> dict:
    """A suite report (evaluation.json) as a dictionary.

    Raises:
        FileNotFoundError: there is none at `path`.
        ValueError: the file is not a JSON object with the report's cases.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no suite report at {path} to keep entries from")
    try:
        report = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise ValueError(f"{path} is not a readable JSON report: {error}") from None
    if not isinstance(report, dict) or not isinstance(report.get("cases"), dict):
        raise ValueError(f"{path} is not a suite report (no cases)")
    return report


def kept_entries(config: EvaluationConfig, runs: dict, previous: dict) -> dict:
    """{(case, MCA name): report entry} of `previous` (a report dictionary) for every case's
    non-DPC MCA of `config` with no finished run in `runs`, where `previous` has the same
    duration and recorded the same config for that MCA. DPC entries are never kept: their
    runs are quick and their policies change.

    Raises:
        ValueError: `previous` is not a report of this duration and platform.
    """
    if not isinstance(previous, dict) or previous.get("duration_s") != config.duration_s:
        raise ValueError(
            f"the previous report is not one of {config.duration_s:g} s flights; "
            "its entries cannot stand in for runs"
        )
    platform = load_platform(config.platform).name
    if run_platform(previous) != platform:
        raise ValueError(
            f"the previous report ran on platform '{run_platform(previous)}', not on "
            f"'{platform}': its entries cannot stand in for runs"
        )
    recorded = previous.get("mca_configs", {})
    robot = load_platform(config.platform)
    kept = {}
    for case in config.cases:
        old = previous.get("cases", {}).get(case.name, {}).get("mcas", {})
        for m in config.mcas:
            name = mca_name(m)
            if isinstance(m, DpcConfig) or runs[(case.name, name)] or name not in old:
                continue
            if same_config(recorded.get(name), m, robot.washout_home):
                kept[(case.name, name)] = old[name]
    return kept


def same_config(recorded: dict | None, config, washout_home=()) -> bool:
    """Whether a report's `recorded` config (`mca_config_record`) is `config` as it runs:
    equal field by field, where a field the record lacks (added to the class since) counts
    as equal at its default, which keeps the behaviour it names, and a washout's empty
    `home_position` (the platform's `washout_home`) equals that pose written out."""
    if not isinstance(recorded, dict):
        return False
    current = mca_config_record(config)
    defaults = mca_config_record(type(config)())
    for key, value in current.items():
        if key not in recorded:
            if value != defaults[key]:
                return False
        elif recorded[key] != value and not (
            key == "home_position"
            and not value
            and np.allclose(recorded[key], washout_home)
            and len(recorded[key]) == len(washout_home)
        ):
            return False
    return all(key in current for key in recorded)


def _stand_in_runs(entry: dict) -> dict:
    """{seed: the figures the tests read} of a kept report entry: its per-flight PI and
    perceived PI."""
    return {
        seed: {"pi": pi, "perceived": {"pi": perceived}}
        for seed, pi, perceived in zip(
            entry["seeds"], entry["pi"], entry["perceived_pi"], strict=True
        )
    }


def dpc_test_key(dpc: str, other: str) -> str:
    """The report's key of the tests of DPC `dpc` against MCA `other`: "dpc_vs_washout",
    "dpc_ground_vs_nmpc_rti_ground"."""
    return f"{dpc}_vs_{other}".replace("-", "_")


def is_dpc_test(key: str) -> bool:
    """Whether a key of a case's report entry holds a DPC's tests (`dpc_test_key`)."""
    return key.startswith("dpc_") and "_vs_" in key


def _dpc_test(dpc: dict, other: dict, dpc_runs: dict, other_runs: dict) -> dict:
    """Rank-sum test of a DPC's PIs against another MCA's, with the paired and the
    perceived tests, from their report entries and runs (seed -> summary)."""
    test = wilcoxon_rank_sum(dpc["pi"], other["pi"])
    return {
        "z": test.z,
        "p": test.p,
        "alpha": SIGNIFICANCE_LEVEL,
        "significant": test.significant(SIGNIFICANCE_LEVEL),
        "median_gap": dpc["pi_median"] - other["pi_median"],
        "step_time_ratio": other["step_time_median_s"] / dpc["step_time_median_s"],
        "paired": _paired_test(dpc_runs, other_runs),
        "perceived": _perceived_tests(dpc_runs, other_runs),
    }


def _bound_entry(
    config: EvaluationConfig,
    out: Path,
    case: EvaluationCase,
    runs: dict,
    kept: set[str],
    previous: dict | None,
) -> dict:
    """The case's bound (per flight: its PI, KKT residual and solve time) and, per MCA,
    its share of the achievable improvement on the flights both have:
    (PI_zero - PI_mca) / (PI_zero - PI_bound); {} without a finished bound. Without bound
    runs on disk, `previous`'s bound for the case stands in; the MCAs in `kept` (whose
    entries come from `previous`) keep their shares from it."""
    old = (previous or {}).get("cases", {}).get(case.name, {})
    platform = load_platform(config.platform).name
    bounds = {}
    for seed in case.seeds:
        bound = finished_bound(out, case.name, config.bound, seed, config.duration_s, platform)
        if bound is not None:
            bounds[seed] = bound
    if bounds:
        pis = [b["pi"] for b in bounds.values()]
        summary = {
            "runs": len(bounds),
            "seeds": list(bounds),
            "pi": pis,
            "pi_median": float(np.median(pis)),
            "kkt_residual_max": float(max(b["solver"]["kkt_residual"] for b in bounds.values())),
            "solve_time_median_s": float(
                np.median([b["solver"]["solve_time_s"] for b in bounds.values()])
            ),
        }
    elif "bound" in old:
        summary = old["bound"]
    else:
        return {}
    bound_pi = dict(zip(summary["seeds"], summary["pi"], strict=True))
    entry = {"bound": summary, "shares": {}}
    for mca in config.names():
        if mca in kept:
            if mca in old.get("shares", {}):
                entry["shares"][mca] = old["shares"][mca]
            continue
        mine = runs[(case.name, mca)]
        shares = [
            improvement_share(mine[s]["pi_zero_motion"], mine[s]["pi"], bound_pi[s])
            for s in sorted(mine.keys() & bound_pi.keys())
        ]
        if shares:
            entry["shares"][mca] = {"share": shares, "share_median": float(np.median(shares))}
    return entry


def improvement_share(pi_zero: float, pi_mca: float, pi_bound: float) -> float:
    """An MCA's share of the achievable improvement on a flight: (PI_zero - PI_mca) /
    (PI_zero - PI_bound); 1 at the bound, 0 at no motion, above 1 where the MCA beats the
    bound on the PI (its correlation part, which the bound does not optimise); NaN where
    the bound gains nothing over no motion."""
    gain = pi_zero - pi_bound
    return float((pi_zero - pi_mca) / gain) if gain > 0 else float("nan")


def _channel_medians(runs: list[dict]) -> dict:
    """rmse_median and cc_median (6 each, conventions.CHANNELS), medians over the runs:
    where the PI comes from (it sums RMSE - CC over the six); {} where a run has neither."""
    if not all("rmse" in r and "cc" in r for r in runs):
        return {}
    return {
        f"{key}_median": np.median([r[key] for r in runs], axis=0).tolist()
        for key in ("rmse", "cc")
    }


def _perceived_medians(runs: list[dict]) -> dict:
    """The perceived figures of the runs (`mca_drake.perception.scores`): each run's
    perceived PI, their median and quartiles, zero motion's median, the median share of time
    a wrong cue is felt per channel (6) and the median sickness figures of the simulator."""
    perceived = [r["perceived"] for r in runs]
    pis = np.array([p["pi"] for p in perceived])
    sickness = [p["sickness"]["simulator"] for p in perceived]
    return {
        "perceived_pi": pis.tolist(),
        "perceived_pi_median": float(np.median(pis)),
        "perceived_pi_iqr": [float(np.percentile(pis, 25)), float(np.percentile(pis, 75))],
        "perceived_pi_zero_motion_median": float(
            np.median([p["pi_zero_motion"] for p in perceived])
        ),
        "false_cue_share_median": np.median(
            [p["false_cue_share"] for p in perceived], axis=0
        ).tolist(),
        "conflict_rms_median_m_s2": float(np.median([s["conflict_rms_m_s2"] for s in sickness])),
        "msi_final_median_percent": float(np.median([s["msi_final_percent"] for s in sickness])),
    }


def _perceived_tests(dpc: dict, other: dict) -> dict | None:
    """DPC against another MCA on the perceived PI: the rank-sum test over their runs and the
    signed-rank test on the flights both finished; None below two runs each.
    `dpc`, `other`: {seed: run summary}."""
    if min(len(dpc), len(other)) < 2:
        return None
    a = [r["perceived"]["pi"] for r in dpc.values()]
    b = [r["perceived"]["pi"] for r in other.values()]
    test = wilcoxon_rank_sum(a, b)
    return {
        "z": test.z,
        "p": test.p,
        "alpha": SIGNIFICANCE_LEVEL,
        "significant": test.significant(SIGNIFICANCE_LEVEL),
        "median_gap": test.median_a - test.median_b,
        "paired": _paired_test(dpc, other, lambda r: r["perceived"]["pi"]),
    }


def _paired_test(dpc: dict, other: dict, score=lambda run: run["pi"]) -> dict | None:
    """Signed-rank test of DPC against another MCA on the flights both have finished (the
    same flights, so the flight-to-flight spread cancels), with the flight where DPC does
    worst against it (`worst_seed`, `worst_difference` = DPC's score minus the other's:
    positive where DPC is worse); None below two shared flights.
    `dpc`, `other`: {seed: run summary}; `score`: the figure compared (default the PI)."""
    shared = sorted(dpc.keys() & other.keys())
    if len(shared) < 2:
        return None
    a, b = [score(dpc[s]) for s in shared], [score(other[s]) for s in shared]
    test = wilcoxon_signed_rank(a, b)
    differences = np.subtract(a, b)
    worst = int(np.argmax(differences))
    return {
        "seeds": shared,
        "p": test.p,
        "median_difference": test.median_difference,
        "dpc_better": test.a_better,
        "worst_seed": shared[worst],
        "worst_difference": float(differences[worst]),
    }


def format_p(p: float) -> str:
    """A p-value as the report prints it: ``p < 0.001`` below 0.001, else three figures.

    Three significant figures rather than three decimals, so a p of 0.0499 does not
    print as 0.050 beside the word "significant".
    """
    return "p < 0.001" if p < 1e-3 else f"p = {p:.3g}"


def rank_sum_verdict(test: dict) -> str:
    """The words after a report's rank-sum test of DPC (first sample) against another MCA.

    `test`: a DPC's test entry (`dpc_test_key`) of the report (``z``, ``alpha``,
    ``significant``, the last from `RankSumResult.significant`). A negative z means DPC's
    PIs rank lower, and a lower PI is better, so a significant result says which side it
    falls on.
    """
    if not test["significant"]:
        return f"no significant difference at {test['alpha']:g}"
    return f"significant at {test['alpha']:g}: DPC {'better' if test['z'] < 0 else 'worse'}"


def _channel_table(mcas: dict) -> list[str]:
    """Markdown lines: per MCA, each channel's median RMSE / CC (rad/s for the rates, m/s^2
    for the specific forces); none for a report without the per-channel medians."""
    if not all("cc_median" in m for m in mcas.values()):
        return []
    lines = [
        "",
        "Median RMSE / CC per channel (the PI sums RMSE - CC; CC counts alike on every "
        "channel, whatever its size):",
        "",
        "| MCA | " + " | ".join(CHANNELS) + " |",
        "|---|" + "---|" * len(CHANNELS),
    ]
    for mca, m in mcas.items():
        cells = (
            f"{e:.3f} / {c:.2f}" for e, c in zip(m["rmse_median"], m["cc_median"], strict=True)
        )
        lines.append(f"| {mca} | " + " | ".join(cells) + " |")
    return lines


def _paired_line(paired: dict | None) -> list[str]:
    """The report's line on a signed-rank test (`_paired_test`); none without one."""
    if not paired:
        return []
    return [
        f"Paired on the {len(paired['seeds'])} flights both ran: DPC better on "
        f"{paired['dpc_better']}, median difference {paired['median_difference']:+.3f}, "
        f"Wilcoxon signed-rank {format_p(paired['p'])}. DPC's worst flight against it: "
        f"{paired['worst_seed']}, {paired['worst_difference']:+.3f}."
    ]


def _perceived_table(mcas: dict) -> list[str]:
    """Markdown lines: per MCA, the median share of time a wrong cue is felt per channel and
    the sickness model's median conflict and incidence; none without perceived figures."""
    if not all("false_cue_share_median" in m for m in mcas.values()):
        return []
    lines = [
        "",
        "What the occupant perceives (vestibular model): median share of time a wrong cue is "
        "felt per channel, median conflict RMS and incidence of the sickness model:",
        "",
        "| MCA | " + " | ".join(CHANNELS) + " | conflict RMS | incidence |",
        "|---|" + "---|" * (len(CHANNELS) + 2),
    ]
    for mca, m in mcas.items():
        cells = " | ".join(f"{v:.0%}" for v in m["false_cue_share_median"])
        lines.append(
            f"| {mca} | {cells} | {m['conflict_rms_median_m_s2']:.3f} m/s^2 | "
            f"{m['msi_final_median_percent']:.2g} % |"
        )
    return lines


def _bound_lines(case: dict) -> list[str]:
    """Markdown lines: the case's offline-optimal bound and each MCA's median share of the
    achievable improvement; none without a bound."""
    bound = case.get("bound")
    if not bound:
        return []
    shares = ", ".join(
        f"{mca} {entry['share_median']:.0%}" for mca, entry in case.get("shares", {}).items()
    )
    return [
        "",
        f"Offline-optimal bound (perfect preview, the tracking objective): median PI "
        f"{bound['pi_median']:.3f} over {bound['runs']} flights, largest KKT residual "
        f"{bound['kkt_residual_max']:.1e}, median solve {bound['solve_time_median_s']:.0f} s. "
        f"Median share of the achievable improvement, (PI_zero - PI) / (PI_zero - PI_bound): "
        f"{shares}.",
    ]


def evaluation_markdown(report: dict) -> str:
    """The report as markdown tables, one per case."""
    lines = [
        f"# MCA evaluation on the analytical plant ({report['duration_s']:g} s per flight)",
        "",
    ]
    for name, case in report["cases"].items():
        lines += [
            f"## Case {name}: {case['vehicle']} flights, seeds "
            f"{case['seeds'][0]}-{case['seeds'][-1]}",
            "",
            "| MCA | runs | PI median | PI IQR | zero-motion PI median | better than zero "
            "motion | perceived PI median | perceived zero-motion | joint range used | "
            "false rotation | step median | step max | violations | safety interventions | "
            "solver failures |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        flights = len(case["seeds"])
        for mca, m in case["mcas"].items():
            runs = f"{m['runs']}" if m["runs"] == flights else f"{m['runs']} of {flights}"
            lines.append(
                f"| {mca} | {runs} | {m['pi_median']:.3f} | {m['pi_iqr'][0]:.3f} to "
                f"{m['pi_iqr'][1]:.3f} | {m['pi_zero_motion_median']:.3f} | "
                f"{m.get('better_than_zero_motion', '-')} of {m['runs']} | "
                f"{m.get('perceived_pi_median', math.nan):.3f} | "
                f"{m.get('perceived_pi_zero_motion_median', math.nan):.3f} | "
                f"{m['joint_range_used_median']:.0%} | "
                f"{m.get('false_rotation_median_deg_s', math.nan):.1f} deg/s | "
                f"{m['step_time_median_s'] * 1e3:.3f} ms | "
                f"{m['step_time_max_s'] * 1e3:.2f} ms | {m['violations']} | "
                f"{m['safety_interventions']} | {m['solver_failures']} |"
            )
        lines += _channel_table(case["mcas"])
        lines += _perceived_table(case["mcas"])
        lines += _bound_lines(case)
        for key, test in case.items():
            if not is_dpc_test(key):
                continue
            lines += [
                "",
                f"{test.get('dpc', 'dpc')} vs {test['other']}: Wilcoxon rank-sum "
                f"z = {test['z']:.3f}, "
                f"{format_p(test['p'])} ({rank_sum_verdict(test)}); median PI gap "
                f"{test['median_gap']:+.3f}; step-time ratio {test['step_time_ratio']:.0f}x.",
            ]
            lines += _paired_line(test.get("paired"))
            perceived = test.get("perceived")
            if perceived:
                lines += [
                    f"Perceived PI: rank-sum z = {perceived['z']:.3f}, "
                    f"{format_p(perceived['p'])} ({rank_sum_verdict(perceived)}); median gap "
                    f"{perceived['median_gap']:+.3f}.",
                    *_paired_line(perceived.get("paired")),
                ]
        # every configured MCA, including one without a single finished run
        ran = {mca: m["runs"] for mca, m in case["mcas"].items()}
        missing = [mca for mca in report["mcas"] if ran.get(mca, 0) < flights]
        if missing:
            lines += [
                "",
                f"Incomplete: {', '.join(missing)} ran on fewer than the {flights} flights; "
                "`mca-drake evaluate --suite` with the same --out-dir resumes the rest.",
            ]
        lines.append("")
    return "\n".join(lines)


def _unrecognized(config):
    """A DpcConfig that runs the default policy where `config` would recognize the vehicle;
    any other config as it is."""
    if isinstance(config, DpcConfig) and config.recognizes():
        return dataclasses.replace(config, unnamed="default")
    return config
