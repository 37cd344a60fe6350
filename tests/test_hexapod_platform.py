"""The hexapod as a platform: its virtual chain against the legs' own kinematics and Drake's
MultibodyPlant, its single-axis limits against their definition, its description files,
and its viability clamp holding the legs (the QP's answer against scipy's, every command
from random and far-out states inside every leg limit, closed loops beyond the rig's
range with zero actuator violations on both plants)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from drake_oracle import drake_head_pose, drake_plant_of
from scipy.optimize import minimize

from mca_drake.platforms.clamp import platform_clamp
from mca_drake.platforms.files import load_platform, read_platform_file
from mca_drake.platforms.leg_clamp import (
    ACCELERATION_SHARE,
    POSITION_RESERVE,
    RATE_RESERVE,
    LegClamp,
)
from mca_drake.platforms.leg_platform import (
    LegPlatform,
    leg_platform,
    pose_of,
    single_axis_limits,
)
from mca_drake.platforms.legs import LegGeometry, leg_lengths, leg_motion, rotation
from mca_drake.platforms.usage import joint_usage
from mca_drake.references.recording import Recording
from mca_drake.references.reference import reference_from_recording
from mca_drake.safety import ViabilityClamp
from mca_drake.simulation.closed_loop import run_closed_loop

H = 0.01


@pytest.fixture(scope="module")
def hexapod() -> LegPlatform:
    return load_platform("hexapod")


def random_poses(rng, count: int, platform: LegPlatform, fraction: float = 0.5):
    """Coordinates q (count, 6) drawn inside `fraction` of the box."""
    return rng.uniform(fraction * platform.q_min, fraction * platform.q_max, size=(count, 6))


def test_the_virtual_chain_puts_the_head_where_the_legs_put_the_platform(hexapod):
    # Oracle: the pose's own definition (t = (x, y, h0 + z), R = Rz Ry Rx) and the head's
    # position in the platform frame, and Drake's MultibodyPlant of the generated URDF.
    rng = np.random.default_rng(0)
    plant = drake_plant_of(str(hexapod.urdf_path))
    context = plant.CreateDefaultContext()
    head = np.array(hexapod.head_position)
    height = hexapod.actuators.neutral_height
    from mca_drake.platforms.kinematics import head_pose

    for q in random_poses(rng, 25, hexapod, fraction=1.0):
        x, y, z, roll, pitch, yaw = pose_of(q)
        R = rotation(roll, pitch, yaw)
        expected = np.eye(4)
        expected[:3, :3] = R
        expected[:3, 3] = np.array([x, y, height + z]) + R @ head
        np.testing.assert_allclose(head_pose(q[None], hexapod)[0], expected, atol=1e-14)
        np.testing.assert_allclose(drake_head_pose(plant, context, q), expected, atol=1e-12)


def test_each_coordinate_alone_reaches_a_leg_limit_at_its_box_edge(hexapod):
    g = hexapod.actuators
    limits = single_axis_limits(g)
    np.testing.assert_array_equal(limits.q_max, hexapod.q_max)
    for k in range(6):
        for edge in (hexapod.q_min[k], hexapod.q_max[k]):
            q = np.zeros(6)
            q[k] = edge
            lengths = hexapod.actuator_positions(q)
            # at the edge a leg is at an end of its stroke (to the bisection's 1e-9)
            gap = min(np.min(lengths - g.min_position), np.min(g.max_position - lengths))
            assert abs(gap) < 1e-8, (k, edge, gap)
            # inside it every leg is within its stroke
            inside = hexapod.actuator_positions(0.999 * q)
            assert np.all((inside > g.min_position) & (inside < g.max_position))
        # at the neutral pose, the coordinate at its speed (acceleration) limit drives the
        # fastest leg at exactly the leg's speed (acceleration) limit
        rate = np.zeros(6)
        rate[k] = hexapod.qd_max[k]
        _, speeds, _ = hexapod.actuator_motion(np.zeros(6), rate, np.zeros(6))
        assert np.max(np.abs(speeds)) == pytest.approx(g.max_speed, rel=1e-12)
        accel = np.zeros(6)
        accel[k] = hexapod.qdd_max[k]
        _, _, accelerations = hexapod.actuator_motion(np.zeros(6), np.zeros(6), accel)
        assert np.max(np.abs(accelerations)) == pytest.approx(g.max_acceleration, rel=1e-12)


def test_the_packaged_hexapod_reaches_about_what_its_model_states(hexapod):
    # The 6DOF2000E's stated excursions (models/hexapod.yaml): within 4 cm and 4 deg.
    stated = [0.25, 0.259, 0.178, math.radians(22), math.radians(22), math.radians(21)]
    reach = 0.5 * (hexapod.q_max - hexapod.q_min)
    assert np.all(np.abs(reach[:3] - stated[:3]) < 0.04), reach
    assert np.all(np.abs(reach[3:] - stated[3:]) < math.radians(4)), np.degrees(reach[3:])
    assert hexapod.kind == "hexapod"
    assert hexapod.summary()["actuators"]["names"] == [f"leg_{i}" for i in range(1, 7)]
    assert "6DOF2000E" in hexapod.source


def test_mirrored_motion_gives_the_mirrored_legs_the_same_lengths(hexapod):
    rng = np.random.default_rng(1)
    signs = hexapod.mirror_joint_signs
    assert signs.tolist() == [1, -1, 1, -1, 1, -1]
    for q in random_poses(rng, 10, hexapod):
        assert sorted(hexapod.actuator_positions(q)) == pytest.approx(
            sorted(hexapod.actuator_positions(signs * q)), abs=1e-12
        )


def test_actuator_motion_is_the_time_derivative_of_the_leg_lengths(hexapod):
    # Oracle: central differences of the lengths along a smooth trajectory q(t).
    rng = np.random.default_rng(2)
    a, w, phase = rng.uniform(0.02, 0.1, 6), rng.uniform(0.5, 3.0, 6), rng.uniform(0, 6, 6)

    def q_at(t):
        return a * np.sin(w * t + phase)

    t, dt = 0.7, 1e-4
    q, qd, qdd = q_at(t), a * w * np.cos(w * t + phase), -a * w * w * np.sin(w * t + phase)
    lengths, speeds, accelerations = hexapod.actuator_motion(q, qd, qdd)
    before, after = (
        hexapod.actuator_positions(q_at(t - dt)),
        hexapod.actuator_positions(q_at(t + dt)),
    )
    np.testing.assert_allclose(speeds, (after - before) / (2 * dt), atol=1e-8)
    np.testing.assert_allclose(accelerations, (after - 2 * lengths + before) / dt**2, atol=2e-5)
    # one pass for a clamp: drift + J qdd is the legs' acceleration, J the Jacobian
    rate_lengths, rate_speeds, drift, J = hexapod.actuator_rates(q, qd)
    np.testing.assert_allclose(rate_lengths, lengths, atol=1e-14)
    np.testing.assert_allclose(rate_speeds, speeds, atol=1e-14)
    np.testing.assert_allclose(drift + J @ qdd, accelerations, atol=1e-12)
    np.testing.assert_allclose(J, hexapod.actuator_jacobian(q), atol=1e-14)
    # batched = one at a time
    batch = hexapod.actuator_motion(
        np.stack([q, 2 * q]), np.stack([qd, qd]), np.stack([qdd, 0 * qdd])
    )
    one = hexapod.actuator_motion(2 * q, qd, 0 * qdd)
    for b, o in zip(batch, one, strict=True):
        np.testing.assert_allclose(b[1], o, atol=1e-15)


# ------------------------------------------------------------------ description files
def test_a_hexapod_file_lists_its_joints_or_gives_the_symmetric_layout(tmp_path, hexapod):
    geometry = hexapod.actuators
    listed = tmp_path / "listed.yaml"
    points = lambda rows: "[" + ", ".join(f"[{x!r}, {y!r}, {z!r}]" for x, y, z in rows) + "]"  # noqa: E731
    listed.write_text(
        "!Hexapod\n"
        f"base_joints: {points(geometry.base_joints)}\n"
        f"platform_joints: {points(geometry.platform_joints)}\n"
        f"neutral_height: {geometry.neutral_height!r}\n"
        f"min_length: {geometry.min_position!r}\nmax_length: {geometry.max_position!r}\n"
        f"max_speed: {geometry.max_speed}\nmax_acceleration: {geometry.max_acceleration}\n"
        "head_position: [0, 0, 1.1]\npayload_mass: 500\npayload_inertia: [120, 120, 100]\n"
    )
    platform = load_platform(listed)
    assert platform.name == "listed" and platform.kind == "hexapod"
    np.testing.assert_allclose(platform.q_max, hexapod.q_max, atol=1e-12)
    np.testing.assert_allclose(platform.qdd_max, hexapod.qdd_max, atol=1e-12)


@pytest.mark.parametrize(
    "extra, message",
    [
        ("base_joints: [[0, 0, 0]]\n", "not both"),
        ("stroke: -1\n", "must be positive|needs base_joints"),
        ("base_radius: fast\n", "must be a number"),
        ("head_position: [0, 1]\n", "head_position"),
        ("payload_mass: 0\n", "payload_mass"),
        ("colour: red\n", "unknown fields"),
        ("max_length: 2\n", "not min/max_length"),
    ],
)
def test_a_bad_hexapod_file_names_what_is_wrong(tmp_path, extra, message):
    base = [
        line
        for line in read_packaged_hexapod_lines()
        if not any(line.startswith(key.split(":")[0] + ":") for key in extra.splitlines())
    ]
    path = tmp_path / "bad.yaml"
    path.write_text("".join(base) + extra)
    with pytest.raises(ValueError, match=message):
        load_platform(path)


def read_packaged_hexapod_lines() -> list[str]:
    from mca_drake.platforms.files import platform_file

    return [
        line + "\n"
        for line in platform_file("hexapod").read_text().splitlines()
        if line and not line.startswith("#")
    ]


def test_the_packaged_file_holds_a_hexapod_description():
    from mca_drake.platforms.files import Hexapod, platform_file

    description = read_platform_file(platform_file("hexapod"))
    assert isinstance(description, Hexapod)
    assert description.stroke == 0.30 and description.name == "hexapod"


# ------------------------------------------------------------------ the clamp
def leg_rows(clamp: LegClamp, x):
    """The clamp's linear leg constraints at x, independently of its own intervals: the
    legs' exact (length, speed) and J, c from `leg_motion`, and each leg's viability
    interval from `viable_acceleration_bounds`' scalar twin on the reserved limits."""
    platform = clamp.platform
    q, qd = x[:6], x[6:]
    lengths, speeds, drift = leg_motion(pose_of(q), pose_of(qd), np.zeros(6), platform.actuators)
    J = np.stack(
        [
            (leg_motion(pose_of(q), pose_of(qd), pose_of(e), platform.actuators)[2] - drift)
            for e in np.eye(6)
        ],
        axis=1,
    )
    g = platform.actuators
    keep = 1 - RATE_RESERVE
    legs = ViabilityClamp(
        [g.min_position + POSITION_RESERVE] * 6,
        [g.max_position - POSITION_RESERVE] * 6,
        [g.max_speed * keep] * 6,
        [g.max_acceleration * ACCELERATION_SHARE] * 6,
        H,
    )
    lo, hi, _ = legs.intervals(np.concatenate([lengths, speeds]))
    return J, drift, np.array(lo), np.array(hi)


