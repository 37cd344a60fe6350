"""Operator controls of a live run: the command grammar, the ramps every change follows, the
operator's wash-out and emergency stop at the supervisor, and the three sources of commands
(UDP port, the terminal's keys, the operator page in Meshcat)."""

from __future__ import annotations

import base64
import math
import os
import socket
import termios
import threading
import time

import msgpack
import numpy as np
import pytest
from conftest import free_udp_port
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from test_live_supervisor import KR500, push, run

from mca_drake.conventions import CONTROL_PERIOD_S as H
from mca_drake.live.control_inputs import (
    BUTTONS,
    KeyboardControl,
    MeshcatControls,
    UdpControlPort,
    slider_name,
)
from mca_drake.live.controls import (
    CONTROL_SETTINGS,
    ESTOP,
    PAUSE,
    RUN,
    WASHOUT,
    ControlsConfig,
    apply_command,
    initial_settings,
    scale_reference,
)
from mca_drake.live.operator import OperatorConsole
from mca_drake.platforms.usage import joint_usage

ONES = [1.0] * len(CONTROL_SETTINGS)


def test_commands_set_what_they_name_and_refuse_the_rest():
    targets, mode, said, ok = apply_command(ONES, RUN, "intensity 0.4", 2.0)
    assert ok and targets[0] == 0.4 and mode == RUN and said == "intensity -> 0.4"
    targets, _, _, ok = apply_command(ONES, RUN, "GAIN f_x 0.5", 2.0)  # both surge gains
    assert ok and targets[4] == targets[5] == 0.5 and targets[1:4] == [1.0] * 3
    targets, _, _, ok = apply_command(ONES, RUN, "gain f_x- 0.7", 2.0)
    assert ok and (targets[4], targets[5]) == (1.0, 0.7)
    for bad in ("intensity 1.5", "intensity nan", "gain f_z 1", "gain w_x 3", "gain w_x",
                "fly", "", "pause now"):  # fmt: skip
        targets, mode, said, ok = apply_command(ONES, RUN, bad, 2.0)
        assert not ok and said.startswith("refused") and targets == ONES and mode == RUN, bad
    _, mode, _, _ = apply_command(ONES, RUN, "toggle", 2.0)
    assert mode == PAUSE
    _, mode, _, _ = apply_command(ONES, PAUSE, "toggle", 2.0)
    assert mode == RUN
    _, mode, said, ok = apply_command(ONES, RUN, "status", 2.0)
    assert ok and mode == RUN and said.startswith("run intensity 1 w_x 1")


def test_the_emergency_stop_holds_until_the_run_ends():
    _, mode, _, _ = apply_command(ONES, WASHOUT, "estop", 2.0)
    assert mode == ESTOP
    for command in ("resume", "toggle", "pause", "washout"):
        _, mode, said, ok = apply_command(ONES, ESTOP, command, 2.0)
        assert mode == ESTOP and not ok and "emergency stop" in said


def test_the_run_starts_with_the_scenarios_settings_and_refuses_bad_ones():
    settings = initial_settings(ControlsConfig(intensity=0.5, gains={"f_x-": 0.6, "w_y": 1.2}))
    assert settings == [0.5, 1.0, 1.2, 1.0, 1.0, 0.6, 1.0, 1.0]
    for bad in (
        ControlsConfig(intensity=1.2),
        ControlsConfig(gains={"f_z": 1.0}),
        ControlsConfig(gains={"a_z": 2.5}),
        ControlsConfig(ramp_s=0.0),
        ControlsConfig(udp="127.0.0.1"),
        ControlsConfig(udp="127.0.0.1:6000", allowed_senders=["somewhere"]),
    ):
        with pytest.raises(ValueError, match="ControlsConfig"):
            bad.validate()


def test_the_cued_reference_is_intensity_times_each_channels_gain():
    settings = [0.8, 0.5, 1.0, 1.5, 1.2, 0.4, 0.9, 0.0]
    gains = np.array([0.5, 1.0, 1.5, 1.2, 0.9, 0.0])
    rng = np.random.default_rng(3)
    for _ in range(50):
        y = rng.normal(size=6)
        expected = 0.7 * 0.8 * gains * y
        if y[3] < 0:  # braking: the surge's negative gain
            expected[3] = 0.7 * 0.8 * 0.4 * y[3]
        assert np.allclose(scale_reference(y.tolist(), settings, 0.7), expected, atol=1e-15)


