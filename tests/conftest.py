"""Shared fixtures: the robot description, an independent Drake MultibodyPlant, a seeded RNG."""

from __future__ import annotations

import socket

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from mca_drake.live.rsi.motion import CommandSegment
from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform, model_path
from mca_drake.safety import ViabilityClamp


@pytest.fixture(scope="session")
def robot():
    return load_platform(DEFAULT_PLATFORM)


@pytest.fixture(scope="session")
def drake_plant():
    """MultibodyPlant parsed from models/kr500.urdf: the independent oracle."""
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(model_path("kr500.urdf")))
    plant.Finalize()
    return plant


@pytest.fixture
def rng():
    return np.random.default_rng(20251121)


def random_joint_states(rng, robot, n: int):
    """n random (q, qd, qdd) strictly inside the Table I limits, each shape (n, 6)."""
    q = rng.uniform(robot.q_min, robot.q_max, size=(n, 6))
    qd = rng.uniform(-robot.qd_max, robot.qd_max, size=(n, 6))
    qdd = rng.uniform(-robot.qdd_max, robot.qdd_max, size=(n, 6))
    return q, qd, qdd


RSI_LOOP_PERIOD = H = 0.01  # the live loop's control period, s


def limits_of(robot):
    return [robot.q_min, robot.q_max, robot.qd_max, robot.qdd_max]


def mca_like_segments(robot, rng, steps: int, gain: float = 0.8) -> list[CommandSegment]:
    """Segments of a random but viable run from home at rest, as the loop sends them: the
    state x_k and the clamped command u_k (a random walk in acceleration, clamped as every
    MCA's command is)."""
    clamp = ViabilityClamp.for_robot(robot, H)
    n = robot.num_joints
    q, qd = np.array(robot.home, float), np.zeros(n)
    wish = np.zeros(n)
    segments = []
    for k in range(steps):
        wish = 0.9 * wish + gain * robot.qdd_max * rng.normal(size=n) * 0.5
        u, _ = clamp(np.r_[q, qd], wish)
        segments.append(CommandSegment(k, q, qd, u))
        q, qd = q + H * qd + 0.5 * H * H * u, qd + H * u
    return segments


def free_udp_port() -> int:
    """A UDP port free on loopback now (for a test's listener that needs its number first)."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    return port
