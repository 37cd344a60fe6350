"""Where an operator's commands come from while a live run goes on (`live.controls`):

    UdpControlPort   one command per datagram on a local UDP port, answered to its sender;
                     senders not allowed are counted and ignored
    KeyboardControl  keys in the terminal running the loop (+ - intensity, space
                     pause/resume, h wash out, x or Esc emergency stop)
    MeshcatControls  the operator page: sliders and buttons in Meshcat beside the 3D view

Each has `name`, `poll()` -> [(command text, answer callback or None)], `show(settings,
mode)` (the settings as they are now, for a source that displays them) and `close()`. The
console (`live.operator.OperatorConsole`) polls them once per control period, after the
period's command has gone out. Nothing here blocks.
"""

from __future__ import annotations

import contextlib
import ipaddress
import os
import select
import socket
from collections.abc import Callable

from mca_drake.live.controls import CONTROL_SETTINGS, ControlsConfig, initial_settings
from mca_drake.live.endpoints import parse_endpoint
from mca_drake.live.receiver import allowed_senders

Answer = Callable[[str], None]
# Datagrams read per poll at most: a flood cannot hold up the loop.
MAX_DATAGRAMS_PER_POLL = 16
# Longest command datagram read, bytes.
MAX_COMMAND_BYTES = 256


