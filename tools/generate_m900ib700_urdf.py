"""Writes models/fanuc_m900ib700.urdf: a FANUC M-900iB/700 carrying a motion-simulator cabin (a
developer tool, run by hand):

    python tools/generate_m900ib700_urdf.py > models/fanuc_m900ib700.urdf

Kinematics and limits. The joint origins, axes, position limits and velocity limits are
ROS-Industrial's description of the robot (github.com/ros-industrial/fanuc,
fanuc_m900ib_support/urdf/m900ib700_macro.xacro): joint 1 0.94 m above the floor, 0.41 m
out to joint 2, a 1.12 m upper arm, 0.25 m to the forearm, a 1.285 m forearm and 0.30 m to
the flange, the axes as written there (joints 3 and 5 turn about -y, joints 4 and 6 about
-x). That description leaves out what a simulator needs and FANUC does not publish, stated
here as estimates:

- accelerations: none published; the KR500's Table I values of the joint with the same role
  (1.676, 1.197, 2.189, 0.564, 1.625, 1.317 rad/s^2), a heavy robot's of the same class;
- efforts: sized like the KR500's, enough to hold and accelerate the arm and a 600 kg cabin;
- masses: about 2.6 t of links (the M-900iB/700's class), each link a solid cylinder along
  its segments; the cabin 600 kg (shell, seat, occupant), a solid box.

The parallel link and the balancers of ROS-Industrial's description are mimic joints that
move with joints 2 and 3 and carry no motion of their own; they are left out (their masses
are in the links'). The head frame is level at q = 0 (x forward, z up), 0.5 m in front of
and 0.9 m above the flange.
"""

from __future__ import annotations

import numpy as np
from cabin_link import box_inertia, cabin_xml

# joint: (origin xyz on the parent link, axis, lower, upper (rad), velocity (rad/s))
JOINTS = [
    ((0.0, 0.0, 0.940), (0, 0, 1), -3.1415, 3.1415, 1.3962),
    ((0.410, 0.0, 0.0), (0, 1, 0), -1.1170, 1.5707, 1.3962),
    ((0.0, 0.0, 1.120), (0, -1, 0), -2.2689, 0.5235, 1.3962),
    ((0.0, 0.0, 0.250), (-1, 0, 0), -6.2831, 6.2831, 1.7453),
    ((1.285, 0.0, 0.0), (0, -1, 0), -2.1293, 2.1293, 1.7453),
    ((0.300, 0.0, 0.0), (-1, 0, 0), -6.2831, 6.2831, 2.7925),
]
QDD_MAX = [1.676, 1.197, 2.189, 0.564, 1.625, 1.317]  # rad/s^2, estimates (see above)
EFFORT = [45000.0, 60000.0, 30000.0, 12000.0, 12000.0, 8000.0]  # N m, sized
LINK_MASS = [900.0, 700.0, 400.0, 350.0, 150.0, 80.0]  # kg
LINK_RADIUS = [0.40, 0.30, 0.25, 0.22, 0.18, 0.16]  # m, of the cylinder model
# Each link's straight segments in its own frame (the next joint's origin is the last end).
SEGMENTS = [
    [((0.0, 0.0, -0.45), (0.0, 0.0, 0.0)), ((0.0, 0.0, 0.0), (0.410, 0.0, 0.0))],
    [((0.0, 0.0, 0.0), (0.0, 0.0, 1.120))],
    [((0.0, 0.0, 0.0), (0.0, 0.0, 0.250))],
    [((0.0, 0.0, 0.0), (1.285, 0.0, 0.0))],
    [((0.0, 0.0, 0.0), (0.300, 0.0, 0.0))],
    [],
]
CABIN_MASS = 600.0  # kg
CABIN_SIZE = (1.6, 1.4, 1.8)  # m, along x (forward at q = 0), y, z (up)
CABIN_CENTER = (0.8, 0.0, 0.7)  # m, in link 6's frame
HEAD = (0.5, 0.0, 0.9)  # m, in link 6's frame; level

COLORS = {
    "base": "0.25 0.25 0.25 1",
    "robot": "0.98 0.84 0.0 1",  # FANUC yellow
    "wrist": "0.2 0.2 0.2 1",
    "cabin": "0.85 0.87 0.9 0.9",
}


