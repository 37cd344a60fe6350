"""The kernel's time stamps of datagrams: when one reached a socket, and when one left.

A process reads a datagram, or learns that its own has gone, only when the scheduler lets it
run; the kernel stamps both events as they happen (Linux: SO_TIMESTAMPNS for arrivals,
SO_TIMESTAMPING's software transmit stamps for departures). These helpers turn the stamps
(CLOCK_REALTIME) into the time.perf_counter() clock the live layer times everything with;
where a platform has no stamps they fall back to the time the process looked.
"""

from __future__ import annotations

import socket
import struct
import time

# Linux's SO_TIMESTAMPNS (and SCM_TIMESTAMPNS): the kernel's receive time of a datagram, as a
# struct timespec of CLOCK_REALTIME (Python's socket module does not name it).
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)
# Linux's SO_TIMESTAMPING (and SCM_TIMESTAMPING: three timespecs, the software one first) and
# the flags for software stamps of datagrams leaving through the device, without the payload
# looped back (linux/net_tstamp.h).
SO_TIMESTAMPING = getattr(socket, "SO_TIMESTAMPING", 37)
_TX_SOFTWARE, _SOFTWARE, _OPT_TSONLY = 1 << 1, 1 << 4, 1 << 11
# The struct timespec they carry: seconds and nanoseconds.
_TIMESPEC = struct.Struct("qq")
# Linux's SO_RXQ_OVFL: every datagram read carries the count of datagrams the kernel dropped
# on this socket so far (its receive buffer was full), a 32-bit unsigned integer.
SO_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40)
_DROP_COUNTER = struct.Struct("I")


# The oldest plausible stamp, s: a datagram waits in its socket as long as its process does
# not read it, as while the live loop waits for a robot to connect (a minute at most) or
# stalls. An older stamp, or one in the future, means the wall clock stepped.
MAX_STAMP_AGE_S = 120.0


def _perf_counter_time(stamp: bytes) -> float | None:
    """A timespec of CLOCK_REALTIME on the perf_counter clock; None for an implausible one
    (older than MAX_STAMP_AGE_S or 1 ms in the future: the clock stepped)."""
    seconds, nanoseconds = _TIMESPEC.unpack_from(stamp)
    # the two clocks' offset, read between two perf_counter reads close together (a process
    # preempted between the reads would be off by the preemption)
    for _ in range(3):
        before = time.perf_counter()
        wall_ns = time.time_ns()
        after = time.perf_counter()
        if after - before < 20e-6:
            break
    ago = 1e-9 * (wall_ns - (seconds * 1_000_000_000 + nanoseconds))
    return 0.5 * (before + after) - ago if -1e-3 <= ago < MAX_STAMP_AGE_S else None


def enable_kernel_timestamps(sock: socket.socket) -> bool:
    """Asks the kernel to stamp every datagram `sock` receives (Linux's SO_TIMESTAMPNS), so
    that the time a datagram waited in the socket counts in its latency; False where the
    platform has no such stamps (`arrival_time` then takes the time it is read)."""
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
    except OSError:
        return False
    return True


def arrival_time(ancillary) -> float:
    """When a datagram read by `recvmsg(..., 64)` reached its socket, on the
    time.perf_counter() clock: the kernel's stamp in `ancillary` where there is one
    (`enable_kernel_timestamps`), else now."""
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS and len(data) >= 16:
            stamped = _perf_counter_time(data)
            if stamped is not None:
                return stamped
    return time.perf_counter()


def enable_send_timestamps(sock: socket.socket) -> bool:
    """Asks the kernel to stamp every datagram `sock` sends as it leaves through the network
    device (software transmit stamps; on loopback, as it is delivered); the stamps queue on
    the socket's error queue, and `departure_time` must read each right after its send (a
    stamp waiting there makes `select` report the socket readable). False where the platform
    has no such stamps."""
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPING, _TX_SOFTWARE | _SOFTWARE | _OPT_TSONLY)
    except OSError:
        return False
    return True


def departure_time(sock: socket.socket, not_before: float) -> float | None:
    """When the datagram just sent on `sock` left, on the time.perf_counter() clock: the first
    stamp on its error queue (`enable_send_timestamps`) from `not_before` (perf_counter, s,
    read before the send; older stamps, of earlier sends, are taken off and skipped); None
    where there is none."""
    while True:
        try:
            _, ancillary, _, _ = sock.recvmsg(1, 256, socket.MSG_ERRQUEUE | socket.MSG_DONTWAIT)
        except OSError:  # BlockingIOError included: the queue is empty
            return None
        for level, kind, data in ancillary:
            if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPING and len(data) >= 16:
                stamped = _perf_counter_time(data)
                # the conversion is good to microseconds
                if stamped is not None and stamped >= not_before - 50e-6:
                    return stamped


def enable_drop_counter(sock: socket.socket) -> bool:
    """Asks the kernel to report, with every datagram `sock` receives, how many it dropped
    on this socket so far for want of room (Linux's SO_RXQ_OVFL); False where the platform
    has no such counter (`kernel_drops` then reads None)."""
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
    except OSError:
        return False
    return True


def kernel_drops(ancillary) -> int | None:
    """The kernel's count of datagrams dropped on the socket so far, from the ancillary data
    of a `recvmsg` (`enable_drop_counter`); None when the datagram carries none (no drop yet
    on Linux, or no counter on the platform)."""
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == SO_RXQ_OVFL and len(data) >= 4:
            return _DROP_COUNTER.unpack_from(data)[0]
    return None
