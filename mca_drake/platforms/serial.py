"""A serial motion platform: the chain of joints from the world to the occupant's head.

`SerialChain` is what every MCA, plant and clamp knows of a serial robot (with or without a
rail): its joints in chain order, each revolute or prismatic with any origin and axis as a
maker writes them in a URDF, their limits, the head frame H on the last link and the home
(neutral) pose. It is read from the URDF (`serial_chain_from_urdf`), the one source of
truth that the MultibodyPlant station parses too, so the numpy and torch plants, the NMPC
and the station can never disagree about the robot.

Normal form. Fixed joints are folded into the next moving joint, and each moving joint's
frame is turned so that its axis is its z axis: joint i moves its frame M_i relative to the
previous one M_(i-1) (the world for i = 1) by

    X_(i-1),i(q_i) = X_prev[i] Rz(q_i)      (revolute)
    X_(i-1),i(q_i) = X_prev[i] Tz(q_i)      (prismatic)

and the head is X_nH = X_last_H in the last frame M_n. The KR500's URDF (whose joints turn
about z already) gives its origins unchanged.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mca_drake.platforms.urdf_chain import MOVING_KINDS, STRUCTURE_TOL, UrdfModel, read_urdf

# The joint count of the paper's six-axis models: the learned plant models of Table II
# (`mca_drake.learning.state_models`, `output_models`) and their excitation data, which
# are the KR500's alone; everything else takes the platform's joint count.
NUM_JOINTS = 6
# How level the head frame must be at home: |1 - (R_WH)_zz| below this.
LEVEL_TOL = 1e-6


@dataclasses.dataclass(frozen=True)
class SerialChain:
    """Kinematic description of a serial motion platform (arrays read-only, SI units).

    Attributes:
        name: the platform's name ("kr500", "kr500-rail", or a user's).
        urdf_path: the file it was read from.
        head_frame: the URDF frame or link that is the occupant's head H.
        joint_names: URDF names of the moving joints, base to tip (n of them).
        joint_kinds: "revolute" or "prismatic" per joint.
        X_prev: pose of each joint's frame in the previous joint's moving frame (the
            world for the first), with the joint's axis along z, shape (n, 4, 4).
        X_last_H: pose of H in the last joint's moving frame, 4x4.
        q_min, q_max: position limits, rad or m, shape (n,).
        qd_max: symmetric velocity limits, rad/s or m/s, shape (n,).
        qdd_max: symmetric acceleration limits, rad/s^2 or m/s^2, shape (n,).
        effort_max: symmetric effort limits, N m or N, shape (n,).
        home: the neutral pose, shape (n,): where a run starts and a wash-out returns.
        washout_home: the pose the classical washout's inverse kinematics works about, away
            from singularities (the head level there too), shape (n,).
        mirror_joint_signs: joint signs that mirror the cabin's motion about the world's
            x-z plane (`conventions.MIRROR_CHANNEL_SIGNS` on the outputs), shape (n,);
            empty where the platform has no such symmetry.
    """

    name: str
    urdf_path: Path
    head_frame: str
    joint_names: tuple[str, ...]
    joint_kinds: tuple[str, ...]
    X_prev: np.ndarray
    X_last_H: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    qdd_max: np.ndarray
    effort_max: np.ndarray
    home: np.ndarray
    washout_home: np.ndarray
    mirror_joint_signs: np.ndarray

    kind = "serial"

    @property
    def num_joints(self) -> int:
        """The number of moving joints n (the platform's coordinates)."""
        return len(self.joint_names)

    @property
    def prismatic(self) -> np.ndarray:
        """Which joints are prismatic, bool shape (n,)."""
        return np.array([kind == "prismatic" for kind in self.joint_kinds])

    @property
    def actuator_names(self) -> tuple[str, ...]:
        """The actuators a rig's controller drives, in order: a serial robot's joints."""
        return self.joint_names

    def actuator_positions(self, q) -> np.ndarray:
        """The actuators' positions (rad or m) of coordinates q (..., n): a serial robot's
        actuators are its joints, so q itself (a hexapod's are its legs' lengths)."""
        return np.asarray(q, dtype=float)

    @property
    def head_velocity_components(self) -> tuple[bool, ...]:
        """Which components of the head's spatial velocity [w_x, w_y, w_z, v_x, v_y, v_z] the
        platform can follow independently (what a washout's inverse kinematics tracks): all
        six on a serial robot (a rig moving in fewer coordinates says which)."""
        return (True,) * 6

    @property
    def x_min(self) -> np.ndarray:
        """Lower state bound [q_min, -qd_max], shape (2n,)."""
        return np.concatenate([self.q_min, -self.qd_max])

    @property
    def x_max(self) -> np.ndarray:
        """Upper state bound [q_max, qd_max], shape (2n,)."""
        return np.concatenate([self.q_max, self.qd_max])

    def summary(self) -> dict:
        """The platform as a run's summary and a policy file name it: name, kind, joint
        count and joint names."""
        return {
            "name": self.name,
            "kind": self.kind,
            "dof": self.num_joints,
            "joints": list(self.joint_names),
        }


def _axis_to_z(axis: np.ndarray) -> np.ndarray:
    """A rotation R (3, 3) with R e_z = axis: the shortest turn of z onto the unit axis."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(axis @ z)
    if c > 1.0 - STRUCTURE_TOL:
        return np.eye(3)
    if c < -1.0 + STRUCTURE_TOL:
        return np.diag([1.0, -1.0, -1.0])  # half a turn about x
    k = np.cross(z, axis)
    s = float(np.linalg.norm(k))
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]]) / s
    return np.eye(3) + s * K + (1.0 - c) * K @ K


def _homogeneous(R: np.ndarray) -> np.ndarray:
    X = np.eye(4)
    X[:3, :3] = R
    return X


def _chain_to(model: UrdfModel, link: str) -> list:
    """The joints from the world to `link`, world first."""
    by_child = {}
    for joint in model.joints.values():
        if joint.child in by_child:
            raise ValueError(f"{model.path}: link '{joint.child}' has two parent joints")
        by_child[joint.child] = joint
    chain, seen = [], set()
    while link != "world":
        if link not in by_child:
            raise ValueError(
                f"{model.path}: link '{link}' is not attached to the world (add a fixed joint "
                "from 'world' to the robot's base)"
            )
        if link in seen:
            raise ValueError(f"{model.path}: the joints around '{link}' form a loop")
        seen.add(link)
        chain.append(by_child[link])
        link = by_child[link].parent
    return chain[::-1]


def serial_chain_from_urdf(
    urdf_path: str | os.PathLike,
    *,
    name: str,
    head_frame: str = "head",
    home: Sequence[float] = (),
    washout_home: Sequence[float] = (),
    acceleration_limits: Sequence[float] = (),
    mirror_joint_signs: Sequence[float] = (),
) -> SerialChain:
    """Reads a serial platform from a URDF (cached per arguments).

    Args:
        urdf_path: the URDF; the robot's base is welded to `world` (directly or through
            fixed joints), revolute (or continuous) and prismatic joints with any origin and
            axis lead to the head frame.
        name: the platform's name.
        head_frame: the URDF link or frame that is the occupant's head H (x forward, y left,
            z up: level at home).
        home: the neutral pose, one value per joint (rad or m); default all zeros.
        washout_home: the classical washout's working pose (see `SerialChain`); default home.
        acceleration_limits: per joint (rad/s^2 or m/s^2), for a URDF without
            `drake:acceleration`; where both are given they must agree.
        mirror_joint_signs: per joint, the signs that mirror the motion (see `SerialChain`).

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file does not parse; the head frame is unknown or not reached by a
            chain of revolute, prismatic and fixed joints; a moving joint outside the chain;
            missing, asymmetric or non-positive limits; a home pose outside the limits or
            whose head frame is not level.
    """
    path = Path(urdf_path)
    if not path.is_file():
        raise FileNotFoundError(f"robot model not found: {path}")
    return _load_cached(
        str(path.resolve()),
        name,
        head_frame,
        tuple(float(v) for v in home),
        tuple(float(v) for v in washout_home),
        tuple(float(v) for v in acceleration_limits),
        tuple(float(v) for v in mirror_joint_signs),
    )


@functools.lru_cache(maxsize=32)
def _load_cached(path, name, head_frame, home, washout_home, acceleration_limits, mirror_signs):
    return _build(
        read_urdf(path), name, head_frame, home, washout_home, acceleration_limits, mirror_signs
    )


def _build(
    model: UrdfModel,
    name: str,
    head_frame: str,
    home: tuple,
    washout_home: tuple,
    acceleration_limits: tuple,
    mirror_joint_signs: tuple,
) -> SerialChain:
    path = model.path
    if head_frame not in model.frames:
        raise ValueError(
            f"{path}: no frame or link named '{head_frame}' (the head frame); links and "
            f"frames: {', '.join(sorted(model.frames))}"
        )
    head_link, X_LinkH = model.frames[head_frame]
    chain = _chain_to(model, head_link)
    moving = [j for j in chain if j.kind in MOVING_KINDS]
    if not moving:
        raise ValueError(f"{path}: no revolute or prismatic joint leads to '{head_frame}'")
    others = [j.name for j in model.joints.values() if j.kind in MOVING_KINDS and j not in chain]
    if others:
        raise ValueError(
            f"{path}: moving joints {others} are not on the chain from the world to "
            f"'{head_frame}'; a serial platform moves the head through one chain"
        )
    # The MultibodyPlant station orders its positions as the file lists the joints.
    in_file = [name for name, j in model.joints.items() if j.kind in MOVING_KINDS]
    if in_file != [j.name for j in moving]:
        raise ValueError(
            f"{path}: list the moving joints from the base to the head ({[j.name for j in moving]}"
            f"); the file lists {in_file}"
        )
    # Walk the chain: T is the pose of the current link in the last moving frame (the world
    # before the first joint).
    X_prev, T = [], np.eye(4)
    for joint in chain:
        if joint.kind == "fixed":
            T = T @ joint.X_PJ @ np.linalg.inv(joint.X_CJ)
            continue
        turn = _homogeneous(_axis_to_z(joint.axis))
        X_prev.append(T @ joint.X_PJ @ turn)
        T = turn.T @ np.linalg.inv(joint.X_CJ)
    X_last_H = T @ X_LinkH

    n = len(moving)

    def limits(getter) -> np.ndarray:
        return np.array([float(getter(j)) for j in moving])

    q_min, q_max = limits(lambda j: j.position[0]), limits(lambda j: j.position[1])
    qd_lo, qd_hi = limits(lambda j: j.velocity[0]), limits(lambda j: j.velocity[1])
    qdd_lo, qdd_hi = limits(lambda j: j.acceleration[0]), limits(lambda j: j.acceleration[1])
    names = [j.name for j in moving]
    if not (np.all(np.isfinite(q_min)) and np.all(np.isfinite(q_max))):
        raise ValueError(f"{path}: every joint of {names} needs finite lower and upper limits")
    if not np.all(q_min < q_max):
        raise ValueError(f"{path}: lower limits must be below upper ones ({q_min}, {q_max})")
    if not (np.allclose(qd_lo, -qd_hi) and np.allclose(qdd_lo, -qdd_hi)):
        raise ValueError(f"{path}: velocity and acceleration limits must be symmetric")
    if acceleration_limits:
        given = _per_joint("acceleration_limits", acceleration_limits, n)
        known = np.isfinite(qdd_hi)
        if not np.allclose(given[known], qdd_hi[known]):
            raise ValueError(
                f"{path}: acceleration_limits {given.tolist()} differ from the URDF's "
                f"drake:acceleration {qdd_hi.tolist()}"
            )
        qdd_hi = given
    if not np.all(np.isfinite(qdd_hi)):
        raise ValueError(
            f"{path}: every joint needs an acceleration limit: drake:acceleration on its "
            "<limit>, or the platform's acceleration_limits"
        )
    if not (np.all(qd_hi > 0) and np.all(np.isfinite(qd_hi)) and np.all(qdd_hi > 0)):
        raise ValueError(f"{path}: velocity and acceleration limits must be positive and finite")
    home_q = _per_joint("home", home, n) if home else np.zeros(n)
    washout_q = _per_joint("washout_home", washout_home, n) if washout_home else home_q.copy()
    for what, pose in (("home", home_q), ("washout_home", washout_q)):
        if not np.all((q_min < pose) & (pose < q_max)):
            raise ValueError(f"{path}: {what} {pose.tolist()} is not strictly inside the limits")
    mirror = (
        _per_joint("mirror_joint_signs", mirror_joint_signs, n)
        if mirror_joint_signs
        else (np.zeros(0))
    )
    if mirror.size and not np.all(np.abs(mirror) == 1.0):
        raise ValueError(f"mirror_joint_signs must be +-1 each; got {mirror.tolist()}")
    chain_description = SerialChain(
        name=name,
        urdf_path=Path(path),
        head_frame=head_frame,
        joint_names=tuple(names),
        joint_kinds=tuple(j.kind for j in moving),
        X_prev=np.array(X_prev),
        X_last_H=X_last_H,
        q_min=q_min,
        q_max=q_max,
        qd_max=qd_hi,
        qdd_max=qdd_hi,
        effort_max=limits(lambda j: j.effort),
        home=home_q,
        washout_home=washout_q,
        mirror_joint_signs=mirror,
    )
    R_WH = _head_pose_at(chain_description, home_q)[:3, :3]
    if abs(1.0 - R_WH[2, 2]) > LEVEL_TOL:
        raise ValueError(
            f"{path}: the head frame '{head_frame}' is not level at home (its z axis is "
            f"{np.round(R_WH[:, 2], 6).tolist()} in the world, should be up); turn it in the "
            "URDF or choose another home"
        )
    # The description is cached and shared: freeze its arrays so nobody edits it in place.
    for field in dataclasses.fields(chain_description):
        value = getattr(chain_description, field.name)
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
    return chain_description


def _per_joint(what: str, values: Sequence[float], n: int) -> np.ndarray:
    array = np.asarray(values, dtype=float)
    if array.shape != (n,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{what} needs {n} finite values, one per joint; got {list(values)}")
    return array


def check_joint_count(robot: SerialChain, n: int, what: str) -> None:
    """Raises ValueError naming `what` unless `robot` has `n` joints."""
    if robot.num_joints != n:
        raise ValueError(
            f"{what} is made for {n} joints; platform '{robot.name}' has {robot.num_joints}"
        )


def joint_motion(kind: str, q: float) -> np.ndarray:
    """The motion of a joint in normal form, 4x4: Rz(q) (revolute) or Tz(q) (prismatic)."""
    X = np.eye(4)
    if kind == "prismatic":
        X[2, 3] = q
    else:
        X[:2, :2] = [[math.cos(q), -math.sin(q)], [math.sin(q), math.cos(q)]]
    return X


def _head_pose_at(robot: SerialChain, q: np.ndarray) -> np.ndarray:
    """X_WH at one pose q (n,), 4x4: the chain product, for load-time checks (the batched
    kinematics are `mca_drake.platforms.kinematics`)."""
    X = np.eye(4)
    for X_prev, kind, q_i in zip(robot.X_prev, robot.joint_kinds, q, strict=True):
        X = X @ X_prev @ joint_motion(kind, float(q_i))
    return X @ robot.X_last_H
