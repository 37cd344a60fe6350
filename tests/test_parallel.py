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


def _ray_task_workers() -> list[int]:
    """Processes running a task of `run_tasks` (Ray names them after the task function)."""
    found = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            text = cmdline.read_bytes().decode(errors="ignore")
        except OSError:
            continue
        if text.startswith("ray::_call"):
            found.append(int(cmdline.parent.name))
    return found


def test_workers_exit_when_their_parent_is_killed():
    """kill -9 of a study's driver: the Ray workers running its tasks end with it."""
    code = (
        "import time\n"
        "from mca_drake.studies.parallel import run_tasks\n"
        "run_tasks(time.sleep, [(120,), (120,)], workers=2, progress=False)\n"
    )
    before = set(_ray_task_workers())
    parent = subprocess.Popen([sys.executable, "-c", code], stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 90
        workers: list[int] = []
        while time.monotonic() < deadline and len(workers) < 2:
            time.sleep(0.2)
            workers = [pid for pid in _ray_task_workers() if pid not in before]
        assert len(workers) == 2, "the workers did not start"
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(timeout=10)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and any(_alive(pid) for pid in workers):
            time.sleep(0.2)
        assert not any(_alive(pid) for pid in workers), "orphaned workers still run"
    finally:
        if parent.poll() is None:
            parent.kill()


def test_tasks_run_on_a_local_ray_and_a_failure_names_its_cause(tmp_path):
    """Two workers: every task runs once (each writes its file), and a failing task stops
    the study with the task's own message."""
    targets = [tmp_path / f"{k}.txt" for k in range(4)]
    run_tasks(Path.write_text, [(t, "done") for t in targets], workers=2, progress=False)
    assert all(t.read_text() == "done" for t in targets)
    with pytest.raises(RuntimeError, match="invalid literal for int"):
        run_tasks(int, [("x",)], workers=2, progress=False)


def test_serial_loop_runs_every_task_and_rejects_no_workers(tmp_path):
    done = []
    run_tasks(done.append, [(1,), (2,)], progress=False)
    assert done == [1, 2]
    with pytest.raises(ValueError, match="workers must be at least 1"):
        run_tasks(done.append, [], workers=0)


def test_a_cluster_refusing_the_token_gets_a_message_with_the_fix(monkeypatch):
    """Ray's AuthenticationError (token authentication, on by default for local clusters
    since Ray 2.59) becomes one message that says how to pass the token."""
    import ray

    from mca_drake.studies.parallel import ray_session

    def refuse(**_):
        raise ray.exceptions.AuthenticationError("token missing or mismatched")

    monkeypatch.setattr(ray, "init", refuse)
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    with pytest.raises(RuntimeError, match="RAY_AUTH_TOKEN") as caught:
        with ray_session(1, "127.0.0.1:6379"):
            pass
    assert "ray get-auth-token" in str(caught.value) and "127.0.0.1:6379" in str(caught.value)


def test_paths_leave_the_driver_absolute(tmp_path, monkeypatch):
    """Relative paths in a task (a Path, a config's file fields, nested) are made absolute
    against the driver's folder: a cluster's workers run in folders of their own."""
    from pathlib import Path

    from mca_drake.cueing import DpcConfig, NmpcConfig
    from mca_drake.studies.parallel import with_absolute_paths
    from mca_drake.studies.table2 import Table2Config

    monkeypatch.chdir(tmp_path)
    task = (
        Path("out"),
        [DpcConfig(policy="policies/p.npz"), NmpcConfig()],
        Table2Config(closed_loop_dataset="data/cl.npz", open_loop_dataset="/abs/ol.npz"),
        "results",  # a plain string is the caller's to resolve
    )
    out, mcas, table2, text = with_absolute_paths(task)
    assert out == tmp_path / "out"
    assert mcas[0].policy == str(tmp_path / "policies" / "p.npz")
    assert mcas[1] is task[1][1]  # nothing to change: the same object
    assert table2.closed_loop_dataset == str(tmp_path / "data" / "cl.npz")
    assert table2.open_loop_dataset == "/abs/ol.npz" and text == "results"
