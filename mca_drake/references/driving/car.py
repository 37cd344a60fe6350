"""The car: commonroad's multi-body vehicle model, and what it gives an IMU.

`Car` integrates the multi-body model of the CommonRoad vehicle models
(`vehiclemodels.vehicle_dynamics_mb`, Althoff et al., TUM, BSD licence: 29 states, a sprung
mass with roll and pitch on front and rear unsprung masses, Pacejka tyres, wheel spin), with
the shipped parameters of its three cars (`CARS`), by classical Runge-Kutta steps of
`STEP_S`. Its inputs are the front wheels' steering rate (rad/s) and the longitudinal
acceleration command (m/s^2), within the model's own limits.

`body_motion` turns the model's states and their derivatives into what an IMU on the
sprung mass at the centre of gravity reads, in the body frame of ISO 8855 (x forward,
y left, z up; the recordings' frame): the angular velocity and the specific force. The
model keeps its planar velocities in the yaw frame and its roll and pitch of the sprung
mass with the opposite signs to ISO 8855 (in a left turn its roll is negative, under
braking its pitch is negative) and its heave positive downwards; `body_motion` converts:

    roll phi = -x7, pitch theta = -x9 (ISO: positive rolls the right side down, positive
    pitches the nose down), yaw psi = x5;
    acceleration in the yaw frame a = (dv_x/dt - r v_y, dv_y/dt + r v_x, -d^2z/dt^2);
    specific force f = R_x(phi)^T R_y(theta)^T (a + (0, 0, g));
    angular velocity (ZYX Euler rates) w = (dphi - dpsi sin(theta),
        dtheta cos(phi) + dpsi cos(theta) sin(phi), dpsi cos(theta) cos(phi) - dtheta sin(phi)).

A level car at rest reads f = (0, 0, +9.81).
"""

from __future__ import annotations

import math

import numpy as np
from vehiclemodels.init_mb import init_mb
from vehiclemodels.parameters_vehicle1 import parameters_vehicle1
from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
from vehiclemodels.parameters_vehicle3 import parameters_vehicle3
from vehiclemodels.vehicle_dynamics_mb import vehicle_dynamics_mb

# CommonRoad's parameter sets: a Ford Escort, a BMW 320i, a VW Vanagon.
CARS = {
    "ford-escort": parameters_vehicle1,
    "bmw-320i": parameters_vehicle2,
    "vw-vanagon": parameters_vehicle3,
}
# The integration step, s: the tyres' vertical and slip dynamics need about 2 ms (at 5 ms
# the unsprung masses' 12 Hz modes are integrated at 0.4 rad per step and drift).
STEP_S = 0.002
# The longitudinal wheel slip the anti-lock braking holds the wheels under.
ABS_SLIP = 0.1
# The model's gravity, m/s^2.
GRAVITY = 9.81


def check_car(car: str) -> str:
    """`car`, or ValueError naming the valid ones."""
    if car not in CARS:
        raise ValueError(f"unknown car '{car}'; valid: {', '.join(CARS)}")
    return car


