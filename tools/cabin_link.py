"""The cabin link that the robot generators (`generate_kr500_urdf.py`,
`generate_m900ib700_urdf.py`) weld to a robot's last link: a solid box of the cabin's mass."""

from __future__ import annotations

import numpy as np


def box_inertia(mass: float, size) -> np.ndarray:
    """The rotational inertia (kg m^2) about its centre of a solid box of `mass` (kg) and
    edge lengths `size` (m, along x, y, z), shape (3, 3)."""
    box = np.asarray(size, dtype=float)
    return np.diag([mass / 12 * (box[(k + 1) % 3] ** 2 + box[(k + 2) % 3] ** 2) for k in range(3)])


def cabin_xml(inertial: str, size: str, parent: str, center: str) -> list[str]:
    """The URDF lines of the `cabin` link (its `inertial` element, a box of edge lengths
    `size` drawn and colliding) welded to `parent` with its centre at `center` ("x y z")."""
    return [
        '  <link name="cabin">',
        inertial,
        f'    <visual><origin xyz="0 0 0" rpy="0 0 0"/><geometry><box size="{size}"/>'
        '</geometry><material name="cabin"/></visual>',
        f'    <collision><origin xyz="0 0 0" rpy="0 0 0"/><geometry><box size="{size}"/>'
        "</geometry></collision>",
        "  </link>",
        f'  <joint name="cabin_weld" type="fixed"><parent link="{parent}"/><child link="cabin"/>'
        f'<origin xyz="{center}" rpy="0 0 0"/></joint>',
    ]
