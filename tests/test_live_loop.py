"""The live loop on loopback: a sender thread streams CSV telemetry (with a stop and a NaN
burst) into `run_live`; the robot stays in its limits and the summary's live block counts
what happened."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from functools import partial

import numpy as np
import pytest

from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.live.csv_udp import CsvDecoder, encode_csv_sample
from mca_drake.live.loop import STALL_PERIODS, run_live
from mca_drake.live.receiver import ReceiverConfig
from mca_drake.platforms.files import load_platform

KR500 = load_platform("kr500")


def stream(address, duration_s, rate_hz=100.0, gap=(1.0, 1.6), nan_at=2.0, sent=None):
    """Sends a gentle surge oscillation at `rate_hz` for `duration_s` (wall), silent during
    `gap`, plus a NaN datagram and garbage at `nan_at` (s); bounded, stops by itself. Sets
    the event `sent` once its first datagram is out."""
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    start = time.perf_counter()
    k = 0
    while (t := time.perf_counter() - start) < duration_s:
        if not gap[0] <= t < gap[1]:
            f = [1.5 * np.sin(2 * np.pi * 0.5 * t), 0.0, 9.81]
            sender.sendto(encode_csv_sample(t, [0.0, 0.05, 0.0], f), address)
            if sent is not None:
                sent.set()
        if abs(t - nan_at) < 0.5 / rate_hz:
            sender.sendto(b"nan,0,0,0,0,0,9.81", address)
            sender.sendto(b"\xff" * 40, address)
        k += 1
        time.sleep(max(0.0, start + k / rate_hz - time.perf_counter()))
    sender.close()


# `stream` as a process of its own (plain Python, no mca_drake): a sender thread shares the
# loop's interpreter lock, so a long step of the loop would hold the stream up too and make a
# gap the test did not send.
STREAM_PROCESS = """
import math, socket, sys, time
host, port, duration = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
start, k = time.perf_counter(), 0
while (t := time.perf_counter() - start) < duration:
    if not 1.0 <= t < 1.6:
        f_x = 1.5 * math.sin(2 * math.pi * 0.5 * t)
        sender.sendto(f"{t!r},0.0,0.05,0.0,{f_x!r},0.0,9.81\\n".encode(), (host, port))
    if abs(t - 2.0) < 0.005:
        sender.sendto(b"nan,0,0,0,0,0,9.81", (host, port))
        sender.sendto(b"\\xff" * 40, (host, port))
    k += 1
    time.sleep(max(0.0, start + k / 100.0 - time.perf_counter()))
