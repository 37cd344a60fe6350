"""Bad input of every class gets a clear error before any work, or a documented safe
fallback: unbounded settings, outputs that cannot be written, damaged files, kills in the
middle of a write, and the one-line error of the command."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from mca_drake.app import cli
from mca_drake.app.scenarios import (
    ClosedLoopScenario,
    DatasetScenario,
    EvaluationScenario,
    SuiteCase,
)
from mca_drake.atomic_io import atomic_write_json, atomic_write_text, check_writable
from mca_drake.cueing import DpcConfig, NmpcConfig, WashoutConfig
from mca_drake.cueing.dpc import default_policy_path, load_policy_arrays
from mca_drake.platforms.files import load_platform
from mca_drake.references.recording import Recording
from mca_drake.references.reference import reference_from_recording
from mca_drake.segments import SegmentDataset
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.closed_loop_dataset import (
    ClosedLoopDatasetConfig,
    flight_path,
    generate_closed_loop_dataset,
)
from mca_drake.systems.station import StationConfig

KR500 = load_platform("kr500")


@pytest.mark.parametrize(
    ("config", "match"),
    [
        (StationConfig(measurement_delay_s=100000.0), r"measurement_delay_s must be in \[0, 1\]"),
        (StationConfig(tracking_damping=float("inf")), "tracking_damping must be a finite"),
        (NmpcConfig(washout_weight=float("nan")), "washout_weight must be a finite"),
        (NmpcConfig(horizon_steps=0), "horizon_steps and max_iterations"),
        (WashoutConfig(tilt_limit=float("inf")), "tilt_limit must be a finite"),
        (ClosedLoopScenario(duration_s=float("inf")), "duration_s must be a finite"),
        (ClosedLoopScenario(duration_s=1e9), r"duration_s must be in \[0.01, 10800\]"),
        # shorter than one control period: nothing to run
        (ClosedLoopScenario(duration_s=1e-9), r"duration_s must be in \[0.01, 10800\]"),
        (ClosedLoopDatasetConfig(horizon=0), "horizon must be at least 1"),
        (ClosedLoopDatasetConfig(horizon=-5), "horizon must be at least 1"),
        (ClosedLoopDatasetConfig(split_seed=-1), "split_seed must be in"),
        (ClosedLoopDatasetConfig(flight_seeds=(1.5,)), "flight_seeds must be a whole number"),
        (DatasetScenario(workers=0), "workers must be >= 1"),
        (EvaluationScenario(mcas=[]), "mcas is empty"),
        (EvaluationScenario(duration_s=0.0), r"duration_s must be in \(0"),
        (EvaluationScenario(cases=[]), "every case's seeds are empty"),
        (
            EvaluationScenario(
                cases=[SuiteCase("A", "light", [1000]), SuiteCase("A", "jet", [2000])]
            ),
            "every case needs a name of its own",
        ),
        (EvaluationScenario(cases=[SuiteCase("F", "light", [100])]), "case F: flight seeds must"),
    ],
    ids=lambda v: v if isinstance(v, str) else type(v).__name__,
)
def test_unbounded_settings_fail_before_any_work(config, match):
    with pytest.raises(ValueError, match=match):
        config.validate()


@pytest.fixture(scope="module")
def short_reference():
    t = np.arange(0.0, 2.0 + 1e-9, 0.01)
    f = np.tile([0.0, 0.0, 9.81], (t.size, 1))
    f[:, 0] += np.sin(t)
    return reference_from_recording(Recording(t, 0.1 * np.sin(np.outer(t, [1, 2, 3])), f))


def test_outputs_are_checked_before_the_run(short_reference, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    with pytest.raises(OSError, match="cannot create the folder"):
        run_closed_loop(
            mca="washout",
            reference=short_reference,
            json_path=blocker / "summary.json",
            progress=False,
            robot=KR500,
        )
    with pytest.raises(OSError, match="is a folder"):
        check_writable(tmp_path)
    code = cli.main(["flight", "--minutes", "60", "--out", str(blocker / "f.csv"), "--quiet"])
    assert code == 2  # refused at once, not after an hour-long flight


def test_non_finite_values_are_written_as_null(tmp_path):
    path = atomic_write_json(tmp_path / "s.json", {"pi": float("nan"), "x": [1.0, float("inf")]})
    assert json.loads(path.read_text()) == {"pi": None, "x": [1.0, None]}


def test_a_kill_mid_write_leaves_no_lasting_temporary(tmp_path):
    """kill -9 inside an atomic write leaves the old file and a temporary; the next write
    of that file removes the dead writer's temporary."""
    target = tmp_path / "result.json"
    atomic_write_text(target, "old")
    code = (
        "import os, tempfile\n"
        "from pathlib import Path\n"
        f"target = Path({str(target)!r})\n"
        "fd, tmp = tempfile.mkstemp(prefix=f'.{target.name}.{os.getpid()}.', suffix='.tmp',"
        " dir=target.parent)\n"
        "os.write(fd, b'half a')\n"
        "os.kill(os.getpid(), 9)\n"
    )
    subprocess.run([sys.executable, "-c", code], check=False)
    assert target.read_text() == "old"
    assert len(list(tmp_path.glob(".result.json.*.tmp"))) == 1
    atomic_write_text(target, "new")
    assert target.read_text() == "new" and not list(tmp_path.glob(".result.json.*.tmp"))


