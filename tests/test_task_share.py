"""rlgsim.lab.studies.task_share: a study report's independent tasks shared with one worker
process give the serial run's results, in order, byte for byte; a task's error is raised; no
nested pool inside a worker."""

from __future__ import annotations

import concurrent.futures as cf
import os

import numpy as np
import pytest

from rlgsim.lab.studies.task_share import TaskShare

TWO_CORES = len(os.sched_getaffinity(0)) >= 2 if hasattr(os, "sched_getaffinity") else False


def _solve(seed: int, n: int) -> tuple[int, bytes]:
    """A least-squares solve (BLAS/LAPACK sums) of seeded data: its result's bytes and pid."""
    rng = np.random.default_rng(seed)
    a, b = rng.standard_normal((n, 8)), rng.standard_normal(n)
    return os.getpid(), np.linalg.lstsq(a, b, rcond=None)[0].tobytes()


def _fails(seed: int, n: int) -> None:
    if seed == 3:
        raise ValueError(f"task {seed} failed")


def _nested(seed: int) -> bool:
    """Inside a worker process: a TaskShare makes no pool of its own."""
    share = TaskShare(_solve, [(seed, 50), (seed + 1, 50)])
    return share.pool is None and len(share.results()) == 2


def test_shared_tasks_give_the_serial_results_in_order():
    tasks = [(seed, 400) for seed in range(6)]
    serial = [_solve(*t)[1] for t in tasks]
    share = TaskShare(_solve, tasks)
    out = share.results()
    assert [b for _, b in out] == serial
    assert share.pool is None                                   # closed
    assert len({pid for pid, _ in out} - {os.getpid()}) <= int(TWO_CORES)   # one worker at most


def test_a_tasks_error_is_raised_and_the_worker_closed():
    share = TaskShare(_fails, [(seed, 1) for seed in range(6)])
    with pytest.raises(ValueError, match="task 3 failed"):
        share.results()
    assert share.pool is None


def test_no_nested_pool_in_a_worker_process():
    with cf.ProcessPoolExecutor(1) as pool:
        assert pool.submit(_nested, 1).result()


def test_fit_all_shared_gives_the_sequential_fits():
    """Paper 001's grouping: IR-LSSVMs of one input set share their tuning in one task; every
    prediction equals the sequential fit_all's, byte for byte, in spec order."""
    from rlgsim.estimators.columns import Columns
    from rlgsim.lab.studies.fitting import fit_all
    from rlgsim.lab.studies.compensators import CompensatorSpec
    from rlgsim.sim.config import Ctx

    rng = np.random.default_rng(7)
    X = Columns({"T": rng.uniform(-10, 40, 60), "U": rng.normal(0, 1, 60)})
    y = 0.01 * X["T"] + 0.1 * np.sin(X["U"]) + rng.normal(0, 0.02, 60)

    def spec(name, kind, inputs, **params):
        return CompensatorSpec(name, kind, inputs, params, "", {}, Ctx("t.toml", "c"))
    ir = dict(tune_cv=3, rescale=False, max_iter=1, cv=3, gammas=[1.0, 100.0],
              sigma2s=[0.5, 2.0])
    specs = [spec("ir huber T", "ir_lssvm", ("T",), weight="huber", **ir),
             spec("poly U", "polynomial", ("U",), degree=2),
             spec("ir huber T,U", "ir_lssvm", ("T", "U"), weight="huber", **ir),
             spec("ir hampel T", "ir_lssvm", ("T",), weight="hampel", **ir)]
    seq = fit_all(specs, X, y, 5, progress=False)
    shared = fit_all(specs, X, y, 5, progress=False, share=True)
    assert [f.spec for f in shared] == specs and all(a.spec is b for a, b in zip(shared, specs))
    for a, b in zip(seq, shared):
        Xi = X.select(a.spec.inputs)
        assert a.hyper == b.hyper
        assert a.model.predict(Xi).tobytes() == b.model.predict(Xi).tobytes()