class ScriptedCommands:
    """A command source that gives `script[t]` (command texts) at loop time t."""

    name = "script"

    def __init__(self, script: dict[float, list[str]], clock):
        self._script, self._clock = dict(script), clock
        self.shown = []

    def poll(self):
        t = self._clock()
        due = [k for k in self._script if k <= t + 1e-9]
        return [(text, None) for k in sorted(due) for text in self._script.pop(k)]

    def show(self, settings, mode):
        self.shown.append((list(settings), mode))

    def close(self):
        pass


def console_run(script, reference, t_end, config=None):
    """The console alone on a constant reference; (times, scaled references, modes)."""
    builder = DiagramBuilder()
    holder = {}
    source = ScriptedCommands(script, lambda: holder["context"].get_time())
    console = builder.AddSystem(OperatorConsole(config, [source], H, update_offset_s=2.5e-5))
    constant = builder.AddSystem(ConstantVectorSource(np.asarray(reference, float)))
    builder.Connect(constant.get_output_port(), console.GetInputPort("reference"))
    simulator = Simulator(builder.Build())
    holder["context"] = simulator.get_context()
    context = console.GetMyContextFromRoot(simulator.get_context())
    times, outputs, modes = [], [], []
    for k in range(round(t_end / H) + 1):
        simulator.AdvanceTo(k * H)
        times.append(k * H)
        outputs.append(console.GetOutputPort("scaled_reference").Eval(context).copy())
        modes.append(int(console.GetOutputPort("mode").Eval(context)[0]))
    return np.array(times), np.array(outputs), np.array(modes), console, context, source


def test_every_change_reaches_the_reference_as_a_ramp_never_a_step():
    y = np.array([0.1, -0.2, 0.05, -3.0, 1.0, 2.0])
    script = {
        0.5: ["intensity 0.2"],
        1.5: ["gain f_x- 2.0"],
        2.5: ["pause"],
        4.0: ["resume"],
        5.5: ["intensity 0"],
    }
    ramp_s = 0.8
    _times, out, modes, console, context, source = console_run(
        script, y, 7.0, ControlsConfig(ramp_s=ramp_s)
    )
    # no period changes any channel by more than the ramp allows: 1/ramp_s per second of
    # each factor (intensity, gain, fade), so at most |y| max_gain h / ramp_s for any one
    largest = np.abs(y) * 2.0 * H / ramp_s + 1e-12
    assert np.all(np.abs(np.diff(out, axis=0)) <= largest)
    at = lambda t: out[round(t / H)]  # noqa: E731
    assert np.allclose(at(0.4), y)
    # 1 -> 0.2 takes 0.8 * 0.8 s = 0.64 s, with the command read in the period after 0.5 s
    assert np.allclose(at(0.5 + 0.64 + 2 * H), 0.2 * y)
    assert not np.allclose(at(0.5 + 0.64 - 2 * H), 0.2 * y)
    braking = 0.2 * y.copy()
    braking[3] = 0.2 * 2.0 * y[3]  # f_x < 0: the braking gain
    assert np.allclose(at(2.4), braking)
    assert np.allclose(at(2.5 + ramp_s + 2 * H), 0.0)  # paused: faded out
    assert modes[round(3.0 / H)] == PAUSE
    assert np.allclose(at(4.0 + ramp_s + 2 * H), braking)  # resumed: faded back in
    assert np.allclose(at(6.9), 0.0)
    log = console.summary(context)["log"]
    assert [e["command"] for e in log] == [t for k in sorted(script) for t in script[k]]
    assert all(abs(e["t_s"] - k) <= H + 1e-9 for e, k in zip(log, sorted(script), strict=True))
    # every source sees the settings asked for after each change
    assert source.shown[0] == ([0.2] + [1.0] * 7, RUN)


