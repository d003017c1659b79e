"""Processes in the kill -9 and orphan tests: which are still alive, and waiting for them to go."""

from __future__ import annotations

import time

import psutil


def alive(procs: list[psutil.Process]) -> list[psutil.Process]:
    """The processes of ``procs`` still running (zombies count as gone)."""
    out = []
    for p in procs:
        try:
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
        except psutil.NoSuchProcess:
            pass
    return out


def wait_gone(procs: list[psutil.Process], timeout_s: float = 15.0) -> list[psutil.Process]:
    """The processes of ``procs`` still alive after ``timeout_s`` (killed, for cleanliness)."""
    deadline = time.monotonic() + timeout_s
    left = alive(procs)
    while left and time.monotonic() < deadline:
        time.sleep(0.1)
        left = alive(procs)
    for p in left:
        try:
            p.kill()
        except psutil.NoSuchProcess:
            pass
    return left
