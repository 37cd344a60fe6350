"""Flights from JSBSim, flown by a seeded scripted pilot: the IMU at the pilot's eye point.

`fly(vehicle, duration_s, seed)` runs a JSBSim flight dynamics model at 100 Hz with a
feedback-control "pilot" (PID-like loops on bank, pitch, vertical speed, altitude, heading,
airspeed and sideslip) whose targets and segment durations are drawn from a numpy Generator
seeded by `seed`, and returns what an IMU at the pilot's eye point measured as a `Recording`
(head-frame axes x forward, y left, z up; SI units).

Vehicles (JSBSim models shipped with the `jsbsim` wheel):

    light  c172p       a single-engine piston aircraft, our analogue of the Cirrus SR-22
    jet    global5000  a twin-jet business aircraft, our analogue of the Cessna Citation X

Flight plans. Flights of at least `FULL_FLIGHT_MIN_DURATION_S[vehicle]` start parked on the
ground: taxi, take-off, a climbing turn to the maneuver altitude, the maneuvers, a descent,
a 3 degree approach, flare, touchdown, roll-out to a stop (then parked to the end). Shorter
flights start airborne, trimmed at the maneuver altitude, and fly maneuvers only. The
maneuvers are a lesson plan in random order (steep turns, aggressive bank reversals, a stall
and recovery, elevator/aileron/rudder doublets, speed and altitude changes) followed by
random draws from the same kinds, with turbulent patches (JSBSim's MIL-F-8785C model) in
between. `FlightConfig.maneuvers` replaces the random plan by an explicit list.

Axes. JSBSim's body axes are x forward, y right, z down and `accelerations/a-pilot-*` is the
specific force at the eye point (level flight: (0, 0, -g)); the head frame is x forward,
y left, z up, so omega = (p, -q, -r) and f = 0.3048 (a_x, -a_y, -a_z) m/s^2.

The recording has round(duration_s * 100) + 1 samples at t = 0, 0.01, ..., covering
[0, duration_s]; sample k is the state after k JSBSim steps of 0.01 s (JSBSim runs at 100 Hz;
sample 0 follows the trim or, on the ground, a few unrecorded seconds settling on the gear).

Sanity. Every step: first wheel contact outside take-off and landing, or faster than 3 m/s
sink, and single-sample load spikes; every 0.1 s: NaN, wheels below ground, a wing tip or
skid touching, overspeed, roll beyond 100 deg or pitch beyond 60 deg, and the mean load
factor (6 g light, 4 g jet). Any of them raises `FlightError` naming vehicle, seed, time,
maneuver and cause. JSBSim's console output goes to a private logger (its last warning is
quoted in the error), and the global5000's declared CSV output to os.devnull.

Limitations (of the models and of this pilot):
- the global5000 model's autopilot system overwrites the nose-wheel steering command, so the
  jet taxis straight (it has no P-factor, the rudder holds the runway heading at speed);
- the pilot neither de-crabs nor fights drift, so gusts fade out over the last ~3 flare
  heights of an approach (else the tyres slam sideways at touchdown);
- JSBSim's gear dampers are massless: the main wheels touching (light, ~2.5 g) and the jet's
  nose wheel coming down (3 to 5 g, the eye point is 18 m ahead of the main gear) give one-
  or two-sample spikes of f_z;
- the c172p cannot reach its stall-hysteresis angle with full back stick: its "stall" is
  the mush and nose drop at 16 deg angle of attack; the jet flies an approach to stall
  (recovery at the stick-shaker angle of attack) as airline training does.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Iterator

import jsbsim
import numpy as np

from mca_drake.references.recording import Recording

VEHICLES = ("light", "jet")
JSBSIM_MODELS = {"light": "c172p", "jet": "global5000"}
SAMPLE_RATE_HZ = 100.0
# Flights at least this long (s) take off and land by default; shorter ones start airborne.
# Taxi, take-off, climb, descent, approach and roll-out take about 8 minutes in the light
# aircraft (to 600 m) and 9 in the jet (to 2000 m); the rest is maneuvers.
FULL_FLIGHT_MIN_DURATION_S = {"light": 600.0, "jet": 720.0}

_STEP_S = 1.0 / SAMPLE_RATE_HZ
_FT = 0.3048  # m per ft
_KT = 1852.0 / 3600.0  # m/s per knot
_G = 9.80665  # m/s^2, JSBSim's standard gravity at sea level
_DEG = math.pi / 180.0
_CONTROL_RATE = 3.0  # fastest stick/pedal motion, normalised deflection per s
_MAX_TOUCHDOWN_SINK = 3.0  # m/s; beyond it a touchdown is a crash (about 600 ft/min)
_CHECK_EVERY = 10  # steps between the full sanity checks (a load spike is checked every step)

# Control modes of the pilot's loops.
_LAT_HEADING, _LAT_BANK, _LAT_HOLD, _LAT_GROUND = range(4)
_VERT_ALTITUDE, _VERT_VSPEED, _VERT_PITCH, _VERT_HOLD = range(4)
_SPEED_AIRSPEED, _SPEED_THROTTLE, _SPEED_TAXI = range(3)


class FlightError(RuntimeError):
    """A flight left the sane envelope (crash, overspeed, overload, NaN); says when and why."""


# --------------------------------------------------------------------------------- maneuvers
# Each maneuver is a small frozen dataclass; the pilot flies them in order. Angles in rad
# (positive bank: right wing down), heights in m, speeds in m/s (calibrated airspeed).


@dataclasses.dataclass(frozen=True)
class Level:
    """Straight and level flight at the current altitude, heading and speed (parked: wait)."""

    # How long, s.
    duration_s: float = 20.0


@dataclasses.dataclass(frozen=True)
class Turn:
    """A level turn at a fixed bank angle, then roll-out to wings level."""

    # Bank angle, rad; positive is a right turn (right wing down).
    bank_rad: float = 30.0 * _DEG
    # Time at the bank angle (after the roll-in), s.
    duration_s: float = 30.0


@dataclasses.dataclass(frozen=True)
class BankReversals:
    """Aggressive rolling: bank alternates between +bank_rad and -bank_rad, altitude held."""

    # Bank angle of each side, rad (the first reversal goes to the sign given).
    bank_rad: float = 45.0 * _DEG
    # Time between reversals, s.
    half_period_s: float = 4.0
    # Total time, s (then roll-out).
    duration_s: float = 20.0


@dataclasses.dataclass(frozen=True)
class AltitudeChange:
    """Climb or descend by a height change at a vertical speed, optionally while turning."""

    # Height change, m (negative: descend).
    altitude_change_m: float = 150.0
    # Magnitude of the vertical speed, m/s.
    vertical_speed_mps: float = 3.0
    # Heading change flown during the climb or descent, rad (positive: to the right).
    heading_change_rad: float = 0.0


@dataclasses.dataclass(frozen=True)
class SpeedChange:
    """A new target airspeed, reached with throttle at constant altitude."""

    # New calibrated airspeed, m/s.
    speed_mps: float = 50.0
    # Time given to the change, s.
    duration_s: float = 25.0


@dataclasses.dataclass(frozen=True)
class Doublet:
    """A step input +a, -a on one control, hands off for a while, then back to the loops."""

    # "elevator", "aileron" or "rudder".
    control: str = "elevator"
    # Step size in normalised control units (1 = full deflection); its sign sets the first step.
    amplitude: float = 0.2
    # Length of each of the two steps, s.
    half_period_s: float = 1.0
    # Hands-off time after the doublet, s (the free response).
    settle_s: float = 4.0


@dataclasses.dataclass(frozen=True)
class Stall:
    """Power-off stall (light) or approach to stall (jet) with recovery to the entry altitude.

    Throttle to idle, hold altitude while the speed decays, then (light) pull to the critical
    angle of attack and hold full back stick while the nose drops, or (jet) hold on to the
    stick-shaker angle of attack; then lower the nose, full power, wings level and climb back.
    """

    # Bank angle held during the entry, rad (0: wings-level stall; else a turning stall).
    bank_rad: float = 0.0


@dataclasses.dataclass(frozen=True)
class Turbulence:
    """From here on, JSBSim's MIL-F-8785C turbulence at this severity (zero duration)."""

    # Probability-of-exceedance index, 0 (calm) ... 7; 2 is light, 3 moderate, 4 severe.
    severity: int = 3


@dataclasses.dataclass(frozen=True)
class Taxi:
    """Taxi (light 5 m/s, with a turn onto the runway; jet 8 m/s, straight), then stop."""

    # Time rolling, s (the stop and the turn onto the runway heading come on top).
    duration_s: float = 30.0
    # Angle between the ramp heading and the runway heading, rad (the jet taxis straight: its
    # JSBSim model overrides the nose-wheel steering).
    turn_rad: float = 90.0 * _DEG


