"""The human-operator pilot (`FlightSpec(pilot="human")`): the scripted pilot's tasks flown
with McRuer's crossover model's reaction delay, neuromuscular lag and remnant, a pilot no
training flies (the validation pilot).

Oracles: the sampled step response of a first-order lag, 1 - exp(-t / T); the first-order
autoregression's variance and lag-one autocorrelation (1 - alpha); the crossover rule's
gain written out.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mca_drake.references.flights import (
    PILOTS,
    TRAINING_SOURCES,
    FlightSpec,
    flight_recording,
    human_operator,
)
from mca_drake.references.jsbsim.aircraft import STEP_S
from mca_drake.references.jsbsim.loops import Hand
from mca_drake.references.jsbsim.style import (
    CROSSOVER_DELAY_S,
    CROSSOVER_INNER_S,
    HumanOperatorRanges,
    PilotStyle,
)


def test_the_hand_lags_a_step_as_a_first_order_lag():
    hand = Hand(lag_s=0.1, remnant=0.0, seed=0)
    assert hand.move((0.0, 0.0, 0.0)) == (0.0, 0.0, 0.0)  # starts where it is told
    for k in range(1, 60):
        out = hand.move((1.0, -0.5, 0.2))
        expected = 1.0 - math.exp(-k * STEP_S / 0.1)
        assert out == pytest.approx((expected, -0.5 * expected, 0.2 * expected), abs=1e-12)


def test_without_a_lag_the_hand_passes_the_commands_through():
    hand = Hand(lag_s=0.0, remnant=0.0, seed=0)
    assert hand.move((0.3, -0.2, 0.1)) == (0.3, -0.2, 0.1)
    assert hand.move((-0.4, 0.5, 0.0)) == (-0.4, 0.5, 0.0)


def test_the_remnant_has_its_rms_and_the_lags_spectrum():
    lag, remnant = 0.12, 0.02
    hand = Hand(lag_s=lag, remnant=remnant, seed=5)
    hand.move((0.0, 0.0, 0.0))
    out = np.array([hand.move((0.0, 0.0, 0.0)) for _ in range(100_000)])[1000:]
    assert np.sqrt(np.mean(out**2, axis=0)) == pytest.approx([remnant] * 3, rel=0.05)
    # white noise through the lag is a first-order autoregression: rho(1) = 1 - alpha
    alpha = 1.0 - math.exp(-STEP_S / lag)
    for axis in range(3):
        x = out[:, axis]
        rho = np.dot(x[1:], x[:-1]) / np.dot(x, x)
        assert rho == pytest.approx(1.0 - alpha, abs=0.01)
    # the axes' remnants are independent
    assert abs(np.corrcoef(out.T)[0, 1]) < 0.05


def test_a_style_refuses_a_remnant_without_a_lag_and_lags_out_of_range():
    with pytest.raises(ValueError, match="needs a neuromuscular_lag_s"):
        PilotStyle(remnant=0.01).validate()
    with pytest.raises(ValueError, match="neuromuscular_lag_s"):
        PilotStyle(neuromuscular_lag_s=0.5).validate()
    with pytest.raises(ValueError, match="remnant"):
        PilotStyle(neuromuscular_lag_s=0.1, remnant=0.5).validate()


def test_a_human_operator_is_drawn_from_its_seed_with_the_crossover_models_gains():
    ranges = HumanOperatorRanges()
    for seed in range(700, 720):
        style = human_operator(seed)
        assert style == human_operator(seed)  # the seed's, every time
        style.validate()
        assert ranges.reaction_delay_s[0] <= style.reaction_delay_s <= ranges.reaction_delay_s[1]
        assert round(style.reaction_delay_s / STEP_S) * STEP_S == pytest.approx(
            style.reaction_delay_s
        )
        lag = style.neuromuscular_lag_s
        assert ranges.neuromuscular_lag_s[0] <= lag <= ranges.neuromuscular_lag_s[1]
        assert ranges.remnant[0] <= style.remnant <= ranges.remnant[1]
        tau_e = style.reaction_delay_s + lag
        assert style.outer_gain == pytest.approx(CROSSOVER_DELAY_S / (CROSSOVER_DELAY_S + tau_e))
        # the inner loops cross over as 1 / tau_e (within the style's allowed gains)
        assert style.inner_gain == pytest.approx(min(max(CROSSOVER_INNER_S / tau_e, 0.2), 1.0))
        assert style.maneuver_weights is None  # the scripted pilot's tasks
    assert human_operator(700) != human_operator(701)


def test_the_human_pilot_flies_and_no_training_source_is_it():
    assert "human" in PILOTS and "human" not in TRAINING_SOURCES
    spec = FlightSpec(vehicle="light", seed=700, pilot="human")
    spec.validate()
    assert "human pilot" in spec.name()
    human = flight_recording(spec, 30.0)
    scripted = flight_recording(FlightSpec(vehicle="light", seed=700), 30.0)
    assert human.metadata["pilot"] == "human"
    assert '"remnant_seed": 700' in human.metadata["pilot_style"]
    assert human.omega.shape == scripted.omega.shape
    assert not np.allclose(human.omega, scripted.omega)
