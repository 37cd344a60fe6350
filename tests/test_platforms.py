"""Motion platforms: packaged files, both URDF readers, the load-time checks, and the
kinematics of any serial chain (revolute and prismatic joints, any origin and axis) against
Drake's MultibodyPlant on the same URDF, finite differences and the torch twin."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch
from drake_oracle import drake_head_pose, drake_plant_of, drake_plant_output
from pydrake.math import RollPitchYaw, RotationMatrix

from mca_drake.app.cli import main
from mca_drake.app.jobs import run_closed_loop_scenario
from mca_drake.app.scenarios import load_scenario
from mca_drake.conventions import MIRROR_CHANNEL_SIGNS
from mca_drake.cueing.dpc import DpcConfig, default_policy_path, load_policy_arrays
from mca_drake.cueing.nmpc import MotionCueingOcp, NmpcConfig
from mca_drake.learning.torch_plant import TorchPlant
from mca_drake.platforms import kinematics, leg_platform, serial, urdf_chain
from mca_drake.platforms.files import (
    load_platform,
    model_path,
    packaged_platforms,
    read_platform_file,
)
from mca_drake.platforms.serial import serial_chain_from_urdf
from mca_drake.systems.dpc import DpcPolicy

# Table I of the paper, as printed.
TABLE_I = {
    "q_max": [3.229, 1.920, 0.942, 6.109, 2.094, 6.109],
    "q_min": [-3.229, -0.698, -3.316, -6.109, -2.094, -6.109],
    "qd_max": [1.571, 1.396, 1.309, 1.571, 1.449, 2.269],
    "qdd_max": [1.676, 1.197, 2.189, 0.564, 1.625, 1.317],
}


def test_the_kr500_has_table_i_limits():
    robot = load_platform("kr500")
    assert robot.joint_names == tuple(f"joint_{i}" for i in range(1, 7))
    assert robot.joint_kinds == ("revolute",) * 6
    for name, values in TABLE_I.items():
        np.testing.assert_array_equal(getattr(robot, name), values, err_msg=name)
    assert robot.summary() == {
        "name": "kr500",
        "kind": "serial",
        "dof": 6,
        "joints": [f"joint_{i}" for i in range(1, 7)],
    }


def test_the_kr500_masses_are_of_its_class(drake_plant):
    context = drake_plant.CreateDefaultContext()
    links = sum(drake_plant.GetBodyByName(f"link_{i}").get_mass(context) for i in range(1, 7))
    cabin = drake_plant.GetBodyByName("cabin").get_mass(context)
    assert 2200 <= links <= 2600
    assert 550 <= cabin <= 650
    assert drake_plant.num_actuators() == 6


def test_a_description_is_read_only():
    robot = load_platform("kr500")
    with pytest.raises(ValueError, match="read-only"):
        robot.q_max[0] = 10.0


def test_packaged_platforms_are_listed_and_load_by_name_or_file():
    packaged = packaged_platforms()
    assert "kr500" in packaged
    for name, path in packaged.items():
        by_name, by_file = load_platform(name), load_platform(path)
        assert by_name is by_file  # one cached description
        assert by_name.name == name


def test_an_unknown_platform_lists_the_packaged_ones():
    with pytest.raises(FileNotFoundError, match=r"unknown platform 'kr5000'.*kr500"):
        load_platform("kr5000")


# ------------------------------------------------------------------ platform files
def _write(tmp_path, name: str, text: str):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_users_platform_file_reads_its_urdf_relative_to_itself(tmp_path):
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "mine.urdf").write_text(model_path("kr500.urdf").read_text())
    path = _write(tmp_path, "my_robot.yaml", "!SerialRobot\nurdf: robots/mine.urdf\n")
    description = read_platform_file(path)
    assert description.name == "my_robot"  # the file's stem
    robot = load_platform(path)
    np.testing.assert_array_equal(robot.q_max, TABLE_I["q_max"])
    assert robot.urdf_path == (tmp_path / "robots" / "mine.urdf").resolve()


@pytest.mark.parametrize(
    "text, match",
    [
        ("!SerialRobot\nurdf: kr500.urdf\nspeed: 3\n", r"unknown fields \['speed'\]"),
        ("urdf: kr500.urdf\n", "one tagged description"),
        ("!SerialRobot\nurdf: kr500.urdf\nhome: [0, zero]\n", "list of numbers"),
        ("!SerialRobot\nurdf: [1, 2]\n", "must be text"),
        ("!!python/object/apply:os.system ['true']\n", "not a platform file"),
        ("!SerialRobot [1, 2]\n", "needs a mapping"),
        ("!SerialRobot\nhead_frame: head\n", "needs `urdf`"),
    ],
)
def test_a_bad_platform_file_is_refused_with_the_reason(tmp_path, text, match):
    (tmp_path / "kr500.urdf").write_text(model_path("kr500.urdf").read_text())
    path = _write(tmp_path, "bad.yaml", text)
    with pytest.raises(ValueError, match=match):
        load_platform(path)


# ------------------------------------------------------------------ URDF readers
@pytest.fixture(params=["drake", "xml"])
def urdf_reader(request, monkeypatch):
    """Each URDF reader in turn: Drake's parser, and the XML reader of machines without
    pydrake; the description cache is emptied around each."""
    if request.param == "xml":
        monkeypatch.setattr(serial, "read_urdf", urdf_chain.read_urdf_with_xml)
    serial._load_cached.cache_clear()
    yield request.param
    serial._load_cached.cache_clear()


@pytest.mark.parametrize("name", sorted(packaged_platforms()))
def test_the_xml_reader_reads_every_joint_as_drakes_parser_does(name):
    """Oracle: Drake's parser. Every joint's kind, links, pose, axis, limits and effort
    agree on every packaged platform's URDF."""
    path = str(load_platform(name).urdf_path)
    drake = urdf_chain.read_urdf_with_drake(path).joints
    xml = urdf_chain.read_urdf_with_xml(path).joints
    assert sorted(drake) == sorted(xml)
    for joint_name, expected in drake.items():
        got = xml[joint_name]
        assert (got.kind, got.parent, got.child) == (expected.kind, expected.parent, expected.child)
        np.testing.assert_allclose(got.X_PJ, expected.X_PJ, atol=1e-15, err_msg=joint_name)
        np.testing.assert_allclose(got.X_CJ, expected.X_CJ, atol=1e-15, err_msg=joint_name)
        np.testing.assert_allclose(got.axis, expected.axis, atol=1e-15, err_msg=joint_name)
        for limit in ("position", "velocity", "acceleration", "effort"):
            assert getattr(got, limit) == getattr(expected, limit), (joint_name, limit)


