"""The URDF against the paper's Table I (typed here independently) and the load-time checks."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mca_drake import robot as robot_module
from mca_drake.robot import JOINT_NAMES, load_kr500, model_path

# Table I of the paper, as printed.
TABLE_I = {
    "q_max": [3.229, 1.920, 0.942, 6.109, 2.094, 6.109],
    "q_min": [-3.229, -0.698, -3.316, -6.109, -2.094, -6.109],
    "qd_max": [1.571, 1.396, 1.309, 1.571, 1.449, 2.269],
    "qdd_max": [1.676, 1.197, 2.189, 0.564, 1.625, 1.317],
    "a": [0.500, 1.300, -0.055, 0.000, 0.000, 0.000],
    "d": [1.045, 0.000, 0.000, 1.025, 0.000, 0.290],
    "alpha": [-1.571, 0.000, -1.571, 1.571, -1.571, 0.000],
    "offset": [0.000, -1.571, 0.000, 0.000, 0.000, 0.000],
}


def test_limits_are_table_i(robot):
    assert robot.joint_names == JOINT_NAMES
    for name in ("q_max", "q_min", "qd_max", "qdd_max"):
        np.testing.assert_array_equal(getattr(robot, name), TABLE_I[name], err_msg=name)


def test_dh_table_is_table_i(robot):
    np.testing.assert_allclose(robot.dh.a, TABLE_I["a"], atol=1e-12)
    np.testing.assert_allclose(robot.dh.d, TABLE_I["d"], atol=1e-12)
    # Table I rounds +-pi/2 to 3 decimals; the model uses pi/2 exactly.
    np.testing.assert_allclose(robot.dh.alpha, TABLE_I["alpha"], atol=5e-4)
    np.testing.assert_allclose(robot.dh.offset, TABLE_I["offset"], atol=5e-4)
    np.testing.assert_allclose(np.abs(robot.dh.alpha[[0, 2, 3, 4]]), np.pi / 2, atol=1e-12)


def test_head_frame_is_architecture_x_6h(robot):
    np.testing.assert_allclose(robot.R_6H, [[0, 0, 1], [0, -1, 0], [1, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(robot.p_6H, [0.9, 0.0, 0.5], atol=1e-12)


def test_neutral_pose_inside_limits(robot):
    assert np.all(robot.q_min < 0) and np.all(robot.q_max > 0)


def test_masses_are_kr500_class(drake_plant):
    context = drake_plant.CreateDefaultContext()
    links = sum(drake_plant.GetBodyByName(f"link_{i}").get_mass(context) for i in range(1, 7))
    cabin = drake_plant.GetBodyByName("cabin").get_mass(context)
    assert 2200 <= links <= 2600
    assert 550 <= cabin <= 650
    assert drake_plant.num_actuators() == 6


def test_description_is_read_only(robot):
    with pytest.raises(ValueError, match="read-only"):
        robot.q_max[0] = 10.0


@pytest.fixture(params=["drake", "xml"])
def urdf_reader(request, monkeypatch):
    """Each URDF reader in turn: Drake's parser, and the XML reader of machines without
    pydrake (`robot._urdf_joints`); the description cache is emptied around each."""
    if request.param == "xml":
        monkeypatch.setattr(robot_module, "_urdf_joints", robot_module._joints_with_xml)
    robot_module._load_cached.cache_clear()
    yield request.param
    robot_module._load_cached.cache_clear()


def test_xml_reader_reads_every_joint_as_drakes_parser_does():
    """Oracle: Drake's parser. Every joint's pose, axis, limits and effort agree."""
    path = str(model_path("kr500.urdf"))
    drake, xml = robot_module._joints_with_drake(path), robot_module._joints_with_xml(path)
    assert sorted(drake) == sorted(xml)
    for name, expected in drake.items():
        got = xml[name]
        np.testing.assert_allclose(got.X_parent, expected.X_parent, atol=1e-15, err_msg=name)
        np.testing.assert_array_equal(got.axis, expected.axis, err_msg=name)
        assert got.at_child_origin == expected.at_child_origin
        if name in JOINT_NAMES:
            assert (got.lower, got.upper) == (expected.lower, expected.upper)
            assert (got.velocity, got.acceleration) == (expected.velocity, expected.acceleration)
            assert got.effort == expected.effort


def test_the_xml_reader_gives_the_kr500_drakes_parser_gives(monkeypatch):
    """Oracle: the description read through Drake's parser; the one read without Drake
    equals it field by field, exactly."""
    path = model_path("kr500.urdf")
    robot_module._load_cached.cache_clear()
    with_drake = load_kr500(path)
    monkeypatch.setattr(robot_module, "_urdf_joints", robot_module._joints_with_xml)
    robot_module._load_cached.cache_clear()
    without = load_kr500(path)
    robot_module._load_cached.cache_clear()
    assert without is not with_drake
    for owner_a, owner_b in ((with_drake, without), (with_drake.dh, without.dh)):
        for field in dataclasses.fields(owner_a):
            a, b = getattr(owner_a, field.name), getattr(owner_b, field.name)
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(b, a, err_msg=field.name)
            elif field.name != "dh":
                assert b == a, field.name


def test_missing_file_is_reported(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        load_kr500(tmp_path / "nope.urdf")


def test_non_dh_urdf_is_rejected(tmp_path, urdf_reader):
    text = model_path("kr500.urdf").read_text()
    # Shift joint_3's origin sideways: no longer Tz(d) Tx(a) Rx(alpha) Rz(offset).
    start = text.index('<joint name="joint_3"')
    origin_at = text.index('<origin xyz="', start) + len('<origin xyz="')
    end = text.index('"', origin_at)
    bad = text[:origin_at] + "1.3 0.2 0.0" + text[end:]
    path = tmp_path / "bad.urdf"
    path.write_text(bad)
    with pytest.raises(ValueError, match=r"joint_3.*not of DH form"):
        load_kr500(path)


def test_missing_acceleration_limit_is_rejected(tmp_path, urdf_reader):
    text = model_path("kr500.urdf").read_text()
    bad = text.replace('drake:acceleration="0.564"', "", 1)
    path = tmp_path / "bad.urdf"
    path.write_text(bad)
    with pytest.raises(ValueError, match="drake:acceleration"):
        load_kr500(path)


def test_xml_reader_refuses_a_file_it_cannot_read(tmp_path, urdf_reader):
    text = model_path("kr500.urdf").read_text()
    broken = tmp_path / "broken.urdf"
    broken.write_text(text[: len(text) // 2])
    with pytest.raises(ValueError, match="cannot parse robot model"):
        load_kr500(broken)
    if urdf_reader == "xml":  # Drake's parser reports bad numbers its own way
        bad = tmp_path / "bad_origin.urdf"
        start = text.index('<joint name="joint_3"')
        origin_at = text.index('<origin xyz="', start) + len('<origin xyz="')
        bad.write_text(text[:origin_at] + "1.3 nan-ish" + text[text.index('"', origin_at) :])
        with pytest.raises(ValueError, match="xyz"):
            load_kr500(bad)