@dataclasses.dataclass(frozen=True)
class Takeoff:
    """Take-off roll, rotation, lift-off and initial climb to `height_m` above ground."""

    # Height above ground that ends the take-off, m.
    height_m: float = 150.0


@dataclasses.dataclass(frozen=True)
class Landing:
    """Descent to the approach height, 3 degree approach, flare, touchdown, roll-out, stop."""

    # Glide path angle, rad.
    glide_path_rad: float = 3.0 * _DEG


Maneuver = (
    Level
    | Turn
    | BankReversals
    | AltitudeChange
    | SpeedChange
    | Doublet
    | Stall
    | Turbulence
    | Taxi
    | Takeoff
    | Landing
)


# ------------------------------------------------------------------------------- airframes


@dataclasses.dataclass(frozen=True)
class _Airframe:
    """Per-model constants of the pilot and the sanity checks (not user knobs)."""

    model: str
    engines: int
    # Speeds, m/s calibrated.
    rotate_speed: float
    climb_speed: float
    approach_speed: float
    taxi_speed: float  # ground speed
    stall_speed: float  # clean, idle
    never_exceed_speed: float  # FlightError above this
    # Vertical speeds, m/s.
    climb_rate: float
    descent_rate: float
    # Angles, rad.
    rotate_pitch: float
    max_pitch: float
    min_pitch: float
    heading_bank: float  # bank used to change heading
    stall_alpha: float  # angle of attack of the break (light) or of the stick shaker (jet)
    recovery_pitch_change: float  # nose-down pitch change of the stall recovery
    recovered_alpha: float  # angle of attack below which the recovery is over
    full_stall: bool  # pull through to the break (else recover at the stall warning)
    # Heights, m.
    approach_height: float  # above ground, start of the glide path
    flare_height: float  # wheels above ground
    cg_height_on_ground: float  # JSBSim's h-agl on the ground, ft -> m
    ground_pitch: float  # pitch attitude on all wheels, rad
    touchdown_pitch: float  # pitch attitude the flare reaches at touchdown (mains first), rad
    # Flap commands (normalised).
    takeoff_flaps: float
    landing_flaps: float
    flaps_up_speed: float  # m/s; flaps retract above it after take-off, extend below it
    retractable_gear: bool
    nosewheel_steering: bool
    # Loop gains: normalised control per rad/s of rate error at the reference dynamic pressure.
    qbar_ref_psf: float
    roll_rate_gain: float
    pitch_rate_gain: float
    yaw_gain: float  # rudder per rad of sideslip
    roll_rate_max: float  # rad/s, normal
    roll_rate_aggressive: float  # rad/s, bank reversals
    pitch_rate_max: float  # rad/s
    # Load factor |f|/g that raises FlightError.
    max_load_factor: float
    idle_throttle: float
    # Seconds of ground time after touchdown (roll-out and stop) used to plan the descent.
    rollout_s: float


_AIRFRAMES = {
    "light": _Airframe(
        model="c172p",
        engines=1,
        rotate_speed=55 * _KT,
        climb_speed=75 * _KT,
        approach_speed=65 * _KT,
        taxi_speed=5.0,
        stall_speed=48 * _KT,
        never_exceed_speed=163 * _KT,
        climb_rate=3.5,
        descent_rate=4.0,
        rotate_pitch=8 * _DEG,
        max_pitch=22 * _DEG,
        min_pitch=-15 * _DEG,
        heading_bank=25 * _DEG,
        stall_alpha=0.27,
        recovery_pitch_change=-10 * _DEG,
        recovered_alpha=0.15,
        full_stall=True,
        approach_height=150.0,
        flare_height=6.0,
        cg_height_on_ground=4.35 * _FT,
        ground_pitch=2.4 * _DEG,
        touchdown_pitch=7 * _DEG,
        takeoff_flaps=1.0 / 3.0,
        landing_flaps=1.0,
        flaps_up_speed=65 * _KT,
        retractable_gear=False,
        nosewheel_steering=True,
        qbar_ref_psf=30.0,
        roll_rate_gain=1.0,
        pitch_rate_gain=1.5,
        yaw_gain=3.0,
        roll_rate_max=20 * _DEG,
        roll_rate_aggressive=50 * _DEG,
        pitch_rate_max=12 * _DEG,
        max_load_factor=6.0,
        idle_throttle=0.0,
        rollout_s=35.0,
    ),
    "jet": _Airframe(
        model="global5000",
        engines=2,
        rotate_speed=150 * _KT,
        climb_speed=250 * _KT,
        approach_speed=130 * _KT,
        taxi_speed=8.0,
        stall_speed=150 * _KT,
        never_exceed_speed=360 * _KT,
        climb_rate=12.0,
        descent_rate=12.0,
        rotate_pitch=10 * _DEG,
        max_pitch=20 * _DEG,
        min_pitch=-12 * _DEG,
        heading_bank=20 * _DEG,
        stall_alpha=0.19,
        recovery_pitch_change=-4 * _DEG,
        recovered_alpha=0.13,
        full_stall=False,
        approach_height=300.0,
        flare_height=20.0,
        cg_height_on_ground=8.79 * _FT,
        ground_pitch=0.3 * _DEG,
        touchdown_pitch=6 * _DEG,
        # The model's flaps add 0.05 lift coefficient per degree (1.5 at 30 deg): with full
        # flaps it would approach at a negative angle of attack, so 20 deg is enough.
        takeoff_flaps=1.0 / 3.0,
        landing_flaps=2.0 / 3.0,
        flaps_up_speed=180 * _KT,
        retractable_gear=True,
        nosewheel_steering=False,
        qbar_ref_psf=200.0,
        roll_rate_gain=1.4,
        pitch_rate_gain=2.0,
        yaw_gain=3.0,
        roll_rate_max=8 * _DEG,
        roll_rate_aggressive=15 * _DEG,
        pitch_rate_max=5 * _DEG,
        max_load_factor=4.0,
        idle_throttle=0.0,
        rollout_s=50.0,
    ),
}


# ---------------------------------------------------------------------------------- config


@dataclasses.dataclass
class FlightConfig:
    """Knobs of a flight; a field left None takes the vehicle's default (`default_config`)."""

    # Start parked on the ground, taxi, take off and finish with approach, touchdown and stop;
    # None: only when duration_s >= FULL_FLIGHT_MIN_DURATION_S[vehicle] (forced on a shorter
    # flight, the recording ends wherever the plan is).
    from_ground: bool | None = None
    # Background turbulence of JSBSim's MIL-F-8785C ("milspec") model: the probability-of-
    # exceedance index, 0 calm, 1 very light, 2 light, 3 moderate, 4 severe ... 7.
    turbulence_severity: int | None = None
    # Strongest severity of the random plan's turbulent patches (at most the background: none).
    turbulence_patch_severity: int | None = None
    # Wind speed 20 ft above ground that sets the turbulence intensity below 1000 ft (JSBSim
    # adds no mean wind for it), m/s.
    wind_speed_20ft_mps: float = 7.5
    # Largest bank angle of the random plan's turns and reversals, rad.
    max_bank_rad: float | None = None
    # Height above ground where the maneuvers start (airborne flights start here), m.
    maneuver_altitude_m: float | None = None
    # Band of heights above ground for the random altitude changes, m.
    min_altitude_m: float | None = None
    max_altitude_m: float | None = None
    # Cruise (maneuvering) calibrated airspeed, m/s.
    cruise_speed_mps: float | None = None
    # Heading at the start, rad from north (None: drawn from the seed).
    initial_heading_rad: float | None = None
    # Maneuvers flown in order instead of the random plan; afterwards level flight (or parked
    # on the ground) to the end. A ground start needs Taxi/Takeoff first.
    maneuvers: tuple[Maneuver, ...] | None = None

    def resolved(self, vehicle: str) -> FlightConfig:
        """A copy with every None field (except from_ground, heading) set to the vehicle's."""
        defaults = _VEHICLE_DEFAULTS[_check_vehicle(vehicle)]
        missing = {name: value for name, value in defaults.items() if getattr(self, name) is None}
        return dataclasses.replace(self, **missing)


_VEHICLE_DEFAULTS = {
    "light": dict(
        turbulence_severity=2,
        turbulence_patch_severity=3,
        max_bank_rad=60 * _DEG,
        maneuver_altitude_m=600.0,
        min_altitude_m=400.0,
        max_altitude_m=1200.0,
        cruise_speed_mps=100 * _KT,
    ),
    "jet": dict(
        turbulence_severity=2,
        turbulence_patch_severity=3,
        max_bank_rad=45 * _DEG,
        maneuver_altitude_m=2000.0,
        min_altitude_m=1500.0,
        max_altitude_m=3500.0,
        cruise_speed_mps=250 * _KT,
    ),
}


