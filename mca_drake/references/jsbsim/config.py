"""A flight's knobs (`FlightConfig`), their per-vehicle defaults and their validation."""

from __future__ import annotations

import dataclasses

from mca_drake.references.jsbsim.aircraft import DEG
from mca_drake.references.jsbsim.fleet import VEHICLE_DEFAULTS, check_vehicle
from mca_drake.references.jsbsim.maneuvers import Doublet, Maneuver, Turbulence
from mca_drake.references.jsbsim.style import PilotStyle


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
    # How the pilot flies (`style.PilotStyle`); None: the scripted pilot.
    style: PilotStyle | None = None

    def resolved(self, vehicle: str) -> FlightConfig:
        """A copy with every None field (except from_ground, heading, style) set: the style's
        turbulence where it has one, else the vehicle's default."""
        defaults = dict(VEHICLE_DEFAULTS[check_vehicle(vehicle)])
        for name in ("turbulence_severity", "turbulence_patch_severity"):
            chosen = getattr(self.style, name, None)
            if chosen is not None:
                defaults[name] = chosen
        missing = {name: value for name, value in defaults.items() if getattr(self, name) is None}
        return dataclasses.replace(self, **missing)


def default_config(vehicle: str) -> FlightConfig:
    """The vehicle's default FlightConfig with every field filled in."""
    return FlightConfig().resolved(vehicle)


def check_config(config: FlightConfig) -> None:
    """Raises ValueError for a resolved config outside the ranges the pilot can fly."""
    for name in ("turbulence_severity", "turbulence_patch_severity"):
        value = getattr(config, name)
        if not 0 <= value <= 7:
            raise ValueError(f"{name} must be in 0 ... 7; got {value}")
    if not 0 < config.max_bank_rad < 80 * DEG:
        raise ValueError(f"max_bank_rad must be in (0, 80 deg); got {config.max_bank_rad}")
    if not 0 < config.min_altitude_m <= config.maneuver_altitude_m <= config.max_altitude_m:
        raise ValueError(
            "need 0 < min_altitude_m <= maneuver_altitude_m <= max_altitude_m; got "
            f"{config.min_altitude_m}, {config.maneuver_altitude_m}, {config.max_altitude_m}"
        )
    if config.style is not None:
        config.style.validate()
    for m in config.maneuvers or ():
        if isinstance(m, Doublet) and m.control not in ("elevator", "aileron", "rudder"):
            raise ValueError(
                f"unknown doublet control '{m.control}'; valid: elevator, aileron, rudder"
            )
        if isinstance(m, Turbulence) and not 0 <= m.severity <= 7:
            raise ValueError(f"turbulence severity must be in 0 ... 7; got {m.severity}")
        if not isinstance(m, Maneuver):
            raise ValueError(f"not a maneuver: {m!r}")
