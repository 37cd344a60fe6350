"""TelemetryReceiver on loopback: the held sample, its scaling and the stream's counters."""

from __future__ import annotations

import socket

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from mca_drake.live.csv_udp import CsvDecoder, encode_csv_sample
from mca_drake.live.receiver import ReceiverConfig, TelemetryReceiver
from mca_drake.live.telemetry import Decoder, TelemetrySample


def rig(decoder=None, **config):
    """A diagram holding only a receiver on a free loopback port; (simulator, receiver,
    sender socket)."""
    builder = DiagramBuilder()
    receiver = builder.AddSystem(
        TelemetryReceiver(decoder or CsvDecoder(), ReceiverConfig(port=0, **config))
    )
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    return simulator, receiver, sender


def outputs(simulator, receiver):
    context = receiver.GetMyContextFromRoot(simulator.get_context())
    reference = receiver.GetOutputPort("reference").Eval(context)
    return reference, receiver.counters(context)


def test_the_newest_sample_leaves_scaled():
    simulator, receiver, sender = rig()
    omega, f = np.array([0.1, -0.2, 0.3]), np.array([1.0, -2.0, 11.0])
    for t in (0.0, 0.01):  # two samples: the newer one is held
        sender.sendto(encode_csv_sample(t, omega * (1 + t), f), receiver.address)
    simulator.AdvanceTo(0.01)  # the poll runs at 0.009
    reference, counters = outputs(simulator, receiver)
    # y_ref by hand (s_w = s_f = 0.5, gravity compensated): an independent formula
    w = omega * 1.01
    np.testing.assert_allclose(
        reference, [0.5 * w[0], 0.5 * w[1], 0.5 * w[2], 0.5, -1.0, 0.5 * (11.0 - 9.81)]
    )
    assert counters["packets"] == 2 and counters["bad"] == 0 and counters["fresh"] == 1
    receiver.close()


def test_before_any_sample_the_reference_is_neutral_and_stale():
    simulator, receiver, _ = rig()
    simulator.AdvanceTo(0.05)
    reference, counters = outputs(simulator, receiver)
    np.testing.assert_allclose(reference, 0.0, atol=1e-12)
    assert counters["fresh"] == 0 and counters["age_s"] == np.inf
    assert counters["stale_periods"] == 5
    receiver.close()


def test_bad_and_late_datagrams_are_counted_and_ignored():
    simulator, receiver, sender = rig()
    good = encode_csv_sample(2.0, [0.1, 0.0, 0.0], [0.0, 0.0, 9.81])
    older = encode_csv_sample(1.0, [0.9, 0.0, 0.0], [0.0, 0.0, 9.81])
    for packet in (b"\x00garbage\xff", good, b"1,2,3", older, b"nan,0,0,0,0,0,9.81"):
        sender.sendto(packet, receiver.address)
    simulator.AdvanceTo(0.01)
    reference, counters = outputs(simulator, receiver)
    assert counters["packets"] == 5
    assert counters["bad"] == 3 and counters["out_of_order"] == 1
    np.testing.assert_allclose(reference[0], 0.05)  # the t = 2 sample, not the older one
    receiver.close()


class SequencedDecoder(Decoder):
    """A test protocol: 'sequence' as ASCII, sent at 100 Hz; level flight."""

    protocol = "sequenced"
    max_datagram_bytes = 64

    def _decode_at_source(self, packet, received_s):
        n = int(packet.decode())
        return TelemetrySample(0.01 * n, np.zeros(3), [0.0, 0.0, 9.81], sequence=n)


def test_gaps_in_the_senders_sequence_count_as_dropped():
    simulator, receiver, sender = rig(SequencedDecoder())
    for n in (1, 2, 5, 6, 10):  # 3, 4 and 7, 8, 9 never sent
        sender.sendto(str(n).encode(), receiver.address)
    simulator.AdvanceTo(0.01)
    _, counters = outputs(simulator, receiver)
    assert counters["dropped"] == 5 and counters["packets"] == 5
    receiver.close()