def default_config(vehicle: str) -> FlightConfig:
    """The vehicle's default FlightConfig with every field filled in."""
    return FlightConfig().resolved(vehicle)


@dataclasses.dataclass
class FlightLog:
    """Vehicle states alongside a recording, on the same time grid.

    Attributes:
        t: sample times, s, shape (T,).
        attitude: roll, pitch, true heading, rad, shape (T, 3) (roll positive right wing down).
        height_m: height of the centre of gravity above ground, m, shape (T,).
        airspeed_mps: calibrated airspeed, m/s, shape (T,).
        on_ground: weight on wheels, shape (T,), bool.
        phases: (start time s, maneuver) in flying order.
    """

    t: np.ndarray
    attitude: np.ndarray
    height_m: np.ndarray
    airspeed_mps: np.ndarray
    on_ground: np.ndarray
    phases: list[tuple[float, str]]

    def phase_at(self, t: float) -> str:
        """The maneuver flown at time t, s."""
        name = self.phases[0][1] if self.phases else ""
        for start, phase in self.phases:
            if start > t:
                break
            name = phase
        return name


# ------------------------------------------------------------------------------ public API


def fly(
    vehicle: str,
    duration_s: float,
    seed: int,
    *,
    config: FlightConfig | None = None,
    progress: bool = False,
) -> Recording:
    """Flies `vehicle` for `duration_s` with the pilot seeded by `seed`; the eye-point IMU.

    Args:
        vehicle: "light" (JSBSim c172p) or "jet" (global5000).
        duration_s: length of the recording, s (> 0).
        seed: seeds the pilot's plan and JSBSim's turbulence; same seed, same recording.
        config: knobs (None: `default_config(vehicle)`).
        progress: show a tqdm bar over simulated time.

    Returns:
        Recording at 100 Hz with round(duration_s * 100) + 1 samples (t = 0, 0.01, ...):
        omega (T, 3) rad/s and f (T, 3) m/s^2 in head axes (x forward, y left, z up);
        metadata: vehicle, jsbsim_model, jsbsim_version, seed, duration_s, from_ground,
        phases ("t name; ...").

    Raises:
        ValueError: unknown vehicle, bad duration or config.
        FlightError: the flight left the sane envelope (crash, overload, overspeed, NaN).
    """
    return fly_with_log(vehicle, duration_s, seed, config=config, progress=progress)[0]


def fly_with_log(
    vehicle: str,
    duration_s: float,
    seed: int,
    *,
    config: FlightConfig | None = None,
    progress: bool = False,
) -> tuple[Recording, FlightLog]:
    """`fly`, plus the vehicle's attitude, height, airspeed and phases on the same grid."""
    _check_vehicle(vehicle)
    if not (math.isfinite(duration_s) and duration_s >= _STEP_S):
        raise ValueError(f"duration_s must be a finite number >= {_STEP_S}; got {duration_s}")
    config = (config or FlightConfig()).resolved(vehicle)
    _check_config(config)
    logger = _QuietLogger()
    previous = jsbsim.get_logger()
    jsbsim.set_logger(logger)  # JSBSim's console chatter goes to our buffer instead
    try:
        flight = _Flight(vehicle, float(duration_s), int(seed), config, logger)
        return flight.run(progress)
    finally:
        jsbsim.set_logger(previous)


# --------------------------------------------------------------------------------- helpers


def _check_vehicle(vehicle: str) -> str:
    if vehicle not in JSBSIM_MODELS:
        raise ValueError(f"unknown vehicle '{vehicle}'; valid: {', '.join(VEHICLES)}")
    return vehicle


def _check_config(config: FlightConfig) -> None:
    for name in ("turbulence_severity", "turbulence_patch_severity"):
        value = getattr(config, name)
        if not 0 <= value <= 7:
            raise ValueError(f"{name} must be in 0 ... 7; got {value}")
    if not 0 < config.max_bank_rad < 80 * _DEG:
        raise ValueError(f"max_bank_rad must be in (0, 80 deg); got {config.max_bank_rad}")
    if not 0 < config.min_altitude_m <= config.maneuver_altitude_m <= config.max_altitude_m:
        raise ValueError(
            "need 0 < min_altitude_m <= maneuver_altitude_m <= max_altitude_m; got "
            f"{config.min_altitude_m}, {config.maneuver_altitude_m}, {config.max_altitude_m}"
        )
    for m in config.maneuvers or ():
        if isinstance(m, Doublet) and m.control not in ("elevator", "aileron", "rudder"):
            raise ValueError(
                f"unknown doublet control '{m.control}'; valid: elevator, aileron, rudder"
            )
        if isinstance(m, Turbulence) and not 0 <= m.severity <= 7:
            raise ValueError(f"turbulence severity must be in 0 ... 7; got {m.severity}")
        if not isinstance(m, Maneuver):
            raise ValueError(f"not a maneuver: {m!r}")


