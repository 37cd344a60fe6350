"""JSBSim flights with the scripted pilot: axis conventions against physics, determinism, sanity.

Oracles are physics, not numbers the code printed: the specific force of unaccelerated flight
from the attitude alone, Euler-angle kinematics linking the recorded body rates to the logged
attitude, the turn rate of a coordinated turn, and the take-off acceleration from the airspeed.
Short explicit-maneuver flights in calm air keep the default run to a few seconds.
"""

from __future__ import annotations

from pathlib import Path

import jsbsim
import numpy as np
import pytest

from mca_drake.references.flights import FlightSpec
from mca_drake.references.jsbsim import (
    FULL_FLIGHT_MIN_DURATION_S,
    JSBSIM_MODELS,
    TRAINING_VEHICLES,
    UNSEEN_VEHICLES,
    VALIDATION_VEHICLES,
    VEHICLES,
    AltitudeChange,
    BankReversals,
    Doublet,
    FlightConfig,
    FlightError,
    Level,
    Stall,
    Takeoff,
    Turn,
    check_training_vehicle,
    default_config,
    fly,
    fly_with_log,
)
from mca_drake.references.recording import check_units

G = 9.81
# JSBSim's WGS84 gravity less the centripetal part of the Earth's rotation is 9.78 to 9.83
# m/s^2 depending on latitude; the trimmed pilot adds < 0.03 m/s^2 of residual acceleration.
GRAVITY_ATOL = 0.1


def calm(*maneuvers, **kwargs) -> FlightConfig:
    """Explicit maneuvers in still air (turbulence would blur the physics checks)."""
    return FlightConfig(
        maneuvers=tuple(maneuvers), turbulence_severity=0, turbulence_patch_severity=0, **kwargs
    )


