"""How a pilot flies: the scripted pilot's style, and a random style drawn per flight.

The scripted pilot flies every airframe the same way: one set of loop gains, one
manoeuvre mix, one sense of how hard to bank. Training only on it teaches a policy that
pilot's habits as much as the task. `PilotStyle` scales what a different pilot would do
differently, and `sample_pilot_style` draws one per flight from `PilotStyleRanges`:

- loop gains: the outer loops (heading -> bank -> roll rate, altitude -> vertical speed,
  attitude -> pitch rate) and the inner ones (rate -> surface, sideslip -> rudder), which
  set how tight and how damped the flying is;
- aggressiveness: the roll and pitch rates commanded at most, how fast the hand moves the
  controls, and the size of doublets;
- targets: bank angles of turns and reversals, climb and descent rates;
- the manoeuvre mix (Dirichlet-distributed weights) and the manoeuvres' durations;
- a reaction delay between the pilot's decision and the surfaces;
- the turbulence the flight meets.

`PilotStyle()` (every factor 1, no delay) is the scripted pilot exactly: a flight with it
equals the flight without a style, sample for sample.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mca_drake.references.jsbsim.aircraft import Airframe

# The random plan's manoeuvre kinds, in the order of `PilotStyle.maneuver_weights`.
MANEUVER_KINDS = (
    "level",
    "turn",
    "steep_turn",
    "reversals",
    "doublet",
    "speed",
    "altitude",
    "stall",
)
# The scripted pilot's mix (shares of the random draws after the lesson plan).
SCRIPTED_WEIGHTS = (0.08, 0.17, 0.13, 0.13, 0.17, 0.1, 0.12, 0.1)


@dataclasses.dataclass(frozen=True)
class PilotStyle:
    """Factors on the scripted pilot's ways; the defaults are the scripted pilot."""

    # Outer-loop gains (heading -> bank, bank -> roll rate, altitude -> vertical speed,
    # attitude -> pitch rate), times the scripted pilot's.
    outer_gain: float = 1.0
    # Inner-loop gains (roll and pitch rate -> surface, sideslip -> rudder): the damping.
    inner_gain: float = 1.0
    # Largest commanded roll and pitch rates, the hand's control rate, the pace of bank
    # reversals and (up to the scripted pilot's) doublet sizes.
    aggressiveness: float = 1.0
    # Bank angles of turns and reversals (capped by the flight's max_bank_rad).
    bank_scale: float = 1.0
    # Climb and descent rates of altitude changes (capped by the airframe's rates).
    vspeed_scale: float = 1.0
    # Durations of level flight, turns, reversals and speed changes.
    duration_scale: float = 1.0
    # Shares of the manoeuvre kinds (`MANEUVER_KINDS`) in the random draws; None: the
    # scripted pilot's `SCRIPTED_WEIGHTS`.
    maneuver_weights: tuple[float, ...] | None = None
    # Time from the pilot's decision to the surfaces, s (a whole number of 0.01 s steps).
    reaction_delay_s: float = 0.0
    # Background and strongest patch turbulence severity (MIL-F-8785C index, 0 ... 7);
    # None: the vehicle's default.
    turbulence_severity: int | None = None
    turbulence_patch_severity: int | None = None
    # The hand's neuromuscular lag: a first-order lag of this time constant between the
    # (delayed) decision and the controls, s (0: none; a human's is about 0.1 s).
    neuromuscular_lag_s: float = 0.0
    # Remnant: noise the pilot adds to every control, uncorrelated with the task, RMS at the
    # controls in normalised deflection (0: none); it passes the neuromuscular lag, which
    # shapes its spectrum, so it needs one. Drawn from `remnant_seed`.
    remnant: float = 0.0
    remnant_seed: int = 0

    def validate(self) -> None:
        """Raises ValueError for a style the pilot cannot fly."""
        factors = ("outer_gain", "inner_gain", "aggressiveness", "bank_scale", "vspeed_scale")
        for name in (*factors, "duration_scale"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0.2 <= value <= 5.0):
                raise ValueError(f"PilotStyle.{name} must be in [0.2, 5]; got {value}")
        if not (np.isfinite(self.reaction_delay_s) and 0.0 <= self.reaction_delay_s <= 0.5):
            raise ValueError(
                f"PilotStyle.reaction_delay_s must be in [0, 0.5] s; got {self.reaction_delay_s}"
            )
        if not (np.isfinite(self.neuromuscular_lag_s) and 0.0 <= self.neuromuscular_lag_s <= 0.3):
            raise ValueError(
                f"PilotStyle.neuromuscular_lag_s must be in [0, 0.3] s; got "
                f"{self.neuromuscular_lag_s}"
            )
        if not (np.isfinite(self.remnant) and 0.0 <= self.remnant <= 0.1):
            raise ValueError(f"PilotStyle.remnant must be in [0, 0.1]; got {self.remnant}")
        if self.remnant > 0 and self.neuromuscular_lag_s == 0:
            raise ValueError("PilotStyle.remnant needs a neuromuscular_lag_s to shape it")
        weights = self.maneuver_weights
        if weights is not None:
            w = np.asarray(weights, dtype=float)
            if w.shape != (len(MANEUVER_KINDS),) or not np.all(np.isfinite(w)) or w.min() < 0:
                raise ValueError(
                    f"PilotStyle.maneuver_weights must be {len(MANEUVER_KINDS)} non-negative "
                    f"shares ({', '.join(MANEUVER_KINDS)}); got {weights}"
                )
            if not w.sum() > 0:
                raise ValueError("PilotStyle.maneuver_weights must not all be zero")
        for name in ("turbulence_severity", "turbulence_patch_severity"):
            value = getattr(self, name)
            if value is not None and not 0 <= value <= 7:
                raise ValueError(f"PilotStyle.{name} must be in 0 ... 7; got {value}")

    def weights(self) -> np.ndarray:
        """The manoeuvre kinds' shares (8), summing to 1."""
        w = np.asarray(self.maneuver_weights or SCRIPTED_WEIGHTS, dtype=float)
        return w / w.sum()

    def airframe(self, air: Airframe) -> Airframe:
        """`air` as this pilot flies it: its loop gains and rate limits scaled."""
        return dataclasses.replace(
            air,
            roll_rate_gain=air.roll_rate_gain * self.inner_gain,
            pitch_rate_gain=air.pitch_rate_gain * self.inner_gain,
            yaw_gain=air.yaw_gain * self.inner_gain,
            roll_rate_max=air.roll_rate_max * self.aggressiveness,
            roll_rate_aggressive=air.roll_rate_aggressive * self.aggressiveness,
            pitch_rate_max=air.pitch_rate_max * self.aggressiveness,
        )


