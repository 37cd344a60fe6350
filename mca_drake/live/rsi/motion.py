"""The RSI driver's motion: the MCA's command segments played on the robot's cycle.

The live loop steps its MCA every control period h (10 ms); a KUKA controller running RSI
asks for a position every interpolation cycle T (4 or 12 ms). The loop sends, after every
step k, the command segment it just decided: the state x_k = [q_k, qd_k] the MCA read and the
command u_k the robot gets (after the supervisor), held over [k h, (k + 1) h) of the loop's
simulated time. Between steps the joint trajectory is exactly

    q(s) = q_k + qd_k tau + u_k tau^2 / 2,   qd(s) = qd_k + u_k tau,   tau = s - k h,

the same double integration as the analytical plant (`MotionCueingPlant`), so the robot
follows the plant's trajectory, not an interpolation of it.

The driver plays that trajectory `delay_s` behind the loop (s = robot time - delay), so that
the segment a cycle needs has been computed and sent before the cycle comes (the loop's
latency and phase fit in the delay). Every cycle's target passes a check of its own against
the robot's limits before it is sent: velocity, the mean acceleration over the cycle,
position, and viability (`ViabilityClamp` at the cycle period: the robot can still brake
inside its limits from where the target leaves it). A target that fails, a segment that has
not come when it is needed (a stalled or killed MCA process, stale telemetry that stopped
the loop), or the loop's end-of-run segment switch the driver to braking: from the last state
it commanded, which passed the same checks, the strongest deceleration the viability clamp
allows, to rest; then it holds. There is no jump (the commanded state is continuous) and no
hold at speed.

Nothing here touches a socket: `mca_drake.live.rsi.driver` does, around a `MotionFollower`.
"""

import dataclasses
import functools
import math
import struct
from collections.abc import Sequence

from mca_drake.input_checks import check_config_numbers
from mca_drake.safety import ViabilityClamp

# A segment on the wire (Unix datagram from the live loop to the driver, one machine):
# magic, flags, step index k, then q, qd, u (n values each: rad or m, per s, per s^2),
# little-endian doubles; the driver knows n (its platform's joints) and takes no other.
SEGMENT_MAGIC = b"MCAS"
SEGMENT_HEADER = struct.Struct("<4sIq")
# The most joints a segment may carry (an RSI controller's 6 axes and 6 external ones).
MAX_SEGMENT_JOINTS = 12
# Bytes of the longest segment datagram (the driver's receive size).
MAX_SEGMENT_BYTES = SEGMENT_HEADER.size + 3 * 8 * MAX_SEGMENT_JOINTS
# flags: the loop ends here (brake to rest and hold).
END_OF_RUN = 1

# Follower modes, in the order a run goes through them.
MODES = ("waiting", "following", "braking", "stopped")


class BadSegment(ValueError):  # noqa: N818 (named like the telemetry layer's BadPacket)
    """A command datagram that is not a segment; the message says why."""