def viable_states(rng, clamp, count):
    states = []
    while len(states) < count:
        q = random_poses(rng, 1, clamp.platform, fraction=0.95)[0]
        qd = rng.uniform(-0.6, 0.6, 6) * clamp.platform.qd_max
        x = np.concatenate([q, qd])
        if clamp.is_viable(x):
            states.append(x)
    return states


def test_the_clamp_returns_the_nearest_command_the_legs_and_box_allow(hexapod):
    # Oracle: scipy's SLSQP on the same problem, built from leg_motion and the box's
    # ViabilityClamp intervals (not from the clamp's own rows).
    rng = np.random.default_rng(3)
    clamp = LegClamp(hexapod, H, period_end=False)  # the QP of the period's start
    weights = 1 / hexapod.qdd_max**2
    solved = 0
    for x in viable_states(rng, clamp, 60):
        u = rng.normal(0, 2.0, 6) * hexapod.qdd_max
        safe, intervened = clamp(x, u)
        J, c, lo, hi = leg_rows(clamp, x)
        blo, bhi, _ = ViabilityClamp.for_robot(hexapod, H).intervals(x)
        legs = J @ safe + c
        assert np.all(legs >= lo - 1e-7) and np.all(legs <= hi + 1e-7)
        assert np.all(safe >= np.array(blo) - 1e-9) and np.all(safe <= np.array(bhi) + 1e-9)
        if not intervened:
            np.testing.assert_array_equal(safe, u)
            continue
        solved += 1
        constraints = [
            {"type": "ineq", "fun": lambda v, J=J, c=c, lo=lo: J @ v + c - lo},
            {"type": "ineq", "fun": lambda v, J=J, c=c, hi=hi: hi - J @ v - c},
        ]
        reference = minimize(
            lambda v, u=u: float(np.sum(weights * (v - u) ** 2)),
            safe,
            method="SLSQP",
            bounds=list(zip(blo, bhi, strict=True)),
            constraints=constraints,
            options={"ftol": 1e-14, "maxiter": 500},
        )
        ours = np.sum(weights * (safe - u) ** 2)
        assert ours <= reference.fun * (1 + 1e-6) + 1e-12
    assert solved > 30  # most of these commands needed the QP


