"""The results page and the README's headline table, generated from the current result
files under `benchmarks/results/` (benchmarks/README.md names the command behind each).

    python benchmarks/results_page.py [--results benchmarks/results] [--page OUT.md]
        [--readme README.md]

Without `--page` or `--readme` the page is printed. `--page` writes it to a file; the docs
build copies the plots it links (paths relative to the results folder, such as
`evaluation/evaluation.png`) next to it. `--readme` rewrites only the lines between
`<!-- headline-table:start -->` and `<!-- headline-table:end -->` of that file with the
headline table. The output depends on the result files alone (fixed number formats, the
files' own order), so a test can compare a README's table with a fresh render.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mca_drake.conventions import CHANNELS
from mca_drake.resources import split_profile

RESULTS_DIR = Path(__file__).resolve().parent / "results"
HEADLINE_START = "<!-- headline-table:start -->"
HEADLINE_END = "<!-- headline-table:end -->"
PAGE_COMMAND = "python benchmarks/results_page.py"

# Display names of the MCAs as the evaluation suite and the benchmarks key them.
MCA_LABELS = {
    "dpc": "DPC",
    "nmpc-converged": "NMPC, converged",
    "nmpc-rti": "NMPC, RTI",
    "washout": "Washout (tuned)",
    "nmpc-rti-perceived": "NMPC, RTI, perceived objective",
    "nmpc-converged-perceived": "NMPC, converged, perceived objective",
    "nmpc-rti-preview256": "NMPC, RTI, 2.56 s preview",
    "nmpc-rti-preview1000": "NMPC, RTI, 10 s horizon and preview",
    # bench_platforms.py's variants on a platform beside its shipped settings
    "nmpc-rti:box": "NMPC, RTI, without the legs' rows",
    "nmpc-rti:kr500-weights": "NMPC, RTI, the KR500's weights",
}


def mca_label(mca: str) -> str:
    """The display name of an MCA as the suite keys it, with its profile
    (`mca_drake.cueing.profiles`): "washout-ground" -> "Washout (tuned), ground profile"."""
    base, profile = split_profile(mca)
    label = MCA_LABELS.get(base, base)
    return f"{label}, {profile} profile" if profile else label


# The headline table's rows, in this order, where the suite ran them (a case that did not
# run one shows "-").
HEADLINE_MCAS = (
    "dpc",
    "nmpc-converged",
    "nmpc-rti",
    "washout",
    "nmpc-rti-perceived",
    "dpc-ground",
    "nmpc-converged-ground",
    "nmpc-rti-ground",
    "nmpc-rti-perceived-ground",
    "washout-ground",
)


# --- number formats (fixed, so that a render is reproducible) ---------------------------


def fmt_pi(value: float) -> str:
    """A performance index (dimensionless), three decimals."""
    return f"{value:.3f}"


def fmt_us(seconds: float) -> str:
    """A duration in s as microseconds, one decimal."""
    return f"{seconds * 1e6:.1f} us"


def fmt_ms(seconds: float) -> str:
    """A duration in s as milliseconds, two decimals."""
    return f"{seconds * 1e3:.2f} ms"


def fmt_step(seconds: float) -> str:
    """A step time in s: microseconds below 1 ms, milliseconds from there."""
    return fmt_us(seconds) if seconds < 1e-3 else fmt_ms(seconds)


def _ms_of(milliseconds: float) -> str:
    """A duration already in ms, two decimals."""
    return f"{milliseconds:.2f} ms"


def _range(spread: dict, fmt: Callable[[float], str]) -> str:
    """`{median, min, max}` (any of them) as 'median (min to max)' or 'min to max'."""
    bounds = f"{fmt(spread['min'])} to {fmt(spread['max'])}" if "min" in spread else ""
    if "median" in spread:
        return f"{fmt(spread['median'])} ({bounds})" if bounds else fmt(spread["median"])
    return bounds


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return lines


# --- the files ------------------------------------------------------------------------


def load_result(results_dir: Path, name: str) -> dict:
    """The JSON result file `name` under `results_dir`; FileNotFoundError names the
    benchmark README, which says which command writes it."""
    path = Path(results_dir) / name
    if not path.is_file():
        raise FileNotFoundError(
            f"{path}: result file missing; benchmarks/README.md names the command that writes it"
        )
    return json.loads(path.read_text())


def provenance_of(data: dict, name: str) -> dict:
    """The `provenance` block of a result file (date, command, calibration, machine);
    ValueError if the file has none or it lacks the date or the command."""
    provenance = data.get("provenance")
    if not isinstance(provenance, dict) or not {"date", "command"} <= set(provenance):
        raise ValueError(f"{name}: no provenance block with date and command")
    return provenance


def _calibration_text(calibration: dict | None) -> str:
    if not calibration:
        return "calibration not recorded"
    return (
        f"calibration numpy {calibration['numpy_s'] * 1e3:.1f} ms, "
        f"pure Python {calibration['python_s'] * 1e3:.1f} ms"
    )


def _machine_text(machine: dict | None) -> str:
    if not machine:
        return "machine not recorded"
    parts = [f"{machine['cores']} cores"] if machine.get("cores") else []
    if machine.get("cpu"):
        parts.append(str(machine["cpu"]))
    return ", ".join(parts) or "machine not recorded"


def provenance_lines(provenance: dict, name: str) -> list[str]:
    """The 'measured when, where, how to regenerate' lines of a section."""
    lines = [
        f"Measured {provenance['date']} ({_machine_text(provenance.get('machine'))}; "
        f"{_calibration_text(provenance.get('calibration'))}). File "
        f"`benchmarks/results/{name}`, regenerated by `{provenance['command']}`.",
    ]
    if provenance.get("note"):
        lines += ["", f"Note: {provenance['note']}"]
    return lines


def _image(results_dir: Path, relative: str, caption: str) -> list[str]:
    """An image link (relative to the results folder) if the plot exists."""
    return [f"![{caption}]({relative})", ""] if (results_dir / relative).is_file() else []


# --- the sections ---------------------------------------------------------------------


@dataclass(frozen=True)
class Section:
    """One benchmark or study on the page: its title, its result file (relative to the
    results folder), what it measures, and how its figures are rendered."""

    title: str
    file: str
    measures: str
    render: Callable[[Path, dict], list[str]]


def _evaluation(results_dir: Path, data: dict) -> list[str]:
    lines = [
        f"{data['duration_s']:.0f} s flights on the analytical plant. PI = sum over the six "
        "channels of (RMSE - CC), lower is better; zero motion scores the reference's own "
        "size. IQR: interquartile range of the flights' PIs.",
        "",
    ]
    waiting = [name for name, case in data["cases"].items() if not case["mcas"]]
    for case_name, case in data["cases"].items():
        if not case["mcas"]:
            continue
        seeds = case["seeds"]
        lines += [f"### Case {case_name}: {case['vehicle']} (seeds {seeds[0]}-{seeds[-1]})", ""]
        rows = []
        for mca, m in case["mcas"].items():
            rows.append(
                [
                    mca_label(mca),
                    str(m["runs"]),
                    fmt_pi(m["pi_median"]),
                    f"{fmt_pi(m['pi_iqr'][0])} to {fmt_pi(m['pi_iqr'][1])}",
                    fmt_pi(m["pi_zero_motion_median"]),
                    str(m.get("better_than_zero_motion", "-")),
                    _perceived_cell(m),
                    str(m["violations"]),
                    str(m["safety_interventions"]),
                    fmt_step(m["step_time_median_s"]),
                ]
            )
        header = ["MCA", "flights", "PI median", "PI IQR", "zero motion PI"]
        header += [
            "flights better than zero motion",
            "perceived PI (zero motion)",
            "violations",
            "clamp interventions",
        ]
        header += ["step median"]
        lines += [*_table(header, rows), ""]
        for key, test in case.items():
            if not (key.startswith("dpc_") and "_vs_" in key):  # a DPC's tests
                continue
            dpc, other = mca_label(test.get("dpc", "dpc")), mca_label(test["other"])
            text = (
                f"- {dpc} vs {other}: median PI gap {test['median_gap']:+.3f}, rank-sum "
                f"p {test['p']:.3g}"
            )
            paired = test.get("paired")
            if paired:
                text += (
                    f"; paired, DPC better on {paired['dpc_better']} of {len(paired['seeds'])} "
                    f"flights (signed-rank p {paired['p']:.3g}), worst flight "
                    f"{paired['worst_seed']} {paired['worst_difference']:+.3f}"
                )
            felt = test.get("perceived")
            if felt:
                text += f"; perceived PI gap {felt['median_gap']:+.3f}, rank-sum p {felt['p']:.3g}"
            lines.append(text)
        lines.append("")
        lines += _suite_bound_lines(case)
    if waiting:
        lines += [f"Not yet run: case {', '.join(waiting)}.", ""]
    lines += _image(results_dir, "evaluation/evaluation.png", "PI per case and MCA")
    lines += [
        "Per-channel RMSE and CC: `benchmarks/results/evaluation/evaluation.md`.",
        "",
    ]
    return lines


def _suite_bound_lines(case: dict) -> list[str]:
    """A case's offline-optimal bound and each MCA's median share of the achievable
    improvement; none where the suite ran without the bound."""
    bound = case.get("bound")
    if not bound:
        return []
    rows = [
        [mca_label(mca), str(len(entry["share"])), f"{entry['share_median']:.0%}"]
        for mca, entry in case.get("shares", {}).items()
    ]
    return [
        f"Offline-optimal bound (the whole flight known, the tracking objective): median PI "
        f"{fmt_pi(bound['pi_median'])} over {bound['runs']} flights; largest KKT residual "
        f"{bound['kkt_residual_max']:.1e}; median solve {bound['solve_time_median_s']:.0f} s. "
        "Share of the achievable improvement: (PI_zero - PI_MCA) / (PI_zero - PI_bound).",
        "",
        *_table(["MCA", "flights", "median share"], rows),
        "",
    ]


def _preview(results_dir: Path, data: dict) -> list[str]:
    """The preview study: per case, the median PI (IQR) of the causal NMPC-rti and of the
    previews, their median paired gain over the causal one, and the bound where solved."""
    lines = [
        f"NMPC-rti on the evaluation suite's {data['duration_s']:.0f} s flights, causal (the "
        "reference held over the horizon) and with a preview: the reference known over its "
        "horizon. Gain: the median over the flights of the causal PI minus the preview's "
        "(positive: the preview is better).",
        "",
    ]
    rows = []
    for case_name, case in data["cases"].items():
        causal = case["mcas"].get("nmpc-rti")
        for mca, m in case["mcas"].items():
            gain = "-"
            if causal and mca != "nmpc-rti":
                pairs = _paired_gains(causal, m)
                gain = f"{statistics.median(pairs):+.3f}" if pairs else "-"
            rows.append(
                [
                    case_name,
                    mca_label(mca),
                    str(m["runs"]),
                    f"{fmt_pi(m['pi_median'])} ({fmt_pi(m['pi_iqr'][0])} to "
                    f"{fmt_pi(m['pi_iqr'][1])})",
                    _perceived_cell(m),
                    gain,
                ]
            )
        bound = case.get("bound")
        if bound:
            rows.append(
                [
                    case_name,
                    "offline-optimal bound",
                    str(bound["runs"]),
                    fmt_pi(bound["pi_median"]),
                    "-",
                    "-",
                ]
            )
    header = ["case", "MCA", "flights", "PI median (IQR)", "perceived PI (zero motion)", "gain"]
    return [*lines, *_table(header, rows), ""]


def _predictive(results_dir: Path, data: dict) -> list[str]:
    """Predictive cueing: per case, each predictive MCA (the NMPC-rti with the learned
    forecast, with the linear one where the file has it, the predictive DPC) against its
    causal twin and the NMPC-rti's
    perfect preview; the share of the preview's gain each captures and the flights it made
    worse."""
    lines = [
        f"The evaluation suite's {data['duration_s']:.0f} s flights and drives, cued by the "
        "NMPC-rti causal (the reference held over the horizon), predictive "
        "(nmpc-rti-predictive: the packaged learned forecast over the horizon, from the past "
        "alone) and with the recorded future over "
        "the horizon (the perfect preview), and by the DPC causal and predictive "
        "(dpc-predictive: the shipped predictive policy reading the learned forecast). Gain: "
        "the median paired gain over the causal twin; share: that gain as a share of the "
        "NMPC-rti's perfect preview's over the causal NMPC-rti (for the DPC, the same "
        "yardstick: no DPC reads the recorded future). Worse: flights the predictive MCA "
        "scored worse than its causal twin on.",
        "",
    ]
    rows = []
    twins = (
        ("nmpc-rti", "nmpc-rti-predictive"),
        ("nmpc-rti", "nmpc-rti-predictive-linear"),
        ("dpc", "dpc-predictive"),
    )
    for case_name, case in data["cases"].items():
        mcas = case["mcas"]
        preview = next((m for name, m in mcas.items() if "preview" in name), None)
        if not (mcas.get("nmpc-rti") and preview):
            continue
        perfect = _paired_gains(mcas["nmpc-rti"], preview)
        for causal_name, name in twins:
            causal, predictive = mcas.get(causal_name), mcas.get(name)
            if not (causal and predictive):
                continue
            predicted = _paired_gains(causal, predictive)
            share = statistics.median(predicted) / statistics.median(perfect)
            rows.append(
                [
                    case_name,
                    name,
                    fmt_pi(causal["pi_median"]),
                    fmt_pi(predictive["pi_median"]),
                    fmt_pi(preview["pi_median"]),
                    f"{statistics.median(predicted):+.3f}",
                    f"{share:.2f}",
                    f"{sum(g < 0 for g in predicted)} of {len(predicted)}",
                    f"{fmt_pi(causal['perceived_pi_median'])} / "
                    f"{fmt_pi(predictive['perceived_pi_median'])} / "
                    f"{fmt_pi(preview['perceived_pi_median'])}",
                    f"{predictive['step_time_median_s'] * 1e3:.2f} ms",
                ]
            )
    header = [
        "case",
        "predictive MCA",
        "causal twin's PI",
        "predictive PI",
        "NMPC-rti perfect preview PI",
        "gain",
        "share",
        "worse",
        "perceived PI (causal / predictive / preview)",
        "predictive step median",
    ]
    return [*lines, *_table(header, rows), ""]


def _predictive_step(results_dir: Path, data: dict) -> list[str]:
    """Each predictive MCA's step time, the forecast included, beside its causal twin's."""
    flight = data["flight"]
    lines = [
        f"One {data['duration_s']:.0f} s flight of the {flight['vehicle']} (seed "
        f"{flight['seed']}, the {flight['pilot']} pilot; it carries "
        f"{', '.join(data['signals'])}), analytical plant: the MCA's compute time per "
        "control step, the forecast included for a predictive MCA; the median over the runs, "
        f"the range across them in brackets. Live budget: p99 within "
        f"{data['budget_p99_s'] * 1e3:.0f} ms at 100 Hz.",
        "",
    ]
    rows = []
    for mca, m in data["mcas"].items():
        low, high = m["median_range_s"]
        p_low, p_high = m["p99_range_s"]
        rows.append(
            [
                mca,
                f"{m['median_s'] * 1e3:.2f} ms ({low * 1e3:.2f}-{high * 1e3:.2f})",
                f"{m['p99_s'] * 1e3:.2f} ms ({p_low * 1e3:.2f}-{p_high * 1e3:.2f})",
                f"{m['within_budget_runs']} of {m['runs']}",
            ]
        )
    return [*lines, *_table(["MCA", "step median", "step p99", "p99 within budget"], rows), ""]


def _paired_gains(base: dict, other: dict) -> list[float]:
    """Per flight both ran, `base`'s PI minus `other`'s (positive: `other` is better)."""
    theirs = dict(zip(base["seeds"], base["pi"], strict=True))
    mine = dict(zip(other["seeds"], other["pi"], strict=True))
    return [theirs[seed] - mine[seed] for seed in sorted(mine.keys() & theirs.keys())]


def _predictor(results_dir: Path, data: dict) -> list[str]:
    """The forecasts' errors against holding the current sample, per horizon and channel."""
    learned = data.get("learned")
    lines = [
        f"The linear forecast (trained on {data.get('chosen_sources', 'every source')}, ridge "
        f"{data['chosen_ridge']:g}: the recipe chosen on the validation references) and the "
        "learned one (the linear forecast corrected by a network trained on the same "
        "references) against the constant one on "
        f"{len(data['validation'])} validation references of {data['duration_s']:.0f} s "
        "(flights by the scripted and the human-operator pilots, drives): RMS forecast error "
        "per channel, learned / linear / constant (rad/s, m/s²).",
        "",
    ]
    for name, block in (("linear", data["linear"]), ("learned", learned)):
        timing = (block or {}).get("forecast_time")
        if timing:
            lines[0] += (
                f" A {name} forecast costs {timing['median_s'] * 1e6:.0f} us median, "
                f"{timing['p99_s'] * 1e6:.0f} us p99 per control step."
            )
    if learned:
        lines[0] += (
            f" The learned one trained in {learned['training_s']:.0f} s (best epoch "
            f"{learned['best_epoch']} of {learned['epochs_run']}, "
            f"{learned['training_samples']} samples); its error relative to the constant "
            f"forecast's, averaged over channels and horizons, is "
            f"{learned['relative_rmse']:.3f} against the linear one's "
            f"{learned['linear_relative_rmse']:.3f} on the same samples."
        )
        if learned.get("signals"):
            lines[0] += (
                f" It reads the controls and vehicle state the references carry "
                f"({', '.join(learned['signals'])}); given none, as from a source that sends "
                f"the motion alone, its relative error is "
                f"{learned['motion_only_relative_rmse']:.3f}."
            )
    rows = []
    for horizon, linear in data["linear"]["rmse"].items():
        constant = data["constant"]["rmse"][horizon]
        if learned:
            ahead = learned["rmse"][horizon]
            cells = [f"{ahead[c]:.3f} / {linear[c]:.3f} / {constant[c]:.3f}" for c in linear]
        else:
            cells = [f"{linear[c]:.3f} / {constant[c]:.3f}" for c in linear]
        rows.append([f"{horizon} s", *cells])
    header = ["ahead", *next(iter(data["linear"]["rmse"].values())).keys()]
    return [*lines, *_table(header, rows), ""]


