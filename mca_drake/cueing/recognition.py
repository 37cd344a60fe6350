"""The kind of vehicle an unnamed reference comes from, recognized from the reference itself
as it goes, and the shipped policy for it (`DpcConfig.unnamed = "recognize"`).

A recording of X-Plane, FlightGear or a logger, and a live stream of a flight simulator,
name no vehicle; the DPC still has to pick between its shipped policies, and a wrong pick
costs more than the right one gains (the transport policy on a light single cues worse
than not moving; the flight policy on a car rides the clamp). The recognizer therefore
only moves away from the default policy on evidence that the vehicle of the other policy
is the only one that could have produced it, and the vehicle never changes within a
recording, so each decision against a kind is final:

- **transport**: a transport pitches, yaws and rolls slowly (the transport envelope of
  `references.synthetic.ENVELOPES`: 20, 6 and 5 deg/s), pulls at most 2.5 g and
  accelerates or brakes at most about 0.6 g. While the reference, smoothed over
  `smoothing_s`, has stayed inside those bounds (times the default scales) for `settle_s`,
  the transport policy runs; the first excursion hands back to the default for good. On
  the training flights (seeds 0-5) every transport stayed within 0.94 of the rate bounds
  and every other aircraft left them (light singles by 2-3.5x, fighters by 2-2.7x).
- **light**: a light aircraft flies slowly, and a pull shows its speed: pitching at q with
  n g takes V = g (n - 1) / q, on the reference a_z / -w_y. Once the transport is ruled
  out, inside a light aircraft's roll and yaw rates, surge and sideslip force, while the
  reference's pulls so far (none, too) have been twice as long slow (below
  `light_pull_speed`) as fast, the light policy runs (decision 0041: a light single's
  calm climb stays inside a transport's bounds past the first 20 s, and pulls it has not
  flown yet cannot tell it from a trainer's calm start); leaving those bounds, or pulling
  fast for longer than slow (and `light_pull_s`), ends it for good, as it ends a named
  light aircraft's. (The median pull speeds of the training and validation flights: light
  singles and Twin Otter 29-42 m/s, jet trainer 62-84, transports 70-101, fighters
  85-146.)
- **ground**: a car corners with a lateral specific force that no aircraft in coordinated
  flight holds, without rolling, on a level road that never pulls g: smoothed, |f_y| above
  `ground_lateral`, |w_x| below `ground_roll_rate` and |a_z| below `ground_vertical`
  together for `ground_hold_s`, and never |a_z| above `aircraft_vertical` before (the
  training drives stay below 0.32, every aircraft passes 1.5). Then the ground policy runs
  for good. On the training flights no aircraft held that evidence for more than 0.6 s.
- otherwise the **default** policy.

A vehicle named a light aircraft or a transport (`DpcConfig.vehicle`) starts in its
envelope's policy at once (`initial_recognition_state(named=...)`: nothing to recognize,
the other kinds ruled out) and keeps it while the reference stays inside that envelope's
bounds above; once it leaves them, the default policy runs for good
(`DpcConfig.envelope_handback`): a hand-flown light aircraft pulled beyond what its
policy was trained on is cued better by the default policy, trained on every aircraft,
than by a policy that extrapolates.

Every change of policy is handed over smoothly: the command blends from the old policy's
to the new one's with a smoothstep weight (no step in the command, nor in its rate), over
`handover_s`, and back to the default over the shorter `handback_s`: the evidence for a
transport or a light aircraft ends in a manoeuvre their policies were not trained for. A
change that comes while another hand-over is still under way blends from the blend that
one had reached (`handover_origin`), not from its new policy alone: no step in the
command, only its rate bends where the earlier blend's weight stops moving.
"""

from __future__ import annotations

import dataclasses
import math

from mca_drake.conventions import GRAVITY
from mca_drake.references.reference import DEFAULT_ANGULAR_SCALE, DEFAULT_FORCE_SCALE
from mca_drake.references.synthetic import ENVELOPES

# The policies the recognizer chooses between, by index (the index is what the DPC's
# discrete state stores): the default first, the one that runs before any evidence.
RECOGNIZED_POLICIES = ("default_policy", "transport_policy", "light_policy", "ground_policy")
DEFAULT, TRANSPORT, LIGHT, GROUND = range(len(RECOGNIZED_POLICIES))

