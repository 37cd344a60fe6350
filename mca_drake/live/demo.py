"""A live demo sender: JSBSim flies the built-in light aircraft in real time and streams its
own FlightGear (FGNetFDM) packets over loopback.

    python -m mca_drake.live.demo --port 5500 [--duration 120] [--seed 7] [--rate 1]

It is a separate process, as a real flight simulator would be: `mca-drake live --demo`
starts it once its receiver listens. The flight is `mca_drake.references.jsbsim.fly`'s
(the scripted pilot, seed `--seed`, training seeds only), paced to the wall clock; JSBSim
sends the packets itself, from an output directive (`jsbsim_output_directive`).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mca_drake.live.fgnetfdm import jsbsim_output_directive
from mca_drake.live.sender_process import start_sender_process
from mca_drake.references.jsbsim import fly_with_log

# Resolution of the packets' time stamps, s (decode with the same).
DEMO_TIME_RESOLUTION_S = 0.001
# The demo flies a training seed (evaluation flights start at 1000).
DEMO_SEED = 7


def stream_flight(
    port: int,
    duration_s: float,
    *,
    seed: int = DEMO_SEED,
    vehicle: str = "light",
    rate: float = 1.0,
    host: str = "127.0.0.1",
) -> None:
    """Flies `vehicle` for `duration_s` (simulated s) at `rate` times real time, JSBSim
    sending FGNetFDM packets to host:port at 100 Hz."""
    if not 0 < rate <= 100:
        raise ValueError(f"rate must be in (0, 100]; got {rate}")
    with tempfile.TemporaryDirectory() as tmp:
        directive = Path(tmp) / "flightgear_udp.xml"
        directive.write_text(
            jsbsim_output_directive(port, host=host, time_resolution_s=DEMO_TIME_RESOLUTION_S)
        )
        start = time.perf_counter()

        def pace(t: float) -> None:
            wait = start + t / rate - time.perf_counter()
            if wait > 0:
                time.sleep(wait)

        fly_with_log(vehicle, duration_s, seed, output_directive=str(directive), on_sample=pace)


def start_demo_sender(port: int, duration_s: float, **options) -> subprocess.Popen:
    """Starts `stream_flight` in its own process (python -m mca_drake.live.demo)."""
    return start_sender_process("mca_drake.live.demo", port, duration_s, **options)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--duration", type=float, default=120.0, help="simulated s")
    parser.add_argument("--seed", type=int, default=DEMO_SEED, help="pilot seed (< 1000)")
    parser.add_argument("--rate", type=float, default=1.0, help="times real time")
    parser.add_argument("--host", default="127.0.0.1")
    args = parser.parse_args(argv)
    if not 0 <= args.seed < 1000:
        parser.error("--seed must be a training seed (0 to 999): evaluation flights start at 1000")
    stream_flight(args.port, args.duration, seed=args.seed, rate=args.rate, host=args.host)
    return 0


if __name__ == "__main__":
    sys.exit(main())