@pytest.mark.parametrize("name", sorted(packaged_platforms()))
def test_the_xml_reader_gives_the_platform_drakes_parser_gives(name, monkeypatch):
    with_drake = load_platform(name)
    monkeypatch.setattr(serial, "read_urdf", urdf_chain.read_urdf_with_xml)
    serial._load_cached.cache_clear()
    leg_platform._build_cached.cache_clear()  # a hexapod's description holds its chain's
    try:
        without = load_platform(name)
    finally:
        serial._load_cached.cache_clear()
        leg_platform._build_cached.cache_clear()
    assert without is not with_drake
    for field in dataclasses.fields(with_drake):
        a, b = getattr(with_drake, field.name), getattr(without, field.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_allclose(b, a, atol=1e-15, rtol=0, err_msg=field.name)
        else:
            assert b == a, field.name


def _kr500_text() -> str:
    return model_path("kr500.urdf").read_text()


def _load(tmp_path, text: str, **kwargs):
    path = _write(tmp_path, "robot.urdf", text)
    return serial_chain_from_urdf(path, name="test", **kwargs)


def test_a_missing_file_is_reported(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        serial_chain_from_urdf(tmp_path / "nope.urdf", name="nope")


def test_a_missing_acceleration_limit_is_refused_or_given_by_the_platform(tmp_path, urdf_reader):
    text = _kr500_text().replace('drake:acceleration="0.564"', "", 1)
    with pytest.raises(ValueError, match="acceleration limit"):
        _load(tmp_path, text)
    limits = list(TABLE_I["qdd_max"])
    np.testing.assert_array_equal(_load(tmp_path, text, acceleration_limits=limits).qdd_max, limits)
    limits[3] = 0.6
    with pytest.raises(ValueError, match="differ from the URDF"):
        _load(tmp_path, _kr500_text(), acceleration_limits=limits)


def test_a_file_that_does_not_parse_is_refused(tmp_path, urdf_reader):
    text = _kr500_text()
    with pytest.raises(ValueError, match="cannot parse robot model"):
        _load(tmp_path, text[: len(text) // 2])


def test_an_unknown_head_frame_lists_the_frames(tmp_path, urdf_reader):
    with pytest.raises(ValueError, match=r"no frame or link named 'seat'.*cabin"):
        _load(tmp_path, _kr500_text(), head_frame="seat")


def test_a_moving_joint_off_the_chain_is_refused(tmp_path, urdf_reader):
    extra = (
        '<link name="tool"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" '
        'iyy="1" iyz="0" izz="1"/></inertial></link>'
        '<joint name="tool_turn" type="revolute"><parent link="link_3"/><child link="tool"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1" '
        'drake:acceleration="1"/></joint></robot>'
    )
    with pytest.raises(ValueError, match=r"\['tool_turn'\] are not on the chain"):
        _load(tmp_path, _kr500_text().replace("</robot>", extra))


def test_a_robot_not_attached_to_the_world_is_refused(tmp_path, urdf_reader):
    text = _kr500_text()
    start = text.index('<joint name="base_weld"')
    text = text[:start] + text[text.index("</joint>", start) + len("</joint>") :]
    with pytest.raises(ValueError, match="world"):
        _load(tmp_path, text)


def test_a_home_pose_must_be_inside_the_limits_and_level(tmp_path, urdf_reader):
    with pytest.raises(ValueError, match="strictly inside"):
        _load(tmp_path, _kr500_text(), home=[0, 0, 0, 0, 3.0, 0])
    with pytest.raises(ValueError, match="not level"):
        _load(tmp_path, _kr500_text(), home=[0, 0, 0, 0, 0.5, 0])
    with pytest.raises(ValueError, match="6 finite values"):
        _load(tmp_path, _kr500_text(), home=[0, 0, 0])
    # joint 1 turns the level cabin about the vertical: still level
    assert _load(tmp_path, _kr500_text(), home=[1.0, 0, 0, 0, 0, 0]).home[0] == 1.0


# ------------------------------------------------------------------ any serial chain
def _random_origin(rng) -> str:
    xyz = " ".join(f"{v:.6f}" for v in rng.uniform(-0.8, 0.8, 3))
    rpy = " ".join(f"{v:.6f}" for v in rng.uniform(-np.pi, np.pi, 3))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def random_chain_urdf(seed: int, head_rpy: str = "0 0 0") -> str:
    """A maker-style chain nothing in the package wrote: a fixed mount, then revolute and
    prismatic joints (one of each at least) with random origins and oblique axes, fixed
    links between some of them, and the head frame welded to the last link."""
    rng = np.random.default_rng(seed)
    kinds = ["prismatic", "revolute", "fixed", "revolute", "revolute", "prismatic", "revolute"]
    inertial = (
        '<inertial><mass value="10"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" '
        'izz="1"/></inertial>'
    )
    parts = ['<?xml version="1.0"?>', '<robot name="chain" xmlns:drake="http://drake.mit.edu">']
    parts.append(f'<link name="mount">{inertial}</link>')
    parts.append(
        '<joint name="mount_weld" type="fixed"><parent link="world"/><child link="mount"/>'
        f"{_random_origin(rng)}</joint>"
    )
    parent = "mount"
    for i, kind in enumerate(kinds):
        child = f"link_{i}"
        parts.append(f'<link name="{child}">{inertial}</link>')
        body = f'<parent link="{parent}"/><child link="{child}"/>{_random_origin(rng)}'
        if kind != "fixed":
            axis = rng.normal(size=3)
            axis *= rng.uniform(0.5, 2.0) / np.linalg.norm(axis)  # not unit: URDF normalises
            low, high = (-0.5, 0.7) if kind == "prismatic" else (-2.0, 2.5)
            body += (
                f'<axis xyz="{axis[0]:.6f} {axis[1]:.6f} {axis[2]:.6f}"/>'
                f'<limit lower="{low}" upper="{high}" velocity="{rng.uniform(0.5, 2):.3f}" '
                f'effort="100" drake:acceleration="{rng.uniform(0.5, 3):.3f}"/>'
            )
        parts.append(f'<joint name="j_{i}" type="{kind}">{body}</joint>')
        parent = child
    parts.append(f'<link name="head">{inertial}</link>')
    parts.append(
        f'<joint name="head_weld" type="fixed"><parent link="{parent}"/><child link="head"/>'
        f'<origin xyz="0.3 -0.2 0.4" rpy="{head_rpy}"/></joint>'
    )
    parts.append("</robot>")
    return "\n".join(parts)


def level_random_chain(tmp_path, seed: int):
    """A random chain whose head weld is turned so that the head is level at q = 0 (its
    rotation at home computed by Drake), written to a file: (path, description)."""
    draft = _write(tmp_path, f"draft_{seed}.urdf", random_chain_urdf(seed))
    plant = drake_plant_of(str(draft))
    context = plant.CreateDefaultContext()
    R_WL = RotationMatrix(drake_head_pose(plant, context, np.zeros(plant.num_positions()))[:3, :3])
    # the draft's head weld turns nothing: H = L, so turn it by R_LW to make it level
    rpy = RollPitchYaw(R_WL.inverse()).vector()
    path = _write(tmp_path, f"chain_{seed}.urdf", random_chain_urdf(seed, " ".join(map(str, rpy))))
    return path, serial_chain_from_urdf(path, name=f"chain-{seed}")


def _platforms(tmp_path):
    """Every packaged platform and three random chains: (name, URDF path, description)."""
    chains = [(name, load_platform(name)) for name in sorted(packaged_platforms())]
    for seed in (1, 2, 3):
        chains.append((f"chain-{seed}", level_random_chain(tmp_path, seed)[1]))
    return chains


def _random_states(rng, robot, n: int):
    q = rng.uniform(robot.q_min, robot.q_max, size=(n, robot.num_joints))
    qd = rng.uniform(-robot.qd_max, robot.qd_max, size=(n, robot.num_joints))
    qdd = rng.uniform(-robot.qdd_max, robot.qdd_max, size=(n, robot.num_joints))
    return q, qd, qdd


def test_random_chains_have_both_joint_kinds_and_read_alike_without_drake(tmp_path, monkeypatch):
    path, robot = level_random_chain(tmp_path, 1)
    assert set(robot.joint_kinds) == {"revolute", "prismatic"} and robot.num_joints == 6
    monkeypatch.setattr(serial, "read_urdf", urdf_chain.read_urdf_with_xml)
    serial._load_cached.cache_clear()
    try:
        without = serial_chain_from_urdf(path, name="chain-1")
    finally:
        serial._load_cached.cache_clear()
    np.testing.assert_allclose(without.X_prev, robot.X_prev, atol=1e-12)
    np.testing.assert_allclose(without.X_last_H, robot.X_last_H, atol=1e-12)
    np.testing.assert_array_equal(without.qdd_max, robot.qdd_max)


def test_every_platform_is_level_and_at_rest_at_home(tmp_path):
    for name, robot in _platforms(tmp_path):
        home = robot.home
        X_WH = kinematics.head_pose(home, robot)
        assert X_WH[2, 2] == pytest.approx(1.0, abs=1e-9), name
        zero = np.zeros_like(home)
        y = kinematics.plant_output(home, zero, zero, robot)
        np.testing.assert_allclose(y, np.zeros(6), atol=1e-9, err_msg=name)


def test_head_pose_and_output_equal_drakes_on_every_platform(tmp_path, rng):
    """Oracle: Drake's MultibodyPlant parsed from the same URDF (head pose by its frame
    kinematics, y from its spatial velocity, Jacobian and bias acceleration), to 1e-9."""
    for name, robot in _platforms(tmp_path):
        plant = drake_plant_of(str(robot.urdf_path))
        context = plant.CreateDefaultContext()
        assert plant.num_positions() == robot.num_joints, name
        q, qd, qdd = _random_states(rng, robot, 50)
        poses = kinematics.head_pose(q, robot)
        outputs = kinematics.plant_output(q, qd, qdd, robot)
        for k in range(q.shape[0]):
            expected = drake_head_pose(plant, context, q[k], robot.head_frame)
            np.testing.assert_allclose(poses[k], expected, atol=1e-9, rtol=0, err_msg=name)
            expected = drake_plant_output(plant, context, q[k], qd[k], qdd[k], robot.head_frame)
            np.testing.assert_allclose(outputs[k], expected, atol=1e-9, rtol=0, err_msg=name)


def test_jacobians_and_curvature_are_derivatives_on_every_platform(tmp_path, rng):
    """Oracle: central differences of the output (itself checked against Drake above)."""
    eps = 1e-6
    for name, robot in _platforms(tmp_path):
        n = robot.num_joints
        q, qd, qdd = _random_states(rng, robot, 6)
        jac = kinematics.plant_output_jacobians(q, qd, qdd, robot)
        np.testing.assert_allclose(jac.y, kinematics.plant_output(q, qd, qdd, robot), atol=1e-13)
        for which, got in enumerate((jac.dy_dq, jac.dy_dqd, jac.dy_dqdd)):
            assert got.shape == (6, 6, n), name
            for j in range(n):
                step = np.zeros(n)
                step[j] = eps
                plus, minus = [q, qd, qdd], [q, qd, qdd]
                plus[which], minus[which] = plus[which] + step, minus[which] - step
                numeric = (
                    kinematics.plant_output(*plus, robot) - kinematics.plant_output(*minus, robot)
                ) / (2 * eps)
                np.testing.assert_allclose(got[..., j], numeric, atol=2e-7, err_msg=name)
        H = kinematics.output_velocity_hessians(q, robot)
        assert H.shape == (6, 6, n, n)
        for i in range(n):
            for j in range(n):
                e_i, e_j = np.eye(n)[i] * 1e-4, np.eye(n)[j] * 1e-4
                y = [
                    kinematics.plant_output(q, qd + a * e_i + b * e_j, qdd, robot)
                    for a, b in ((1, 1), (1, -1), (-1, 1), (-1, -1))
                ]
                numeric = (y[0] - y[1] - y[2] + y[3]) / (4 * 1e-8)
                np.testing.assert_allclose(H[..., i, j], numeric, atol=1e-5, err_msg=name)


def test_the_torch_twin_equals_numpy_on_every_platform(tmp_path, rng):
    for name, robot in _platforms(tmp_path):
        plant = TorchPlant(robot, dtype=torch.float64)
        q, qd, qdd = _random_states(rng, robot, 40)
        x = torch.tensor(np.concatenate([q, qd], axis=-1))
        y = plant.output(x, torch.tensor(qdd)).numpy()
        expected = kinematics.plant_output(q, qd, qdd, robot)
        np.testing.assert_allclose(y, expected, atol=1e-12, rtol=0, err_msg=name)
        pose = plant.head_pose(torch.tensor(q)).numpy()
        np.testing.assert_allclose(pose, kinematics.head_pose(q, robot), atol=1e-12, err_msg=name)


@pytest.mark.parametrize("name", sorted(packaged_platforms()))
def test_the_mirror_signs_mirror_the_cue_in_drake(name, rng):
    """Oracle: Drake's output of the mirrored joint motion is the mirrored output
    (`conventions.MIRROR_CHANNEL_SIGNS`), and the flipped joints' limits are symmetric."""
    robot = load_platform(name)
    signs = robot.mirror_joint_signs
    assert signs.shape == (robot.num_joints,)
    plant = drake_plant_of(str(robot.urdf_path))
    context = plant.CreateDefaultContext()
    for q, qd, qdd in zip(*(0.9 * a for a in _random_states(rng, robot, 10)), strict=True):
        y = drake_plant_output(plant, context, q, qd, qdd)
        mirrored = drake_plant_output(plant, context, signs * q, signs * qd, signs * qdd)
        np.testing.assert_allclose(mirrored, np.array(MIRROR_CHANNEL_SIGNS) * y, atol=1e-9)
    flipped = signs < 0
    np.testing.assert_array_equal(robot.q_min[flipped], -robot.q_max[flipped])


def test_the_rail_carries_the_kr500_unchanged(rng):
    """With the rail still, the rail platform is the KR500 (outputs equal to round-off);
    sliding it adds the rail's acceleration along the world's y axis, in the head frame."""
    kr500, rail = load_platform("kr500"), load_platform("kr500-rail")
    assert rail.joint_kinds == ("prismatic", *kr500.joint_kinds)
    np.testing.assert_array_equal(rail.qdd_max[1:], kr500.qdd_max)
    assert (rail.q_max[0], rail.qd_max[0], rail.qdd_max[0]) == (4.55, 1.47, 1.078)
    q, qd, qdd = _random_states(rng, kr500, 20)
    still = np.zeros((20, 1))
    on_rail = kinematics.plant_output(
        np.hstack([rng.uniform(-4, 4, (20, 1)), q]),
        np.hstack([still, qd]),
        np.hstack([still, qdd]),
        rail,
    )
    np.testing.assert_allclose(on_rail, kinematics.plant_output(q, qd, qdd, kr500), atol=1e-12)
    slide = np.hstack([still + 1.0, qdd])
    moved = kinematics.plant_output(np.hstack([still, q]), np.hstack([still, qd]), slide, rail)
    R_WH = kinematics.head_pose(q, kr500)[:, :3, :3]
    expected = np.einsum("nji,j->ni", R_WH, [0.0, 1.0, 0.0])  # R^T e_y, 1 m/s^2
    change = moved - kinematics.plant_output(q, qd, qdd, kr500)
    np.testing.assert_allclose(change[:, :3], 0.0, atol=1e-12)
    np.testing.assert_allclose(change[:, 3:5], expected[:, :2], atol=1e-12)
    np.testing.assert_allclose(change[:, 5], expected[:, 2], atol=1e-12)


# ------------------------------------------------------------------ the command
def test_the_platforms_command_lists_every_packaged_platform_as_json(capsys):
    assert main(["platforms", "--json"]) == 0
    records = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    assert set(records) == set(packaged_platforms())
    assert {k: records["kr500"][k] for k in ("kind", "dof")} == {"kind": "serial", "dof": 6}
    rail = records["kr500-rail"]
    assert (rail["kind"], rail["dof"]) == ("serial", 7)
    assert rail["joints"][0] == {
        "name": "rail_axis",
        "kind": "prismatic",
        "unit": "m",
        "position": [-4.55, 4.55],
        "velocity": 1.47,
        "acceleration": 1.078,
    }
    assert main(["platforms"]) == 0
    table = capsys.readouterr().out
    assert "kr500-rail: serial, 7 joints" in table and "-4.550 .. 4.550 m" in table


def test_the_platforms_command_describes_a_file_and_refuses_an_unknown_name(tmp_path, capsys):
    (tmp_path / "mine.urdf").write_text(model_path("kr500.urdf").read_text())
    path = _write(tmp_path, "mine.yaml", "!SerialRobot\nurdf: mine.urdf\n")
    assert main(["platforms", str(path), "--json"]) == 0
    (record,) = json.loads(capsys.readouterr().out)
    assert (record["name"], record["dof"]) == ("mine", 6)
    assert main(["platforms", "kr5000"]) == 2
    assert "unknown platform 'kr5000'" in capsys.readouterr().err


# ------------------------------------------------------------------ closed loops
def test_a_scenario_runs_on_the_platform_it_names(tmp_path):
    """By packaged name, by file and inline: the summary records the platform that ran,
    and the rail's extra joint is in the states and the joint use."""
    (tmp_path / "kr500_rail.urdf").write_text(model_path("kr500_rail.urdf").read_text())
    inline = "{platform: !SerialRobot {name: my-rail, urdf: %s, home: [0, 0, 0, 0, 0, 0, 0]}}" % (
        tmp_path / "kr500_rail.urdf"
    )
    quick = "{mca: nmpc-rti, plant: analytical, duration_s: 1.0}"
    for override, name, dof in (
        ("{platform: kr500-rail}", "kr500-rail", 7),
        (f"{{platform: {packaged_platforms()['kr500']}}}", "kr500", 6),
        (inline, "my-rail", 7),
    ):
        scenario = load_scenario("closed_loop_dpc", [quick, override])
        result = run_closed_loop_scenario(scenario, progress=False, json_path="", plot_dir="")
        assert result.summary["platform"]["name"] == name
        assert result.summary["platform"]["dof"] == dof
        assert result.states.shape[1] == 2 * dof
        assert len(result.summary["joint_range_used"]) == dof
        assert sum(result.summary["violations"].values()) == 0
    with pytest.raises(ValueError, match=r"platform: unknown platform 'kr5000'"):
        load_scenario("closed_loop_dpc", [quick, "{platform: kr5000}"])


def test_the_dpc_of_the_kr500_is_refused_on_the_rail_and_simulate_takes_platform(tmp_path, capsys):
    scenario = load_scenario(
        "closed_loop_dpc", ["{platform: kr500-rail, plant: analytical, duration_s: 1.0}"]
    )
    scenario.mca = DpcConfig(policy=str(default_policy_path()))
    with pytest.raises(ValueError, match=r"trained for platform 'kr500', not for 'kr500-rail'"):
        run_closed_loop_scenario(scenario, progress=False, json_path="", plot_dir="")
    summary = tmp_path / "summary.json"
    argv = ["simulate", "--platform", "kr500-rail", "--mca", "washout", "--plant", "analytical"]
    argv += ["--duration", "1", "--json", str(summary), "--plots", "", "--quiet"]
    assert main(argv) == 0
    assert json.loads(summary.read_text())["platform"]["dof"] == 7
    capsys.readouterr()
    # a platform without a shipped policy: the suite's DPC says how to train one
    mine = tmp_path / "mine.yaml"
    mine.write_text(packaged_platforms()["kr500"].read_text().replace("name: kr500", "name: mine"))
    (tmp_path / "kr500.urdf").write_text(model_path("kr500.urdf").read_text())
    assert main(["evaluate", "--suite", "--platform", str(mine), "--mcas", "dpc"]) == 2
    assert "train-policy --platform mine" in capsys.readouterr().err


def test_the_nmpc_refuses_a_platform_whose_home_is_not_zero(tmp_path):
    turned = _load(tmp_path, _kr500_text(), home=[0.5, 0, 0, 0, 0, 0])
    with pytest.raises(ValueError, match=r"washes out towards q = 0; platform 'test'"):
        MotionCueingOcp(NmpcConfig(), turned)


def test_the_dpc_network_refuses_a_platform_of_another_joint_count():
    """Policy arrays given directly (no file to name a platform) still meet the platform's
    joints: the KR500's six are refused on the rail's seven, naming both counts."""
    arrays, _ = load_policy_arrays(default_policy_path())
    with pytest.raises(ValueError, match=r"commands 6 joints, platform 'kr500-rail' has 7"):
        DpcPolicy(arrays, load_platform("kr500-rail"))


def test_the_fanuc_is_the_robot_ros_industrial_describes():
    """Oracle: ROS-Industrial's m900ib700_macro.xacro (fanuc_m900ib_support), its numbers
    copied here by hand: each joint's origin, axis, position and velocity limit."""
    published = {  # joint: (origin xyz, axis, lower, upper, velocity)
        "joint_1": ((0, 0, 0.940), (0, 0, 1), -3.1415, 3.1415, 1.3962),
        "joint_2": ((0.410, 0, 0), (0, 1, 0), -1.1170, 1.5707, 1.3962),
        "joint_3": ((0, 0, 1.120), (0, -1, 0), -2.2689, 0.5235, 1.3962),
        "joint_4": ((0, 0, 0.250), (-1, 0, 0), -6.2831, 6.2831, 1.7453),
        "joint_5": ((1.285, 0, 0), (0, -1, 0), -2.1293, 2.1293, 1.7453),
        "joint_6": ((0.300, 0, 0), (-1, 0, 0), -6.2831, 6.2831, 2.7925),
    }
    robot = load_platform("fanuc-m900ib700")
    joints = urdf_chain.read_urdf_with_xml(str(robot.urdf_path)).joints
    assert robot.joint_names == tuple(published)
    for name, (xyz, axis, lower, upper, velocity) in published.items():
        joint = joints[name]
        np.testing.assert_allclose(joint.X_PJ[:3, 3], xyz, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(joint.X_PJ[:3, :3], np.eye(3), atol=1e-12, err_msg=name)
        np.testing.assert_allclose(joint.axis, axis, atol=1e-12, err_msg=name)
        assert joint.position == (lower, upper) and joint.velocity == (-velocity, velocity), name
    np.testing.assert_allclose(robot.q_min, [p[2] for p in published.values()])
    np.testing.assert_allclose(robot.qd_max, [p[4] for p in published.values()])


def test_a_live_robot_run_checks_the_platform_fits_one_rsi_controller():
    """Over RSI the rail is external axis E1 beside A1-A6: a live scenario with a robot on
    the rail validates; settings for external axes it does not have are refused before
    anything starts, naming the platform."""
    from mca_drake.app.scenarios import LiveScenario

    def scenario(platform, **rsi):
        from mca_drake.live.rsi.driver import RsiDriverConfig

        return LiveScenario(
            protocol="csv",
            robot="rsi://127.0.0.1:49152",
            plant="analytical",
            platform=platform,
            rsi=RsiDriverConfig(**rsi),
        )

    scenario("kr500-rail").validate()
    scenario("kr500-rail", external_home=[4750.0], external_signs=[-1]).validate()
    scenario("kr500").validate()
    with pytest.raises(ValueError, match=r"kr500-rail.*external_signs must hold 1 values"):
        scenario("kr500-rail", external_signs=[1, 1]).validate()
    with pytest.raises(ValueError, match=r"'kr500'.*external_home must hold 0 values"):
        scenario("kr500", external_home=[0.0]).validate()
