"""Controls and vehicle state in recordings: optional named columns, kept by the loader in
SI, written back exactly, resampled with the motion, and recorded by JSBSim flights.

Oracles: unit conversions worked by hand (knots, degrees, feet), numpy's interpolation,
the file written and read back, and the aircraft's physics: a command comes before the
motion it commands, with the sign `vehicle_signals` documents."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.references.jsbsim import fly
from mca_drake.references.recording import (
    Recording,
    RecordingError,
    load_recording,
    save_recording,
)

HEADER = "t,omega_x,omega_y,omega_z,f_x,f_y,f_z"


def write(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n")
    return path


def imu_rows(t, extra):
    return [[ti, 0.0, 0.0, 0.0, 0.0, 0.0, 9.81, *e] for ti, e in zip(t, extra, strict=True)]


def test_signal_columns_load_in_si_and_other_columns_are_ignored(tmp_path):
    t = np.arange(0, 1.0, 0.01)
    extra = [(0.5, 100.0, 10.0, 1000.0, 7.0, 1.0) for _ in t]
    path = write(
        tmp_path / "r.csv",
        HEADER + ",throttle,speed [kt],roll [deg],height [ft],gear_noise,on_ground",
        imu_rows(t, extra),
    )
    recording = load_recording(path)
    assert sorted(recording.signals) == ["height", "on_ground", "roll", "speed", "throttle"]
    np.testing.assert_allclose(recording.signals["throttle"], 0.5)
    np.testing.assert_allclose(recording.signals["speed"], 100 * 1852 / 3600)  # knots
    np.testing.assert_allclose(recording.signals["roll"], np.deg2rad(10.0))
    np.testing.assert_allclose(recording.signals["height"], 304.8)  # 1000 ft
    np.testing.assert_allclose(recording.signals["on_ground"], 1.0)


def test_signals_are_written_back_exactly(tmp_path, rng):
    t = np.arange(0, 2.0, 0.01)
    signals = {"steering": rng.uniform(-1, 1, t.size), "speed": rng.uniform(0, 40, t.size)}
    omega, f = rng.normal(scale=0.1, size=(t.size, 3)), rng.normal(size=(t.size, 3))
    f[:, 2] += 9.81
    original = Recording(t, omega, f, {"vehicle": "bmw-320i"}, signals)
    again = load_recording(save_recording(tmp_path / "r.csv", original))
    assert list(again.signals) == ["steering", "speed"]
    for name, values in signals.items():
        np.testing.assert_array_equal(again.signals[name], values)
    np.testing.assert_array_equal(again.omega, omega)


def test_signals_are_resampled_with_the_motion(tmp_path):
    t = np.arange(0, 2.0, 0.005)  # 200 Hz
    brake = np.clip((t - 0.5) * 2.0, 0.0, 1.0)
    path = write(tmp_path / "r.csv", HEADER + ",brake", imu_rows(t, [(b,) for b in brake]))
    recording = load_recording(path)  # to 100 Hz
    np.testing.assert_allclose(recording.t, np.arange(0, 1.995 + 1e-9, 0.01))
    np.testing.assert_allclose(recording.signals["brake"], np.interp(recording.t, t, brake))
    sliced = recording.sliced(0.5, 1.0)
    assert sliced.signals["brake"].shape == sliced.t.shape


def test_a_control_in_percent_or_an_unknown_unit_is_one_clear_error(tmp_path):
    t = np.arange(0, 1.0, 0.01)
    path = write(tmp_path / "p.csv", HEADER + ",throttle", imu_rows(t, [(80.0,) for _ in t]))
    with pytest.raises(RecordingError, match=r"throttle spans 80 .* is it in percent"):
        load_recording(path)
    path = write(tmp_path / "u.csv", HEADER + ",speed [furlong/h]", imu_rows(t, [(1,) for _ in t]))
    with pytest.raises(RecordingError, match="column speed: unknown unit 'furlong/h'"):
        load_recording(path)
    with pytest.raises(RecordingError, match="unknown signal 'stick'"):
        Recording(t, np.zeros((t.size, 3)), np.zeros((t.size, 3)), signals={"stick": t})


def _lagged_correlation(command, motion, lag_steps):
    return float(np.corrcoef(command[:-lag_steps], motion[lag_steps:])[0, 1])


def test_a_jsbsim_flight_records_the_commands_before_the_motion_they_command():
    recording = fly("light", 120.0, 100)
    s = recording.signals
    assert {"aileron", "elevator", "rudder", "throttle", "brake", "speed", "on_ground"} <= set(s)
    omega = recording.omega  # head frame: x forward, y left, z up
    # aileron: positive rolls right (a positive omega_x), 0.3 s later
    assert _lagged_correlation(s["aileron"], omega[:, 0], 30) > 0.5
    # rudder: positive yaws the nose right (a negative omega_z): it coordinates the turns
    assert _lagged_correlation(s["rudder"], -omega[:, 2], 30) > 0.3
    # elevator: a step up pitches the nose up (a negative omega_y) 0.05 s later
    assert _lagged_correlation(np.diff(s["elevator"]), -np.diff(omega[:, 1]), 5) > 0.2
    assert 20.0 < np.median(s["speed"]) < 80.0  # a light aircraft's airspeed, m/s


def test_a_drive_records_the_drivers_controls_before_the_motion():
    from mca_drake.references.driving.drive import drive

    lane_change = drive("double-lane-change", None, 3)
    s = lane_change.signals
    assert {"steering", "throttle", "brake", "speed", "on_ground"} <= set(s)
    # steering: positive turns left (a positive omega_z), 0.2 s later
    assert _lagged_correlation(s["steering"], lane_change.omega[:, 2], 20) > 0.8
    stop = drive("braking", None, 3)
    s = stop.signals
    # the brake decelerates (a negative f_x) and the car comes to rest
    assert _lagged_correlation(s["brake"], -stop.f[:, 0], 10) > 0.8
    assert s["speed"][0] > 10.0 and s["speed"][-1] == 0.0
