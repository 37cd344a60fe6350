"""A drive: a car driven through a manoeuvre on a rough road, as the driver's head feels it.

`drive(manoeuvre, duration_s, seed)` draws the manoeuvre's settings from the seed
(`draw_course`), drives it with the multi-body car (`car.Car`) and the driver
(`driver.Driver`) at `car.STEP_S`, samples the sprung mass's motion at 100 Hz, adds the
road's roughness (`road`), moves the specific force to the driver's head, and returns a
`Recording` (head frame x forward, y left, z up; SI; at rest f = (0, 0, +9.81)).

Road roughness. The multi-body model drives on a flat road, so the road's profile acts on
top of it through linear quarter-car models, one per wheel (the model's own sprung mass
share, spring and damper per corner), superposed on the model's motion: each corner's
body displacement z_i from its wheel's road height (two profiles of the ISO 8608 class,
left and right, each axle's wheel meeting the front's heights a wheelbase later), then
heave (their mean), pitch ((rear - front) / wheelbase, ISO: nose down positive) and roll
((left - right) / track) and their rates and accelerations. The tyre's own stiffness and
the wheel hop are left out of this part: the profile's wavelengths above about 0.35 m
reach the body below the wheel-hop frequency.

Head offset. The specific force at the head, r from the centre of gravity (body frame,
`head_offset_m`), adds the rigid body's lever-arm terms dw/dt x r + w x (w x r)
(`car.lever_arm`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import signal
from tqdm.auto import tqdm

from mca_drake.references.driving.car import (
    STEP_S,
    Car,
    body_motion,
    check_car,
    gravity_in_body,
    lever_arm,
)
from mca_drake.references.driving.courses import (
    MANOEUVRES,
    Course,
    braking,
    circle,
    double_lane_change,
    lap,
    proving_ground,
    slalom,
)
from mca_drake.references.driving.driver import Driver, DriverGains
from mca_drake.references.driving.road import ROAD_CLASSES, road_profile
from mca_drake.references.recording import Recording

SAMPLE_RATE_HZ = 100.0
SUBSTEPS = round(1.0 / (SAMPLE_RATE_HZ * STEP_S))
# The driver's head from the centre of gravity of a saloon's left front seat, m, body frame.
DEFAULT_HEAD_OFFSET_M = (0.1, 0.37, 0.55)


@dataclasses.dataclass(frozen=True)
class DriveSettings:
    """What a drive's seed chooses, and the course it gives."""

    manoeuvre: str
    course: Course
    description: str
    gains: DriverGains


def draw_course(
    manoeuvre: str, rng: np.random.Generator, duration_s: float | None = None
) -> DriveSettings:
    """The manoeuvre's settings drawn from `rng`: speeds, sizes and the driver's pace.

    double-lane-change 70-90 km/h, offset 3-3.8 m; slalom 40-60 km/h, cones 18-24 m apart,
    0.6-1.2 m either side (at most 6 m/s^2); braking from 60-120 km/h at 4-9 m/s^2; circle
    radius 40-100 m up to 5-7 m/s^2; laps of a track whose shape is drawn too
    (`random_track`) at up to 3.5-5 m/s^2; a proving-ground road of `duration_s` (default
    300 s) of driving (`courses.proving_ground`).
    """
    if manoeuvre not in MANOEUVRES:
        raise ValueError(f"unknown manoeuvre '{manoeuvre}'; valid: {', '.join(MANOEUVRES)}")
    gains = DriverGains(
        lookahead_s=float(rng.uniform(1.0, 1.4)), steering_gain=float(rng.uniform(6.0, 10.0))
    )
    if manoeuvre == "double-lane-change":
        speed, offset = rng.uniform(70, 90) / 3.6, rng.uniform(3.0, 3.8)
        course = double_lane_change(speed, offset)
        text = f"ISO 3888-1 double lane change at {speed * 3.6:.0f} km/h, offset {offset:.1f} m"
    elif manoeuvre == "slalom":
        speed, spacing = rng.uniform(40, 60) / 3.6, rng.uniform(18, 24)
        # a sine of wavelength 2 spacing at speed v asks for A (pi v / spacing)^2 of lateral
        # acceleration: at most 6 m/s^2, well inside the tyres' grip
        largest = 6.0 / (np.pi * speed / spacing) ** 2
        amplitude = min(rng.uniform(0.6, 1.2), largest)
        course = slalom(speed, spacing, amplitude)
        text = f"slalom at {speed * 3.6:.0f} km/h, cones {spacing:.1f} m apart, {amplitude:.1f} m"
    elif manoeuvre == "braking":
        speed, decel = rng.uniform(60, 120) / 3.6, rng.uniform(4, 9)
        course = braking(speed, decel)
        text = f"braking from {speed * 3.6:.0f} km/h at {decel:.1f} m/s^2"
    elif manoeuvre == "circle":
        radius, lateral = rng.uniform(40, 100), rng.uniform(5, 7)
        course = circle(radius, lateral)
        text = f"steady-state circle, radius {radius:.0f} m, up to {lateral:.1f} m/s^2"
    elif manoeuvre == "proving-ground":
        course = proving_ground(rng, duration_s or 300.0)
        text = f"proving ground: {course.length_m:.0f} m of lane changes, slaloms, bends, braking"
    else:
        lateral = rng.uniform(3.5, 5.0)
        course = lap(random_track(rng), max_lateral_m_s2=lateral)
        text = f"laps of a {course.length_m:.0f} m track at up to {lateral:.1f} m/s^2"
    return DriveSettings(manoeuvre, course, text, gains)


