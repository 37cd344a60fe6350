"""The KR500 motion simulator as described by models/kr500.urdf (the one source of truth).

Everything the library knows about the robot (joint names, Table I limits, the DH table,
the head frame X_6H) is read from the URDF through Drake's parser, so the numpy and torch
plants, the NMPC and the MultibodyPlant station can never disagree about the robot. Where
pydrake is not installed (a GPU machine that only trains), the standard library's XML parser
reads the same file the same way (tests compare the two).

The URDF encodes standard Denavit-Hartenberg kinematics (see tools/generate_kr500_urdf.py):
the origin of joint_(i+1) on link_i is Tz(d_i) Tx(a_i) Rx(alpha_i) Rz(offset_(i+1)), the
`flange` weld on link_6 is Tz(d_6) Tx(a_6) Rx(alpha_6) (DH frame 6) and the `head` weld on
the flange is X_6H. `load_kr500` recovers the DH table from those origins and fails loudly if
a URDF does not have that structure.
"""

from __future__ import annotations

import dataclasses
import functools
import os
from pathlib import Path

import numpy as np

from mca_drake.resources import drake_installed, packaged_folder

NUM_JOINTS = 6
JOINT_NAMES = tuple(f"joint_{i}" for i in range(1, NUM_JOINTS + 1))
# The KR500's left-right symmetry: with joints 1, 4 and 6 (the vertical and the two roll
# axes) turned the other way, the cabin moves as the mirror image of itself about the base's
# x-z plane, and its outputs are those of `conventions.MIRROR_CHANNEL_SIGNS` (the limits of
# those joints are symmetric).
MIRROR_JOINT_SIGNS = (-1.0, 1.0, 1.0, -1.0, 1.0, -1.0)
# Tolerance for "this URDF has DH structure" checks; URDF rpy round trips are ~1e-16.
_STRUCTURE_TOL = 1e-9


def models_dir() -> Path:
    """The folder holding kr500.urdf: the package's copy of models/ (`resources`)."""
    return packaged_folder("models")


def model_path(name: str = "kr500.urdf") -> Path:
    """Absolute path of a file in the models folder, e.g. `model_path("kr500.urdf")`."""
    path = models_dir() / name
    if not path.is_file():
        available = sorted(p.name for p in models_dir().iterdir())
        raise FileNotFoundError(f"no model '{name}' in {models_dir()}; available: {available}")
    return path


@dataclasses.dataclass(frozen=True)
class DhTable:
    """Standard DH parameters, one entry per joint (shape (6,) each).

    A_i(q_i) = Rz(q_i + offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i); lengths in m, angles in rad.
    """

    a: np.ndarray
    d: np.ndarray
    alpha: np.ndarray
    offset: np.ndarray


@dataclasses.dataclass(frozen=True)
class KR500:
    """Kinematic description of the KR500 simulator, read from the URDF.

    Attributes:
        urdf_path: the file it was read from.
        joint_names: URDF joint names in Table I order (joint_1 ... joint_6).
        q_min, q_max: position limits, rad, shape (6,).
        qd_max: symmetric velocity limits, rad/s, shape (6,).
        qdd_max: symmetric acceleration limits, rad/s^2, shape (6,).
        effort_max: symmetric joint torque limits, N m, shape (6,).
        dh: the DH table (Table I).
        X_6H: 4x4 homogeneous transform of the head frame H in DH frame 6.
    """

    urdf_path: Path
    joint_names: tuple[str, ...]
    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    qdd_max: np.ndarray
    effort_max: np.ndarray
    dh: DhTable
    X_6H: np.ndarray

    @property
    def R_6H(self) -> np.ndarray:
        """Rotation of H in DH frame 6, shape (3, 3)."""
        return self.X_6H[:3, :3]

    @property
    def p_6H(self) -> np.ndarray:
        """Position of H's origin in DH frame 6, m, shape (3,)."""
        return self.X_6H[:3, 3]

    @property
    def x_min(self) -> np.ndarray:
        """Lower state bound [q_min, -qd_max], shape (12,)."""
        return np.concatenate([self.q_min, -self.qd_max])

    @property
    def x_max(self) -> np.ndarray:
        """Upper state bound [q_max, qd_max], shape (12,)."""
        return np.concatenate([self.q_max, self.qd_max])