def test_a_flood_is_read_a_bounded_number_per_poll():
    simulator, receiver, sender = rig(max_datagrams_per_poll=4)
    for k in range(10):
        sender.sendto(encode_csv_sample(k, [0, 0, 0], [0, 0, 9.81]), receiver.address)
    simulator.AdvanceTo(0.01)
    assert outputs(simulator, receiver)[1]["packets"] == 4
    simulator.AdvanceTo(0.03)
    assert outputs(simulator, receiver)[1]["packets"] == 10
    receiver.close()


@pytest.mark.parametrize(
    "change, match",
    [
        ({"port": 70000}, "port"),
        ({"stale_after_s": 0.0}, "positive"),
    ],
)
def test_bad_settings_are_refused(change, match):
    with pytest.raises(ValueError, match=match):
        ReceiverConfig(**change).validate()


def test_a_port_in_use_is_an_error():
    first = TelemetryReceiver(CsvDecoder(), ReceiverConfig(port=0))
    with pytest.raises(OSError):
        TelemetryReceiver(CsvDecoder(), ReceiverConfig(port=first.address[1]))
    first.close()


def test_a_datagrams_age_counts_its_wait_in_the_socket():
    """The kernel's receive time stamps the sample: one sent 30 ms before the poll reads it
    is at least 30 ms old then, not 0."""
    import time

    simulator, receiver, sender = rig()
    sender.sendto(encode_csv_sample(0.0, [0, 0, 0], [0, 0, 9.81]), receiver.address)
    simulator.AdvanceTo(0.01)  # the socket's time stamps are on from the first datagram on
    sender.sendto(encode_csv_sample(0.01, [0, 0, 0], [0, 0, 9.81]), receiver.address)
    time.sleep(0.03)
    simulator.AdvanceTo(0.02)
    _, counters = outputs(simulator, receiver)
    assert counters["packets"] == 2
    assert 0.03 <= counters["age_s"] < 1.0
    receiver.close()


def test_a_stream_that_queued_while_the_loop_waited_is_followed():
    """A sender whose first sample was polled, then streamed 3 s at 200 Hz while the loop
    did not poll (as while it waits for a robot, or stalls): the socket's buffer fills and
    the kernel drops the rest, a gap of over a second in the sender's time. The queued
    samples keep their kernel receive stamps, older than a second, so the sender's clock
    and the arrivals agree across the gap and no sample is taken for a jump ahead; the
    newest sample, sent after the wait, is the one held. (Stamps older than a second taken
    as the time they were read locked the stream out for good.)"""
    import time

    simulator, receiver, sender = rig()
    start = time.perf_counter()
    sender.sendto(encode_csv_sample(0.0, [0, 0, 0], [0.1, 0, 9.81]), receiver.address)
    simulator.AdvanceTo(0.01)
    k = 0
    while (t := time.perf_counter() - start) < 3.0:  # 200 Hz, nobody polling
        sender.sendto(encode_csv_sample(t, [0, 0, 0], [0.1, 0, 9.81]), receiver.address)
        k += 1
        time.sleep(max(0.0, start + k / 200 - time.perf_counter()))
    step = 0.01
    for _ in range(20):  # the loop runs: a fresh sample every period
        t = time.perf_counter() - start
        sender.sendto(encode_csv_sample(t, [0, 0, 0], [0.2, 0, 9.81]), receiver.address)
        simulator.AdvanceTo(simulator.get_context().get_time() + step)
        time.sleep(step)
    reference, counters = outputs(simulator, receiver)
    assert counters["kernel_dropped"] > 0  # the gap
    assert counters["time_jumps"] == 0
    assert counters["age_s"] < 0.5  # the held sample is a fresh one
    assert reference[3] == pytest.approx(0.5 * 0.2)  # f_x of the fresh samples, scaled
    receiver.close()
