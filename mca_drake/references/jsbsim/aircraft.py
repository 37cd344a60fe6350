"""The two vehicles: JSBSim model names, units, and the per-model constants of the pilot.

Everything here is a constant table (no state): the unit conversions that JSBSim's imperial
properties need, the 100 Hz step, the airframe constants of the scripted pilot and of the
sanity checks (`Airframe`), and each vehicle's default `FlightConfig` knobs.
"""

from __future__ import annotations

import dataclasses
import math

VEHICLES = ("light", "jet")
JSBSIM_MODELS = {"light": "c172p", "jet": "global5000"}
SAMPLE_RATE_HZ = 100.0
# Flights at least this long (s) take off and land by default; shorter ones start airborne.
# Taxi, take-off, climb, descent, approach and roll-out take about 8 minutes in the light
# aircraft (to 600 m) and 9 in the jet (to 2000 m); the rest is maneuvers.
FULL_FLIGHT_MIN_DURATION_S = {"light": 600.0, "jet": 720.0}

STEP_S = 1.0 / SAMPLE_RATE_HZ  # s, one JSBSim step and one recorded sample
FT = 0.3048  # m per ft
KT = 1852.0 / 3600.0  # m/s per knot
G = 9.80665  # m/s^2, JSBSim's standard gravity at sea level
DEG = math.pi / 180.0  # rad per degree


def check_vehicle(vehicle: str) -> str:
    """`vehicle` itself if it is one of VEHICLES; else ValueError listing the valid ones."""
    if vehicle not in JSBSIM_MODELS:
        raise ValueError(f"unknown vehicle '{vehicle}'; valid: {', '.join(VEHICLES)}")
    return vehicle


@dataclasses.dataclass(frozen=True)
class Airframe:
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


AIRFRAMES = {
    "light": Airframe(
        model="c172p",
        engines=1,
        rotate_speed=55 * KT,
        climb_speed=75 * KT,
        approach_speed=65 * KT,
        taxi_speed=5.0,
        stall_speed=48 * KT,
        never_exceed_speed=163 * KT,
        climb_rate=3.5,
        descent_rate=4.0,
        rotate_pitch=8 * DEG,
        max_pitch=22 * DEG,
        min_pitch=-15 * DEG,
        heading_bank=25 * DEG,
        stall_alpha=0.27,
        recovery_pitch_change=-10 * DEG,
        recovered_alpha=0.15,
        full_stall=True,
        approach_height=150.0,
        flare_height=6.0,
        cg_height_on_ground=4.35 * FT,
        ground_pitch=2.4 * DEG,
        touchdown_pitch=7 * DEG,
        takeoff_flaps=1.0 / 3.0,
        landing_flaps=1.0,
        flaps_up_speed=65 * KT,
        retractable_gear=False,
        nosewheel_steering=True,
        qbar_ref_psf=30.0,
        roll_rate_gain=1.0,
        pitch_rate_gain=1.5,
        yaw_gain=3.0,
        roll_rate_max=20 * DEG,
        roll_rate_aggressive=50 * DEG,
        pitch_rate_max=12 * DEG,
        max_load_factor=6.0,
        idle_throttle=0.0,
        rollout_s=35.0,
    ),
    "jet": Airframe(
        model="global5000",
        engines=2,
        rotate_speed=150 * KT,
        climb_speed=250 * KT,
        approach_speed=130 * KT,
        taxi_speed=8.0,
        stall_speed=150 * KT,
        never_exceed_speed=360 * KT,
        climb_rate=12.0,
        descent_rate=12.0,
        rotate_pitch=10 * DEG,
        max_pitch=20 * DEG,
        min_pitch=-12 * DEG,
        heading_bank=20 * DEG,
        stall_alpha=0.19,
        recovery_pitch_change=-4 * DEG,
        recovered_alpha=0.13,
        full_stall=False,
        approach_height=300.0,
        flare_height=20.0,
        cg_height_on_ground=8.79 * FT,
        ground_pitch=0.3 * DEG,
        touchdown_pitch=6 * DEG,
        # The model's flaps add 0.05 lift coefficient per degree (1.5 at 30 deg): with full
        # flaps it would approach at a negative angle of attack, so 20 deg is enough.
        takeoff_flaps=1.0 / 3.0,
        landing_flaps=2.0 / 3.0,
        flaps_up_speed=180 * KT,
        retractable_gear=True,
        nosewheel_steering=False,
        qbar_ref_psf=200.0,
        roll_rate_gain=1.4,
        pitch_rate_gain=2.0,
        yaw_gain=3.0,
        roll_rate_max=8 * DEG,
        roll_rate_aggressive=15 * DEG,
        pitch_rate_max=5 * DEG,
        max_load_factor=4.0,
        idle_throttle=0.0,
        rollout_s=50.0,
    ),
}


# Default knobs of `FlightConfig` per vehicle (field name: value; angles rad, heights above
# ground m, speeds m/s calibrated).
VEHICLE_DEFAULTS = {
    "light": dict(
        turbulence_severity=2,
        turbulence_patch_severity=3,
        max_bank_rad=60 * DEG,
        maneuver_altitude_m=600.0,
        min_altitude_m=400.0,
        max_altitude_m=1200.0,
        cruise_speed_mps=100 * KT,
    ),
    "jet": dict(
        turbulence_severity=2,
        turbulence_patch_severity=3,
        max_bank_rad=45 * DEG,
        maneuver_altitude_m=2000.0,
        min_altitude_m=1500.0,
        max_altitude_m=3500.0,
        cruise_speed_mps=250 * KT,
    ),
}
