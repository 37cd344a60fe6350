"""Flights from JSBSim, flown by a seeded scripted pilot: the IMU at the pilot's eye point.

`fly(vehicle, duration_s, seed)` runs a JSBSim flight dynamics model at 100 Hz with a
feedback-control "pilot" (PID-like loops on bank, pitch, vertical speed, altitude, heading,
airspeed and sideslip) whose targets and segment durations are drawn from a numpy Generator
seeded by `seed`, and returns what an IMU at the pilot's eye point measured as a `Recording`
(head-frame axes x forward, y left, z up; SI units).

Vehicles (JSBSim models shipped with the `jsbsim` wheel; the table is `fleet`'s docstring):

    light  c172p       a single-engine piston aircraft, our analogue of the Cirrus SR-22
    jet    global5000  a twin-jet business aircraft, our analogue of the Cessna Citation X
    f16, DHC6, A320, 787-8, t6texan2, T38, MD11, B747 (named by their JSBSim
           models): a fighter, a twin turboprop, airliners, two trainers and a jumbo,
           flown airborne only (trimmed at the maneuver altitude)

JSBSim's 737 and pa28 are reserved for unseen-vehicle checks and refused by name.

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

Modules, each depending only on those above it:

    aircraft   units, the step, and `Airframe` (what the pilot must know of a model)
    fleet      the vehicles: their airframes, config defaults, classes; `check_vehicle`
    maneuvers  the maneuver dataclasses (`Maneuver`) and their phase names
    config     `FlightConfig`, `default_config` and the config checks
    plan       `RandomPlan`: the seeded random choice of maneuvers, drawn as the flight goes
    model      the JSBSim wrapper: set-up, trim, state, command setters, `FlightError` checks
    loops      the pilot's feedback loops (roll, pitch, yaw, speed) and their modes
    pilot      the scripted pilot: flies the plan's maneuvers through the loops
    flight     `fly`, `fly_with_log`, `FlightLog`: the recorder tying them together
"""

from __future__ import annotations

from mca_drake.references.jsbsim.aircraft import SAMPLE_RATE_HZ
from mca_drake.references.jsbsim.config import FlightConfig, default_config
from mca_drake.references.jsbsim.fleet import (
    FULL_FLIGHT_MIN_DURATION_S,
    JSBSIM_MODELS,
    RESERVED_MODELS,
    TRAINING_VEHICLES,
    UNSEEN_VEHICLES,
    VALIDATION_VEHICLES,
    VEHICLE_CLASSES,
    VEHICLES,
    check_training_vehicle,
    check_vehicle,
)
from mca_drake.references.jsbsim.flight import FlightLog, fly, fly_with_log
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
)
from mca_drake.references.jsbsim.model import FlightError

__all__ = [
    "FULL_FLIGHT_MIN_DURATION_S",
    "JSBSIM_MODELS",
    "RESERVED_MODELS",
    "SAMPLE_RATE_HZ",
    "TRAINING_VEHICLES",
    "UNSEEN_VEHICLES",
    "VALIDATION_VEHICLES",
    "VEHICLES",
    "VEHICLE_CLASSES",
    "AltitudeChange",
    "BankReversals",
    "Doublet",
    "FlightConfig",
    "FlightError",
    "FlightLog",
    "Landing",
    "Level",
    "Maneuver",
    "SpeedChange",
    "Stall",
    "Takeoff",
    "Taxi",
    "Turbulence",
    "Turn",
    "check_training_vehicle",
    "check_vehicle",
    "default_config",
    "fly",
    "fly_with_log",
]
