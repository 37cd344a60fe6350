"""Flight policies by envelope: the DPC runs the shipped policy of the cued vehicle's flight
envelope (`mca_drake.cueing.dpc.ENVELOPE_POLICIES`) unless its config names a policy or a
profile; references carry their vehicle to it, and training can keep one class's flights."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mca_drake.cueing import DpcConfig, NmpcConfig
from mca_drake.cueing.dpc import (
    ENVELOPE_POLICIES,
    default_policy_path,
    for_vehicle,
    shipped_policy_path,
    vehicle_policy_name,
)
from mca_drake.learning.dpc_training import flights_of_vehicles
from mca_drake.platforms.files import load_platform
from mca_drake.references.driving import CARS
from mca_drake.references.jsbsim import VEHICLES
from mca_drake.references.recording import Recording
from mca_drake.references.reference import Reference, reference_from_recording
from mca_drake.references.synthetic import ENVELOPES, VEHICLE_ENVELOPES
from mca_drake.resources import SHIPPED_POLICIES
from mca_drake.segments import SOURCE_COLUMNS, SegmentDataset, core_shapes
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")
DATA = Path(__file__).parent / "data"

LIGHT = ("light", "DHC6")
TRANSPORT = ("jet", "A320", "787-8", "MD11", "B747")
AEROBATIC_FIGHTER = ("t6texan2", "T37", "T38", "f16", "f15", "A4", "F4N")


def test_light_and_transport_aircraft_get_their_policy_and_the_rest_the_default():
    """Against the fleet's documented envelopes: the light single and the Twin Otter (the
    light envelope) fly the light policy; the CS/FAR 25 transports the transport policy;
    the trainers and fighters, unnamed and unknown vehicles the default policy; every car
    `mca-drake drive` drives, and "car", the ground policy."""
    assert set(LIGHT) | set(TRANSPORT) | set(AEROBATIC_FIGHTER) == set(VEHICLES)
    assert set(ENVELOPE_POLICIES) <= set(ENVELOPES)
    assert set(ENVELOPE_POLICIES.values()) <= set(SHIPPED_POLICIES)
    for vehicles, envelope, policy in (
        (LIGHT, "light", "light_policy"),
        (TRANSPORT, "transport", "transport_policy"),
    ):
        for vehicle in vehicles:
            assert VEHICLE_ENVELOPES[vehicle] == envelope
            assert vehicle_policy_name(vehicle) == policy, vehicle
            assert DpcConfig(vehicle=vehicle).policy_path("kr500") == shipped_policy_path(policy)
    for vehicle in (*CARS, "car"):
        assert vehicle_policy_name(vehicle) == "ground_policy", vehicle
        assert DpcConfig(vehicle=vehicle).policy_path("kr500") == shipped_policy_path(
            "ground_policy"
        )
        assert DpcConfig(vehicle=vehicle).policy_path("kr500-rail").name == (
            "kr500-rail_ground_policy.npz"
        )
    for vehicle in (*AEROBATIC_FIGHTER, "", "no-such-aircraft"):
        assert vehicle_policy_name(vehicle) == "default_policy", vehicle
        assert DpcConfig(vehicle=vehicle).policy_path("kr500") == default_policy_path()
    files = {shipped_policy_path(p).read_bytes() for p in ("light_policy", "transport_policy")}
    assert len(files | {default_policy_path().read_bytes()}) == 3


def test_a_named_policy_or_profile_wins_over_the_vehicle():
    v6 = shipped_policy_path("policy_v6")
    assert DpcConfig(policy=str(v6), vehicle="light").policy_path("kr500") == v6
    ground = DpcConfig(profile="ground", vehicle="light").policy_path("kr500")
    assert ground == shipped_policy_path("ground_policy")


def test_a_replaced_default_runs_wherever_the_default_would():
    """`default_policy` stands for the shipped default policy: for an unnamed, unknown or
    fighter vehicle, as the recognizer's fallback, with `unnamed` "default"; the envelope
    policies, the ground's and a named policy are untouched."""
    v11 = str(DATA / "policy_v11.npz")
    replaced = DpcConfig(default_policy=v11)
    for vehicle in ("", "f16", "no-such-aircraft"):
        config = DpcConfig(default_policy=v11, vehicle=vehicle)
        assert config.policy_path("kr500") == Path(v11), vehicle
    assert DpcConfig(default_policy=v11, unnamed="default").policy_path("kr500") == Path(v11)
    for vehicle, policy in (("light", "light_policy"), ("B747", "transport_policy")):
        config = DpcConfig(default_policy=v11, vehicle=vehicle)
        assert config.policy_path("kr500") == shipped_policy_path(policy)
    assert DpcConfig(default_policy=v11, profile="ground").policy_path("kr500") == (
        shipped_policy_path("ground_policy")
    )
    v6 = shipped_policy_path("policy_v6")
    assert DpcConfig(default_policy=v11, policy=str(v6)).policy_path("kr500") == v6
    assert replaced.recognizes()
    shipped = DpcConfig().recognized_policy_paths("kr500")
    assert shipped[0] == default_policy_path()
    assert replaced.recognized_policy_paths("kr500") == (Path(v11), *shipped[1:])