class Car:
    """One car of `CARS`, starting at the origin heading along +x at `speed_mps`.

    Attributes:
        params: the model's parameters (CommonRoad's VehicleParameters).
        state: the model's 29 states.
        derivative: their derivative at the last step's end (for the accelerations).
    """

    def __init__(self, car: str = "bmw-320i", speed_mps: float = 0.0) -> None:
        self.params = CARS[check_car(car)]()
        self.state = np.array(init_mb([0.0, 0.0, 0.0, speed_mps, 0.0, 0.0, 0.0], self.params))
        self.derivative = self._f(self.state, (0.0, 0.0))

    def _f(self, x: np.ndarray, u) -> np.ndarray:
        # the model divides by wheel speeds that reach zero in a spin: a state that is no
        # longer finite then, which `step` reports, not a warning per division
        with np.errstate(all="ignore"):
            return np.asarray(vehicle_dynamics_mb(x, list(u), self.params), dtype=float)

    def step(self, steering_rate: float, acceleration: float, dt: float = STEP_S) -> None:
        """One Runge-Kutta step of `dt` s with the inputs held; a braking command is eased
        as an anti-lock system would (`anti_lock`)."""
        acceleration = self.anti_lock(acceleration)
        f, x, u = self._f, self.state, (steering_rate, acceleration)
        k1 = f(x, u)
        k2 = f(x + 0.5 * dt * k1, u)
        k3 = f(x + 0.5 * dt * k2, u)
        k4 = f(x + dt * k3, u)
        self.state = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        self.derivative = f(self.state, u)
        if not np.all(np.isfinite(self.state)):
            raise RuntimeError("the car model's state is no longer finite")

    def anti_lock(self, acceleration: float) -> float:
        """The braking command (negative `acceleration`, m/s^2) eased in proportion where a
        wheel's longitudinal slip 1 - R_w w / v_x exceeds `ABS_SLIP`, as an anti-lock system
        holds the tyres near their peak grip; other commands unchanged. (The model applies
        a braking torque whatever the wheel's speed, so without this its wheels lock as
        the car slows and it skids at the tyres' full friction.)"""
        if acceleration >= 0.0:
            return acceleration
        x, radius = self.state, self.params.R_w
        v = max(float(x[3]), 0.5)
        slip = max(1.0 - radius * float(w) / v for w in x[23:27])
        return acceleration if slip <= ABS_SLIP else acceleration * ABS_SLIP / slip

    @property
    def position(self) -> tuple[float, float]:
        """The centre of gravity in the road plane, m."""
        return float(self.state[0]), float(self.state[1])

    @property
    def heading(self) -> float:
        """The yaw angle, rad (0 along +x, positive to the left)."""
        return float(self.state[4])

    @property
    def speed(self) -> float:
        """The longitudinal velocity, m/s."""
        return float(self.state[3])

    @property
    def steering(self) -> float:
        """The front wheels' steering angle, rad."""
        return float(self.state[2])


def body_motion(x: np.ndarray, dx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(angular velocity (3) rad/s, specific force (3) m/s^2, (roll, pitch) rad) of the
    sprung mass at the centre of gravity in the ISO 8855 body frame, from the model's
    states `x` (29) and their derivative `dx` (29)."""
    r, vx, vy = x[5], x[3], x[10]
    phi, dphi = -x[6], -x[7]
    theta, dtheta = -x[8], -x[9]
    a = np.array([dx[3] - r * vy, dx[10] + r * vx, -dx[12] + GRAVITY])
    cp, sp, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    # R_y(theta)^T, then R_x(phi)^T
    a = np.array([ct * a[0] - st * a[2], a[1], st * a[0] + ct * a[2]])
    f = np.array([a[0], cp * a[1] + sp * a[2], -sp * a[1] + cp * a[2]])
    omega = np.array([dphi - r * st, dtheta * cp + r * ct * sp, r * ct * cp - dtheta * sp])
    return omega, f, np.array([phi, theta])


def gravity_in_body(phi, theta) -> np.ndarray:
    """The specific force of gravity alone, m/s^2, in the body frame of a body rolled by
    `phi` and pitched by `theta` (rad, ISO 8855; arrays broadcast): shape (..., 3)."""
    phi, theta = np.asarray(phi, dtype=float), np.asarray(theta, dtype=float)
    return GRAVITY * np.stack(
        [-np.sin(theta), np.cos(theta) * np.sin(phi), np.cos(theta) * np.cos(phi)], axis=-1
    )


def lever_arm(
    omega: np.ndarray, f: np.ndarray, offset_m: np.ndarray, time_step: float
) -> np.ndarray:
    """The specific force (T, 3) at a point `offset_m` (3, body frame, m) from the centre of
    gravity of a rigid body with angular velocity `omega` (T, 3) and specific force `f`
    (T, 3) at the centre of gravity, sampled every `time_step` s:
    f + dw/dt x r + w x (w x r), dw/dt by central differences."""
    r = np.asarray(offset_m, dtype=float)
    domega = np.gradient(omega, time_step, axis=0)
    return f + np.cross(domega, r) + np.cross(omega, np.cross(omega, r))
