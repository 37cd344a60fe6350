"""The driver: follows a course's path and speed with the steering rate and the pedals.

Path: pure pursuit (Coulter 1992) from the centre of gravity: the point of the path a
look-ahead distance L_d ahead (`lookahead_s` seconds of travel, at least `min_lookahead_m`)
at the angle alpha from the heading asks for the steering angle atan(2 l sin(alpha) / L_d)
of a bicycle of wheelbase l; the hands turn the wheels towards it at `steering_gain` per
second, within the car's steering-rate limit. Speed: the acceleration command is the
target speed's change ahead (its feedforward) plus `speed_gain` times the speed error,
within `max_acceleration` and `max_braking`. Past an open course's end the target is a
stop at `stop_deceleration` and the car then stands.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from mca_drake.references.driving.car import Car
from mca_drake.references.driving.courses import SPACING_M, Course

# Below this speed, with the course asking for a stop, the stop is completed without the
# multi-body model (m/s): its slip-based tyres are singular as the speed goes to zero (at
# 1-3 m/s they already brake the car at 10 m/s^2 under a 1 m/s^2 command).
STOP_SPEED = 3.0


def _with_stop(course: Course, gains: DriverGains) -> Course:
    """An open course with a straight run-out after its end on which the target speed
    falls to a stop at `gains.stop_deceleration` (then 0, and 50 m more road)."""
    dx, dy = course.x[-1] - course.x[-2], course.y[-1] - course.y[-2]
    norm = math.hypot(dx, dy)
    v_end = float(course.speed[-1])
    length = v_end**2 / (2.0 * gains.stop_deceleration) + 50.0
    s = np.arange(1, int(length / SPACING_M) + 1) * SPACING_M
    speed = np.sqrt(np.clip(v_end**2 - 2.0 * gains.stop_deceleration * s, 0.0, None))
    speed[speed < STOP_SPEED] = 0.0
    return Course(
        np.concatenate([course.x, course.x[-1] + s * dx / norm]),
        np.concatenate([course.y, course.y[-1] + s * dy / norm]),
        np.concatenate([course.speed, speed]),
        stop_deceleration=course.stop_deceleration or gains.stop_deceleration,
    )


@dataclasses.dataclass(frozen=True)
class DriverGains:
    """How the driver drives (defaults: a calm, precise driver)."""

    lookahead_s: float = 0.8
    min_lookahead_m: float = 5.0
    steering_gain: float = 8.0  # 1/s
    speed_gain: float = 1.0  # 1/s
    max_acceleration: float = 4.0  # m/s^2
    max_braking: float = 9.0  # m/s^2
    stop_deceleration: float = 3.0  # m/s^2 past an open course's end


class Driver:
    """Drives `course` with `car`: `command()` gives (steering rate, acceleration)."""

    def __init__(self, course: Course, car: Car, gains: DriverGains | None = None) -> None:
        self.gains = gains or DriverGains()
        self.course = course if course.closed else _with_stop(course, self.gains)
        self.car = car
        self.index = 0  # the path point nearest the car
        self.laps = 0
        self.wheelbase = car.params.a + car.params.b

    def _advance(self) -> None:
        """Moves `index` to the path point nearest the car (searching ahead only)."""
        c, (px, py) = self.course, self.car.position
        n = c.x.size
        window = np.arange(self.index, self.index + 400)
        if c.closed:
            window %= n
        else:
            window = window[window < n]
        d = (c.x[window] - px) ** 2 + (c.y[window] - py) ** 2
        nearest = int(window[int(np.argmin(d))])
        if c.closed and nearest < self.index:
            self.laps += 1
        self.index = nearest

    def _point(self, ahead_m: float) -> tuple[float, float]:
        """The path's point `ahead_m` m beyond the nearest one."""
        c = self.course
        i = self.index + round(ahead_m / SPACING_M)
        i = i % c.x.size if c.closed else min(i, c.x.size - 1)
        return float(c.x[i]), float(c.y[i])

    @property
    def stopping(self) -> bool:
        """The car is below `STOP_SPEED` where the course slows it to a stop."""
        c = self.course
        if c.closed or self.car.speed >= STOP_SPEED:
            return False
        i = min(self.index + round(STOP_SPEED / SPACING_M), c.x.size - 1)
        return c.speed[i] < STOP_SPEED

    def command(self) -> tuple[float, float]:
        """(steering rate rad/s, acceleration m/s^2) for the car's state now."""
        g, car, c = self.gains, self.car, self.course
        self._advance()
        v = max(car.speed, 0.0)
        lookahead = max(g.lookahead_s * v, g.min_lookahead_m)
        tx, ty = self._point(lookahead)
        px, py = car.position
        alpha = math.atan2(ty - py, tx - px) - car.heading
        alpha = (alpha + math.pi) % (2.0 * math.pi) - math.pi
        wanted = math.atan2(2.0 * self.wheelbase * math.sin(alpha), lookahead)
        steering_rate = g.steering_gain * (wanted - car.steering)
        # speed: the target a second ahead, as feedforward, and the error now
        target = float(c.speed[self.index])
        i = self.index + round(max(v, 1.0) / SPACING_M)
        ahead = float(c.speed[i % c.x.size] if c.closed else c.speed[min(i, c.x.size - 1)])
        accel = (ahead - target) + g.speed_gain * (target - v)
        accel = min(max(accel, -g.max_braking), g.max_acceleration)
        return steering_rate, accel