"""


def stream_process(address, duration_s):
    """`stream`'s datagrams (100 Hz, silent from 1.0 to 1.6 s, a NaN and garbage at 2 s)
    from a process of its own; bounded, it ends by itself."""
    process = subprocess.Popen(
        [sys.executable, "-c", STREAM_PROCESS, address[0], str(address[1]), str(duration_s)]
    )
    process.wait(timeout=duration_s + 10)


def live_with_sender(sender, sender_seconds, mca, seconds, **options):
    """`run_live` on a free loopback port with `sender(address, sender_seconds)` streaming
    from a thread started once the socket listens; the summary."""
    threads = []

    def start_sender(address):
        thread = threading.Thread(target=sender, args=(address, sender_seconds), daemon=True)
        thread.start()
        threads.append(thread)

    summary = run_live(
        CsvDecoder(),
        mca,
        seconds,
        receiver=ReceiverConfig(port=0),
        on_listening=start_sender,
        **{"robot": KR500, **options},
    )
    threads[0].join(timeout=5)
    return summary


def test_a_live_run_survives_a_stop_and_bad_packets():
    # the sender outlasts the loop by a second: it starts while the loop still collects
    # its garbage (up to a few tenths of a second on a busy machine) and must not end first
    summary = live_with_sender(stream_process, 4.0, "washout", 3.0)
    live = summary["live"]
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert live["packets"] > 200 and live["bad"] >= 2
    assert live["stale_events"] == 1, live["transitions"]  # the 0.6 s gap
    assert live["health"]["fault_s"] > 0.5 and live["health"]["ok_s"] > 1.0
    assert [t["to"] for t in live["transitions"]][-1] in ("ok", "degraded")
    assert np.isfinite(summary["pi"]) and np.isfinite(summary["pi_zero_motion"])
    assert live["latency_s"]["median"] < 0.02  # arrival to command, within two periods
    assert 0.7 < summary["realtime_factor"] < 1.3  # it ran at the real-time rate


def test_the_live_command_listens_cues_and_reports(tmp_path):
    """`mca-drake live` in its own process: prints where it listens, cues what it gets and
    writes the summary with the live block."""
    import json
    import subprocess
    import sys

    out = tmp_path / "live.json"
    command = [sys.executable, "-m", "mca_drake.app.cli", "live", "--protocol", "csv"]
    command += ["--port", "0", "--duration", "2", "--mca", "washout", "--json", str(out)]
    trajectory = tmp_path / "live.csv"
    command += ["--trajectory", str(trajectory)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()  # blocks until the socket is bound
        assert line.startswith("listening on udp://127.0.0.1:"), line
        port = int(line.strip().rsplit(":", 1)[1])
        stream(("127.0.0.1", port), 2.2, gap=(10.0, 10.0), nan_at=-1.0)
        assert process.wait(timeout=30) == 0, process.stderr.read()
    finally:
        process.kill()
    summary = json.loads(out.read_text())
    assert summary["live"]["protocol"] == "csv" and summary["live"]["packets"] > 100
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert summary["mca"] == "washout"
    # the time series: a row per period scored, with the health and the guard's reaction
    import csv

    with open(trajectory, newline="") as file:
        rows = list(csv.DictReader(file))
    assert len(rows) == round(summary["duration_s"] / CONTROL_PERIOD_S)
    assert {row["health"] for row in rows} <= {"ok", "degraded", "fault"}
    assert {row["plausibility"] for row in rows} <= {"none", "spike", "step", "fade", "reset"}
    assert list(rows[0])[-4:] == ["plausibility", "health", "mode", "intensity"]


def test_an_unknown_protocol_is_one_clear_error():
    import pytest

    from mca_drake.live.loop import make_decoder

    with pytest.raises(ValueError, match="unknown protocol 'mavlink'"):
        make_decoder("mavlink")
    with pytest.raises(ValueError, match="xplane-version"):
        make_decoder("xplane")


def test_a_live_run_on_the_kr500_station_holds_the_limits():
    summary = live_with_sender(stream, 2.2, "dpc", 2.0, plant="multibody")
    assert summary["plant"] == "multibody"
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert summary["live"]["packets"] > 100 and np.isfinite(summary["pi"])


def test_the_demo_cues_jsbsims_own_packets():
    """`mca-drake live --demo` on the analytical plant: a JSBSim process streams the light
    aircraft's FGNetFDM packets in real time; the loop cues them inside the limits."""
    import json
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "demo.json"
        command = [sys.executable, "-m", "mca_drake.app.cli", "live", "--demo"]
        command += ["--plant", "analytical", "--duration", "4", "--mca", "dpc"]
        command += ["--json", str(out)]
        done = subprocess.run(command, capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        summary = json.loads(out.read_text())
    live = summary["live"]
    assert live["protocol"] == "fgnetfdm" and live["bad"] == 0
    assert live["packets"] > 150  # 100 Hz from JSBSim, after its start-up
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert live["health"]["ok_s"] > 1.0


def impaired_stream(address, duration_s, seed=0, sent=None):
    """100 Hz telemetry through a bad network: 10 % lost, 0-8 ms jitter, one pair in ten
    swapped, a burst of NaN datagrams at 1.0 s and a 0.5 s stop at 2.0 s (bounded). `sent`
    (a list) gets the wall time of every datagram sent that the receiver can use: not a NaN
    one, nor a held one sent after a newer sample (refused as out of order)."""
    rng = np.random.default_rng(seed)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    start, k, held = time.perf_counter(), 0, None
    while (t := time.perf_counter() - start) < duration_s:
        k += 1
        packet = encode_csv_sample(t, [0.0, 0.1 * np.sin(t), 0.0], [np.sin(3 * t), 0.0, 9.81])
        if 1.0 <= t < 1.1:
            packet = b"nan,nan,0,0,0,0,9.81"
        if 2.0 <= t < 2.5 or rng.random() < 0.1:
            packet = None  # stopped, or lost
        if packet is not None:
            if held is None and rng.random() < 0.1:
                held = packet  # sent after the next one: reordered
            else:
                sender.sendto(packet, address)
                usable = not packet.startswith(b"nan")
                if held is not None:
                    sender.sendto(held, address)
                    usable = usable or not held.startswith(b"nan")  # newest usable after a NaN
                    held = None
                if sent is not None and usable:
                    sent.append(time.perf_counter())
        time.sleep(max(0.0, start + k / 100 + rng.uniform(0, 0.008) - time.perf_counter()))
    sender.close()


def test_loss_jitter_reordering_nan_and_a_stop_never_break_a_limit():
    sent = []
    # the sender outlasts the loop by a second (the loop's clock starts after it does)
    summary = live_with_sender(partial(impaired_stream, sent=sent), 4.5, "nmpc-rti", 3.5)
    live = summary["live"]
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert live["bad"] >= 5 and live["out_of_order"] >= 3
    # Telemetry goes stale only where the loop saw no usable sample for stale_after_s
    # (0.1 s): the stop, possibly the NaN burst, and any silence of a sender the machine held
    # up (what it really sent is the oracle), or a stall of the loop itself. The loop sees a
    # sample late by less than a stall (STALL_PERIODS periods, 50 ms) unless a stall is
    # counted, so every stale event needs a sender silence over 0.1 - 0.05 s or a stall.
    silences = int(np.sum(np.diff(sent) > 0.1 - STALL_PERIODS * CONTROL_PERIOD_S))
    assert int(np.sum(np.diff(sent) > 0.4)) >= 1  # the stop
    assert 1 <= live["stale_events"] <= silences + live["stalls"]
    assert [t["to"] for t in live["transitions"]][-1] != "fault"  # recovered
    assert summary["solver_failures"] == 0


def periodic_sender(address, start_wall, duration_s, period_s=0.01):
    """Sends a sample every `period_s` from `start_wall` (time.perf_counter() of the
    parent's clock: both read CLOCK_MONOTONIC) for `duration_s`; bounded."""
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    k = 0
    while k * period_s < duration_s:
        target = start_wall + k * period_s
        while (left := target - time.perf_counter()) > 0:
            time.sleep(left - 5e-4 if left > 1e-3 else 0)
        sender.sendto(encode_csv_sample(k * period_s, [0.0, 0.05, 0.0], [0.3, 0, 9.81]), address)
        k += 1
    sender.close()


def test_the_phase_lock_brings_the_polls_just_after_a_periodic_senders_packets():
    """A 100 Hz sender at a phase of its own (its process starts a few ms after the socket
    opens): whatever that phase, the lock moves the control instants so that samples arrive
    in the wake window before their poll instant, and bring the poll forward: they wait only
    for the wake-up (uniformly 0 to 10 ms without the lock)."""
    import multiprocessing

    processes = []

    def start(address):
        # the loop's grid starts now; its polls come at multiples of 10 ms (less 20 us)
        first = time.perf_counter() + 0.0065
        process = multiprocessing.get_context("fork").Process(
            target=periodic_sender, args=(address, first, 6.3), daemon=True
        )
        process.start()
        processes.append(process)

    summary = run_live(
        CsvDecoder(), "dpc", 6.0, receiver=ReceiverConfig(port=0), on_listening=start, robot=KR500
    )
    processes[0].join(timeout=5)
    live = summary["live"]
    assert live["packets"] >= 550, live
    assert live["wait_s"]["median"] < 0.001, live
    assert live["early_polls"] > 200, live  # the samples brought their polls forward
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}


