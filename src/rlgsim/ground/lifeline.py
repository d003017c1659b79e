"""Process pools whose workers never outlive the process that started them.

A :class:`concurrent.futures.ProcessPoolExecutor` worker blocks on its task queue; when the
coordinating process is killed (``kill -9``, the OOM killer, a lost terminal) nothing wakes it
up, so the workers, the forkserver and multiprocessing's resource tracker stay alive forever.
:func:`process_pool` gives every worker a lifeline instead:

* on Linux, ``prctl(PR_SET_PDEATHSIG, SIGKILL)``: the kernel kills the worker when its parent
  dies (the coordinator for the ``fork`` start method, the forkserver for ``forkserver``);
* a daemon thread in the worker polls ``os.getppid()`` once a second (portable fallback);
* for ``spawn``/``forkserver`` pools, whose workers are not the coordinator's children, a pipe
  whose write end only the coordinator holds: a daemon thread in the worker blocks on the read
  end and ends the worker at EOF — which the kernel delivers the moment the coordinator dies,
  however it dies.

Once the workers are gone, the forkserver and the resource tracker exit on their own (they
exit when no process holds their pipes any more). Used by the Monte Carlo campaigns and the
calibration campaign; both ``sim`` and ``estimators`` import it.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import sys
import threading
import time
from typing import Any

#: Exit status of a worker whose coordinator died.
ORPHAN_EXIT = 70

#: Both ends of the lifeline pipe of each pool made here (by ``id(pool)``).
_LIFELINES: dict[int, tuple[Any, Any]] = {}


def _set_parent_death_signal() -> None:
    """Linux: SIGKILL this process when its parent dies. Elsewhere a no-op."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes
        import signal
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)          # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):                        # pragma: no cover - no prctl
        pass


def _watch_pipe(lifeline) -> None:
    try:
        while True:
            lifeline.recv_bytes()                            # nothing is ever sent
    except (EOFError, OSError):
        pass
    os._exit(ORPHAN_EXIT)


def _poll_parent(parent: int) -> None:
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(ORPHAN_EXIT)


def worker_init(lifeline=None, expected_parent: int | None = None, initializer=None,
                initargs: tuple = ()) -> None:
    """Initializer of every worker of :func:`process_pool` (then the caller's own)."""
    _set_parent_death_signal()
    parent = os.getppid()
    if expected_parent is not None and parent != expected_parent:   # orphaned already
        os._exit(ORPHAN_EXIT)
    if lifeline is not None:
        threading.Thread(target=_watch_pipe, args=(lifeline,), daemon=True,
                         name="rlgsim-lifeline").start()
    threading.Thread(target=_poll_parent, args=(parent,), daemon=True,
                     name="rlgsim-parent-poll").start()
    if initializer is not None:
        initializer(*initargs)


def process_pool(max_workers: int | None = None, mp_context=None, initializer=None,
                 initargs: tuple = ()) -> cf.ProcessPoolExecutor:
    """A :class:`~concurrent.futures.ProcessPoolExecutor` whose workers exit when this process
    dies. Arguments as for the executor; call :func:`release` after ``shutdown`` (a ``with``
    block does not need it: the pipe is closed when this process exits anyway)."""
    ctx = mp_context or multiprocessing.get_context()
    reader = writer = expected = None
    if ctx.get_start_method() == "fork":
        expected = os.getpid()                 # the workers are this process's children
    else:
        reader, writer = ctx.Pipe(duplex=False)
    pool = cf.ProcessPoolExecutor(max_workers=max_workers, mp_context=ctx,
                                  initializer=worker_init,
                                  initargs=(reader, expected, initializer, tuple(initargs)))
    if writer is not None:
        _LIFELINES[id(pool)] = (reader, writer)
    return pool


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` exists and has not finished (a zombie has): used to tell the
    temporary files of a live run from those a killed run left behind."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:                                          # e.g. another user's process
        return True
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            return fh.read().rsplit(b")", 1)[-1].split()[0] != b"Z"
    except (OSError, IndexError):
        return True


def release(pool: cf.Executor) -> None:
    """Close the lifeline pipe of a pool made by :func:`process_pool` (after its shutdown)."""
    for conn in _LIFELINES.pop(id(pool), ()):
        conn.close()
