"""Only the senders the scenario allows move the robot: an intruder on 127.0.0.2 beside the
real sender on 127.0.0.1 is counted and ignored; a sample far ahead of the sender's clock is
that packet's fault; a restarted clock is followed; the kernel's drops are counted."""

from __future__ import annotations

import ipaddress
import socket

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from mca_drake.live.csv_udp import CsvDecoder, encode_csv_sample
from mca_drake.live.receiver import ReceiverConfig, TelemetryReceiver, allowed_senders

LEVEL = [0.0, 0.0, 9.81]


def rig(**config):
    """A receiver on a free loopback port, polled by a simulator; (simulator, receiver)."""
    builder = DiagramBuilder()
    receiver = builder.AddSystem(TelemetryReceiver(CsvDecoder(), ReceiverConfig(port=0, **config)))
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    return simulator, receiver


def sender_at(host: str) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((host, 0))
    return sock


def poll(simulator, receiver, periods: int = 1):
    """Advances `periods` control periods; (reference, counters)."""
    simulator.AdvanceTo(simulator.get_context().get_time() + 0.01 * periods)
    context = receiver.GetMyContextFromRoot(simulator.get_context())
    return receiver.GetOutputPort("reference").Eval(context), receiver.counters(context)


def sample(t: float, roll_rate: float) -> bytes:
    return encode_csv_sample(t, [roll_rate, 0.0, 0.0], LEVEL)


def test_the_first_sender_is_locked_in_and_an_intruder_ignored():
    simulator, receiver = rig()
    real, intruder = sender_at("127.0.0.1"), sender_at("127.0.0.2")
    real.sendto(sample(0.0, 0.1), receiver.address)
    reference, counters = poll(simulator, receiver)
    for k in range(5):  # the intruder's samples are newer and larger
        intruder.sendto(sample(1.0 + 0.01 * k, 2.0), receiver.address)
    real.sendto(sample(0.01, 0.2), receiver.address)
    reference, counters = poll(simulator, receiver)
    assert reference[0] == pytest.approx(0.5 * 0.2)  # s_w = 0.5 of the real sender's rate
    assert counters["foreign"] == 5 and counters["packets"] == 7
    assert counters["sender_ip"] == int(ipaddress.IPv4Address("127.0.0.1"))
    assert counters["sender_port"] == real.getsockname()[1]
    receiver.close()


def test_with_an_allow_list_an_intruder_that_comes_first_is_ignored():
    simulator, receiver = rig(allowed_senders=["127.0.0.1"])
    real, intruder = sender_at("127.0.0.1"), sender_at("127.0.0.2")
    intruder.sendto(sample(0.0, 2.0), receiver.address)
    reference, counters = poll(simulator, receiver)
    np.testing.assert_allclose(reference, 0.0, atol=1e-12)  # nothing read: neutral
    real.sendto(sample(0.0, 0.1), receiver.address)
    reference, counters = poll(simulator, receiver)
    assert reference[0] == pytest.approx(0.05) and counters["foreign"] == 1
    receiver.close()


def test_an_allowed_port_excludes_the_same_host_on_another_port():
    real, other = sender_at("127.0.0.1"), sender_at("127.0.0.1")
    simulator, receiver = rig(allowed_senders=[f"127.0.0.1:{real.getsockname()[1]}"])
    other.sendto(sample(0.0, 2.0), receiver.address)
    real.sendto(sample(0.0, 0.1), receiver.address)
    reference, counters = poll(simulator, receiver)
    assert reference[0] == pytest.approx(0.05) and counters["foreign"] == 1
    receiver.close()


@pytest.mark.parametrize("item", ["localhost", "127.0.0.1:0", "127.0.0.1:x", "::1", "1.2.3"])
def test_a_bad_allowed_sender_is_refused(item):
    with pytest.raises(ValueError, match="allowed sender"):
        allowed_senders([item])


def test_a_time_far_ahead_is_that_packets_fault():
    simulator, receiver = rig()
    real = sender_at("127.0.0.1")
    real.sendto(sample(10.0, 0.1), receiver.address)
    poll(simulator, receiver)
    real.sendto(sample(1e12, 3.0), receiver.address)  # one datagram from the far future
    for k in range(1, 4):
        real.sendto(sample(10.0 + 0.01 * k, 0.2), receiver.address)
    reference, counters = poll(simulator, receiver)
    assert counters["time_jumps"] == 1 and counters["out_of_order"] == 0
    assert reference[0] == pytest.approx(0.1)  # the stream goes on
    receiver.close()


@pytest.mark.parametrize("first", [1e12, 500.0])
def test_a_restarted_clock_is_followed(first):
    """A held sample far ahead (a bad first datagram) or a sender that restarts its clock
    at 0: after `restart_samples` increasing samples the receiver follows the new clock."""
    simulator, receiver = rig(restart_samples=5)
    real = sender_at("127.0.0.1")
    real.sendto(sample(first, 0.3), receiver.address)
    poll(simulator, receiver)
    for k in range(8):
        real.sendto(sample(0.01 * k, 0.1), receiver.address)
    reference, counters = poll(simulator, receiver)
    assert counters["restarts"] == 1 and counters["out_of_order"] == 4
    assert reference[0] == pytest.approx(0.05)
    receiver.close()


def test_the_kernels_drops_are_counted():
    """A flood into a small buffer: every datagram sent is either read or counted as
    dropped by the kernel (loopback loses nothing else). The kernel reports its count with
    the next datagram it queues, so one more follows the flood."""
    simulator, receiver = rig(receive_buffer_bytes=4096, max_datagrams_per_poll=1000)
    real = sender_at("127.0.0.1")
    sent = 3000
    for k in range(sent):
        real.sendto(sample(0.0001 * k, 0.1), receiver.address)
    poll(simulator, receiver, periods=5)
    real.sendto(sample(1.0, 0.1), receiver.address)
    _, counters = poll(simulator, receiver)
    assert counters["kernel_dropped"] > 0
    assert counters["packets"] + counters["kernel_dropped"] == sent + 1
    receiver.close()