def test_the_emergency_stop_brakes_every_joint_to_rest_within_its_limits():
    t_stop = 0.6  # pushed for 0.6 s at 1 rad/s^2 (or less where a limit is near)
    operator = lambda t: ESTOP if t >= t_stop - 1e-9 else RUN  # noqa: E731
    supervisor, context, states, commands = run(push, lambda t: True, operator=operator, t_end=3.0)
    n = 6
    k = round(t_stop / H)
    qd, qdd_max = states[k, n:], KR500.qdd_max
    assert np.all(np.abs(qd) > 0.3)
    # the brake: every joint's velocity to zero in one period where its limit allows
    for j in range(k, k + 20):
        expected = np.clip(-states[j, n:] / H, -qdd_max, qdd_max)
        assert np.allclose(commands[j], expected, atol=1e-9)
    # at rest after ceil(max |qd| / (qdd_max h)) periods, and there to the end
    periods = math.ceil(np.max(np.abs(qd) / (qdd_max * H)) - 1e-9)
    assert np.all(np.abs(states[k + periods :, n:]) < 1e-12)
    assert np.any(np.abs(states[k + periods - 1, n:]) > 1e-3)
    usage = joint_usage(states[:, :n], states[:, n:], commands, KR500)
    assert usage.violations() == {"q": 0, "qd": 0, "qdd": 0}
    stopped_at, rest_at = supervisor.estop_times(context)
    assert abs(stopped_at - t_stop) <= H + 1e-9
    assert abs(rest_at - (t_stop + periods * H)) <= H + 1e-9
    assert supervisor.health(context)["state"] == 0  # a stop is not a fault


def test_the_operators_wash_out_returns_home_and_resume_rejoins_the_mca():
    operator = lambda t: WASHOUT if 1.0 <= t < 9.0 else RUN  # noqa: E731
    supervisor, context, states, commands = run(push, lambda t: True, operator=operator)
    assert np.max(np.abs(states[100, :6])) > 0.4  # driven away by the MCA
    assert np.max(np.abs(states[890, :6])) < 0.02  # home by the end of the wash-out
    usage = joint_usage(states[:, :6], states[:, 6:], commands, KR500)
    assert usage.violations() == {"q": 0, "qd": 0, "qdd": 0}
    assert supervisor.health(context)["fault_s"] == 0.0 and not supervisor.transitions
    assert supervisor.health(context)["weight"] == 1.0  # rejoined


def wait_for(poll, timeout_s=2.0):
    """`poll()` until it returns something (bounded); its last result."""
    end = time.monotonic() + timeout_s
    while not (got := poll()) and time.monotonic() < end:
        time.sleep(0.005)
    return got


def test_the_udp_port_answers_its_sender_and_ignores_an_intruder():
    port = UdpControlPort("127.0.0.1:0", ["127.0.0.1"])
    operator = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    intruder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        operator.settimeout(2.0)
        intruder.bind(("127.0.0.2", 0))
        intruder.sendto(b"estop", port.address)
        time.sleep(0.05)
        operator.sendto(b"intensity 0.5\n", port.address)
        commands = wait_for(port.poll)
        assert [text for text, _ in commands] == ["intensity 0.5"]
        assert port.foreign == 1
        commands[0][1]("intensity -> 0.5")
        assert operator.recv(256) == b"intensity -> 0.5\n"
    finally:
        for s in (operator, intruder):
            s.close()
        port.close()


def test_a_control_port_that_cannot_listen_says_where():
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    try:
        with pytest.raises(ValueError, match=r"cannot listen for controls on udp://127\.0\.0\.1"):
            UdpControlPort(f"127.0.0.1:{busy.getsockname()[1]}", ["127.0.0.1"])
    finally:
        busy.close()


def test_keys_in_a_terminal_become_commands_and_the_terminal_is_given_back():
    main, terminal = os.openpty()
    try:
        before = termios.tcgetattr(terminal)
        keys = KeyboardControl(terminal, step=0.1)
        assert termios.tcgetattr(terminal) != before  # keys one by one, no echo
        os.write(main, b"--x")
        assert [t for t, _ in wait_for(keys.poll)] == ["intensity 0.9", "intensity 0.8", "estop"]
        os.write(main, b"\x1b[A")  # an arrow key: nothing
        time.sleep(0.05)
        assert keys.poll() == []
        keys.show([0.3] + [1.0] * 7, RUN)  # the intensity changed elsewhere
        os.write(main, b"+ h")
        expected = ["intensity 0.4", "toggle", "washout"]
        assert [t for t, _ in wait_for(keys.poll)] == expected
        keys.close()
        assert termios.tcgetattr(terminal) == before
    finally:
        os.close(main)
        os.close(terminal)