def _clip(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


def _wrap(angle: float) -> float:
    """Angle wrapped to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _describe(m: Maneuver) -> str:
    fields = []
    for field in dataclasses.fields(m):
        value = getattr(m, field.name)
        if field.name.endswith("_rad"):
            fields.append(f"{field.name[:-4]}={value / _DEG:+.0f}deg")
        elif isinstance(value, float):
            fields.append(f"{field.name}={value:.3g}")
        else:
            fields.append(f"{field.name}={value}")
    return f"{type(m).__name__.lower()}({', '.join(fields)})"


class _QuietLogger(jsbsim.FGLogger):
    """Keeps JSBSim's warnings and errors (for error messages) instead of printing them."""

    def __init__(self) -> None:
        super().__init__()
        self._level = jsbsim.LogLevel.BULK
        self._parts: list[str] = []
        self.messages: list[str] = []

    def set_level(self, level) -> None:
        self._level = level
        self._parts = []

    def file_location(self, filename: str, line: int) -> None:
        pass

    def message(self, message: str) -> None:
        if self._level >= jsbsim.LogLevel.WARN:
            self._parts.append(message)

    def format(self, format) -> None:
        pass

    def flush(self) -> None:
        if self._parts:
            self.messages.append(" ".join("".join(self._parts).split()))
            del self.messages[:-20]  # the last few are enough to explain a failure
            self._parts = []


# ---------------------------------------------------------------------------------- flight


class _Flight:
    """One JSBSim flight: the model, the pilot's loops and maneuvers, the recorder."""

    def __init__(
        self,
        vehicle: str,
        duration_s: float,
        seed: int,
        config: FlightConfig,
        logger: _QuietLogger,
    ) -> None:
        self.vehicle = vehicle
        self.duration_s = duration_s
        self.seed = seed
        self.config = config
        self.logger = logger
        self.air = _AIRFRAMES[vehicle]
        self.rng = np.random.default_rng(seed)
        if config.from_ground is None:
            self.from_ground = duration_s >= FULL_FLIGHT_MIN_DURATION_S[vehicle]
        else:
            self.from_ground = bool(config.from_ground)
        self.n_samples = round(duration_s * SAMPLE_RATE_HZ) + 1
        self.t = 0.0
        self.phase = "initialisation"
        self.phases: list[tuple[float, str]] = []
        self._build_model()
        self._init_pilot()

    # ------------------------------------------------------------------------ JSBSim set-up

    def _build_model(self) -> None:
        fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        fdm.set_debug_level(0)
        if not fdm.load_model(self.air.model):
            raise RuntimeError(f"JSBSim could not load model {self.air.model}")
        # Some models (global5000) declare a CSV output that JSBSim would write next to its
        # aircraft files; send every declared output to the null device.
        n = 0
        while fdm.set_output_filename(n, os.devnull):
            n += 1
        fdm.disable_output()
        fdm.set_dt(_STEP_S)
        # The turbulence generator's seed: the first draw of the pilot's generator.
        fdm["simulation/randomseed"] = int(self.rng.integers(1, 2**31 - 1))
        self.fdm = fdm
        pm = fdm.get_property_manager()

        def node(name: str):
            found = pm.get_node(name)
            if found is None:
                raise RuntimeError(f"JSBSim model {self.air.model} has no property {name}")
            return found

        state = (
            "accelerations/a-pilot-x-ft_sec2",
            "accelerations/a-pilot-y-ft_sec2",
            "accelerations/a-pilot-z-ft_sec2",
            "velocities/p-rad_sec",
            "velocities/q-rad_sec",
            "velocities/r-rad_sec",
            "attitude/phi-rad",
            "attitude/theta-rad",
            "attitude/psi-rad",
            "velocities/vc-kts",
            "position/h-agl-ft",
            "velocities/h-dot-fps",
            "aero/alpha-rad",
            "aero/beta-rad",
            "aero/qbar-psf",
            "gear/wow",
            "velocities/u-fps",
            "aero/stall-hyst-norm",
        )
        self._getters = tuple(node(name).get_double_value for name in state)
        self._set_aileron = node("fcs/aileron-cmd-norm").set_double_value
        self._set_elevator = node("fcs/elevator-cmd-norm").set_double_value
        self._set_rudder = node("fcs/rudder-cmd-norm").set_double_value
        self._set_steer = node("fcs/steer-cmd-norm").set_double_value
        self._set_throttles = tuple(
            node(f"fcs/throttle-cmd-norm[{i}]").set_double_value for i in range(self.air.engines)
        )
        self._set_brake_left = node("fcs/left-brake-cmd-norm").set_double_value
        self._set_brake_right = node("fcs/right-brake-cmd-norm").set_double_value
        self._set_flaps = node("fcs/flap-cmd-norm").set_double_value
        self._set_gear = node("gear/gear-cmd-norm").set_double_value
        self._set_speedbrake = node("fcs/speedbrake-cmd-norm").set_double_value
        self._nose_on_ground = node("gear/unit[0]/WOW").get_double_value  # unit 0: nose gear
        self._severity = node("atmosphere/turbulence/milspec/severity")
        self._wind_20ft = node("atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps")
        # Structure contacts (wing tips, skids): touching the ground with them is a crash.
        reactions = fdm.get_ground_reactions()
        self._structure = tuple(
            (name, node(f"contact/unit[{i}]/WOW").get_double_value)
            for i in range(reactions.get_num_gear_units())
            for name in [f"contact/unit[{i}]"]
            if pm.hasNode(f"contact/unit[{i}]/WOW")
        )

    def _initialise(self) -> None:
        """Initial conditions, engines running, trim (airborne) or settled on the gear."""
        fdm, cfg, air = self.fdm, self.config, self.air
        heading = cfg.initial_heading_rad
        if heading is None:
            heading = float(self.rng.uniform(0.0, 2.0 * math.pi))
        fdm["atmosphere/turb-type"] = 3  # MIL-F-8785C (Dryden), JSBSim's "milspec"
        self._wind_20ft.set_double_value(cfg.wind_speed_20ft_mps / _FT)
        self._severity.set_double_value(0)  # calm while trimming and settling
        fdm["ic/psi-true-rad"] = heading
        fdm["ic/terrain-elevation-ft"] = 0.0
        if self.from_ground:
            self.runway_heading = heading
            fdm["ic/h-agl-ft"] = air.cg_height_on_ground / _FT + 0.2
            fdm["ic/vc-kts"] = 0.0
            fdm["ic/theta-rad"] = 0.0
        else:
            fdm["ic/h-agl-ft"] = cfg.maneuver_altitude_m / _FT
            fdm["ic/vc-kts"] = cfg.cruise_speed_mps / _KT
            fdm["ic/gamma-deg"] = 0.0
        if not fdm.run_ic():
            self._fail("JSBSim rejected the initial conditions")
        fdm["propulsion/set-running"] = -1
        if self.air.engines == 1:
            fdm["fcs/mixture-cmd-norm"] = 1.0
        if self.from_ground:
            # Parked: idle, brakes set; settle on the gear (not recorded).
            self._set_brake_left(1.0)
            self._set_brake_right(1.0)
            self._set_gear(1.0)
            for set_throttle in self._set_throttles:
                set_throttle(air.idle_throttle)
            for _ in range(300):
                fdm.run()
            self.throttle_int = air.idle_throttle
        else:
            self._set_gear(0.0 if air.retractable_gear else 1.0)
            fdm["gear/gear-pos-norm"] = 0.0 if air.retractable_gear else 1.0
            try:
                fdm["simulation/do_simple_trim"] = 1
            except jsbsim.TrimFailureError as error:
                self._fail(f"JSBSim could not trim at the start ({error})")
            self.throttle_int = fdm["fcs/throttle-cmd-norm"]
            for _ in range(100):  # let the trimmed state settle
                fdm.run()
        self._severity.set_double_value(cfg.turbulence_severity)

    # ------------------------------------------------------------------------------ pilot

    def _init_pilot(self) -> None:
        air, cfg = self.air, self.config
        self.lateral = _LAT_HEADING
        self.vertical = _VERT_ALTITUDE
        self.speed_mode = _SPEED_AIRSPEED
        self.heading_c = 0.0
        self.bank_c = 0.0
        self.altitude_c = cfg.maneuver_altitude_m
        self.vspeed_c = 0.0
        self.pitch_c = 0.0
        self.speed_c = cfg.cruise_speed_mps
        self.throttle_c = air.idle_throttle
        self.roll_rate_max = air.roll_rate_max
        self.vspeed_limit = max(air.climb_rate, air.descent_rate)
        self.speed_protection = True
        self.gamma_gain = 1.0  # pitch per flight-path error, rad/rad (raised in the flare)
        self.pitch_floor = -math.pi / 2  # lowest pitch command, rad (raised in the flare)
        # Held control values in the _HOLD modes plus doublet offsets (normalised).
        self.aileron_hold = 0.0
        self.elevator_hold = 0.0
        self.rudder_hold = 0.0
        self.rudder_open = False
        self.aileron_offset = 0.0
        self.elevator_offset = 0.0
        self.rudder_offset = 0.0
        self.brake = 0.0
        # Integrators and last outputs.
        self.aileron_int = 0.0
        self.elevator_int = 0.0
        self.rudder_int = 0.0
        self.pitch_int = 0.0  # pitch attitude that gives the commanded flight path, rad
        self.throttle_int = 0.0
        self.aileron = self.elevator = self.rudder = 0.0
        self.ground_allowed = False

    def _read_state(self) -> tuple[float, ...]:
        values = tuple(g() for g in self._getters)
        (
            _ax,
            _ay,
            _az,
            self.p,
            self.q,
            self.r,
            self.phi,
            self.theta,
            self.psi,
            vc_kts,
            h_agl_ft,
            hdot_fps,
            self.alpha,
            self.beta,
            self.qbar,
            wow,
            u_fps,
            hyst,
        ) = values
        self.v = vc_kts * _KT
        self.h = h_agl_ft * _FT - self.air.cg_height_on_ground  # wheels (about) above ground
        self.hdot = hdot_fps * _FT
        self.wow = wow > 0.5
        self.u = u_fps * _FT
        self.stalled = hyst > 0.5
        return values

    def _control(self) -> None:
        """The pilot's loops: one step of every axis, written to JSBSim."""
        air, dt = self.air, _STEP_S
        airborne = not self.wow
        # Gains are set at the reference dynamic pressure; a slower aircraft needs more stick.
        sched = _clip(air.qbar_ref_psf / max(self.qbar, 1.0), 0.3, 5.0)

        # Roll: heading -> bank -> roll rate -> aileron.
        lateral = self.lateral
        if lateral == _LAT_HEADING or lateral == _LAT_BANK:
            if lateral == _LAT_HEADING:
                bank_c = _clip(
                    1.5 * _wrap(self.heading_c - self.psi), -air.heading_bank, air.heading_bank
                )
            else:
                bank_c = self.bank_c
            p_c = _clip(2.0 * (bank_c - self.phi), -self.roll_rate_max, self.roll_rate_max)
            error = p_c - self.p
            if airborne:
                self.aileron_int = _clip(self.aileron_int + 0.3 * error * dt, -0.3, 0.3)
            aileron = sched * air.roll_rate_gain * error + self.aileron_int
        elif lateral == _LAT_HOLD:
            aileron = self.aileron_hold
        else:  # on the ground: wings level with the roll rate only
            aileron = -0.5 * self.p
        aileron = _clip(aileron + self.aileron_offset, -1.0, 1.0)

        # Pitch: altitude -> vertical speed -> pitch attitude -> pitch rate -> elevator.
        vertical = self.vertical
        if vertical != _VERT_HOLD:
            v = max(self.v, 0.5 * air.stall_speed)
            if vertical == _VERT_PITCH:
                pitch_c = self.pitch_c
            else:
                if vertical == _VERT_ALTITUDE:
                    vspeed_c = _clip(
                        0.15 * (self.altitude_c - self.h), -self.vspeed_limit, self.vspeed_limit
                    )
                else:
                    vspeed_c = self.vspeed_c
                if self.speed_protection:
                    # Trade height for speed when slow (and the reverse when fast), as a pilot
                    # does when the throttle alone cannot hold the speed; at most half the
                    # normal descent rate either way.
                    slow = self.speed_c - 8.0 - self.v
                    fast = self.v - self.speed_c - 8.0
                    if slow > 0.0:
                        vspeed_c -= min(0.7 * slow, 0.5 * air.descent_rate)
                    elif fast > 0.0:
                        vspeed_c += min(0.5 * fast, 0.5 * air.descent_rate)
                gamma_error = _clip((vspeed_c - self.hdot) / v, -0.3, 0.3)
                if airborne:
                    self.pitch_int = _clip(
                        self.pitch_int + 0.3 * gamma_error * dt, air.min_pitch, air.max_pitch
                    )
                pitch_c = self.pitch_int + self.gamma_gain * gamma_error
            pitch_c = _clip(max(pitch_c, self.pitch_floor), air.min_pitch, air.max_pitch)
            cos_phi = max(math.cos(self.phi), 0.3)
            # Pitch rate of a coordinated level turn, q = (g / V) sin(phi) tan(phi).
            q_turn = _G / v * math.sin(self.phi) ** 2 / cos_phi
            q_c = _clip(1.5 * (pitch_c - self.theta), -air.pitch_rate_max, air.pitch_rate_max)
            error = q_c * cos_phi + q_turn - self.q
            self.elevator_int = _clip(self.elevator_int + 1.0 * error * dt, -1.0, 1.0)
            # Positive elevator is nose down in JSBSim (checked: +0.2 gives q < 0).
            elevator = -(sched * air.pitch_rate_gain * error + self.elevator_int)
        else:
            elevator = self.elevator_hold
        elevator = _clip(elevator + self.elevator_offset, -1.0, 1.0)

        # Yaw: zero sideslip in the air; heading with rudder (and nose wheel) on the ground.
        if lateral == _LAT_GROUND:
            heading_error = _clip(_wrap(self.heading_c - self.psi), -0.5, 0.5)
            turn = 3.0 * heading_error - 1.5 * self.r
            # Positive rudder yaws the nose left, positive steering right (both checked).
            rudder = -_clip(turn, -1.0, 1.0)
            # Nose-wheel steering is for taxi speeds; at roll-out speeds it would skid the tyres.
            steer_gain = min(1.0, air.taxi_speed / max(self.u, 1.0))
            self._set_steer(_clip(steer_gain * turn, -1.0, 1.0))
        elif self.rudder_open:
            rudder = self.rudder_hold
        else:
            if airborne:
                self.rudder_int = _clip(self.rudder_int - 0.5 * self.beta * dt, -0.3, 0.3)
            rudder = -sched * air.yaw_gain * self.beta + self.rudder_int
        rudder = _clip(rudder + self.rudder_offset, -1.0, 1.0)

        # Throttle.
        speed_mode = self.speed_mode
        if speed_mode == _SPEED_AIRSPEED:
            error = self.speed_c - self.v
            throttle = self.throttle_int + 0.08 * error
            # Integrate only while it can help (anti-windup at idle and full power).
            if 0.0 < throttle < 1.0 or (throttle >= 1.0) != (error > 0.0):
                self.throttle_int = _clip(self.throttle_int + 0.02 * error * dt, 0.0, 1.0)
            throttle = _clip(throttle, air.idle_throttle, 1.0)
        elif speed_mode == _SPEED_TAXI:
            error = self.speed_c - self.u
            if self.speed_c <= 0.0:
                # Stop with moderate braking (a smooth stop, not a panic stop), then hold.
                self.throttle_int = air.idle_throttle
                throttle = air.idle_throttle
                self.brake = 1.0 if self.u < 0.5 else 0.3
            else:
                self.throttle_int = _clip(self.throttle_int + 0.03 * error * dt, 0.0, 0.6)
                throttle = _clip(self.throttle_int + 0.1 * error, air.idle_throttle, 0.8)
                self.brake = _clip(-0.3 * (error + 1.0), 0.0, 1.0)
        else:
            throttle = self.throttle_c

        # A pilot's hand (and the surface actuators) cannot step: rate-limit every control,
        # or a reversal or doublet would give a one-sample jump of the roll acceleration (and of
        # the lateral specific force at an eye point metres above the roll axis).
        step = _CONTROL_RATE * dt
        aileron = _clip(aileron, self.aileron - step, self.aileron + step)
        elevator = _clip(elevator, self.elevator - step, self.elevator + step)
        rudder = _clip(rudder, self.rudder - step, self.rudder + step)
        self.aileron, self.elevator, self.rudder = aileron, elevator, rudder
        self._set_aileron(aileron)
        self._set_elevator(elevator)
        self._set_rudder(rudder)
        for set_throttle in self._set_throttles:
            set_throttle(throttle)
        self._set_brake_left(self.brake)
        self._set_brake_right(self.brake)

    # ---------------------------------------------------------------- mode-setting helpers

    def _hold_heading(self, heading: float | None = None) -> None:
        self.lateral = _LAT_HEADING
        self.heading_c = self.psi if heading is None else heading

    def _hold_altitude(self, altitude: float | None = None) -> None:
        if self.vertical not in (_VERT_ALTITUDE, _VERT_VSPEED):
            self.pitch_int = self.theta  # bumpless: start from the current attitude
        self.vertical = _VERT_ALTITUDE
        self.altitude_c = self.h if altitude is None else altitude

    def _hold_vspeed(self, vspeed: float) -> None:
        if self.vertical not in (_VERT_ALTITUDE, _VERT_VSPEED):
            self.pitch_int = self.theta
        self.vertical = _VERT_VSPEED
        self.vspeed_c = vspeed

    def _hold_speed(self, speed: float | None = None) -> None:
        if self.speed_mode != _SPEED_AIRSPEED:
            self.throttle_int = self.throttle_c
        self.speed_mode = _SPEED_AIRSPEED
        if speed is not None:
            self.speed_c = speed

    def _set_throttle(self, throttle: float) -> None:
        self.speed_mode = _SPEED_THROTTLE
        self.throttle_c = throttle

    def _wait(self, seconds: float) -> Iterator[None]:
        end = self.t + seconds
        while self.t < end - 0.5 * _STEP_S:
            yield

    def _wait_until(self, condition: Callable[[], bool], timeout_s: float) -> Iterator[None]:
        end = self.t + timeout_s
        while not condition() and self.t < end:
            yield

    def _roll_out(self) -> Iterator[None]:
        self.lateral = _LAT_BANK
        self.bank_c = 0.0
        self.roll_rate_max = self.air.roll_rate_max
        yield from self._wait_until(lambda: abs(self.phi) < 5 * _DEG, 15.0)
        self._hold_heading()

    # ------------------------------------------------------------------------- maneuvers

    def _fly_level(self, m: Level) -> Iterator[None]:
        if self.wow:  # parked on the ground
            self.speed_c = 0.0
            yield from self._wait(m.duration_s)
            return
        self._hold_heading(self.heading_c if self.lateral == _LAT_HEADING else None)
        self._hold_altitude(self.altitude_c if self.vertical == _VERT_ALTITUDE else None)
        self._hold_speed()
        yield from self._wait(m.duration_s)

    def _steep_bank_speed(self, bank: float) -> None:
        """Steep banks need speed margin (the stall speed grows as 1/sqrt(cos(bank)))."""
        if abs(bank) > 35 * _DEG:
            self._hold_speed(max(self.speed_c, self.config.cruise_speed_mps))

    def _fly_turn(self, m: Turn) -> Iterator[None]:
        self._hold_altitude(self.altitude_c if self.vertical == _VERT_ALTITUDE else None)
        self._hold_speed()
        self._steep_bank_speed(m.bank_rad)
        self.lateral = _LAT_BANK
        self.bank_c = m.bank_rad
        roll_in = abs(m.bank_rad - self.phi) / self.roll_rate_max + 1.0
        yield from self._wait(roll_in + m.duration_s)
        yield from self._roll_out()

    def _fly_bank_reversals(self, m: BankReversals) -> Iterator[None]:
        self._hold_altitude(self.altitude_c if self.vertical == _VERT_ALTITUDE else None)
        self._hold_speed()
        self._steep_bank_speed(m.bank_rad)
        self.lateral = _LAT_BANK
        self.roll_rate_max = self.air.roll_rate_aggressive
        end = self.t + m.duration_s
        bank = m.bank_rad
        while self.t < end - 0.5 * _STEP_S:
            self.bank_c = bank
            yield from self._wait(min(m.half_period_s, end - self.t))
            bank = -bank
        yield from self._roll_out()

    def _fly_altitude_change(self, m: AltitudeChange) -> Iterator[None]:
        base = self.altitude_c if self.vertical == _VERT_ALTITUDE else self.h
        target = base + m.altitude_change_m
        self._hold_altitude(target)
        self.vspeed_limit = abs(m.vertical_speed_mps)
        if m.altitude_change_m > 0:
            self._hold_speed(min(self.speed_c, self.config.cruise_speed_mps))
        self._hold_heading(self.heading_c + m.heading_change_rad)
        timeout = abs(m.altitude_change_m) / max(abs(m.vertical_speed_mps), 0.5) * 2.0 + 30.0
        yield from self._wait_until(lambda: abs(target - self.h) < 10.0, timeout)
        self.vspeed_limit = max(self.air.climb_rate, self.air.descent_rate)
        yield from self._wait_until(lambda: abs(_wrap(self.heading_c - self.psi)) < 0.05, 60.0)

    def _fly_speed_change(self, m: SpeedChange) -> Iterator[None]:
        self._hold_altitude(self.altitude_c if self.vertical == _VERT_ALTITUDE else None)
        self._hold_speed(m.speed_mps)
        yield from self._wait(m.duration_s)

    def _fly_doublet(self, m: Doublet) -> Iterator[None]:
        self._hold_altitude(self.altitude_c if self.vertical == _VERT_ALTITUDE else None)
        if abs(self.phi) > 5 * _DEG:  # a doublet starts from wings level
            yield from self._roll_out()
        self._hold_heading(self.heading_c if self.lateral == _LAT_HEADING else None)
        yield from self._wait_until(lambda: abs(self.p) < 0.03 and abs(self.phi) < 5 * _DEG, 10.0)
        # Hands off that axis: its control stays where the loop had it, plus the steps.
        if m.control == "elevator":
            self.elevator_hold, self.vertical = self.elevator, _VERT_HOLD
        elif m.control == "aileron":
            self.aileron_hold, self.lateral = self.aileron, _LAT_HOLD
        else:
            self.rudder_hold, self.rudder_open = self.rudder, True
        offset = m.control + "_offset"
        setattr(self, offset, m.amplitude)
        yield from self._wait(m.half_period_s)
        setattr(self, offset, -m.amplitude)
        yield from self._wait(m.half_period_s)
        setattr(self, offset, 0.0)
        yield from self._wait(m.settle_s)
        self.rudder_open = False
        self._hold_altitude(self.altitude_c)
        if self.lateral == _LAT_HOLD:
            yield from self._roll_out()

    def _fly_stall(self, m: Stall) -> Iterator[None]:
        air = self.air
        entry_altitude = self.altitude_c if self.vertical == _VERT_ALTITUDE else self.h
        entry_speed = self.speed_c
        self._hold_altitude(entry_altitude)
        if m.bank_rad:
            self.lateral, self.bank_c = _LAT_BANK, m.bank_rad
        else:
            self._hold_heading(self.heading_c if self.lateral == _LAT_HEADING else None)
        self.speed_protection = False
        self._set_throttle(air.idle_throttle)
        if air.retractable_gear:
            self._set_speedbrake(1.0)  # the jet decelerates too slowly at idle alone
        # Entry: hold altitude while the speed decays, until the wing is near its limit.
        yield from self._wait_until(
            lambda: self.alpha > air.stall_alpha - 0.04 or self.v < 1.05 * air.stall_speed, 90.0
        )
        if air.full_stall:
            # Pull to the break, then keep pulling while it develops (the nose drops, the
            # sink rate builds up).
            self.vertical = _VERT_PITCH
            self.pitch_c = self.theta
            end = self.t + 10.0
            while not (self.stalled or self.alpha > air.stall_alpha) and self.t < end:
                self.pitch_c = min(self.pitch_c + 2 * _DEG * _STEP_S, air.max_pitch)
                yield
            self.vertical, self.elevator_hold = _VERT_HOLD, min(self.elevator - 0.2, -0.6)
            yield from self._wait(2.5)
        else:
            # Approach to stall: keep holding altitude until the stall warning.
            yield from self._wait_until(lambda: self.alpha > air.stall_alpha, 40.0)
        # Recovery: nose down, full power, wings level; then climb back.
        self._set_speedbrake(0.0)
        self.vertical = _VERT_PITCH
        self.pitch_c = self.theta + air.recovery_pitch_change
        self._set_throttle(1.0)
        self.lateral, self.bank_c = _LAT_BANK, 0.0
        yield from self._wait(1.0)
        yield from self._wait_until(
            lambda: (
                not self.stalled
                and self.alpha < air.recovered_alpha
                and self.v > 1.25 * air.stall_speed
            ),
            20.0,
        )
        self.speed_protection = True
        self._hold_heading()
        self.throttle_int = 1.0
        self._hold_speed(max(entry_speed, air.climb_speed))
        self._hold_vspeed(air.climb_rate)
        yield from self._wait_until(lambda: self.h > entry_altitude - 10.0, 120.0)
        self._hold_altitude(entry_altitude)

    def _fly_turbulence(self, m: Turbulence) -> Iterator[None]:
        self._severity.set_double_value(int(m.severity))
        return
        yield  # a generator that does not step

    def _fly_taxi(self, m: Taxi) -> Iterator[None]:
        air = self.air
        self.ground_allowed = True
        self.lateral = _LAT_GROUND
        self.vertical, self.elevator_hold = _VERT_HOLD, 0.0
        self.speed_mode = _SPEED_TAXI
        self.speed_c = air.taxi_speed
        self.brake = 0.0
        if air.nosewheel_steering:
            # From the ramp heading (the start), half way the turn onto the runway heading.
            runway = self.runway_heading = _wrap(self.psi + m.turn_rad)
            self.heading_c = self.psi
            yield from self._wait(0.5 * m.duration_s)
            self.heading_c = runway
            self.speed_c = 0.6 * air.taxi_speed
            yield from self._wait_until(lambda: abs(_wrap(runway - self.psi)) < 0.03, 40.0)
            self.speed_c = air.taxi_speed
            yield from self._wait(0.5 * m.duration_s)
        else:
            self.heading_c = self.runway_heading = self.psi
            yield from self._wait(m.duration_s)
        # Stop (hold short, run-up), then line up.
        self.speed_c = 0.0
        yield from self._wait_until(lambda: self.u < 0.2, 30.0)
        yield from self._wait(3.0)

    def _fly_takeoff(self, m: Takeoff) -> Iterator[None]:
        air = self.air
        self.ground_allowed = True
        self.lateral = _LAT_GROUND
        self.heading_c = self.runway_heading if self.wow else self.psi
        self._set_flaps(air.takeoff_flaps)
        self.brake = 0.0
        self._set_throttle(1.0)
        self.vertical, self.elevator_hold = _VERT_HOLD, 0.0
        yield from self._wait_until(lambda: self.v > air.rotate_speed, 90.0)
        if self.v <= air.rotate_speed:
            self._fail(f"take-off roll did not reach the rotation speed ({self.v:.1f} m/s)")
        # Rotate at about 3 deg/s.
        self.vertical = _VERT_PITCH
        self.pitch_c = self.theta
        self.elevator_int = -self.elevator_hold
        while self.wow or self.h < 3.0:
            self.pitch_c = min(self.pitch_c + 3 * _DEG * _STEP_S, air.rotate_pitch)
            if self.t > self.phase_start + 150.0:
                self._fail("no lift-off")
            yield
        self.ground_allowed = False
        self._hold_heading(self.heading_c)
        self.pitch_int = self.theta
        self.throttle_c = 1.0
        self._hold_vspeed(air.climb_rate)
        self.speed_c = air.climb_speed
        self.throttle_int = 1.0
        while self.h < m.height_m:
            if air.retractable_gear and self.h > 10.0 and self.hdot > 1.0:
                self._set_gear(0.0)
            if self.h > 0.6 * m.height_m and self.v > air.flaps_up_speed:
                self._set_flaps(0.0)
            yield
        self._set_flaps(0.0)
        self._set_gear(0.0 if air.retractable_gear else 1.0)

    def _fly_landing(self, m: Landing) -> Iterator[None]:
        air = self.air
        # Descend to the approach height while slowing down; first flaps below their speed.
        self.vspeed_limit = air.descent_rate
        self._hold_speed(air.approach_speed + 15 * _KT)
        self._hold_altitude(air.approach_height)
        self._hold_heading(self.heading_c if self.lateral == _LAT_HEADING else None)
        while abs(self.h - air.approach_height) > 20.0 or self.v > self.speed_c + 10.0:
            if self.v < air.flaps_up_speed:
                self._set_flaps(air.takeoff_flaps)
            # The jet needs its speed brake to slow down while descending.
            self._set_speedbrake(
                1.0 if self.v > self.speed_c + 5.0 and air.retractable_gear else 0.0
            )
            if self.t > self.phase_start + 600.0:
                self._fail("could not reach the approach height and speed in 10 minutes")
            yield
        self._set_speedbrake(0.0)
        # Configure, then the glide path (the runway is wherever it leads).
        self._set_flaps(air.landing_flaps)
        self._set_gear(1.0)
        self._hold_speed(air.approach_speed)
        self.ground_allowed = True
        while self.h > air.flare_height:
            self._hold_vspeed(-max(self.v, air.approach_speed) * math.tan(m.glide_path_rad))
            if self.h < 3.0 * air.flare_height:
                # This pilot does not de-crab or fight drift: touching down while drifting in a
                # gust slams the tyres sideways (a 2 g lateral spike at the eye), so the gusts
                # fade out over the last part of the approach (the low-altitude turbulence
                # intensity follows the wind at 20 ft).
                fade = _clip((self.h - air.flare_height) / (2.0 * air.flare_height), 0.0, 1.0)
                self._wind_20ft.set_double_value(fade * self.config.wind_speed_20ft_mps / _FT)
            yield
        self._wind_20ft.set_double_value(0.0)
        # Flare: idle, sink rate proportional to height, down to a gentle touchdown.
        self.speed_protection = False
        self._set_throttle(air.idle_throttle)
        sink_per_m = air.approach_speed * math.tan(m.glide_path_rad) / air.flare_height
        self.gamma_gain = 6.0  # the flare is a quick, tight pull
        self.lateral, self.bank_c = _LAT_BANK, 0.0  # wings level for the touchdown
        end = self.t + 30.0
        start_pitch = self.theta
        while not self.wow and self.t < end:
            self._hold_vspeed(-max(sink_per_m * self.h, 0.3))
            # The nose comes up to the touchdown attitude as the wheels near the ground, so
            # the main wheels touch first and the aircraft floats while the speed bleeds off.
            progress = _clip(1.0 - self.h / air.flare_height, 0.0, 1.0)
            self.pitch_floor = start_pitch + progress * (air.touchdown_pitch - start_pitch)
            yield
        self.pitch_floor = -math.pi / 2
        if not self.wow:
            self._fail("no touchdown within 30 s of the flare")
        # Roll-out: lower the nose gently (dropping it slams the nose gear), wings level,
        # runway heading, moderate brakes, to a stop.
        self.gamma_gain = 1.0
        self.lateral = _LAT_GROUND
        self.heading_c = self.psi
        self._set_flaps(0.0)
        self.vertical = _VERT_PITCH
        self.pitch_c = self.theta
        end = self.t + 15.0
        while self.t < end and not self._nose_on_ground() > 0.5:
            # 1 deg/s, then 0.25 deg/s over the last 2 deg before the nose wheel touches.
            rate = 1.0 if self.theta > air.ground_pitch + 2 * _DEG else 0.25
            self.pitch_c = max(self.pitch_c - rate * _DEG * _STEP_S, air.ground_pitch - _DEG)
            yield
        self.vertical, self.elevator_hold = _VERT_HOLD, 0.0
        self.brake = 0.5
        yield from self._wait_until(lambda: self.u < 5.0, 120.0)
        self.speed_mode = _SPEED_TAXI
        self.speed_c = 0.0
        yield from self._wait_until(lambda: self.u < 0.2, 60.0)
        self.speed_protection = True

    # ---------------------------------------------------------------------------- plans

    def _random_plan(self) -> Iterator[Maneuver]:
        """The seeded pilot's plan; maneuvers are drawn when the previous one is over.

        A lesson plan first (every kind once, in random order), then random draws; each
        maneuver must fit in the time left before the pilot has to head home (ground flights)
        or before the end of the recording (airborne flights).
        """
        rng, air, cfg = self.rng, self.air, self.config
        light = self.vehicle == "light"
        if self.from_ground:
            yield Taxi(
                duration_s=float(rng.uniform(15.0, 30.0)),
                turn_rad=float(rng.choice([-1, 1]) * rng.uniform(60, 120) * _DEG),
            )
            yield Takeoff()
            yield AltitudeChange(
                altitude_change_m=cfg.maneuver_altitude_m - self.h,
                vertical_speed_mps=air.climb_rate,
                heading_change_rad=float(rng.choice([-1, 1]) * rng.uniform(30, 150) * _DEG),
            )
            yield SpeedChange(speed_mps=cfg.cruise_speed_mps, duration_s=15.0)
        kinds = (
            "level",
            "turn",
            "steep_turn",
            "reversals",
            "doublet",
            "speed",
            "altitude",
            "stall",
        )
        weights = np.array([0.08, 0.17, 0.13, 0.13, 0.17, 0.1, 0.12, 0.1])
        lesson = [
            kinds[i] for i in rng.permutation(len(kinds))[: len(kinds)] if kinds[i] != "level"
        ]
        stall_time = 80.0 if light else 100.0  # s, entry + recovery + climb back
        while True:
            room = self.duration_s - self._time_to_land() - self.t  # s left for maneuvers
            if room < (25.0 if self.from_ground else 0.0):
                break
            if not self.from_ground:
                room = math.inf  # the end of the recording may cut the last maneuver
            if self.h < cfg.min_altitude_m - 30.0:  # back up to the maneuver band first
                yield AltitudeChange(cfg.maneuver_altitude_m - self.h, air.climb_rate)
                continue
            kind = lesson.pop(0) if lesson else str(rng.choice(kinds, p=weights / weights.sum()))
            if cfg.turbulence_patch_severity > cfg.turbulence_severity and rng.uniform() < 0.25:
                low, high = cfg.turbulence_severity + 1, cfg.turbulence_patch_severity
                yield Turbulence(severity=int(rng.integers(low, high + 1)))
            elif rng.uniform() < 0.5:
                yield Turbulence(severity=cfg.turbulence_severity)
            side = float(rng.choice([-1.0, 1.0]))
            if kind == "stall" and (room < stall_time or self.h < cfg.min_altitude_m):
                kind = "turn"
            if kind == "altitude":
                change = self._draw_altitude_change(room)
                if change is None:
                    kind = "turn"
                else:
                    rate = air.climb_rate if change > 0 else air.descent_rate
                    turn = float(rng.choice([0.0, 1.0]) * rng.uniform(-120, 120) * _DEG)
                    yield AltitudeChange(
                        altitude_change_m=change,
                        vertical_speed_mps=float(rng.uniform(0.6, 1.0) * rate),
                        heading_change_rad=turn,
                    )
                    continue
            longest = room - 10.0  # s; every maneuver below ends in time to head home
            if kind == "level":
                yield Level(duration_s=min(float(rng.uniform(8.0, 25.0)), longest))
            elif kind == "turn":
                bank = rng.uniform(15, 35) if light else rng.uniform(15, 30)
                yield Turn(
                    bank_rad=side * float(bank) * _DEG,
                    duration_s=min(float(rng.uniform(10, 40)), longest - 10.0),
                )
            elif kind == "steep_turn":
                low = min(45 * _DEG if light else 35 * _DEG, cfg.max_bank_rad)
                yield Turn(
                    bank_rad=side * float(rng.uniform(low, cfg.max_bank_rad)),
                    duration_s=min(float(rng.uniform(20, 45)), longest - 10.0),
                )
            elif kind == "reversals":
                low = min(30 * _DEG if light else 20 * _DEG, cfg.max_bank_rad)
                half = rng.uniform(2.5, 6.0) if light else rng.uniform(5.0, 9.0)
                yield BankReversals(
                    bank_rad=side * float(rng.uniform(low, cfg.max_bank_rad)),
                    half_period_s=float(half),
                    duration_s=min(float(rng.uniform(15, 35)), longest - 10.0),
                )
            elif kind == "doublet":
                control = str(rng.choice(["elevator", "aileron", "rudder"]))
                # Normalised step sizes; the jet's surfaces are far more powerful at its speeds
                # (its rudder has no limiter in the model: 0.2 gives 0.5 g sideways at the eye).
                if light:
                    size = {"elevator": (0.05, 0.15), "aileron": (0.15, 0.4), "rudder": (0.2, 0.5)}
                else:
                    size = {"elevator": (0.04, 0.1), "aileron": (0.08, 0.2), "rudder": (0.05, 0.12)}
                yield Doublet(
                    control=control,
                    amplitude=side * float(rng.uniform(*size[control])),
                    half_period_s=float(rng.uniform(0.5, 1.5)),
                    settle_s=float(rng.uniform(3.0, 8.0)),
                )
            elif kind == "speed":
                low = 0.75 if light else 0.8
                yield SpeedChange(
                    speed_mps=float(rng.uniform(low, 1.1) * cfg.cruise_speed_mps),
                    duration_s=min(float(rng.uniform(15, 35)), longest),
                )
            else:
                yield Stall()
        if self.from_ground:
            yield Turbulence(severity=cfg.turbulence_severity)
            yield Landing()

    def _draw_altitude_change(self, room: float) -> float | None:
        """A climb or descent inside the altitude band that fits in `room` s, m (None: none)."""
        rng, air, cfg = self.rng, self.air, self.config
        base = self.altitude_c if self.vertical == _VERT_ALTITUDE else self.h
        up_room = cfg.max_altitude_m - base
        down_room = base - cfg.min_altitude_m
        # Time cost per metre: climbing also lengthens the way home (ground flights).
        home = 1.0 / (0.8 * air.descent_rate) if self.from_ground else 0.0
        up_time = 1.3 / air.climb_rate + home
        down_time = 1.3 / air.descent_rate - home
        largest = 300.0 if self.vehicle == "light" else 800.0
        smallest = 100.0 if self.vehicle == "light" else 300.0
        up = min(up_room, largest, (room - 20.0) / up_time)
        down = min(down_room, largest, (room - 20.0) / max(down_time, 1e-3))  # inf - x: inf
        options = [
            sign * extent for sign, extent in ((1.0, up), (-1.0, down)) if extent >= smallest
        ]
        if not options:
            return None
        extent = options[int(rng.integers(len(options)))]
        return float(np.sign(extent) * rng.uniform(smallest, abs(extent)))

    def _time_to_land(self) -> float:
        """Seconds from the maneuvers to a stop on the ground (the pilot's rule of thumb)."""
        if not self.from_ground:
            return 0.0
        air = self.air
        descent = max(self.h - air.approach_height, 0.0) / (0.8 * air.descent_rate)
        approach = air.approach_height / (air.approach_speed * math.tan(3 * _DEG))
        return descent + approach + air.rollout_s + 30.0

    def _pilot(self) -> Iterator[None]:
        """Flies the plan, one step per `next`; then holds (level, or parked) to the end."""
        handlers = {
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
        if self.from_ground:
            self.lateral = _LAT_GROUND
            self.heading_c = self.psi
            self.vertical, self.elevator_hold = _VERT_HOLD, 0.0
            self.speed_mode, self.speed_c = _SPEED_TAXI, 0.0
            self.ground_allowed = True
        else:
            self.vertical = _VERT_HOLD  # so that the altitude hold starts from this attitude
            self._hold_heading()
            self._hold_altitude()
            self._hold_speed(self.config.cruise_speed_mps)
        plan = self._random_plan() if self.config.maneuvers is None else self.config.maneuvers
        for maneuver in plan:
            self.phase = _describe(maneuver)
            self.phase_start = self.t
            self.phases.append((round(self.t, 2), self.phase))
            yield from handlers[type(maneuver)](maneuver)
        self.phase = "parked" if self.wow else "level"
        self.phases.append((round(self.t, 2), self.phase))
        while True:
            if self.wow:
                self.lateral, self.speed_mode, self.speed_c = _LAT_GROUND, _SPEED_TAXI, 0.0
            yield

    # ------------------------------------------------------------------------ the loop

    def _fail(self, what: str) -> None:
        recent = f"; JSBSim said: {self.logger.messages[-1]}" if self.logger.messages else ""
        raise FlightError(
            f"{self.vehicle} flight (seed {self.seed}) failed at t = {self.t:.2f} s during "
            f"'{self.phase}': {what}{recent}"
        )

    def _check(self, values: tuple[float, ...]) -> None:
        """Sanity checks of the state; raises FlightError with what went wrong."""
        if not all(math.isfinite(x) for x in values):
            self._fail("non-finite state (NaN or inf) from JSBSim")
        air = self.air
        if self.h < -1.0:
            self._fail(f"below ground (wheels {self.h:.1f} m)")
        for name, touching in self._structure:
            if touching() > 0.5:
                self._fail(f"structure {name} touched the ground (crash)")
        if self.v > air.never_exceed_speed:
            self._fail(f"overspeed: {self.v / _KT:.0f} kt > {air.never_exceed_speed / _KT:.0f} kt")
        if not self.wow and (abs(self.phi) > 100 * _DEG or abs(self.theta) > 60 * _DEG):
            self._fail(
                f"loss of control: roll {self.phi / _DEG:.0f} deg, pitch "
                f"{self.theta / _DEG:.0f} deg"
            )

    def _check_contact(self, sink: float) -> None:
        """The wheels just touched the ground, coming down at `sink` m/s."""
        if not self.ground_allowed:
            self._fail(
                f"hit the ground at {sink:.1f} m/s sink and {self.v / _KT:.0f} kt outside "
                "take-off and landing"
            )
        if sink > _MAX_TOUCHDOWN_SINK:
            self._fail(f"hard landing: touched down at {sink:.1f} m/s sink")

    def _check_load(self, samples: list[tuple[float, ...]]) -> None:
        """Mean load factor |f| / g of the IMU samples (ft/s^2 rows) against the limit."""
        mean = sum(math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) for a in samples)
        load = mean / len(samples) * _FT / _G
        peak = max(math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) for a in samples) * _FT / _G
        limit = self.air.max_load_factor
        if load > limit or peak > 3.0 * limit:
            self._fail(
                f"load factor {load:.1f} g over {len(samples) * _STEP_S:.2f} s (peak {peak:.1f} g)"
                f" > {limit:g} g"
            )

    def run(self, progress: bool) -> tuple[Recording, FlightLog]:
        self._initialise()
        n = self.n_samples
        imu = [None] * n
        log = [None] * n
        values = self._read_state()
        imu[0] = values[:6]
        log[0] = (self.phi, self.theta, self.psi, self.h, self.v, self.wow)
        pilot = self._pilot()
        # JSBSim's gear dampers are massless: a wheel touching down gives a one- or two-sample
        # spike at the eye point (the jet's nose wheel, about 4 g). So the load factor limit
        # applies to the mean over _CHECK_EVERY samples; a single sample may reach 3x the limit.
        spike2 = (3.0 * self.air.max_load_factor * _G / _FT) ** 2  # |a|^2, (ft/s^2)^2
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=round(self.duration_s), unit="sim s", desc=f"{self.vehicle} flight")
        self.logger.messages.clear()  # set-up warnings do not explain a failure in flight
        was_on_ground, sink = self.wow, -self.hdot
        run = self.fdm.run
        read = self._read_state
        control = self._control
        for k in range(1, n):
            next(pilot)
            control()
            run()
            self.t = k * _STEP_S
            values = read()
            ax, ay, az = values[0], values[1], values[2]
            imu[k] = values[:6]
            if self.wow and not was_on_ground:
                self._check_contact(sink)
            was_on_ground, sink = self.wow, -self.hdot
            if ax * ax + ay * ay + az * az > spike2 or k % _CHECK_EVERY == 0:
                self._check(values)
                self._check_load(imu[max(k - _CHECK_EVERY + 1, 0) : k + 1])
            log[k] = (self.phi, self.theta, self.psi, self.h, self.v, self.wow)
            if bar is not None and k % 100 == 0:
                bar.update(1)
        if bar is not None:
            bar.close()
        return self._package(np.array(imu), np.array(log, dtype=float))

    def _package(self, imu: np.ndarray, log: np.ndarray) -> tuple[Recording, FlightLog]:
        t = np.arange(self.n_samples) * _STEP_S
        omega = np.column_stack([imu[:, 3], -imu[:, 4], -imu[:, 5]])
        f = _FT * np.column_stack([imu[:, 0], -imu[:, 1], -imu[:, 2]])
        metadata = {
            "source": "jsbsim scripted pilot (mca_drake.references.jsbsim_flight)",
            "vehicle": self.vehicle,
            "jsbsim_model": self.air.model,
            "jsbsim_version": jsbsim.__version__,
            "seed": str(self.seed),
            "duration_s": repr(self.duration_s),
            "from_ground": str(self.from_ground).lower(),
            "phases": "; ".join(f"{start:.2f} {name}" for start, name in self.phases),
        }
        recording = Recording(t, omega, f, metadata)
        flight_log = FlightLog(
            t=t,
            attitude=log[:, 0:3],
            height_m=log[:, 3] + self.air.cg_height_on_ground,
            airspeed_mps=log[:, 4],
            on_ground=log[:, 5] > 0.5,
            phases=list(self.phases),
        )
        return recording, flight_log
