"""The route pilot: a second, independent pilot that flies a route of waypoints, for evaluation.

Every training flight comes from the scripted pilot (`pilot`, `loops`, `plan`) and its
random-style variants: one manoeuvre vocabulary (turns, reversals, doublets, stalls) flown by
one cascade of PID loops. A policy that did well only on that pilot's flights would be
judged on its own training distribution. The route pilot shares nothing with it but the
JSBSim wrapper (`model`) and the recorder (`flight`): it is structured and flies differently,
and it is never used for training, tuning or choosing recipes (`EVALUATION_ONLY`).

What it flies (`draw_route`): a route drawn from the seed, from the aircraft's cruise
altitude: legs to waypoints with heading changes, climbs and descents to new flight levels,
speed changes, orbits around a point, and approaches down a 3 degree glide path to a
decision height followed by a go-around, until the recording ends.

How it flies (`RoutePilot`), three laws unlike the scripted pilot's cascades:

- lateral: nonlinear L1 guidance (Park, Deyst & How, 2004) towards the leg's line or the
  orbit's circle: the lateral acceleration a = 2 V^2 sin(eta) / L1 towards a point L1
  ahead on the path, flown as the bank of a coordinated turn, atan(a / g); the bank by
  proportional-derivative attitude feedback on the aileron, with no integrator;
- longitudinal: total energy control (TECS, Lambregts 1983): the throttle drives the rate
  of the total specific energy (flight-path angle plus acceleration over g) to its
  command, the elevator its distribution between height and speed, through a pitch
  attitude and a pitch-rate inner loop;
- directional: a yaw damper on the yaw rate less that of the coordinated turn.

Positions are the aircraft's north and east distances from the start, m, integrated from
JSBSim's ground velocity.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator

import numpy as np

from mca_drake.references.jsbsim.aircraft import DEG, FT, STEP_S, Airframe, G
from mca_drake.references.jsbsim.config import FlightConfig
from mca_drake.references.jsbsim.model import Model

# Pilots whose flights are evaluation flights only: no dataset, tuning or recipe choice
# may fly them.
EVALUATION_ONLY = ("route",)
# Height above ground of the approaches' decision height (go-around), m.
DECISION_HEIGHT_M = 60.0
# Glide path of the approaches, rad.
GLIDE_PATH = 3.0 * DEG


@dataclasses.dataclass(frozen=True)
class Leg:
    """One leg of a route.

    Attributes:
        kind: "leg" (fly to a waypoint), "orbit" (circle a point), "approach" (down the
            glide path to the decision height, then go around and climb back).
        north_m, east_m: the waypoint, or the orbit's centre, m from the start.
        altitude_m: the height above ground to hold on the leg (approach: where the go-around
            climbs back to), m.
        speed_mps: calibrated airspeed to hold, m/s.
        radius_m: the orbit's radius, m (orbits only); its sign the direction (+ clockwise
            seen from above, that is right turns).
        duration_s: how long to orbit, s (orbits only).
    """

    kind: str
    north_m: float
    east_m: float
    altitude_m: float
    speed_mps: float
    radius_m: float = 0.0
    duration_s: float = 0.0


def approach_speed(air: Airframe) -> float:
    """The route pilot's approach speed, m/s: the airframe's, or 1.25 times its clean
    stall speed where that is faster (the route pilot flies its approaches clean)."""
    return max(air.approach_speed, 1.25 * air.stall_speed)


def draw_route(
    rng: np.random.Generator,
    air: Airframe,
    config: FlightConfig,
    heading: float,
    duration_s: float,
) -> list[Leg]:
    """A route of at least `duration_s` of flying, drawn from `rng`, from the start at the
    origin heading `heading` (rad) at the config's maneuver altitude and cruise speed.

    Leg kinds are drawn with probabilities 0.45 (waypoint leg, a third of them with a new
    flight level), 0.2 (orbit), 0.2 (approach and go-around) and 0.15 (speed change on a
    waypoint leg); legs last 30 to 90 s at the cruise speed.
    """
    cruise = config.cruise_speed_mps
    low, high = config.min_altitude_m, config.max_altitude_m
    north, east, altitude, track = 0.0, 0.0, config.maneuver_altitude_m, heading
    legs: list[Leg] = []
    flown = 0.0
    while flown < duration_s + 30.0:
        kind = str(rng.choice(["leg", "orbit", "approach", "speed"], p=[0.45, 0.2, 0.2, 0.15]))
        speed = cruise
        if kind == "orbit":
            radius = cruise**2 / (G * math.tan(float(rng.uniform(20, 35)) * DEG))
            side = float(rng.choice([-1.0, 1.0]))
            # the centre abeam the present track, one radius to the side
            centre_n = north + side * radius * -math.sin(track)
            centre_e = east + side * radius * math.cos(track)
            lasting = float(rng.uniform(40, 90))
            legs.append(Leg("orbit", centre_n, centre_e, altitude, speed, side * radius, lasting))
            flown += lasting
            continue
        if kind == "approach":
            # the threshold: a descent to the approach height at the cruise speed and the
            # descent rate, 30 s level to slow down, then the glide path down to the
            # decision height
            speed = approach_speed(air)
            descent_s = max(altitude - air.approach_height, 0.0) / air.descent_rate
            glide = (air.approach_height - DECISION_HEIGHT_M) / math.tan(GLIDE_PATH)
            distance = descent_s * cruise + 30.0 * speed + glide
            track += float(rng.uniform(-60, 60)) * DEG
            north += distance * math.cos(track)
            east += distance * math.sin(track)
            legs.append(Leg("approach", north, east, altitude, speed))
            flown += descent_s + 30.0 + glide / speed + 60.0  # and the go-around's climb
            continue
        if kind == "leg" and rng.uniform() < 1 / 3:
            altitude = float(np.clip(altitude + rng.uniform(-1, 1) * (high - low) / 2, low, high))
        if kind == "speed":
            speed = float(rng.uniform(0.85, 1.1)) * cruise
        track += float(rng.choice([-1.0, 1.0]) * rng.uniform(20, 150)) * DEG
        distance = float(rng.uniform(30, 90)) * cruise
        north += distance * math.cos(track)
        east += distance * math.sin(track)
        legs.append(Leg("leg", north, east, altitude, speed))
        flown += distance / cruise
    return legs


class RoutePilot:
    """Flies `route` in `model`: `fly()` steps the route's legs, `step()` the control laws;
    one of each per JSBSim step (the recorder's `pilot` and `loops`).

    Args:
        model: the JSBSim model, trimmed in the air at the route's start.
        config: the resolved flight config (cruise speed: the first target).
        route: the legs, in flying order.
        throttle: the trim throttle (the energy integrator's start).

    Attributes:
        ground_allowed: False: the route is flown in the air (the recorder's check).
        phases: (start time s, leg) in flying order.
    """

    def __init__(self, model: Model, config: FlightConfig, route: list[Leg], throttle: float):
        self.model = model
        self.air = model.air
        self.route = route
        self.ground_allowed = False
        self.phases: list[tuple[float, str]] = []
        fdm = model.fdm
        self._v_north = fdm.get_property_manager().get_node("velocities/v-north-fps")
        self._v_east = fdm.get_property_manager().get_node("velocities/v-east-fps")
        self.north = self.east = 0.0
        # targets
        self.altitude_c = config.maneuver_altitude_m
        self.speed_c = self.cruise = config.cruise_speed_mps
        self.gamma_c: float | None = None  # a commanded flight path (the glide), else None
        self.bank_c = 0.0
        self.bank_max = (45 if self.air.agile else 30) * DEG
        # the path: a line from A to B, or a circle
        self.line: tuple[float, float, float, float] | None = None
        self.circle: tuple[float, float, float] | None = None
        # energy and pitch integrators, and the filtered airspeed rate
        self.throttle_int = throttle
        self.pitch_int = model.state.theta
        self.v_last = model.state.v
        self.v_dot = 0.0
        # the surfaces start where the trim left them (no bump at the first step)
        self.speedbrake = 0.0
        self.outputs = [
            float(fdm[f"fcs/{name}-cmd-norm"]) for name in ("aileron", "elevator", "rudder")
        ]

    # ------------------------------------------------------------------ guidance (the route)

    def fly(self) -> Iterator[None]:
        """Flies the legs one after the other; after the last, holds the last leg's line."""
        for leg in self.route:
            self.phases.append((self.model.t, f"route {leg.kind}"))
            self.model.phase = f"route {leg.kind} to ({leg.north_m:.0f}, {leg.east_m:.0f}) m"
            if leg.kind == "orbit":
                yield from self._orbit(leg)
            elif leg.kind == "approach":
                yield from self._approach(leg)
            else:
                yield from self._leg(leg)
        while True:
            yield

    def _phase(self, name: str) -> None:
        self.phases.append((self.model.t, name))
        self.model.phase = name

    def _to(self, leg: Leg) -> None:
        self.line = (self.north, self.east, leg.north_m, leg.east_m)
        self.circle = None

    def _remaining_m(self, leg: Leg) -> float:
        """Distance left along the line to the leg's waypoint, m (negative: passed it)."""
        a_n, a_e, b_n, b_e = self.line
        length = math.hypot(b_n - a_n, b_e - a_e)
        along = ((self.north - a_n) * (b_n - a_n) + (self.east - a_e) * (b_e - a_e)) / length
        return length - along

    def _leg(self, leg: Leg) -> Iterator[None]:
        self._to(leg)
        self.altitude_c, self.speed_c, self.gamma_c = leg.altitude_m, leg.speed_mps, None
        while self._remaining_m(leg) > 2.0 * self.model.state.v:  # turn 2 s early
            yield

    def _orbit(self, leg: Leg) -> Iterator[None]:
        self.line = None
        self.circle = (leg.north_m, leg.east_m, leg.radius_m)
        self.altitude_c, self.speed_c, self.gamma_c = leg.altitude_m, leg.speed_mps, None
        end = self.model.t + leg.duration_s
        while self.model.t < end:
            yield

    def _approach(self, leg: Leg) -> Iterator[None]:
        self._to(leg)
        s, slope = self.model.state, math.tan(GLIDE_PATH)
        # towards the threshold: down to the approach height at the cruise speed, slowed to
        # the approach speed there, level until the glide path comes down to the aircraft
        # (intercepted from below, as an ILS approach is)
        self.altitude_c, self.speed_c, self.gamma_c = self.air.approach_height, self.cruise, None
        while self._remaining_m(leg) > 0.0 and s.h > self.air.approach_height + 15.0:
            yield
        self.speed_c = leg.speed_mps
        while self._remaining_m(leg) * slope > s.h - DECISION_HEIGHT_M:
            yield
        self._phase("route glide")
        self.gamma_c = -GLIDE_PATH
        while s.h > DECISION_HEIGHT_M and self._remaining_m(leg) > 0.0:
            yield
        # go around: climb at the climb speed back to the approach's starting altitude
        self._phase("route go-around")
        self.gamma_c = None
        self.altitude_c, self.speed_c = leg.altitude_m, self.air.climb_speed
        end = self.model.t + 60.0
        while self.model.t < end and s.h < leg.altitude_m - 30.0:
            yield

    # --------------------------------------------------------------- control (every step)

    def step(self) -> None:
        """One step of the three control laws, written to JSBSim."""
        s, air, dt = self.model.state, self.air, STEP_S
        v_n, v_e = self._v_north.get_double_value() * FT, self._v_east.get_double_value() * FT
        self.north += v_n * dt
        self.east += v_e * dt
        v = max(s.v, 0.5 * air.stall_speed)
        sched = min(max(air.qbar_ref_psf / max(s.qbar, 1.0), 0.3), 5.0)
        # lateral: L1 guidance -> bank (slewed at the airframe's normal roll rate) ->
        # aileron (PD on the attitude)
        step = air.roll_rate_max * dt
        self.bank_c += min(max(self._l1_bank(v_n, v_e) - self.bank_c, -step), step)
        aileron = sched * air.roll_rate_gain * (1.2 * (self.bank_c - s.phi) - s.p)
        # longitudinal: total energy control -> throttle and pitch -> elevator
        throttle, pitch_c = self._energy(v)
        cos_phi = max(math.cos(s.phi), 0.3)
        q_turn = G / v * math.sin(s.phi) ** 2 / cos_phi
        q_c = min(max(1.2 * (pitch_c - s.theta), -air.pitch_rate_max), air.pitch_rate_max)
        elevator = -sched * air.pitch_rate_gain * (q_c * cos_phi + q_turn - s.q)
        # directional: yaw damper on the yaw rate beyond the coordinated turn's
        r_turn = G / v * math.sin(s.phi)
        rudder = sched * air.yaw_gain * (s.r - r_turn)
        commands = [min(max(c, -1.0), 1.0) for c in (aileron, elevator, rudder)]
        # the surfaces move at most 2.5 deflections per second
        limit = 2.5 * dt
        for i, c in enumerate(commands):
            self.outputs[i] += min(max(c - self.outputs[i], -limit), limit)
        aileron, elevator, rudder = self.outputs
        self.model.controls.write(aileron, elevator, rudder, throttle, 0.0)
        self.model.controls.set_speedbrake(self.speedbrake)

    def _l1_bank(self, v_n: float, v_e: float) -> float:
        """The bank of the L1 lateral acceleration towards the path, rad, from the ground
        velocity (north, east; m/s): the bank is commanded from the ground track alone."""
        ground = max(math.hypot(v_n, v_e), 1.0)
        l1 = max(12.0 * ground, 150.0)  # m: the look-ahead, about 12 s of flight
        if self.circle is not None:
            c_n, c_e, radius = self.circle
            # the point L1 ahead on the circle, in the direction of the orbit
            d_n, d_e = self.north - c_n, self.east - c_e
            angle = math.atan2(d_e, d_n) + math.copysign(min(l1 / abs(radius), 1.0), radius)
            target = (c_n + abs(radius) * math.cos(angle), c_e + abs(radius) * math.sin(angle))
        elif self.line is not None:
            a_n, a_e, b_n, b_e = self.line
            length = max(math.hypot(b_n - a_n, b_e - a_e), 1.0)
            u_n, u_e = (b_n - a_n) / length, (b_e - a_e) / length
            along = (self.north - a_n) * u_n + (self.east - a_e) * u_e
            cross = (self.north - a_n) * -u_e + (self.east - a_e) * u_n
            ahead = math.sqrt(max(l1 * l1 - cross * cross, 0.0))
            target = (a_n + (along + ahead) * u_n, a_e + (along + ahead) * u_e)
        else:
            return 0.0
        to_n, to_e = target[0] - self.north, target[1] - self.east
        eta = math.atan2(v_n * to_e - v_e * to_n, v_n * to_n + v_e * to_e)
        eta = min(max(eta, -math.pi / 2), math.pi / 2)
        lateral = 2.0 * ground * ground * math.sin(eta) / l1
        bank = math.atan(lateral / G)
        return min(max(bank, -self.bank_max), self.bank_max)

    def _energy(self, v: float) -> tuple[float, float]:
        """Total energy control: (throttle, pitch command rad)."""
        s, air, dt = self.model.state, self.air, STEP_S
        # the airspeed's rate, low-passed over 0.5 s (one sample's difference is noise)
        self.v_dot += (((s.v - self.v_last) / dt) - self.v_dot) * dt / 0.5
        self.v_last = s.v
        gamma = s.hdot / v
        if self.gamma_c is None:
            gamma_c = 0.08 * (self.altitude_c - s.h) / v
        else:
            gamma_c = self.gamma_c
        gamma_c = min(max(gamma_c, -air.descent_rate / v), air.climb_rate / v)
        accel_c = min(max(0.15 * (self.speed_c - s.v), -0.05 * G), 0.05 * G)
        energy_error = (gamma_c - gamma) + (accel_c - self.v_dot) / G
        balance_error = (gamma_c - gamma) - (accel_c - self.v_dot) / G
        self.throttle_int = min(max(self.throttle_int + 0.3 * energy_error * dt, 0.0), 1.0)
        throttle = min(max(self.throttle_int + 1.0 * energy_error, air.idle_throttle), 1.0)
        # at idle with energy to lose (a descent at speed): the speed brakes, where the
        # airframe has them
        idle = throttle <= air.idle_throttle
        self.speedbrake = min(max(-20.0 * energy_error, 0.0), 1.0) if idle else 0.0
        self.pitch_int = min(
            max(self.pitch_int + 0.4 * balance_error * dt, air.min_pitch), air.max_pitch
        )
        pitch_c = self.pitch_int + 0.8 * balance_error
        return throttle, min(max(pitch_c, air.min_pitch), air.max_pitch)
