"""The driving demo sender: a training drive as BeamNG MotionSim packets, cued live."""

from __future__ import annotations

import json
import struct
import subprocess
import sys

import numpy as np
import pytest

from mca_drake.app import cli
from mca_drake.live.beamng import BEAMNG_FIELDS, BEAMNG_SIZE, BeamNGDecoder
from mca_drake.live.drive_demo import beamng_packet

G = 9.81


def test_a_level_car_at_rest_is_sent_with_no_acceleration():
    """BeamNG's acceleration leaves gravity out: at rest every acc field is zero and the
    up vector is +z."""
    packet = beamng_packet([0.0, 0.0, G], [0.0, 0.0, 0.0])
    assert len(packet) == BEAMNG_SIZE and packet[:4] == b"BNG1"
    fields = dict(zip(BEAMNG_FIELDS, struct.unpack("<21f", packet[4:]), strict=True))
    assert [fields[k] for k in ("accX", "accY", "accZ")] == [0.0, 0.0, 0.0]
    assert [fields[k] for k in ("upX", "upY", "upZ")] == [0.0, 0.0, 1.0]


def test_braking_in_a_left_turn_is_sent_in_beamngs_axes():
    """6 m/s^2 of braking and 4 m/s^2 towards the left, turning left at 0.5 rad/s: BeamNG's
    acceleration is along right, forward, down (accX = -4, accY = -6) and its yaw rate is
    positive nose right (yawVel = -0.5)."""
    packet = beamng_packet([-6.0, 4.0, G], [0.0, 0.0, 0.5])
    fields = dict(zip(BEAMNG_FIELDS, struct.unpack("<21f", packet[4:]), strict=True))
    assert (fields["accX"], fields["accY"], fields["accZ"]) == pytest.approx((-4.0, -6.0, 0.0))
    assert fields["yawVel"] == pytest.approx(-0.5)


def test_the_decoder_reads_back_what_was_sent():
    rng = np.random.default_rng(3)
    decoder = BeamNGDecoder()
    for _ in range(50):
        f = rng.normal(0.0, 3.0, 3) + np.array([0.0, 0.0, G])
        omega = rng.normal(0.0, 0.5, 3)
        sample = decoder.decode(beamng_packet(f, omega), received_s=1.0)
        np.testing.assert_allclose(sample.f, f, rtol=1e-6, atol=1e-5)
        np.testing.assert_allclose(sample.omega, omega, rtol=1e-6, atol=1e-6)


def test_the_driving_demo_cues_a_drive_live(tmp_path):
    """`mca-drake live --demo --protocol beamng`: a sender process drives a training drive
    and streams it at 100 Hz; the loop cues it on the analytical plant inside the limits."""
    out = tmp_path / "drive_demo.json"
    command = [sys.executable, "-m", "mca_drake.app.cli", "live", "--demo", "--protocol"]
    command += ["beamng", "--plant", "analytical", "--duration", "4", "--mca", "washout"]
    command += ["--json", str(out)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr
    summary = json.loads(out.read_text())
    live = summary["live"]
    assert live["protocol"] == "beamng" and live["bad"] == 0
    assert live["packets"] > 150
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert live["health"]["ok_s"] > 1.0


def test_the_demo_streams_flights_or_drives_only(capsys):
    assert cli.main(["live", "--demo", "--protocol", "xplane", "--duration", "1"]) == 2
    assert "--demo streams fgnetfdm (a flight) or beamng (a drive)" in capsys.readouterr().err
