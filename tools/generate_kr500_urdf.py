"""Writes models/kr500.urdf from the paper's Table I (a developer tool, run by hand).

The URDF is the project's single source of truth; this script only documents how its
numbers were obtained so that a reviewer can regenerate and diff it:

    python tools/generate_kr500_urdf.py > models/kr500.urdf

Kinematics. Standard Denavit-Hartenberg: A_i(q_i) = Rz(q_i + offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i).
A URDF joint rotates *after* its fixed origin, so the DH product is regrouped as

    link_i frame = DH frame (i-1) rotated by Rz(q_i + offset_i)
    origin of joint_1      = Rz(offset_1)                                  (DH frame 0 = world)
    origin of joint_(i+1)  = Tz(d_i) Tx(a_i) Rx(alpha_i) Rz(offset_(i+1))  on link_i
    origin of flange weld  = Tz(d_6) Tx(a_6) Rx(alpha_6)                   on link_6 (= DH frame 6)
    origin of head weld    = X_6H                                          on flange

Table I prints alpha and offset rounded to 3 decimals (1.571); they are +-pi/2 exactly,
which is what makes R_WH = I at q = 0 (the README's "Conventions").

Inertia. Plausible KR500-class numbers (about 2.4 t of links, from the public KR500
data sheet mass class), each link a solid cylinder along its DH segments, plus a 600 kg
cabin (shell, seat, occupant) as a solid box on the flange.
"""

from __future__ import annotations

import math

import numpy as np
from cabin_link import box_inertia, cabin_xml
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

PI_2 = math.pi / 2
# Table I, joints 1..6.
Q_UPPER = [3.229, 1.920, 0.942, 6.109, 2.094, 6.109]
Q_LOWER = [-3.229, -0.698, -3.316, -6.109, -2.094, -6.109]
QD_MAX = [1.571, 1.396, 1.309, 1.571, 1.449, 2.269]
QDD_MAX = [1.676, 1.197, 2.189, 0.564, 1.625, 1.317]
DH_A = [0.500, 1.300, -0.055, 0.0, 0.0, 0.0]
DH_D = [1.045, 0.0, 0.0, 1.025, 0.0, 0.290]
DH_ALPHA = [-PI_2, 0.0, -PI_2, PI_2, -PI_2, 0.0]
DH_OFFSET = [0.0, -PI_2, 0.0, 0.0, 0.0, 0.0]
# Plausible joint torque limits (N m) for a KR500-class robot with a 600 kg payload.
EFFORT = [40000.0, 50000.0, 25000.0, 12000.0, 12000.0, 8000.0]
LINK_MASS = [700.0, 600.0, 450.0, 400.0, 150.0, 100.0]  # kg, 2400 in all
LINK_RADIUS = [0.35, 0.25, 0.22, 0.18, 0.16, 0.15]  # m, of the cylinder model
CABIN_MASS = 600.0  # kg: shell, seat, occupant
CABIN_SIZE = (1.8, 1.4, 1.6)  # m, along flange x (up at q=0), y, z (forward at q=0)
CABIN_CENTER = (0.7, 0.0, 0.8)  # m, in the flange (DH 6) frame
R_6H = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
P_6H = np.array([0.9, 0.0, 0.5])

COLORS = {
    "base": "0.25 0.25 0.25 1",
    "robot": "0.96 0.49 0.0 1",  # KUKA orange
    "wrist": "0.2 0.2 0.2 1",
    "cabin": "0.85 0.87 0.9 0.9",
}


def origin(X: RigidTransform) -> str:
    rpy = RollPitchYaw(X.rotation()).vector()
    p = X.translation()

    def fmt(values) -> str:
        # repr keeps every digit: the DH numbers must survive the round trip exactly.
        return " ".join(repr(float(v) + 0.0) for v in values)

    return f'<origin xyz="{fmt(p)}" rpy="{fmt(rpy)}"/>'


def Rx(a: float) -> RigidTransform:
    return RigidTransform(RotationMatrix.MakeXRotation(a), np.zeros(3))


def Rz(a: float) -> RigidTransform:
    return RigidTransform(RotationMatrix.MakeZRotation(a), np.zeros(3))


def T(x: float, y: float, z: float) -> RigidTransform:
    return RigidTransform(np.array([x, y, z]))


def dh_tail(i: int) -> RigidTransform:
    """Tz(d_i) Tx(a_i) Rx(alpha_i) for 0-based joint index i."""
    return T(DH_A[i], 0.0, DH_D[i]) @ Rx(DH_ALPHA[i])