def test_a_command_within_every_limit_passes_unchanged(hexapod):
    clamp = LegClamp(hexapod, H)
    x = np.zeros(12)
    u = 0.1 * hexapod.qdd_max
    safe, intervened = clamp(x, u)
    assert not intervened and safe is not None
    np.testing.assert_array_equal(safe, u)
    nan = np.full(6, np.nan)
    safe, intervened = clamp(np.concatenate([np.zeros(6), 0.1 * hexapod.qd_max]), nan)
    assert intervened and np.all(np.isfinite(safe))


def test_random_commands_never_take_a_leg_beyond_its_limits(hexapod):
    # The clamp's promise, checked on the legs' exact motion at ten substeps per period
    # (the plant's exact step; lengths, speeds and accelerations by leg_motion).
    rng = np.random.default_rng(4)
    clamp = platform_clamp(hexapod, H)
    assert isinstance(clamp, LegClamp)
    g = hexapod.actuators
    x = np.zeros(12)
    worst = {"length": -np.inf, "speed": -np.inf, "acceleration": -np.inf}
    for step in range(1500):
        # commands that push hard for seconds in one direction, then another
        if step % 100 == 0:
            push = rng.normal(0, 3.0, 6) * hexapod.qdd_max
        u, _ = clamp(x, push + rng.normal(0, 0.3, 6) * hexapod.qdd_max)
        q, qd = x[:6], x[6:]
        for s in np.linspace(0, H, 6):
            lengths, speeds, accelerations = hexapod.actuator_motion(
                q + s * qd + 0.5 * s * s * u, qd + s * u, u
            )
            worst["length"] = max(
                worst["length"], np.max(g.min_position - lengths), np.max(lengths - g.max_position)
            )
            worst["speed"] = max(worst["speed"], np.max(np.abs(speeds)) - g.max_speed)
            worst["acceleration"] = max(
                worst["acceleration"], np.max(np.abs(accelerations)) - g.max_acceleration
            )
        x = np.concatenate([q + H * qd + 0.5 * H * H * u, qd + H * u])
    assert worst["length"] < 0, worst
    assert worst["speed"] < 0, worst
    assert worst["acceleration"] < 0, worst
    # and it used the rig: some leg came within 2 cm of a stroke end
    assert worst["length"] > -0.02, worst


