"""The time series of a run (`mca_drake.simulation.trajectory`, `--trajectory`): one row per
control period with the reference, the cue, the joints and what the plausibility guard did.

Oracles: the run's own arrays (the file must hold them exactly: floats round-trip), the
period where a spike was injected, and the columns the docs name."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from mca_drake.app import cli
from mca_drake.conventions import CHANNELS, GRAVITY
from mca_drake.cueing.washout import WashoutConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.recording import Recording, save_recording
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.simulation.trajectory import trajectory_csv, write_trajectory

KR500 = load_platform("kr500")
DT = 0.01


def _rows(path):
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def test_the_trajectory_holds_the_run_and_names_the_spike(tmp_path):
    t = np.arange(300) * DT
    y = np.column_stack([0.02 * np.sin(t), 0 * t, 0 * t, np.sin(t), 0.3 * np.cos(t), 0 * t])
    y += 1e-5 * np.random.default_rng(0).standard_normal(y.shape)
    y[150, 5] += 25.0  # a one-sample spike
    result = run_closed_loop(
        mca=WashoutConfig(), reference=Reference(y, DT), robot=KR500, progress=False
    )
    path = write_trajectory(tmp_path / "run.csv", result, KR500)
    rows = _rows(path)
    assert len(rows) == len(result.times)
    names = list(KR500.joint_names)
    expected = ["t", *(f"ref_{c}" for c in CHANNELS), *(f"cue_{c}" for c in CHANNELS)]
    expected += [f"{p}_{j}" for p in ("q", "qd", "qdd") for j in names] + ["plausibility"]
    assert list(rows[0]) == expected
    for k in (0, 150, 299):
        row = rows[k]
        assert float(row["t"]) == result.times[k]
        assert [float(row[f"ref_{c}"]) for c in CHANNELS] == result.reference[k].tolist()
        assert [float(row[f"cue_{c}"]) for c in CHANNELS] == result.outputs[k].tolist()
        assert [float(row[f"q_{j}"]) for j in names] == result.states[k, :6].tolist()
        assert [float(row[f"qdd_{j}"]) for j in names] == result.accelerations[k].tolist()
    reactions = [row["plausibility"] for row in rows]
    assert reactions[150] == "spike"
    assert set(reactions[:150] + reactions[151:]) == {"none"}


def test_mismatched_arrays_are_refused():
    with pytest.raises(ValueError, match="outputs has shape"):
        trajectory_csv(
            KR500,
            np.zeros(3),
            np.zeros((3, 6)),
            np.zeros((2, 6)),
            np.zeros((3, 12)),
            np.zeros((3, 6)),
        )


def test_evaluate_writes_the_trajectory_of_a_recording(tmp_path, capsys):
    t = np.arange(0.0, 3.0 + 1e-9, DT)
    f = np.column_stack([0.5 * np.sin(t), 0 * t, GRAVITY + 0 * t])
    recording = save_recording(
        tmp_path / "rec.csv", Recording(t, 0.05 * np.sin(np.outer(t, [1, 2, 3])), f)
    )
    out = tmp_path / "trajectory.csv"
    code = cli.main(
        [
            "evaluate",
            "--reference",
            str(recording),
            "--mca",
            "washout",
            "--trajectory",
            str(out),
            "--quiet",
        ]
    )
    assert code == 0
    rows = _rows(out)
    assert len(rows) == len(t)
    assert rows[-1]["plausibility"] == "none"