def _optimal(results_dir: Path, data: dict) -> list[str]:
    flight = data["flight"]
    lines = [
        f"The bound of one {flight['duration_s']:.0f} s {flight['vehicle']} flight (seed "
        f"{flight['seed']}) per objective, solved on one core (BLAS on one thread), each in a "
        "process of its own; peak memory is that process's.",
        "",
    ]
    rows = [
        [
            r["objective"],
            f"{r['solve_s']:.0f} s",
            str(r["iterations"]),
            f"{r['kkt_residual']:.1e}" + ("" if r["converged"] else " (not reached)"),
            f"{r['peak_rss_mb']:.0f} MB",
            fmt_pi(r["pi"]),
            fmt_pi(r["perceived_pi"]),
            fmt_pi(r["pi_zero_motion"]),
        ]
        for r in data["runs"]
    ]
    header = ["objective", "solve", "iterations", "KKT residual", "peak memory", "PI"]
    header += ["perceived PI", "zero motion PI"]
    return [*lines, *_table(header, rows), ""]


def _perceived_cell(m: dict) -> str:
    """A suite row's perceived PI median with zero motion's, or '-' for a report made
    before the runs carried the perceived block."""
    if "perceived_pi_median" not in m:
        return "-"
    return f"{fmt_pi(m['perceived_pi_median'])} ({fmt_pi(m['perceived_pi_zero_motion_median'])})"


