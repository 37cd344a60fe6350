"""Every `mca-drake` command line of the docs' shell examples runs, shrunk (slow).

A page's command lines run in order in one folder, as a reader would type them: a flight
written by one line is the reference of the next, a tuning's `best.yaml` the `--set` of a
later run. What makes them long is shrunk (simulated seconds, flights, trials, epochs, Ray
workers: `shrink`), what a reader brings is stood in for (`STAND_INS`: a platform file of
their own, a flight, a trained policy, a dataset), and the few that cannot run here say why
(`NOT_RUN`). The oracle is the command itself: exit status 0 (an error is one line and
status 2). What the commands print is checked by test_docs.py, on the blocks that show it.
"""

from __future__ import annotations

import functools
import json
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from test_docs import DOCS, REPO, _blocks

pytestmark = pytest.mark.slow

# Command lines that cannot run in a test, by a part of the line, and why.
NOT_RUN = {
    "--address auto": "joins a running Ray cluster (`ray start --head` first)",
    "rsi://192.168": "drives a KUKA controller at a real address",
    "controller: 192.168": "drives a KUKA controller at a real address",
    "live_rsi.yaml": "drives a KUKA controller (the scenario's address)",
    "--robot rsi://127.0.0.1": "needs a KUKA controller (or tests/test_rsi_driver.py's one)",
}

# Flags whose values make a command long, and the value each runs with here.
SHRUNK_FLAGS = {
    "--duration": "3",
    "--minutes": "0.3",
    "--seconds": "20",
    "--flights": "1",
    "--trials": "2",
    "--max-epochs": "1",
    "--average-epochs": "1",
    "--workers": "1",
}
# Seconds of a live run (the demo's JSBSim needs a second to start streaming).
LIVE_SECONDS = "3"
# Minutes of a dataset's flights: 14 windows of 256 steps each, so that a training on one
# vehicle's flight finds validation windows.
DATASET_MINUTES = "0.6"

# Files the docs' readers bring: their path in a page's folder, and what stands in for it.
STAND_INS = {
    "my_robot.yaml": "models/fanuc-m900ib700.yaml",
    "fanuc_m900ib700.urdf": "models/fanuc_m900ib700.urdf",
    "my-rig.yaml": "models/rig-3dof.yaml",
    "results/policy/policy.npz": "mca_drake/data/default_policy.npz",
    "results/policy_v11/policy.npz": "tests/data/policy_v11.npz",
    "results/policy_v5/policy.npz": "mca_drake/data/policy_v6.npz",
}
# Stand-ins made once per session (`made_stand_ins`), for a path in a page's folder.
MADE = {
    "flight.csv": "flight.csv",
    "datasets/closed_loop/dataset.npz": "dataset/dataset.npz",
    "datasets/more/dataset.npz": "more/dataset.npz",
    "datasets/open_loop.npz": "open_loop.npz",
    "datasets/mixed_t37/dataset.npz": "dataset/dataset.npz",
    "results/tune/best.yaml": "tune/best.yaml",
}
# Command lines the docs show failing (with the one-line error they print), by a part.
FAILING = {"duraton_s": 2}


def _loops_expanded(block: str) -> list[str]:
    """The block's lines with `for NAME in WORDS; do ... done` loops unrolled (nested ones
    too) and `$NAME`, `"$NAME"`, `${NAME}` replaced by each word."""
    lines = block.replace("\\\n", " ").splitlines()
    out: list[str] = []
    i = 0
    while i < len(lines):
        match = re.match(r"\s*for (\w+) in ([^;]+); do\s*$", lines[i])
        if not match:
            out.append(lines[i])
            i += 1
            continue
        depth, j = 1, i + 1
        while depth:
            depth += bool(re.match(r"\s*for ", lines[j])) - (lines[j].strip() == "done")
            j += 1
        body = _loops_expanded("\n".join(lines[i + 1 : j - 1]))
        name = match.group(1)
        for word in match.group(2).split():
            for line in body:
                out.append(re.sub(rf"\$\{{?{name}\}}?", word, line))
        i = j
    return out


def page_commands() -> dict[str, list[str]]:
    """Every page's `mca-drake` command lines, in the page's order."""
    commands: dict[str, list[str]] = {}
    for page, block in [*_blocks("bash"), *_blocks("text")]:
        name = str(page.relative_to(DOCS if page.is_relative_to(DOCS) else REPO))
        for line in _loops_expanded(block):
            line = line.split(" #")[0].strip().removeprefix("$ ")
            for part in re.split(r"\s*(?:&&|;|\|)\s*", line):
                part = part.strip().removesuffix("&").strip()
                if part.startswith("mca-drake ") and "..." not in part:
                    commands.setdefault(name, []).append(part)
    return commands


