"""The kernel's send and receive stamps over loopback, against the process's own clock."""

from __future__ import annotations

import select
import socket
import sys
import time

import pytest

from mca_drake.live.socket_stamps import (
    arrival_time,
    departure_time,
    enable_kernel_timestamps,
    enable_send_timestamps,
)

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="Linux's socket time stamps")


@pytest.fixture
def pair():
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sender.bind(("127.0.0.1", 0))
    receiver.bind(("127.0.0.1", 0))
    yield sender, receiver
    sender.close()
    receiver.close()


def test_a_datagram_leaves_within_its_send_and_arrives_after_it_left(pair):
    """The departure stamp falls between the clock read before `sendto` and after it, the
    arrival stamp after the departure and before the receiver looked; the stamp read, the
    socket is not left looking readable."""
    sender, receiver = pair
    assert enable_send_timestamps(sender) and enable_kernel_timestamps(receiver)
    for _ in range(20):
        before = time.perf_counter()
        sender.sendto(b"state", receiver.getsockname())
        after = time.perf_counter()
        left = departure_time(sender, before)
        assert left is not None and before - 50e-6 <= left <= after + 50e-6, (before, left, after)
        assert not select.select([sender], [], [], 0.0)[0]  # the stamp was taken off
        _, ancillary, _, _ = receiver.recvmsg(64, 64)
        looked = time.perf_counter()
        arrived = arrival_time(ancillary)
        assert left - 50e-6 <= arrived <= looked, (left, arrived, looked)


def test_an_earlier_sends_stamp_is_skipped(pair):
    sender, receiver = pair
    assert enable_send_timestamps(sender)
    sender.sendto(b"first", receiver.getsockname())
    time.sleep(0.002)
    before = time.perf_counter()
    sender.sendto(b"second", receiver.getsockname())
    after = time.perf_counter()
    left = departure_time(sender, before)
    assert left is not None and before - 50e-6 <= left <= after + 50e-6
    assert departure_time(sender, before) is None  # each stamp is read once


def test_without_send_stamps_there_is_no_departure_time(pair):
    sender, receiver = pair
    sender.sendto(b"state", receiver.getsockname())
    assert departure_time(sender, 0.0) is None
    # and a datagram without a kernel stamp arrives when it is read
    _, ancillary, _, _ = receiver.recvmsg(64, 64)
    before = time.perf_counter()
    assert before <= arrival_time(ancillary) <= time.perf_counter()
