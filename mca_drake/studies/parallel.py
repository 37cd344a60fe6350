"""The parallel, resumable task loop that every batch study shares, on Ray.

A study lists its unfinished tasks (small picklable arguments: configs, seeds, paths); each
task writes its own result file atomically, so a killed study resumes by listing again.
Tasks run in this process (`workers == 1`, no cluster address) or as Ray tasks: on a local
Ray started with `workers` CPUs, or on an existing cluster (`address`, or the RAY_ADDRESS
environment variable). Each task builds its own Drake diagram: diagrams and
MathematicalPrograms do not pickle. When the driver dies (kill -9), Ray ends its workers,
so no orphan goes on simulating and writing files.

A cluster's workers run in folders of their own: every path a task carries (a `Path`, and
the file fields of its configs, `PATH_FIELDS`) is made absolute on the driver before the
task leaves it, and each study resolves its output folder at its start.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from tqdm.auto import tqdm

# Config fields that name a file: resolved against the driver's folder before a task leaves.
PATH_FIELDS = frozenset(
    {
        "policy",
        "recording",
        "initial_policy",
        "learned_output_weights",
        "closed_loop_dataset",
        "open_loop_dataset",
    }
)


def with_absolute_paths(value):
    """`value` with every `Path`, and every non-empty `PATH_FIELDS` field of the configs in
    it (nested dataclasses, lists and tuples included), made absolute; unchanged objects
    are returned as they are."""
    if isinstance(value, Path):
        return value.resolve()
    if isinstance(value, list | tuple):
        items = [with_absolute_paths(v) for v in value]
        changed = any(a is not b for a, b in zip(items, value, strict=True))
        return type(value)(items) if changed else value
    if not dataclasses.is_dataclass(value) or isinstance(value, type):
        return value
    changes = {}
    for field in dataclasses.fields(value):
        current = getattr(value, field.name)
        if field.name in PATH_FIELDS and isinstance(current, str) and current:
            absolute = str(Path(current).resolve())
            if absolute != current:
                changes[field.name] = absolute
        else:
            new = with_absolute_paths(current)
            if new is not current:
                changes[field.name] = new
    return dataclasses.replace(value, **changes) if changes else value


def ray_address(address: str | None = None) -> str | None:
    """The cluster to run on: `address`, else RAY_ADDRESS, else None (a local Ray)."""
    return address or os.environ.get("RAY_ADDRESS") or None


def run_tasks(
    function: Callable,
    tasks: Sequence[tuple],
    *,
    workers: int = 1,
    address: str | None = None,
    total: int | None = None,
    description: str = "tasks",
    unit: str = "task",
    progress: bool = True,
) -> None:
    """Calls `function(*task)` for every task, with a progress bar over tasks.

    Args:
        function: a module-level function (Ray ships it by reference), which writes its own
            result.
        tasks: the argument tuples of the unfinished tasks.
        workers: CPUs of the local Ray (1 with no `address`: run here, serially).
        address: a Ray cluster to run on ("auto", "ray://host:10001", ...); default
            RAY_ADDRESS, else a local Ray with `workers` CPUs.
        total: the study's size, finished tasks included (the bar starts at
            total - len(tasks)); default len(tasks).

    Raises:
        ValueError: workers below 1.
        RuntimeError: a task failed; the message is the task's error.
    """
    if workers < 1:
        raise ValueError(f"workers must be at least 1; got {workers}")
    address = ray_address(address)
    total = len(tasks) if total is None else total
    bar = tqdm(
        total=total, initial=total - len(tasks), desc=description, unit=unit, disable=not progress
    )
    with bar:
        if workers == 1 and address is None:
            for task in tasks:
                function(*task)
                bar.update(1)
        elif tasks:
            tasks = [tuple(with_absolute_paths(arg) for arg in task) for task in tasks]
            _run_on_ray(function, tasks, workers, address, bar)


@contextlib.contextmanager
def ray_session(workers: int, address: str | None = None):
    """Connects to Ray for the block: a cluster at `address`, or a local Ray with `workers`
    CPUs (started here and shut down at the end); an already connected Ray is reused."""
    # ray (heavy: about a second to import) only for parallel runs
    import ray

    started = not ray.is_initialized()
    if started:
        if address is None:
            ray.init(
                num_cpus=workers,
                include_dashboard=False,
                log_to_driver=False,
                configure_logging=False,
            )
        else:
            try:
                ray.init(address=address, log_to_driver=False, configure_logging=False)
            except ray.exceptions.AuthenticationError as err:
                raise RuntimeError(_token_hint(address, err)) from None
    try:
        yield ray
    finally:
        if started:
            ray.shutdown()


def _token_hint(address: str, err: Exception) -> str:
    """What to do when a cluster with token authentication refuses this process."""
    return (
        f"the Ray cluster at {address} refused the connection: it uses token "
        "authentication (RAY_AUTH_MODE=token) and this process has not got its token. On the "
        "head node, `ray get-auth-token` prints it; give it here as RAY_AUTH_TOKEN=<token> "
        "(or RAY_AUTH_TOKEN_PATH=<file>) with RAY_AUTH_MODE=token, then run again "
        f"(docs/guides/ray.md). Ray said: {' '.join(str(err).split())[:200]}"
    )


def _run_on_ray(function: Callable, tasks: Sequence[tuple], workers: int, address, bar) -> None:
    with ray_session(workers, address) as ray:
        remote = ray.remote(num_cpus=1, max_retries=0)(_call)
        pending = [remote.remote(function, task) for task in tasks]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            try:
                ray.get(done[0])
            except ray.exceptions.RayTaskError as err:
                for ref in pending:
                    ray.cancel(ref, force=True)
                name = getattr(function, "__name__", "study")
                raise RuntimeError(f"a {name} task failed: {err.cause}") from err
            bar.update(1)


def _call(function: Callable, task: tuple):
    """The Ray task: `function(*task)`; the function travels by reference (any picklable
    callable, builtins included)."""
    return function(*task)