def with_intruder(address, duration_s):
    """The real stream from 127.0.0.1, and an intruder on 127.0.0.2 that starts 0.2 s after
    the real stream's first datagram (however late a loaded machine schedules it) with a
    violent roll (3 rad/s) at 100 Hz; both bounded."""
    intruder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    intruder.bind(("127.0.0.2", 0))
    first_sent = threading.Event()

    def flood():
        first_sent.wait(timeout=5.0)
        start = time.perf_counter()
        time.sleep(0.2)
        while (t := time.perf_counter() - start) < duration_s:
            intruder.sendto(encode_csv_sample(t + 100.0, [3.0, 0.0, 0.0], [0, 0, 9.81]), address)
            time.sleep(0.01)
        intruder.close()

    thread = threading.Thread(target=flood, daemon=True)
    thread.start()
    stream(address, duration_s, gap=(9.0, 9.0), nan_at=99.0, sent=first_sent)
    thread.join(timeout=5)


def test_a_live_run_reads_only_its_sender_and_counts_an_intruder():
    summary = live_with_sender(with_intruder, 1.7, "washout", 1.5)
    live = summary["live"]
    assert live["foreign"] > 50  # about 130 sent in the 1.3 s the intruder runs
    assert live["sender"].startswith("udp://127.0.0.1:") and "locked" in live["sender"]
    # the intruder's roll never became a reference (s_w x 3 rad/s = 1.5 rad/s cued would
    # leave an RMSE of order 1 in w_x): the real stream has none
    assert summary["rmse"][0] < 0.05
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert live["health"]["ok_s"] > 0.8