def _perceived(results_dir: Path, data: dict) -> list[str]:
    flight = data["flight"]
    lines = [
        f"NMPC-rti at the shipped weights on a {flight['duration_s']:.0f} s {flight['vehicle']} "
        f"flight (seed {flight['seed']}), both objectives alternated in one run; step times "
        "are the median (min to max) over the runs.",
        "",
    ]
    timing = data.get("timing_provenance")
    if timing:  # the suite's figures refreshed later than the step times
        lines += [
            f"Step times measured {timing['date']} ({_machine_text(timing.get('machine'))}; "
            f"{_calibration_text(timing.get('calibration'))}) by `{timing['command']}`.",
            "",
        ]
    rows = []
    for objective, o in data["objectives"].items():
        rows.append(
            [
                objective,
                _range(o["median_ms"], _ms_of),
                _range(o["p99_ms"], _ms_of),
                _range(o["max_ms"], _ms_of),
                fmt_pi(o["pi"]),
                fmt_pi(o["perceived_pi"]),
            ]
        )
    header = ["objective", "step median", "step p99", "step max", "PI", "perceived PI"]
    lines += [*_table(header, rows), ""]
    suite = data.get("suite") or {}
    if suite:
        lines += [
            "The evaluation suite's runs: median PI and perceived PI (IQR), and the runs' cost.",
            "",
        ]
        rows = []
        for case, mcas in suite.items():
            for mca, m in mcas.items():
                rows.append(
                    [
                        case,
                        mca_label(mca),
                        str(m["flights"]),
                        f"{fmt_pi(m['pi']['median'])} ({fmt_pi(m['pi']['iqr'][0])} to "
                        f"{fmt_pi(m['pi']['iqr'][1])})",
                        f"{fmt_pi(m['perceived_pi']['median'])} "
                        f"({fmt_pi(m['perceived_pi']['iqr'][0])} to "
                        f"{fmt_pi(m['perceived_pi']['iqr'][1])})",
                        f"{m['core_hours']:.2f}",
                    ]
                )
        header = ["case", "MCA", "flights", "PI", "perceived PI", "core-hours"]
        lines += [*_table(header, rows), ""]
    return lines


def _dpc(results_dir: Path, data: dict) -> list[str]:
    rows = []
    for mca in ("dpc", "nmpc-converged"):
        entry = data.get(mca)
        if entry is None:
            continue
        unit = fmt_us if mca == "dpc" else fmt_ms
        runs = len(entry.get("runs", [])) or "-"
        rows.append(
            [
                MCA_LABELS[mca],
                f"{entry['seconds']:.0f} s",
                _range(entry["step_median_s"], unit),
                str(runs),
            ]
        )
    lines = [f"{data['vehicle']} flight, seed {data['seed']}, policy: {data['policy']}.", ""]
    lines += _table(["MCA", "flight", "step median: median (min to max) of runs", "runs"], rows)
    if "step_time_ratio" in data:
        ratio = data["step_time_ratio"]
        lines += ["", f"Converged NMPC / DPC step time: {_range(ratio, lambda v: f'{v:.0f}x')}."]
    return [*lines, ""]


