"""Recording files: exact round trip, resampling, and a clear message for each bad file."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.references.recording import (
    COLUMNS,
    Recording,
    RecordingError,
    load_recording,
    save_recording,
)

G = 9.81


def level_flight(n=300, rate=100.0, rng=None):
    rng = rng or np.random.default_rng(0)
    t = np.arange(n) / rate
    omega = 0.05 * rng.normal(size=(n, 3))
    f = np.column_stack(
        [0.3 * rng.normal(size=n), 0.2 * rng.normal(size=n), G + rng.normal(size=n)]
    )
    return Recording(t, omega, f, {"vehicle": "test"})


def write(tmp_path, text, name="rec.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_round_trip_is_exact(tmp_path):
    rec = level_flight()
    path = save_recording(tmp_path / "r.csv", rec)
    back = load_recording(path)
    np.testing.assert_array_equal(back.t, rec.t)
    np.testing.assert_array_equal(back.omega, rec.omega)
    np.testing.assert_array_equal(back.f, rec.f)
    assert back.metadata["vehicle"] == "test"


def test_columns_in_any_order_with_extras(tmp_path):
    rec = level_flight(n=30)  # 0.3 s: a recording is at least 0.2 s long
    order = ["f_z", "extra", *reversed(COLUMNS[:-1])]
    # gentle rates (peak 0.12 rad/s) must name their unit
    lines = [",".join(f"{c} [rad/s]" if c.startswith("omega") else c for c in order)]
    for row in rec.as_array():
        values = dict(zip(COLUMNS, row, strict=True))
        lines.append(",".join("1.0" if c == "extra" else repr(float(values[c])) for c in order))
    back = load_recording(write(tmp_path, "\n".join(lines) + "\n"))
    np.testing.assert_array_equal(back.f, rec.f)


def test_resampling_to_100_hz_is_linear_interpolation(tmp_path):
    t = np.arange(0, 2.0001, 0.04)  # 25 Hz
    omega = np.column_stack([t, 2 * t, -t])  # linear: interpolation is exact
    f = np.column_stack([np.zeros_like(t), np.zeros_like(t), G + 0.5 * t])
    path = save_recording(tmp_path / "r.csv", Recording(t, omega, f))
    back = load_recording(path)
    np.testing.assert_allclose(np.diff(back.t), 0.01, atol=1e-12)
    assert back.t[-1] == pytest.approx(2.0)
    np.testing.assert_allclose(back.omega[:, 1], 2 * back.t, atol=1e-12)
    np.testing.assert_allclose(back.f[:, 2], G + 0.5 * back.t, atol=1e-12)


HEADER = ",".join(COLUMNS)


@pytest.mark.parametrize(
    ("body", "match"),
    [
        (
            "t,omega_x,omega_y,f_x,f_y,f_z\n0,0,0,0,0,9.81\n",
            r"line 1: missing columns \['omega_z'\]",
        ),
        (
            f"{HEADER}\n0,0,0,0,0,0,9.81\n0.01,0,zero,0,0,0,9.81\n",
            r"line 3, column omega_y: 'zero'",
        ),
        (
            f"{HEADER}\n0,0,0,0,0,0,9.81\n0.01,0,0,0,nan,0,9.81\n",
            r"line 3, column f_x: .*not finite",
        ),
        (
            f"{HEADER}\n0,0,0,0,0,0,9.81\n0.01,0,0,0,0,0,9.81\n0.01,0,0,0,0,0,9.81\n",
            r"line 4, column t: .*does not increase",
        ),
        (f"{HEADER}\n0,0,0,0,0,0,9.81\n", "at least 2 samples"),
        (f"{HEADER}\n0,0,0,0,0,0,9.81\n0.01,0,0,0\n", "line 3: 4 values for 7 columns"),
        ("# only comments\n", "no header"),
    ],
)
def test_bad_files_name_line_and_column(tmp_path, body, match):
    path = write(tmp_path, body)
    with pytest.raises(RecordingError, match=match) as err:
        load_recording(path)
    assert str(path) in str(err.value)


def test_file_in_g_is_caught(tmp_path):
    rec = level_flight()
    in_g = Recording(rec.t, rec.omega, rec.f / G)
    path = save_recording(tmp_path / "g.csv", in_g)
    with pytest.raises(RecordingError, match=r"look like g.*multiply by 9\.81"):
        load_recording(path)


def test_file_in_deg_per_s_is_caught(tmp_path):
    rec = level_flight()
    omega = rec.omega.copy()
    omega[100:150, 0] = 0.6  # a brisk 0.6 rad/s roll ...
    in_deg = Recording(rec.t, np.degrees(omega), rec.f)  # ... written as 34 deg/s
    with pytest.raises(RecordingError, match=r"omega_x.*deg/s"):
        load_recording(save_recording(tmp_path / "d.csv", in_deg))


def test_z_down_axes_are_caught(tmp_path):
    rec = level_flight()
    z_down = Recording(rec.t, rec.omega * [1, -1, -1], rec.f * [1, -1, -1])
    with pytest.raises(RecordingError, match="z-down"):
        load_recording(save_recording(tmp_path / "z.csv", z_down))


def test_gravity_removed_is_caught(tmp_path):
    rec = level_flight()
    no_gravity = Recording(rec.t, rec.omega, rec.f - [0, 0, G])
    with pytest.raises(RecordingError, match="gravity"):
        load_recording(save_recording(tmp_path / "n.csv", no_gravity))


def test_missing_file():
    with pytest.raises(FileNotFoundError, match="recording not found"):
        load_recording("no/such/file.csv")


def test_recording_rejects_bad_arrays():
    with pytest.raises(RecordingError, match=r"shape|T >= 2"):
        Recording(np.arange(3.0), np.zeros((3, 2)), np.zeros((3, 3)))
    with pytest.raises(RecordingError, match="increase"):
        Recording(np.array([0.0, 0.0]), np.zeros((2, 3)), np.zeros((2, 3)))
