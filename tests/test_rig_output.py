"""The rig's own output: the formats against hand-built messages, bad settings refused, and
a live run's datagrams (and a serial port's bytes, on a pseudo-terminal pair) carrying the
positions the platform reached."""

from __future__ import annotations

import os
import select
import socket
import struct
import time

import numpy as np
import pytest

from mca_drake.live.rig_output import RigConnection, RigOutputConfig, encode, where
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.leg_platform import pose_of
from mca_drake.platforms.legs import leg_lengths

POSITIONS = [0.0123, -0.1045, 0.5, 1.25, -0.75, 2.0]


def test_the_default_line_is_the_positions_in_si_units():
    assert encode(POSITIONS, RigOutputConfig()) == (
        b"0.012300,-0.104500,0.500000,1.250000,-0.750000,2.000000\n"
    )


def test_a_template_writes_scaled_counts_in_the_users_layout():
    config = RigOutputConfig(
        format="template",
        template="A{0}B{1}C{5}{{}}\r\n",
        scale=[1000.0] * 6,
        offset=[0, 0, 0, 0, 0, 32768],
        number_format=".0f",
    )
    config.validate(6)
    # {k} only; other braces are text
    assert encode(POSITIONS, config) == b"A12B-104C34768{{}}\r\n"


def test_a_binary_layout_packs_rounded_counts():
    config = RigOutputConfig(format="binary", binary_layout="<6i", scale=[1e4] * 6)
    config.validate(6)
    message = encode(POSITIONS, config)
    assert struct.unpack("<6i", message) == (123, -1045, 5000, 12500, -7500, 20000)
    floats = RigOutputConfig(format="binary", binary_layout=">6f")
    np.testing.assert_allclose(struct.unpack(">6f", encode(POSITIONS, floats)), POSITIONS, 1e-6)


def test_settings_that_cannot_be_written_are_refused():
    bad = [
        (RigOutputConfig(url="tcp://127.0.0.1:5"), "not udp://HOST:PORT or serial://"),
        (RigOutputConfig(url="udp://127.0.0.1"), "needs a port"),
        (RigOutputConfig(url="serial:///dev/null?baud=1234"), "baud must be one of"),
        (RigOutputConfig(format="morse"), "format must be one of"),
        (RigOutputConfig(format="template", template="X{7}"), "names actuator 7"),
        (RigOutputConfig(format="template", template="no placeholder"), "no {k} placeholder"),
        (RigOutputConfig(format="binary", binary_layout="<5i"), "packs 5 values"),
        (RigOutputConfig(format="binary", binary_layout="<6z"), "binary_layout"),
        (RigOutputConfig(scale=[1.0] * 5), "scale needs 6 values"),
        (RigOutputConfig(number_format="q"), "not a format spec"),
    ]
    for config, message in bad:
        with pytest.raises(ValueError, match=message):
            config.validate(6)
    assert where("serial:///dev/ttyUSB0?baud=115200") == ("serial", ("/dev/ttyUSB0", 115200))


def test_a_serial_port_gets_the_bytes(tmp_path):
    main, terminal = os.openpty()
    try:
        config = RigOutputConfig(url=f"serial://{os.ttyname(terminal)}?baud=115200")
        connection = RigConnection(config)
        connection.send(encode(POSITIONS, config))
        connection.close()
        assert os.read(main, 4096) == encode(POSITIONS, config)
        assert (connection.sent, connection.failed) == (1, 0)
    finally:
        os.close(main)
        os.close(terminal)
    with pytest.raises(ValueError, match="cannot open the rig's serial port"):
        RigConnection(RigOutputConfig(url=f"serial://{tmp_path}/none?baud=9600"))


def live_run_listened(tmp_path, options_for, mca: str = "dpc"):
    """A 2 s live run (`mca`, the DPC by default, on `test_live_loop.stream_process`) whose
    output goes to a loopback listener: `options_for(url)` gives run_live's options for the
    listener's udp://127.0.0.1:PORT. Returns (summary, the datagrams received, the
    trajectory's rows)."""
    from test_live_loop import live_with_sender, stream_process

    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", 0))
    listener.setblocking(False)
    trajectory = tmp_path / "run.csv"
    url = f"udp://127.0.0.1:{listener.getsockname()[1]}"
    try:
        summary = live_with_sender(
            stream_process, 2.2, mca, 2.0, trajectory=str(trajectory), **options_for(url)
        )
        datagrams = []
        while True:
            try:
                datagrams.append(listener.recv(4096))
            except BlockingIOError:
                break
    finally:
        listener.close()
    return summary, datagrams, np.genfromtxt(trajectory, delimiter=",", names=True)


