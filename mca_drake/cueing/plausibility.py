"""Input plausibility: the reference as an MCA may read it, after telemetry that is
physically possible but wrong has been handled (a physics hiccup's one-sample spike, a
paused game that keeps sending its last frame, a reset that jumps every channel, a NaN).

Every MCA reads the reference through this guard, offline as live, so that a recording with
a glitch is cued as the live stream it came from would be. Per control period, on the
scaled reference (`Reference.y`, channels `conventions.CHANNELS`):

- **not finite**: a channel that is NaN or inf is treated as a spike on that channel.
- **spike**: a channel that jumps from the guard's last output by more than its
  `spike_thresholds` entry is held at that output for up to `spike_samples` periods. If it
  comes back within the threshold, the spike never reached the MCA; if it stays away, it was
  a real jump (a reset, a teleport, a kerb that lasts) and is followed, bounded by the next
  rule.
- **step bound**: the output moves by at most `max_steps` per period, channel by channel:
  above anything the training flights and drives do in one period (at the default scales,
  10 ms: 0.04 rad/s, 5.8 m/s^2 of surge, 0.7 of sway, 2.3 of heave), so a clean reference
  passes unchanged and a jump reaches the cabin as a ramp, not a blow.
- **frozen**: every channel exactly equal to the period before for `frozen_s`, after a
  stream that was moving (it changed in at least half of the `frozen_s` before the freeze):
  a paused game. The output fades to zero (the MCA washes the cabin out to home) over
  `fade_s` with a smoothstep, and fades back in over `fade_s` once the stream moves again.
  A reference that was never moving (a synthetic step held constant) is never taken for
  frozen.

The guard's state is a flat list of floats (`initial_state`, `guard_step`) that the
Drake system (`mca_drake.systems.plausibility.ReferenceGuard`) keeps in its discrete state
and the live loop steps the same way; the counts (`counts`) go into the run's summary as
its `plausibility` block.
"""

import dataclasses
import math

from mca_drake.conventions import NUM_CHANNELS
from mca_drake.input_checks import check_config_numbers


@dataclasses.dataclass
class PlausibilityConfig:
    """How the reference is guarded before an MCA reads it (module docstring). Values are in
    the units of the scaled reference (rad/s for w, m/s^2 for f and a_z)."""

    # Off: the MCA reads the reference as it is.
    enabled: bool = True
    # A jump from the last output larger than this, per channel, is a spike candidate. At
    # the default scales 10 m/s^2 is 2 g of the vehicle in 10 ms: more than any training
    # flight or drive changes in one period (5.8), less than a touchdown transient (7-8 g).
    spike_thresholds: list[float] = dataclasses.field(
        default_factory=lambda: [0.3, 0.3, 0.3, 10.0, 10.0, 10.0]
    )
    # Periods a spike candidate is held before it is taken for a real jump (30 ms at
    # 100 Hz: a one-frame glitch of a 60 Hz game spans two periods).
    spike_samples: int = 3
    # The largest change of the output in one period, per channel.
    max_steps: list[float] = dataclasses.field(
        default_factory=lambda: [0.1, 0.1, 0.1, 6.0, 2.0, 4.0]
    )
    # All channels unchanged this long (after a moving stream): frozen, s. 0: never.
    frozen_s: float = 0.5
    # Fade out on a freeze and back in after it, and cross-fade over a reset, s.
    fade_s: float = 1.0
    # A reset or teleport: at least `reset_channels` channels jump at once, each by more
    # than `reset_factor` times its recent RMS change per period (over about 1 s) and more
    # than its `reset_floors` entry. The output then cross-fades from where it was to the
    # stream over `fade_s`. 0 channels: never. On the training flights and drives no period
    # comes near: a single channel's jump (an afterburner lit, a touchdown) is no reset.
    reset_channels: int = 3
    reset_factor: float = 20.0
    reset_floors: list[float] = dataclasses.field(
        default_factory=lambda: [0.02, 0.02, 0.02, 0.3, 0.3, 0.3]
    )

    def validate(self) -> None:
        """Raises ValueError for a setting outside its range."""
        check_config_numbers(self)
        for name in ("spike_thresholds", "max_steps", "reset_floors"):
            values = getattr(self, name)
            if len(values) != NUM_CHANNELS or min(values) <= 0:
                raise ValueError(
                    f"PlausibilityConfig.{name} needs {NUM_CHANNELS} positive values; got {values}"
                )
        if self.spike_samples < 0:
            raise ValueError(
                f"PlausibilityConfig.spike_samples must be >= 0; got {self.spike_samples}"
            )
        if not 0 <= self.reset_channels <= NUM_CHANNELS or self.reset_factor <= 0:
            raise ValueError(
                f"PlausibilityConfig: reset_channels in [0, {NUM_CHANNELS}] and reset_factor > "
                f"0; got {self.reset_channels}, {self.reset_factor}"
            )
        if self.frozen_s < 0 or self.fade_s <= 0:
            raise ValueError(
                f"PlausibilityConfig: frozen_s >= 0 and fade_s > 0; got {self.frozen_s}, "
                f"{self.fade_s}"
            )


