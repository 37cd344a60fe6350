"""The scripted pilot: flies a plan of maneuvers by setting the modes and targets of its loops.

Each maneuver is flown by a generator that advances one JSBSim step per `next`: it sets the
loops' targets (`loops.Loops`), then yields until the maneuver's condition or time is met.
`Pilot.fly` chains them over the plan and keeps the list of phases.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator

from mca_drake.references.jsbsim.aircraft import DEG, KT, STEP_S
from mca_drake.references.jsbsim.config import FlightConfig
from mca_drake.references.jsbsim.loops import (
    PITCH_HOLD,
    ROLL_BANK,
    ROLL_GROUND,
    ROLL_HOLD,
    SPEED_TAXI,
    Loops,
    clip,
    wrap,
)
from mca_drake.references.jsbsim.maneuvers import (
    AltitudeChange,
    BankReversals,
    Doublet,
    Landing,
    Level,
    Maneuver,
    SpeedChange,
    Stall,
    Takeoff,
    Taxi,
    Turbulence,
    Turn,
    describe,
)
from mca_drake.references.jsbsim.model import Model

# Bank at which the pilot ends a doublet's hands-off free response, rad.
DOUBLET_BANK_LIMIT = 75 * DEG


class Pilot:
    """Flies `plan` with `loops` in `model`; `fly()` steps it, one JSBSim step per `next`.

    Args:
        model: the JSBSim model (state, clock, controls beyond the loops, checks).
        loops: the pilot's feedback loops on that model.
        config: the resolved flight config (cruise speed, wind).
        from_ground: the flight starts parked on the ground.
        plan: the maneuvers, in flying order (may be drawn lazily, as `plan.RandomPlan`).
        runway_heading: true heading of the runway, rad (None: set by a Taxi maneuver).

    Attributes:
        ground_allowed: wheels touching the ground is expected now (taxi, take-off, landing).
        phases: (start time s, maneuver name) in flying order.
    """

    def __init__(
        self,
        model: Model,
        loops: Loops,
        config: FlightConfig,
        from_ground: bool,
        plan: Iterable[Maneuver],
        runway_heading: float | None,
    ) -> None:
        self.model = model
        self.loops = loops
        self.config = config
        self.from_ground = from_ground
        self.plan = plan
        self.runway_heading = runway_heading
        self.ground_allowed = False
        self.phase_start = 0.0  # s, start of the maneuver flown now
        self.phases: list[tuple[float, str]] = []

    def fly(self) -> Iterator[None]:
        """Flies the plan, one step per `next`; then holds (level, or parked) to the end."""
        handlers: dict[type, Callable[..., Iterator[None]]] = {
            Level: self._fly_level,
            Turn: self._fly_turn,
            BankReversals: self._fly_bank_reversals,
            AltitudeChange: self._fly_altitude_change,
            SpeedChange: self._fly_speed_change,
            Doublet: self._fly_doublet,
            Stall: self._fly_stall,
            Turbulence: self._fly_turbulence,
            Taxi: self._fly_taxi,
            Takeoff: self._fly_takeoff,
            Landing: self._fly_landing,
        }
        model, s, loops = self.model, self.model.state, self.loops
        roll, speed = loops.roll, loops.speed
        if self.from_ground:
            roll.mode = ROLL_GROUND
            roll.heading_c = s.psi
            loops.hold_elevator(0.0)
            speed.mode, speed.speed_c = SPEED_TAXI, 0.0
            self.ground_allowed = True
        else:
            loops.pitch.mode = PITCH_HOLD  # so that the altitude hold starts from this attitude
            loops.hold_heading()
            loops.hold_altitude()
            loops.hold_speed(self.config.cruise_speed_mps)
        for maneuver in self.plan:
            model.phase = describe(maneuver)
            self.phase_start = model.t
            self.phases.append((round(model.t, 2), model.phase))
            yield from handlers[type(maneuver)](maneuver)
        model.phase = "parked" if s.wow else "level"
        self.phases.append((round(model.t, 2), model.phase))
        while True:
            if s.wow:
                roll.mode, speed.mode, speed.speed_c = ROLL_GROUND, SPEED_TAXI, 0.0
            yield

    # ------------------------------------------------------------------------------ helpers

    def _wait(self, seconds: float, until: Callable[[], bool] | None = None) -> Iterator[None]:
        """Steps for `seconds` s (to the nearest step), or until `until()` holds."""
        model = self.model
        end = model.t + seconds
        while model.t < end - 0.5 * STEP_S and not (until is not None and until()):
            yield

    def _wait_until(self, condition: Callable[[], bool], timeout_s: float) -> Iterator[None]:
        """Steps until `condition()` holds, or for `timeout_s` s."""
        model = self.model
        end = model.t + timeout_s
        while not condition() and model.t < end:
            yield

    def _roll_out(self) -> Iterator[None]:
        """Rolls wings level at the normal roll rate, then holds the heading reached."""
        s, loops = self.model.state, self.loops
        loops.hold_bank(0.0)
        loops.roll.rate_max = self.model.air.roll_rate_max
        yield from self._wait_until(lambda: abs(s.phi) < 5 * DEG, 15.0)
        loops.hold_heading()

    def _steep_bank_speed(self, bank: float) -> None:
        """Steep banks need speed margin (the stall speed grows as 1/sqrt(cos(bank)))."""
        if abs(bank) > 35 * DEG:
            self.loops.hold_speed(max(self.loops.speed.speed_c, self.config.cruise_speed_mps))

    # ---------------------------------------------------------------------------- maneuvers

    def _fly_level(self, m: Level) -> Iterator[None]:
        loops = self.loops
        if self.model.state.wow:  # parked on the ground
            loops.speed.speed_c = 0.0
            yield from self._wait(m.duration_s)
            return
        loops.keep_heading()
        loops.keep_altitude()
        loops.hold_speed()
        yield from self._wait(m.duration_s)

    def _fly_turn(self, m: Turn) -> Iterator[None]:
        loops = self.loops
        loops.keep_altitude()
        loops.hold_speed()
        self._steep_bank_speed(m.bank_rad)
        loops.hold_bank(m.bank_rad)
        roll_in = abs(m.bank_rad - self.model.state.phi) / loops.roll.rate_max + 1.0
        yield from self._wait(roll_in + m.duration_s)
        yield from self._roll_out()

    def _fly_bank_reversals(self, m: BankReversals) -> Iterator[None]:
        model, loops = self.model, self.loops
        loops.keep_altitude()
        loops.hold_speed()
        self._steep_bank_speed(m.bank_rad)
        loops.roll.mode = ROLL_BANK
        loops.roll.rate_max = model.air.roll_rate_aggressive
        end = model.t + m.duration_s
        bank = m.bank_rad
        while model.t < end - 0.5 * STEP_S:
            loops.roll.bank_c = bank
            yield from self._wait(min(m.half_period_s, end - model.t))
            bank = -bank
        yield from self._roll_out()

    def _fly_altitude_change(self, m: AltitudeChange) -> Iterator[None]:
        s, loops, air = self.model.state, self.loops, self.model.air
        target = loops.held_altitude() + m.altitude_change_m
        loops.hold_altitude(target)
        loops.pitch.vspeed_limit = abs(m.vertical_speed_mps)
        if m.altitude_change_m > 0:
            loops.hold_speed(min(loops.speed.speed_c, self.config.cruise_speed_mps))
        loops.hold_heading(loops.roll.heading_c + m.heading_change_rad)
        timeout = abs(m.altitude_change_m) / max(abs(m.vertical_speed_mps), 0.5) * 2.0 + 30.0
        yield from self._wait_until(lambda: abs(target - s.h) < 10.0, timeout)
        loops.pitch.vspeed_limit = max(air.climb_rate, air.descent_rate)
        yield from self._wait_until(lambda: abs(wrap(loops.roll.heading_c - s.psi)) < 0.05, 60.0)

    def _fly_speed_change(self, m: SpeedChange) -> Iterator[None]:
        self.loops.keep_altitude()
        self.loops.hold_speed(m.speed_mps)
        yield from self._wait(m.duration_s)

    def _fly_doublet(self, m: Doublet) -> Iterator[None]:
        s, loops = self.model.state, self.loops
        loops.keep_altitude()
        if abs(s.phi) > 5 * DEG:  # a doublet starts from wings level
            yield from self._roll_out()
        loops.keep_heading()
        yield from self._wait_until(lambda: abs(s.p) < 0.03 and abs(s.phi) < 5 * DEG, 10.0)
        # Hands off that axis: its control stays where the loop had it, plus the steps.
        # The steps and the free response, unless they bank the aircraft steeply: a pilot
        # takes the controls back then (the trainers' ailerons roll them past 100 deg within
        # a step, and a spirally unstable one rolls on in the free response).
        axis = loops.hands_off(m.control)
        steep = lambda: abs(s.phi) > DOUBLET_BANK_LIMIT  # noqa: E731
        for offset, duration in (
            (m.amplitude, m.half_period_s),
            (-m.amplitude, m.half_period_s),
            (0.0, m.settle_s),
        ):
            axis.offset = offset
            yield from self._wait(duration, until=steep)
            if steep():
                break
        axis.offset = 0.0
        loops.yaw.hands_off = False
        loops.hold_altitude(loops.pitch.altitude_c)
        if loops.roll.mode == ROLL_HOLD:
            yield from self._roll_out()

    def _fly_stall(self, m: Stall) -> Iterator[None]:
        model, loops = self.model, self.loops
        s, air, controls, pitch = model.state, model.air, model.controls, loops.pitch
        entry_altitude = loops.held_altitude()
        entry_speed = loops.speed.speed_c
        loops.hold_altitude(entry_altitude)
        if m.bank_rad:
            loops.hold_bank(m.bank_rad)
        else:
            loops.keep_heading()
        pitch.speed_protection = False
        loops.set_throttle(air.idle_throttle)
        if air.retractable_gear:
            controls.set_speedbrake(1.0)  # the jet decelerates too slowly at idle alone
        # Entry: hold altitude while the speed decays, until the wing is near its limit.
        yield from self._wait_until(
            lambda: s.alpha > air.stall_alpha - 0.04 or s.v < 1.05 * air.stall_speed, 90.0
        )
        if air.full_stall:
            # Pull to the break, then keep pulling while it develops (the nose drops, the
            # sink rate builds up).
            loops.hold_attitude(s.theta)
            end = model.t + 10.0
            while not (s.stalled or s.alpha > air.stall_alpha) and model.t < end:
                pitch.attitude_c = min(pitch.attitude_c + 2 * DEG * STEP_S, air.max_pitch)
                yield
            loops.hold_elevator(min(pitch.output - 0.2, -0.6))
            yield from self._wait(2.5)
        else:
            # Approach to stall: keep holding altitude until the stall warning.
            yield from self._wait_until(lambda: s.alpha > air.stall_alpha, 40.0)
        # Recovery: nose down, full power, wings level; then climb back.
        controls.set_speedbrake(0.0)
        loops.hold_attitude(s.theta + air.recovery_pitch_change)
        loops.set_throttle(1.0)
        loops.hold_bank(0.0)
        yield from self._wait(1.0)
        yield from self._wait_until(
            lambda: (
                not s.stalled and s.alpha < air.recovered_alpha and s.v > 1.25 * air.stall_speed
            ),
            20.0,
        )
        pitch.speed_protection = True
        loops.hold_heading()
        loops.speed.integral = 1.0
        loops.hold_speed(max(entry_speed, air.climb_speed))
        loops.hold_vspeed(air.climb_rate)
        yield from self._wait_until(lambda: s.h > entry_altitude - 10.0, 120.0)
        loops.hold_altitude(entry_altitude)

    def _fly_turbulence(self, m: Turbulence) -> Iterator[None]:
        self.model.set_turbulence(int(m.severity))
        return
        yield  # a generator that does not step

    def _fly_taxi(self, m: Taxi) -> Iterator[None]:
        s, air, loops = self.model.state, self.model.air, self.loops
        roll, speed = loops.roll, loops.speed
        self.ground_allowed = True
        roll.mode = ROLL_GROUND
        loops.hold_elevator(0.0)
        speed.mode = SPEED_TAXI
        speed.speed_c = air.taxi_speed
        speed.brake = 0.0
        if air.nosewheel_steering:
            # From the ramp heading (the start), half way the turn onto the runway heading.
            runway = self.runway_heading = wrap(s.psi + m.turn_rad)
            roll.heading_c = s.psi
            yield from self._wait(0.5 * m.duration_s)
            roll.heading_c = runway
            speed.speed_c = 0.6 * air.taxi_speed
            yield from self._wait_until(lambda: abs(wrap(runway - s.psi)) < 0.03, 40.0)
            speed.speed_c = air.taxi_speed
            yield from self._wait(0.5 * m.duration_s)
        else:
            roll.heading_c = self.runway_heading = s.psi
            yield from self._wait(m.duration_s)
        # Stop (hold short, run-up), then line up.
        speed.speed_c = 0.0
        yield from self._wait_until(lambda: s.u < 0.2, 30.0)
        yield from self._wait(3.0)

    def _fly_takeoff(self, m: Takeoff) -> Iterator[None]:
        model, loops = self.model, self.loops
        s, air, controls = model.state, model.air, model.controls
        roll, pitch, speed = loops.roll, loops.pitch, loops.speed
        self.ground_allowed = True
        roll.mode = ROLL_GROUND
        roll.heading_c = self.runway_heading if s.wow else s.psi
        controls.set_flaps(air.takeoff_flaps)
        speed.brake = 0.0
        loops.set_throttle(1.0)
        loops.hold_elevator(0.0)
        yield from self._wait_until(lambda: s.v > air.rotate_speed, 90.0)
        if s.v <= air.rotate_speed:
            model.fail(f"take-off roll did not reach the rotation speed ({s.v:.1f} m/s)")
        # Rotate at about 3 deg/s.
        loops.hold_attitude(s.theta)
        pitch.integral = -pitch.held
        while s.wow or s.h < 3.0:
            pitch.attitude_c = min(pitch.attitude_c + 3 * DEG * STEP_S, air.rotate_pitch)
            if model.t > self.phase_start + 150.0:
                model.fail("no lift-off")
            yield
        self.ground_allowed = False
        loops.hold_heading(roll.heading_c)
        pitch.attitude_int = s.theta
        speed.throttle_c = 1.0
        loops.hold_vspeed(air.climb_rate)
        speed.speed_c = air.climb_speed
        speed.integral = 1.0
        while s.h < m.height_m:
            if air.retractable_gear and s.h > 10.0 and s.hdot > 1.0:
                controls.set_gear(0.0)
            if s.h > 0.6 * m.height_m and s.v > air.flaps_up_speed:
                controls.set_flaps(0.0)
            yield
        controls.set_flaps(0.0)
        controls.set_gear(0.0 if air.retractable_gear else 1.0)

    def _fly_landing(self, m: Landing) -> Iterator[None]:
        model, loops = self.model, self.loops
        s, air, controls = model.state, model.air, model.controls
        roll, pitch, speed = loops.roll, loops.pitch, loops.speed
        # Descend to the approach height while slowing down; first flaps below their speed.
        pitch.vspeed_limit = air.descent_rate
        loops.hold_speed(air.approach_speed + 15 * KT)
        loops.hold_altitude(air.approach_height)
        loops.keep_heading()
        while abs(s.h - air.approach_height) > 20.0 or s.v > speed.speed_c + 10.0:
            if s.v < air.flaps_up_speed:
                controls.set_flaps(air.takeoff_flaps)
            # The jet needs its speed brake to slow down while descending.
            controls.set_speedbrake(
                1.0 if s.v > speed.speed_c + 5.0 and air.retractable_gear else 0.0
            )
            if model.t > self.phase_start + 600.0:
                model.fail("could not reach the approach height and speed in 10 minutes")
            yield
        controls.set_speedbrake(0.0)
        # Configure, then the glide path (the runway is wherever it leads).
        controls.set_flaps(air.landing_flaps)
        controls.set_gear(1.0)
        loops.hold_speed(air.approach_speed)
        self.ground_allowed = True
        while s.h > air.flare_height:
            loops.hold_vspeed(-max(s.v, air.approach_speed) * math.tan(m.glide_path_rad))
            if s.h < 3.0 * air.flare_height:
                # This pilot does not de-crab or fight drift: touching down while drifting in a
                # gust slams the tyres sideways (a 2 g lateral spike at the eye), so the gusts
                # fade out over the last part of the approach (the low-altitude turbulence
                # intensity follows the wind at 20 ft).
                fade = clip((s.h - air.flare_height) / (2.0 * air.flare_height), 0.0, 1.0)
                model.set_wind_20ft(fade * self.config.wind_speed_20ft_mps)
            yield
        model.set_wind_20ft(0.0)
        # Flare: idle, sink rate proportional to height, down to a gentle touchdown.
        pitch.speed_protection = False
        loops.set_throttle(air.idle_throttle)
        sink_per_m = air.approach_speed * math.tan(m.glide_path_rad) / air.flare_height
        pitch.gamma_gain = 6.0  # the flare is a quick, tight pull
        loops.hold_bank(0.0)  # wings level for the touchdown
        end = model.t + 30.0
        start_pitch = s.theta
        while not s.wow and model.t < end:
            loops.hold_vspeed(-max(sink_per_m * s.h, 0.3))
            # The nose comes up to the touchdown attitude as the wheels near the ground, so
            # the main wheels touch first and the aircraft floats while the speed bleeds off.
            progress = clip(1.0 - s.h / air.flare_height, 0.0, 1.0)
            pitch.attitude_floor = start_pitch + progress * (air.touchdown_pitch - start_pitch)
            yield
        pitch.attitude_floor = -math.pi / 2
        if not s.wow:
            model.fail("no touchdown within 30 s of the flare")
        # Roll-out: lower the nose gently (dropping it slams the nose gear), wings level,
        # runway heading, moderate brakes, to a stop.
        pitch.gamma_gain = 1.0
        roll.mode = ROLL_GROUND
        roll.heading_c = s.psi
        controls.set_flaps(0.0)
        loops.hold_attitude(s.theta)
        end = model.t + 15.0
        while model.t < end and not model.nose_on_ground():
            # 1 deg/s, then 0.25 deg/s over the last 2 deg before the nose wheel touches.
            rate = 1.0 if s.theta > air.ground_pitch + 2 * DEG else 0.25
            pitch.attitude_c = max(pitch.attitude_c - rate * DEG * STEP_S, air.ground_pitch - DEG)
            yield
        loops.hold_elevator(0.0)
        speed.brake = 0.5
        yield from self._wait_until(lambda: s.u < 5.0, 120.0)
        speed.mode = SPEED_TAXI
        speed.speed_c = 0.0
        yield from self._wait_until(lambda: s.u < 0.2, 60.0)
        pitch.speed_protection = True