def _split_dh_origin(X: np.ndarray, what: str) -> tuple[float, float, float, float]:
    """(a, d, alpha, offset) of X = Tz(d) Tx(a) Rx(alpha) Rz(offset); raises if X is not so."""
    R, p = X[:3, :3], X[:3, 3]
    if abs(p[1]) > _STRUCTURE_TOL or abs(R[0, 2]) > _STRUCTURE_TOL:
        raise ValueError(
            f"{what}: origin is not of DH form Tz(d) Tx(a) Rx(alpha) Rz(offset) "
            f"(p_y = {p[1]:.3g}, R[0, 2] = {R[0, 2]:.3g}, both should be 0)"
        )
    offset = float(np.arctan2(-R[0, 1], R[0, 0]))
    alpha = float(np.arctan2(-R[1, 2], R[2, 2]))
    return float(p[0]), float(p[2]), alpha, offset


@dataclasses.dataclass(frozen=True)
class _UrdfJoint:
    """What `load_kr500` reads of one URDF joint (angles rad, lengths m, SI limits)."""

    X_parent: np.ndarray  # pose of the joint frame in its parent link, 4x4
    at_child_origin: bool  # the joint frame is the child link's frame (always, in URDF)
    axis: np.ndarray  # revolute axis in the joint frame, (3,)
    lower: float
    upper: float
    velocity: tuple[float, float]  # (lower, upper) limits
    acceleration: tuple[float, float]  # (lower, upper) limits; inf where not given
    effort: float


def _joints_with_drake(path: str) -> dict[str, _UrdfJoint]:
    """The joints of `path` as Drake's parser reads them (the MultibodyPlant station's view)."""
    # Imported here so that `import mca_drake.robot` stays cheap for the numpy-only paths.
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    plant = MultibodyPlant(0.0)
    try:
        Parser(plant).AddModels(path)
    except RuntimeError as err:
        raise ValueError(f"cannot parse robot model {path}: {err}") from err
    plant.Finalize()
    efforts = {}
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        efforts[actuator.joint().name()] = actuator.effort_limit()
    joints = {}
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        revolute = joint.num_velocities() == 1
        X_child = joint.frame_on_child().GetFixedPoseInBodyFrame().GetAsMatrix4()

        def first(values, default=0.0):
            return float(values[0]) if len(values) else default

        joints[joint.name()] = _UrdfJoint(
            X_parent=joint.frame_on_parent().GetFixedPoseInBodyFrame().GetAsMatrix4(),
            at_child_origin=bool(np.allclose(X_child, np.eye(4), atol=_STRUCTURE_TOL)),
            axis=np.asarray(joint.revolute_axis()) if revolute else np.zeros(3),
            lower=first(joint.position_lower_limits()),
            upper=first(joint.position_upper_limits()),
            velocity=(
                first(joint.velocity_lower_limits()),
                first(joint.velocity_upper_limits()),
            ),
            acceleration=(
                first(joint.acceleration_lower_limits()),
                first(joint.acceleration_upper_limits()),
            ),
            effort=float(efforts.get(joint.name(), np.inf)),
        )
    return joints


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's rpy: R = Rz(yaw) Ry(pitch) Rx(roll), (3, 3)."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (np.cos, np.sin))
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _joints_with_xml(path: str) -> dict[str, _UrdfJoint]:
    """The joints of `path` read with the standard library's XML parser, as the URDF
    specification (and Drake's parser, tested to agree on models/kr500.urdf) reads them:
    the torch training path uses this where pydrake is not installed."""
    # Imported here: only machines without Drake read the URDF this way.
    import xml.etree.ElementTree as ET

    drake_ns = "{http://drake.mit.edu}"
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as err:
        raise ValueError(f"cannot parse robot model {path}: {err}") from err

    def numbers(element, name: str, default: str, count: int) -> list[float]:
        text = default if element is None else element.get(name, default)
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            values = []
        if len(values) != count:
            raise ValueError(f"{path}: {name}={text!r} must be {count} numbers")
        return values

    joints = {}
    for joint in root.findall("joint"):  # the robot's joints, not a transmission's
        origin = joint.find("origin")
        X = np.eye(4)
        X[:3, :3] = _rpy_matrix(*numbers(origin, "rpy", "0 0 0", 3))
        X[:3, 3] = numbers(origin, "xyz", "0 0 0", 3)
        limit = joint.find("limit")
        revolute = joint.get("type") in ("revolute", "continuous")

        def value(name: str, default: float, limit=limit) -> float:
            return default if limit is None else numbers(limit, name, str(default), 1)[0]

        velocity = value("velocity", np.inf) if revolute else 0.0
        acceleration = value(f"{drake_ns}acceleration", np.inf) if revolute else 0.0
        joints[joint.get("name")] = _UrdfJoint(
            X_parent=X,
            at_child_origin=True,
            axis=np.array(numbers(joint.find("axis"), "xyz", "1 0 0", 3))
            if revolute
            else np.zeros(3),
            lower=value("lower", -np.inf) if revolute else 0.0,
            upper=value("upper", np.inf) if revolute else 0.0,
            velocity=(-velocity, velocity),
            acceleration=(-acceleration, acceleration),
            effort=value("effort", np.inf) if revolute else np.inf,
        )
    return joints