class UdpControlPort:
    """The UDP control port at `address` ("HOST:PORT"; port 0: any free one, `address`
    tells which) of `ControlsConfig.udp`: one command per datagram (ASCII,
    `live.controls` grammar), each answered with one datagram to its sender; datagrams from
    senders not in `allowed_senders` are counted (`foreign`) and not answered."""

    def __init__(self, address: str, allowed: list[str]):
        where, _, number = address.rpartition(":")
        host, _ = parse_endpoint(where, "control port")
        if not number.isdigit() or int(number) > 65535:
            raise ValueError(f"control port {address!r} is not HOST:PORT (port 0: any free one)")
        port = int(number)
        self._allowed = allowed_senders(allowed)
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._socket.bind((host, port))
        except OSError as error:
            self._socket.close()
            raise ValueError(f"cannot listen for controls on udp://{address}: {error}") from None
        self._socket.setblocking(False)
        self.foreign = 0
        self.name = "udp://{}:{}".format(*self.address)

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port)."""
        return self._socket.getsockname()

    def _allowed_sender(self, sender: tuple[str, int]) -> bool:
        ip = int(ipaddress.IPv4Address(sender[0]))
        return any(ip == a and (p is None or p == sender[1]) for a, p in self._allowed)

    def poll(self) -> list[tuple[str, Answer | None]]:
        """The commands waiting in the socket (at most MAX_DATAGRAMS_PER_POLL)."""
        commands = []
        for _ in range(MAX_DATAGRAMS_PER_POLL):
            try:
                data, sender = self._socket.recvfrom(MAX_COMMAND_BYTES)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # an ICMP error from an earlier answer: not a command
                continue
            if not self._allowed_sender(sender):
                self.foreign += 1
                continue
            text = data.decode("ascii", errors="replace").strip()
            commands.append((text, self._answer_to(sender)))
        return commands

    def _answer_to(self, sender: tuple[str, int]) -> Answer:
        def answer(text: str) -> None:
            try:
                self._socket.sendto((text + "\n").encode("ascii", "replace"), sender)
            except OSError:
                pass  # an answer that cannot go out does not stop the rig

        return answer

    def show(self, settings: list[float], mode: int) -> None:
        """Nothing to show: the port answers each command."""

    def close(self) -> None:
        """Closes the socket."""
        self._socket.close()


# Keys and the commands they send; "+" and "-" step the intensity (`keyboard_step`).
KEYS = {" ": "toggle", "p": "toggle", "h": "washout", "r": "resume", "x": "estop", "\x1b": "estop"}


class KeyboardControl:
    """Keys pressed in the terminal of file descriptor `fd` (the loop's stdin). While it is
    open the terminal reads keys one by one without echo (Ctrl-C still ends the run); it is
    restored on `close`. Escape sequences (arrow keys) are ignored; a lone Esc is an
    emergency stop."""

    name = "keyboard"

    def __init__(self, fd: int, step: float):
        self._fd, self._step = fd, step
        self._intensity = 1.0
        self._saved = None
        if os.isatty(fd):
            # POSIX terminals only: where a terminal is given
            import termios
            import tty

            self._saved = termios.tcgetattr(fd)
            tty.setcbreak(fd)

    def poll(self) -> list[tuple[str, Answer | None]]:
        """The commands of the keys pressed since the last poll."""
        ready, _, _ = select.select([self._fd], [], [], 0)
        if not ready:
            return []
        try:
            keys = os.read(self._fd, 64).decode("ascii", errors="ignore")
        except OSError:
            return []
        if keys.startswith("\x1b") and len(keys) > 1:
            return []  # an escape sequence: an arrow or function key
        commands = []
        for key in keys:
            if key in "+=-":
                sign = -1 if key == "-" else 1
                self._intensity = min(1.0, max(0.0, self._intensity + sign * self._step))
                commands.append((f"intensity {self._intensity:.3g}", None))
            elif key.lower() in KEYS:
                commands.append((KEYS[key.lower()], None))
        return commands

    def show(self, settings: list[float], mode: int) -> None:
        """Keeps + and - stepping from the intensity as it is now."""
        self._intensity = settings[0]

    def close(self) -> None:
        """Gives the terminal back as it was."""
        if self._saved is not None:
            import termios  # POSIX terminals only: where a terminal was given

            termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)
            self._saved = None


# The operator page's buttons: label -> command.
BUTTONS = {"Pause / resume": "toggle", "Wash out home": "washout", "EMERGENCY STOP": "estop"}
# Browser keys for the buttons (Meshcat's keycodes, pressed in the page).
BUTTON_KEYS = {"Pause / resume": "Space", "Wash out home": "KeyH", "EMERGENCY STOP": "Escape"}
SLIDER_STEP = 0.05


def slider_name(setting: str) -> str:
    """The operator page's slider of a setting: "intensity" or "gain f_x+"."""
    return setting if setting == "intensity" else f"gain {setting}"


class MeshcatControls:
    """The operator page in `meshcat`: a slider per setting (intensity in [0, 1], gains in
    [0, max_gain]) and the buttons of BUTTONS (with BUTTON_KEYS in the page). A slider
    moved by the operator sends its setting's command; a setting changed elsewhere moves its
    slider (`show`), so the page shows what the rig does."""

    name = "meshcat"

    def __init__(self, meshcat, config: ControlsConfig, settings: list[float]):
        self._meshcat = meshcat
        self._values = dict(zip(CONTROL_SETTINGS, settings, strict=True))
        for setting, value in self._values.items():
            top = 1.0 if setting == "intensity" else config.max_gain
            meshcat.AddSlider(slider_name(setting), 0.0, top, SLIDER_STEP, value)
        self._clicks = {}
        for label in BUTTONS:
            meshcat.AddButton(label, BUTTON_KEYS[label])
            self._clicks[label] = 0

    def poll(self) -> list[tuple[str, Answer | None]]:
        """The commands of the sliders moved and the buttons clicked since the last poll."""
        commands = []
        for setting, seen in self._values.items():
            value = self._meshcat.GetSliderValue(slider_name(setting))
            if abs(value - seen) > 1e-9:
                self._values[setting] = value
                verb = "intensity" if setting == "intensity" else f"gain {setting}"
                commands.append((f"{verb} {value:.6g}", None))
        for label, seen in self._clicks.items():
            clicks = self._meshcat.GetButtonClicks(label)
            if clicks != seen:
                self._clicks[label] = clicks
                commands.append((BUTTONS[label], None))
        return commands

    def show(self, settings: list[float], mode: int) -> None:
        """Moves the sliders whose setting changed elsewhere."""
        for setting, value in zip(CONTROL_SETTINGS, settings, strict=True):
            if abs(value - self._values[setting]) > 1e-9:
                self._values[setting] = value
                self._meshcat.SetSliderValue(slider_name(setting), value)

    def close(self) -> None:
        """Takes the controls off the page (the 3D view stays)."""
        for setting in CONTROL_SETTINGS:
            self._meshcat.DeleteSlider(slider_name(setting))
        for label in BUTTONS:
            self._meshcat.DeleteButton(label)


@contextlib.contextmanager
def control_inputs(config: ControlsConfig, meshcat=None, keyboard_fd: int | None = None):
    """The sources `config` asks for (none when it is not `enabled`), open for the `with`
    block and closed after it (the terminal given back): the UDP port (`udp`), the
    keyboard (`keyboard`, when `keyboard_fd` is a terminal) and the operator page
    (`meshcat`, when a Meshcat is given)."""
    with contextlib.ExitStack() as stack:
        sources = []
        if not config.enabled:
            yield sources
            return

        def opened(source):
            stack.callback(source.close)
            sources.append(source)

        if config.udp:
            opened(UdpControlPort(config.udp, config.allowed_senders))
        if config.keyboard and keyboard_fd is not None and os.isatty(keyboard_fd):
            opened(KeyboardControl(keyboard_fd, config.keyboard_step))
        if config.meshcat and meshcat is not None:
            opened(MeshcatControls(meshcat, config, initial_settings(config)))
        yield sources


__all__ = [
    "BUTTONS",
    "BUTTON_KEYS",
    "KEYS",
    "KeyboardControl",
    "MeshcatControls",
    "UdpControlPort",
    "control_inputs",
    "slider_name",
]