def _training_recipe(results_dir: Path, data: dict) -> list[str]:
    rows = []
    for step, figures in data["steps"].items():
        for stage in figures["stages"]:
            rows.append(
                [
                    step,
                    f"{stage['horizon']}",
                    f"{stage['epochs']} ({stage['best_epoch']})",
                    f"{stage['wall_s']:.0f} s",
                ]
            )
    total, target = data["training_wall_s_total"], data["target_wall_s"]
    covered = data["training_wall_s_target_steps"]
    verdict = "within" if covered <= target else "over"
    lines = _table(["step", "rollout steps", "epochs (best)", "wall time"], rows)
    lines += [
        "",
        f"Whole recipe: {total / 60:.1f} min; its first steps "
        f"({', '.join(data['target_steps'])}) {covered / 60:.1f} min, {verdict} their "
        f"{target / 60:.0f}-minute target (dataset `{data['dataset']}`; the transports' last "
        f"step on `{data['styles_dataset']}`, the default's and the light aircraft's on "
        f"`{data['default_styles_dataset']}`).",
    ]
    return [*lines, ""]


def _nmpc(results_dir: Path, data: dict) -> list[str]:
    rows = []
    for label, f in data["flight"].items():
        weights, _, mode = label.partition("/")
        rows.append(
            [
                f"{weights} weights, {mode.replace('_', ' ')}",
                f"{f['seconds']:.0f} s",
                _ms_of(f["median_ms"]),
                _ms_of(f["p99_ms"]),
                _ms_of(f["max_ms"]),
                fmt_pi(f["pi"]),
                str(f["violations"]),
                str(f["failures"]),
            ]
        )
    header = ["weights, mode", "flight", "step median", "p99", "max", "PI", "violations"]
    lines = _table([*header, "solver failures"], rows)
    lines += [
        "",
        "shipped: NmpcConfig's (tuned) defaults; paper: NmpcConfig.paper(); rti window: RTI "
        "over the converged run's window, for the PI gap.",
        "",
        f"The default-size evaluation suite's converged NMPC runs cost "
        f"{data['suite_converged_core_hours']:.2f} core-hours at this mean step time.",
        "",
    ]
    if data.get("adversarial"):
        rows = [
            [
                kind,
                f"{f['seconds']:.0f} s",
                _ms_of(f["median_ms"]),
                _ms_of(f["p99_ms"]),
                _ms_of(f["max_ms"]),
                str(f["violations"]),
            ]
            for kind, f in data["adversarial"].items()
        ]
        lines += [
            "Converged NMPC on the adversarial references (3 g steps, 3 rad/s spins, 1 g chirp):",
            "",
        ]
        header = ["reference", "length", "step median", "p99", "max", "violations"]
        lines += [*_table(header, rows), ""]
    return lines


def _station(results_dir: Path, data: dict) -> list[str]:
    flights = data["flights"]
    rows = [
        [
            f["vehicle"],
            str(f["seed"]),
            f"{f['pi_multibody']:.4f}",
            f"{f['pi_analytical']:.4f}",
            f"{f['difference']:+.4f}",
            f"{f['realtime_factor_multibody']:.1f}",
        ]
        for f in flights
    ]
    gaps = [abs(f["difference"]) for f in flights]
    factors = [f["realtime_factor_multibody"] for f in flights]
    violations = sum(f["violations_multibody"] for f in flights)
    header = ["vehicle", "seed", "PI station", "PI analytical", "difference", "real-time factor"]
    lines = [f"Case {data['case']}, {mca_label(data['mca'])}.", ""]
    lines += _table(header, rows)
    lines += [
        "",
        f"Over {len(flights)} flights, |PI station - PI analytical|: median "
        f"{statistics.median(gaps):.4f}, max {max(gaps):.4f}. Station real-time factor: median "
        f"{statistics.median(factors):.1f} ({min(factors):.1f} to {max(factors):.1f}). "
        f"Limit violations on the station: {violations}.",
        "",
    ]
    return lines


def _platforms(results_dir: Path, data: dict) -> list[str]:
    flights = ", ".join(f"{f['vehicle']} {f['seed']}" for f in data["flights"])
    lines = [f"Flights of {data['duration_s']:g} s: {flights} (validation seeds).", ""]
    for name, platform in data["platforms"].items():
        rows = [
            [
                mca_label(mca),
                f"{fmt_pi(m['pi']['median'])} ({fmt_pi(m['pi']['q1'])} to {fmt_pi(m['pi']['q3'])})",
                fmt_pi(m["perceived_pi"]["median"]),
                fmt_pi(m["worst_pi"]),
                str(m["violations"]),
                " ".join(f"{v:.0%}" for v in m["joint_range_used"]),
                f"{fmt_ms(m['step_time_s']['median'])} ({fmt_ms(m['step_time_s']['p99'])})",
            ]
            + ([f"{m['bound_share']['median']:.0%}"] if "bound_share" in m else [])
            for mca, m in platform["mcas"].items()
        ]
        station = platform["station"]
        header = ["MCA", "PI median (IQR)", "perceived PI", "worst PI", "violations"]
        header += ["joint range used", "step median (p99)"]
        legged = any("interventions" in m for m in platform["mcas"].values())
        if legged:
            header += ["clamp interventions"]
            for row, m in zip(rows, platform["mcas"].values(), strict=True):
                row.append(str(m.get("interventions", "")))
        header += ["bound share"] if platform.get("bound") else []
        lines += [f"**{name}** ({platform['platform']['dof']} joints)", ""]
        lines += _table(header, rows)
        lines += [
            "",
            f"Station ({mca_label(station['mca'])}, {station['flight']}): real-time factor "
            f"{station['realtime_factor']:.1f}, PI {fmt_pi(station['pi'])}.",
        ]
        if platform.get("bound"):
            bound = platform["bound"]
            lines += [
                f"Offline-optimal bound: median PI {fmt_pi(bound['pi']['median'])}, solved in "
                f"{bound['wall_s']['median']:.0f} s (median) per flight."
            ]
        policy = platform.get("policy")
        if policy and policy.get("training_wall_s_total") is not None:
            total = policy["training_wall_s_total"] / 60
            if policy.get("training_wall_s"):
                made = f"trained in {policy['training_wall_s'] / 60:.1f} min"
            else:
                made = "moved from another platform's (`mca-drake transfer-policy`), not trained"
            lines += [
                f"Shipped default policy `{policy['file']}`: {made} ({total:.1f} min with its "
                "starting weights' runs)."
            ]
        lines += [""]
    for mca, gain in data["rail_gain"].items():
        if gain:
            channels = ", ".join(f"{c} {v:+.3f}" for c, v in gain["rmse_decrease"].items())
            lines += [
                f"The rail against the KR500, {mca_label(mca)}: median PI lower by "
                f"{gain['pi_decrease']:.3f}; RMSE lower per channel by {channels}.",
                "",
            ]
    return lines


