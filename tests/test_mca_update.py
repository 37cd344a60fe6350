"""The two phases an MCA's step can run in (`mca_drake.systems.mca_update`): the order of
Drake's own events is the oracle (a poll in an unrestricted update and a plant in a discrete
update at the same instant), and every MCA computes the same command in either phase."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from mca_drake.cueing import mca_config_from_name
from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform
from mca_drake.simulation.builders import AddMca
from mca_drake.systems.mca_update import MCA_UPDATE_EVENTS, DeclareMcaUpdate

H, STEPS = 0.01, 6


class Poll(LeafSystem):
    """Sets its output to k at every t_k, in an unrestricted update (as TelemetryReceiver)."""

    def __init__(self):
        super().__init__()
        index = self.DeclareDiscreteState(1)
        self.DeclarePeriodicUnrestrictedUpdateEvent(H, 0.0, self._poll)
        self.DeclareStateOutputPort("k", index)

    def _poll(self, context, state):
        state.get_mutable_discrete_state().set_value(0, [round(context.get_time() / H)])


class Mca(LeafSystem):
    """Holds (the instant of its last step, the poll it read then); DeclareMcaUpdate in the
    phase `event`."""

    def __init__(self, event: str):
        super().__init__()
        self._input = self.DeclareVectorInputPort("k", 1)
        index = self.DeclareDiscreteState(2)
        DeclareMcaUpdate(self, H, self._update, event)
        self.DeclareStateOutputPort("command", index)

    def _update(self, context, discrete):
        discrete.set_value(0, [round(context.get_time() / H), self._input.Eval(context)[0]])


class Plant(LeafSystem):
    """Records, in a discrete update at every t_k (from t_1 on), the instant at which the
    command it would integrate was computed."""

    def __init__(self):
        super().__init__()
        self._input = self.DeclareVectorInputPort("command", 2)
        self.DeclarePeriodicDiscreteUpdateEvent(H, H, self._update)
        self.DeclareDiscreteState(1)
        self.computed_at: list[int] = []

    def _update(self, context, discrete):
        self.computed_at.append(round(self._input.Eval(context)[0]))


def run_event_order(event: str) -> tuple[list[float], list[int]]:
    """(the polls the MCA read at steps 0 .. STEPS - 1, the plant's record at t_1 ...)."""
    builder = DiagramBuilder()
    poll, mca, plant = (builder.AddSystem(s) for s in (Poll(), Mca(event), Plant()))
    builder.Connect(poll.get_output_port(), mca.get_input_port())
    builder.Connect(mca.get_output_port(), plant.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    seen = []
    for k in range(STEPS):
        simulator.AdvanceTo((k + 0.5) * H)  # the updates of t_k handled
        context = mca.GetMyContextFromRoot(simulator.get_context())
        seen.append(float(mca.get_output_port().Eval(context)[1]))
    return seen, plant.computed_at


def test_a_discrete_step_sees_its_instants_poll_and_the_plant_the_previous_command():
    seen, computed_at = run_event_order("discrete")
    assert seen == [float(k) for k in range(STEPS)]  # the poll of its own instant
    # a discrete plant at t_k integrates the command computed at t_(k-1)
    assert computed_at == list(range(STEPS - 1))


def test_an_unrestricted_step_sees_the_poll_a_period_late_and_drives_the_plant_at_once():
    seen, computed_at = run_event_order("unrestricted")
    assert seen == [0.0] + [float(k) for k in range(STEPS - 1)]  # the poll of t_(k-1)
    # the plant at t_k integrates the command computed at t_k
    assert computed_at == list(range(1, STEPS))


def test_an_unknown_event_is_refused():
    with pytest.raises(ValueError, match="unknown MCA update event 'later'"):
        Mca("later")


@pytest.mark.parametrize("name", ["dpc", "washout", "nmpc-rti"])
def test_every_mca_computes_the_same_command_in_either_phase(name):
    robot = load_platform(DEFAULT_PLATFORM)
    x = np.r_[0.1, -0.2, 0.3, 0.0, 0.2, -0.1, 0.05, 0.0, -0.1, 0.2, 0.0, 0.1]
    reference = np.array([0.1, -0.05, 0.02, 0.5, -0.3, 0.2])
    commands = {}
    for event in MCA_UPDATE_EVENTS:
        builder = DiagramBuilder()
        mca = AddMca(builder, mca_config_from_name(name), robot, H, update_event=event)
        diagram = builder.Build()
        context = diagram.CreateDefaultContext()
        sub = mca.GetMyMutableContextFromRoot(context)
        mca.GetInputPort("state").FixValue(sub, x)
        mca.GetInputPort("reference").FixValue(sub, reference)
        if mca.HasInputPort("inertial_output"):
            mca.GetInputPort("inertial_output").FixValue(sub, np.zeros(6))
        simulator = Simulator(diagram, context)
        simulator.AdvanceTo(2.5 * H)  # steps at t = 0, H, 2H
        commands[event] = mca.GetOutputPort("joint_acceleration").Eval(sub).copy()
    assert np.any(commands["unrestricted"] != 0.0)
    np.testing.assert_array_equal(commands["discrete"], commands["unrestricted"])
