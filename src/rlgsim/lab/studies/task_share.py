"""Independent tasks of a study report shared between this process and one worker process.

A study's report does some work of its own (tables, figures) and some independent heavy tasks
(paper 002: one navigation run per environment). :class:`TaskShare` hands the tasks, in order, to
one worker process as soon as it is made; this process goes on with its own work and, when it
needs the results (:meth:`TaskShare.results`), takes the tasks the worker has not started from
the back of the list, so both cores work until the last task ends. Every task runs exactly as it
would in this process (the same function and arguments, and this process's BLAS and OpenMP
thread counts: another count could change a sum's last bit), so the results are the same bytes
whichever process ran a task — and the same as the serial run.

No worker is made (everything runs here, in order) inside a worker process (a Monte Carlo unit:
no nested pools), on one core, or for fewer than two tasks (one, unless the caller works
meanwhile: ``background``). The pool is
:func:`rlgsim.ground.lifeline.process_pool` with the platform's default start method (``fork``
on Linux, as paper 000's parallel fits use: the worker starts in milliseconds with every module
already imported, where a ``forkserver`` worker spends seconds importing them again and
re-runs an unguarded ``__main__`` script); its worker never outlives this process.

Written here rather than with joblib: joblib's ``Parallel`` hands out all tasks to its workers;
what is wanted is this process working on something else meanwhile and then taking over the
tasks not yet started — a future's ``cancel`` does exactly that.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
from typing import Any, Callable, Sequence


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count()
                                                                                  or 1)


def _thread_counts() -> dict[str, int]:
    """This process's BLAS and OpenMP thread counts (threadpoolctl's user APIs)."""
    from threadpoolctl import threadpool_info
    counts: dict[str, int] = {}
    for pool in threadpool_info():
        api = pool["user_api"]
        counts[api] = min(counts.get(api, pool["num_threads"]), pool["num_threads"])
    return counts


def _as_caller(fn: Callable, args: tuple, counts: dict[str, int]) -> Any:
    """``fn(*args)`` with the caller's BLAS/OpenMP thread counts (the worker's side)."""
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=counts or None):
        return fn(*args)


class TaskShare:
    """``fn(*args)`` for every ``args`` of ``tasks``, shared with one worker process (module
    docstring). ``fn`` must be a module-level function and the arguments picklable.
    ``background``: the caller does work of its own before :meth:`results`, so a single task
    goes to the worker too (otherwise one task runs here, when its results are asked for)."""

    def __init__(self, fn: Callable, tasks: Sequence[tuple], *, background: bool = False
                 ) -> None:
        self.fn = fn
        self.tasks = [tuple(t) for t in tasks]
        self.pool: cf.ProcessPoolExecutor | None = None
        self.futures: list[cf.Future] = []
        if (len(self.tasks) >= (1 if background else 2) and _cores() >= 2
                and multiprocessing.parent_process() is None):
            from rlgsim.ground.lifeline import process_pool
            self.pool = process_pool(1)
            counts = _thread_counts()
            self.futures = [self.pool.submit(_as_caller, fn, t, counts) for t in self.tasks]

    def results(self, landed: Callable[[int, Any], None] | None = None) -> list[Any]:
        """Every task's result, in task order; a task's exception is raised here.
        ``landed(i, result)``, if given, is called in this process as each result arrives
        (e.g. a progress bar), in no particular order."""
        def got(i: int, value: Any) -> Any:
            if landed is not None:
                landed(i, value)
            return value
        if self.pool is None:
            return [got(i, self.fn(*t)) for i, t in enumerate(self.tasks)]
        try:
            out: list[Any] = [None] * len(self.tasks)
            last = len(self.tasks)            # this process takes tasks from the back, one
            while last > 0 and self.futures[last - 1].cancel():  # at a time, while the worker
                last -= 1                                        # has not started them
                out[last] = got(last, self.fn(*self.tasks[last]))
            for i in range(last):
                out[i] = got(i, self.futures[i].result())
            return out
        finally:
            self.close()

    def close(self) -> None:
        """Shut the worker down (cancelling what it has not started); idempotent."""
        if self.pool is not None:
            from rlgsim.ground.lifeline import release
            self.pool.shutdown(wait=True, cancel_futures=True)
            release(self.pool)
            self.pool = None