def _unnamed(results_dir: Path, data: dict) -> list[str]:
    pilot = data["provenance"].get("pilot", "")
    if pilot:
        flights = (
            f"The flight cases' aircraft and first seeds ({data['duration_s']:g} s) flown by "
            f"the {pilot}-operator pilot that no training flies, cued as recordings that name "
            "no vehicle: the DPC recognizing the vehicle from the reference, and the default "
            "policy throughout, against the NMPC-rti on the same flights."
        )
    else:
        flights = (
            f"The suite's flights ({data['duration_s']:g} s) cued as recordings that name no "
            "vehicle: the DPC recognizing the vehicle from the reference, and the default "
            "policy throughout, against the suite's NMPC-rti on the same flights (for the "
            "drives also its ground profile)."
        )
    notice = data["out_of_range_notice"]
    lines = [
        f"{flights} Difference: DPC - NMPC-rti, median and worst flight (lower is "
        "better); flights better than zero motion; the share of the time the reference lay "
        "outside the running policy's training range, and on how many flights that share "
        f"passed {notice:.0%}, where the run's report suggests the NMPC (with the worst "
        "difference among the other flights); the policy each flight ended with.",
        "",
    ]
    rows = []
    for name, case in data["cases"].items():
        for label, entry in case["dpcs"].items():
            versus = entry.get("vs_nmpc-rti", {})
            ground = entry.get("vs_nmpc-rti-ground")
            ended = ", ".join(
                f"{file.removesuffix('.npz')} {count}"
                for file, count in entry["ended_with"].items()
            )
            rows.append(
                [
                    f"{name} ({case['vehicle']})",
                    label,
                    fmt_pi(entry["pi_median"]),
                    fmt_pi(versus["nmpc_pi_median"]) if versus else "-",
                    f"{versus['median_difference']:+.3f}" if versus else "-",
                    f"{versus['worst_difference']:+.3f}" if versus else "-",
                    f"{ground['median_difference']:+.3f}" if ground else "-",
                    f"{entry['better_than_zero_motion']}/{len(case['seeds'])}",
                    f"{entry['out_of_distribution_median']:.1%} "
                    f"({entry['out_of_distribution_max']:.1%})",
                    _flagged(entry, versus),
                    ended,
                ]
            )
    header = ["case", "DPC", "median PI", "NMPC-rti", "difference", "worst"]
    header += ["vs NMPC-rti ground", "better than zero motion"]
    header += ["outside the training range, median (largest)"]
    header += ["NMPC suggested (worst of the others)", "ended with"]
    return [*lines, *_table(header, rows), ""]


def _flagged(entry: dict, versus: dict) -> str:
    """How many flights' reports suggested the NMPC (outside the training range more than
    the file's `out_of_range_notice` of the time) and the worst difference to the NMPC-rti
    among the others."""
    worst = versus.get("worst_difference_unflagged") if versus else None
    return f"{entry['flagged']}" + (f" ({worst:+.3f})" if worst is not None else "")


def _selection(results_dir: Path, data: dict) -> list[str]:
    seeds = data["provenance"].get("seeds_per_vehicle", "")
    lines = [
        f"Each shipped DPC policy against what it was chosen over, on {data['duration_s']:g} s "
        f"validation flights ({seeds} per vehicle and pilot, seeds from 700) of its envelope, "
        "flown by the scripted pilot and by the human-operator pilot that nothing trains on. "
        "Difference: the alternative - the shipped policy, median over the flights (positive: "
        "the shipped policy is better), and on how many flights the alternative is better; "
        "holds: no alternative better by median.",
        "",
    ]
    rows = []
    for name, selection in data["selections"].items():
        for pilot, entry in selection["pilots"].items():
            shipped = entry["shipped"]
            for label, figures in entry["mcas"].items():
                paired = figures.get(f"paired_vs_{shipped}")
                rows.append(
                    [
                        name,
                        pilot,
                        label,
                        fmt_pi(figures["all"]),
                        f"{paired['median_difference']:+.3f}" if paired else "shipped",
                        f"{paired['better_on']}/{paired['flights']}" if paired else "-",
                        "yes" if entry["holds"] else f"no ({', '.join(entry['beaten_by'])})",
                    ]
                )
    header = ["selection", "pilot", "policy", "median PI", "difference", "better on", "holds"]
    return [*lines, *_table(header, rows), ""]


def _hazards(results_dir: Path, data: dict) -> list[str]:
    provenance = data["provenance"]
    lines = [
        f"A validation flight ({provenance.get('flight', '')}, {data['duration_s']:g} s) cued "
        f"clean and with each hazard injected at {provenance.get('hazard_at_s', 0):g} s (a "
        "touchdown: in the first second), with the input plausibility guard and without: the "
        "PI (beside the clean run's), the largest change of the cabin's specific "
        "force (f_x, f_y, a_z, a vector norm) in one control period (m/s², beside the clean "
        "flight's largest), the largest "
        "departure from the clean run's cue, when the cue was back within 0.05 of it (a reset "
        "does not come back to the clean flight), violations.",
        "",
    ]
    rows = []
    for name, entry in data["mcas"].items():
        clean = entry["clean"]["jolts"]["peak_force_change_m_s2"]
        clean_pi = entry["clean"].get("pi")
        for hazard, runs in entry["hazards"].items():
            for label, row in runs.items():
                recovered = row["recovered_after_s"]
                pi = "-" if "pi" not in row else f"{row['pi']:.3f} ({clean_pi:.3f})"
                rows.append(
                    [
                        name,
                        hazard,
                        label,
                        pi,
                        f"{row['jolts']['peak_force_change_m_s2']:.3f} ({clean:.3f})",
                        f"{row['largest_departure_from_clean']:.3f}",
                        "-" if recovered is None else f"{recovered:.2f} s",
                        str(row["violations"]),
                    ]
                )
    header = ["MCA", "hazard", "guard", "PI (clean)", "force change (clean)", "departure"]
    header += ["recovered"]
    header += ["violations"]
    return [*lines, *_table(header, rows), ""]


def _platform_suites(results_dir: Path, data: dict) -> list[str]:
    first = next(iter(data["platforms"].values()))
    cases = list(first["cases"])
    lines = [
        f"The suite's cases with their first {data['flights_per_case']} flights each, "
        f"{data['duration_s']:g} s, on every packaged platform: median PI per case and over "
        "every flight, the median of the cases' perceived PIs, violations and safety "
        "interventions summed.",
        "",
    ]
    rows = []
    for name, platform in data["platforms"].items():
        for mca, overall in platform["all"].items():
            entries = [platform["cases"][c]["mcas"].get(mca) for c in cases]
            found = [e for e in entries if e]
            rows.append(
                [
                    name,
                    mca_label(mca),
                    *(fmt_pi(e["pi_median"]) if e else "-" for e in entries),
                    fmt_pi(overall["pi_median"]),
                    fmt_pi(statistics.median(e["perceived_pi_median"] for e in found)),
                    str(sum(e["violations"] for e in found)),
                    str(sum(e["safety_interventions"] for e in found)),
                ]
            )
    header = ["platform", "MCA", *(f"case {c}" for c in cases), "all flights"]
    header += ["perceived (median of cases)", "violations", "interventions"]
    return [*lines, *_table(header, rows), ""]


def _paired_keys(entry: dict) -> list[str]:
    return [k for k in entry if k.startswith("paired_vs_")]


def _validation(results_dir: Path, data: dict) -> list[str]:
    mcas = data["mcas"]
    first = next(iter(mcas.values()))
    vehicles = [
        k for k in first if k not in ("all", "interventions") and k not in _paired_keys(first)
    ]
    rows = []
    for label, entry in mcas.items():
        row = [mca_label(label)]
        row += [fmt_pi(entry[v]) for v in vehicles]
        row += [fmt_pi(entry["all"]), str(entry["interventions"])]
        paired = [entry[k] for k in _paired_keys(entry)]
        row.append(
            f"{paired[0]['median_difference']:+.3f}, better on {paired[0]['better_on']} of "
            f"{paired[0]['flights']} (p {paired[0]['signed_rank_p']:.3g})"
            if paired
            else "-"
        )
        rows.append(row)
    header = ["MCA", *(f"median PI {v}" for v in vehicles), "median PI, all"]
    header += ["clamp interventions", "paired vs first MCA"]
    return [*_table(header, rows), ""]