def _urdf_joints(path: str) -> dict[str, _UrdfJoint]:
    """Drake's parser where pydrake is installed (the station's own view of the file), the
    XML reader elsewhere (tests/test_robot.py checks that both read the same KR500)."""
    if drake_installed():
        return _joints_with_drake(path)
    return _joints_with_xml(path)


@functools.lru_cache(maxsize=8)
def _load_cached(path: str) -> KR500:
    joints = _urdf_joints(path)

    def fixed_pose(joint_name: str) -> np.ndarray:
        joint = joints[joint_name]
        if not joint.at_child_origin:
            raise ValueError(f"{path}: {joint_name} must sit at its child link's origin")
        return joint.X_parent

    missing = [n for n in (*JOINT_NAMES, "flange_weld", "head_weld") if n not in joints]
    if missing:
        raise ValueError(f"{path}: missing joints {missing}; a KR500 model needs {JOINT_NAMES}")
    if "base_weld" in joints and not np.allclose(
        fixed_pose("base_weld"), np.eye(4), atol=_STRUCTURE_TOL
    ):
        raise ValueError(f"{path}: the base must be welded to the world at the identity")

    a, d, alpha, offset = (np.zeros(NUM_JOINTS) for _ in range(4))
    for i, name in enumerate(JOINT_NAMES):
        if not np.allclose(joints[name].axis, [0.0, 0.0, 1.0], atol=_STRUCTURE_TOL):
            raise ValueError(f"{path}: {name} must rotate about its z axis (DH convention)")
        a_prev, d_prev, alpha_prev, offset[i] = _split_dh_origin(fixed_pose(name), name)
        if i == 0:
            if max(abs(a_prev), abs(d_prev), abs(alpha_prev)) > _STRUCTURE_TOL:
                raise ValueError(f"{path}: joint_1 must sit at the world origin (DH frame 0 = W)")
        else:
            a[i - 1], d[i - 1], alpha[i - 1] = a_prev, d_prev, alpha_prev
    a[5], d[5], alpha[5], flange_offset = _split_dh_origin(fixed_pose("flange_weld"), "flange_weld")
    if abs(flange_offset) > _STRUCTURE_TOL:
        raise ValueError(f"{path}: flange_weld must not rotate about z (it is DH frame 6)")

    robot_joints = [joints[n] for n in JOINT_NAMES]

    def limits(getter) -> np.ndarray:
        return np.array([float(getter(j)) for j in robot_joints])

    qd_lo, qd_hi = limits(lambda j: j.velocity[0]), limits(lambda j: j.velocity[1])
    qdd_lo, qdd_hi = limits(lambda j: j.acceleration[0]), limits(lambda j: j.acceleration[1])
    if not (np.allclose(qd_lo, -qd_hi) and np.allclose(qdd_lo, -qdd_hi)):
        raise ValueError(f"{path}: velocity and acceleration limits must be symmetric")
    if not np.all(np.isfinite(qdd_hi)):
        raise ValueError(f"{path}: every joint needs drake:acceleration on its <limit>")
    robot = KR500(
        urdf_path=Path(path),
        joint_names=JOINT_NAMES,
        q_min=limits(lambda j: j.lower),
        q_max=limits(lambda j: j.upper),
        qd_max=qd_hi,
        qdd_max=qdd_hi,
        effort_max=limits(lambda j: j.effort),
        dh=DhTable(a=a, d=d, alpha=alpha, offset=offset),
        X_6H=fixed_pose("head_weld"),
    )
    # The description is cached and shared: freeze its arrays so nobody edits it in place.
    for owner in (robot, robot.dh):
        for field in dataclasses.fields(owner):
            value = getattr(owner, field.name)
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
    return robot


def load_kr500(urdf_path: str | os.PathLike | None = None) -> KR500:
    """Loads the KR500 description (cached per path).

    Args:
        urdf_path: a URDF with the KR500 structure; default models/kr500.urdf.

    Raises:
        ValueError: the file does not parse or does not have DH structure.
    """
    path = Path(urdf_path) if urdf_path is not None else model_path("kr500.urdf")
    if not path.is_file():
        raise FileNotFoundError(f"robot model not found: {path}")
    return _load_cached(str(path.resolve()))
