"""Operator controls of a live run: what an operator may change while the rig runs, the
commands that change it, and how a change reaches the reference without a step.

The settings (`CONTROL_SETTINGS`) are a master intensity and a gain per channel, surge with
separate gains for acceleration (`f_x+`, f_x > 0) and braking (`f_x-`, f_x < 0). The MCA
cues the scaled reference

    y_mca,i = fade * intensity * g_i * y_i,   g_f_x = gain f_x+ if f_x >= 0 else gain f_x-

(continuous in y: both surge gains meet at f_x = 0). Each setting moves toward the value the
operator asked for at most 1 / `ramp_s` per second, and `fade` (1 running, 0 paused) the
same way, so no command steps the reference: the MCA sees a ramp, and its clamp keeps the
robot inside its limits whatever the gains.

Modes (`MODES`): `run`; `pause` (the cues fade out; the MCA keeps the cabin at its neutral
cue until `resume` fades them back in); `washout` (the supervisor blends to its wash-out to
the home pose, as in a fault, until `resume`); `estop` (latched for the rest of the run:
the supervisor brakes every joint to rest at its acceleration limits).

Commands, one per line (what the UDP control port reads, one per datagram, and what the
keyboard and the operator page send):

    intensity V      V in [0, 1]
    gain CH V        CH one of w_x w_y w_z f_x f_x+ f_x- f_y a_z (f_x sets both); V in
                     [0, max_gain]
    pause | resume | toggle (pause <-> resume) | washout | estop | status

Every command gets an answer (`apply_command`): what it changed, or why it was refused.
"""

import dataclasses
import math

from mca_drake.input_checks import check_config_numbers

# The operator's settings, in the order of the console's state and `settings` port.
CONTROL_SETTINGS = ("intensity", "w_x", "w_y", "w_z", "f_x+", "f_x-", "f_y", "a_z")
MODES = ("run", "pause", "washout", "estop")
RUN, PAUSE, WASHOUT, ESTOP = range(len(MODES))
# The settings' index per reference channel; surge's is its f_x+ (f_x- follows it).
_CHANNEL_SETTING = (1, 2, 3, 4, 6, 7)
_SURGE_POSITIVE, _SURGE_NEGATIVE = 4, 5
_GAIN_NAMES = {"w_x", "w_y", "w_z", "f_x", "f_x+", "f_x-", "f_y", "a_z"}


@dataclasses.dataclass
class ControlsConfig:
    """The operator's controls of a live run and where they come from."""

    # False: no console in the loop (the MCA cues the guarded reference as it is; the
    # supervisor's own wash-out and the hardware stop remain).
    enabled: bool = True
    # Time (s) a setting takes to move by 1.0 (intensity 1 -> 0, a gain 1 -> 2), and the
    # fade of pause/resume from 1 to 0: every change is a ramp this steep, never a step.
    ramp_s: float = 1.0
    # The largest gain a channel may be given (the intensity's is 1).
    max_gain: float = 2.0
    # The settings the run starts with: the intensity and gains by name (CONTROL_SETTINGS;
    # "f_x" sets both surge gains), e.g. {"f_x-": 0.7} for gentler braking.
    intensity: float = 1.0
    gains: dict[str, float] = dataclasses.field(default_factory=dict)
    # The UDP control port, "HOST:PORT" (one command per datagram, answered); "": none.
    udp: str = ""
    # Who may send commands to it: "HOST" or "HOST:PORT" (IPv4); others are counted and
    # ignored. Loopback only unless the scenario says otherwise.
    allowed_senders: list[str] = dataclasses.field(default_factory=lambda: ["127.0.0.1"])
    # Keys in the terminal running the loop (when it is one): + and - intensity, space
    # pause/resume, h wash out, x or Esc emergency stop.
    keyboard: bool = True
    # Intensity change per key press.
    keyboard_step: float = 0.1
    # The operator page: sliders and buttons beside the 3D view, when the run draws in
    # Meshcat.
    meshcat: bool = True

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        if not self.ramp_s > 0:
            raise ValueError("ControlsConfig.ramp_s must be positive")
        if not self.max_gain >= 1:
            raise ValueError("ControlsConfig.max_gain must be at least 1")
        if not 0 < self.keyboard_step <= 1:
            raise ValueError("ControlsConfig.keyboard_step must be in (0, 1]")
        initial_settings(self)  # raises for a bad intensity or gain
        if self.udp:
            # the receiver loads pydrake: only for a scenario with a control port
            from mca_drake.live.endpoints import parse_endpoint
            from mca_drake.live.receiver import allowed_senders

            _, port = parse_endpoint(self.udp, "ControlsConfig.udp")
            if port is None:
                raise ValueError(f"ControlsConfig.udp {self.udp!r} needs a port: HOST:PORT")
            try:
                allowed_senders(self.allowed_senders)
            except ValueError as err:
                raise ValueError(f"ControlsConfig.allowed_senders: {err}") from None


