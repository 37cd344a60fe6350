"""Input plausibility (`mca_drake.cueing.plausibility`, `systems.plausibility.ReferenceGuard`):
spikes held, jumps bounded, frozen streams faded out and back, non-finite samples held; and
in front of every MCA without changing a clean run.

Oracles: the clean reference itself (a guard must pass it unchanged), the hold and ramp
sequences in closed form, the smoothstep fade in closed form, and the same closed loop run
without the guard.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mca_drake.cueing.plausibility import (
    PlausibilityConfig,
    counts,
    frozen,
    guard_step,
    initial_state,
)
from mca_drake.cueing.washout import WashoutConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop

DT = 0.01
KR500 = load_platform("kr500")


def _smooth(seconds: float, seed: int = 0) -> np.ndarray:
    """A smooth, noisy-looking reference (T, 6) within a flight's rates."""
    t = np.arange(round(seconds / DT)) * DT
    rng = np.random.default_rng(seed)
    phases = rng.uniform(0, 2 * np.pi, 6)
    amplitudes = np.array([0.05, 0.03, 0.03, 1.0, 0.8, 1.5])
    y = amplitudes * np.sin(2 * np.pi * 0.3 * t[:, None] + phases)
    return y + 1e-4 * rng.standard_normal(y.shape)  # every sample differs, as telemetry does


def _guarded(y: np.ndarray, config: PlausibilityConfig | None = None):
    config = config or PlausibilityConfig()
    state = initial_state()
    out = np.array([guard_step(state, row, DT, config) for row in y])
    return out, state


def test_a_clean_reference_passes_unchanged():
    y = _smooth(20.0)
    out, state = _guarded(y)
    np.testing.assert_array_equal(out, y)
    assert counts(state) == dict.fromkeys(counts(state), 0)


def test_a_one_sample_spike_is_held_at_the_sample_before():
    y = _smooth(5.0)
    spiky = y.copy()
    k = 200
    spiky[k, 5] += 25.0  # 50 m/s^2 of the vehicle at the default scale 0.5
    out, state = _guarded(spiky)
    expected = y.copy()
    expected[k, 5] = y[k - 1, 5]  # held
    np.testing.assert_array_equal(out, expected)
    assert counts(state)["spike_periods"] == 1


def test_a_jump_that_stays_is_held_then_followed_at_the_step_bound():
    config = PlausibilityConfig()
    y = np.zeros((40, 6))
    y[10:, 4] = 21.0  # a reset: the lateral force jumps by 21 and stays
    out, state = _guarded(y, config)
    held = config.spike_samples
    step = config.max_steps[4]
    expected = np.zeros(40)
    for k in range(10 + held, 40):
        expected[k] = min(expected[k - 1] + step, 21.0)
    np.testing.assert_allclose(out[:, 4], expected, rtol=0, atol=1e-12)
    assert np.all(np.abs(np.diff(out[:, 4])) <= step + 1e-12)
    assert counts(state)["spike_periods"] == held
    assert counts(state)["step_bounded_periods"] == math.ceil(21.0 / step) - 1


def test_a_frozen_stream_fades_out_to_zero_and_back_in():
    config = PlausibilityConfig(frozen_s=0.5, fade_s=1.0)
    y = _smooth(8.0)
    start, stop = 300, 600  # a paused game: the last frame, 3 s
    y[start:stop] = y[start - 1]
    out, state = _guarded(y, config)
    np.testing.assert_array_equal(out[:start], y[:start])
    # frozen once 0.5 s of repeats have passed: the weight falls by DT / fade_s per period
    # from there (smoothstep), then rises again once the stream moves
    first = start - 1 + round(config.frozen_s / DT)
    weights = np.ones(len(y))
    fade = 1.0
    for k in range(first, len(y)):
        fade = max(fade - DT / config.fade_s, 0.0) if k < stop else min(fade + DT, 1.0)
        weights[k] = fade * fade * (3 - 2 * fade)
    np.testing.assert_allclose(out, weights[:, None] * y, rtol=0, atol=1e-12)
    assert np.all(out[first + 100 : stop] == 0.0)  # faded out: the MCA washes out to home
    assert counts(state)["frozen_events"] == 1
    assert counts(state)["frozen_periods"] == stop - first
    assert not frozen(state)


def test_a_synthetic_step_held_constant_is_not_taken_for_frozen():
    y = np.zeros((500, 6))
    y[100:, 5] = 3.0  # constant before and after: never a moving stream
    out, state = _guarded(y)
    np.testing.assert_array_equal(out, y)
    assert counts(state)["frozen_events"] == 0