@dataclasses.dataclass(frozen=True)
class CommandSegment:
    """The loop's command over one control period.

    Attributes:
        k: the control step: the segment holds over simulated time [k h, (k + 1) h).
        q, qd: the state the MCA read at k h, rad and rad/s (m and m/s for a prismatic
            joint), n floats each (the platform's joints, 1 to MAX_SEGMENT_JOINTS).
        u: the joint acceleration commanded over the period, rad/s^2 (m/s^2), n floats.
        end: the loop ends with this segment: the driver brakes to rest after it.
    """

    k: int
    q: tuple[float, ...]
    qd: tuple[float, ...]
    u: tuple[float, ...]
    end: bool = False

    def __post_init__(self) -> None:
        n = len(self.q)
        if not 1 <= n <= MAX_SEGMENT_JOINTS:
            raise ValueError(f"segment q must hold 1 to {MAX_SEGMENT_JOINTS} joints; got {n}")
        for name in ("q", "qd", "u"):
            values = tuple(map(float, getattr(self, name)))
            if len(values) != n or not all(map(math.isfinite, values)):
                raise ValueError(f"segment {name} must hold {n} finite numbers; got {values}")
            object.__setattr__(self, name, values)
        if self.k < 0:
            raise ValueError(f"segment step k must be >= 0; got {self.k}")

    def pack(self) -> bytes:
        """The segment as one datagram (`SEGMENT_HEADER`, then q, qd, u as doubles)."""
        flags = END_OF_RUN if self.end else 0
        return _segment_struct(len(self.q)).pack(
            SEGMENT_MAGIC, flags, self.k, *self.q, *self.qd, *self.u
        )

    @classmethod
    def unpack(cls, datagram: bytes, joints: int) -> "CommandSegment":
        """The segment of `joints` joints in `datagram`; BadSegment for anything else (a
        segment of another joint count included: the loop and the driver disagree on the
        platform)."""
        layout = _segment_struct(joints)
        if len(datagram) != layout.size:
            raise BadSegment(
                f"segment datagram of {len(datagram)} bytes; expected {layout.size} "
                f"({joints} joints)"
            )
        magic, flags, k, *values = layout.unpack(datagram)
        if magic != SEGMENT_MAGIC:
            raise BadSegment(f"segment datagram starts {magic!r}, not {SEGMENT_MAGIC!r}")
        if flags & ~END_OF_RUN:
            raise BadSegment(f"segment datagram has unknown flags {flags:#x}")
        n = joints
        try:
            return cls(k, values[:n], values[n : 2 * n], values[2 * n :], bool(flags))
        except ValueError as error:
            raise BadSegment(str(error)) from error


@functools.cache
def _segment_struct(joints: int) -> struct.Struct:
    """The wire layout of a segment of `joints` joints."""
    if not 1 <= joints <= MAX_SEGMENT_JOINTS:
        raise ValueError(f"a segment holds 1 to {MAX_SEGMENT_JOINTS} joints; got {joints}")
    return struct.Struct(SEGMENT_HEADER.format + f"{3 * joints}d")


class SegmentBuffer:
    """The most recent segments, by step, and the exact trajectory they make.

    Args:
        period_s: the loop's control period h, s.
        capacity: segments kept (older ones are dropped); must cover the driver's delay.
    """

    def __init__(self, period_s: float, capacity: int = 64):
        if not period_s > 0 or capacity < 2:
            raise ValueError("SegmentBuffer needs period_s > 0 and capacity >= 2")
        self.period_s = float(period_s)
        self.capacity = int(capacity)
        self._segments: dict[int, CommandSegment] = {}
        self.newest_k = -1  # the newest step held (-1: none yet)
        self.end_k: int | None = None  # the end-of-run segment's step, once sent

    def add(self, segment: CommandSegment) -> bool:
        """Keeps `segment`; False (and nothing kept) for one older than the capacity allows,
        a repeat of a held step, or one after the end of the run."""
        k = segment.k
        if k in self._segments or k <= self.newest_k - self.capacity:
            return False
        if self.end_k is not None and k > self.end_k:
            return False
        self._segments[k] = segment
        if segment.end:
            self.end_k = k
        if k > self.newest_k:
            self.newest_k = k
            for old in [j for j in self._segments if j <= k - self.capacity]:
                del self._segments[old]
        return True

    def lead_s(self, s: float) -> float:
        """How far (s) the held trajectory reaches beyond simulated time s (< 0: behind)."""
        return (self.newest_k + 1) * self.period_s - s

    def state_at(self, s: float) -> tuple[list[float], list[float], bool] | None:
        """(q, qd, end) at simulated time s by exact integration of the segment that holds
        there (`end`: s is past the end-of-run segment's start); None if it is not held."""
        k = math.floor(s / self.period_s + 1e-12)
        segment = self._segments.get(k)
        if segment is None:
            return None
        tau = s - k * self.period_s
        half_tau2 = 0.5 * tau * tau
        q = [
            a + b * tau + c * half_tau2
            for a, b, c in zip(segment.q, segment.qd, segment.u, strict=True)
        ]
        qd = [b + c * tau for b, c in zip(segment.qd, segment.u, strict=True)]
        return q, qd, segment.end