def random_track(rng: np.random.Generator) -> np.ndarray:
    """A closed centre line (400, 2), m: a radius around the loop of 150-220 m with random
    harmonics (2 to 7 waves per lap), stretched 1-1.4 along x: straights, hairpins and
    sweepers in a new order for every seed."""
    t = np.linspace(0.0, 2.0 * np.pi, 400, endpoint=False)
    r = np.full_like(t, rng.uniform(150.0, 220.0))
    for k in range(2, 8):
        r += rng.uniform(0.0, 60.0 / k) * np.cos(k * t + rng.uniform(0, 2 * np.pi))
    return np.column_stack([r * np.cos(t) * rng.uniform(1.0, 1.4), r * np.sin(t)])


def natural_duration_s(course) -> float:
    """How long a drive of `course` lasts when no duration is given, s: its length (to its
    end, or one lap of a closed one) at its mean target speed, plus 5 s for the standing
    start, and at least 10 s."""
    return max(course.length_m / max(float(course.speed.mean()), 1.0) + 5.0, 10.0)


def drive(
    manoeuvre: str,
    duration_s: float | None,
    seed: int,
    *,
    car: str = "bmw-320i",
    road_class: str = "B",
    head_offset_m=DEFAULT_HEAD_OFFSET_M,
    progress: bool = False,
) -> Recording:
    """The recording of a drive: `manoeuvre` (`MANOEUVRES`) drawn from `seed`,
    `duration_s` s long (None: the manoeuvre's course to its end, at least 10 s; a lap
    drive: one lap), on a road of ISO 8608 class `road_class` ("" or None: smooth),
    felt at `head_offset_m` (3, m, body frame) from the centre of gravity.

    Raises:
        ValueError: an unknown manoeuvre, car or road class, or a bad duration or offset.
    """
    check_car(car)
    if road_class and road_class not in ROAD_CLASSES:
        raise ValueError(f"unknown road class '{road_class}'; valid: {', '.join(ROAD_CLASSES)}")
    offset = np.asarray(head_offset_m, dtype=float)
    if offset.shape != (3,) or not np.all(np.isfinite(offset)) or np.abs(offset).max() > 5:
        raise ValueError(f"head_offset_m must be 3 finite values within 5 m; got {head_offset_m}")
    rng = np.random.default_rng(seed)
    settings = draw_course(manoeuvre, rng, duration_s)
    course = settings.course
    if duration_s is None:
        duration_s = natural_duration_s(course)
    if not (math.isfinite(duration_s) and 0.0 < duration_s <= 7200.0):
        raise ValueError(f"duration_s must be in (0, 7200] s; got {duration_s}")
    samples = round(duration_s * SAMPLE_RATE_HZ) + 1
    scale = 1.0
    for _ in range(MAX_ATTEMPTS):
        try:
            omega, force, travelled, vehicle, signals = _drive_course(
                car, _slower(course, scale), settings.gains, samples, manoeuvre, progress
            )
            break
        except LostControlError:
            scale *= SLOWER
    else:
        raise LostControlError(
            f"{manoeuvre} drive, seed {seed}: the car left control {MAX_ATTEMPTS} times, "
            f"down to {scale / SLOWER:.0%} of the course's speed"
        )
    if road_class:
        omega, force = _with_road(omega, force, travelled, vehicle, road_class, rng)
    force = lever_arm(omega, force, offset, 1.0 / SAMPLE_RATE_HZ)
    t = np.arange(samples) / SAMPLE_RATE_HZ
    metadata = {
        "source": "commonroad multi-body car driven by mca_drake.references.driving",
        "speed_scale": f"{scale:g}",
        "vehicle": car,
        "manoeuvre": manoeuvre,
        "description": settings.description,
        "seed": str(seed),
        "duration_s": repr(float(duration_s)),
        "road_class": road_class or "smooth",
        "head_offset_m": " ".join(f"{v:g}" for v in offset),
    }
    signals["on_ground"] = np.ones(samples)
    return Recording(t, omega, force, metadata, signals)