def garbage_stream(address, duration_s, rate_hz=100.0):
    """Sends datagrams no CSV decoder reads (a flight simulator's binary frames on the wrong
    --protocol) at `rate_hz` for `duration_s`; bounded, stops by itself."""
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    start, k = time.perf_counter(), 0
    while time.perf_counter() - start < duration_s:
        sender.sendto(b"\x00\x00\x00\x18" + bytes(404), address)
        k += 1
        time.sleep(max(0.0, start + k / rate_hz - time.perf_counter()))
    sender.close()


def test_a_run_whose_every_datagram_is_refused_says_so_within_a_second(capsys):
    """Binary frames to a CSV loop: after its first second the loop tells the user (stderr
    and the summary's `live.notices`) that every datagram was refused, with the decoder's
    reason; a stream it reads raises no notice."""
    summary = live_with_sender(garbage_stream, 1.6, "washout", 1.5)
    notices = summary["live"]["notices"]
    assert len(notices) == 1 and "datagrams so far were refused" in notices[0]
    assert "not read as csv packets" in notices[0] and "csv" in notices[0].split("the last:")[1]
    assert notices[0] in capsys.readouterr().err
    clean = live_with_sender(stream, 1.6, "washout", 1.5)
    assert clean["live"]["notices"] == [] and clean["live"]["packets"] > 50


# A recording streamed as CSV over UDP at 100 Hz from its own process (its sample times).
RECORDING_STREAM_PROCESS = """
import socket, sys, time
from mca_drake.live.csv_udp import encode_csv_sample
from mca_drake.references.recording import load_recording
recording = load_recording(sys.argv[1])
sender, address = socket.socket(socket.AF_INET, socket.SOCK_DGRAM), (sys.argv[2], int(sys.argv[3]))
print("ready", flush=True)
time.sleep(1.0)  # the loop's clock starts after its garbage collection, within this second
start = time.perf_counter()
for t, omega, f in zip(recording.t - recording.t[0], recording.omega, recording.f):
    time.sleep(max(0.0, start + t - time.perf_counter()))
    sender.sendto(encode_csv_sample(float(t), omega, f), address)
"""


def test_live_cueing_scores_as_offline_cueing_of_the_same_samples(tmp_path):
    """A light aircraft's flight (a training seed) streamed on loopback: the live PI over
    the span the stream covered is within 0.1 of the offline run on the recording."""
    from mca_drake.references.flights import FlightSpec, flight_recording
    from mca_drake.references.recording import save_recording
    from mca_drake.references.reference import reference_from_recording
    from mca_drake.simulation.closed_loop import run_closed_loop

    seconds = 12.0
    recording = flight_recording(FlightSpec(vehicle="light", seed=7), seconds)
    path = tmp_path / "light.csv"
    save_recording(path, recording)
    processes = []

    def start(address):
        command = [sys.executable, "-c", RECORDING_STREAM_PROCESS, str(path), *map(str, address)]
        processes.append(subprocess.Popen(command, stdout=subprocess.PIPE, text=True))
        # the loop's clock starts once this returns: the sender's imports and the
        # recording's load (seconds on a busy machine) are behind it by then
        processes[0].stdout.readline()

    # the loop outlasts the stream by the sender's one-second wait and then some
    summary = run_live(
        CsvDecoder(),
        "dpc",
        seconds + 3.0,
        receiver=ReceiverConfig(port=0),
        on_listening=start,
        robot=KR500,
    )
    processes[0].wait(timeout=30)
    processes[0].stdout.close()
    first, last = summary["scored_span_s"]
    assert first < 1.0 and abs(last - first - seconds) < 0.1  # the stream, not the tail
    offline = run_closed_loop(
        mca="dpc",
        reference=reference_from_recording(recording).truncated(last - first),
        robot=KR500,
        progress=False,
    ).summary
    assert abs(summary["pi"] - offline["pi"]) < 0.1, (summary["pi"], offline["pi"])
    assert summary["pi"] < summary["pi_zero_motion"] - 1.0  # it cued
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}