@dataclasses.dataclass(frozen=True)
class PilotStyleRanges:
    """The distribution `sample_pilot_style` draws from: each factor log-uniform in its
    (low, high), the delay uniform, the mix Dirichlet, the severities uniform integers.

    The ranges keep the flights inside what the airframes fly without a FlightError: the
    corners of these ranges (every factor at its low or high end together, the largest
    delay, moderate turbulence) flew the training vehicles' 300 s flights without one,
    where wider gains (0.6 to 1.6) with a 0.2 s delay lost control of the agile ones in
    steep turns and aileron doublets.
    """

    outer_gain: tuple[float, float] = (0.7, 1.4)
    inner_gain: tuple[float, float] = (0.8, 1.25)
    aggressiveness: tuple[float, float] = (0.7, 1.3)
    bank_scale: tuple[float, float] = (0.6, 1.4)
    vspeed_scale: tuple[float, float] = (0.5, 1.0)
    duration_scale: tuple[float, float] = (0.5, 2.0)
    # Delays of the pilot's decisions beyond the scripted pilot's, s.
    reaction_delay_s: tuple[float, float] = (0.0, 0.1)
    # Dirichlet concentration per kind: 2 draws mixes far from the scripted one (a
    # pilot who mostly turns, one who mostly flies doublets), none of them empty on average.
    maneuver_concentration: float = 2.0
    turbulence_severity: tuple[int, int] = (0, 3)
    turbulence_patch_severity: tuple[int, int] = (0, 4)

    def validate(self) -> None:
        """Raises ValueError for ranges that would draw styles `PilotStyle` refuses."""
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, tuple) and not value[0] <= value[1]:
                raise ValueError(f"PilotStyleRanges.{field.name}: low above high ({value})")
        if not self.maneuver_concentration > 0:
            raise ValueError("PilotStyleRanges.maneuver_concentration must be positive")
        PilotStyle(
            **{name: getattr(self, name)[0] for name in _FACTORS},
            reaction_delay_s=self.reaction_delay_s[0],
            turbulence_severity=self.turbulence_severity[0],
        ).validate()
        PilotStyle(
            **{name: getattr(self, name)[1] for name in _FACTORS},
            reaction_delay_s=self.reaction_delay_s[1],
            turbulence_severity=self.turbulence_severity[1],
            turbulence_patch_severity=self.turbulence_patch_severity[1],
        ).validate()


_FACTORS = (
    "outer_gain",
    "inner_gain",
    "aggressiveness",
    "bank_scale",
    "vspeed_scale",
    "duration_scale",
)


