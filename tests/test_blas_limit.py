"""The one-thread BLAS limit of a simulation (sim/thermal_integrator.one_blas_thread) is applied
when the first caller enters and restored when the last one leaves — nested or in another
thread, whichever thread leaves last — and a real limit takes BLAS to one thread."""

from __future__ import annotations

import threading

import pytest

import rlgsim.sim.thermal.integrator as ti
from rlgsim.sim.thermal.integrator import one_blas_thread


class _Recorder:
    """Stands in for threadpoolctl's limiter: records when it is applied and restored."""

    def __init__(self, log: list[str]) -> None:
        self.log = log
        log.append("apply")

    def restore_original_limits(self) -> None:
        self.log.append("restore")


def test_the_limit_lasts_until_the_last_user_leaves(monkeypatch):
    """Thread A enters first, B second; A leaves first: nothing is restored until B, inside a
    nested block meanwhile, leaves too."""
    log: list[str] = []
    monkeypatch.setattr(ti, "_blas_limit", lambda: _Recorder(log))
    a_in, a_out, b_in, b_may_leave = (threading.Event() for _ in range(4))
    seen: dict[str, list[str]] = {}

    def a() -> None:
        with one_blas_thread():
            a_in.set()
            b_in.wait()
        a_out.set()

    def b() -> None:
        a_in.wait()
        with one_blas_thread():
            b_in.set()
            a_out.wait()                 # A has left: B is still inside
            seen["b_after_a_left"] = list(log)
            with one_blas_thread():      # nested
                seen["nested"] = list(log)
            b_may_leave.wait()

    ta, tb = threading.Thread(target=a), threading.Thread(target=b)
    ta.start(), tb.start()
    ta.join()
    b_may_leave.set()
    tb.join()
    assert seen["b_after_a_left"] == ["apply"]
    assert seen["nested"] == ["apply"]
    assert log == ["apply", "restore"]
    assert ti._users == 0 and ti._limit is None


def test_the_limit_is_restored_after_an_error(monkeypatch):
    log: list[str] = []
    monkeypatch.setattr(ti, "_blas_limit", lambda: _Recorder(log))
    with pytest.raises(RuntimeError):
        with one_blas_thread():
            raise RuntimeError("a failing run")
    assert log == ["apply", "restore"] and ti._users == 0


def test_a_real_limit_takes_blas_to_one_thread():
    threadpoolctl = pytest.importorskip("threadpoolctl")

    def blas_threads() -> list[int]:
        return [p["num_threads"] for p in threadpoolctl.threadpool_info()
                if p.get("user_api") == "blas"]

    if not blas_threads():
        pytest.skip("no BLAS library seen by threadpoolctl")
    # the suite runs BLAS on one thread (conftest.py): two threads first, so that the limit
    # and its restoring can be told apart from that
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        start = blas_threads()
        if max(start) < 2:
            pytest.skip("BLAS does not start a second thread here")
        with one_blas_thread():
            assert blas_threads() == [1] * len(start)
        assert blas_threads() == start
