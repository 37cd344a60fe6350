"""The demo senders' processes: a simulator's stand-in runs apart from the loop, as a real
simulator would, so that its work never shares the loop's process."""

import subprocess
import sys


def start_sender_process(module: str, port: int, duration_s: float, **options):
    """Starts `python -m module --port PORT --duration S` with `options` as further flags
    (recording="drive.csv" -> --recording drive.csv); its standard output is discarded.

    Returns:
        The subprocess.Popen of the sender.
    """
    command = [sys.executable, "-m", module, "--port", str(port)]
    command += ["--duration", repr(float(duration_s))]
    for name, value in options.items():
        command += [f"--{name}", str(value)]
    return subprocess.Popen(command, stdout=subprocess.DEVNULL)