def sample_pilot_style(
    rng: np.random.Generator, ranges: PilotStyleRanges | None = None
) -> PilotStyle:
    """A random pilot's style drawn from `ranges` (default PilotStyleRanges()).

    The delay is rounded to whole JSBSim steps (0.01 s); the patches' severity is at least
    the background's (a patch is never calmer than the air around it).
    """
    ranges = ranges or PilotStyleRanges()
    ranges.validate()
    factors = {
        name: float(np.exp(rng.uniform(*np.log(getattr(ranges, name))))) for name in _FACTORS
    }
    delay = round(float(rng.uniform(*ranges.reaction_delay_s)), 2)
    weights = rng.dirichlet(np.full(len(MANEUVER_KINDS), ranges.maneuver_concentration))
    background = int(rng.integers(ranges.turbulence_severity[0], ranges.turbulence_severity[1] + 1))
    low, high = ranges.turbulence_patch_severity
    patches = max(background, int(rng.integers(low, high + 1)))
    return PilotStyle(
        **factors,
        maneuver_weights=tuple(float(w) for w in weights),
        reaction_delay_s=delay,
        turbulence_severity=background,
        turbulence_patch_severity=patches,
    )


@dataclasses.dataclass(frozen=True)
class HumanOperatorRanges:
    """The human-operator pilot's distribution (`sample_human_operator`): McRuer's
    crossover model of a human in a control loop, on the scripted pilot's tasks.

    A human closes the loop around the aircraft with an effective time delay tau_e (reaction
    and neuromuscular, 0.2 to 0.4 s in McRuer and Krendel's measurements; a trained pilot's
    at the low end), a neuromuscular lag of about 0.1 s, and remnant, control activity
    uncorrelated with the task. The crossover model (the pilot adapts so that pilot and
    aircraft together look like omega_c e^(-tau_e s) / s near crossover) keeps a phase
    margin of pi / 2 - omega_c tau_e: a later pilot crosses over lower, omega_c falling as
    1 / tau_e. The inner loops (rate -> surface), the fastest, take that as their gain:
    the scripted pilot's times `CROSSOVER_INNER_S` / tau_e; the outer loops, slower, the
    scripted pilot's times `CROSSOVER_DELAY_S` / (`CROSSOVER_DELAY_S` + tau_e). The
    manoeuvre mix is the scripted pilot's: the same tasks, flown as a human would.
    """

    reaction_delay_s: tuple[float, float] = (0.10, 0.15)
    neuromuscular_lag_s: tuple[float, float] = (0.08, 0.12)
    # Remnant RMS at the controls, normalised deflection.
    remnant: tuple[float, float] = (0.005, 0.02)
    # How hard the human flies (rate limits, the hand's speed), as the random styles'.
    aggressiveness: tuple[float, float] = (0.7, 1.0)


# The crossover model's delays for the human operator's gains (`HumanOperatorRanges`), s:
# the effective delay at which the scripted pilot's inner loops (gain CROSSOVER_INNER_S /
# tau_e) keep their phase margin, set where the light aircraft's pitch loop stops
# oscillating (gain 0.3 at a delay of 0.1 s and a lag of 0.08 s, 0.2 at 0.15 and 0.1);
# and the one at which the outer loops' gain halves (the 0.1 s of added delay at full
# gain the random styles fly safely, plus a hand's lag).
CROSSOVER_INNER_S = 0.055
CROSSOVER_DELAY_S = 0.25


def sample_human_operator(seed: int, rng: np.random.Generator, ranges=None) -> PilotStyle:
    """A human operator's style drawn from `ranges` (default HumanOperatorRanges()): delay
    (whole 0.01 s steps), neuromuscular lag and remnant uniform, aggressiveness
    log-uniform, the loop gains the crossover model's (`HumanOperatorRanges`); its
    remnant drawn from `seed`'s own stream."""
    ranges = ranges or HumanOperatorRanges()
    delay = round(float(rng.uniform(*ranges.reaction_delay_s)), 2)
    lag = float(rng.uniform(*ranges.neuromuscular_lag_s))
    tau_e = delay + lag
    return PilotStyle(
        outer_gain=CROSSOVER_DELAY_S / (CROSSOVER_DELAY_S + tau_e),
        inner_gain=min(max(CROSSOVER_INNER_S / tau_e, 0.2), 1.0),
        aggressiveness=float(np.exp(rng.uniform(*np.log(ranges.aggressiveness)))),
        reaction_delay_s=delay,
        neuromuscular_lag_s=lag,
        remnant=float(rng.uniform(*ranges.remnant)),
        remnant_seed=int(seed),
    )