def test_jsbsims_stream_scores_as_offline_cueing_of_the_samples_received(tmp_path):
    """JSBSim flying the light aircraft in real time (FGNetFDM with its time directive):
    the live PI over the span it streamed is within 0.1 of the offline run on the samples
    the loop received (the trajectory's reference over that span)."""
    from mca_drake.conventions import CHANNELS
    from mca_drake.live.demo import DEMO_TIME_RESOLUTION_S, start_demo_sender
    from mca_drake.live.loop import make_decoder
    from mca_drake.references.reference import Reference
    from mca_drake.simulation.closed_loop import run_closed_loop

    seconds, senders = 10.0, []
    trajectory = tmp_path / "run.csv"
    summary = run_live(
        make_decoder("fgnetfdm", fgnetfdm_time_resolution_s=DEMO_TIME_RESOLUTION_S),
        "dpc",
        seconds,
        receiver=ReceiverConfig(port=0),
        on_listening=lambda address: senders.append(start_demo_sender(address[1], seconds)),
        robot=KR500,
        trajectory=str(trajectory),
    )
    senders[0].terminate()
    senders[0].wait(timeout=10)
    rows = np.genfromtxt(trajectory, delimiter=",", names=True, dtype=None, encoding="ascii")
    first, last = (round(t / CONTROL_PERIOD_S) for t in summary["scored_span_s"])
    assert last - first > 500
    received = np.column_stack([rows[f"ref_{c}"] for c in CHANNELS])[first : last + 1]
    offline = run_closed_loop(
        mca="dpc", reference=Reference(received), robot=KR500, progress=False
    ).summary
    assert offline["pi_zero_motion"] == pytest.approx(summary["pi_zero_motion"], abs=1e-9)
    assert abs(summary["pi"] - offline["pi"]) < 0.1, (summary["pi"], offline["pi"])
    # the controls and state FGNetFDM carries ride along, one row per period's sample
    span = slice(first, last + 1)
    for name in ("aileron", "elevator", "rudder", "speed", "roll", "pitch", "height"):
        assert np.isfinite(rows[name][span]).all(), name
    assert (rows["speed"][span] > 20.0).all()  # m/s: the light aircraft in flight
    assert np.abs(rows["aileron"][span]).max() <= 1.0
    assert (rows["on_ground"][span] == 0.0).all()


def test_a_live_run_cues_its_scaling_and_is_scored_at_the_default():
    """Scaled to nothing (both scales 0), the live washout is asked for no motion and the
    robot stays at home, while the run is scored against the telemetry at the default
    scaling: its PI is zero motion's."""
    from mca_drake.references.reference import ReferenceScaling

    nothing = ReferenceScaling(angular_scale=0.0, force_scale=0.0)
    summary = live_with_sender(
        partial(stream, gap=(9.0, 9.0), nan_at=-1.0), 2.5, "washout", 2.5, scaling=nothing
    )
    assert summary["live"]["packets"] > 100
    assert summary["scaling"]["force_scale"] == 0.0
    # the surge it was sent (0.75 m/s^2 amplitude at the default scaling) is all error
    assert summary["rmse"][3] == pytest.approx(0.75 / np.sqrt(2), rel=0.1)
    assert summary["pi"] == pytest.approx(summary["pi_zero_motion"], abs=1e-6)


def test_a_predictive_nmpc_cues_live():
    """The predictive NMPC's forecast runs in the live loop's phase: it cues the stream's
    surge (its shape followed) within every limit."""
    summary = live_with_sender(
        partial(stream, gap=(9.0, 9.0), nan_at=-1.0), 3.0, "nmpc-rti-predictive", 3.0
    )
    assert summary["mca"] == "nmpc-rti-predictive"
    assert summary["live"]["packets"] > 150
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert summary["cc"][3] > 0.8  # f_x, the surge oscillation sent
