"""Supervisor in a closed loop with the analytical plant: faults wash out to home inside the
limits, and the loop recovers."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from mca_drake.live.receiver import TELEMETRY_FIELDS
from mca_drake.live.supervisor import Supervisor, SupervisorConfig
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.usage import joint_usage
from mca_drake.systems.motion_cueing_plant import MotionCueingPlant

KR500 = load_platform("kr500")


class Scripted(LeafSystem):
    """An output of `size` given by fn(t)."""

    def __init__(self, size, fn):
        super().__init__()
        self._fn = fn
        self.DeclareVectorOutputPort("y", size, self._calc, {self.time_ticket()})

    def _calc(self, context, output: BasicVector):
        output.SetFromVector(self._fn(context.get_time()))


def telemetry(fresh: bool):
    values = np.zeros(len(TELEMETRY_FIELDS))
    values[TELEMETRY_FIELDS.index("fresh")] = float(fresh)
    values[TELEMETRY_FIELDS.index("age_s")] = 0.01 if fresh else 1.0
    return values


def run(
    command,
    fresh,
    step_time=lambda t: 1e-3,
    reference=lambda t: np.zeros(6),
    t_end=12.0,
    operator=None,
    initial_state=None,
    telemetry_fn=None,
):
    """Closes the loop plant -> supervisor (with the operator's mode `operator(t)`, if
    given); returns (supervisor, context, states, commands)."""
    builder = DiagramBuilder()
    plant = builder.AddSystem(
        MotionCueingPlant(load_platform("kr500"), initial_state=initial_state)
    )
    supervisor = builder.AddSystem(Supervisor(SupervisorConfig(), robot=KR500))
    sources = {
        "mca_command": Scripted(6, command),
        "reference": Scripted(6, reference),
        "telemetry": Scripted(
            len(TELEMETRY_FIELDS), telemetry_fn or (lambda t: telemetry(fresh(t)))
        ),
        "mca_statistics": Scripted(4, lambda t: [step_time(t), 0, 0, 0]),
    }
    if operator is not None:
        sources["operator"] = Scripted(1, lambda t: [operator(t)])
    for name, source in sources.items():
        builder.Connect(builder.AddSystem(source).get_output_port(), supervisor.GetInputPort(name))
    builder.Connect(plant.GetOutputPort("state"), supervisor.GetInputPort("state"))
    builder.Connect(
        supervisor.GetOutputPort("joint_acceleration"), plant.GetInputPort("joint_acceleration")
    )
    simulator = Simulator(builder.Build())
    root = simulator.get_mutable_context()
    plant_context = plant.GetMyContextFromRoot(root)
    states, commands = [], []
    for k in range(round(t_end / 0.01)):
        simulator.AdvanceTo(k * 0.01)
        states.append(plant.GetOutputPort("state").Eval(plant_context).copy())
        commands.append(plant.GetInputPort("joint_acceleration").Eval(plant_context).copy())
    return supervisor, supervisor.GetMyContextFromRoot(root), np.array(states), np.array(commands)


def push(t):
    """An MCA that drives every joint away from home for a second, then coasts."""
    return np.full(6, 1.0) if t < 1.0 else np.zeros(6)


def test_stale_telemetry_washes_out_home_inside_the_limits_and_recovers(robot):
    fresh = lambda t: not 2.0 <= t < 10.0  # noqa: E731 (a stop from 2 s to 10 s)
    supervisor, context, states, commands = run(push, fresh)
    usage = joint_usage(states[:, :6], states[:, 6:], commands, robot)
    assert usage.violations() == {"q": 0, "qd": 0, "qdd": 0}
    k_stop, k_back = 200, 1000
    # driven away from home (and moving at 1 rad/s) while healthy; home and at rest by the
    # end of the stop
    assert np.max(np.abs(states[k_stop, :6])) > 0.8
    assert np.max(np.abs(states[k_back, :6])) < 0.05
    assert np.max(np.abs(states[k_back, 6:])) < 0.1
    # no acceleration jump at either transition: the blend spreads it over 0.3 s
    jumps = np.abs(np.diff(commands, axis=0)).max(axis=1)
    assert jumps[k_stop - 5 : k_stop + 40].max() < 0.5 * np.abs(commands).max()
    names = [(a, b) for _, a, b, _ in supervisor.transitions]
    assert names[0] == ("ok", "fault") and names[-1][1] == "ok"
    health = supervisor.health(context)
    assert health["state"] == 0 and health["weight"] == 1.0
    assert health["fault_s"] == pytest.approx(8.0 + 0.5, abs=0.03)  # the stop and recovery_s


def test_a_non_finite_mca_command_never_reaches_the_robot(robot):
    bad = lambda t: np.full(6, np.nan) if 1.0 <= t < 1.5 else np.full(6, 0.5)  # noqa: E731
    supervisor, _, states, commands = run(bad, lambda t: True, t_end=3.0)
    assert np.all(np.isfinite(commands)) and np.all(np.isfinite(states))
    assert any("not finite" in why for *_, why in supervisor.transitions)


def test_consecutive_overruns_are_a_fault_and_one_is_degraded():
    step = lambda t: 0.02 if 1.0 <= t < 1.02 else 1e-3  # noqa: E731 (two slow steps)
    supervisor, _, _, _ = run(lambda t: np.zeros(6), lambda t: True, step, t_end=2.0)
    assert [b for _, _, b, _ in supervisor.transitions][:1] == ["degraded"]
    assert "fault" not in [b for _, _, b, _ in supervisor.transitions]
    step3 = lambda t: 0.02 if 1.0 <= t < 1.035 else 1e-3  # noqa: E731 (four slow steps)
    supervisor, _, _, _ = run(lambda t: np.zeros(6), lambda t: True, step3, t_end=2.0)
    assert "fault" in [b for _, _, b, _ in supervisor.transitions]


def test_an_insane_reference_is_a_fault():
    reference = lambda t: np.r_[0, 0, 0, 500.0, 0, 0] if t > 0.5 else np.zeros(6)  # noqa: E731
    supervisor, _, _, _ = run(lambda t: np.zeros(6), lambda t: True, reference=reference, t_end=1.0)
    assert supervisor.transitions[0][2:] == ("fault", "reference beyond max_reference")


@pytest.mark.parametrize(
    "change",
    [{"blend_s": 0.0}, {"overruns_to_fault": 0}, {"home_acceleration_fraction": 1.5}],
)
def test_bad_settings_are_refused(change):
    with pytest.raises(ValueError, match="SupervisorConfig"):
        SupervisorConfig(**change).validate()


def test_a_judgement_offset_outside_the_period_is_refused():
    with pytest.raises(ValueError, match="judge_offset_s"):
        Supervisor(SupervisorConfig(), judge_offset_s=SupervisorConfig().time_step, robot=KR500)


def test_the_first_sample_starts_the_mca_without_a_recovery_wait():
    """Waiting for the stream is a fault ("no telemetry yet") that the first sample ends at
    once: the MCA blends in over blend_s, not after recovery_s as after a lost stream."""
    started = lambda t: t >= 1.0  # noqa: E731

    def telemetry_from(t):
        values = telemetry(True)
        if not started(t):
            values[TELEMETRY_FIELDS.index("age_s")] = np.inf  # no sample yet
        return values

    supervisor, _, _, commands = run(
        lambda t: np.full(6, 0.2), lambda t: True, t_end=3.0, telemetry_fn=telemetry_from
    )
    transitions = supervisor.transitions
    assert [(to, why) for _, _, to, why in transitions] == [
        ("fault", "no telemetry yet"),
        ("ok", "first sample"),
    ]
    assert abs(transitions[1][0] - 1.0) <= 0.011
    config = SupervisorConfig()
    k = round((1.0 + config.blend_s) / 0.01) + 2
    assert np.allclose(commands[k], 0.2)  # the MCA's own command, 0.3 s after the start