@dataclasses.dataclass
class RsiMotionConfig:
    """How the driver plays the loop's trajectory (module docstring)."""

    # The robot's interpolation cycle T, s (RSI runs at 4 or 12 ms).
    cycle_s: float = 0.004
    # The trajectory is played this long (s) behind the loop's simulated time: room for the
    # loop's latency, its phase and one period, so that a cycle's segment has come.
    delay_s: float = 0.025
    # Slack on the per-cycle checks, relative (round-off of the integration, not room to
    # exceed a limit: the MCA's commands are clamped to the same limits).
    relative_tolerance: float = 1e-6

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        if not 0 < self.cycle_s <= 0.1:
            raise ValueError(f"RsiMotionConfig.cycle_s must be in (0, 0.1] s; got {self.cycle_s}")
        if not self.delay_s > 0:
            raise ValueError(f"RsiMotionConfig.delay_s must be positive; got {self.delay_s}")
        if not 0 <= self.relative_tolerance < 1e-2:
            raise ValueError("RsiMotionConfig.relative_tolerance must be in [0, 0.01)")


class MotionFollower:
    """The commanded joint state, one robot cycle at a time (module docstring).

    Args:
        limits: the platform's limits: q_min, q_max (rad or m), qd_max (per s), qdd_max
            (per s^2), n values each (`mca_drake.platforms.serial.SerialChain` has them).
        home: the pose the robot starts at and the loop's first segment starts from (n).
        config: cycle, delay and tolerance.
        units: each joint's position unit in messages ("rad" or "m"; default all "rad").

    Attributes:
        q, qd: the state commanded last, rad and rad/s or m and m/s (n floats each).
        mode: one of MODES.
        reason: why the follower left "following" ("" while it has not).
    """

    def __init__(
        self,
        limits,
        home: Sequence[float],
        config: RsiMotionConfig | None = None,
        units: Sequence[str] = (),
    ):
        self.config = config or RsiMotionConfig()
        self.config.validate()
        q_min, q_max, qd_max, qdd_max = (list(map(float, v)) for v in limits)
        self._clamp = ViabilityClamp(q_min, q_max, qd_max, qdd_max, self.config.cycle_s)
        tol = self.config.relative_tolerance
        self._q_min = [v - tol * abs(v) - tol for v in q_min]
        self._q_max = [v + tol * abs(v) + tol for v in q_max]
        self._qd_max = [v * (1 + tol) for v in qd_max]
        self._qdd_max = [v * (1 + tol) for v in qdd_max]
        self.home = [float(v) for v in home]
        n = self.joints = len(q_min)
        if len(self.home) != n:
            raise ValueError(f"home must hold {n} joint positions; got {self.home}")
        self.units = list(units) or ["rad"] * n
        if len(self.units) != n:
            raise ValueError(f"units must name {n} joints' units; got {self.units}")
        if not self._clamp.is_viable(self.home + [0.0] * n):
            raise ValueError(f"home pose {self.home} is not inside the robot's limits")
        self.q, self.qd = list(self.home), [0.0] * n
        # the positions sent the cycle before self.q and the cycle's length: the robot rested
        # at home before, so the first target is checked as a start from rest
        self._previous: tuple[list[float], float] = (list(self.home), self.config.cycle_s)
        self.mode = "waiting"
        self.reason = ""

    def step(self, s: float, dt: float, buffer: SegmentBuffer) -> list[float]:
        """Advances the commanded state by one cycle of dt seconds (the robot's clock) to the
        trajectory at simulated time s; returns the commanded positions q (rad or m, n)."""
        sent_before = self.q  # what the controller holds now; _check differences against it
        if self.mode in ("waiting", "following"):
            target = buffer.state_at(s)
            if target is None:
                if self.mode == "following":
                    self._brake("no command for this cycle: the loop stalled or stopped")
            else:
                q, qd, end = target
                problem = self._check(q, qd, dt)
                if not problem:
                    self.q, self.qd, self.mode = q, qd, "following"
                    if end:
                        self._brake("the loop ended")  # braking from the next cycle
                    self._previous = (sent_before, dt)
                    return self.q
                self._brake(problem)
        if self.mode == "braking":  # the cycle that switched to braking brakes already
            self._braking_step(dt)
        self._previous = (sent_before, dt)
        return self.q

    def halt(self, reason: str) -> None:
        """Stops following for `reason`: brakes to rest from the state commanded last and
        holds there (nothing changes once braking or stopped)."""
        if self.mode in ("waiting", "following"):
            self._brake(reason)

    def _check(self, q: list[float], qd: list[float], dt: float) -> str:
        """Why the target (q, qd) one cycle of dt after the commanded state cannot be sent
        ("" if it can). Beside the state's limits, the positions sent are checked as the
        controller sees them, by differences: a trajectory within the limits has first
        differences within qd_max dt and second differences (a triangle-weighted mean of its
        acceleration) within qdd_max, and a jump in the commands has not."""
        sent, sent_dt = self._previous
        for j in range(self.joints):
            unit = self.units[j]
            velocity = (q[j] - self.q[j]) / dt
            if abs(velocity) > self._qd_max[j]:
                return (
                    f"joint {j + 1} moves {velocity:.4f} {unit}/s in a cycle: a jump in the "
                    "commands"
                )
            before = (self.q[j] - sent[j]) / sent_dt
            acceleration = (velocity - before) / (0.5 * (dt + sent_dt))
            if abs(acceleration) > self._qdd_max[j]:
                return (
                    f"joint {j + 1} acceleration {acceleration:.3f} {unit}/s^2 between cycles "
                    "over its limit: a jump in the commands"
                )
            if not self._q_min[j] <= q[j] <= self._q_max[j]:
                return f"joint {j + 1} position {q[j]:.4f} {unit} outside its limits"
            if abs(qd[j]) > self._qd_max[j]:
                return f"joint {j + 1} velocity {qd[j]:.4f} {unit}/s over its limit"
            mean_acceleration = (qd[j] - self.qd[j]) / dt
            if abs(mean_acceleration) > self._qdd_max[j]:
                return (
                    f"joint {j + 1} acceleration {mean_acceleration:.3f} {unit}/s^2 over its "
                    "limit: a jump in the commands"
                )
        if not self._clamp.is_viable(q + qd):
            return "the target leaves no room to brake inside the limits"
        return ""

    def _brake(self, reason: str) -> None:
        self.mode = "braking"
        self.reason = reason
        if not any(self.qd):
            self.mode = "stopped"

    def _braking_step(self, dt: float) -> None:
        """The strongest braking the viability clamp allows, over dt in steps of the cycle
        period (the clamp's exact zero-order-hold step; a dt of several cycles, after missed
        ones, takes as many steps)."""
        h = self.config.cycle_s
        for _ in range(max(1, round(dt / h))):
            wanted = [-v / h for v in self.qd]  # to rest in one step, if the limits allow
            u, _ = self._clamp(self.q + self.qd, wanted)
            u = u.tolist()
            self.q = [
                q + v * h + 0.5 * a * h * h for q, v, a in zip(self.q, self.qd, u, strict=True)
            ]
            self.qd = [v + a * h for v, a in zip(self.qd, u, strict=True)]
            if all(abs(v) < 1e-12 for v in self.qd):
                self.qd = [0.0] * self.joints
                self.mode = "stopped"
                return
