"""Independent computations with Drake's MultibodyPlant: the oracles of the kinematics tests."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable

G = 9.81


def drake_plant_of(urdf: str) -> MultibodyPlant:
    """A finalized MultibodyPlant parsed from the URDF at `urdf`."""
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(urdf)
    plant.Finalize()
    return plant


def drake_head_pose(plant, context, q, head: str = "head") -> np.ndarray:
    """X_WH (4, 4) of the frame `head` at positions q."""
    plant.SetPositions(context, q)
    return plant.GetFrameByName(head).CalcPoseInWorld(context).GetAsMatrix4()


def drake_plant_output(plant, context, q, qd, qdd, head: str = "head") -> np.ndarray:
    """y from Drake: head spatial velocity, J qdd + bias acceleration, pose."""
    plant.SetPositions(context, q)
    plant.SetVelocities(context, qd)
    frame, world = plant.GetFrameByName(head), plant.world_frame()
    R_WH = frame.CalcPoseInWorld(context).rotation().matrix()
    omega_W = frame.CalcSpatialVelocityInWorld(context).rotational()
    J = plant.CalcJacobianSpatialVelocity(
        context, JacobianWrtVariable.kV, frame, np.zeros(3), world, world
    )
    bias = plant.CalcBiasSpatialAcceleration(
        context, JacobianWrtVariable.kV, frame, np.zeros(3), world, world
    )
    A = J @ qdd + bias.get_coeffs()  # [alpha_W; a_W]
    a_H = R_WH.T @ A[3:]
    f_H = R_WH.T @ (A[3:] - np.array([0.0, 0.0, -G]))
    return np.concatenate([R_WH.T @ omega_W, f_H[:2], a_H[2:]])