def test_a_replaced_default_must_exist_and_be_causal(tmp_path):
    with pytest.raises(FileNotFoundError, match="default_policy"):
        DpcConfig(default_policy=str(tmp_path / "missing.npz")).validate()
    v11 = str(DATA / "policy_v11.npz")
    with pytest.raises(ValueError, match="predictor"):
        DpcConfig(default_policy=v11, predictor="learned").validate()
    DpcConfig(default_policy=v11).validate()


def test_a_replaced_default_flies_as_that_file_named_outright():
    """Array for array, the DPC with `default_policy` on an unnamed reference with
    `unnamed` "default" is the run of that file named as `policy`."""
    v11 = str(DATA / "policy_v11.npz")
    replaced = DpcConfig(default_policy=v11, unnamed="default")
    runs = [
        run_closed_loop(mca=config, reference=_reference(""), progress=False, robot=KR500)
        for config in (replaced, DpcConfig(policy=v11))
    ]
    np.testing.assert_array_equal(runs[0].outputs, runs[1].outputs)
    assert runs[0].summary["policy_file"] == "policy_v11.npz"


def test_for_vehicle_fills_only_a_dpc_without_a_vehicle():
    assert for_vehicle(DpcConfig(), "MD11") == DpcConfig(vehicle="MD11")
    assert for_vehicle(DpcConfig(), "light").policy_path("kr500") == shipped_policy_path(
        "light_policy"
    )
    assert for_vehicle(DpcConfig(vehicle="f16"), "MD11") == DpcConfig(vehicle="f16")
    assert for_vehicle(DpcConfig(), "") == DpcConfig()
    nmpc = NmpcConfig(mode="rti")
    assert for_vehicle(nmpc, "MD11") is nmpc


def test_a_reference_keeps_its_vehicle_when_made_and_cut():
    t = np.arange(0.0, 2.0, 0.01)
    recording = Recording(
        t=t, omega=np.zeros((t.size, 3)), f=np.tile([0.0, 0.0, 9.81], (t.size, 1))
    )
    reference = reference_from_recording(recording, vehicle="B747")
    assert reference.vehicle == "B747"
    assert reference.truncated(1.0).vehicle == "B747"
    assert reference_from_recording(recording).vehicle == ""


def _reference(vehicle: str) -> Reference:
    """1.5 s of a gentle surge and roll-rate pulse, 100 Hz."""
    t = np.arange(0.0, 1.5, 0.01)
    y = np.zeros((t.size, 6))
    y[:, 0] = 0.05 * np.sin(2 * np.pi * t)
    y[:, 3] = 0.5 * np.sin(np.pi * t)
    return Reference(y, 0.01, "test", vehicle)


@pytest.mark.parametrize(
    ("vehicle", "policy"),
    [
        ("DHC6", "light_policy"),
        ("A320", "transport_policy"),
        ("MD11", "transport_policy"),
        ("f16", "default_policy"),
        ("", "default_policy"),
    ],
)
def test_the_closed_loop_runs_the_reference_vehicles_policy(vehicle, policy):
    """The run of DpcConfig() on a reference of `vehicle` is, array for array, the run of
    the envelope's policy file named outright; its summary records the vehicle."""
    picked = run_closed_loop(
        mca=DpcConfig(), reference=_reference(vehicle), progress=False, robot=KR500
    )
    named = DpcConfig(policy=str(shipped_policy_path(policy)))
    outright = run_closed_loop(
        mca=named, reference=_reference(vehicle), progress=False, robot=KR500
    )
    np.testing.assert_array_equal(picked.outputs, outright.outputs)
    assert picked.summary["mca"] == "dpc"
    assert picked.summary["mca_config"]["vehicle"] == vehicle
    assert picked.summary["policy_file"] == f"{policy}.npz"


def _dataset(vehicles: dict[str, str]) -> SegmentDataset:
    """Two 4-step segments per flight seed, zeros, with `flight_vehicles` metadata."""
    seeds = [int(s) for s in vehicles for _ in range(2)]
    arrays = {k: np.zeros((len(seeds), 4, *shape)) for k, shape in core_shapes(6).items()}
    source = np.zeros((len(seeds), len(SOURCE_COLUMNS)), dtype=int)
    source[:, SOURCE_COLUMNS.index("flight_seed")] = seeds
    return SegmentDataset(arrays, source, {"flight_vehicles": vehicles})


