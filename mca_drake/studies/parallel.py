"""The parallel, resumable task loop that every batch study shares.

A study lists its unfinished tasks (small picklable arguments); each task writes its own
result file atomically, so a killed study resumes by listing again. Tasks run in this
process (`workers == 1`) or in a pool of fresh (spawned) worker processes, each building its
own Drake diagram: diagrams and MathematicalPrograms do not pickle.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
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
        with concurrent.futures.ProcessPoolExecutor(workers, mp_context=context) as pool:
            futures = [pool.submit(function, *task) for task in tasks]
            for future in concurrent.futures.as_completed(futures):
                future.result()  # re-raises a worker's error with its message
                bar.update(1)