def _cue_response(results_dir: Path, data: dict) -> list[str]:
    times = data["sample_times_s"]
    lines = [
        "Share of a 10 s step in one channel that the MCA renders, at each time into the step "
        "(1: all of it), and the largest cue it adds on another channel (rms during the step; "
        "rad/s or m/s^2).",
        "",
    ]
    for label, channels in data["mcas"].items():
        rows = []
        for channel, response in channels.items():
            worst = max(response["cross_talk_rms"].items(), key=lambda item: item[1])
            step = data["step_sizes"][channel]
            rows.append(
                [f"{channel} ({step:g})"]
                + [f"{share:.2f}" for share in response["share"]]
                + [f"{worst[0]} {worst[1]:.3f}"]
            )
        header = ["channel (step)", *(f"{t:g} s" for t in times), "largest cross-talk"]
        lines += [f"**{mca_label(label)}**", "", *_table(header, rows), ""]
    return lines


def _tuned(results_dir: Path, data: dict) -> list[str]:
    columns = [
        ("zero_motion_median", "zero motion PI", fmt_pi),
        ("nmpc_tuned_median", "NMPC-rti tuned PI", fmt_pi),
        ("nmpc_paper_median", "NMPC-rti paper PI", fmt_pi),
        ("tuned_better_on", "tuned NMPC better on", str),
        ("washout_median", "washout (tuned) PI", fmt_pi),
        ("washout_beats_zero_on", "washout better than zero motion on", str),
    ]
    vehicles = data["vehicles"]
    present = [c for c in columns if any(c[0] in v for v in vehicles.values())]
    rows = [
        [vehicle, str(v["flights"])] + [fmt(v[key]) if key in v else "-" for key, _, fmt in present]
        for vehicle, v in vehicles.items()
    ]
    lines = ["Medians over the flights of each vehicle.", ""]
    return [*lines, *_table(["vehicle", "flights", *(c[1] for c in present)], rows), ""]


def _tuning(results_dir: Path, data: dict) -> list[str]:
    best = data["best_config"]
    weights = ", ".join(
        f"{name} {value:.4g}" for name, value in zip(CHANNELS, best["output_weights"], strict=True)
    )
    lines = [
        f"{data['mca']}: {data['trials']} trials ({data['feasible_trials']} feasible) on "
        f"{len(data['flights'])} training flights of {data['duration_s']:.0f} s. Median PI of the "
        f"best config {fmt_pi(data['best']['pi_median'])}, of the untuned baseline "
        f"{fmt_pi(data['baseline']['pi_median'])}, of zero motion "
        f"{fmt_pi(data['zero_motion']['pi_median'])}; false-rotation limit "
        f"{data['max_false_rotation_deg_s']:g} deg/s RMS.",
        "",
        f"Best config (NmpcConfig's defaults, `benchmarks/results/tuning/nmpc/best.yaml`): output "
        f"weights {weights}; input weight {best['input_weight']:.4g}, washout weight "
        f"{best['washout_weight']:.4g}, terminal position {best['terminal_position_weight']:.4g}, "
        f"terminal velocity {best['terminal_velocity_weight']:.4g}.",
        "",
    ]
    lines += _image(results_dir, "tuning/nmpc/convergence.png", "tuning convergence")
    lines += _image(results_dir, "tuning/nmpc/importance.png", "parameter importance")
    return lines


def _spread_table(tables: dict) -> list[str]:
    """Markdown lines: one row per set and vehicle of coverage spread tables."""
    header = ["set", "vehicle", "flights", "minutes", *(f"std {c}" for c in CHANNELS)]
    rows = []
    for title, table in tables.items():
        for vehicle, s in table.items():
            rows.append(
                [title, vehicle, str(s["flights"]), f"{s['minutes']:.1f}"]
                + [f"{v:.3f}" for v in s["std"]]
                + [f"{s['a_z_p99']:.2f}"]
            )
    return _table([*header, "p99 abs a_z"], rows)


def _coverage(results_dir: Path, data: dict) -> list[str]:
    lines = [
        f"Dataset `{data['dataset']}`: spread of each scaled reference channel (rad/s, m/s^2) "
        "and the 99th percentile of |a_z| (m/s^2), beside the evaluation flights'.",
        "",
    ]
    return [*lines, *_spread_table(data["tables"]), ""]


def _coverage_sources(results_dir: Path, data: dict) -> list[str]:
    sources = data["sources"]
    lines = [
        f"References of each training source ({', '.join(sources['sources'])}) over "
        f"{len(sources['flights'])} flights of the training aircraft, before any MCA cues "
        "them, beside the evaluation cases' flights: each channel's spread (rad/s, m/s^2) "
        "and the 99th percentile of |a_z|.",
        "",
    ]
    lines += [*_spread_table(data["tables"]), ""]
    lines += [
        "Share of each evaluation case's reference samples inside the 0.5-99.5 percentile "
        "range of a source's references, per channel.",
        "",
    ]
    rows = [
        [source, case, *(f"{v:.1%}" for v in shares)]
        for source, cases in data["inside"].items()
        for case, shares in cases.items()
    ]
    return [*lines, *_table(["training", "evaluation case", *CHANNELS], rows), ""]


def _live(results_dir: Path, data: dict) -> list[str]:
    rows = []
    for label, run in data["runs"].items():
        live = run["live"]
        latency, wait, jitter = live["latency_s"], live["wait_s"], live["loop_jitter_s"]
        rows.append(
            [
                label,
                f"{fmt_ms(latency['median'])} / {fmt_ms(latency['p99'])} / "
                f"{fmt_ms(latency['max'])}",
                fmt_ms(wait["median"]),
                fmt_ms(jitter["p99"]),
                f"{live['cpu_load']:.2f}",
                f"{live['packets']} / {live['dropped']}",
                str(sum(run["violations"].values())),
            ]
        )
        rig = run.get("rig")
        if rig:  # the rig's own output: from a sample to the rig's message computed from it
            rig_latency = rig["latency_s"]
            rows[-1].insert(
                2,
                f"{fmt_ms(rig_latency['median'])} / {fmt_ms(rig_latency['p99'])} / "
                f"{fmt_ms(rig_latency['max'])}",
            )
    header = ["run", "sample to command: median / p99 / max", "wait for the poll (median)"]
    if any(run.get("rig") for run in data["runs"].values()):
        header.insert(2, "sample to rig message: median / p99 / max")
    header += ["loop jitter p99", "CPU load", "packets / dropped", "violations"]
    sender = data.get("sender", "JSBSim's FGNetFDM packets of the light aircraft, seed 7")
    lines = [
        f"The sender: {sender}, streamed over loopback in real time at 100 Hz; the loop cues "
        "them at real-time rate 1.",
        "",
    ]
    return [*lines, *_table(header, rows), ""]


def _rsi(results_dir: Path, data: dict) -> list[str]:
    rows = []
    for label, run in data["runs"].items():
        robot, driver = run["emulator"], run["driver"]
        robot_latency, driver_latency = robot["reply_latency_s"], driver["reply_latency_s"]
        rows.append(
            [
                label,
                str(robot["cycles"]),
                str(robot["late"]),
                f"{fmt_ms(robot_latency['median'])} / {fmt_ms(robot_latency['p99'])} / "
                f"{fmt_ms(robot_latency['max'])}",
                f"{fmt_ms(driver_latency['median'])} / {fmt_ms(driver_latency['p99'])} / "
                f"{fmt_ms(driver_latency['max'])}",
                fmt_ms(run["live_latency_s"]["median"]),
                str(sum(run["violations"].values())),
            ]
        )
    header = ["run", "cycles", "late replies", "reply latency, robot's view: median / p99 / max"]
    header += ["driver's own", "telemetry to command (median)", "violations"]
    lines = [
        "The live loop drives the loopback RSI robot (its own process, real-time priority) "
        "through the RSI driver; reply latency from the robot's state leaving to the reply in "
        "its socket.",
        "",
    ]
    platform = data.get("platform", {})
    if platform.get("dof", 6) > 6:
        travel = ", ".join(
            f"{label}: {', '.join(f'{v:.0f}' for v in run.get('external_travel', []))}"
            for label, run in data["runs"].items()
        )
        lines += [
            f"Platform {platform['name']} ({platform['dof']} joints): the joints beyond the "
            f"robot's six are the controller's external axes; travel of each (mm or deg) "
            f"{travel}.",
            "",
        ]
    return [*lines, *_table(header, rows), ""]