def test_training_keeps_the_flights_of_the_vehicles_asked_for():
    data = _dataset({"100": "light", "101": "f16", "102": "A320", "103": "light"})
    kept = flights_of_vehicles(data, ("light", "A320"))
    assert sorted(set(kept.source[:, 0].tolist())) == [100, 102, 103]
    assert len(kept) == 6
    with pytest.raises(ValueError, match=r"no flight of MD11.*A320, f16, light"):
        flights_of_vehicles(data, ("MD11",))
    unlabelled = SegmentDataset(data.arrays, data.source, {})
    with pytest.raises(ValueError, match="flight_vehicles"):
        flights_of_vehicles(unlabelled, ("light",))


def test_a_recording_names_no_vehicle_and_a_built_in_flight_its_own(tmp_path):
    """A built-in flight's reference carries its vehicle; a recording whose header names
    none has none (its spec's `vehicle` is only the field's default), so the DPC runs the
    default policy unless its config names the vehicle."""
    from mca_drake.references.drives import motion_reference
    from mca_drake.references.flights import FlightSpec

    csv = tmp_path / "flight.csv"
    rows = [f"{0.01 * k:.2f},0,0,0,0,0,9.81" for k in range(51)]  # 0.5 s, level and still
    csv.write_text("t,omega_x,omega_y,omega_z,f_x,f_y,f_z\n" + "\n".join(rows) + "\n")
    recorded = motion_reference(FlightSpec(recording=str(csv)), 0.5)
    assert recorded.vehicle == "" and FlightSpec(vehicle="DHC6").flown_by() == "DHC6"
    picked = for_vehicle(DpcConfig(), recorded.vehicle)
    assert picked.policy_path("kr500") == default_policy_path()


def test_a_recording_that_names_its_car_is_cued_by_the_ground_policy_whole(tmp_path):
    """A recording whose header names its car (`# vehicle: bmw-320i`, as `mca-drake drive`
    writes it), cued with the default `--mca dpc` by `simulate` and `evaluate` without
    `--duration`: the ground policy, and why, in the summary, over the whole 3 s file
    (not the built-in flight's 60 s); the same file without the header: the default
    policy."""
    from mca_drake.app.cli import main

    rows = [
        f"{0.01 * k:.2f},0,0,{0.1 * np.sin(k / 50):.6f},{np.sin(k / 30):.6f},0,9.81"
        for k in range(301)
    ]  # 3 s: a gentle yaw and surge
    header = "t,omega_x [rad/s],omega_y [rad/s],omega_z [rad/s],f_x,f_y,f_z\n"
    body = header + "\n".join(rows) + "\n"
    named, unnamed = tmp_path / "car.csv", tmp_path / "anything.csv"
    named.write_text("# vehicle: bmw-320i\n" + body)
    unnamed.write_text(body)
    for command in ("simulate", "evaluate"):
        for recording, policy in ((named, "ground_policy"), (unnamed, "default_policy")):
            out = tmp_path / f"{command}_{recording.stem}.json"
            args = [command, "--reference", str(recording), "--json", str(out), "--quiet"]
            if command == "simulate":
                args += ["--plant", "analytical", "--plots", ""]
            assert main(args) == 0
            summary = json.loads(out.read_text())
            assert summary["policy_file"] == f"{policy}.npz", summary["policy_reason"]
            assert summary["duration_s"] == pytest.approx(3.0)
        assert (
            "is a car: the ground policy"
            in json.loads((tmp_path / f"{command}_car.json").read_text())["policy_reason"]
        )


@pytest.mark.parametrize(
    ("protocol", "policy"),
    [("beamng", "ground"), ("outsim", "ground"), ("f1", "ground"), ("csv", "default")],
)
def test_a_racing_simulators_stream_is_cued_by_the_ground_policy(protocol, policy):
    """Live, the protocol says what it streams: BeamNG, Live for Speed's OutSim and the F1
    games are cars, and the default DPC runs the ground policy for them (a CSV stream
    names nothing: the default policy). No sender: the loop listens 0.3 s at home."""
    from mca_drake.live.loop import make_decoder, run_live
    from mca_drake.live.receiver import ReceiverConfig

    summary = run_live(
        make_decoder(protocol), "dpc", 0.3, receiver=ReceiverConfig(port=0), robot=KR500
    )
    assert summary["policy_file"] == f"{policy}_policy.npz"
    assert summary["mca_config"]["vehicle"] == ("car" if policy == "ground" else "")