# Layout of the guard's state (a flat list of floats, `initial_state`):
#   [0:6] the last output (before the fade), [6:12] each channel's held periods,
#   [12:18] the last raw sample, [18:24] each channel's recent mean square change per
#   period, [24:30] the output a reset cross-fades from, then the scalars below.
_OUT, _HELD, _RAW, _MS, _FROM = (k * NUM_CHANNELS for k in range(5))
_SCALARS = 5 * NUM_CHANNELS
(
    _STARTED,  # 0 before the first sample
    _UNCHANGED,  # periods every channel has repeated exactly
    _ACTIVITY,  # share of recent periods in which the raw sample changed (running mean)
    _FADE,  # fade weight, 0 (faded out) to 1
    _FROZEN,  # 1 while frozen
    _SPIKES,  # spike periods held (any channel)
    _STEPPED,  # periods in which the step bound acted (any channel)
    _FROZEN_EVENTS,  # freezes seen
    _FROZEN_PERIODS,  # periods frozen
    _NON_FINITE,  # periods with a channel not finite
    _MOVING,  # the activity when the current run of unchanged periods began
    _CROSS,  # periods left of a reset's cross-fade
    _RESETS,  # resets seen
    _REACTION,  # the reaction of the last period (index in REACTIONS)
) = range(_SCALARS, _SCALARS + 14)
STATE_SIZE = _SCALARS + 14
# What the guard did in a period, by index (a trajectory's `plausibility` column): nothing,
# a channel held as a spike, the step bound, the fade of a freeze (out, held out or back
# in), a reset's cross-fade; the first that applies in this order: reset, frozen, spike, step.
REACTIONS = ("none", "spike", "step", "fade", "reset")
# The time constant of each channel's recent mean square change, s.
_CHANGE_WINDOW_S = 1.0

# The counts of a run, by name, for the summary's `plausibility` block, each with its slot
# in the state (in periods or events; the summary converts the frozen periods to seconds).
_COUNTED = {
    "spike_periods": _SPIKES,
    "step_bounded_periods": _STEPPED,
    "frozen_events": _FROZEN_EVENTS,
    "frozen_periods": _FROZEN_PERIODS,
    "non_finite_periods": _NON_FINITE,
    "resets": _RESETS,
}
COUNTS = tuple(_COUNTED)


def initial_state() -> list[float]:
    """The guard's state before its first sample."""
    state = [0.0] * STATE_SIZE
    state[_FADE] = 1.0
    return state


def _smoothstep(w: float) -> float:
    return w * w * (3.0 - 2.0 * w)


