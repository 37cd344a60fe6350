"""The hexapod's inverse and forward kinematics against Drake's closed-chain model: the
platform as a free body, each leg a cylinder on a ball joint at its base joint with a rod
on a prismatic joint, the chains closed at the platform joints by position constraints,
solved by Drake's InverseKinematics (a model that shares no code with
`mca_drake.platforms.legs`)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BallRpyJoint, FixedOffsetFrame, PrismaticJoint, SpatialInertia
from pydrake.solvers import IpoptSolver, SnoptSolver, Solve, SolverOptions

from mca_drake.platforms.files import load_platform
from mca_drake.platforms.leg_platform import pose_of
from mca_drake.platforms.legs import leg_lengths, rotation

# What the solver's tolerances (below) allow the two to differ by (m, rad).
SOLVER_TOLERANCE = 1e-8


def tight() -> SolverOptions:
    """Feasibility and optimality tolerances well below SOLVER_TOLERANCE."""
    options = SolverOptions()
    options.SetOption(SnoptSolver.id(), "Major feasibility tolerance", 1e-12)
    options.SetOption(SnoptSolver.id(), "Major optimality tolerance", 1e-12)
    options.SetOption(IpoptSolver.id(), "tol", 1e-12)
    return options


def closed_chain(geometry):
    """A MultibodyPlant of the hexapod's bodies and joints (the loops open) and its parts."""
    plant = MultibodyPlant(0.0)
    inertia = SpatialInertia.SolidBoxWithMass(1.0, 0.1, 0.1, 0.1)
    platform = plant.AddRigidBody("platform", inertia)
    rods, legs = [], []
    for i, b in enumerate(np.asarray(geometry.base_joints, dtype=float)):
        base = plant.AddFrame(FixedOffsetFrame(f"b_{i}", plant.world_frame(), RigidTransform(b)))
        cylinder = plant.AddRigidBody(f"cylinder_{i}", inertia)
        rod = plant.AddRigidBody(f"rod_{i}", inertia)
        plant.AddJoint(BallRpyJoint(f"base_joint_{i}", base, cylinder.body_frame()))
        legs.append(
            plant.AddJoint(
                PrismaticJoint(f"leg_{i}", cylinder.body_frame(), rod.body_frame(), [0, 0, 1])
            )
        )
        rods.append(rod)
    plant.Finalize()
    return plant, platform, rods, legs


def closed_chain_ik(plant, platform, rods, geometry):
    ik = InverseKinematics(plant)
    for rod, p in zip(rods, np.asarray(geometry.platform_joints, dtype=float), strict=True):
        ik.AddPositionConstraint(
            frameB=rod.body_frame(),
            p_BQ=np.zeros(3),
            frameA=platform.body_frame(),
            p_AQ_lower=p,
            p_AQ_upper=p,
        )
    return ik


def initial_guess(plant, platform, legs, geometry, lengths):
    """Platform at the neutral pose, each leg's ball joint turned towards its platform joint."""
    context = plant.CreateDefaultContext()
    plant.SetFreeBodyPose(context, platform, RigidTransform([0.0, 0.0, geometry.neutral_height]))
    q = plant.GetPositions(context)
    for i, (b, p) in enumerate(
        zip(np.asarray(geometry.base_joints), np.asarray(geometry.platform_joints), strict=True)
    ):
        direction = p + np.array([0.0, 0.0, geometry.neutral_height]) - b
        direction /= np.linalg.norm(direction)
        R = RotationMatrix.MakeFromOneVector(direction, 2)
        ball = plant.GetJointByName(f"base_joint_{i}")
        rpy = R.ToRollPitchYaw().vector()
        q[ball.position_start() : ball.position_start() + 3] = rpy
        q[legs[i].position_start()] = lengths[i]
    return q


@pytest.fixture(scope="module")
def hexapod():
    return load_platform("hexapod")


def random_coordinates(hexapod, count, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.6 * hexapod.q_min, 0.6 * hexapod.q_max, size=(count, 6))


def test_drakes_closed_chain_gives_the_leg_lengths_of_a_pose(hexapod):
    g = hexapod.actuators
    plant, platform, rods, legs = closed_chain(g)
    for q in random_coordinates(hexapod, 5, seed=0):
        x, y, z, roll, pitch, yaw = pose_of(q)
        ik = closed_chain_ik(plant, platform, rods, g)
        X_WP = RigidTransform(
            RotationMatrix(rotation(roll, pitch, yaw)), [x, y, g.neutral_height + z]
        )
        # the platform's free-body positions held at the pose
        context = plant.CreateDefaultContext()
        plant.SetFreeBodyPose(context, platform, X_WP)
        held = plant.GetPositions(context)
        start = platform.floating_positions_start()
        ik.prog().AddBoundingBoxConstraint(
            held[start : start + 7], held[start : start + 7], ik.q()[start : start + 7]
        )
        guess = initial_guess(plant, platform, legs, g, leg_lengths(np.zeros(6), g))
        result = Solve(ik.prog(), guess, tight())
        assert result.is_success(), result.get_solver_id().name()
        solved = result.GetSolution(ik.q())
        drake_lengths = [solved[leg.position_start()] for leg in legs]
        np.testing.assert_allclose(
            drake_lengths, hexapod.actuator_positions(q), atol=SOLVER_TOLERANCE
        )


def test_drakes_closed_chain_gives_the_pose_of_the_leg_lengths(hexapod):
    # Forward kinematics: the legs fixed at our lengths, Drake finds the platform's pose.
    g = hexapod.actuators
    plant, platform, rods, legs = closed_chain(g)
    context = plant.CreateDefaultContext()
    for q in random_coordinates(hexapod, 5, seed=1):
        lengths = hexapod.actuator_positions(q)
        ik = closed_chain_ik(plant, platform, rods, g)
        for leg, length in zip(legs, lengths, strict=True):
            i = leg.position_start()
            ik.prog().AddBoundingBoxConstraint(length, length, ik.q()[i])
        result = Solve(ik.prog(), initial_guess(plant, platform, legs, g, lengths), tight())
        assert result.is_success(), result.get_solver_id().name()
        plant.SetPositions(context, result.GetSolution(ik.q()))
        X_WP = plant.EvalBodyPoseInWorld(context, platform)
        x, y, z, roll, pitch, yaw = pose_of(q)
        np.testing.assert_allclose(
            X_WP.translation(), [x, y, g.neutral_height + z], atol=SOLVER_TOLERANCE
        )
        np.testing.assert_allclose(
            X_WP.rotation().matrix(), rotation(roll, pitch, yaw), atol=SOLVER_TOLERANCE
        )
