"""Drives: the car's IMU against closed forms, the road against ISO 8608, the command.

Oracles: a steady circle's centripetal acceleration v^2 / R (R fitted to the car's own
path), a straight stop's deceleration (the derivative of the car's own speed), gravity at
rest, a rigid body's lever-arm terms for a spin of known rate, and the ISO 8608 PSD
through scipy's Welch estimate.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from mca_drake.references.driving import drive
from mca_drake.references.driving.car import GRAVITY, Car, body_motion, lever_arm
from mca_drake.references.driving.courses import SPACING_M, Course, braking
from mca_drake.references.driving.drive import SUBSTEPS, _settled
from mca_drake.references.driving.driver import Driver
from mca_drake.references.driving.road import ROAD_CLASSES, road_profile, road_psd


def _drive_course(course: Course, seconds: float):
    """The car on `course` for `seconds`: positions (T, 2), speeds (T,), omega and f (T, 3)
    at the centre of gravity, roll and pitch (T, 2), at 100 Hz."""
    car = _settled("bmw-320i", float(course.speed[0]))
    driver = Driver(course, car)
    rows = []
    for _ in range(round(seconds * 100)):
        omega, f, angles = body_motion(car.state, car.derivative)
        rows.append((*car.position, car.speed, *omega, *f, *angles))
        command = driver.command()
        for _ in range(SUBSTEPS):
            car.step(*command)
    a = np.array(rows)
    return a[:, :2], a[:, 2], a[:, 3:6], a[:, 6:9], a[:, 9:11]


def test_steady_cornering_feels_v_squared_over_r():
    """On a 60 m circle at 15 m/s, the lateral acceleration (the body-frame specific force
    with the roll's share of gravity taken out) is v^2 / R of the car's own path."""
    radius, speed = 60.0, 15.0
    angle = np.arange(0.0, 4 * np.pi, SPACING_M / radius)
    course = Course(
        radius * np.sin(angle), radius * (1 - np.cos(angle)), np.full(angle.size, speed)
    )
    position, v, omega, f, angles = _drive_course(course, 20.0)
    steady = slice(1000, None)
    # the path's radius, fitted (algebraic circle fit) to the car's positions
    x, y = position[steady].T
    A = np.column_stack([x, y, np.ones_like(x)])
    cx, cy, c = np.linalg.lstsq(A, x * x + y * y, rcond=None)[0]
    fitted = np.sqrt(c + (cx / 2) ** 2 + (cy / 2) ** 2)
    phi = angles[steady, 0]
    lateral = f[steady, 1] * np.cos(phi) - f[steady, 2] * np.sin(phi)
    np.testing.assert_allclose(lateral, v[steady] ** 2 / fitted, rtol=0.02)
    np.testing.assert_allclose(omega[steady, 2], v[steady] / fitted, rtol=0.02)
    assert np.all(phi > 0.0)  # rolling outward: the right side down in a left turn


def test_straight_braking_feels_the_deceleration():
    """Braking in a straight line, f_x is minus the car's own deceleration (with the
    pitch's share of gravity taken out), and the nose dives."""
    _, v, _, f, angles = _drive_course(braking(25.0, 5.0), 6.0)
    braking_phase = (v > 5.0) & (np.gradient(v, 0.01) < -3.0)
    theta = angles[braking_phase, 1]
    longitudinal = f[braking_phase, 0] * np.cos(theta) + f[braking_phase, 2] * np.sin(theta)
    decel = -np.gradient(v, 0.01)[braking_phase]
    np.testing.assert_allclose(longitudinal, -decel, atol=0.15)
    assert np.median(decel) == pytest.approx(5.0, rel=0.1)
    assert np.all(theta > 0.0)  # ISO 8855: nose down is positive pitch


def test_a_car_at_rest_and_a_stopped_drive_feel_gravity():
    car = Car("bmw-320i", 0.0)
    for _ in range(1500):  # 3 s: the suspension settles from its initial state
        car.step(0.0, 0.0)
    omega, f, (phi, theta) = body_motion(car.state, car.derivative)
    # gravity alone, seen through the body's static attitude on its springs (about 0.1
    # degree nose down: the model's front and rear springs under the weight)
    expected = GRAVITY * np.array(
        [-np.sin(theta), np.cos(theta) * np.sin(phi), np.cos(theta) * np.cos(phi)]
    )  # written out here: the test's own oracle, not the package's helper
    np.testing.assert_allclose(f, expected, atol=1e-4)
    assert abs(theta) < np.radians(0.5) and abs(phi) < 1e-6
    np.testing.assert_allclose(omega, 0.0, atol=1e-4)  # the last of the settling
    recording = drive("braking", 20.0, seed=1, road_class="", head_offset_m=(0.0, 0.0, 0.0))
    np.testing.assert_allclose(recording.f[-1], [0.0, 0.0, GRAVITY], atol=1e-3)
    np.testing.assert_allclose(recording.omega[-1], 0.0, atol=1e-6)


def test_the_head_offset_adds_the_lever_arm_terms():
    """A spin about z at rate w = a t: the head 1 m ahead feels -w^2 along x (centripetal)
    and a along y (tangential), the closed forms of dw/dt x r + w x (w x r)."""
    t = np.arange(0.0, 2.0, 0.01)
    accel = 0.5
    omega = np.column_stack([np.zeros_like(t), np.zeros_like(t), accel * t])
    f = np.tile([0.0, 0.0, GRAVITY], (t.size, 1))
    head = lever_arm(omega, f, np.array([1.0, 0.0, 0.0]), 0.01)
    np.testing.assert_allclose(head[:, 0], -((accel * t) ** 2), atol=1e-9)
    np.testing.assert_allclose(head[:, 1], accel, atol=1e-9)
    np.testing.assert_allclose(head[:, 2], GRAVITY)
    # in a drive: the offset's difference is exactly the lever arm of the CG's motion
    centre = drive("slalom", 8.0, seed=2, road_class="", head_offset_m=(0.0, 0.0, 0.0))
    offset = np.array([0.2, 0.4, 0.6])
    moved = drive("slalom", 8.0, seed=2, road_class="", head_offset_m=offset)
    expected = lever_arm(centre.omega, centre.f, offset, 0.01)
    np.testing.assert_allclose(moved.f, expected, atol=1e-9)


def test_road_profiles_have_the_iso_8608_spectrum():
    for road_class in ("A", "C", "E"):
        z = road_profile(4000.0, road_class, np.random.default_rng(3))
        n, psd = scipy.signal.welch(z, fs=1 / 0.05, nperseg=8192)
        band = (n > 0.05) & (n < 2.0)
        ratio = psd[band] / road_psd(n[band], road_class)
        assert np.median(ratio) == pytest.approx(1.0, rel=0.1), road_class
    assert ROAD_CLASSES["B"] == pytest.approx(4 * ROAD_CLASSES["A"])


@pytest.mark.parametrize(
    "manoeuvre", ["double-lane-change", "slalom", "circle", "lap", "proving-ground"]
)
def test_every_manoeuvre_drives_to_a_sane_recording(manoeuvre):
    recording = drive(manoeuvre, 8.0, seed=5)
    assert recording.rate_hz == pytest.approx(100.0) and recording.t[-1] == pytest.approx(8.0)
    assert np.all(np.isfinite(recording.f)) and np.abs(recording.f).max() < 20.0
    assert recording.metadata["manoeuvre"] == manoeuvre
    assert recording.metadata["road_class"] == "B"


def test_a_seed_is_a_drive():
    first, again = (drive("double-lane-change", 4.0, seed=5) for _ in range(2))
    np.testing.assert_array_equal(again.f, first.f)
    other = drive("double-lane-change", 4.0, seed=6)
    assert np.abs(other.f - first.f).max() > 0.1


def test_a_lap_drive_without_a_duration_lasts_one_lap():
    """A lap's natural length is one lap: the closed course's length (its points' own
    polyline, measured here) at its mean target speed, plus the standing start's 5 s."""
    from mca_drake.references.driving.drive import draw_course, natural_duration_s

    course = draw_course("lap", np.random.default_rng(0)).course
    assert course.closed
    lap_m = np.hypot(np.diff(course.x), np.diff(course.y)).sum()
    expected = lap_m / course.speed.mean() + 5.0
    assert natural_duration_s(course) == pytest.approx(expected, rel=0.01)
    assert 20.0 < natural_duration_s(course) < 600.0


def test_bad_drives_are_refused():
    with pytest.raises(ValueError, match="unknown manoeuvre"):
        drive("drift", 5.0, 0)
    with pytest.raises(ValueError, match="unknown car"):
        drive("braking", 5.0, 0, car="tractor")
    with pytest.raises(ValueError, match="unknown road class"):
        drive("braking", 5.0, 0, road_class="Z")
    with pytest.raises(ValueError, match="head_offset_m"):
        drive("braking", 5.0, 0, head_offset_m=(0.0, 1.0))
    with pytest.raises(ValueError, match="duration_s"):
        drive("braking", -1.0, 0)


def test_the_drive_command_writes_a_recording(tmp_path):
    from mca_drake.app.cli import main
    from mca_drake.references.recording import load_recording

    out = tmp_path / "drive.csv"
    assert (
        main(["drive", "--manoeuvre", "braking", "--seed", "3", "--out", str(out), "--quiet"]) == 0
    )
    recording = load_recording(out)
    assert recording.metadata["manoeuvre"] == "braking"
    assert recording.f[:, 0].min() < -3.0  # it braked
    # its header names the car, so that the default DPC cues it as a car
    from mca_drake.cueing.dpc import DpcConfig, for_vehicle
    from mca_drake.references.flights import FlightSpec, flight_reference

    assert recording.metadata["vehicle"] == "bmw-320i"
    reference = flight_reference(FlightSpec(recording=str(out)), 2.0)
    assert reference.vehicle == "bmw-320i"
    assert for_vehicle(DpcConfig(), reference.vehicle).policy_path("kr500").name == (
        "ground_policy.npz"
    )


def test_a_drive_spec_is_driven_once_and_cached(tmp_path):
    from mca_drake.references.drives import DriveSpec, motion_reference

    spec = DriveSpec(manoeuvre="braking", seed=9, road_class="", head_offset_m=[0.0, 0.0, 0.0])
    reference = motion_reference(spec, 12.0, cache_dir=tmp_path)
    (cached,) = tmp_path.iterdir()
    assert cached.name == "drive_braking_bmw-320i_smooth_0_0_0_9_12s.csv"
    again = motion_reference(spec, 12.0, cache_dir=tmp_path)
    np.testing.assert_allclose(again.y, reference.y, atol=1e-6)
    assert reference.name == "built-in braking drive (bmw-320i), seed 9"
    # the reference is the drive's recording, scaled as flights are
    from mca_drake.references.reference import reference_from_recording

    direct = drive("braking", 12.0, 9, road_class="", head_offset_m=(0.0, 0.0, 0.0))
    np.testing.assert_allclose(reference.y, reference_from_recording(direct).y, atol=1e-6)
    for bad, match in (
        (DriveSpec(manoeuvre="drift"), "unknown drive manoeuvre"),
        (DriveSpec(car="tractor"), "unknown car"),
        (DriveSpec(road_class="Q"), "unknown road class"),
        (DriveSpec(head_offset_m=[0.0]), "head_offset_m"),
    ):
        with pytest.raises(ValueError, match=match):
            bad.validate()


def test_a_scenario_cues_a_drive_where_a_flight_would_be(tmp_path):
    """A !DriveSpec in a closed-loop scenario's `flight`: loaded, driven, cued."""
    from mca_drake.app.jobs import run_scenario
    from mca_drake.app.scenarios import load_scenario
    from mca_drake.references.drives import DriveSpec

    path = tmp_path / "drive.yaml"
    path.write_text(
        "scenario: !ClosedLoopScenario\n  mca: washout\n  plant: analytical\n"
        "  flight: !DriveSpec {manoeuvre: slalom, seed: 3, road_class: ''}\n"
        f"  duration_s: 4.0\n  output_dir: {tmp_path / 'out'}\n"
    )
    scenario = load_scenario(path, ["{flight: {seed: 4}}"])
    assert scenario.flight == DriveSpec(manoeuvre="slalom", seed=4, road_class="")
    summary = run_scenario(scenario, progress=False)
    assert summary["reference"] == "built-in slalom drive (bmw-320i), seed 4"
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
