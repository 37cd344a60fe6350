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


def _uniform(rate_hz: float, duration_s: float, f_x) -> Recording:
    """A level recording sampled at `rate_hz` with surge `f_x(t)` (m/s^2)."""
    t = np.arange(round(duration_s * rate_hz) + 1) / rate_hz
    f = np.column_stack([f_x(t), np.zeros_like(t), np.full_like(t, GRAVITY)])
    return Recording(t, np.zeros((t.size, 3)), f)


def test_a_clean_10_hz_file_passes_the_rate_check(tmp_path):
    """Steps of 0.1 s in floating point may read 0.1000000000000001: still 10 Hz."""
    t = np.arange(60) * np.nextafter(0.1, 1.0)
    recording = Recording(t, np.zeros((60, 3)), np.tile([0.0, 0.0, GRAVITY], (60, 1)))
    assert np.median(np.diff(t)) > 0.1  # the float steps really exceed 1 / 10 Hz
    loaded = load_recording(_write(tmp_path, recording_to_csv(recording)), rate_hz=None)
    assert loaded.t.size == 60


def test_a_fast_file_is_low_passed_before_it_is_resampled(tmp_path):
    """A 99 Hz vibration in a 1 kHz file must not fold into a 1 Hz surge at 100 Hz, while a
    2 Hz cue keeps its size. Expected gains: the zero-phase Butterworth of order N at f_c has
    |H|^2 = 1 / (1 + (f / f_c)^(2N)); at 40 Hz, 99 Hz keeps 7e-4 of its size, 2 Hz all."""
    vibration = _uniform(1000.0, 10.0, lambda t: np.sin(2 * np.pi * 99.0 * t))
    path = _write(tmp_path, recording_to_csv(vibration))
    resampled = load_recording(path)
    gain_99 = 1 / (1 + (99.0 / 40.0) ** 8)
    steady = slice(100, -100)  # away from the filter's ends
    assert np.max(np.abs(resampled.f[steady, 0])) < 3 * gain_99
    # the same vibration resampled without the filter: the alias this prevents
    aliased = np.interp(resampled.t, vibration.t, vibration.f[:, 0])
    assert np.max(np.abs(aliased)) > 0.5
    assert resampled.metadata["anti_alias_cutoff_hz"] == "40"

    cue = _uniform(1000.0, 10.0, lambda t: np.sin(2 * np.pi * 2.0 * t))
    kept = load_recording(_write(tmp_path, recording_to_csv(cue), "cue.csv"))
    expected = np.sin(2 * np.pi * 2.0 * kept.t) / (1 + (2.0 / 40.0) ** 8)
    np.testing.assert_allclose(kept.f[steady, 0], expected[steady], atol=2e-3)


@pytest.mark.parametrize("samples", [2, 20])
def test_a_recording_shorter_than_20_control_periods_is_refused(tmp_path, samples):
    rows = "".join(f"{k / 100},0,0,0,0,0,9.81\n" for k in range(samples))  # 100 Hz
    path = _write(tmp_path, HEADER + "\n" + rows)
    with pytest.raises(RecordingError, match=r"needs at least 0\.2 s"):
        load_recording(path)


def test_a_folder_a_fifo_and_a_nul_byte_get_their_own_message(tmp_path):
    import os

    with pytest.raises(RecordingError, match="is a folder"):
        load_recording(tmp_path)
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(RecordingError, match="not a regular file"):
        load_recording(fifo)  # refused before it is opened: nothing blocks
    nul = _write(tmp_path, HEADER + "\n0,0,0,0,0,0,9.81\n0.5,\x000,0,0,0,0,9.81\n")
    with pytest.raises(RecordingError, match="line 3: a NUL byte"):
        load_recording(nul)


def test_a_long_file_is_read_only_as_far_as_asked(tmp_path):
    """A damaged row far past the requested duration is never reached with
    max_duration_s, and stops a whole read: the rest of the file is not parsed."""
    long = _uniform(100.0, 60.0, lambda t: 0.3 * np.sin(t))
    text = recording_to_csv(long) + "not,a,row\n"
    path = _write(tmp_path, text)
    with pytest.raises(RecordingError, match=r"line .*: 3 values"):
        load_recording(path)
    short = load_recording(path, max_duration_s=3.0)
    assert 3.0 <= short.duration_s <= 3.0 + 0.5 + 0.01
    np.testing.assert_allclose(short.f[:, 0], 0.3 * np.sin(short.t), atol=1e-9)


def test_an_isolated_glitch_is_kept_and_a_corrupt_column_refused(motion, tmp_path):
    """A 22 g one-sample ground contact loads (the plausibility guard holds it); the same
    value over many samples, or any value beyond 100 g, is a corrupt column."""
    glitch = motion.f.copy()
    glitch[65, 2] = 22 * GRAVITY  # at 0.65 s
    path = _write(tmp_path, recording_to_csv(Recording(motion.t, motion.omega, glitch)))
    loaded = load_recording(path)
    assert loaded.f[65, 2] == pytest.approx(22 * GRAVITY)
    spread = motion.f.copy()
    spread[100:110, 2] = 22 * GRAVITY  # ten samples in a row: not a glitch
    path = _write(tmp_path, recording_to_csv(Recording(motion.t, motion.omega, spread)))
    with pytest.raises(RecordingError, match="beyond any vehicle"):
        load_recording(path)


def test_a_recording_that_is_not_mostly_level_loads_once_its_header_says_so(motion, tmp_path):
    """A parabolic flight's specific force: median f_z near 0. Refused with the way out in
    the message; loaded with `# level: false`."""
    parabola = Recording(motion.t, motion.omega, motion.f - [0, 0, GRAVITY])
    text = recording_to_csv(parabola)
    with pytest.raises(RecordingError, match="'# level: false'"):
        load_recording(_write(tmp_path, text, "parabola.csv"))
    lines = text.splitlines()
    lines.insert(1, "# level: false")
    loaded = load_recording(_write(tmp_path, "\n".join(lines), "parabola_level.csv"))
    np.testing.assert_allclose(loaded.f, parabola.f)
