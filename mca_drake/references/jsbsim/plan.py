"""The seeded pilot's random flight plan: which maneuvers, with which draws, in which order.

`RandomPlan` draws each maneuver from the flight's numpy Generator only when the previous one
is over, because what fits depends on where the flight is then (time left, height, the
altitude the pilot holds). So the draws interleave with the flight, and the plan asks the
flight for those three things through the callables it is given.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import numpy as np

from mca_drake.references.jsbsim.aircraft import DEG, Airframe
from mca_drake.references.jsbsim.config import FlightConfig
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
from mca_drake.references.jsbsim.style import MANEUVER_KINDS, PilotStyle


class RandomPlan:
    """The seeded pilot's plan; iterating draws each maneuver when the previous one is over.

    A lesson plan first (every kind once, in random order), then random draws; each maneuver
    must fit in the time left before the pilot has to head home (ground flights) or before the
    end of the recording (airborne flights). Ground flights start with taxi, take-off and a
    climbing turn to the maneuver altitude, and end with a landing.

    Args:
        rng: the flight's Generator (its set-up draws already taken); the plan draws from it.
        config: the resolved flight config (altitudes, speeds, bank, turbulence knobs).
        air: the vehicle's airframe constants (`air.agile` picks the maneuvers' ranges).
        from_ground: the flight takes off and must land before `duration_s`.
        duration_s: length of the recording, s.
        time_s: the flight's simulation time now, s.
        height_m: height of the wheels above ground now, m.
        held_altitude_m: the altitude the pilot holds now (else the height), m.
        style: how the pilot flies: the manoeuvre mix, bank and vertical-speed targets,
            durations and doublet sizes (None: the scripted pilot).
    """

    def __init__(
        self,
        rng: np.random.Generator,
        config: FlightConfig,
        air: Airframe,
        *,
        from_ground: bool,
        duration_s: float,
        time_s: Callable[[], float],
        height_m: Callable[[], float],
        held_altitude_m: Callable[[], float],
        style: PilotStyle | None = None,
    ) -> None:
        self.rng = rng
        self.style = style or PilotStyle()
        self.config = config
        self.air = air
        self.light = air.agile  # the small aircraft's ranges (`Airframe.agile`)
        self.from_ground = from_ground
        self.duration_s = duration_s
        self._time_s = time_s
        self._height_m = height_m
        self._held_altitude_m = held_altitude_m

    def __iter__(self) -> Iterator[Maneuver]:
        rng, air, cfg = self.rng, self.air, self.config
        light = self.light
        if self.from_ground:
            yield Taxi(
                duration_s=float(rng.uniform(15.0, 30.0)),
                turn_rad=float(rng.choice([-1, 1]) * rng.uniform(60, 120) * DEG),
            )
            yield Takeoff()
            yield AltitudeChange(
                altitude_change_m=cfg.maneuver_altitude_m - self._height_m(),
                vertical_speed_mps=air.climb_rate,
                heading_change_rad=float(rng.choice([-1, 1]) * rng.uniform(30, 150) * DEG),
            )
            yield SpeedChange(speed_mps=cfg.cruise_speed_mps, duration_s=15.0)
        style = self.style
        kinds = MANEUVER_KINDS
        weights = style.weights()

        # this pilot's bank targets (a larger bank than the scripted pilot's draw only up
        # to the flight's limit) and durations
        def bank_of(drawn_rad: float) -> float:
            return min(drawn_rad * style.bank_scale, max(drawn_rad, cfg.max_bank_rad))

        def lasting(drawn_s: float) -> float:
            return drawn_s * style.duration_scale

        lesson = [
            kinds[i] for i in rng.permutation(len(kinds))[: len(kinds)] if kinds[i] != "level"
        ]
        stall_time = 80.0 if light else 100.0  # s, entry + recovery + climb back
        while True:
            room = self.duration_s - self.time_to_land() - self._time_s()  # s for maneuvers
            if room < (25.0 if self.from_ground else 0.0):
                break
            if not self.from_ground:
                room = math.inf  # the end of the recording may cut the last maneuver
            height = self._height_m()
            if height < cfg.min_altitude_m - 30.0:  # back up to the maneuver band first
                yield AltitudeChange(cfg.maneuver_altitude_m - height, air.climb_rate)
                continue
            kind = lesson.pop(0) if lesson else str(rng.choice(kinds, p=weights))
            if cfg.turbulence_patch_severity > cfg.turbulence_severity and rng.uniform() < 0.25:
                low, high = cfg.turbulence_severity + 1, cfg.turbulence_patch_severity
                yield Turbulence(severity=int(rng.integers(low, high + 1)))
            elif rng.uniform() < 0.5:
                yield Turbulence(severity=cfg.turbulence_severity)
            side = float(rng.choice([-1.0, 1.0]))
            if kind == "stall" and (room < stall_time or self._height_m() < cfg.min_altitude_m):
                kind = "turn"
            if kind == "altitude":
                change = self._draw_altitude_change(room)
                if change is None:
                    kind = "turn"
                else:
                    rate = air.climb_rate if change > 0 else air.descent_rate
                    turn = float(rng.choice([0.0, 1.0]) * rng.uniform(-120, 120) * DEG)
                    yield AltitudeChange(
                        altitude_change_m=change,
                        vertical_speed_mps=float(rng.uniform(0.6, 1.0) * rate) * style.vspeed_scale,
                        heading_change_rad=turn,
                    )
                    continue
            longest = room - 10.0  # s; every maneuver below ends in time to head home
            if kind == "level":
                yield Level(duration_s=min(lasting(float(rng.uniform(8.0, 25.0))), longest))
            elif kind == "turn":
                bank = rng.uniform(15, 35) if light else rng.uniform(15, 30)
                yield Turn(
                    bank_rad=side * bank_of(float(bank) * DEG),
                    duration_s=min(lasting(float(rng.uniform(10, 40))), longest - 10.0),
                )
            elif kind == "steep_turn":
                low = min(45 * DEG if light else 35 * DEG, cfg.max_bank_rad)
                yield Turn(
                    bank_rad=side * bank_of(float(rng.uniform(low, cfg.max_bank_rad))),
                    duration_s=min(lasting(float(rng.uniform(20, 45))), longest - 10.0),
                )
            elif kind == "reversals":
                low = min(30 * DEG if light else 20 * DEG, cfg.max_bank_rad)
                half = rng.uniform(2.5, 6.0) if light else rng.uniform(5.0, 9.0)
                yield BankReversals(
                    bank_rad=side * bank_of(float(rng.uniform(low, cfg.max_bank_rad))),
                    half_period_s=float(half) / style.aggressiveness,
                    duration_s=min(lasting(float(rng.uniform(15, 35))), longest - 10.0),
                )
            elif kind == "doublet":
                yield self._draw_doublet(side)
            elif kind == "speed":
                low = 0.75 if light else 0.8
                yield SpeedChange(
                    speed_mps=float(rng.uniform(low, 1.1) * cfg.cruise_speed_mps),
                    duration_s=min(lasting(float(rng.uniform(15, 35))), longest),
                )
            else:
                yield Stall()
        if self.from_ground:
            yield Turbulence(severity=cfg.turbulence_severity)
            yield Landing()

    def _draw_doublet(self, side: float) -> Doublet:
        """A doublet on a random control, first step to `side` (+1 or -1)."""
        rng = self.rng
        control = str(rng.choice(["elevator", "aileron", "rudder"]))
        # Normalised step sizes; the jet's surfaces are far more powerful at its speeds (its
        # rudder has no limiter in the model: 0.2 gives 0.5 g sideways at the eye).
        if self.light:
            size = {"elevator": (0.05, 0.15), "aileron": (0.15, 0.4), "rudder": (0.2, 0.5)}
        else:
            size = {"elevator": (0.04, 0.1), "aileron": (0.08, 0.2), "rudder": (0.05, 0.12)}
        # a gentler pilot's doublets are smaller; none is larger than the scripted pilot's,
        # whose largest already rolls the trainers near the doublet's bank limit
        amplitude = float(rng.uniform(*size[control])) * min(self.style.aggressiveness, 1.0)
        return Doublet(
            control=control,
            amplitude=side * amplitude,
            half_period_s=float(rng.uniform(0.5, 1.5)),
            settle_s=float(rng.uniform(3.0, 8.0)),
        )

    def _draw_altitude_change(self, room: float) -> float | None:
        """A climb or descent inside the altitude band that fits in `room` s, m (None: none)."""
        rng, air, cfg = self.rng, self.air, self.config
        base = self._held_altitude_m()
        up_room = cfg.max_altitude_m - base
        down_room = base - cfg.min_altitude_m
        # Time cost per metre: climbing also lengthens the way home (ground flights).
        home = 1.0 / (0.8 * air.descent_rate) if self.from_ground else 0.0
        up_time = 1.3 / air.climb_rate + home
        down_time = 1.3 / air.descent_rate - home
        largest = 300.0 if self.light else 800.0
        smallest = 100.0 if self.light else 300.0
        up = min(up_room, largest, (room - 20.0) / up_time)
        down = min(down_room, largest, (room - 20.0) / max(down_time, 1e-3))  # inf - x: inf
        options = [
            sign * extent for sign, extent in ((1.0, up), (-1.0, down)) if extent >= smallest
        ]
        if not options:
            return None
        extent = options[int(rng.integers(len(options)))]
        return float(np.sign(extent) * rng.uniform(smallest, abs(extent)))

    def time_to_land(self) -> float:
        """Seconds from the maneuvers to a stop on the ground (the pilot's rule of thumb)."""
        if not self.from_ground:
            return 0.0
        air = self.air
        descent = max(self._height_m() - air.approach_height, 0.0) / (0.8 * air.descent_rate)
        approach = air.approach_height / (air.approach_speed * math.tan(3 * DEG))
        return descent + approach + air.rollout_s + 30.0
