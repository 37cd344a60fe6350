"""The cabin's pose for VR motion compensation: every control period, where the occupant's
head is relative to its home pose, on a UDP stream of its own.

One ASCII line per control period, just after the command:

    t,x,y,z,qw,qx,qy,qz\\n

`t` the loop time (s) of the period's end; `x, y, z` the head frame's displacement from its
home pose (m) and `qw, qx, qy, qz` its rotation from the home orientation (a unit
quaternion, w first, qw >= 0), both expressed in the home head frame H0 (x forward, y left,
z up): X_H0H = X_WH0^-1 X_WH, with the head at the period's end (q + h qd + h^2 u / 2), as
the rig output sends its actuators. A VR runtime that subtracts this pose from the headset's
tracked pose sees the world hold still while the cabin moves.
"""

import math
import socket

import numpy as np
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from mca_drake.live.recorder import AFTER_COMMAND_S
from mca_drake.live.rig_output import positions_at_period_end, where
from mca_drake.platforms.kinematics import head_pose
from mca_drake.platforms.serial import SerialChain


def quaternion_wxyz(R: np.ndarray) -> list[float]:
    """The unit quaternion (w, x, y, z), w >= 0, of a rotation matrix R (3, 3)."""
    trace = R[0, 0] + R[1, 1] + R[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    else:
        i = int(np.argmax([R[0, 0], R[1, 1], R[2, 2]]))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + R[i, i] - R[j, j] - R[k, k], 0.0))
        q = [0.0] * 4
        q[0] = (R[k, j] - R[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + k] = (R[k, i] + R[i, k]) / s
    norm = math.sqrt(sum(v * v for v in q))
    sign = -1.0 if q[0] < 0 else 1.0
    return [sign * v / norm for v in q]


def pose_line(t: float, X_H0H: np.ndarray) -> bytes:
    """The stream's line for time `t` (s) and the head's pose relative to home (4, 4)."""
    values = [t, *X_H0H[:3, 3], *quaternion_wxyz(X_H0H[:3, :3])]
    return (",".join(f"{v:.9f}" for v in values) + "\n").encode()


class PoseStreamSender(LeafSystem):
    """Sends the head's pose relative to home every control period (module docstring) to
    `url` (udp://HOST:PORT).

    .. pydrake_system::

        name: PoseStreamSender
        input_ports:
        - state
        - command

    `state` (2n): [q, qd] now; `command` (n): the acceleration over the period.
    """

    def __init__(self, url: str, robot: SerialChain, home: np.ndarray, period_s: float):
        super().__init__()
        kind, address = where(url)
        if kind != "udp":
            raise ValueError(f"the pose stream goes to udp://HOST:PORT; got {url!r}")
        self._address, self.url = address, url
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._socket.setblocking(False)
        self._robot, self._h, self._n = robot, period_s, robot.num_joints
        self._home_inverse = np.linalg.inv(head_pose(np.asarray(home, dtype=float), robot))
        self._state = self.DeclareVectorInputPort("state", 2 * self._n)
        self._command = self.DeclareVectorInputPort("command", self._n)
        self.DeclarePeriodicPublishEvent(period_s, AFTER_COMMAND_S, self._send)
        self.sent = self.failed = 0

    def _send(self, context: Context) -> EventStatus:
        h = self._h
        q = positions_at_period_end(self._state.Eval(context), self._command.Eval(context), h)
        t_end = (round(context.get_time() / h) + 1) * h  # (published just after the instant)
        line = pose_line(t_end, self._home_inverse @ head_pose(q, self._robot))
        try:
            self._socket.sendto(line, self._address)
            self.sent += 1
        except OSError:
            self.failed += 1
        return EventStatus.Succeeded()

    def close(self) -> None:
        """Closes the socket."""
        self._socket.close()

    def summary(self) -> dict:
        """The summary's `pose_stream` block: where, lines sent and failed."""
        return {"url": self.url, "sent": self.sent, "failed": self.failed}


__all__ = ["PoseStreamSender", "pose_line", "quaternion_wxyz"]