@functools.cache
def _tracked_files() -> frozenset[str] | None:
    """The repository's files under version control (None where git cannot say)."""
    done = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True)
    return frozenset(done.stdout.splitlines()) if done.returncode == 0 else None


def _is_repository_file(word: str) -> bool:
    """Whether a command's word names a file or folder the repository ships: a scenario, a
    packaged policy, test data. Data a checkout made for itself (datasets/, results/) is
    not: a page's command reads the page folder's stand-in or what an earlier line wrote."""
    if not (REPO / word).exists():
        return False
    tracked = _tracked_files()
    folder = word.rstrip("/") + "/"
    return tracked is None or word in tracked or any(f.startswith(folder) for f in tracked)


def shrink(words: list[str]) -> list[str]:
    """A command's words made short to run: long values cut (`SHRUNK_FLAGS`), live runs a
    few seconds on loopback, scenarios cut by a last `--set`, a suite to one case. Paths to
    the repository's files (scenarios, packaged policies, test data) become absolute;
    outputs stay in the page's folder."""
    command = words[1]
    out = [words[0], command]
    i = 2
    while i < len(words):
        word = words[i]
        value = words[i + 1] if i + 1 < len(words) else None
        # a list of seeds, cases or tuning flights: its first
        listed = word in ("--seeds", "--cases") or (command, word) == ("tune", "--flights")
        if word in SHRUNK_FLAGS and value is not None and not listed:
            shrunk = {
                ("live", "--duration"): LIVE_SECONDS,
                ("dataset", "--minutes"): DATASET_MINUTES,
            }.get((command, word))
            out += [word, shrunk or SHRUNK_FLAGS[word]]
            i += 2
            continue
        if listed and value is not None:
            out += [word, value.split(",")[0]]
            i += 2
            continue
        if word == "--host" and value == "0.0.0.0":
            out += [word, "127.0.0.1"]  # tests listen on loopback only
            i += 2
            continue
        if word == "--horizons" and value is not None:
            out += [word, "128,256"]  # within the datasets' segments (256)
            i += 2
            continue
        previous = out[-1]
        if not previous.startswith("--out") and "/" in word and _is_repository_file(word):
            word = str(REPO / word)
        out.append(word)
        i += 1
    flags = set(out)
    if command in ("simulate", "optimal") and "--duration" not in flags:
        out += ["--duration", SHRUNK_FLAGS["--duration"]]
    if command == "live" and "--duration" not in flags:
        out += ["--duration", LIVE_SECONDS]
    if command == "live" and "--no-keyboard" not in flags:
        out += ["--no-keyboard"]
    if command == "evaluate" and "--suite" in flags:
        out += [] if "--cases" in flags else ["--cases", "A"]
        out += [] if "--flights" in flags else ["--flights", "1"]
        out += [] if "--duration" in flags else ["--duration", SHRUNK_FLAGS["--duration"]]
    if command == "tune":
        out += [] if "--trials" in flags else ["--trials", "2"]
        out += [] if "--duration" in flags else ["--duration", SHRUNK_FLAGS["--duration"]]
        # A 3 s flight is mostly its start's transient, which the false-rotation limit would
        # refuse in every trial; step times depend on the test machine's load.
        out += ["--max-false-rotation", "0", "--budget-ms", "0"]
    if command == "dataset" and out[2] == "closed-loop":
        # a flight of each vehicle listed (later commands train on a vehicle by name)
        vehicles = out[out.index("--vehicles") + 1].split(",") if "--vehicles" in flags else []
        if "--flights" in flags:
            out[out.index("--flights") + 1] = str(max(1, len(vehicles)))
        else:
            out += ["--flights", str(max(1, len(vehicles)))]
        out += [] if "--minutes" in flags else ["--minutes", DATASET_MINUTES]
        out += [] if "--horizon" in flags else ["--horizon", "256"]
    if command == "dataset" and out[2] == "bound":
        # each flight's bound is a Gauss-Newton solve of minutes; two iterations run the same
        # code path (its result is written whether or not it converged)
        out += [] if "--max-iterations" in flags else ["--max-iterations", "2"]
    if command == "train-policy":
        out += [] if "--max-epochs" in flags else ["--max-epochs", "1"]
        out += [] if "--horizons" in flags else ["--horizons", "128,256"]
        out += [] if "--dataset" in flags else ["--dataset", "datasets/closed_loop/dataset.npz"]
        # a few short flights have few windows: any start counts, or validation has none
        out += ["--max-start-position", "3.2"]
    if command == "table2":
        # one candidate, one epoch, on the stand-in datasets
        out += ["--max-epochs", "1", "--only", "state_node2"]
    if command == "run":
        out += ["--set", _scenario_shrink(Path(out[2]).stem)]
    return out