def far_reference(seconds: float = 12.0):
    """Cues far beyond the rig: a 6 m/s^2 surge held 5 s, 4 m/s^2 of sway, 0.3 rad/s of
    rotation on every axis."""
    t = np.arange(0.0, seconds + 1e-9, 0.01)
    omega = 0.3 * np.sin(2 * np.pi * np.outer(t, [0.3, 0.4, 0.5]))
    f = np.tile([0.0, 0.0, 9.81], (t.size, 1))
    f[(t > 1) & (t < 6), 0] = 6.0
    f[:, 1] = 4 * np.sin(2 * np.pi * 0.2 * t)
    f[:, 2] += 3 * np.sin(2 * np.pi * 0.7 * t)
    return reference_from_recording(Recording(t, omega, f), name="far")


@pytest.mark.parametrize(
    "mca, plant",
    [
        ("washout", "analytical"),
        ("nmpc-rti", "analytical"),
        ("nmpc-rti", "multibody"),
        ("dpc", "analytical"),  # the hexapod's own shipped policy
    ],
)
def test_cues_far_beyond_the_rig_leave_every_leg_inside_its_limits(hexapod, mca, plant):
    result = run_closed_loop(
        mca=mca,
        reference=far_reference(),
        duration_s=10.0,
        progress=False,
        robot=hexapod,
        plant=plant,
    )
    violations = result.summary["violations"]
    assert set(violations) >= {"actuator_position", "actuator_speed", "actuator_acceleration"}
    assert sum(violations.values()) == 0, violations
    # Oracle: the legs' lengths of the run's joint trajectory, straight from leg_lengths
    n = hexapod.num_joints
    lengths = leg_lengths(pose_of(result.states[:, :n]), hexapod.actuators)
    g = hexapod.actuators
    assert np.all((lengths >= g.min_position) & (lengths <= g.max_position))
    assert result.summary["pi"] < result.summary["pi_zero_motion"]
    if mca == "nmpc-rti":
        assert result.summary["safety_interventions"] > 0  # the legs, not the box, held it