def _rotation_to(direction: np.ndarray) -> np.ndarray:
    """A rotation matrix taking +z to the unit vector `direction`."""
    z = direction / np.linalg.norm(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (R = Rz(y) Ry(p) Rx(r)) of a rotation matrix."""
    pitch = float(np.arcsin(-np.clip(R[2, 0], -1.0, 1.0)))
    if abs(np.cos(pitch)) > 1e-9:
        return float(np.arctan2(R[2, 1], R[2, 2])), pitch, float(np.arctan2(R[1, 0], R[0, 0]))
    return float(np.arctan2(-R[1, 2], R[1, 1])), pitch, 0.0


def _fmt(values) -> str:
    return " ".join(f"{float(v) + 0.0:.12g}" for v in values)


def _cylinder(start, end, radius: float, material: str, tag: str) -> str:
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = float(np.linalg.norm(end - start))
    rpy = _rpy(_rotation_to(end - start))
    mat = f'<material name="{material}"/>' if tag == "visual" else ""
    return (
        f'    <{tag}><origin xyz="{_fmt((start + end) / 2)}" rpy="{_fmt(rpy)}"/><geometry>'
        f'<cylinder radius="{radius}" length="{length:.12g}"/></geometry>{mat}</{tag}>'
    )


def _inertial(mass: float, com, inertia: np.ndarray) -> str:
    entries = " ".join(
        f'i{a}="{float(inertia[r, c]):.12g}"'
        for a, r, c in (
            ("xx", 0, 0),
            ("xy", 0, 1),
            ("xz", 0, 2),
            ("yy", 1, 1),
            ("yz", 1, 2),
            ("zz", 2, 2),
        )
    )
    return (
        f'    <inertial><origin xyz="{_fmt(com)}" rpy="0 0 0"/><mass value="{mass:.12g}"/>'
        f"<inertia {entries}/></inertial>"
    )


def link_inertial(i: int) -> str:
    """Solid cylinders along link i's segments (a housing cylinder where it has none)."""
    m, r = LINK_MASS[i], LINK_RADIUS[i]
    segments = [(np.asarray(s, float), np.asarray(e, float)) for s, e in SEGMENTS[i]]
    if not segments:
        side = m * (3 * r**2 + (2 * r) ** 2) / 12
        return _inertial(m, np.zeros(3), np.diag([m * r**2 / 2, side, side]))
    lengths = np.array([np.linalg.norm(e - s) for s, e in segments])
    masses = m * lengths / lengths.sum()
    com = sum(mi * (s + e) / 2 for mi, (s, e) in zip(masses, segments, strict=True)) / m
    inertia = np.zeros((3, 3))
    for mi, (s, e), length in zip(masses, segments, lengths, strict=True):
        R = _rotation_to(e - s)
        local = np.diag([mi * (3 * r**2 + length**2) / 12] * 2 + [mi * r**2 / 2])
        c = (s + e) / 2 - com
        inertia += R @ local @ R.T + mi * (c @ c * np.eye(3) - np.outer(c, c))
    return _inertial(m, com, inertia)


def main() -> None:
    out = [
        '<?xml version="1.0"?>',
        "<!-- FANUC M-900iB/700 motion simulator with cabin. Generated by",
        "     tools/generate_m900ib700_urdf.py from ROS-Industrial's m900ib700_macro.xacro",
        "     (kinematics, position and velocity limits); that script states the estimates",
        "     (accelerations, efforts, masses). `head` is the occupant's head frame H. -->",
        '<robot name="m900ib700" xmlns:drake="http://drake.mit.edu">',
    ]
    out += [f'  <material name="{k}"><color rgba="{v}"/></material>' for k, v in COLORS.items()]
    out += [
        '  <link name="base_link">',
        _inertial(1200.0, (0.0, 0.0, 0.25), np.diag([150.0, 150.0, 200.0])),
        '    <visual><origin xyz="0 0 0.25" rpy="0 0 0"/><geometry><box size="1.3 1.3 0.5"/>'
        '</geometry><material name="base"/></visual>',
        "  </link>",
        '  <joint name="base_weld" type="fixed"><parent link="world"/><child link="base_link"/>'
        '<origin xyz="0 0 0" rpy="0 0 0"/></joint>',
    ]
    parent = "base_link"
    for i, (xyz, axis, lower, upper, velocity) in enumerate(JOINTS):
        name = f"link_{i + 1}"
        material = "robot" if i < 4 else "wrist"
        r = LINK_RADIUS[i]
        visuals = [_cylinder(s, e, r, material, "visual") for s, e in SEGMENTS[i]]
        collisions = [_cylinder(s, e, r, material, "collision") for s, e in SEGMENTS[i]]
        out += [f'  <link name="{name}">', link_inertial(i), *visuals, *collisions, "  </link>"]
        out += [
            f'  <joint name="joint_{i + 1}" type="revolute">',
            f'    <parent link="{parent}"/><child link="{name}"/>',
            f'    <origin xyz="{_fmt(xyz)}" rpy="0 0 0"/>',
            f'    <axis xyz="{_fmt(axis)}"/>',
            f'    <limit lower="{lower}" upper="{upper}" velocity="{velocity}" '
            f'effort="{EFFORT[i]}" drake:acceleration="{QDD_MAX[i]}"/>',
            "  </joint>",
            # A transmission gives Drake a joint actuator, with `effort` as its torque limit.
            f'  <transmission name="joint_{i + 1}_transmission" type="SimpleTransmission">'
            f'<joint name="joint_{i + 1}"/><actuator name="joint_{i + 1}_motor"/>'
            "</transmission>",
        ]
        parent = name
    out += cabin_xml(
        _inertial(CABIN_MASS, np.zeros(3), box_inertia(CABIN_MASS, CABIN_SIZE)),
        _fmt(CABIN_SIZE),
        "link_6",
        _fmt(CABIN_CENTER),
    )
    out += [
        '  <link name="head"/>',
        '  <joint name="head_weld" type="fixed"><parent link="link_6"/><child link="head"/>'
        f'<origin xyz="{_fmt(HEAD)}" rpy="0 0 0"/></joint>',
        "</robot>",
    ]
    print("\n".join(out))


if __name__ == "__main__":
    main()