def separate_tunes(commands: list[list[str]]) -> list[list[str]]:
    """A page's new tunes in the default folder after its first get folders of their own:
    the page shows them as alternatives, and a second tune into a folder that holds one is
    refused (`--resume` continues the first)."""
    out, default_taken = [], False
    for words in commands:
        if words[1] == "tune" and "--out-dir" not in words and "--resume" not in words:
            if default_taken:
                words = [*words, "--out-dir", f"results/tune_{len(out)}"]
            default_taken = True
        out.append(words)
    return out


def _scenario_shrink(name: str) -> str:
    """The last `--set` of a `run`: the scenario made short."""
    if name.startswith("evaluation"):
        return "{duration_s: 3, workers: 1, cases: [{name: A, vehicle: light, seeds: [1000]}]}"
    if name == "dataset":
        seconds = 60 * float(DATASET_MINUTES)
        return f"{{flight_seeds: [100], flight_duration_s: {seconds:g}, horizon: 256, workers: 1}}"
    return f"{{duration_s: {SHRUNK_FLAGS['--duration']}}}"


# The commands that make the stand-ins of MADE, in one folder.
MAKE_STAND_INS = (
    "flight --vehicle light --minutes 0.34 --seed 3 --out flight.csv",
    "dataset closed-loop --vehicle light --flights 2 --minutes 0.34 --horizon 256 "
    "--out-dir dataset --quiet",
    "dataset closed-loop --vehicle jet --flights 1 --first-seed 130 --minutes 0.34 "
    "--horizon 256 --out-dir more --quiet",
    "dataset open-loop --repetitions 1 --duration 3 --horizon 256 --out open_loop.npz --quiet",
    "tune --mca washout --trials 1 --duration 3 --flights light:100 --max-false-rotation 0 "
    "--out-dir tune --quiet",
)


@pytest.fixture(scope="session")
def made_stand_ins(tmp_path_factory) -> Path:
    """The stand-ins of MADE (short flights, small datasets, a tuning's best.yaml), made
    with the commands the docs show (MAKE_STAND_INS)."""
    folder = tmp_path_factory.mktemp("stand_ins")
    for line in MAKE_STAND_INS:
        done = subprocess.run(
            [sys.executable, "-m", "mca_drake.app.cli", *shlex.split(line)],
            cwd=folder,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert done.returncode == 0, (line, done.stderr[-2000:])
    return folder


# Runs a page's commands in one process (one import of Drake and torch), in order: a JSON
# list of argument lists in (a `$(cat FILE)` word is FILE's text, read when its command
# runs), one line per command out: its exit status and seconds.
DRIVER = """
import contextlib, io, json, re, sys, time
from pathlib import Path
from mca_drake.app import cli
for argv in json.load(open(sys.argv[1])):
    words = [Path(m.group(1)).read_text() if (m := re.fullmatch(r"\\$\\(cat ([^)]+)\\)", w))
             else w for w in argv[1:]]
    start, errors = time.perf_counter(), io.StringIO()
    with contextlib.redirect_stderr(errors):
        try:
            rc = cli.main(words)
        except SystemExit as exit:
            rc = exit.code
    last = errors.getvalue().strip().splitlines()[-1:] if rc else []
    print("RESULT " + json.dumps([rc, time.perf_counter() - start, last]), flush=True)
"""


def _page_cases():
    for page, lines in page_commands().items():
        yield pytest.param(page, lines, id=page)


@pytest.mark.parametrize(("page", "lines"), list(_page_cases()))
def test_a_pages_command_lines_run_shrunk(page, lines, made_stand_ins, tmp_path):
    for name, source in STAND_INS.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / source, tmp_path / name)
    tunes = any(line.startswith("mca-drake tune ") for line in lines)
    for name, made in MADE.items():
        if tunes and name.startswith("results/tune/"):
            continue  # the page's own tune makes it
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(made_stand_ins / made, tmp_path / name)
    runnable = [line for line in lines if not any(part in line for part in NOT_RUN)]
    plan = tmp_path / "commands.json"
    plan.write_text(json.dumps(separate_tunes([shrink(shlex.split(line)) for line in runnable])))
    done = subprocess.run(
        [sys.executable, "-c", DRIVER, str(plan)],
        cwd=tmp_path,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    results = [json.loads(r[7:]) for r in done.stdout.splitlines() if r.startswith("RESULT ")]
    for line, (rc, seconds, error) in zip(runnable, results, strict=False):
        print(f"{seconds:6.1f} s  exit {rc}  {line}", *error)
    expected = [next((rc for part, rc in FAILING.items() if part in line), 0) for line in runnable]
    failed = [
        (line, error)
        for line, (rc, _, error), want in zip(runnable, results, expected, strict=False)
        if rc != want
    ]
    assert len(results) == len(runnable), done.stderr[-3000:]
    assert failed == [], done.stderr[-3000:]
