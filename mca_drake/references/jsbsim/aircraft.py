"""Units, the 100 Hz step, and what the pilot must know of an airframe (`Airframe`).

Constants only (no state): the unit conversions that JSBSim's imperial properties need, the
step, and the dataclass of per-model constants of the scripted pilot and of the sanity
checks. The vehicles themselves (one `Airframe` each) are in `fleet`.
"""

from __future__ import annotations

import dataclasses
import math

SAMPLE_RATE_HZ = 100.0

STEP_S = 1.0 / SAMPLE_RATE_HZ  # s, one JSBSim step and one recorded sample
FT = 0.3048  # m per ft
KT = 1852.0 / 3600.0  # m/s per knot
G = 9.80665  # m/s^2, JSBSim's standard gravity at sea level
DEG = math.pi / 180.0  # rad per degree


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
    # Piston engines (their mixture is set rich at the start; turbines have none).
    piston: bool = False
    # The random plan's ranges for small agile aircraft (bank reversals of 2.5-6 s half
    # period, larger doublets, altitude changes of 100-300 m, speeds down to 0.75 cruise, a
    # shorter stall); else those of large aircraft (reversals 5-9 s, gentler doublets,
    # altitude changes of 300-800 m, speeds down to 0.8 cruise).
    agile: bool = False
    # Taxi, take-off and landing are calibrated for this airframe (its ground, flare and
    # approach constants were flown); else its flights start and stay airborne.
    ground_ops: bool = False
