"""Shared fixtures: the robot description, an independent Drake MultibodyPlant, a seeded RNG."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from mca_drake.robot import load_kr500, model_path


@pytest.fixture(scope="session")
def robot():
    return load_kr500()


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
