"""The joints of a URDF as a robot maker writes them, read with Drake's parser or without it.

A serial motion platform (`mca_drake.platforms.serial`) is the chain of joints from the
world to its head frame. This module reads what that needs of every joint: its kind
(revolute, prismatic, fixed), parent and child links, the pose of its frame in the parent
link (URDF `<origin xyz rpy>`, any values), its axis (any unit vector) and its limits
(position, velocity, `drake:acceleration`, effort). Drake's parser is used where pydrake is
installed (the MultibodyPlant station's own view of the file); the standard library's XML
parser elsewhere (a GPU machine that only trains), reading the file as the URDF
specification and Drake do (tests/test_platforms.py checks that both agree).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from mca_drake.resources import drake_installed

# Joint kinds of a platform's chain; "fixed" joints are folded into the next moving one.
MOVING_KINDS = ("revolute", "prismatic")
# Tolerance for "this pose is the identity" checks; URDF rpy round trips are ~1e-16.
STRUCTURE_TOL = 1e-9


@dataclasses.dataclass(frozen=True)
class UrdfJoint:
    """What a platform needs of one URDF joint (angles rad, lengths m, SI limits).

    Attributes:
        name: the joint's name.
        kind: "revolute", "prismatic" or "fixed" (URDF "continuous" reads as revolute
            without position limits).
        parent, child: the names of the links it connects ("world" for the world).
        X_PJ: pose of the joint frame J in the parent link's frame, 4x4 (`<origin>`).
        X_CJ: pose of the joint frame in the child link's frame, 4x4 (the identity in URDF).
        axis: unit axis in J, shape (3,); zeros for a fixed joint.
        position: (lower, upper) limits, rad or m; infinite where not given.
        velocity: (lower, upper) limits, rad/s or m/s; infinite where not given.
        acceleration: (lower, upper) limits, rad/s^2 or m/s^2; infinite where not given.
        effort: symmetric effort limit, N m or N; infinite where not given.
    """

    name: str
    kind: str
    parent: str
    child: str
    X_PJ: np.ndarray
    X_CJ: np.ndarray
    axis: np.ndarray
    position: tuple[float, float]
    velocity: tuple[float, float]
    acceleration: tuple[float, float]
    effort: float


@dataclasses.dataclass(frozen=True)
class UrdfModel:
    """The joints of a URDF and where its named frames sit.

    Attributes:
        path: the file.
        joints: by name, in file order.
        frames: extra frames by name: (link, pose in that link, 4x4). Every link is also a
            frame (at the identity in itself), so a head frame may be a link or a frame.
    """

    path: str
    joints: dict[str, UrdfJoint]
    frames: dict[str, tuple[str, np.ndarray]]


def read_urdf(path: str) -> UrdfModel:
    """The joints of the URDF at `path`, with Drake's parser where pydrake is installed.

    Raises:
        ValueError: the file does not parse.
    """
    if drake_installed():
        return read_urdf_with_drake(path)
    return read_urdf_with_xml(path)


def read_urdf_with_drake(path: str) -> UrdfModel:
    """The joints of `path` as Drake's parser reads them (the MultibodyPlant's view)."""
    # Imported here so that reading a platform stays cheap for the numpy-only paths.
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

    def first(values, default: float) -> float:
        return float(values[0]) if len(values) else default

    def link_name(body) -> str:
        return "world" if body.index() == plant.world_body().index() else body.name()

    joints = {}
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        kind = {"revolute": "revolute", "prismatic": "prismatic", "weld": "fixed"}.get(
            joint.type_name()
        )
        if kind is None:
            raise ValueError(
                f"{path}: joint '{joint.name()}' is a {joint.type_name()} joint; a platform's "
                f"chain takes revolute, prismatic and fixed joints (a robot whose base is not "
                "attached to the world reads as floating: add a fixed joint from 'world')"
            )
        if kind == "revolute":
            axis = np.asarray(joint.revolute_axis(), dtype=float)
        elif kind == "prismatic":
            axis = np.asarray(joint.translation_axis(), dtype=float)
        else:
            axis = np.zeros(3)
        moving = kind != "fixed"
        joints[joint.name()] = UrdfJoint(
            name=joint.name(),
            kind=kind,
            parent=link_name(joint.parent_body()),
            child=link_name(joint.child_body()),
            X_PJ=joint.frame_on_parent().GetFixedPoseInBodyFrame().GetAsMatrix4(),
            X_CJ=joint.frame_on_child().GetFixedPoseInBodyFrame().GetAsMatrix4(),
            axis=axis,
            position=(
                first(joint.position_lower_limits(), -math.inf) if moving else 0.0,
                first(joint.position_upper_limits(), math.inf) if moving else 0.0,
            ),
            velocity=(
                first(joint.velocity_lower_limits(), -math.inf) if moving else 0.0,
                first(joint.velocity_upper_limits(), math.inf) if moving else 0.0,
            ),
            acceleration=(
                first(joint.acceleration_lower_limits(), -math.inf) if moving else 0.0,
                first(joint.acceleration_upper_limits(), math.inf) if moving else 0.0,
            ),
            effort=float(efforts.get(joint.name(), math.inf)),
        )
    return UrdfModel(path=path, joints=joints, frames=_drake_frames(plant, link_name))


def _drake_frames(plant, link_name) -> dict[str, tuple[str, np.ndarray]]:
    """Every named frame of `plant` (links' own frames and URDF `<frame>` elements)."""
    # Imported here: only the Drake reader calls this.
    from pydrake.multibody.tree import FrameIndex

    frames = {}
    for index in range(plant.num_frames()):
        frame = plant.get_frame(FrameIndex(index))
        name = frame.name()
        if not name or name.startswith("_") or name in frames:
            continue
        X_BF = frame.GetFixedPoseInBodyFrame().GetAsMatrix4()
        frames[name] = (link_name(frame.body()), X_BF)
    return frames


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's rpy: R = Rz(yaw) Ry(pitch) Rx(roll), (3, 3)."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (np.cos, np.sin))
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def read_urdf_with_xml(path: str) -> UrdfModel:
    """The joints of `path` read with the standard library's XML parser, as the URDF
    specification (and Drake's parser, tested to agree) reads them: the torch training path
    uses this where pydrake is not installed."""
    # Imported here: only machines without Drake read the URDF this way.
    import xml.etree.ElementTree as ET

    drake_ns = "{http://drake.mit.edu}"
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as err:
        raise ValueError(f"cannot parse robot model {path}: {err}") from err

    def numbers(element, name: str, default: str, count: int, finite: bool = False) -> list:
        text = default if element is None else element.get(name, default)
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            values = []
        wrong = [v for v in values if math.isnan(v) or (finite and math.isinf(v))]
        if len(values) != count or wrong:
            raise ValueError(f"{path}: {name}={text!r} must be {count} numbers")
        return values

    def pose(element) -> np.ndarray:
        X = np.eye(4)
        X[:3, :3] = rpy_matrix(*numbers(element, "rpy", "0 0 0", 3, finite=True))
        X[:3, 3] = numbers(element, "xyz", "0 0 0", 3, finite=True)
        return X

    joints = {}
    for joint in root.findall("joint"):  # the robot's joints, not a transmission's
        kind = joint.get("type")
        if kind == "continuous":
            kind = "revolute"
        if kind not in (*MOVING_KINDS, "fixed"):
            raise ValueError(
                f"{path}: joint '{joint.get('name')}' is of type {kind!r}; a platform's chain "
                "takes revolute, continuous, prismatic and fixed joints"
            )
        limit = joint.find("limit")
        moving = kind != "fixed"
        bounded = moving and joint.get("type") != "continuous"

        def value(name: str, default: float, limit=limit) -> float:
            return default if limit is None else numbers(limit, name, str(default), 1)[0]

        velocity = value("velocity", math.inf) if moving else 0.0
        acceleration = value(f"{drake_ns}acceleration", math.inf) if moving else 0.0
        axis = np.zeros(3)
        if moving:
            axis = np.array(numbers(joint.find("axis"), "xyz", "1 0 0", 3, finite=True))
            norm = float(np.linalg.norm(axis))
            if norm < STRUCTURE_TOL:
                raise ValueError(f"{path}: joint '{joint.get('name')}' has a zero axis")
            axis = axis / norm
        joints[joint.get("name")] = UrdfJoint(
            name=joint.get("name"),
            kind=kind,
            parent=joint.find("parent").get("link"),
            child=joint.find("child").get("link"),
            X_PJ=pose(joint.find("origin")),
            X_CJ=np.eye(4),
            axis=axis,
            position=(
                value("lower", -math.inf) if bounded else (-math.inf if moving else 0.0),
                value("upper", math.inf) if bounded else (math.inf if moving else 0.0),
            ),
            velocity=(-velocity, velocity),
            acceleration=(-acceleration, acceleration),
            effort=value("effort", math.inf) if moving else math.inf,
        )
    frames = {link.get("name"): (link.get("name"), np.eye(4)) for link in root.findall("link")}
    frames.setdefault("world", ("world", np.eye(4)))
    for frame in root.findall(f"{drake_ns}frame") + root.findall("frame"):
        frames[frame.get("name")] = (frame.get("link"), pose(frame))
    return UrdfModel(path=path, joints=joints, frames=frames)