# Why each policy was chosen, for a summary.
RECOGNITION_REASONS = (
    "no vehicle named: the default policy (nothing recognized)",
    "no vehicle named: recognized as a transport (rotation rates inside the transport envelope)",
    "no vehicle named: recognized as a light aircraft (slow pulls, inside a light "
    "aircraft's roll, yaw, surge and sideslip)",
    "no vehicle named: recognized as a car (lateral force without roll, level)",
)
# Why a named vehicle's envelope policy handed back to the default.
HANDBACK_REASONS = {
    TRANSPORT: "the reference left the transport envelope (rotation rates, 2.5 g or 0.6 g of "
    "surge): the default policy",
    LIGHT: "the reference left a light aircraft's bounds (roll, yaw, surge, sideslip or fast "
    "pulls): the default policy",
}


def _transport_rates() -> tuple[float, float, float]:
    """The transport envelope's roll, pitch and yaw rate bounds on the reference, rad/s."""
    return tuple(DEFAULT_ANGULAR_SCALE * r for r in ENVELOPES["transport"].max_rates)


@dataclasses.dataclass(frozen=True)
class RecognitionConfig:
    """How an unnamed reference is recognized (module docstring). Every bound applies to the
    reference as the policy reads it (`Reference.y`, scaled by `ReferenceScaling`: the
    shipped policies learned references of the default scales)."""

    # Time constant of the first-order low-pass on each channel's magnitude, s: a single
    # sample (a spike) moves it by a hundredth, a manoeuvre's second fully.
    smoothing_s: float = 1.0
    # The transport envelope's roll, pitch and yaw rate bounds on the reference, rad/s.
    transport_rates: tuple[float, float, float] = dataclasses.field(
        default_factory=_transport_rates
    )
    # A transport's surge specific force (m/s^2 on the reference: 0.6 g, thrust to weight
    # up to 0.35 with a climb's pitch, or braking) and vertical one (|a_z|: the transport
    # envelope's load factor 2.5, 1.5 g above level flight), times the default scale.
    transport_surge: float = DEFAULT_FORCE_SCALE * 0.6 * GRAVITY
    transport_vertical: float = dataclasses.field(
        default_factory=lambda: (
            DEFAULT_FORCE_SCALE * (ENVELOPES["transport"].load_factors[1] - 1.0) * GRAVITY
        )
    )
    # A light aircraft's sideslip specific force (m/s^2 on the reference: the light
    # envelope's 0.2 g times the default scale).
    light_lateral: float = dataclasses.field(
        default_factory=lambda: DEFAULT_FORCE_SCALE * ENVELOPES["light"].max_horizontal_force[1]
    )
    # A light aircraft's bounds on the reference, beyond the transport's: roll and yaw rate
    # (rad/s) and surge specific force (m/s^2). Yaw and surge are the light envelope's 20
    # deg/s and 0.3 g times the default scales, surge with a third more for take-off and
    # landing rolls; roll is a light aircraft's manoeuvring roll (the envelope's 60 deg/s is
    # full aileron, seldom flown): the training flights' light singles and Twin Otter stay
    # below 0.26 smoothed, the jet trainer and the fighters pass 0.31.
    light_roll_rate: float = 0.30
    light_yaw_rate: float = dataclasses.field(
        default_factory=lambda: DEFAULT_ANGULAR_SCALE * ENVELOPES["light"].max_rates[2]
    )
    light_surge: float = dataclasses.field(
        default_factory=lambda: (
            DEFAULT_FORCE_SCALE * 4.0 / 3.0 * ENVELOPES["light"].max_horizontal_force[0]
        )
    )
    # A pull: smoothed pitch rate above this (rad/s on the reference) with smoothed vertical
    # force above this (m/s^2) of the matching sign; its speed is a_z / -w_y (m/s at equal
    # angular and force scales, g (n - 1) / q).
    pull_pitch_rate: float = 0.02
    pull_vertical: float = 0.3
    # A light aircraft pulls slower than this (m/s): on the training and validation
    # flights the light singles' and Twin Otter's pulls had median speeds of 29-42 m/s,
    # the jet trainer's 62-84, the transports' 70-101, the fighters' 85-146.
    light_pull_speed: float = 50.0
    # The light policy starts while the slow pulls have lasted this many times as long as
    # the fast ones (and, with `light_needs_slow_pulls`, this long, s); fast pulls longer
    # than this and than the slow ones rule a light aircraft out, and end its policy.
    light_pull_s: float = 3.0
    light_pull_ratio: float = 2.0
    # Whether a light aircraft is recognized (False: only transports and cars are).
    recognize_light: bool = True
    # Whether the light policy waits for `light_pull_s` of slow pulls before it runs.
    # False: it runs once the transport is ruled out, inside a light aircraft's bounds,
    # while the pulls so far (none, too) have been `light_pull_ratio` times as long slow as
    # fast: a light single's take-off and climb stay inside the transport's bounds for the
    # first 20 s and longer, and waiting for its pulls kept the default for up to 38 s
    # more (decision 0041).
    light_needs_slow_pulls: bool = False
    # How long the reference must be watched before the transport or the light policy
    # takes over, s (the transport's or light aircraft's bounds held all along).
    settle_s: float = 20.0
    # Ground evidence: smoothed |f_y| above this (m/s^2 on the reference; 0.2 g at the
    # default force scale, above the light and transport envelopes' sideslip forces)...
    ground_lateral: float = 1.0
    # ...with smoothed |w_x| below this (rad/s on the reference)...
    ground_roll_rate: float = 0.03
    # ...and smoothed |a_z| below this (m/s^2 on the reference), for
    ground_vertical: float = 0.5
    # this long, s.
    ground_hold_s: float = 2.0
    # Smoothed |a_z| above this once (m/s^2 on the reference) rules out a car for good.
    aircraft_vertical: float = 1.0
    # Hand-over from one policy's command to the next, s, and back to the default policy
    # (the evidence for the other ended, often in a manoeuvre it was not trained for).
    handover_s: float = 2.0
    handback_s: float = 0.5

    def validate(self) -> None:
        """Raises ValueError for a non-positive or non-finite setting."""
        if len(self.transport_rates) != 3:
            raise ValueError(f"transport_rates must be 3 values; got {self.transport_rates}")
        bad = []
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool):
                continue
            values = value if isinstance(value, tuple) else (value,)
            if not all(math.isfinite(v) and v > 0 for v in values):
                bad.append(field.name)
        if bad:
            raise ValueError(f"RecognitionConfig: {', '.join(bad)} must be positive and finite")