SECTIONS = (
    Section(
        "Evaluation suite",
        "evaluation/evaluation.json",
        "every MCA on the same evaluation flights: case A light aircraft, case B jet, case C "
        "four aircraft used in neither training nor tuning",
        _evaluation,
    ),
    Section(
        "Perceived motion",
        "perceived.json",
        "the NMPC's perceived objective (vestibular models) against its inertial one: step "
        "times, PI and perceived PI; and the suite's PI and perceived PI per MCA with the "
        "runs' cost",
        _perceived,
    ),
    Section(
        "Reference preview",
        "evaluation_preview/evaluation.json",
        "what knowing the future is worth: NMPC-rti causal against a 2.56 s preview over its "
        "own horizon and a 10 s preview over a 10 s horizon, on the suite's flights",
        _preview,
    ),
    Section(
        "Offline-optimal bound",
        "optimal.json",
        "the whole-flight optimum with perfect preview (`mca-drake optimal`) of one 300 s "
        "flight: solve time on one core, memory, iterations, KKT residual, PI",
        _optimal,
    ),
    Section(
        "DPC step time",
        "dpc.json",
        "the DPC policy's step time inside the Drake diagram and converged NMPC's on the same "
        "flight",
        _dpc,
    ),
    Section(
        "Training recipe",
        "training_recipe.json",
        "the shipped flight policies' training steps run from nothing: epochs and wall "
        "time per curriculum step, and the whole recipe's wall time",
        _training_recipe,
    ),
    Section(
        "NMPC step time and PI",
        "nmpc.json",
        "NMPC's step times and PI in both modes (RTI, converged) at the shipped and the "
        "paper's weights, and converged NMPC on adversarial references",
        _nmpc,
    ),
    Section(
        "KR500 station against the analytical plant",
        "station_case_c.json",
        "the PI on the 1 kHz MultibodyPlant station (inverse dynamics, head IMU) against the "
        "analytical plant's on the unseen aircraft's flights, and the station's real-time "
        "factor",
        _station,
    ),
    Section(
        "Evaluation suite per platform",
        "platform_suites.json",
        "the suite's five cases, cut to two flights each, on every packaged platform with each "
        "MCA as its name means there (`bench_platform_suites.py`)",
        _platform_suites,
    ),
    Section(
        "Motion platforms",
        "platforms.json",
        "every packaged platform (the KR500, the KR500 on a rail, the FANUC M-900iB/700) on "
        "the same flights: each MCA's PI (the DPC with the platform's own policy), limits, "
        "joint use and step time, the station's real-time factor, how each policy was "
        "trained, and what the rail adds per channel (`bench_platforms.py`)",
        _platforms,
    ),
    Section(
        "Hexapod and small rigs",
        "platforms_legged.json",
        "the packaged hexapod and 2- and 3-DOF rigs beside the KR500 on the same flights: the "
        "NMPC-rti with the platform's tuned weights, without the legs' rows and with the "
        "KR500's weights, and the washout: PI, the legs' violations and the commands their "
        "clamp changed, step time, each flight's offline-optimal bound and the share of it "
        "each MCA gets, and the station's real-time factor (`bench_platforms.py --platforms "
        "kr500,hexapod,rig-2dof,rig-3dof --bound`)",
        _platforms,
    ),
    Section(
        "Hexapod and small rigs: the offline bound",
        "platforms_legged_bound.json",
        "the same platforms on 30 s of the same flights with each flight's offline-optimal "
        "bound on each platform (the legs' limits held at every sample): every MCA's share "
        "of the improvement the platform allows (`bench_platforms.py --platforms "
        "kr500,hexapod,rig-2dof,rig-3dof --mcas dpc,nmpc-rti,washout --bound --duration 30`)",
        _platforms,
    ),
    Section(
        "References that name no vehicle",
        "unnamed.json",
        "the suite's flights cued without their vehicle's name, the DPC recognizing it from "
        "the reference (`bench_unnamed.py`)",
        _unnamed,
    ),
    Section(
        "References that name no vehicle, flown by the human-operator pilot",
        "unnamed_human.json",
        "the flight cases' aircraft flown by the human-operator pilot no training flies, "
        "cued without their vehicle's name (`bench_unnamed.py --pilot human`)",
        _unnamed,
    ),
    Section(
        "Hazards in the reference",
        "hazards.json",
        "a flight cued with a spike, a frozen stream and a reset injected, with the input "
        "plausibility guard and without (`bench_hazards.py`)",
        _hazards,
    ),
    Section(
        "How each shipped policy was selected",
        "selection.json",
        "every shipped DPC policy against the alternatives it was chosen over, on validation "
        "flights of the scripted and the human-operator pilot (`bench_selection.py`)",
        _selection,
    ),
    Section(
        "Validation flights",
        "validation.json",
        "MCAs on 300 s flights of two aircraft no training saw (A4, F4N), kept apart from "
        "evaluation case C",
        _validation,
    ),
    Section(
        "Cue response",
        "cue_response.json",
        "how each MCA answers one cue at a time: a step in one channel from the neutral pose",
        _cue_response,
    ),
    Section(
        "Tuned configs on evaluation flights",
        "tuned.json",
        "the tuned MCA configs against their baselines (the paper's NMPC weights, zero "
        "motion) on 120 s evaluation flights of the light aircraft and the jet",
        _tuned,
    ),
    Section(
        "NMPC tuning",
        "tuning/nmpc/report.json",
        "the search (Optuna on Ray Tune) that produced NmpcConfig's default weights",
        _tuning,
    ),
    Section(
        "Training-set coverage",
        "coverage.json",
        "what the shipped policy's closed-loop training set covers per vehicle, beside the "
        "evaluation flights",
        _coverage,
    ),
    Section(
        "Training sources' coverage",
        "coverage_sources.json",
        "what the scripted pilot's, the random-style pilots' and the synthetic references "
        "cover beside the evaluation flights, cases A to E",
        _coverage_sources,
    ),
    Section(
        "Live loop",
        "live.json",
        "latency from a telemetry sample's arrival to the command computed from it, loop "
        "jitter and CPU load on live JSBSim telemetry, with and without the input "
        "plausibility guard and the operator's controls in the loop",
        _live,
    ),
    Section(
        "Live loop, driving",
        "live_driving.json",
        "the same figures on a racing simulator's telemetry: a car's drive as BeamNG "
        "MotionSim packets",
        _live,
    ),
    Section(
        "Live loop, hexapod",
        "live_hexapod.json",
        "the same figures on the packaged hexapod with the rig's own output: its leg lengths "
        "to a loopback listener each period, and the latency from a sample to that message "
        "(`bench_live.py --platform hexapod --rig`)",
        _live,
    ),
    Section(
        "Predictive cueing",
        "evaluation_predictive/evaluation.json",
        "the NMPC-rti with a forecast of the reference as its preview against the causal "
        "NMPC-rti and the perfect preview, on the suite's cases A-E",
        _predictive,
    ),
    Section(
        "Predictive step time",
        "predictive_step.json",
        "each predictive MCA's step time with its forecast, beside its causal twin's "
        "(`bench_predictive_step.py`)",
        _predictive_step,
    ),
    Section(
        "Reference forecasts",
        "predictor.json",
        "the learned and the linear forecasts' errors at 0.5, 1 and 2.5 s ahead against "
        "holding the current sample, on validation flights and drives",
        _predictor,
    ),
    Section(
        "KUKA RSI driver",
        "rsi.json",
        "reply latency and late replies per RSI cycle time, live, against a loopback robot",
        _rsi,
    ),
    Section(
        "KUKA RSI driver, the KR500 on its rail",
        "rsi-kr500-rail.json",
        "the same with the rail as the controller's external axis E1 beside A1-A6",
        _rsi,
    ),
)