@pytest.mark.parametrize(
    "damage",
    ["truncated", "empty", "bit_flip", "metadata_list", "complex_weights"],
)
def test_damaged_policy_files_are_clear_errors(tmp_path, damage):
    good = default_policy_path().read_bytes()
    path = tmp_path / "policy.npz"
    if damage == "truncated":
        path.write_bytes(good[: len(good) // 2])
    elif damage == "empty":
        path.write_bytes(b"")
    elif damage == "bit_flip":
        flipped = bytearray(good)
        flipped[len(flipped) // 2] ^= 0xFF
        path.write_bytes(bytes(flipped))
    else:
        arrays, _ = load_policy_arrays(default_policy_path())
        meta = '["a", "list"]' if damage == "metadata_list" else '{"format": "mca-drake-policy-1"}'
        if damage == "complex_weights":
            arrays["W1"] = arrays["W1"] + 1j
        np.savez(path, metadata_json=np.array(meta), **arrays)
    with pytest.raises(ValueError, match=str(path)):
        load_policy_arrays(path)
    assert cli.main(["evaluate", "--suite", "--policy", str(path), "--quiet"]) == 2


def test_a_damaged_flight_file_is_simulated_again(tmp_path):
    config = ClosedLoopDatasetConfig(flight_seeds=(3,), flight_duration_s=2.0, horizon=50)
    generate_closed_loop_dataset(config, tmp_path, progress=False)
    flight = flight_path(tmp_path, 3)
    flight.write_bytes(flight.read_bytes()[:200])  # killed while copying, say
    merged = generate_closed_loop_dataset(config, tmp_path, progress=False)
    assert len(SegmentDataset.load(merged)) == 4
    assert len(SegmentDataset.load(flight)) == 4


def test_an_unexpected_error_is_one_line_with_a_hint(monkeypatch, capsys):
    def broken(args):
        raise KeyError("deep inside")

    from mca_drake.app.cli import recordings

    monkeypatch.setattr(recordings, "run_flight", broken)
    assert cli.main(["flight"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "KeyError" in err and "--debug" in err
    with pytest.raises(KeyError):
        cli.main(["--debug", "flight"])


def test_the_console_script_never_prints_a_traceback(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("scenario: !ClosedLoopScenario {duration_s: [1\n")
    result = subprocess.run(
        [sys.executable, "-m", "mca_drake.app.cli", "run", str(bad)],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "PYTHONWARNINGS": "ignore"},
    )
    assert result.returncode == 2 and "not valid YAML" in result.stderr
    assert "Traceback" not in result.stderr


def test_dpc_config_with_a_missing_policy_names_it():
    with pytest.raises(FileNotFoundError, match=r"no/such\.npz"):
        DpcConfig(policy="no/such.npz").validate()


def test_a_killed_dataset_job_resumes_to_the_same_dataset(tmp_path):
    """kill -9 of `mca-drake dataset closed-loop` after its first flight file: the rerun
    simulates only what is missing and merges the same dataset as an uninterrupted run."""
    import signal
    import time

    args = ["dataset", "closed-loop", "--flights", "2", "--minutes", "0.05", "--horizon", "20"]
    script = [sys.executable, "-m", "mca_drake.app.cli", *args, "--quiet", "--out-dir"]
    whole = tmp_path / "whole"
    subprocess.run([*script, str(whole)], check=True, capture_output=True)
    killed = tmp_path / "killed"
    job = subprocess.Popen([*script, str(killed)], stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not flight_path(killed, 100).is_file():
        time.sleep(0.05)
    os.kill(job.pid, signal.SIGKILL)
    job.wait(timeout=10)
    assert not (killed / "dataset.npz").is_file(), "the job finished before the kill"
    stamp = flight_path(killed, 100).stat().st_mtime_ns
    subprocess.run([*script, str(killed)], check=True, capture_output=True)
    assert flight_path(killed, 100).stat().st_mtime_ns == stamp  # not simulated again
    a = SegmentDataset.load(whole / "dataset.npz")
    b = SegmentDataset.load(killed / "dataset.npz")
    for name in a.arrays:
        np.testing.assert_array_equal(a.arrays[name], b.arrays[name])
    np.testing.assert_array_equal(a.source, b.source)