# The recognizer's state, one vector of floats (the DPC keeps it in its discrete state, so
# that a simulation re-run from a context starts over): the smoothed magnitudes of the six
# channels (0-5), then the scalars below.
_TIME, _GROUND_HELD, _NOT_TRANSPORT, _NOT_GROUND, _POLICY, _PREVIOUS, _SINCE, _NOT_LIGHT = range(
    6, 14
)
# the pitch rate and vertical force smoothed with their signs, and the time spent in slow
# and in fast pulls (`pull_speed`)
_PITCH, _VERTICAL, _SLOW_PULLS, _FAST_PULLS = range(14, 18)
# the named vehicle's policy the state started in (0: none named, recognized from the
# default)
_NAMED = 18
# where a change of policy during another's hand-over hands over from: the policy that hand-
# over came from (-1: none, the change came after it ended) and the weight its successor had
# then, so that the command goes on from the blend it had reached (no step)
_OUTER, _OUTER_WEIGHT = 19, 20
# then the changes of policy, (time s, index in RECOGNIZED_POLICIES) each, NaN where there
# were fewer: each kind is taken at most once (leaving one rules it out) and a car's
# comes last, so at most
# default -> transport -> default -> light -> default -> ground
MAX_CHANGES = 5
_FIRST_CHANGE = 21
RECOGNITION_STATE_SIZE = _FIRST_CHANGE + 2 * MAX_CHANGES


def initial_recognition_state(named: int = DEFAULT) -> list[float]:
    """The recognizer's state before the first sample: the default policy, from t = 0; or,
    with `named` TRANSPORT or LIGHT (a vehicle named of that envelope), that policy from
    t = 0 with every other kind ruled out, handed back to the default once the reference
    leaves the envelope. ValueError for another `named`."""
    if named not in (DEFAULT, TRANSPORT, LIGHT):
        raise ValueError(
            f"named: {RECOGNIZED_POLICIES[TRANSPORT]} or {RECOGNIZED_POLICIES[LIGHT]} "
            f"(or {RECOGNIZED_POLICIES[DEFAULT]}: none); got {named!r}"
        )
    state = [0.0] * RECOGNITION_STATE_SIZE
    state[_PREVIOUS] = state[_OUTER] = -1.0  # nothing to hand over from
    state[_OUTER_WEIGHT] = 1.0
    state[_SINCE] = -math.inf
    state[_FIRST_CHANGE:] = [math.nan] * (2 * MAX_CHANGES)
    if named != DEFAULT:
        state[_POLICY] = state[_NAMED] = float(named)
        state[_NOT_GROUND] = 1.0
        state[_NOT_LIGHT if named == TRANSPORT else _NOT_TRANSPORT] = 1.0
    return state


