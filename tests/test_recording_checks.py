"""The recording loader against files a user might really have: each wrong one gets a clear
error that names the file, the line or column, and the fix; each valid variant loads to the
same motion."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.conventions import GRAVITY
from mca_drake.references.recording import (
    Recording,
    RecordingError,
    load_recording,
    recording_to_csv,
)
from mca_drake.references.reference import reference_from_recording


@pytest.fixture(scope="module")
def motion() -> Recording:
    """20 s at 100 Hz of gentle motion: rates up to 0.3 rad/s, about 1 m/s^2 of surge."""
    t = np.arange(0.0, 20.0 + 1e-9, 0.01)
    omega = 0.3 * np.sin(np.outer(t, [0.7, 1.1, 0.5]))
    f = np.column_stack([np.sin(0.9 * t), 0.5 * np.sin(1.3 * t), GRAVITY + 0.5 * np.sin(t)])
    return Recording(t, omega, f)


def _write(tmp_path, text: str, name: str = "flight.csv", encoding: str = "utf-8"):
    path = tmp_path / name
    path.write_bytes(text.encode(encoding))
    return path


def _table(recording: Recording, header: str, scale=(1.0, 1.0, 1.0)) -> str:
    """CSV with a given header line and columns scaled by (t, omega, f) factors."""
    rows = np.column_stack(
        [recording.t * scale[0], recording.omega * scale[1], recording.f * scale[2]]
    )
    return header + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in rows)


HEADER = "t,omega_x,omega_y,omega_z,f_x,f_y,f_z"


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        # omega in deg/s (peaks of 17 deg/s read as rad/s)
        (lambda r: _table(r, HEADER, (1, 180 / np.pi, 1)), "deg/s: multiply by pi/180"),
        # time in ms
        (lambda r: _table(r, HEADER, (1000, 1, 1)), "is t in ms"),
        # specific force in g
        (lambda r: _table(r, HEADER, (1, 1, 1 / GRAVITY)), "multiply by 9.81"),
        # gravity removed: the right diagnosis, and the wrong fix is refused too
        (
            lambda r: _table(Recording(r.t, r.omega, r.f - [0, 0, GRAVITY]), HEADER),
            "gravity looks subtracted",
        ),
        (
            lambda r: _table(Recording(r.t, r.omega, (r.f - [0, 0, GRAVITY]) * GRAVITY), HEADER),
            "median f_z",
        ),
        # z-down axes
        (lambda r: _table(Recording(r.t, -r.omega, -r.f), HEADER), "z-down"),
    ],
    ids=["deg_per_s", "time_in_ms", "in_g", "gravity_removed", "gravity_removed_times_g", "z_down"],
)
def test_wrong_units_fail_with_the_fix(motion, tmp_path, mutate, match):
    path = _write(tmp_path, mutate(motion))
    with pytest.raises(RecordingError, match=match) as info:
        load_recording(path)
    assert str(path) in str(info.value)


def test_decimal_comma_names_the_line(motion, tmp_path):
    text = recording_to_csv(motion).splitlines()
    text[5] = text[5].replace("0.0,", "0,0,", 1) if "0.0," in text[5] else text[5] + ",0"
    path = _write(tmp_path, "\n".join(text))
    with pytest.raises(RecordingError, match="line 6: 8 values for 7 columns: a decimal comma"):
        load_recording(path)


def test_a_gap_is_refused(motion, tmp_path):
    shifted = motion.t.copy()
    shifted[motion.t >= 5.0] += 60.0  # no sample for 60 s after t = 4.99 s
    gap = Recording(shifted, motion.omega, motion.f)
    path = _write(tmp_path, recording_to_csv(gap))
    with pytest.raises(RecordingError, match=r"a gap of 60.01 s .*split the file"):
        load_recording(path)


def test_an_absurd_force_is_refused(motion, tmp_path):
    f = motion.f.copy()
    f[700, 0] = 1e300
    path = _write(tmp_path, recording_to_csv(Recording(motion.t, motion.omega, f)))
    with pytest.raises(RecordingError, match=r"column f_x at t = 7 s .*beyond any vehicle"):
        load_recording(path)


def test_text_that_is_not_utf8_names_the_line(motion, tmp_path):
    text = recording_to_csv(motion).replace("# mca-drake recording v1", "# pilot: Müller")
    path = _write(tmp_path, text, encoding="latin-1")
    with pytest.raises(RecordingError, match=r"line 1: byte .* is not UTF-8"):
        load_recording(path)


def test_valid_variants_load_to_the_same_motion(motion, tmp_path):
    """A byte-order mark, Unix-epoch time stamps and units named in the header (ms, deg/s,
    g) all give the motion of the plain file."""
    plain = load_recording(_write(tmp_path, recording_to_csv(motion), "plain.csv"))
    bom = load_recording(_write(tmp_path, recording_to_csv(motion), "bom.csv", "utf-8-sig"))
    epoch = Recording(motion.t + 1_763_884_800.0, motion.omega, motion.f)
    stamped = load_recording(_write(tmp_path, recording_to_csv(epoch), "epoch.csv"))
    units = _table(
        motion,
        "t [ms],omega_x [deg/s],omega_y [deg/s],omega_z [deg/s],f_x [g],f_y [g],f_z [g]",
        (1000, 180 / np.pi, 1 / GRAVITY),
    )
    named = load_recording(_write(tmp_path, units, "units.csv"))
    for other, atol in ((bom, 0), (stamped, 1e-6), (named, 1e-12)):
        np.testing.assert_allclose(other.t, plain.t, rtol=0, atol=1e-6)
        np.testing.assert_allclose(other.omega, plain.omega, rtol=0, atol=atol + 1e-12)
        np.testing.assert_allclose(other.f, plain.f, rtol=0, atol=atol * 10 + 1e-12)
    assert stamped.t[0] == 0.0 and float(stamped.metadata["t0_s"]) == 1_763_884_800.0
    reference_from_recording(stamped)  # uniformly sampled, usable


def test_an_unknown_unit_is_named(motion, tmp_path):
    path = _write(tmp_path, _table(motion, HEADER.replace("omega_x", "omega_x [rpm]")))
    with pytest.raises(RecordingError, match="column omega_x: unknown unit 'rpm'"):
        load_recording(path)


def test_epoch_time_stamps_in_python_give_the_exact_control_period(motion):
    """A Recording built in Python with Unix-epoch times resolves each step only to 2.4e-7
    s; its reference still gets the 0.01 s period (to the nanosecond)."""
    epoch = Recording(motion.t + 1_763_884_800.0, motion.omega, motion.f)
    reference = reference_from_recording(epoch.resampled())
    assert reference.time_step == 0.01


def test_gentle_rates_without_a_unit_are_ambiguous(motion, tmp_path):
    """Rates peaking below 8 deg/s fit both readings: rad/s or deg/s must be named; named,
    either loads, and a file this module writes names it."""
    slow = Recording(motion.t, motion.omega * 0.2, motion.f)  # peaks at 0.06 rad/s
    path = _write(tmp_path, _table(slow, HEADER), "bare.csv")
    with pytest.raises(RecordingError, match=r"name the unit in the header"):
        load_recording(path)
    named = _write(tmp_path, _table(slow, HEADER.replace("omega_x", "omega_x [rad/s]")))
    with pytest.raises(RecordingError, match="omega_y, omega_z peak"):
        load_recording(named)  # every rate column needs its unit
    written = _write(tmp_path, recording_to_csv(slow), "written.csv")
    np.testing.assert_allclose(load_recording(written).omega, slow.omega, rtol=0, atol=1e-15)
    in_deg = _table(
        slow,
        HEADER.replace("omega_x", "omega_x [deg/s]")
        .replace("omega_y", "omega_y [deg/s]")
        .replace("omega_z", "omega_z [deg/s]"),
        (1, 180 / np.pi, 1),
    )
    loaded = load_recording(_write(tmp_path, in_deg, "deg.csv"))
    np.testing.assert_allclose(loaded.omega, slow.omega, rtol=0, atol=1e-12)


def test_rates_that_fit_both_readings_need_a_unit(motion, tmp_path):
    """A deg/s file peaking at 6 deg/s reads as 6 rad/s, aerobatic but possible: both fit,
    so the loader asks for the unit instead of guessing."""
    gentle_deg = Recording(motion.t, motion.omega * 20.0, motion.f)  # numbers peak at 6
    with pytest.raises(RecordingError, match="6 rad/s or 6 deg/s"):
        load_recording(_write(tmp_path, _table(gentle_deg, HEADER)))
