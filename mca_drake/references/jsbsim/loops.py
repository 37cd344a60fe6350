"""The pilot's feedback loops: one step of every axis per JSBSim step, and their modes.

Four axes, each with its mode, targets, integrators and last output:

- roll (`RollAxis`): heading -> bank -> roll rate -> aileron; on the ground wings level;
- pitch (`PitchAxis`): altitude -> vertical speed -> pitch attitude -> pitch rate -> elevator;
- yaw (`YawAxis`): zero sideslip with the rudder in the air; on the ground (roll mode
  ROLL_GROUND) the roll axis's heading with rudder and nose wheel;
- speed (`SpeedAxis`): airspeed with the throttle, or taxi speed with throttle and brakes.

`Loops.step` runs them and writes the commands to JSBSim; its `hold_*` methods switch the
modes without a bump. Angles in rad, speeds in m/s, controls normalised (1 = full).
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque

import numpy as np

from mca_drake.references.jsbsim.aircraft import STEP_S, Airframe, G
from mca_drake.references.jsbsim.config import FlightConfig
from mca_drake.references.jsbsim.model import AircraftState, Controls
from mca_drake.references.jsbsim.style import PilotStyle

# Modes of the roll axis: hold a heading, hold a bank angle, hands off (aileron held),
# on the ground (wings level; the yaw axis steers to the heading).
ROLL_HEADING, ROLL_BANK, ROLL_HOLD, ROLL_GROUND = range(4)
# Modes of the pitch axis: hold an altitude, a vertical speed, a pitch attitude, or hands off
# (elevator held).
PITCH_ALTITUDE, PITCH_VSPEED, PITCH_ATTITUDE, PITCH_HOLD = range(4)
# Modes of the speed axis: hold an airspeed, a fixed throttle, a taxi speed (with brakes).
SPEED_AIRSPEED, SPEED_THROTTLE, SPEED_TAXI = range(3)

CONTROL_RATE = 3.0  # fastest stick/pedal motion, normalised deflection per s


def clip(x: float, lo: float, hi: float) -> float:
    """`x` limited to [lo, hi] (scalar; cheaper than numpy at one call per step)."""
    return lo if x < lo else hi if x > hi else x


def wrap(angle: float) -> float:
    """Angle wrapped to [-pi, pi), rad."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclasses.dataclass(slots=True)
class RollAxis:
    """Roll loop state: heading -> bank -> roll rate -> aileron."""

    mode: int
    # Largest commanded roll rate, rad/s (raised for bank reversals).
    rate_max: float
    # Targets, rad: true heading (ROLL_HEADING, ROLL_GROUND), bank (ROLL_BANK).
    heading_c: float = 0.0
    bank_c: float = 0.0
    # Aileron held in ROLL_HOLD, and a doublet's step added to the output.
    held: float = 0.0
    offset: float = 0.0
    # Integrator (aileron trim) and the last aileron command.
    integral: float = 0.0
    output: float = 0.0


@dataclasses.dataclass(slots=True)
class PitchAxis:
    """Pitch loop state: altitude -> vertical speed -> pitch attitude -> pitch rate -> elevator."""

    mode: int
    # Target height of the wheels above ground, m (PITCH_ALTITUDE).
    altitude_c: float
    # Largest vertical speed the altitude hold commands, m/s.
    vspeed_limit: float
    # Target vertical speed, m/s (PITCH_VSPEED), and pitch attitude, rad (PITCH_ATTITUDE).
    vspeed_c: float = 0.0
    attitude_c: float = 0.0
    # Trade height for speed when far off the target speed (off in stalls and the flare).
    speed_protection: bool = True
    # Pitch per flight-path error, rad/rad (raised in the flare).
    gamma_gain: float = 1.0
    # Lowest pitch command, rad (raised in the flare).
    attitude_floor: float = -math.pi / 2
    # Elevator held in PITCH_HOLD, and a doublet's step added to the output.
    held: float = 0.0
    offset: float = 0.0
    # Integrators: elevator trim, and the pitch attitude that gives the commanded flight
    # path, rad; the last elevator command.
    integral: float = 0.0
    attitude_int: float = 0.0
    output: float = 0.0