TABLE2_FILE = "table2/table2.md"
TABLE2_COMMAND = "OMP_NUM_THREADS=1 mca-drake table2 --out-dir benchmarks/results/table2"


def _table2_lines(results_dir: Path) -> list[str]:
    """Table II from the study's own page: its table and notes as written, with the date the
    page states."""
    path = results_dir / TABLE2_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path}: result file missing; written by `{TABLE2_COMMAND}`")
    text = path.read_text()
    date = re.search(r"\d{4}-\d{2}-\d{2}", text.splitlines()[0])
    body = text[text.index("| Metric") :].rstrip("\n").splitlines()
    return [
        "## Table II: plant-model candidates",
        "",
        "The paper's Table II reproduced: state and output models of the plant, trained and "
        "scored on the same segments; ours with the paper's figure in parentheses.",
        "",
        f"Measured {date.group(0) if date else '(date not recorded)'} (2-core CPU machine, as "
        f"the page states). File `benchmarks/results/{TABLE2_FILE}`, regenerated by "
        f"`{TABLE2_COMMAND}`.",
        "",
        *body,
        "",
    ]


def render_results_page(results_dir: Path) -> str:
    """The results page (Markdown): per benchmark and study, what it measures, when and on
    what machine (with its calibration), the command that regenerates it, its headline
    figures (medians with their spread; step times in us or ms, PIs dimensionless) and its
    plots, linked relative to `results_dir`. Raises FileNotFoundError for a missing result
    file and ValueError for one without provenance."""
    results_dir = Path(results_dir)
    lines = [
        "# Results",
        "",
        f"Generated by `{PAGE_COMMAND}` from the result files under `benchmarks/results/`; "
        "`benchmarks/README.md` says what each benchmark measures and how to run it. Each "
        "section states when its figures were measured, on what machine and with what "
        "calibration (wall time of a fixed numpy and a fixed pure-Python workload: a slower "
        "machine or a busier day shows there first).",
        "",
        "## Headline",
        "",
        render_headline_table(results_dir).rstrip("\n"),
        "",
    ]
    for section in SECTIONS:
        data = load_result(results_dir, section.file)
        provenance = provenance_of(data, section.file)
        lines += [f"## {section.title}", "", f"Measures {section.measures}.", ""]
        lines += [*provenance_lines(provenance, section.file), ""]
        lines += section.render(results_dir, data)
    lines += _table2_lines(results_dir)
    return "\n".join(lines).rstrip("\n") + "\n"


def render_headline_table(results_dir: Path) -> str:
    """The README's headline table (Markdown): the evaluation suite's median PI per case for
    each MCA and zero motion, the DPC and NMPC step times (median; us, ms) from their
    benchmarks, the dates, and the command that regenerates it."""
    results_dir = Path(results_dir)
    suite = load_result(results_dir, "evaluation/evaluation.json")
    dpc = load_result(results_dir, "dpc.json")
    nmpc = load_result(results_dir, "nmpc.json")
    cases = {name: case for name, case in suite["cases"].items() if case["mcas"]}
    steps = {
        "dpc": fmt_us(dpc["dpc"]["step_median_s"]["median"]),
        "nmpc-converged": _ms_of(nmpc["flight"]["shipped/converged"]["median_ms"]),
        "nmpc-rti": _ms_of(nmpc["flight"]["shipped/rti"]["median_ms"]),
    }
    header = ["MCA", *(f"case {name}: {case['vehicle']}" for name, case in cases.items())]
    rows = []
    for mca in HEADLINE_MCAS:
        if not any(mca in case["mcas"] for case in cases.values()):
            continue
        rows.append(
            [mca_label(mca)]
            + [
                _headline_cell(case["mcas"][mca]) if mca in case["mcas"] else "-"
                for case in cases.values()
            ]
            + [steps.get(mca, "-")]
        )
    zero = []
    for case in cases.values():
        first = next(iter(case["mcas"].values()))
        cell = fmt_pi(first["pi_zero_motion_median"])
        if "perceived_pi_zero_motion_median" in first:
            cell += f" ({fmt_pi(first['perceived_pi_zero_motion_median'])})"
        zero.append(cell)
    rows.append(["Zero motion", *zero, "-"])
    suite_date = provenance_of(suite, "evaluation/evaluation.json")["date"]
    dpc_date = provenance_of(dpc, "dpc.json")["date"]
    nmpc_date = provenance_of(nmpc, "nmpc.json")["date"]
    flights = {len(case["seeds"]) for case in cases.values()}
    lines = _table([*header, "step time (median)"], rows)
    lines += [
        "",
        "Median PI (lower is better; the perceived PI, through the vestibular models, in "
        f"brackets where the suite has it) over each case's "
        f"{'/'.join(str(n) for n in sorted(flights))} flights of {suite['duration_s']:.0f} s on "
        f"the analytical plant, evaluation suite of {suite_date}; step times on a "
        f"light-aircraft flight, DPC "
        f"{dpc_date} (`dpc.json`), NMPC {nmpc_date} (`nmpc.json`). Generated by "
        f"`{PAGE_COMMAND} --readme README.md` from `benchmarks/results/`.",
    ]
    return "\n".join(lines) + "\n"


def _headline_cell(m: dict) -> str:
    """A headline cell: the median PI, and the perceived PI's in brackets where there is one."""
    cell = fmt_pi(m["pi_median"])
    if "perceived_pi_median" in m:
        cell += f" ({fmt_pi(m['perceived_pi_median'])})"
    return cell


def replace_headline_block(text: str, table: str) -> str:
    """`text` with the lines between the headline markers replaced by `table`; ValueError
    if the markers are missing or out of order."""
    lines = text.splitlines(keepends=True)
    try:
        start = next(i for i, line in enumerate(lines) if line.strip() == HEADLINE_START)
        end = next(i for i, line in enumerate(lines) if line.strip() == HEADLINE_END)
    except StopIteration:
        raise ValueError(f"no '{HEADLINE_START}' ... '{HEADLINE_END}' lines") from None
    if end < start:
        raise ValueError(f"'{HEADLINE_END}' comes before '{HEADLINE_START}'")
    return "".join(lines[: start + 1]) + table + "".join(lines[end:])


def _write_atomically(path: Path, text: str) -> None:
    """Writes `text` to a temporary file beside `path`, then renames it over `path`."""
    path = Path(path)
    mode = path.stat().st_mode & 0o777 if path.exists() else 0o644
    fd, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.chmod(temporary, mode)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=RESULTS_DIR, help="results folder")
    parser.add_argument("--page", type=Path, help="write the results page here")
    parser.add_argument("--readme", type=Path, help="rewrite this file's headline table")
    args = parser.parse_args()
    if args.readme:
        text = args.readme.read_text()
        try:
            updated = replace_headline_block(text, render_headline_table(args.results))
        except ValueError as error:
            raise SystemExit(f"{args.readme}: {error}") from None
        _write_atomically(args.readme, updated)
    if args.page:
        _write_atomically(args.page, render_results_page(args.results))
    if not (args.readme or args.page):
        print(render_results_page(args.results), end="")


if __name__ == "__main__":
    main()