def guard_step(
    state: list[float], raw, time_step: float, config: PlausibilityConfig
) -> list[float]:
    """The guarded reference (6 floats) for the raw sample `raw` (6), updating `state` in
    place. `time_step` is the control period, s."""
    n = NUM_CHANNELS
    raw = [float(v) for v in raw]
    if not state[_STARTED]:
        state[_STARTED] = 1.0
        first = [v if math.isfinite(v) else 0.0 for v in raw]
        state[_OUT : _OUT + n] = first
        state[_RAW : _RAW + n] = first
        if len(first) != n or any(not math.isfinite(v) for v in raw):
            state[_NON_FINITE] += 1
        return list(first)
    finite = [math.isfinite(v) for v in raw]
    if not all(finite):
        state[_NON_FINITE] += 1
    # frozen: every channel bit for bit the period before, after a moving stream
    unchanged = all(
        f and v == r for f, v, r in zip(finite, raw, state[_RAW : _RAW + n], strict=True)
    )
    window = max(config.frozen_s / time_step, 1.0)
    if unchanged:
        if state[_UNCHANGED] == 0:
            state[_MOVING] = state[_ACTIVITY]  # how the stream moved before this run
        state[_UNCHANGED] += 1
        reached = config.frozen_s > 0 and state[_UNCHANGED] * time_step >= config.frozen_s - 1e-9
        if reached and not state[_FROZEN] and state[_MOVING] >= 0.5:
            state[_FROZEN] = 1.0
            state[_FROZEN_EVENTS] += 1
    else:
        state[_UNCHANGED] = 0.0
        state[_FROZEN] = 0.0
    # the share of recent periods (about one frozen_s window) in which the stream changed
    state[_ACTIVITY] += ((0.0 if unchanged else 1.0) - state[_ACTIVITY]) / window
    if state[_FROZEN]:
        state[_FROZEN_PERIODS] += 1
    # a reset: several channels jump at once, far beyond their recent changes
    alpha = min(time_step / _CHANGE_WINDOW_S, 1.0)
    jumped = 0
    for i in range(n):
        if not finite[i]:
            continue
        change = raw[i] - state[_RAW + i]
        bound = max(config.reset_factor * math.sqrt(state[_MS + i]), config.reset_floors[i])
        if abs(change) > bound:
            jumped += 1
        else:  # a jump does not raise the bound for the next one
            state[_MS + i] += alpha * (change * change - state[_MS + i])
        state[_RAW + i] = raw[i]
    if config.reset_channels and jumped >= config.reset_channels and not state[_FROZEN]:
        state[_CROSS] = max(round(config.fade_s / time_step), 1)
        state[_FROM : _FROM + n] = state[_OUT : _OUT + n]
        state[_RESETS] += 1
    if state[_CROSS]:
        state[_REACTION] = REACTIONS.index("reset")
        return _cross_fade(state, raw, finite, time_step, config)
    # spikes and the step bound, channel by channel
    spiked = stepped = False
    for i in range(n):
        last = state[_OUT + i]
        target = raw[i] if finite[i] else last
        jump = abs(target - last) if finite[i] else math.inf
        if jump > config.spike_thresholds[i]:
            if state[_HELD + i] < config.spike_samples:
                state[_HELD + i] += 1
                spiked = True
                continue  # held at the last output
            # held long enough: a real jump, followed (the count stays up until the output
            # has caught up, so the ramp is not held again)
        else:
            state[_HELD + i] = 0.0
        if not finite[i]:
            continue  # held past spike_samples: nothing to follow
        step = config.max_steps[i]
        if target - last > step:
            target, stepped = last + step, True
        elif last - target > step:
            target, stepped = last - step, True
        state[_OUT + i] = target
    state[_SPIKES] += spiked
    state[_STEPPED] += stepped
    reaction = "spike" if spiked else "step" if stepped else "none"
    if state[_FROZEN] or state[_FADE] < 1.0:
        reaction = "fade"
    state[_REACTION] = REACTIONS.index(reaction)
    return _faded(state, time_step, config)


def _faded(state: list[float], time_step: float, config: PlausibilityConfig) -> list[float]:
    """The output after the freeze's fade: out while frozen, back in after."""
    rate = time_step / config.fade_s
    if state[_FROZEN]:
        state[_FADE] = max(state[_FADE] - rate, 0.0)
    else:
        state[_FADE] = min(state[_FADE] + rate, 1.0)
    weight = _smoothstep(state[_FADE])
    return [weight * v for v in state[_OUT : _OUT + NUM_CHANNELS]]


def _cross_fade(state, raw, finite, time_step: float, config: PlausibilityConfig) -> list[float]:
    """One period of a reset's cross-fade from where the output was to the stream (a
    channel that is not finite holds)."""
    total = max(round(config.fade_s / time_step), 1)
    weight = _smoothstep((total - state[_CROSS] + 1) / total)
    state[_CROSS] -= 1
    for i in range(NUM_CHANNELS):
        state[_HELD + i] = 0.0
        if finite[i]:
            start = state[_FROM + i]
            state[_OUT + i] = start + weight * (raw[i] - start)
    return _faded(state, time_step, config)


def counts(state: list[float]) -> dict[str, int]:
    """The guard's counts so far (`COUNTS`), in control periods and events."""
    return {name: int(state[i]) for name, i in _COUNTED.items()}


def reaction(state: list[float]) -> str:
    """What the guard did in its last period (`REACTIONS`)."""
    return REACTIONS[int(state[_REACTION])]


def frozen(state: list[float]) -> bool:
    """Whether the stream counts as frozen now."""
    return bool(state[_FROZEN])


def summary_block(state: list[float], time_step: float) -> dict:
    """The summary's `plausibility` block: `counts`, with the time frozen in seconds
    (`frozen_s`) in place of its periods."""
    block = counts(state)
    block["frozen_s"] = round(block.pop("frozen_periods") * time_step, 6)
    return block


__all__ = [
    "COUNTS",
    "REACTIONS",
    "STATE_SIZE",
    "PlausibilityConfig",
    "counts",
    "frozen",
    "guard_step",
    "initial_state",
    "reaction",
    "summary_block",
]
