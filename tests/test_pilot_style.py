"""Pilot styles: the scripted pilot is the identity style, the sampler draws from its
documented distributions, and a style changes the flight the way it says.

Oracles: the scripted pilot's own flights (sample for sample), scipy's one-sample
Kolmogorov-Smirnov test against the documented distributions, the Dirichlet's mean, and
the roll rate of a turn against the rate limit the style sets.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import scipy.stats

from mca_drake.references.flights import FlightSpec, flight_recording, pilot_style
from mca_drake.references.jsbsim import FlightConfig, Turn, fly, fly_with_log
from mca_drake.references.jsbsim.fleet import AIRFRAMES
from mca_drake.references.jsbsim.style import (
    MANEUVER_KINDS,
    SCRIPTED_WEIGHTS,
    PilotStyle,
    PilotStyleRanges,
    sample_pilot_style,
)

FACTORS = ("outer_gain", "inner_gain", "aggressiveness", "bank_scale", "vspeed_scale")


@pytest.mark.parametrize(("vehicle", "duration_s"), [("light", 60.0), ("jet", 300.0)])
def test_the_identity_style_flies_the_scripted_pilots_flight(vehicle, duration_s):
    """PilotStyle() changes nothing: the same samples as a flight without a style (the
    300 s jet flight takes off and flies the random plan)."""
    scripted = fly(vehicle, duration_s, seed=3)
    styled = fly(vehicle, duration_s, seed=3, config=FlightConfig(style=PilotStyle()))
    np.testing.assert_array_equal(styled.omega, scripted.omega)
    np.testing.assert_array_equal(styled.f, scripted.f)


def test_the_sampler_draws_from_the_documented_distributions():
    ranges = PilotStyleRanges()
    rng = np.random.default_rng(0)
    styles = [sample_pilot_style(rng, ranges) for _ in range(1500)]
    for name in (*FACTORS, "duration_scale"):
        low, high = getattr(ranges, name)
        values = np.array([getattr(s, name) for s in styles])
        assert values.min() >= low and values.max() <= high, name
        # log-uniform: the logarithm is uniform on [log low, log high]
        unit = (np.log(values) - np.log(low)) / (np.log(high) - np.log(low))
        assert scipy.stats.kstest(unit, "uniform").pvalue > 1e-3, name
    delays = np.array([s.reaction_delay_s for s in styles])
    assert delays.min() >= 0 and delays.max() <= ranges.reaction_delay_s[1]
    np.testing.assert_allclose(delays * 100, np.round(delays * 100), atol=1e-9)  # whole steps
    weights = np.array([s.maneuver_weights for s in styles])
    np.testing.assert_allclose(weights.sum(axis=1), 1.0)
    # a symmetric Dirichlet's mean is 1/K per kind, its variance (K - 1) / (K^2 (K a + 1))
    K, a = len(MANEUVER_KINDS), ranges.maneuver_concentration
    standard_error = np.sqrt((K - 1) / (K * K * (K * a + 1)) / len(styles))
    np.testing.assert_allclose(weights.mean(axis=0), 1 / K, atol=4 * standard_error)
    background = np.array([s.turbulence_severity for s in styles])
    patches = np.array([s.turbulence_patch_severity for s in styles])
    assert set(background) == set(range(ranges.turbulence_severity[1] + 1))
    assert np.all(patches >= background) and patches.max() <= ranges.turbulence_patch_severity[1]


def test_a_style_scales_the_airframe_it_flies():
    air = AIRFRAMES["light"]
    style = PilotStyle(inner_gain=1.2, aggressiveness=0.8)
    styled = style.airframe(air)
    assert styled.roll_rate_gain == pytest.approx(1.2 * air.roll_rate_gain)
    assert styled.pitch_rate_gain == pytest.approx(1.2 * air.pitch_rate_gain)
    assert styled.yaw_gain == pytest.approx(1.2 * air.yaw_gain)
    assert styled.roll_rate_max == pytest.approx(0.8 * air.roll_rate_max)
    assert styled.roll_rate_aggressive == pytest.approx(0.8 * air.roll_rate_aggressive)
    assert styled.pitch_rate_max == pytest.approx(0.8 * air.pitch_rate_max)
    assert styled.stall_speed == air.stall_speed  # the airframe itself is the same


def test_a_gentler_pilot_rolls_into_a_turn_no_faster_than_his_limit():
    """The roll rate into a 60 degree turn stays under the style's (scaled) limit, and the
    gentle pilot's peak rate is lower than the scripted pilot's."""
    turn = FlightConfig(
        maneuvers=(Turn(np.radians(60), 10.0),),
        turbulence_severity=0,
        turbulence_patch_severity=0,
    )
    peaks = {}
    for aggressiveness in (1.0, 0.7):
        config = dataclasses.replace(turn, style=PilotStyle(aggressiveness=aggressiveness))
        _, log = fly_with_log("light", 8.0, seed=1, config=config)
        p = np.gradient(np.unwrap(log.attitude[:, 0]), 0.01)  # roll-in: about the body x axis
        peaks[aggressiveness] = np.abs(p).max()
    limit = AIRFRAMES["light"].roll_rate_max
    assert peaks[0.7] <= 0.7 * limit * 1.15  # the loop overshoots its command a little
    assert peaks[0.7] < 0.85 * peaks[1.0]


def test_a_random_style_flight_is_its_seeds_and_says_so(tmp_path):
    spec = FlightSpec(vehicle="light", seed=5, pilot="random-style")
    recording = flight_recording(spec, 60.0, cache_dir=tmp_path)
    again = flight_recording(spec, 60.0)  # flown again, not read from the cache
    np.testing.assert_array_equal(recording.f, again.f)
    scripted = flight_recording(FlightSpec(vehicle="light", seed=5), 60.0)
    assert np.abs(recording.f - scripted.f).max() > 0.1
    style = json.loads(recording.metadata["pilot_style"])
    drawn = [json.loads(json.dumps(dataclasses.asdict(pilot_style(5, d)))) for d in range(5)]
    assert style in drawn  # the seed's first style that flew
    assert recording.metadata["pilot"] == "random-style"
    assert "random-style pilot" in spec.name()
    # the cache keeps the pilot apart from the scripted flight of the same seed
    assert [p.name for p in tmp_path.iterdir()] == ["light_random-style_5_60s.csv"]
    cached = flight_recording(spec, 60.0, cache_dir=tmp_path)
    np.testing.assert_allclose(cached.f, recording.f, atol=1e-6)


def test_bad_styles_and_pilots_are_refused():
    with pytest.raises(ValueError, match=r"unknown flight\.pilot"):
        FlightSpec(pilot="ace").validate()
    with pytest.raises(ValueError, match="outer_gain"):
        PilotStyle(outer_gain=0.0).validate()
    with pytest.raises(ValueError, match="reaction_delay_s"):
        PilotStyle(reaction_delay_s=float("nan")).validate()
    with pytest.raises(ValueError, match="maneuver_weights"):
        PilotStyle(maneuver_weights=(1.0, 2.0)).validate()
    with pytest.raises(ValueError, match="turbulence_severity"):
        fly("light", 5.0, seed=1, config=FlightConfig(style=PilotStyle(turbulence_severity=9)))
    with pytest.raises(ValueError, match="low above high"):
        PilotStyleRanges(outer_gain=(1.5, 1.0)).validate()
    np.testing.assert_allclose(PilotStyle().weights(), SCRIPTED_WEIGHTS)
