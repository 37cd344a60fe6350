"""Reference scaling and the ReferenceSource system."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from mca_drake.references.recording import Recording
from mca_drake.references.reference import (
    Reference,
    ReferenceScaling,
    reference_from_recording,
    scaled_reference,
    scaled_reference_sample,
)
from mca_drake.systems import ReferenceSource

G = 9.81


def test_level_flight_asks_for_nothing():
    t = np.arange(10) * 0.01
    rec = Recording(t, np.zeros((10, 3)), np.tile([0.0, 0.0, G], (10, 1)))
    np.testing.assert_allclose(reference_from_recording(rec).y, 0.0, atol=1e-15)


def test_scaling_and_gravity_compensation():
    t = np.arange(4) * 0.01
    omega = np.array([[0.2, -0.4, 0.6]] * 4)
    f = np.array([[2.0, -1.0, 12.81]] * 4)
    ref = reference_from_recording(
        Recording(t, omega, f), ReferenceScaling(angular_scale=0.5, force_scale=0.25)
    )
    np.testing.assert_allclose(ref.y[0], [0.1, -0.2, 0.3, 0.5, -0.25, 0.75])
    assert ref.time_step == pytest.approx(0.01)


def test_limits_clip_and_tanh():
    t = np.arange(3) * 0.01
    f = np.array([[10.0, 0.0, G]] * 3)
    rec = Recording(t, np.zeros((3, 3)), f)
    limits = (1.0, 1.0, 1.0, 2.0, 2.0, 2.0)
    clip = reference_from_recording(rec, ReferenceScaling(force_scale=1.0, limits=limits))
    assert clip.y[0, 3] == pytest.approx(2.0)
    soft = reference_from_recording(
        rec, ReferenceScaling(force_scale=1.0, limits=limits, limit_mode="tanh")
    )
    assert soft.y[0, 3] == pytest.approx(2.0 * np.tanh(5.0))


@pytest.mark.parametrize(
    "scaling",
    [
        ReferenceScaling(),
        ReferenceScaling(angular_scale=0.3, force_scale=0.7, limits=(0.2,) * 3 + (1.5,) * 3),
        ReferenceScaling(limits=(0.4, 0.3, 0.2, 1.0, 2.0, 3.0), limit_mode="tanh"),
    ],
)
def test_one_sample_in_floats_scales_as_the_arrays_do(scaling, rng):
    """The live loop's float version against the array formula that scales recordings,
    over samples within and beyond the limits."""
    omega = rng.normal(scale=0.8, size=(200, 3))
    f = rng.normal(scale=6.0, size=(200, 3))
    f[:, 2] += G
    expected = scaled_reference(omega, f, scaling)
    got = [
        scaled_reference_sample(w.tolist(), a.tolist(), scaling)
        for w, a in zip(omega, f, strict=True)
    ]
    np.testing.assert_allclose(got, expected, rtol=1e-15, atol=1e-15)
    assert all(type(v) is float for v in got[0])


def test_bad_scaling_and_reference():
    rec = Recording(np.arange(3) * 0.01, np.zeros((3, 3)), np.tile([0, 0, G], (3, 1)))
    with pytest.raises(ValueError, match="limit_mode"):
        reference_from_recording(rec, ReferenceScaling(limits=(1,) * 6, limit_mode="soft"))
    with pytest.raises(ValueError, match="six positive"):
        reference_from_recording(rec, ReferenceScaling(limits=(1.0, 2.0)))
    with pytest.raises(ValueError, match=r"shape \(T, 6\)"):
        Reference(np.zeros((5, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        Reference(np.full((5, 6), np.nan))


def ramp_reference(n=50, h=0.01):
    y = np.arange(n)[:, None] + np.arange(6)[None, :] / 10.0  # y[k, c] = k + c / 10
    return Reference(y, h, "ramp")


def test_source_outputs_sample_and_preview_at_sample_times():
    ref = ramp_reference()
    source = ReferenceSource(ref, preview_samples=4)
    context = source.CreateDefaultContext()
    for k in (0, 1, 17, 46, 47, 49, 60):
        context.SetTime(k * ref.time_step)
        expected_k = min(k, 49)
        np.testing.assert_array_equal(
            source.GetOutputPort("reference").Eval(context), ref.y[expected_k]
        )
        preview = source.GetOutputPort("reference_preview").Eval(context).reshape(4, 6)
        rows = np.minimum(np.arange(k, k + 4), 49)
        np.testing.assert_array_equal(preview, ref.y[rows])  # holds the last value past the end


def test_source_holds_between_samples():
    ref = ramp_reference()
    source = ReferenceSource(ref)
    context = source.CreateDefaultContext()
    context.SetTime(0.0399)
    np.testing.assert_array_equal(source.GetOutputPort("reference").Eval(context), ref.y[3])


def test_source_in_a_simulation_matches_the_recording():
    ref = ramp_reference()
    builder = DiagramBuilder()
    source = builder.AddSystem(ReferenceSource(ref, preview_samples=2))
    log = LogVectorOutput(source.GetOutputPort("reference"), builder, ref.time_step)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.3)
    data = log.FindLog(simulator.get_context())
    np.testing.assert_array_equal(data.data().T, ref.y[: data.data().shape[1]])


def test_source_rejects_bad_preview():
    with pytest.raises(ValueError, match="preview_samples"):
        ReferenceSource(ramp_reference(), preview_samples=0)