@pytest.fixture(scope="module")
def meshcat():
    from pydrake.geometry import Meshcat, MeshcatParams

    return Meshcat(MeshcatParams(host="localhost"))


def browser_message(meshcat, **message):
    """What the page sends when its control is used (msgpack over the websocket), handed to
    Meshcat as its websocket would (from the thread that made the Meshcat)."""
    meshcat._InjectWebsocketMessage(msgpack.packb(message))
    meshcat.Flush()


def websocket_message(port: int, **message) -> None:
    """Sends `message` to the Meshcat on `port` as a page does: over a websocket (RFC 6455
    handshake, one masked binary frame of msgpack), from any thread."""
    payload = msgpack.packb(message)
    assert len(payload) < 126
    key = base64.b64encode(os.urandom(16)).decode()
    with socket.create_connection(("127.0.0.1", port), timeout=5) as client:
        client.sendall(
            (
                f"GET / HTTP/1.1\r\nHost: localhost:{port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                "Sec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        answer = b""
        while b"\r\n\r\n" not in answer:
            answer += client.recv(4096)
        assert answer.startswith(b"HTTP/1.1 101"), answer[:80]
        mask = os.urandom(4)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
        client.sendall(bytes([0x82, 0x80 | len(payload)]) + mask + masked)
        time.sleep(0.2)  # the server reads the frame before the connection closes


def test_the_operator_page_sends_what_its_sliders_and_buttons_say(meshcat):
    page = MeshcatControls(meshcat, ControlsConfig(), [1.0] * 8)
    try:
        assert page.poll() == []
        browser_message(meshcat, type="slider", name="intensity", value=0.4)
        browser_message(meshcat, type="slider", name=slider_name("f_x-"), value=0.65)
        assert [t for t, _ in page.poll()] == ["intensity 0.4", "gain f_x- 0.65"]
        browser_message(meshcat, type="button", name="EMERGENCY STOP")
        assert [t for t, _ in page.poll()] == ["estop"]
        # a setting changed elsewhere moves its slider, and is not sent back as a command
        page.show([0.7] + [1.0] * 7, RUN)
        assert meshcat.GetSliderValue("intensity") == pytest.approx(0.7)
        assert page.poll() == []
    finally:
        page.close()
    assert not set(meshcat.GetButtonNames()) & set(BUTTONS)


@pytest.mark.parametrize("where", ["udp", "keyboard", "meshcat"])
def test_an_emergency_stop_from_each_input_brings_the_live_robot_to_rest(where, meshcat, tmp_path):
    """A live run (the default DPC cueing a surge oscillation on loopback) stopped 1.5 s in
    from the UDP port, the terminal's keys or the operator page's button."""
    from test_live_loop import live_with_sender, stream_process

    config = ControlsConfig(udp=f"127.0.0.1:{free_udp_port()}" if where == "udp" else "")
    main, terminal = os.openpty()
    page_port = meshcat.port()  # (Meshcat is asked from the thread that made it)

    def press_stop():
        time.sleep(1.5)
        if where == "udp":
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as operator:
                host, port = config.udp.split(":")
                operator.sendto(b"estop", (host, int(port)))
        elif where == "keyboard":
            os.write(main, b"x")
        else:
            websocket_message(page_port, type="button", name="EMERGENCY STOP")

    def stream_and_stop(address, seconds):
        stopper = threading.Thread(target=press_stop, daemon=True)
        stopper.start()
        stream_process(address, seconds)
        stopper.join(timeout=5)

    trajectory = tmp_path / "run.csv"
    try:
        summary = live_with_sender(
            stream_and_stop,
            3.2,
            "dpc",
            3.0,
            controls=config,
            keyboard_fd=terminal,
            meshcat=meshcat,
            trajectory=str(trajectory),
        )
    finally:
        os.close(main)
        os.close(terminal)
    controls = summary["controls"]
    estop = controls["estop"]
    assert estop is not None and estop["source"].startswith({"udp": "udp://"}.get(where, where))
    assert 1.0 < estop["t_s"] < 2.5
    assert estop["time_to_rest_s"] is not None and 0 <= estop["time_to_rest_s"] < 1.0
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert controls["final"]["mode"] == "estop"
    rows = np.genfromtxt(trajectory, delimiter=",", names=True, dtype=None, encoding="ascii")
    qd = np.column_stack([rows[name] for name in rows.dtype.names if name.startswith("qd_")])
    after = rows["t"] >= estop["t_s"] + estop["time_to_rest_s"] + 2 * H
    assert after.sum() > 20 and np.all(np.abs(qd[after]) < 1e-3)  # at rest, and it stays
    assert np.any(np.abs(qd[rows["t"] < estop["t_s"]]) > 1e-3)  # it moved before
    assert set(rows["mode"][after]) == {"estop"}


def test_a_scenario_and_the_live_flags_set_the_controls(tmp_path):
    from mca_drake.app.cli import build_parser
    from mca_drake.app.cli.live import _scenario_from_flags
    from mca_drake.app.scenarios import load_scenario

    path = tmp_path / "live.yaml"
    path.write_text(
        "scenario: !LiveScenario\n  protocol: csv\n  duration_s: 5\n  controls:\n"
        "    intensity: 0.5\n    gains: {f_x-: 0.7}\n    udp: 127.0.0.1:5601\n"
    )
    scenario = load_scenario(path)
    scenario.validate()
    assert initial_settings(scenario.controls) == [0.5, 1, 1, 1, 1, 0.7, 1, 1]
    with pytest.raises(ValueError, match=r"LiveScenario\.controls: ControlsConfig: no channel"):
        load_scenario(path, "scenario: {controls: {gains: {f_z: 1.0}}}").validate()
    argv = ["live", "--protocol", "csv", "--duration", "5", "--control-port", "127.0.0.1:5602"]
    args = build_parser().parse_args([*argv, "--intensity", "0.3", "--no-keyboard"])
    controls = _scenario_from_flags(args).controls
    assert (controls.udp, controls.intensity, controls.keyboard) == ("127.0.0.1:5602", 0.3, False)
    args = build_parser().parse_args([*argv, "--intensity", "1.3"])
    with pytest.raises(ValueError, match="intensity must be a number in"):
        _scenario_from_flags(args)


def test_the_live_command_takes_keys_from_its_terminal(tmp_path):
    """`mca-drake live` with a terminal for stdin (a pseudo-terminal this test holds): it
    says which keys control it, `-` turns the intensity down and `x` stops the robot; the
    report and the summary say so."""
    import json
    import subprocess
    import sys

    from test_live_loop import stream

    out = tmp_path / "live.json"
    command = [sys.executable, "-m", "mca_drake.app.cli", "live", "--protocol", "csv"]
    command += ["--port", "0", "--duration", "3", "--json", str(out)]
    main, terminal = os.openpty()
    process = subprocess.Popen(
        command, stdin=terminal, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        line = process.stdout.readline()  # blocks until the socket is bound
        port = int(line.strip().rsplit(":", 1)[1])
        assert "x or Esc STOP" in process.stdout.readline()
        sender = threading.Thread(
            target=stream, args=(("127.0.0.1", port), 3.2), kwargs={"gap": (9, 9), "nan_at": -1}
        )
        sender.start()
        time.sleep(1.0)
        os.write(main, b"--")
        time.sleep(0.7)
        os.write(main, b"x")
        sender.join(timeout=10)
        assert process.wait(timeout=30) == 0, process.stderr.read()
        report = process.stdout.read()
    finally:
        process.kill()
        os.close(main)
        os.close(terminal)
    assert "emergency stop at" in report and "from keyboard: at rest after" in report
    controls = json.loads(out.read_text())["controls"]
    assert [e["command"] for e in controls["log"]] == ["intensity 0.9", "intensity 0.8", "estop"]
    assert controls["final"]["mode"] == "estop" and controls["estop"]["time_to_rest_s"] >= 0