def initial_settings(config: ControlsConfig) -> list[float]:
    """The settings a run starts with (CONTROL_SETTINGS order), from `config`.

    Raises:
        ValueError: an intensity outside [0, 1], an unknown gain name or a gain outside
            [0, max_gain].
    """
    settings = [1.0] * len(CONTROL_SETTINGS)
    for text in [f"intensity {config.intensity}"] + [
        f"gain {name} {value}" for name, value in config.gains.items()
    ]:
        _, why = _set_value(settings, text.split(), config.max_gain)
        if why:
            raise ValueError(f"ControlsConfig: {why}")
    return settings


def _number(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def _set_value(targets: list[float], words: list[str], max_gain: float) -> tuple[str, str]:
    """Sets the target of `intensity V` or `gain CH V` in `targets`; (answer, refusal)."""
    if words[0] == "intensity" and len(words) == 2:
        value = _number(words[1])
        if value is None or not 0 <= value <= 1:
            return "", f"intensity must be a number in [0, 1]; got {words[1]!r}"
        targets[0] = value
        return f"intensity -> {value:g}", ""
    if words[0] == "gain" and len(words) == 3:
        name, value = words[1], _number(words[2])
        if name not in _GAIN_NAMES:
            return "", f"no channel {name!r}; one of {' '.join(sorted(_GAIN_NAMES))}"
        if value is None or not 0 <= value <= max_gain:
            return "", f"gain must be a number in [0, {max_gain:g}]; got {words[2]!r}"
        names = ("f_x+", "f_x-") if name == "f_x" else (name,)
        for each in names:
            targets[CONTROL_SETTINGS.index(each)] = value
        return f"gain {name} -> {value:g}", ""
    return "", f"'{words[0]}' takes {'V' if words[0] == 'intensity' else 'CH V'}"


def apply_command(
    targets: list[float], mode: int, text: str, max_gain: float
) -> tuple[list[float], int, str, bool]:
    """One operator command applied to the settings' targets and the mode.

    Args:
        targets: the settings asked for so far (CONTROL_SETTINGS order); not changed.
        mode: the current mode (index in MODES).
        text: the command (module docstring), e.g. "gain f_x- 0.7".
        max_gain: the largest gain allowed.

    Returns:
        (targets, mode, answer, accepted): the new targets and mode, the answer for the
        operator ("intensity -> 0.5", or why the command was refused) and whether it was
        taken.
    """
    targets = list(targets)
    words = text.strip().lower().split()
    if not words:
        return targets, mode, "refused: empty command", False
    verb = words[0]
    if verb in ("intensity", "gain"):
        answer, why = _set_value(targets, words, max_gain)
        return targets, mode, answer or f"refused: {why}", not why
    if len(words) != 1 or verb not in ("pause", "resume", "toggle", "washout", "estop", "status"):
        return targets, mode, f"refused: unknown command {text.strip()[:60]!r}", False
    if verb == "status":
        return targets, mode, status_text(targets, mode), True
    if verb == "toggle":
        verb = "pause" if mode == RUN else "resume"
    if mode == ESTOP:
        return targets, mode, "refused: the emergency stop holds until the run ends", False
    new = {"pause": PAUSE, "resume": RUN, "washout": WASHOUT, "estop": ESTOP}[verb]
    return targets, new, f"{MODES[mode]} -> {MODES[new]}", True


def status_text(settings: list[float], mode: int) -> str:
    """The mode and settings as one line, e.g. "run intensity 1 w_x 1 ... a_z 1"."""
    values = " ".join(f"{n} {v:g}" for n, v in zip(CONTROL_SETTINGS, settings, strict=True))
    return f"{MODES[mode]} {values}"


def fade_target(mode: int) -> float:
    """Where the fade goes in `mode`: 1 running, 0 otherwise."""
    return 1.0 if mode == RUN else 0.0


def ramp(current: float, target: float, max_step: float) -> float:
    """`current` moved toward `target` by at most `max_step`."""
    return min(max(target, current - max_step), current + max_step)


def scale_reference(reference: list[float], settings: list[float], fade: float) -> list[float]:
    """The reference the MCA cues under `settings` (CONTROL_SETTINGS order) and `fade`
    (module docstring); plain Python floats: this runs between a sample and its command."""
    scale = fade * settings[0]
    out = [scale * settings[k] * y for k, y in zip(_CHANNEL_SETTING, reference, strict=True)]
    if reference[3] < 0:
        out[3] = scale * settings[_SURGE_NEGATIVE] * reference[3]
    return out


__all__ = [
    "CONTROL_SETTINGS",
    "ESTOP",
    "MODES",
    "PAUSE",
    "RUN",
    "WASHOUT",
    "ControlsConfig",
    "apply_command",
    "fade_target",
    "initial_settings",
    "ramp",
    "scale_reference",
    "status_text",
]
