"""Two DPC policies on the same evaluation flights: the gain of a new policy over an old one.

    mca-drake evaluate --suite --mcas dpc --policy results/policy/policy.npz \
        --workers 2 --out-dir results/evaluation_candidate
    python benchmarks/compare_policies.py results/evaluation_candidate \
        benchmarks/results/evaluation [--labels candidate,shipped] [--json out.json]

Reads the finished DPC runs of two suite folders (`runs/{case}_dpc_{seed}.json`, written by
`mca_drake.studies.evaluation`), refuses folders whose runs mix policies or were made by the
same policy file, and prints per case: each policy's median PI over the flights both
finished, the gain (new - old; < 0: the new policy is better), on how many flights the new
one is better, the Wilcoxon rank-sum p and the paired signed-rank p. Reads files only;
the shipped policy's runs are those of the evaluation suite's folder
(`benchmarks/results/evaluation`, its runs/ kept beside it but not in git).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_json
from mca_drake.metrics import wilcoxon_rank_sum, wilcoxon_signed_rank


def dpc_runs(folder: Path) -> tuple[dict[str, dict[int, float]], str]:
    """{case: {seed: PI}} of the DPC runs in `folder`/runs, and their policy's SHA-256.
    Raises ValueError when there is none or they come from more than one policy file."""
    runs: dict[str, dict[int, float]] = {}
    policies = set()
    for path in sorted((folder / "runs").glob("*_dpc_*.json")):
        summary = json.loads(path.read_text())
        if not np.isfinite(summary.get("pi", np.nan)):
            raise ValueError(f"{path}: no finite PI")
        runs.setdefault(summary["case"], {})[int(summary["seed"])] = float(summary["pi"])
        policies.add(summary.get("policy_sha256", ""))
    if not runs:
        raise ValueError(f"{folder}: no finished DPC run in {folder / 'runs'}")
    if len(policies) != 1:
        raise ValueError(f"{folder}: DPC runs of {len(policies)} policies; rerun the suite")
    return runs, policies.pop()


def compare(new: dict[str, dict[int, float]], old: dict[str, dict[int, float]]) -> dict:
    """Per case shared by both: the flights both ran, medians, gain, wins and the two tests
    (None where fewer than two flights are shared)."""
    cases = {}
    for case in sorted(new.keys() & old.keys()):
        seeds = sorted(new[case].keys() & old[case].keys())
        a = np.array([new[case][s] for s in seeds])
        b = np.array([old[case][s] for s in seeds])
        entry = {
            "flights": len(seeds),
            "median_new": float(np.median(a)) if seeds else None,
            "median_old": float(np.median(b)) if seeds else None,
            "new_better": int(np.sum(a < b)),
        }
        if len(seeds) >= 2:
            entry["gain"] = entry["median_new"] - entry["median_old"]
            entry["rank_sum_p"] = wilcoxon_rank_sum(a, b).p
            entry["signed_rank_p"] = wilcoxon_signed_rank(a, b).p
        cases[case] = entry
    return cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("new", type=Path, help="suite folder of the new policy")
    parser.add_argument("old", type=Path, help="suite folder of the old policy")
    parser.add_argument(
        "--labels", default="new,old", help="names of the two, e.g. candidate,shipped"
    )
    parser.add_argument("--json", type=Path, help="write the figures here")
    args = parser.parse_args()
    labels = args.labels.split(",")
    if len(labels) != 2:
        raise SystemExit("--labels needs two names, e.g. candidate,shipped")
    new, new_policy = dpc_runs(args.new)
    old, old_policy = dpc_runs(args.old)
    if new_policy == old_policy:
        raise SystemExit("both folders hold runs of the same policy file")
    cases = compare(new, old)
    if not cases:
        raise SystemExit("the two folders share no case")
    for case, e in cases.items():
        line = f"case {case}: {e['flights']} shared flights"
        if "gain" in e:
            line += (
                f"; median PI {labels[0]} {e['median_new']:.3f}, {labels[1]} "
                f"{e['median_old']:.3f}, gain {e['gain']:+.3f}; {labels[0]} better on "
                f"{e['new_better']}; rank-sum p = {e['rank_sum_p']:.3g}, signed-rank p = "
                f"{e['signed_rank_p']:.3g}"
            )
        print(line)
    if args.json:
        atomic_write_json(args.json, {"labels": labels, "cases": cases})


if __name__ == "__main__":
    main()
