"""The maneuvers a flight is made of, as small frozen dataclasses the pilot flies in order.

Angles in rad (positive bank: right wing down), heights in m, speeds in m/s (calibrated
airspeed). `Maneuver` is their union; `describe` is the name a flight's phase list and its
error messages give a maneuver. The seeded random choice of maneuvers is `plan.RandomPlan`.
"""

from __future__ import annotations

import dataclasses

from mca_drake.references.jsbsim.aircraft import DEG


@dataclasses.dataclass(frozen=True)
class Level:
    """Straight and level flight at the current altitude, heading and speed (parked: wait)."""

    # How long, s.
    duration_s: float = 20.0


@dataclasses.dataclass(frozen=True)
class Turn:
    """A level turn at a fixed bank angle, then roll-out to wings level."""

    # Bank angle, rad; positive is a right turn (right wing down).
    bank_rad: float = 30.0 * DEG
    # Time at the bank angle (after the roll-in), s.
    duration_s: float = 30.0


@dataclasses.dataclass(frozen=True)
class BankReversals:
    """Aggressive rolling: bank alternates between +bank_rad and -bank_rad, altitude held."""

    # Bank angle of each side, rad (the first reversal goes to the sign given).
    bank_rad: float = 45.0 * DEG
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
    turn_rad: float = 90.0 * DEG


@dataclasses.dataclass(frozen=True)
class Takeoff:
    """Take-off roll, rotation, lift-off and initial climb to `height_m` above ground."""

    # Height above ground that ends the take-off, m.
    height_m: float = 150.0


@dataclasses.dataclass(frozen=True)
class Landing:
    """Descent to the approach height, 3 degree approach, flare, touchdown, roll-out, stop."""

    # Glide path angle, rad.
    glide_path_rad: float = 3.0 * DEG


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


def describe(m: Maneuver) -> str:
    """`m` as a phase name: class name and fields, angles in whole degrees."""
    fields = []
    for field in dataclasses.fields(m):
        value = getattr(m, field.name)
        if field.name.endswith("_rad"):
            fields.append(f"{field.name[:-4]}={value / DEG:+.0f}deg")
        elif isinstance(value, float):
            fields.append(f"{field.name}={value:.3g}")
        else:
            fields.append(f"{field.name}={value}")
    return f"{type(m).__name__.lower()}({', '.join(fields)})"
