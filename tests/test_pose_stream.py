"""The pose stream for VR motion compensation: the quaternion against Drake's, and a live
run's lines against the head pose Drake's MultibodyPlant gives for the positions reached."""

from __future__ import annotations

import numpy as np
import pytest
from drake_oracle import drake_head_pose
from pydrake.math import RollPitchYaw, RotationMatrix

from mca_drake.conventions import CONTROL_PERIOD_S as H
from mca_drake.live.pose_stream import PoseStreamSender, quaternion_wxyz


def test_the_quaternion_is_drakes(rng):
    for _ in range(200):
        R = RotationMatrix(RollPitchYaw(*rng.uniform(-np.pi, np.pi, 3)))
        q = R.ToQuaternion()
        expected = np.array([q.w(), q.x(), q.y(), q.z()]) * (1 if q.w() >= 0 else -1)
        np.testing.assert_allclose(quaternion_wxyz(R.matrix()), expected, atol=1e-12)
    # half turns (w = 0) and the identity
    for R in (np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.eye(3)):
        q = np.array(quaternion_wxyz(R))
        assert np.linalg.norm(q) == pytest.approx(1.0)
        np.testing.assert_allclose(RotationMatrix(R).ToQuaternion().wxyz() @ q, 1.0, atol=1e-12)


def test_a_stream_that_is_not_udp_is_refused(robot):
    with pytest.raises(ValueError, match="udp://HOST:PORT"):
        PoseStreamSender("serial:///dev/ttyS0?baud=9600", robot, np.zeros(6), H)


def test_a_live_run_streams_the_heads_pose_from_home(tmp_path, drake_plant):
    from test_rig_output import live_run_listened

    summary, datagrams, rows = live_run_listened(tmp_path, lambda url: {"pose_stream": url})
    lines = [datagram.decode() for datagram in datagrams]
    assert summary["pose_stream"]["sent"] == len(lines) >= 190
    values = np.array([[float(v) for v in line.strip().split(",")] for line in lines])
    q = np.column_stack([rows[name] for name in rows.dtype.names if name.startswith("q_")])
    context = drake_plant.CreateDefaultContext()
    X_WH0 = drake_head_pose(drake_plant, context, q[0])  # the run starts at home, at rest
    for k in range(0, min(len(values), len(q)) - 1, 10):
        t, position, quaternion = values[k, 0], values[k, 1:4], values[k, 4:]
        assert t == pytest.approx((k + 1) * H)
        # line k: the head where the platform is at the next instant, the trajectory's k + 1
        X_H0H = np.linalg.inv(X_WH0) @ drake_head_pose(drake_plant, context, q[k + 1])
        np.testing.assert_allclose(position, X_H0H[:3, 3], atol=1e-8)
        expected = RotationMatrix(X_H0H[:3, :3]).ToQuaternion().wxyz()
        np.testing.assert_allclose(quaternion, expected * np.sign(expected[0]), atol=1e-8)
    assert np.ptp(values[:, 1:4], axis=0).max() > 1e-4  # the head moved