def test_non_finite_samples_are_held_and_counted():
    y = _smooth(2.0)
    bad = y.copy()
    bad[50, 0] = np.nan
    bad[51, 3] = np.inf
    out, state = _guarded(bad)
    assert np.all(np.isfinite(out))
    assert out[50, 0] == y[49, 0] and out[51, 3] == y[50, 3]
    np.testing.assert_array_equal(out[52:], y[52:])
    assert counts(state)["non_finite_periods"] == 2


def test_bad_settings_are_refused():
    for bad in (
        PlausibilityConfig(spike_thresholds=[1.0] * 5),
        PlausibilityConfig(max_steps=[1.0, 1.0, 1.0, 1.0, 1.0, 0.0]),
        PlausibilityConfig(fade_s=0.0),
        PlausibilityConfig(frozen_s=math.nan),
    ):
        with pytest.raises(ValueError, match="PlausibilityConfig"):
            bad.validate()


def test_the_guard_changes_no_clean_closed_loop_run():
    reference = Reference(_smooth(10.0, seed=3), DT)
    guarded = run_closed_loop(mca=WashoutConfig(), reference=reference, robot=KR500, progress=False)
    plain = run_closed_loop(
        mca=WashoutConfig(),
        reference=reference,
        robot=KR500,
        progress=False,
        plausibility=PlausibilityConfig(enabled=False),
    )
    np.testing.assert_array_equal(guarded.commands, plain.commands)
    assert guarded.summary["plausibility"]["spike_periods"] == 0
    assert "plausibility" not in plain.summary


def test_a_spike_leaves_the_cue_as_the_clean_runs():
    clean = _smooth(10.0, seed=4)
    spiky = clean.copy()
    spiky[400, 5] += 25.0
    runs = {}
    for label, y, enabled in (
        ("clean", clean, True),
        ("spiky", spiky, True),
        ("raw", spiky, False),
    ):
        runs[label] = run_closed_loop(
            mca=WashoutConfig(),
            reference=Reference(y, DT),
            robot=KR500,
            progress=False,
            plausibility=PlausibilityConfig(enabled=enabled),
        ).outputs
    spiked_gap = np.abs(runs["raw"] - runs["clean"]).max()
    guarded_gap = np.abs(runs["spiky"] - runs["clean"]).max()
    # the held sample differs from the clean one by one period's change (< 0.01 here)
    assert guarded_gap < 0.02 * spiked_gap


def test_a_reset_cross_fades_from_where_the_output_was_to_the_stream():
    config = PlausibilityConfig(fade_s=0.5)
    y = _smooth(4.0, seed=5)
    k = 200
    jumped = y.copy()
    jumped[k:] += [0.1, -0.1, 0.1, 1.5, -1.2, 2.0]  # every channel at once: a reset
    out, state = _guarded(jumped, config)
    np.testing.assert_array_equal(out[:k], y[:k])
    total = round(config.fade_s / DT)
    for j in range(total):
        share = (j + 1) / total
        weight = share * share * (3 - 2 * share)
        expected = out[k - 1] + weight * (jumped[k + j] - out[k - 1])
        np.testing.assert_allclose(out[k + j], expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out[k + total :], jumped[k + total :])
    assert counts(state)["resets"] == 1


def test_one_channel_jumping_alone_is_no_reset():
    """An afterburner lit: the surge alone steps by 5.5 on the reference, within the step
    bound and below the spike threshold; it passes unchanged."""
    y = _smooth(4.0, seed=6)
    y[200:, 3] += 5.5
    out, state = _guarded(y)
    np.testing.assert_array_equal(out, y)
    assert counts(state)["resets"] == 0


def test_the_drake_system_steps_as_the_guard_does():
    """ReferenceGuard in a diagram (its output logged at each period) against guard_step on
    the same samples: a freeze and a reset included, equal to the last bit."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import LogVectorOutput

    from mca_drake.systems import ReferenceSource
    from mca_drake.systems.plausibility import ReferenceGuard

    y = _smooth(8.0, seed=7)
    y[300:600] = y[299]  # frozen 3 s
    y[700:] += [0.1, -0.1, 0.1, 1.5, -1.2, 2.0]  # a reset
    builder = DiagramBuilder()
    source = builder.AddSystem(ReferenceSource(Reference(y, DT)))
    guard = builder.AddSystem(ReferenceGuard(PlausibilityConfig(), DT))
    builder.Connect(source.GetOutputPort("reference"), guard.GetInputPort("reference"))
    log = LogVectorOutput(guard.GetOutputPort("guarded_reference"), builder, DT)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo((len(y) - 1) * DT + 1e-9)
    logged = log.FindLog(simulator.get_context()).data().T
    expected, state = _guarded(y)
    np.testing.assert_array_equal(logged, expected)
    assert counts(state)["frozen_events"] == 1 and counts(state)["resets"] >= 1