def test_the_usage_counts_a_leg_beyond_its_stroke(hexapod):
    # A hand-made trajectory: 1 cm of heave beyond the box edge, then back.
    q = np.zeros((3, 6))
    q[1, 2] = hexapod.q_max[2] + 0.01
    usage = joint_usage(q, np.zeros_like(q), np.zeros_like(q), hexapod)
    violations = usage.violations()
    assert violations["actuator_position"] == 1 and violations["q"] == 1
    assert violations["actuator_speed"] == 0


def test_a_geometry_that_cannot_move_is_refused():
    g = LegGeometry.symmetric(1.0, 0.7, 0.2, 0.2, 0.9, 0.4, 0.5, 6.0)
    g.min_position = float(leg_lengths(np.zeros(6), g)[0])  # a leg at its stroke's end
    with pytest.raises(ValueError, match="cannot move"):
        leg_platform(g, name="stuck")


def test_meshcat_draws_each_leg_between_its_joints(hexapod):
    from pydrake.geometry import StartMeshcat
    from pydrake.systems.analysis import Simulator

    from mca_drake.simulation.builders import MakeMultibodyClosedLoop
    from mca_drake.systems.meshcat_legs import leg_segments, stroke_used

    # the segments' lengths are the legs' lengths; mid-stroke is 0, a stroke's end 1
    rng = np.random.default_rng(5)
    for q in random_poses(rng, 5, hexapod):
        segments = leg_segments(hexapod, q)
        np.testing.assert_allclose(
            np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1),
            hexapod.actuator_positions(q),
            atol=1e-14,
        )
    g = hexapod.actuators
    np.testing.assert_allclose(
        stroke_used(hexapod, np.array([g.min_position, 0.5 * (g.min_position + g.max_position)])),
        [1.0, 0.0],
    )
    meshcat = StartMeshcat()
    try:
        diagram, handles = MakeMultibodyClosedLoop(
            far_reference(2.0), "washout", meshcat=meshcat, robot=hexapod
        )
        simulator = Simulator(diagram)
        handles["station"].SetInitialState(simulator.get_mutable_context())
        simulator.AdvanceTo(0.5)
        assert all(meshcat.HasPath(f"legs/leg_{i}") for i in range(1, 7))
    finally:
        meshcat.Delete()