# A drive whose car leaves control (the model's state diverges: a spin) is driven again at
# this share of the course's speeds, at most MAX_ATTEMPTS times in all.
SLOWER = 0.85
MAX_ATTEMPTS = 4
# Beyond these the car has left control: body slip angle, roll (rad), specific force.
MAX_SLIP_RAD, MAX_ROLL_RAD, MAX_FORCE_M_S2 = 0.12, 0.12, 15.0


class LostControlError(RuntimeError):
    """The car left control on every attempt at a drive."""


def _check_control(vehicle: Car, force: np.ndarray, angles: np.ndarray) -> None:
    """LostControlError where the car slides (a body slip angle beyond `MAX_SLIP_RAD`),
    rolls beyond `MAX_ROLL_RAD` or feels more than `MAX_FORCE_M_S2`: the driver model
    would not bring it back as a driver would, and the model's tyres leave their range."""
    x = vehicle.state
    slip = abs(math.atan2(x[10], max(x[3], 1.0)))
    if slip > MAX_SLIP_RAD or abs(angles[0]) > MAX_ROLL_RAD or np.abs(force).max() > MAX_FORCE_M_S2:
        raise LostControlError(
            f"slip {math.degrees(slip):.0f} deg, roll {math.degrees(angles[0]):.0f} deg, "
            f"|f| {np.abs(force).max():.1f} m/s^2"
        )


def _slower(course: Course, scale: float) -> Course:
    """`course` with every target speed times `scale`."""
    return dataclasses.replace(course, speed=course.speed * scale)


def _drive_course(car: str, course: Course, gains, samples: int, manoeuvre, progress):
    """(omega, f (samples, 3) at the centre of gravity, distance travelled (samples,) m,
    the car, the driver's signals) of one attempt at driving `course`; LostControlError
    where the model diverges. The signals (`vehicle_signals`): steering (the front wheels'
    angle over full lock), throttle and brake (the longitudinal command over the model's
    largest acceleration), speed (m/s), each (samples,)."""
    vehicle = _settled(car, float(course.speed[0]))
    driver = Driver(course, vehicle, gains)
    omega = np.zeros((samples, 3))
    force = np.zeros((samples, 3))
    travelled = np.zeros(samples)  # m along the road
    lock, most = vehicle.params.steering.max, vehicle.params.longitudinal.a_max
    signals = {name: np.zeros(samples) for name in ("steering", "throttle", "brake", "speed")}
    bar = tqdm(total=samples - 1, unit="sample", desc=f"{manoeuvre} drive") if progress else None
    distance = 0.0
    try:
        for k in range(samples):
            omega[k], force[k], angles = body_motion(vehicle.state, vehicle.derivative)
            travelled[k] = distance
            signals["steering"][k] = vehicle.steering / lock
            signals["speed"][k] = vehicle.speed
            _check_control(vehicle, force[k], angles)
            if k == samples - 1:
                break
            if driver.stopping:  # the stop's end, then the body settling on its springs
                decel = driver.course.stop_deceleration
                omega[k:], force[k:], rolled = _stop(angles, vehicle.speed, decel, samples - k)
                travelled[k:] = distance + rolled
                rolling = np.gradient(rolled, 1.0 / SAMPLE_RATE_HZ)
                signals["steering"][k:] = vehicle.steering / lock
                signals["speed"][k:] = np.maximum(rolling, 0.0)
                signals["brake"][k:] = np.where(rolling > 0.0, min(decel / most, 1.0), 0.0)
                break
            steering_rate, acceleration = driver.command()
            signals["throttle"][k] = min(max(acceleration / most, 0.0), 1.0)
            signals["brake"][k] = min(max(-acceleration / most, 0.0), 1.0)
            for _ in range(SUBSTEPS):
                vehicle.step(steering_rate, acceleration)
                distance += max(vehicle.speed, 0.0) * STEP_S
            if bar is not None:
                bar.update(1)
    except (RuntimeError, FloatingPointError, ZeroDivisionError) as error:
        raise LostControlError(str(error)) from error
    finally:
        if bar is not None:
            bar.close()
    signals["steering"] = np.clip(signals["steering"], -1.0, 1.0)
    return omega, force, travelled, vehicle, signals


# The sprung mass settling on its springs once the car stands: a saloon's body mode
# (natural frequency, Hz; damping ratio).
SETTLING_HZ, SETTLING_DAMPING = 1.3, 0.3
# Seconds driven straight at the entry speed before the recording starts, for the model's
# suspension to settle from its initial state (not recorded).
SETTLE_S = 2.0