@dataclasses.dataclass(slots=True)
class YawAxis:
    """Yaw loop state: rudder for zero sideslip (steering on the ground)."""

    # Rudder held (hands off, a rudder doublet) instead of the sideslip loop.
    hands_off: bool = False
    # Rudder held when hands off, and a doublet's step added to the output.
    held: float = 0.0
    offset: float = 0.0
    # Integrator (rudder trim) and the last rudder command.
    integral: float = 0.0
    output: float = 0.0


@dataclasses.dataclass(slots=True)
class SpeedAxis:
    """Speed loop state: airspeed with the throttle, or taxi speed with throttle and brakes."""

    mode: int
    # Target speed, m/s: calibrated airspeed (SPEED_AIRSPEED) or ground speed (SPEED_TAXI).
    speed_c: float
    # Throttle in SPEED_THROTTLE, 0 ... 1.
    throttle_c: float
    # Integrator: the throttle that holds the speed, 0 ... 1.
    integral: float = 0.0
    # Both wheel brakes, 0 ... 1.
    brake: float = 0.0


class Hand:
    """The pilot's hand between the decision and the controls: a first-order lag of
    `lag_s` (the neuromuscular system) on each of aileron, elevator and rudder, with
    remnant noise added before it (white, scaled so that its RMS after the lag is
    `remnant`; `PilotStyle.neuromuscular_lag_s`, `remnant`). Without a lag it passes the
    commands through.

    Args:
        lag_s: the lag's time constant, s (0: none).
        remnant: RMS of the remnant at the controls, normalised deflection (needs a lag).
        seed: the remnant's random stream.
    """

    def __init__(self, lag_s: float, remnant: float, seed: int) -> None:
        # exact discretisation of dy/dt = (u - y) / lag_s with u held over a step
        self._alpha = 1.0 - math.exp(-STEP_S / lag_s) if lag_s > 0 else 1.0
        # white noise of variance s^2 through y += alpha (n - y) has variance
        # s^2 alpha / (2 - alpha)
        a = self._alpha
        self._noise = remnant * math.sqrt((2.0 - a) / a) if remnant > 0 else 0.0
        self._rng = np.random.default_rng([seed, REMNANT_STREAM]) if self._noise else None
        self._position: list[float] | None = None

    def move(self, commands: tuple[float, float, float]) -> tuple[float, float, float]:
        """The controls (3) after one step toward `commands` (3); the first call starts
        at `commands` (the trim, not a bump)."""
        if self._alpha == 1.0:
            return commands
        targets = list(commands)
        if self._rng is not None:
            noise = self._rng.standard_normal(3) * self._noise
            targets = [c + n for c, n in zip(targets, noise.tolist(), strict=True)]
        if self._position is None:
            self._position = list(commands)
        a = self._alpha
        self._position = [p + a * (t - p) for p, t in zip(self._position, targets, strict=True)]
        # a hand holds the stick inside its travel
        return tuple(clip(p, -1.0, 1.0) for p in self._position)


# The remnant's stream of a flight's seed (apart from the plan's and the style's draws).
REMNANT_STREAM = 4


