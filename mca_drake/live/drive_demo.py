"""A live driving sender: a training drive streamed as BeamNG.drive's MotionSim packets.

    python -m mca_drake.live.drive_demo --port 5500 [--duration 120] [--seed 7]
        [--car bmw-320i] [--rate 1] [--recording drive.csv]

The racing counterpart of `mca_drake.live.demo`, in a process of its own as a game would be:
`mca-drake live --demo --protocol beamng` starts it once its receiver listens. It sends the
training drive of `--car` and `--seed` (`references.drives.training_spec`: a lap on even
seeds, the proving ground on odd ones; training seeds only), or the recording `--recording`
(the demo drives the car before its loop listens, since the car model runs only a few times
faster than real time), one packet per sample, 100 Hz, paced to the wall clock.

`beamng_packet` encodes a sample as `live.beamng.BeamNGDecoder` reads it with its default
signs: the recording holds the specific force f and the rates omega at the head, not the
car's attitude, so the packet says the car is level (zero roll and pitch, up = +z) and
carries the kinematic acceleration a = f - (0, 0, g), in BeamNG's axes (accX right, accY
forward, accZ down) and its rate senses (roll right side down, pitch nose up, yaw nose
right). Decoding gives back f and omega to float32 precision.
"""

from __future__ import annotations

import argparse
import socket
import struct
import subprocess
import sys
import time

import numpy as np

from mca_drake.conventions import GRAVITY
from mca_drake.live.beamng import BEAMNG_FORMAT
from mca_drake.live.sender_process import start_sender_process
from mca_drake.references.drives import drive_recording, training_spec
from mca_drake.references.driving import CARS
from mca_drake.references.recording import Recording, load_recording

# The demo drives a training seed (evaluation drives start at 1000).
DEMO_SEED = 7
DEMO_CAR = "bmw-320i"
_FLOATS = struct.Struct("<21f")


def beamng_packet(f, omega) -> bytes:
    """The MotionSim packet of a level car whose head feels specific force `f` (3, m/s^2,
    x forward, y left, z up) and turns at `omega` (3, rad/s, same axes)."""
    a = np.asarray(f, dtype=float) - (0.0, 0.0, GRAVITY)
    w = np.asarray(omega, dtype=float)
    position, velocity, up, angles, angular_acceleration = (
        (0.0,) * 3,
        (0.0,) * 3,
        (0, 0, 1),
        (0.0,) * 3,
        (0.0,) * 3,
    )
    acc = (-a[1], a[0], -a[2])
    rates = (w[0], -w[1], -w[2])
    values = (*position, *velocity, *acc, *up, *angles, *rates, *angular_acceleration)
    return BEAMNG_FORMAT + _FLOATS.pack(*values)


def demo_drive(duration_s: float, *, seed: int = DEMO_SEED, car: str = DEMO_CAR) -> Recording:
    """The demo's drive: the training drive of `car` and `seed`, `duration_s` s long."""
    return drive_recording(training_spec(car, seed), duration_s)


def stream_recording(
    port: int, recording: Recording, *, rate: float = 1.0, host: str = "127.0.0.1"
) -> int:
    """Sends the samples of `recording` to host:port as MotionSim packets at `rate` times
    real time; returns the number sent."""
    if not 0 < rate <= 100:
        raise ValueError(f"rate must be in (0, 100]; got {rate}")
    packets = [beamng_packet(f, w) for f, w in zip(recording.f, recording.omega, strict=True)]
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    start = time.perf_counter()
    try:
        for t, packet in zip(recording.t - recording.t[0], packets, strict=True):
            wait = start + t / rate - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            sender.sendto(packet, (host, port))
    finally:
        sender.close()
    return len(packets)


def start_drive_sender(port: int, duration_s: float, **options) -> subprocess.Popen:
    """Starts the sender in its own process (python -m mca_drake.live.drive_demo) with
    `options` as its flags (recording="drive.csv": send that file)."""
    return start_sender_process("mca_drake.live.drive_demo", port, duration_s, **options)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--duration", type=float, default=120.0, help="driven s")
    parser.add_argument("--seed", type=int, default=DEMO_SEED, help="drive seed (< 1000)")
    parser.add_argument("--car", default=DEMO_CAR, help=f"one of {', '.join(CARS)}")
    parser.add_argument("--rate", type=float, default=1.0, help="times real time")
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--recording", help="send this recording CSV instead of driving")
    args = parser.parse_args(argv)
    if not 0 <= args.seed < 1000:
        parser.error("--seed must be a training seed (0 to 999): evaluation drives start at 1000")
    if args.recording:
        recording = load_recording(args.recording)
    else:
        recording = demo_drive(args.duration, seed=args.seed, car=args.car)
    stream_recording(args.port, recording, rate=args.rate, host=args.host)
    return 0


if __name__ == "__main__":
    sys.exit(main())