def _settled(car: str, speed_mps: float) -> Car:
    """The car after `SETTLE_S` s straight at `speed_mps`, moved back to the origin."""
    vehicle = Car(car, speed_mps)
    for _ in range(round(SETTLE_S / STEP_S)):
        vehicle.step(0.0, 0.0)
    vehicle.state[0] = vehicle.state[1] = vehicle.state[4] = 0.0
    return vehicle


def _stop(
    angles: np.ndarray, speed: float, deceleration: float, count: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(omega (count, 3), f (count, 3), distance rolled (count,) m) of the stop's last
    `speed` m/s at a constant `deceleration` (m/s^2) in a straight line, the body's roll
    and pitch (`angles`) held, then the body settling on its springs (`_settling`) from
    them as the brakes' pull ends."""
    t = np.arange(count) / SAMPLE_RATE_HZ
    braking = t < speed / deceleration
    n = int(braking.sum())
    omega, force = _settling(angles, np.zeros(2), count - n)
    phi, theta = angles
    held = gravity_in_body(phi, theta)
    held[0] -= deceleration * np.cos(theta)
    force = np.vstack([np.tile(held, (n, 1)), force])
    omega = np.vstack([np.zeros((n, 3)), omega])
    rolled = np.where(braking, speed * t - 0.5 * deceleration * t**2, speed**2 / (2 * deceleration))
    return omega, force, rolled


def _settling(angles: np.ndarray, rates: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """(omega (count, 3), f (count, 3)) of a standing car whose body's roll and pitch
    (`angles`, rad) and their rates (`rates`, rad/s) ring down as a damped oscillator
    (`SETTLING_HZ`, `SETTLING_DAMPING`): f is gravity seen through them."""
    t = np.arange(count) / SAMPLE_RATE_HZ
    wn = 2.0 * np.pi * SETTLING_HZ
    zeta = SETTLING_DAMPING
    wd = wn * np.sqrt(1.0 - zeta**2)
    decay = np.exp(-zeta * wn * t)[:, None]
    x0, v0 = np.asarray(angles)[None, :], np.asarray(rates)[None, :]
    b = (v0 + zeta * wn * x0) / wd
    cos, sin = np.cos(wd * t)[:, None], np.sin(wd * t)[:, None]
    x = decay * (x0 * cos + b * sin)
    v = decay * ((-zeta * wn) * (x0 * cos + b * sin) + (-x0 * wd * sin + b * wd * cos))
    phi, theta = x[:, 0], x[:, 1]
    force = gravity_in_body(phi, theta)
    omega = np.column_stack([v[:, 0], v[:, 1], np.zeros(count)])
    return omega, force


def _with_road(omega, force, travelled, vehicle: Car, road_class: str, rng):
    """The drive's motion plus the road roughness's, through quarter cars per corner."""
    p = vehicle.params
    dt = 1.0 / SAMPLE_RATE_HZ
    wheelbase = p.a + p.b
    length = travelled[-1] + wheelbase + 1.0
    spacing = 0.05
    left, right = (road_profile(length, road_class, rng, spacing) for _ in range(2))
    grid = np.arange(left.size) * spacing

    def corner(profile, ahead_m, mass, spring, damper):
        """Body displacement over a corner (m), from the road under its wheel."""
        road = np.interp(travelled + ahead_m, grid, profile)
        system = signal.lti([damper, spring], [mass, damper, spring])
        _, z, _ = signal.lsim(system, road, np.arange(road.size) * dt)
        return z

    mass_f = 0.25 * p.m_s * p.b / wheelbase * 2.0  # per front corner
    mass_r = 0.25 * p.m_s * p.a / wheelbase * 2.0
    front = (p.K_sf, p.K_sdf)
    rear = (p.K_sr, p.K_sdr)
    z_lf = corner(left, wheelbase, mass_f, *front)
    z_rf = corner(right, wheelbase, mass_f, *front)
    z_lr = corner(left, 0.0, mass_r, *rear)
    z_rr = corner(right, 0.0, mass_r, *rear)
    heave = 0.25 * (z_lf + z_rf + z_lr + z_rr)
    pitch = (0.5 * (z_lr + z_rr) - 0.5 * (z_lf + z_rf)) / wheelbase  # nose down positive
    roll = (0.5 * (z_lf + z_lr) - 0.5 * (z_rf + z_rr)) / (0.5 * (p.T_f + p.T_r))
    omega = omega + np.column_stack(
        [np.gradient(roll, dt), np.gradient(pitch, dt), np.zeros_like(roll)]
    )
    # heave's acceleration, and gravity seen through the extra roll and pitch
    g = force[:, 2]
    extra = np.column_stack(
        [-g * np.sin(pitch), g * np.sin(roll), np.gradient(np.gradient(heave, dt), dt)]
    )
    return omega, force + extra
