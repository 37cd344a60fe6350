"""The live loop's recorder: rows before each poll are the values at each control instant
(Drake's own logger at t_k is the oracle), rows after each command are the commands the
plant integrated (the double integrator's closed form is the oracle)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import LogVectorOutput

from mca_drake.live.loop import PLANT_DELAY_S, PROBE_DELAY_S
from mca_drake.live.recorder import AFTER_COMMAND_S, BEFORE_POLL_S, LiveRecorder
from mca_drake.platforms.files import load_platform
from mca_drake.systems import MotionCueingPlant
from mca_drake.systems.mca_update import DeclareMcaUpdate

H, STEPS = 0.01, 25


def command_at(k: int) -> np.ndarray:
    return np.array([np.sin(0.3 * k), 0.1 * k, -0.05, 0.0, np.cos(k), 0.2])


class CountingMca(LeafSystem):
    """Stores command_at(k) at every t_k in a discrete update, as the live loop's MCAs do."""

    def __init__(self):
        super().__init__()
        self._index = self.DeclareDiscreteState(7)  # k, u
        DeclareMcaUpdate(self, H, self._update, "discrete")
        self.DeclareVectorOutputPort("u", 6, self._output, {self.xd_ticket()})

    def _update(self, context, discrete):
        k = int(context.get_discrete_state(self._index).value()[0])
        discrete.set_value(self._index, np.r_[k + 1, command_at(k)])

    def _output(self, context, output):
        output.SetFromVector(context.get_discrete_state(self._index).value()[1:])


def test_the_delays_keep_their_order():
    # probe, then the recorder, then the plant that integrates what was recorded
    assert 0 < PROBE_DELAY_S < AFTER_COMMAND_S < PLANT_DELAY_S < H - BEFORE_POLL_S


def test_rows_are_the_instants_values_and_the_commands_the_plant_integrated():
    builder = DiagramBuilder()
    mca = builder.AddSystem(CountingMca())
    x0 = np.r_[np.full(6, 0.1), np.full(6, -0.2)]
    plant = builder.AddSystem(
        MotionCueingPlant(
            load_platform("kr500"), time_step=H, initial_state=x0, update_offset_s=PLANT_DELAY_S
        )
    )
    builder.Connect(mca.get_output_port(), plant.get_input_port())
    state = plant.GetOutputPort("state")
    recorder = builder.AddSystem(LiveRecorder({"state": 12}, {"command": 6}, H))
    builder.Connect(state, recorder.GetInputPort("state"))
    builder.Connect(mca.get_output_port(), recorder.GetInputPort("command"))
    oracle = LogVectorOutput(state, builder, H)  # at every t_k, before its updates
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(STEPS * H)

    states, commands = recorder.rows("state"), recorder.rows("command")
    assert states.shape == (STEPS + 1, 12) and commands.shape == (STEPS, 6)
    logged = oracle.FindLog(simulator.get_context()).data().T
    np.testing.assert_array_equal(states, logged)  # x_k, as at t_k before its updates
    np.testing.assert_array_equal(commands, [command_at(k) for k in range(STEPS)])
    x = x0.copy()
    for k in range(STEPS):  # the double integrator's exact step with u_k
        u = command_at(k)
        x = np.r_[x[:6] + H * x[6:] + 0.5 * H * H * u, x[6:] + H * u]
        np.testing.assert_allclose(states[k + 1], x, rtol=0, atol=1e-12)


def test_bad_recorder_settings_are_named():
    with pytest.raises(ValueError, match="both"):
        LiveRecorder({"a": 1}, {"a": 1}, H)
    with pytest.raises(ValueError, match="no room"):
        LiveRecorder({"a": 1}, {"b": 1}, 1e-5)
    recorder = LiveRecorder({"a": 1}, {"b": 1}, H)
    with pytest.raises(KeyError, match="no port 'c'"):
        recorder.rows("c")
