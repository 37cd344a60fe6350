"""A hostile-user probe, as a table: bad input of every class through the `mca-drake`
command, and the adversarial reference set on the station.

    python benchmarks/probe_bad_input.py [--json out.json]

Each case runs `mca-drake` in this process and is classed as: a clear error (exit 2, one
line on stderr, no traceback), a traceback (an exception escaped), silent garbage (exit 0
on input that is wrong) or, for the valid variants, accepted. Then DPC, washout and
NMPC-rti cue 3 g steps in each axis, 3 rad/s spins and a 1 g chirp on the multibody station
and the measured q, qd, qdd violations are summed (converged NMPC: `pytest -m slow
tests/test_station_limits.py`). No reserved aircraft is flown. `--json` writes the table
with its provenance (date, command, calibration, machine).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from common import print_calibration, result_header
from test_station_limits import KINDS, adversarial_reference

from mca_drake.app import cli
from mca_drake.atomic_io import atomic_write_json
from mca_drake.conventions import GRAVITY
from mca_drake.cueing.dpc import default_policy_path, load_policy_arrays
from mca_drake.platforms.files import load_platform
from mca_drake.references.recording import Recording, recording_to_csv
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")

REPO = Path(__file__).resolve().parents[1]
SCENARIO = str(REPO / "diagrams" / "closed_loop_dpc.yaml")


def _motion() -> Recording:
    t = np.arange(0.0, 20.0 + 1e-9, 0.01)
    omega = 0.3 * np.sin(np.outer(t, [0.7, 1.1, 0.5]))
    f = np.column_stack([np.sin(0.9 * t), 0.5 * np.sin(1.3 * t), GRAVITY + 0.5 * np.sin(t)])
    return Recording(t, omega, f)


def _table(r: Recording, header="t,omega_x,omega_y,omega_z,f_x,f_y,f_z", scale=(1, 1, 1)):
    rows = np.column_stack([r.t * scale[0], r.omega * scale[1], r.f * scale[2]])
    return header + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in rows)


def recording_cases(folder: Path) -> list[tuple[str, str, str | bytes]]:
    """(class, name, file content) of recordings; class 'valid' must load."""
    m = _motion()
    csv_text = recording_to_csv(m)
    lines = csv_text.splitlines()
    comma = list(lines)
    comma[5] = comma[5].replace(".", ",", 1)
    gap_t = m.t.copy()
    gap_t[m.t >= 5.0] += 60.0
    huge = m.f.copy()
    huge[700, 0] = 1e300
    no_g = Recording(m.t, m.omega, m.f - [0, 0, GRAVITY])
    return [
        ("units", "omega in deg/s", _table(m, scale=(1, 180 / np.pi, 1))),
        ("units", "omega in deg/s, peak below 8 deg/s", _table(m, scale=(1, 20, 1))),
        (
            "valid",
            "omega in deg/s, peak below 8 deg/s, unit named",
            _table(m, "t,omega_x [deg/s],omega_y [deg/s],omega_z [deg/s],f_x,f_y,f_z", (1, 20, 1)),
        ),
        ("units", "time in ms", _table(m, scale=(1000, 1, 1))),
        ("units", "specific force in g", _table(m, scale=(1, 1, 1 / GRAVITY))),
        ("units", "gravity removed", _table(no_g)),
        ("units", "gravity removed, times 9.81", _table(no_g, scale=(1, 1, GRAVITY))),
        ("units", "z-down axes", _table(Recording(m.t, -m.omega, -m.f))),
        ("encoding", "decimal comma", "\n".join(comma)),
        ("encoding", "latin-1 bytes", csv_text.replace("v1", "v1 Müller").encode("latin-1")),
        ("encoding", "empty file", ""),
        ("encoding", "header only", lines[1]),
        ("time base", "60 s gap", recording_to_csv(Recording(gap_t, m.omega, m.f))),
        ("time base", "time not increasing", "\n".join([*lines[:5], lines[4], *lines[5:]])),
        ("values", "f = 1e300", recording_to_csv(Recording(m.t, m.omega, huge))),
        ("values", "NaN value", csv_text.replace(lines[8].split(",")[1], "nan", 1)),
        ("values", "text value", "\n".join([*lines[:8], lines[8].replace(",", ",abc,", 1)])),
        ("columns", "missing f_z", _table(m).replace("f_z", "f_w", 1)),
        ("valid", "UTF-8 BOM", csv_text.encode("utf-8-sig")),
        ("valid", "Unix-epoch time stamps", recording_to_csv(Recording(m.t + 1.7e9, m.omega, m.f))),
        (
            "valid",
            "units named in the header",
            _table(
                m,
                "t [ms],omega_x [deg/s],omega_y [deg/s],omega_z [deg/s],f_x [g],f_y [g],f_z [g]",
                (1000, 180 / np.pi, 1 / GRAVITY),
            ),
        ),
    ]


def cli_cases(folder: Path) -> list[tuple[str, str, list[str]]]:
    """(class, name, argv) of command lines; class 'valid' must succeed."""
    blocker = folder / "a_file"
    blocker.write_text("x")
    bad_yaml = folder / "bad.yaml"
    bad_yaml.write_text("scenario: !ClosedLoopScenario {duration_s: [1\n")
    untagged = folder / "untagged.yaml"
    untagged.write_text("scenario: {duration_s: 5}\n")
    good = default_policy_path().read_bytes()
    policies = {}
    for name, data in (("truncated", good[: len(good) // 2]), ("empty", b"")):
        policies[name] = folder / f"{name}.npz"
        policies[name].write_bytes(data)
    flipped = bytearray(good)
    flipped[len(flipped) // 2] ^= 0xFF
    policies["bit-flipped"] = folder / "flipped.npz"
    policies["bit-flipped"].write_bytes(bytes(flipped))
    arrays, _ = load_policy_arrays(default_policy_path())
    for name, meta, w1 in (
        ("list metadata", '["a"]', arrays["W1"]),
        ("complex weights", '{"format": "mca-drake-policy-1"}', arrays["W1"] + 1j),
    ):
        policies[name] = folder / f"{name.replace(' ', '_')}.npz"
        np.savez(policies[name], metadata_json=np.array(meta), **{**arrays, "W1": w1})
    damaged = folder / "dataset.npz"
    damaged.write_bytes(good[:100])
    no_best = folder / "ckpt.pt"
    no_best.write_bytes(b"not a checkpoint")
    atomic_write_json(folder / "ckpt.json", {"format": "mca-drake-checkpoint-1"})

    def run_set(text):
        return ["run", SCENARIO, "--quiet", "--set", text]

    cases = [
        ("yaml", "syntax error in a file", ["run", str(bad_yaml)]),
        ("yaml", "syntax error in --set", run_set("{duration_s: [1")),
        ("yaml", "unknown field", run_set("{durration_s: 1}")),
        ("yaml", "unknown MCA field", run_set("{mca: !NmpcConfig {washout_wieght: 1}}")),
        ("yaml", "unknown MCA tag", run_set("{mca: !LqrConfig {}}")),
        ("yaml", "null MCA", run_set("{mca: null}")),
        ("yaml", "scalar MCA", run_set("{mca: 3}")),
        ("yaml", "untagged scenario file", ["run", str(untagged)]),
        ("yaml", "unknown SimulatorConfig field", run_set("{simulator_config: {rate: 1}}")),
        ("yaml", "null flight", run_set("{flight: null}")),
        ("settings", "measurement delay 1e5 s", run_set("{station: {measurement_delay_s: 1e5}}")),
        ("settings", "tracking damping inf", run_set("{station: {tracking_damping: .inf}}")),
        ("settings", "duration inf", run_set("{duration_s: .inf}")),
        ("settings", "duration -1", run_set("{duration_s: -1}")),
        ("settings", "random seed -1", run_set("{random_seed: -1}")),
        ("settings", "NMPC weight NaN", run_set("{mca: !NmpcConfig {input_weight: .nan}}")),
        ("settings", "washout tilt limit inf", run_set("{mca: !WashoutConfig {tilt_limit: .inf}}")),
        ("settings", "plant mujoco", run_set("{plant: mujoco}")),
        ("settings", "missing recording", run_set("{flight: {recording: no/such.csv}}")),
        ("cli", "simulate --mca lqr", ["simulate", "--mca", "lqr"]),
        ("cli", "simulate --duration -1", ["simulate", "--duration", "-1"]),
        ("cli", "simulate --duration 1e9", ["simulate", "--duration", "1e9"]),
        ("cli", "--policy with washout", ["simulate", "--mca", "washout", "--policy", "p.npz"]),
        ("cli", "evaluate without input", ["evaluate"]),
        ("cli", "suite --cases C", ["evaluate", "--suite", "--cases", "C"]),
        ("cli", "suite --flights 0", ["evaluate", "--suite", "--flights", "0"]),
        ("cli", "suite --duration 0", ["evaluate", "--suite", "--duration", "0"]),
        ("cli", "suite --workers 0", ["evaluate", "--suite", "--workers", "0"]),
        ("cli", "suite --mcas ''", ["evaluate", "--suite", "--mcas", ""]),
        ("cli", "dataset --horizon 0", ["dataset", "closed-loop", "--horizon", "0"]),
        ("cli", "dataset --horizon -5", ["dataset", "closed-loop", "--horizon", "-5"]),
        ("cli", "dataset --workers 0", ["dataset", "closed-loop", "--workers", "0"]),
        ("cli", "dataset --flights 0", ["dataset", "closed-loop", "--flights", "0"]),
        ("cli", "dataset --minutes -1", ["dataset", "closed-loop", "--minutes", "-1"]),
        ("cli", "flight --vehicle boeing", ["flight", "--vehicle", "boeing"]),
        ("cli", "open-loop --horizon 0", ["dataset", "open-loop", "--horizon", "0"]),
        ("cli", "train-policy, missing dataset", ["train-policy", "--dataset", "no/such.npz"]),
        (
            "files",
            "train-policy, damaged dataset",
            ["train-policy", "--dataset", str(damaged)],
        ),
        ("files", "export-policy, damaged checkpoint", ["export-policy", str(no_best)]),
        ("files", "export-policy, missing checkpoint", ["export-policy", "no/such.pt"]),
    ]
    for name, path in policies.items():
        cases.append(("files", f"policy {name}", ["simulate", "--policy", str(path), "--quiet"]))
    cases += [
        ("outputs", "--json under a file", ["simulate", "--json", str(blocker / "s.json")]),
        ("outputs", "--plots under a file", ["simulate", "--plots", str(blocker / "p")]),
        ("outputs", "flight --out under a file", ["flight", "--out", str(blocker / "f.csv")]),
        (
            "outputs",
            "suite --out-dir under a file",
            ["evaluate", "--suite", "--out-dir", str(blocker / "e")],
        ),
        ("outputs", "scenario output_dir under a file", run_set(f"{{output_dir: {blocker}/o}}")),
    ]
    return cases


def classify(argv: list[str], expect_valid: bool) -> str:
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = cli.main(argv)
    except SystemExit as exit_:  # argparse's own usage errors: exit 2 with a usage line
        code = exit_.code
    except Exception:
        return "traceback"
    text = err.getvalue()
    if expect_valid:
        return "accepted" if code == 0 else "refused a valid file"
    if code == 0:
        return "silent garbage"
    one_line = [line for line in text.splitlines() if line.startswith("mca-drake")]
    return "clear error" if code == 2 and one_line and "Traceback" not in text else "unclear"


def station_violations() -> dict[str, int]:
    totals = {}
    for mca in ("dpc", "washout", "nmpc-rti"):
        count = 0
        for kind in KINDS:
            r = run_closed_loop(
                mca=mca,
                reference=adversarial_reference(kind),
                plant="multibody",
                progress=False,
                robot=KR500,
            )
            count += sum(r.summary["violations"].values())
        totals[mca] = count
    return totals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", help="also write the table to this JSON file")
    parser.add_argument("--skip-station", action="store_true")
    args = parser.parse_args()
    calibration = print_calibration()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for group, name, content in recording_cases(folder):
            path = folder / f"{abs(hash(name))}.csv"
            path.write_bytes(content if isinstance(content, bytes) else content.encode())
            argv = ["plot-recording", str(path), "--out", str(folder / "plot.png")]
            rows.append((f"recording: {group}", name, classify(argv, group == "valid")))
        for group, name, argv in cli_cases(folder):
            rows.append((group, name, classify(argv, group == "valid")))
    width = max(len(n) for _, n, _ in rows)
    for group, name, outcome in rows:
        print(f"{group:20s} {name:{width}s} {outcome}")
    by_group: dict[str, Counter] = {}
    for group, _, outcome in rows:
        by_group.setdefault(group, Counter())[outcome] += 1
    print("\n| input class | tried | clear errors | valid accepted | tracebacks | silent garbage |")
    print("|---|---|---|---|---|---|")
    total = Counter()
    for group, counts in by_group.items():
        total.update(counts)
        print(
            f"| {group} | {sum(counts.values())} | {counts['clear error']} | "
            f"{counts['accepted']} | {counts['traceback']} | {counts['silent garbage']} |"
        )
    print(
        f"| all | {sum(total.values())} | {total['clear error']} | {total['accepted']} | "
        f"{total['traceback']} | {total['silent garbage']} |"
    )
    other = {k: v for k, v in total.items() if k not in ("clear error", "accepted")}
    result = {"provenance": result_header(calibration), "rows": rows, "totals": dict(total)}
    if not args.skip_station:
        violations = station_violations()
        print(f"\nstation, adversarial set ({len(KINDS)} references): violations {violations}")
        result["station_violations"] = violations
    print(f"other outcomes: {other or 'none'}")
    if args.json:
        atomic_write_json(args.json, result)


if __name__ == "__main__":
    main()