def segments(i: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Straight segments (start, end) of link i+1 in its own frame: up d_i, then out a_i."""
    p0, p1, p2 = np.zeros(3), np.array([0.0, 0.0, DH_D[i]]), np.array([DH_A[i], 0.0, DH_D[i]])
    return [(s, e) for s, e in ((p0, p1), (p1, p2)) if np.linalg.norm(e - s) > 1e-9]


def cylinder_between(start, end, radius, material, tag="visual") -> str:
    axis = end - start
    length = float(np.linalg.norm(axis))
    center = (start + end) / 2
    z = axis / length
    # rotation taking +z to the segment direction
    R = RotationMatrix.MakeFromOneVector(z, 2)
    X = RigidTransform(R, center)
    mat = f'<material name="{material}"/>' if tag == "visual" else ""
    return (
        f'    <{tag}>{origin(X)}<geometry><cylinder radius="{radius}" length="{length:.12g}"/>'
        f"</geometry>{mat}</{tag}>"
    )


def joint_housing(radius, material, tag="visual") -> str:
    mat = f'<material name="{material}"/>' if tag == "visual" else ""
    return (
        f'    <{tag}><origin xyz="0 0 0" rpy="0 0 0"/><geometry><cylinder radius="{radius}" '
        f'length="{2 * radius:.12g}"/></geometry>{mat}</{tag}>'
    )


def link_inertial(i: int) -> str:
    """Solid cylinders along the segments (housing only when the link has no length)."""
    m, r = LINK_MASS[i], LINK_RADIUS[i]
    segs = segments(i)
    if not segs:  # a wrist link with no DH length: a housing cylinder about its joint axis
        ixx = iyy = m * (3 * r**2 + (2 * r) ** 2) / 12
        izz = m * r**2 / 2
        return inertial(m, np.zeros(3), np.diag([ixx, iyy, izz]))
    lengths = np.array([np.linalg.norm(e - s) for s, e in segs])
    masses = m * lengths / lengths.sum()
    com = sum(mi * (s + e) / 2 for mi, (s, e) in zip(masses, segs, strict=True)) / m
    inertia = np.zeros((3, 3))
    for mi, (s, e), L in zip(masses, segs, lengths, strict=True):
        z = (e - s) / L
        R = RotationMatrix.MakeFromOneVector(z, 2).matrix()
        I_local = np.diag([mi * (3 * r**2 + L**2) / 12] * 2 + [mi * r**2 / 2])
        c = (s + e) / 2 - com
        inertia += R @ I_local @ R.T + mi * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    return inertial(m, com, inertia)


def inertial(m, com, inertia) -> str:
    c = [f"{float(v):.12g}" for v in com]
    inertia_xml = " ".join(
        f'i{a}{b}="{float(inertia[row, col]):.12g}"'
        for a, b, row, col in (
            ("x", "x", 0, 0),
            ("x", "y", 0, 1),
            ("x", "z", 0, 2),
            ("y", "y", 1, 1),
            ("y", "z", 1, 2),
            ("z", "z", 2, 2),
        )
    )
    return (
        f'    <inertial><origin xyz="{c[0]} {c[1]} {c[2]}" rpy="0 0 0"/>'
        f'<mass value="{float(m):.12g}"/><inertia {inertia_xml}/></inertial>'
    )


def main() -> None:
    out = [
        '<?xml version="1.0"?>',
        "<!-- KUKA KR500 motion simulator with cabin. Generated by tools/generate_kr500_urdf.py",
        "     from Table I of the paper (standard DH); see that script for the conventions.",
        "     Link i's frame is DH frame (i-1) rotated by q_i + offset_i about its z axis;",
        "     `flange` is DH frame 6; `head` is the occupant's head frame H. -->",
        '<robot name="kr500" xmlns:drake="http://drake.mit.edu">',
    ]
    out += [f'  <material name="{k}"><color rgba="{v}"/></material>' for k, v in COLORS.items()]
    # Base pedestal below DH frame 0 (ground at z = -0.0; the pedestal is visual only).
    out += [
        '  <link name="base">',
        inertial(1000.0, np.array([0.0, 0.0, -0.15]), np.diag([100.0, 100.0, 150.0])),
        '    <visual><origin xyz="0 0 -0.15" rpy="0 0 0"/><geometry><box size="1.2 1.2 0.3"/>'
        '</geometry><material name="base"/></visual>',
        "  </link>",
        '  <joint name="base_weld" type="fixed"><parent link="world"/><child link="base"/>'
        '<origin xyz="0 0 0" rpy="0 0 0"/></joint>',
    ]
    parent = "base"
    for i in range(6):
        name = f"link_{i + 1}"
        mat = "robot" if i < 4 else "wrist"
        r = LINK_RADIUS[i]
        parts = [cylinder_between(s, e, r, mat) for s, e in segments(i)]
        parts.append(joint_housing(r * 1.15, "wrist"))
        coll = [cylinder_between(s, e, r, mat, "collision") for s, e in segments(i)]
        out += [f'  <link name="{name}">', link_inertial(i), *parts, *coll, "  </link>"]
        X_P_joint = (dh_tail(i - 1) if i > 0 else RigidTransform()) @ Rz(DH_OFFSET[i])
        out += [
            f'  <joint name="joint_{i + 1}" type="revolute">',
            f'    <parent link="{parent}"/><child link="{name}"/>',
            f"    {origin(X_P_joint)}",
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{Q_LOWER[i]}" upper="{Q_UPPER[i]}" velocity="{QD_MAX[i]}" '
            f'effort="{EFFORT[i]}" drake:acceleration="{QDD_MAX[i]}"/>',
            "  </joint>",
            # A transmission gives Drake a joint actuator, with `effort` as its torque limit.
            f'  <transmission name="joint_{i + 1}_transmission" type="SimpleTransmission">'
            f'<joint name="joint_{i + 1}"/><actuator name="joint_{i + 1}_motor"/>'
            "</transmission>",
        ]
        parent = name
    out += [
        '  <link name="flange"/>',
        '  <joint name="flange_weld" type="fixed"><parent link="link_6"/>'
        f'<child link="flange"/>{origin(dh_tail(5))}</joint>',
    ]
    out += cabin_xml(
        inertial(CABIN_MASS, np.zeros(3), box_inertia(CABIN_MASS, CABIN_SIZE)),
        " ".join(str(v) for v in CABIN_SIZE),
        "flange",
        " ".join(str(v) for v in CABIN_CENTER),
    )
    out += [
        '  <link name="head"/>',
        '  <joint name="head_weld" type="fixed"><parent link="flange"/><child link="head"/>'
        f"{origin(RigidTransform(RotationMatrix(R_6H), P_6H))}</joint>",
        "</robot>",
    ]
    print("\n".join(out))


if __name__ == "__main__":
    main()
