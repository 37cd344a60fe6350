"""The batch-study task loop: a killed parent leaves no worker behind."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mca_drake.studies.parallel import run_tasks

pytestmark = pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc (Linux)")


def _children(pid: int) -> list[int]:
    """Processes whose parent is `pid`, from /proc."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_workers_exit_when_their_parent_is_killed():
    code = (
        "import time\n"
        "from mca_drake.studies.parallel import run_tasks\n"
        "run_tasks(time.sleep, [(60,), (60,)], workers=2, progress=False)\n"
    )
    parent = subprocess.Popen([sys.executable, "-c", code])
    try:
        deadline = time.monotonic() + 60
        workers: list[int] = []
        while time.monotonic() < deadline and len(workers) < 2:
            time.sleep(0.2)
            workers = [
                pid
                for pid in _children(parent.pid)
                if "spawn_main" in Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="ignore")
            ]
        assert len(workers) == 2, "the workers did not start"
        time.sleep(1.0)  # both are inside their 60 s task
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(timeout=10)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and any(_alive(pid) for pid in workers):
            time.sleep(0.2)
        assert not any(_alive(pid) for pid in workers), "orphaned workers still run"
    finally:
        if parent.poll() is None:
            parent.kill()


def test_serial_loop_runs_every_task_and_rejects_no_workers(tmp_path):
    done = []
    run_tasks(done.append, [(1,), (2,)], progress=False)
    assert done == [1, 2]
    with pytest.raises(ValueError, match="workers must be at least 1"):
        run_tasks(done.append, [], workers=0)
