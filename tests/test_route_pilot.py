"""The route pilot: an independent pilot for evaluation flights only.

Oracles are physics and the route's own geometry: the turn rate of a coordinated orbit
(g tan(phi) / V), the 3 degree glide path, a go-around that climbs; and the structure: it
shares no module with the scripted pilot and flies no training seed. Seeds from 9000 on:
neither training nor the suite's evaluation flights.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from mca_drake.references.flights import FlightSpec, flight_recording
from mca_drake.references.jsbsim import FlightConfig, fly, fly_with_log
from mca_drake.references.jsbsim.fleet import AIRFRAMES
from mca_drake.references.jsbsim.route import DECISION_HEIGHT_M, approach_speed, draw_route
from mca_drake.studies.evaluation import ROUTE_VEHICLES, default_cases

G = 9.81


def _phase_starts(recording, name: str) -> list[float]:
    """Start times (s) of the route's phases called `name`."""
    starts = []
    for item in recording.metadata["phases"].split("; "):
        start, phase = item.split(" ", 1)
        if phase == name:
            starts.append(float(start))
    return starts


CALM = FlightConfig(turbulence_severity=0, turbulence_patch_severity=0)


def test_an_orbit_is_a_coordinated_turn():
    """Circling, the heading turns at the rate the lift's horizontal part gives,
    f_z sin(phi) / V (f_z: the specific force along the body's up axis), with the ball
    centred."""
    recording, log = fly_with_log("light", 60.0, seed=9000, pilot="route", config=CALM)
    assert _phase_starts(recording, "route orbit")[0] == 0.0
    steady = (recording.t > 25.0) & (recording.t < 55.0)
    phi = log.attitude[steady, 0]
    assert np.all(np.abs(phi) > np.radians(15))  # banked all along
    heading_rate = np.gradient(np.unwrap(log.attitude[:, 2]), recording.t)[steady]
    true_airspeed = log.airspeed_mps[steady] * 1.03  # 600 m: TAS about 3 % above CAS
    expected = recording.f[steady, 2] * np.sin(phi) / true_airspeed
    np.testing.assert_allclose(heading_rate, expected, rtol=0.1, atol=0.003)
    assert abs(recording.f[steady, 1]).mean() < 0.3  # ball centred


def test_an_approach_follows_the_glide_path_and_goes_around():
    recording, log = fly_with_log("light", 300.0, seed=9003, pilot="route", config=CALM)
    (glide,) = _phase_starts(recording, "route glide")
    (go_around,) = _phase_starts(recording, "route go-around")
    assert go_around - glide > 20.0
    gliding = (recording.t > glide + 10.0) & (recording.t < go_around - 1.0)
    climb = np.gradient(log.height_m, recording.t)
    gamma = np.degrees(np.arcsin(climb[gliding] / (log.airspeed_mps[gliding] * 1.01)))
    np.testing.assert_allclose(gamma.mean(), -3.0, atol=0.5)
    speed = approach_speed(AIRFRAMES["light"])
    np.testing.assert_allclose(log.airspeed_mps[gliding][-1], speed, atol=3.0)
    after = recording.t > go_around
    assert log.height_m[after].min() > DECISION_HEIGHT_M - 25.0
    assert log.height_m[after][-1] > log.height_m[after].min() + 50.0  # climbing away


@pytest.mark.parametrize("vehicle", ROUTE_VEHICLES)
def test_every_case_e_aircraft_flies_its_routes(vehicle):
    for seed in (9001, 9002):
        recording = fly(vehicle, 300.0, seed, pilot="route")
        assert recording.metadata["source"].startswith("jsbsim route pilot")
        assert np.all(np.isfinite(recording.f))


def test_routes_are_drawn_from_the_seed_and_fly_clean():
    from mca_drake.references.jsbsim.config import default_config

    air, config = AIRFRAMES["jet"], default_config("jet")
    first = draw_route(np.random.default_rng(4), air, config, 0.3, 300.0)
    again = draw_route(np.random.default_rng(4), air, config, 0.3, 300.0)
    assert first == again
    kinds = {
        leg.kind
        for seed in range(40)
        for leg in draw_route(np.random.default_rng(seed), air, config, 0.0, 300.0)
    }
    assert kinds == {"leg", "orbit", "approach"}
    for seed in range(40):
        for leg in draw_route(np.random.default_rng(seed), air, config, 0.0, 300.0):
            assert config.min_altitude_m <= leg.altitude_m <= config.max_altitude_m
            if leg.kind == "approach":  # flown clean: above the clean stall speed
                assert leg.speed_mps >= 1.25 * air.stall_speed


def test_the_route_pilot_is_independent_of_the_scripted_one():
    """route.py imports none of the scripted pilot's modules (its plan, loops, pilot or
    style): only the units, the config and the JSBSim wrapper."""
    import mca_drake.references.jsbsim.route as route

    tree = ast.parse(Path(route.__file__).read_text())
    imported = {
        node.module
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.module and "jsbsim." in node.module
    }
    assert imported == {
        "mca_drake.references.jsbsim.aircraft",
        "mca_drake.references.jsbsim.config",
        "mca_drake.references.jsbsim.model",
    }


def test_the_route_pilot_flies_evaluation_flights_only(tmp_path):
    with pytest.raises(ValueError, match="evaluation flights only"):
        FlightSpec(vehicle="light", seed=500, pilot="route").validate()
    spec = FlightSpec(vehicle="MD11", seed=9004, pilot="route")
    assert "route pilot" in spec.name()
    recording = flight_recording(spec, 20.0, cache_dir=tmp_path)
    assert recording.metadata["source"].startswith("jsbsim route pilot")
    assert [p.name for p in tmp_path.iterdir()] == ["MD11_route_9004_20s.csv"]
    case = {c.name: c for c in default_cases()}["E"]
    assert case.pilot == "route" and min(case.seeds) >= 1000
    assert [case.vehicle_of(s) for s in case.seeds[:6]] == list(ROUTE_VEHICLES)
    with pytest.raises(ValueError, match="airborne only"):
        fly("light", 5.0, 9000, pilot="route", config=FlightConfig(from_ground=True))
    with pytest.raises(ValueError, match="unknown pilot"):
        fly("light", 5.0, 9000, pilot="ace")