class Loops:
    """The pilot's four loops, reading `state` and writing `controls` once per step.

    Args:
        air: the vehicle's airframe constants (gains, limits).
        config: the resolved flight config (maneuver altitude and cruise speed: the targets
            at the start).
        state: the aircraft state, updated by the model each step.
        controls: JSBSim's command setters.
        throttle: the throttle the model was initialised at (the speed integrator's start).
        style: how the pilot flies: the outer loops' gains, the hand's control rate and
            the reaction delay (the inner gains and rate limits come with `air`,
            `PilotStyle.airframe`); None: the scripted pilot.
    """

    def __init__(
        self,
        air: Airframe,
        config: FlightConfig,
        state: AircraftState,
        controls: Controls,
        throttle: float,
        style: PilotStyle | None = None,
    ) -> None:
        style = style or PilotStyle()
        self.air = air
        self.outer_gain = style.outer_gain
        self.control_rate = CONTROL_RATE * style.aggressiveness
        # the surfaces' commands of the last `delay` steps, oldest first: what the pilot
        # decided reaches the surfaces `reaction_delay_s` later
        # (the first command is held until the delay has passed: the trim, not a bump)
        self._delay = round(style.reaction_delay_s / STEP_S)
        self._delayed: deque[tuple[float, float, float]] = deque()
        self._hand = Hand(style.neuromuscular_lag_s, style.remnant, style.remnant_seed)
        self.state = state
        self.controls = controls
        self.roll = RollAxis(mode=ROLL_HEADING, rate_max=air.roll_rate_max)
        self.pitch = PitchAxis(
            mode=PITCH_ALTITUDE,
            altitude_c=config.maneuver_altitude_m,
            vspeed_limit=max(air.climb_rate, air.descent_rate),
        )
        self.yaw = YawAxis()
        self.speed = SpeedAxis(
            mode=SPEED_AIRSPEED,
            speed_c=config.cruise_speed_mps,
            throttle_c=air.idle_throttle,
            integral=throttle,
        )

    # ------------------------------------------------------------------------------- step

    def step(self) -> None:
        """The pilot's loops: one step of every axis, written to JSBSim."""
        s = self.state
        airborne = not s.wow
        # Gains are set at the reference dynamic pressure; a slower aircraft needs more stick.
        sched = clip(self.air.qbar_ref_psf / max(s.qbar, 1.0), 0.3, 5.0)
        aileron = self._aileron(sched, airborne)
        elevator = self._elevator(sched, airborne)
        rudder = self._rudder(sched, airborne)
        throttle = self._throttle()
        # A pilot's hand (and the surface actuators) cannot step: rate-limit every control,
        # or a reversal or doublet would give a one-sample jump of the roll acceleration (and of
        # the lateral specific force at an eye point metres above the roll axis).
        step = self.control_rate * STEP_S
        roll, pitch, yaw = self.roll, self.pitch, self.yaw
        aileron = clip(aileron, roll.output - step, roll.output + step)
        elevator = clip(elevator, pitch.output - step, pitch.output + step)
        rudder = clip(rudder, yaw.output - step, yaw.output + step)
        roll.output, pitch.output, yaw.output = aileron, elevator, rudder
        if self._delay:
            self._delayed.append((aileron, elevator, rudder))
            if len(self._delayed) > self._delay:
                aileron, elevator, rudder = self._delayed.popleft()
            else:
                aileron, elevator, rudder = self._delayed[0]
        aileron, elevator, rudder = self._hand.move((aileron, elevator, rudder))
        self.controls.write(aileron, elevator, rudder, throttle, self.speed.brake)

    def _aileron(self, sched: float, airborne: bool) -> float:
        """Roll: heading -> bank -> roll rate -> aileron."""
        air, s, roll, dt = self.air, self.state, self.roll, STEP_S
        mode = roll.mode
        if mode == ROLL_HEADING or mode == ROLL_BANK:
            if mode == ROLL_HEADING:
                bank_c = clip(
                    1.5 * self.outer_gain * wrap(roll.heading_c - s.psi),
                    -air.heading_bank,
                    air.heading_bank,
                )
            else:
                bank_c = roll.bank_c
            p_c = clip(2.0 * self.outer_gain * (bank_c - s.phi), -roll.rate_max, roll.rate_max)
            error = p_c - s.p
            if airborne:
                roll.integral = clip(roll.integral + 0.3 * error * dt, -0.3, 0.3)
            aileron = sched * air.roll_rate_gain * error + roll.integral
        elif mode == ROLL_HOLD:
            aileron = roll.held
        else:  # on the ground: wings level with the roll rate only
            aileron = -0.5 * s.p
        return clip(aileron + roll.offset, -1.0, 1.0)

    def _elevator(self, sched: float, airborne: bool) -> float:
        """Pitch: altitude -> vertical speed -> pitch attitude -> pitch rate -> elevator."""
        air, s, pitch, dt = self.air, self.state, self.pitch, STEP_S
        mode = pitch.mode
        if mode != PITCH_HOLD:
            v = max(s.v, 0.5 * air.stall_speed)
            if mode == PITCH_ATTITUDE:
                pitch_c = pitch.attitude_c
            else:
                if mode == PITCH_ALTITUDE:
                    vspeed_c = clip(
                        0.15 * self.outer_gain * (pitch.altitude_c - s.h),
                        -pitch.vspeed_limit,
                        pitch.vspeed_limit,
                    )
                else:
                    vspeed_c = pitch.vspeed_c
                if pitch.speed_protection:
                    # Trade height for speed when slow (and the reverse when fast), as a pilot
                    # does when the throttle alone cannot hold the speed; at most half the
                    # normal descent rate either way.
                    speed_c = self.speed.speed_c
                    slow = speed_c - 8.0 - s.v
                    fast = s.v - speed_c - 8.0
                    if slow > 0.0:
                        vspeed_c -= min(0.7 * slow, 0.5 * air.descent_rate)
                    elif fast > 0.0:
                        vspeed_c += min(0.5 * fast, 0.5 * air.descent_rate)
                gamma_error = clip((vspeed_c - s.hdot) / v, -0.3, 0.3)
                if airborne:
                    pitch.attitude_int = clip(
                        pitch.attitude_int + 0.3 * gamma_error * dt, air.min_pitch, air.max_pitch
                    )
                pitch_c = pitch.attitude_int + pitch.gamma_gain * gamma_error
            pitch_c = clip(max(pitch_c, pitch.attitude_floor), air.min_pitch, air.max_pitch)
            cos_phi = max(math.cos(s.phi), 0.3)
            # Pitch rate of a coordinated level turn, q = (g / V) sin(phi) tan(phi).
            q_turn = G / v * math.sin(s.phi) ** 2 / cos_phi
            q_c = clip(
                1.5 * self.outer_gain * (pitch_c - s.theta), -air.pitch_rate_max, air.pitch_rate_max
            )
            error = q_c * cos_phi + q_turn - s.q
            pitch.integral = clip(pitch.integral + 1.0 * error * dt, -1.0, 1.0)
            # Positive elevator is nose down in JSBSim (checked: +0.2 gives q < 0).
            elevator = -(sched * air.pitch_rate_gain * error + pitch.integral)
        else:
            elevator = pitch.held
        return clip(elevator + pitch.offset, -1.0, 1.0)

    def _rudder(self, sched: float, airborne: bool) -> float:
        """Yaw: zero sideslip in the air; heading with rudder (and nose wheel) on the ground."""
        air, s, yaw, dt = self.air, self.state, self.yaw, STEP_S
        if self.roll.mode == ROLL_GROUND:
            heading_error = clip(wrap(self.roll.heading_c - s.psi), -0.5, 0.5)
            turn = 3.0 * heading_error - 1.5 * s.r
            # Positive rudder yaws the nose left, positive steering right (both checked).
            rudder = -clip(turn, -1.0, 1.0)
            # Nose-wheel steering is for taxi speeds; at roll-out speeds it would skid the tyres.
            steer_gain = min(1.0, air.taxi_speed / max(s.u, 1.0))
            self.controls.set_steer(clip(steer_gain * turn, -1.0, 1.0))
        elif yaw.hands_off:
            rudder = yaw.held
        else:
            if airborne:
                yaw.integral = clip(yaw.integral - 0.5 * s.beta * dt, -0.3, 0.3)
            rudder = -sched * air.yaw_gain * s.beta + yaw.integral
        return clip(rudder + yaw.offset, -1.0, 1.0)

    def _throttle(self) -> float:
        """Throttle (and, taxiing, the brakes) for the speed axis's mode."""
        air, s, speed, dt = self.air, self.state, self.speed, STEP_S
        mode = speed.mode
        if mode == SPEED_AIRSPEED:
            error = speed.speed_c - s.v
            throttle = speed.integral + 0.08 * error
            # Integrate only while it can help (anti-windup at idle and full power).
            if 0.0 < throttle < 1.0 or (throttle >= 1.0) != (error > 0.0):
                speed.integral = clip(speed.integral + 0.02 * error * dt, 0.0, 1.0)
            throttle = clip(throttle, air.idle_throttle, 1.0)
        elif mode == SPEED_TAXI:
            error = speed.speed_c - s.u
            if speed.speed_c <= 0.0:
                # Stop with moderate braking (a smooth stop, not a panic stop), then hold.
                speed.integral = air.idle_throttle
                throttle = air.idle_throttle
                speed.brake = 1.0 if s.u < 0.5 else 0.3
            else:
                speed.integral = clip(speed.integral + 0.03 * error * dt, 0.0, 0.6)
                throttle = clip(speed.integral + 0.1 * error, air.idle_throttle, 0.8)
                speed.brake = clip(-0.3 * (error + 1.0), 0.0, 1.0)
        else:
            throttle = speed.throttle_c
        return throttle

    # ------------------------------------------------------------------------------ modes

    def held_altitude(self) -> float:
        """The altitude the pitch axis holds, else the height now, m."""
        return self.pitch.altitude_c if self.pitch.mode == PITCH_ALTITUDE else self.state.h

    def keep_heading(self) -> None:
        """Holds the heading held so far, else the heading now."""
        self.hold_heading(self.roll.heading_c if self.roll.mode == ROLL_HEADING else None)

    def keep_altitude(self) -> None:
        """Holds the altitude held so far, else the height now."""
        self.hold_altitude(self.held_altitude())

    def hold_heading(self, heading: float | None = None) -> None:
        """Holds `heading`, rad (None: the heading now)."""
        self.roll.mode = ROLL_HEADING
        self.roll.heading_c = self.state.psi if heading is None else heading

    def hold_bank(self, bank: float) -> None:
        """Holds the bank angle `bank`, rad (positive right wing down)."""
        self.roll.mode, self.roll.bank_c = ROLL_BANK, bank

    def hold_altitude(self, altitude: float | None = None) -> None:
        """Holds `altitude` (wheels above ground), m (None: the height now)."""
        pitch = self.pitch
        if pitch.mode not in (PITCH_ALTITUDE, PITCH_VSPEED):
            pitch.attitude_int = self.state.theta  # bumpless: start from the current attitude
        pitch.mode = PITCH_ALTITUDE
        pitch.altitude_c = self.state.h if altitude is None else altitude

    def hold_vspeed(self, vspeed: float) -> None:
        """Holds the vertical speed `vspeed`, m/s (positive up)."""
        pitch = self.pitch
        if pitch.mode not in (PITCH_ALTITUDE, PITCH_VSPEED):
            pitch.attitude_int = self.state.theta  # bumpless: start from the current attitude
        pitch.mode = PITCH_VSPEED
        pitch.vspeed_c = vspeed

    def hold_attitude(self, attitude: float) -> None:
        """Holds the pitch attitude `attitude`, rad."""
        self.pitch.mode, self.pitch.attitude_c = PITCH_ATTITUDE, attitude

    def hold_elevator(self, elevator: float) -> None:
        """Hands off the pitch axis: the elevator stays at `elevator` (normalised)."""
        self.pitch.mode, self.pitch.held = PITCH_HOLD, elevator

    def hold_speed(self, speed: float | None = None) -> None:
        """Holds the calibrated airspeed `speed`, m/s (None: the last target speed)."""
        if self.speed.mode != SPEED_AIRSPEED:
            self.speed.integral = self.speed.throttle_c  # bumpless: from the fixed throttle
        self.speed.mode = SPEED_AIRSPEED
        if speed is not None:
            self.speed.speed_c = speed

    def set_throttle(self, throttle: float) -> None:
        """A fixed throttle, 0 ... 1 (the speed is not held)."""
        self.speed.mode = SPEED_THROTTLE
        self.speed.throttle_c = throttle

    def hands_off(self, control: str) -> RollAxis | PitchAxis | YawAxis:
        """Lets go of "elevator", "aileron" or "rudder": it stays where the loop had it.

        Returns the control's axis, whose `offset` then adds a doublet's steps to it.
        """
        if control == "elevator":
            self.hold_elevator(self.pitch.output)
            return self.pitch
        if control == "aileron":
            self.roll.mode, self.roll.held = ROLL_HOLD, self.roll.output
            return self.roll
        self.yaw.hands_off, self.yaw.held = True, self.yaw.output
        return self.yaw