def test_a_live_run_sends_the_positions_the_platform_reaches(tmp_path):
    summary, lines, rows = live_run_listened(
        tmp_path, lambda url: {"rig": RigOutputConfig(url=url, number_format=".9f")}
    )
    rig = summary["rig"]
    assert rig["sent"] == len(lines) and rig["failed"] == 0 and len(lines) >= 190
    sent = np.array([[float(v) for v in line.decode().strip().split(",")] for line in lines])
    q = np.column_stack([rows[name] for name in rows.dtype.names if name.startswith("q_")])
    # line k: where the platform is at the next control instant, the trajectory's row k + 1
    count = min(len(sent), len(q)) - 1
    np.testing.assert_allclose(sent[:count], q[1 : count + 1], atol=1e-8)
    assert np.ptp(q[:, 0]) > 1e-4  # it moved


def test_a_hexapod_gets_its_leg_lengths_within_their_stroke(tmp_path):
    hexapod = load_platform("hexapod")
    summary, lines, rows = live_run_listened(
        tmp_path,
        lambda url: {"rig": RigOutputConfig(url=url, number_format=".9f"), "robot": hexapod},
        mca="washout",
    )
    rig = summary["rig"]
    assert rig["actuators"] == [f"leg_{i}" for i in range(1, 7)]
    # a sample's message goes out after the command computed from it, within a period
    latency = rig["latency_s"]
    live = summary["live"]["latency_s"]
    assert live["median"] < latency["median"] < 0.01 + live["median"]
    assert rig["sent"] == len(lines) and rig["failed"] == 0 and len(lines) >= 190
    sent = np.array([[float(v) for v in line.decode().strip().split(",")] for line in lines])
    g = hexapod.actuators
    assert sent.shape[1] == 6
    assert np.all((sent >= g.min_position) & (sent <= g.max_position))
    # Oracle: the legs' lengths of the trajectory's next row, from leg_lengths of its pose
    q = np.column_stack([rows[name] for name in rows.dtype.names if name.startswith("q_")])
    expected = leg_lengths(pose_of(q), g)
    count = min(len(sent), len(q)) - 1
    np.testing.assert_allclose(sent[:count], expected[1 : count + 1], atol=1e-8)
    assert np.ptp(sent[:, 0]) > 1e-4  # it moved


def test_a_hexapod_run_over_a_serial_port_sends_one_line_a_period_within_the_stroke():
    """The same live run as over UDP, to a pseudo-terminal this test opens (nothing touches
    a real device): every line parses, one per control period, each leg within its stroke."""
    import threading

    from test_live_loop import live_with_sender, stream_process

    hexapod = load_platform("hexapod")
    main, terminal = os.openpty()
    received = bytearray()
    stop = threading.Event()

    def drain():  # the rig's side: read whatever arrives until the run has ended
        while not stop.is_set():
            ready, _, _ = select.select([main], [], [], 0.05)
            if ready:
                received.extend(os.read(main, 65536))

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    try:
        url = f"serial://{os.ttyname(terminal)}?baud=115200"
        summary = live_with_sender(
            stream_process,
            2.2,
            "washout",
            2.0,
            rig=RigOutputConfig(url=url, number_format=".9f"),
            robot=hexapod,
        )
        time.sleep(0.2)
    finally:
        stop.set()
        reader.join(timeout=5)
        os.close(main)
        os.close(terminal)
    lines = bytes(received).decode("ascii").splitlines()
    rig = summary["rig"]
    assert rig["failed"] == 0 and rig["sent"] == len(lines) >= 190
    # one line per control period of the run (the loop's periods, counted by the summary)
    assert abs(len(lines) - round(summary["duration_s"] / 0.01)) <= 2
    sent = np.array([[float(v) for v in line.split(",")] for line in lines])
    g = hexapod.actuators
    assert sent.shape == (len(lines), 6)
    assert np.all((sent >= g.min_position) & (sent <= g.max_position))
    assert np.ptp(sent[:, 0]) > 1e-4  # it moved
