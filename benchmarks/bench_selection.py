"""Every shipped DPC policy's selection, again, by one command: each shipped policy against
the alternatives it was chosen over, on validation flights of its envelope flown by the
scripted pilot and by the human-operator pilot that nothing trains on.

    python benchmarks/bench_selection.py [--selections default,light,transport,ground,
        recognizer] [--seeds 2] [--nmpc] [--out-dir results/selection]
        [--json benchmarks/results/selection.json] [--keep-others]

A selection (`selections`) names the shipped policy, the alternatives it was chosen over (the
training recipe's earlier steps kept in tests/data, the policy that ran before it on that
envelope) and the validation vehicles of its envelope; `recognizer` compares the DPC that
recognizes an unnamed reference's vehicle (`DpcConfig()`) with the default policy throughout
and with the recognizer reading the reference unclipped (`range_clip: never`), on unnamed
flights of every envelope (one per aircraft and pilot: its choice was made on 36
validation flights, decision 0024). Each flies seeds 700 on (`--seeds` per vehicle and
pilot; never training or evaluation seeds), 300 s on the analytical plant, with the
scripted pilot and the human-operator pilot (drives have no pilot: once), through
`bench_validation.run_flights` (one JSON per run under --out-dir/runs, resumable; the
flights are cached with bench_validation's). `--nmpc` adds the NMPC-rti (the ground profile's
on drives) for scale. Prints and writes per selection and pilot the medians, each
alternative's paired difference to the shipped policy (median, better on, worst flight) and
whether the shipped policy holds its place: no alternative better by median; to `--json`
(default `benchmarks/results/selection.json`) with the date, command and calibration.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from bench_validation import FIRST_VALIDATION_SEED, report, run_flights
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing.dpc import DpcConfig, default_policy_path, shipped_policy_path
from mca_drake.references.drives import is_car

ROOT = Path(__file__).resolve().parent.parent
STEPS = ROOT / "tests" / "data"


@dataclasses.dataclass(frozen=True)
class Selection:
    """A shipped policy and what it was chosen over (labels and MCA configs, the shipped one
    first), on validation flights of these vehicles."""

    decision: str
    vehicles: tuple[str, ...]
    mcas: tuple[tuple[str, object], ...]
    nmpc: str = "nmpc-rti"
    # cued as recordings that name no vehicle (the recognizer's selection)
    unnamed: bool = False
    # flights per vehicle and pilot at most (None: --seeds): the recognizer's eight aircraft
    # fly one each, its choice having been made on 36 validation flights (decision 0024)
    most_seeds: int | None = None


def _policy(path: Path) -> DpcConfig:
    return DpcConfig(policy=str(path))


def selections() -> dict[str, Selection]:
    """The selections, by name (the shipped files are looked up at call time: a missing one
    is an install error, not an import error)."""
    default = _policy(default_policy_path())
    return {
        # the default policy over the recipe's step 2 it fine-tunes, each in its place inside
        # the recognizing DPC, on unnamed flights of the aircraft it cues: the light aircraft's
        # first 20 s and what follows their light phase, the trainers and fighters
        # (decision 0039)
        "default": Selection(
            "docs/decisions/0039-the-default-policy-learns-pilots-of-drawn-styles.md",
            ("light", "DHC6", "T37", "A4", "F4N", "f16"),
            (
                ("recognized", DpcConfig()),
                (
                    "recognized_step2",
                    DpcConfig(default_policy=str(STEPS / "default_step2.npz")),
                ),
            ),
            unnamed=True,
        ),
        # the light aircraft's own policy over the default it fine-tunes (decision 0040) and
        # the recipe's light step of decision 0016
        "light": Selection(
            "docs/decisions/0040-the-envelope-policies-learn-pilots-of-drawn-styles.md",
            ("light", "DHC6"),
            (
                ("light", _policy(shipped_policy_path("light_policy"))),
                ("step3", _policy(STEPS / "light_step1.npz")),
                ("default", default),
            ),
        ),
        # the transports' policy over their first step (decisions 0038, 0040) and the default
        # (decision 0020)
        "transport": Selection(
            "docs/decisions/0040-the-envelope-policies-learn-pilots-of-drawn-styles.md",
            ("jet", "A320", "787-8"),
            (
                ("transport", _policy(shipped_policy_path("transport_policy"))),
                ("step1", _policy(STEPS / "transport_step1.npz")),
                ("default", default),
            ),
        ),
        # the ground policy over the flight policy it was fine-tuned from (decision 0013)
        "ground": Selection(
            "docs/decisions/0013-ground-policy-learns-the-ground-objective.md",
            ("bmw-320i", "ford-escort", "vw-vanagon"),
            (
                ("ground", _policy(shipped_policy_path("ground_policy"))),
                ("step1_v11", _policy(STEPS / "policy_v11.npz")),
            ),
            nmpc="nmpc-rti-ground",
        ),
        # the recognized policy over the default throughout and over the unclipped reference
        # (decisions 0024, 0025)
        "recognizer": Selection(
            "docs/decisions/0025-a-recognized-policy-reads-its-training-range.md",
            ("A4", "F4N", "light", "DHC6", "jet", "787-8", "f16", "T37"),
            (
                ("recognized", DpcConfig()),
                ("default", DpcConfig(unnamed="default")),
                ("unclipped", DpcConfig(range_clip="never")),
            ),
            unnamed=True,
            most_seeds=1,
        ),
    }


def run_selection(selection: Selection, pilot: str, args) -> dict:
    """The figures of one selection with one pilot (`report` of bench_validation, plus
    whether the shipped policy holds its place)."""
    mcas = list(selection.mcas) + ([(selection.nmpc, selection.nmpc)] if args.nmpc else [])
    count = min(args.seeds, selection.most_seeds or args.seeds)
    seeds = range(FIRST_VALIDATION_SEED, FIRST_VALIDATION_SEED + count)
    flights = [(vehicle, seed) for vehicle in selection.vehicles for seed in seeds]
    out_dir = Path(args.out_dir)
    results = run_flights(
        mcas,
        flights,
        out_dir,
        args.duration,
        Path(args.flights_dir),
        pilot=pilot,
        unnamed=selection.unnamed,
    )
    figures = report(results, flights)
    shipped = selection.mcas[0][0]
    rivals = [label for label, _ in selection.mcas[1:]]
    beaten_by = [
        label for label in rivals if figures[label][f"paired_vs_{shipped}"]["median_difference"] < 0
    ]
    return {
        "flights": [f"{v} {s}" for v, s in flights],
        "mcas": figures,
        "shipped": shipped,
        "holds": not beaten_by,
        "beaten_by": beaten_by,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    names = list(selections())
    parser.add_argument("--selections", default=",".join(names), help="comma-separated")
    parser.add_argument("--seeds", type=int, default=2, help="flights per vehicle and pilot")
    parser.add_argument("--duration", type=float, default=300.0, help="s per flight")
    parser.add_argument("--nmpc", action="store_true", help="also the NMPC-rti, for scale")
    parser.add_argument("--out-dir", default="results/selection")
    parser.add_argument(
        "--flights-dir",
        default="results/validation/flights",
        help="cached flights (shared with bench_validation)",
    )
    parser.add_argument("--json", help="default benchmarks/results/selection.json")
    parser.add_argument(
        "--keep-others",
        action="store_true",
        help="keep the --json file's selections this run does not fly (its provenance "
        "names the ones flown again)",
    )
    args = parser.parse_args()
    wanted = args.selections.split(",")
    unknown = set(wanted) - set(names)
    if unknown:
        raise SystemExit(f"--selections: unknown {', '.join(sorted(unknown))}; valid: {names}")
    calibration = print_calibration()
    figures: dict = {}
    for name in wanted:
        selection = selections()[name]
        drives = all(is_car(v) for v in selection.vehicles)
        figures[name] = {"decision": selection.decision, "pilots": {}}
        for pilot in ("scripted",) if drives else ("scripted", "human"):
            print(f"== {name}, {pilot} pilot", flush=True)
            figures[name]["pilots"][pilot] = run_selection(selection, pilot, args)
    out = args.json or default_result_path("selection.json")
    header = result_header(calibration) | {"seeds_per_vehicle": args.seeds}
    if args.keep_others:
        figures, header = kept_with(Path(out), figures, header, args.duration)
    atomic_write_json(
        out, {"provenance": header, "duration_s": args.duration, "selections": figures}
    )


def kept_with(path: Path, figures: dict, header: dict, duration_s: float) -> tuple[dict, dict]:
    """`figures` joined by the selections of the result file at `path` that they do not
    hold, and `header` naming which were flown now and, for each kept one, the provenance
    of the run that flew it (the file's, or what the file itself kept: never nested).
    Raises SystemExit where the file is missing, unreadable or of another flight duration
    (its figures would not compare)."""
    try:
        previous = json.loads(path.read_text())
        kept = previous["selections"]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise SystemExit(f"--keep-others: cannot read the selections of {path}: {error}") from error
    if previous.get("duration_s") != duration_s:
        raise SystemExit(
            f"--keep-others: {path} holds {previous.get('duration_s')} s flights, this run "
            f"{duration_s} s"
        )
    flown_then = dict(previous.get("provenance", {}))
    kept_then = flown_then.pop("kept", {})
    flown_then.pop("flown_now", None)
    provenances = {
        name: kept_then.get(name, flown_then) for name in sorted(kept) if name not in figures
    }
    header = header | {"flown_now": sorted(figures), "kept": provenances}
    # the file's order, then what it did not hold
    joined = {name: figures.get(name, value) for name, value in kept.items()}
    return joined | figures, header


if __name__ == "__main__":
    main()