def head_rates_to_body(omega: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Head-axis rates (x fwd, y left, z up) back to body rates p, q, r (y right, z down)."""
    return omega[:, 0], -omega[:, 1], -omega[:, 2]


# --------------------------------------------------------------------------- axes vs physics


@pytest.mark.parametrize("vehicle", ["light", "jet"])
def test_level_flight_reads_gravity_and_no_rotation(vehicle):
    recording, log = fly_with_log(vehicle, 30.0, seed=1, config=calm(Level(30.0)))
    steady = recording.t > 5.0  # after the altitude and speed loops have settled
    phi, theta = log.attitude[steady, 0], log.attitude[steady, 1]
    # Unaccelerated: the accelerometer reads -g rotated into the head frame, which depends on
    # the attitude only: f = g (sin theta, sin phi cos theta, cos phi cos theta).
    expected = G * np.column_stack(
        [np.sin(theta), np.sin(phi) * np.cos(theta), np.cos(phi) * np.cos(theta)]
    )
    np.testing.assert_allclose(recording.f[steady], expected, atol=GRAVITY_ATOL)
    # Level and straight: rates of a few milli-rad/s at most (the loops' corrections).
    assert np.max(np.abs(recording.omega[steady])) < 0.01
    if vehicle == "light":
        # It flies level at < 1 deg pitch, so f is (0, 0, +g): z up, specific force.
        np.testing.assert_allclose(recording.f[steady].mean(axis=0), [0, 0, G], atol=0.15)
    else:
        # The jet cruises at 5 deg angle of attack: f_x = g sin(theta) ~ 0.85 m/s^2, f_z ~ +g.
        assert 0.5 < recording.f[steady, 0].mean() < 1.2
        assert abs(recording.f[steady, 2].mean() - G) < GRAVITY_ATOL


def test_roll_to_the_right_gives_positive_omega_x():
    recording, log = fly_with_log("light", 8.0, seed=1, config=calm(Turn(np.radians(45), 20.0)))
    rolling_in = (recording.t > 0.3) & (recording.t < 2.0)
    assert np.all(np.diff(log.attitude[rolling_in, 0]) > 0)  # right wing going down
    assert recording.omega[rolling_in, 0].mean() > 0.1  # rad/s


def test_coordinated_right_turn_gives_negative_omega_z():
    bank = np.radians(30)
    recording, log = fly_with_log("light", 25.0, seed=1, config=calm(Turn(bank, 30.0)))
    steady = recording.t > 10.0
    phi = log.attitude[steady, 0]
    np.testing.assert_allclose(phi, bank, atol=np.radians(3))
    assert np.all(recording.omega[steady, 2] < 0)  # yawing right about an up axis
    # Coordinated level turn: turn rate g tan(phi) / V (V true airspeed, within a few % of the
    # calibrated one at 600 m), ball centred (f_y ~ 0), load factor 1 / cos(phi).
    heading_rate = np.gradient(np.unwrap(log.attitude[:, 2]), recording.t)[steady]
    true_airspeed = log.airspeed_mps[steady] * 1.03
    np.testing.assert_allclose(heading_rate, G * np.tan(phi) / true_airspeed, rtol=0.1)
    assert abs(recording.f[steady, 1].mean()) < 0.3
    np.testing.assert_allclose(recording.f[steady, 2].mean(), G / np.cos(bank), atol=0.3)


def test_body_rates_match_the_attitude_kinematics():
    """phi', theta', psi' from the logged Euler angles equal the usual maps of p, q, r."""
    plan = calm(
        BankReversals(np.radians(40), 3.0, 12.0),
        Doublet("elevator", 0.1, 1.0, 3.0),
        Doublet("rudder", 0.3, 1.0, 3.0),
    )
    recording, log = fly_with_log("light", 30.0, seed=2, config=plan)
    p, q, r = head_rates_to_body(recording.omega)
    phi, theta, psi = log.attitude.T
    t = recording.t
    phi_dot = np.gradient(phi, t)
    theta_dot = np.gradient(theta, t)
    psi_dot = np.gradient(np.unwrap(psi), t)
    inside = slice(2, -2)  # central differences are one-sided at the ends
    np.testing.assert_allclose(
        phi_dot[inside],
        (p + (q * np.sin(phi) + r * np.cos(phi)) * np.tan(theta))[inside],
        atol=0.02,
    )
    np.testing.assert_allclose(
        theta_dot[inside], (q * np.cos(phi) - r * np.sin(phi))[inside], atol=0.02
    )
    np.testing.assert_allclose(
        psi_dot[inside], ((q * np.sin(phi) + r * np.cos(phi)) / np.cos(theta))[inside], atol=0.02
    )
    assert np.max(np.abs(p)) > 0.3  # the flight did roll hard


def test_take_off_run_shows_positive_f_x():
    config = calm(Takeoff(), from_ground=True)
    recording, log = fly_with_log("light", 40.0, seed=1, config=config)
    assert log.on_ground[0] and not log.on_ground[-1]
    rolling = log.on_ground & (log.airspeed_mps > 5.0) & (log.airspeed_mps < 25.0)
    assert rolling.sum() > 300  # several seconds of ground run
    assert np.all(recording.f[rolling, 0] > 1.0)  # pushed back into the seat
    # On the ground run f_x = dV/dt + g sin(theta) (still air, no rotation).
    acceleration = np.gradient(log.airspeed_mps, recording.t)[rolling]
    expected = acceleration + G * np.sin(log.attitude[rolling, 1])
    np.testing.assert_allclose(recording.f[rolling, 0].mean(), expected.mean(), atol=0.3)


# ---------------------------------------------------------------------------- the recording


def test_same_seed_same_recording_and_different_seeds_differ():
    first = fly("light", 20.0, seed=7)
    again = fly("light", 20.0, seed=7)
    other = fly("light", 20.0, seed=8)
    np.testing.assert_array_equal(first.as_array(), again.as_array())
    assert first.metadata == again.metadata
    assert not np.allclose(first.f, other.f)


@pytest.mark.parametrize("vehicle", ["light", "jet"])
def test_short_default_flight_is_sane_at_100_hz(vehicle):
    recording = fly(vehicle, 30.0, seed=3)
    assert recording.t.shape == (3001,)
    np.testing.assert_allclose(recording.t, 0.01 * np.arange(3001), rtol=0, atol=1e-12)
    assert np.all(np.isfinite(recording.as_array()))
    check_units(recording, where=f"{vehicle} flight")  # SI units, z-up head axes
    meta = recording.metadata
    assert meta["vehicle"] == vehicle
    assert meta["jsbsim_model"] == {"light": "c172p", "jet": "global5000"}[vehicle]
    assert meta["jsbsim_version"] == jsbsim.__version__
    assert meta["seed"] == "3" and float(meta["duration_s"]) == 30.0
    assert meta["from_ground"] == "false"  # shorter than FULL_FLIGHT_MIN_DURATION_S
    assert 30.0 < FULL_FLIGHT_MIN_DURATION_S[vehicle]


def test_stall_and_recovery_stays_sane():
    recording, log = fly_with_log("light", 90.0, seed=4, config=calm(Stall()))
    assert log.airspeed_mps.min() < 26.0  # reached the stall (clean stall about 25 m/s)
    assert log.airspeed_mps[-1] > 40.0  # and recovered
    assert np.all(np.isfinite(recording.f))


def test_flight_chatter_stays_quiet_and_writes_no_files(capfd):
    output = Path(jsbsim.get_default_root_dir()) / "global5000.csv"
    before = output.stat().st_mtime_ns if output.exists() else None
    fly("jet", 1.0, seed=0)
    after = output.stat().st_mtime_ns if output.exists() else None
    assert before == after  # the model's <output> directive goes to os.devnull
    captured = capfd.readouterr()
    assert captured.out == "" and captured.err == ""


# ------------------------------------------------------------------------------------ errors


def test_bad_vehicle_lists_the_valid_ones():
    with pytest.raises(ValueError, match=r"unknown vehicle 'x'; valid: light, jet"):
        fly("x", 10.0, seed=0)


@pytest.mark.parametrize("reserved", ["737", "pa28"])
def test_reserved_aircraft_are_refused_by_name(reserved):
    with pytest.raises(ValueError, match="reserved for unseen-vehicle checks"):
        fly(reserved, 10.0, seed=0)
    with pytest.raises(ValueError, match="reserved"):
        FlightSpec(vehicle=reserved, seed=1000).validate()


def test_airborne_only_vehicles_refuse_a_ground_start():
    with pytest.raises(ValueError, match="airborne only"):
        fly("A320", 10.0, seed=0, config=FlightConfig(from_ground=True))
    assert FULL_FLIGHT_MIN_DURATION_S["A320"] == float("inf")


def test_bad_config_is_refused():
    with pytest.raises(ValueError, match="turbulence_severity"):
        fly("light", 1.0, seed=0, config=FlightConfig(turbulence_severity=9))
    with pytest.raises(ValueError, match="doublet control 'stick'"):
        fly("light", 1.0, seed=0, config=FlightConfig(maneuvers=(Doublet("stick"),)))
    with pytest.raises(ValueError, match="duration_s"):
        fly("light", 0.0, seed=0)


def test_dive_into_the_ground_raises_flight_error():
    config = calm(
        AltitudeChange(altitude_change_m=-500.0, vertical_speed_mps=8.0),
        maneuver_altitude_m=150.0,
        min_altitude_m=100.0,
    )
    with pytest.raises(
        FlightError,
        match=r"light flight \(seed 3\) failed at t = \d+\.\d+ s during 'altitudechange.*"
        r"hit the ground at \d+\.\d m/s sink",
    ):
        fly("light", 60.0, seed=3, config=config)


def test_default_config_fills_every_field():
    for vehicle in ("light", "jet"):
        config = default_config(vehicle)
        for name in ("turbulence_severity", "max_bank_rad", "maneuver_altitude_m"):
            assert getattr(config, name) is not None
    assert default_config("jet").cruise_speed_mps > default_config("light").cruise_speed_mps


# ------------------------------------------------------------------------------- full flights


@pytest.mark.slow
def test_fifteen_minute_light_flight_takes_off_turns_steeply_and_lands():
    recording, log = fly_with_log("light", 900.0, seed=0)
    assert recording.metadata["from_ground"] == "true"
    names = [name for _, name in log.phases]
    assert any(name.startswith("taxi") for name in names)
    takeoff = next(start for start, name in log.phases if name.startswith("takeoff"))
    # The take-off roll pushes the pilot back until the wheels leave the ground.
    after = recording.t > takeoff
    lift_off = recording.t[after][np.argmax(~log.on_ground[after])]
    roll = after & (recording.t < lift_off) & (log.airspeed_mps > 5.0)
    assert roll.sum() > 500 and recording.f[roll, 0].mean() > 1.0
    # Steep turns: bank beyond 40 deg, with the load factor that goes with them.
    steep = np.abs(log.attitude[:, 0]) > np.radians(40)
    assert steep.sum() > 500  # more than 5 s
    assert recording.f[steep, 2].max() > 1.3 * G
    assert any(name.startswith("stall") for name in names)
    assert any(name.startswith("landing") for name in names)
    # It ends stopped on its wheels.
    assert log.on_ground[-1] and log.airspeed_mps[-1] < 2.0
    check_units(recording, where="light flight")


@pytest.mark.slow
def test_fifteen_minute_jet_flight_lands():
    recording, log = fly_with_log("jet", 900.0, seed=0)
    assert log.on_ground[0] and log.on_ground[-1] and log.airspeed_mps[-1] < 2.0
    assert np.abs(log.attitude[:, 0]).max() > np.radians(30)
    assert log.height_m.max() > 1500.0
    check_units(recording, where="jet flight")


@pytest.mark.parametrize("vehicle", [v for v in VEHICLES if v not in ("light", "jet")])
def test_every_other_vehicle_trims_level_and_reads_gravity(vehicle):
    """Each airborne-only airframe trims and holds level flight: the accelerometer reads
    gravity through the attitude plus the along-track acceleration (the autothrottle's slow
    speed swings: d(airspeed)/dt by finite differences), and the rates stay near zero
    (physics, not numbers the code printed)."""
    recording, log = fly_with_log(vehicle, 20.0, seed=1, config=calm(Level(20.0)))
    steady = recording.t > 5.0
    speed_rate = np.gradient(log.airspeed_mps, recording.t)[steady]
    phi, theta = log.attitude[steady, 0], log.attitude[steady, 1]
    expected = np.column_stack(
        [
            G * np.sin(theta) + speed_rate,
            G * np.sin(phi) * np.cos(theta),
            G * np.cos(phi) * np.cos(theta),
        ]
    )
    np.testing.assert_allclose(recording.f[steady], expected, atol=2 * GRAVITY_ATOL)
    assert np.max(np.abs(recording.omega[steady])) < 0.02
    assert recording.metadata["jsbsim_model"] == JSBSIM_MODELS[vehicle]


def test_training_and_unseen_vehicles_are_apart():
    assert not set(TRAINING_VEHICLES) & set(UNSEEN_VEHICLES)
    assert not set(VALIDATION_VEHICLES) & (set(TRAINING_VEHICLES) | set(UNSEEN_VEHICLES))
    for vehicle in UNSEEN_VEHICLES + VALIDATION_VEHICLES:
        with pytest.raises(ValueError, match="kept for"):
            check_training_vehicle(vehicle)
    assert {"light", "jet"} <= set(TRAINING_VEHICLES)
    assert not {"737", "pa28"} & set(VEHICLES)


@pytest.mark.slow
@pytest.mark.parametrize("vehicle", [v for v in VEHICLES if v not in ("light", "jet")])
def test_random_plans_of_every_other_vehicle_fly_without_flight_error(vehicle):
    for seed in range(3):
        recording = fly(vehicle, 300.0, seed=seed)
        assert np.all(np.isfinite(recording.as_array()))
        check_units(recording, where=f"{vehicle} flight")


@pytest.mark.slow
@pytest.mark.parametrize("vehicle", ["light", "jet"])
def test_many_seeds_fly_without_flight_error(vehicle):
    for seed in range(10, 16):
        recording, log = fly_with_log(vehicle, 900.0, seed=seed)
        assert log.on_ground[-1], f"{vehicle} seed {seed} did not land in time"
        assert np.all(np.isfinite(recording.as_array()))