def recognition_step(
    state: list[float], reference, time_step: float, config: RecognitionConfig
) -> None:
    """Advances `state` (`initial_recognition_state`, as a list of floats: the DPC's step
    budget is tens of microseconds, and Python floats cost a third of numpy's small-array
    calls) by one sample of the reference (6 values), `time_step` s after the previous one;
    the policy to run is then `policy_weights(state, config)`. A non-finite reference
    sample is skipped (the DPC stops on it anyway)."""
    magnitudes = [abs(v) for v in reference]
    if not math.isfinite(sum(magnitudes)):
        return
    alpha = time_step / (config.smoothing_s + time_step)
    for i in range(6):
        state[i] += alpha * (magnitudes[i] - state[i])
    now = state[_TIME] = state[_TIME] + time_step
    w_x, w_y, w_z, _, f_y, a_z = state[:6]
    rates = config.transport_rates
    f_x = state[3]
    if w_x > rates[0] or w_y > rates[1] or w_z > rates[2]:
        state[_NOT_TRANSPORT] = 1.0
    if f_x > config.transport_surge or a_z > config.transport_vertical:
        state[_NOT_TRANSPORT] = 1.0
    if w_x > config.light_roll_rate or w_z > config.light_yaw_rate or f_x > config.light_surge:
        state[_NOT_LIGHT] = 1.0
    if f_y > config.light_lateral:
        state[_NOT_LIGHT] = 1.0
    if a_z > config.aircraft_vertical:
        state[_NOT_GROUND] = 1.0
    # a pull's speed: pitching at q with n g takes V = g (n - 1) / q (in a loop or a turn
    # alike), on the reference a_z / -w_y at equal scales; pitch up with positive g (y
    # points left: a pitch up is a negative w_y) or down with negative g
    pitch = state[_PITCH] = state[_PITCH] + alpha * (reference[1] - state[_PITCH])
    vertical = state[_VERTICAL] = state[_VERTICAL] + alpha * (reference[5] - state[_VERTICAL])
    if abs(pitch) > config.pull_pitch_rate and abs(vertical) > config.pull_vertical:
        if pitch * vertical < 0.0:
            slow = abs(vertical) < config.light_pull_speed * abs(pitch)
            state[_SLOW_PULLS if slow else _FAST_PULLS] += time_step
    if state[_FAST_PULLS] > max(state[_SLOW_PULLS], config.light_pull_s):
        state[_NOT_LIGHT] = 1.0  # pulls mostly faster than a light aircraft flies
    ground_like = f_y > config.ground_lateral and w_x < config.ground_roll_rate
    ground_like = ground_like and a_z < config.ground_vertical
    state[_GROUND_HELD] = state[_GROUND_HELD] + time_step if ground_like else 0.0
    policy = int(state[_POLICY])
    # a named vehicle needs no evidence for its own kind, only stays inside its bounds
    named = state[_NAMED] != 0.0
    if policy == GROUND:
        chosen = GROUND
    elif not state[_NOT_GROUND] and state[_GROUND_HELD] >= config.ground_hold_s - 1e-9:
        chosen = GROUND
    elif now < config.settle_s - 1e-9 and not named:
        chosen = DEFAULT
    elif not state[_NOT_TRANSPORT]:
        chosen = TRANSPORT
    elif (
        (named or config.recognize_light)
        and not state[_NOT_LIGHT]
        and (named or policy == LIGHT or _slow_pulls(state, config))
    ):
        chosen = LIGHT
    else:
        chosen = DEFAULT
    if chosen != policy and policy == LIGHT:
        # leaving the light policy is a decision against a light aircraft, final as every
        # other (it leaves on a light bound or fast pulls, which set this already, or for a
        # car's evidence): no later slow pulls bring it back, so the change record cannot
        # overflow (two of six Twin Otter flights of the human-operator pilot once went
        # light - default - light - default - light and on)
        state[_NOT_LIGHT] = 1.0
    if chosen != policy:
        # a change during a hand-over hands over from the blend reached, not from the
        # policy taking over alone (whose command can differ from the blend by a step)
        _, handing_from, weight = policy_weights(state, config)
        state[_OUTER], state[_OUTER_WEIGHT] = float(handing_from), weight
        state[_PREVIOUS], state[_POLICY], state[_SINCE] = policy, chosen, now
        # the first free slot (MAX_CHANGES is the most the transitions allow)
        times = state[_FIRST_CHANGE::2]
        slot = _FIRST_CHANGE + 2 * next(k for k, t in enumerate(times) if not math.isfinite(t))
        state[slot], state[slot + 1] = now, chosen


