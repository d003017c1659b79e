"""Independent tasks of a study report shared between this process and one worker process.

A study's report does some work of its own (tables, figures) and some independent heavy tasks
(paper 002: one navigation run per environment). :class:`TaskShare` hands the tasks, in order, to
one worker process as soon as it is made, one at a time (a thread here waits on each); this
process goes on with its own work and, when it needs the results (:meth:`TaskShare.results`),
takes the tasks the worker has not started from the back of the list, so both cores work until
the last task ends. Every task runs exactly as it
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
tasks not yet started.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import threading
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
        self._lock = threading.Lock()
        self._front, self._back = 0, len(self.tasks)   # tasks [front, back) not yet taken
        self._worker_out: dict[int, Any] = {}
        self._error: BaseException | None = None
        self._feeder: threading.Thread | None = None
        if (len(self.tasks) >= (1 if background else 2) and _cores() >= 2
                and multiprocessing.parent_process() is None):
            from rlgsim.ground.lifeline import process_pool
            self.pool = process_pool(1)
            counts = _thread_counts()
            i = self._take(front=True)              # the first submit forks the worker: here,
            first = self.pool.submit(_as_caller, fn, self.tasks[i], counts)   # not in a thread
            self._feeder = threading.Thread(target=self._feed,
                                            args=(self.pool, counts, i, first),
                                            name="rlgsim-task-share", daemon=True)
            self._feeder.start()

    def _take(self, front: bool) -> int | None:
        """The next task not yet taken, from the front (the worker) or the back (here)."""
        with self._lock:
            if self._front >= self._back:
                return None
            if front:
                self._front += 1
                return self._front - 1
            self._back -= 1
            return self._back

    def _feed(self, pool: cf.ProcessPoolExecutor, counts: dict[str, int], i: int | None,
              fut: cf.Future) -> None:
        """The worker's side (a thread of this process that only waits): one task at a time
        from the front (``i``, ``fut``: the first, submitted by ``__init__``), so the worker
        never holds a task this process could have taken."""
        while True:
            try:
                self._worker_out[i] = fut.result()
            except BaseException as exc:          # noqa: BLE001 — raised by results()
                self._error = exc
                return
            i = self._take(front=True)
            if i is None:
                return
            fut = pool.submit(_as_caller, self.fn, self.tasks[i], counts)

    def results(self, landed: Callable[[int, Any], None] | None = None) -> list[Any]:
        """Every task's result, in task order; a task's exception is raised here.
        ``landed(i, result)``, if given, is called in this process as it finishes each of its
        own tasks, and for the worker's tasks once all are done (e.g. a progress bar)."""
        def got(i: int, value: Any) -> Any:
            if landed is not None:
                landed(i, value)
            return value
        if self.pool is None:
            return [got(i, self.fn(*t)) for i, t in enumerate(self.tasks)]
        try:
            out: list[Any] = [None] * len(self.tasks)
            while self._error is None and (i := self._take(front=False)) is not None:
                out[i] = got(i, self.fn(*self.tasks[i]))     # from the back, one at a time
            self._feeder.join()
            if self._error is not None:
                raise self._error
            for i, value in self._worker_out.items():
                out[i] = got(i, value)
            return out
        finally:
            self.close()

    def close(self) -> None:
        """Stop handing out tasks and shut the worker down (after the task it is running);
        idempotent."""
        if self.pool is not None:
            from rlgsim.ground.lifeline import release
            with self._lock:
                self._back = self._front                     # nothing more to take
            self._feeder.join()
            self.pool.shutdown(wait=True, cancel_futures=True)
            release(self.pool)
            self.pool = None
