"""The parallel, resumable task loop that every batch study shares.

A study lists its unfinished tasks (small picklable arguments); each task writes its own
result file atomically, so a killed study resumes by listing again. Tasks run in this
process (`workers == 1`) or in a pool of fresh (spawned) worker processes, each building its
own Drake diagram: diagrams and MathematicalPrograms do not pickle. A worker watches its
parent and exits when the parent is gone (killed with -9, say), so no orphan goes on
simulating and writing files.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Sequence

from tqdm.auto import tqdm


def run_tasks(
    function: Callable,
    tasks: Sequence[tuple],
    *,
    workers: int = 1,
    total: int | None = None,
    description: str = "tasks",
    unit: str = "task",
    progress: bool = True,
) -> None:
    """Calls `function(*task)` for every task, in `workers` processes, with a progress bar.

    Args:
        function: a module-level function (picklable), which writes its own result.
        tasks: the argument tuples of the unfinished tasks.
        total: the study's size, finished tasks included (the bar starts at
            total - len(tasks)); default len(tasks).

    Raises:
        ValueError: workers below 1.
        Exception: the first error a task raised, with its message.
    """
    if workers < 1:
        raise ValueError(f"workers must be at least 1; got {workers}")
    total = len(tasks) if total is None else total
    bar = tqdm(
        total=total, initial=total - len(tasks), desc=description, unit=unit, disable=not progress
    )
    with bar:
        if workers == 1:
            for task in tasks:
                function(*task)
                bar.update(1)
            return
        context = multiprocessing.get_context("spawn")
        with concurrent.futures.ProcessPoolExecutor(
            workers, mp_context=context, initializer=_watch_parent, initargs=(os.getpid(),)
        ) as pool:
            futures = [pool.submit(function, *task) for task in tasks]
            for future in concurrent.futures.as_completed(futures):
                future.result()  # re-raises a worker's error with its message
                bar.update(1)


# How often a worker checks that its parent still runs, s.
_PARENT_POLL_S = 0.5


def _watch_parent(parent_pid: int) -> None:
    """Worker initialiser: a daemon thread that ends this process once `parent_pid` is no
    longer its parent (the parent died and the worker was re-parented)."""

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(_PARENT_POLL_S)
        os._exit(1)  # no cleanup to run: results are written atomically, per task

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()