def _slow_pulls(state, config: RecognitionConfig) -> bool:
    """Whether the pulls so far were a light aircraft's, for the light policy to start:
    `light_pull_ratio` times as long slow as fast (none at all, too), and with
    `light_needs_slow_pulls` slow for `light_pull_s` at least."""
    slow, fast = state[_SLOW_PULLS], state[_FAST_PULLS]
    if slow < config.light_pull_ratio * fast:
        return False
    return not config.light_needs_slow_pulls or slow >= config.light_pull_s - 1e-9


def policy_weights(state, config: RecognitionConfig) -> tuple[int, int, float]:
    """(the policy now chosen, the one handed over from or -1, the weight of the chosen one's
    command in [0, 1]): a smoothstep 3 s^2 - 2 s^3 of the share s of the hand-over's time
    elapsed since the change (`handback_s` back to the default, else `handover_s`), 1
    once it is over."""
    policy, previous = int(state[_POLICY]), int(state[_PREVIOUS])
    duration = config.handback_s if policy == DEFAULT else config.handover_s
    share = (state[_TIME] - state[_SINCE]) / duration
    if previous < 0 or share >= 1.0:
        return policy, -1, 1.0
    share = max(share, 0.0)
    return policy, previous, share * share * (3.0 - 2.0 * share)


def handover_origin(state) -> tuple[int, float]:
    """Where the hand-over `policy_weights` describes blends from, when the change came
    during an earlier hand-over: (the policy that one came from, the weight of its
    successor then, the `previous` of `policy_weights`), the blend old + w (previous - old)
    of their commands standing for the previous policy's alone; (-1, 1.0) otherwise. (A
    third change within one hand-over blends from the second's blend without the first.)"""
    return int(state[_OUTER]), float(state[_OUTER_WEIGHT])


def recognition_final(state, config: RecognitionConfig) -> bool:
    """Whether nothing can change any more: the ground policy runs, or the default with
    every other kind ruled out, and its hand-over is over. Stepping such a state changes
    only its clock, so the DPC stops stepping it (a few microseconds a step)."""
    policy = int(state[_POLICY])
    if policy == DEFAULT:
        ruled_out = state[_NOT_TRANSPORT] and state[_NOT_GROUND]
        if not (ruled_out and (state[_NOT_LIGHT] or not config.recognize_light)):
            return False
    elif policy != GROUND:
        return False
    return policy_weights(state, config)[1] < 0


def recognized_policy(state) -> int:
    """The index in RECOGNIZED_POLICIES of the policy `state` has chosen."""
    return int(state[_POLICY])


def policy_changes(state) -> list[tuple[float, int]]:
    """(time s, index in RECOGNIZED_POLICIES) of each change of policy, in time order (the
    policy `initial_recognition_state` started in runs from 0 before the first: the
    default, or a named vehicle's)."""
    changes = [float(v) for v in state[_FIRST_CHANGE:]]
    pairs = zip(changes[::2], changes[1::2], strict=True)
    return [(t, int(i)) for t, i in pairs if math.isfinite(t)]


__all__ = [
    "HANDBACK_REASONS",
    "RECOGNITION_REASONS",
    "RECOGNITION_STATE_SIZE",
    "RECOGNIZED_POLICIES",
    "RecognitionConfig",
    "handover_origin",
    "initial_recognition_state",
    "policy_changes",
    "policy_weights",
    "recognition_final",
    "recognition_step",
    "recognized_policy",
]
