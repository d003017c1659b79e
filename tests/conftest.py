"""Test-suite settings.

Property tests (hypothesis) explore new random examples on every developer run; under CI
(``CI`` set, as ``.ci/run`` is run) they draw a fixed, derandomised set instead, so a landing
never depends on the luck of the draw. A failure found locally is kept in ``.hypothesis/`` and
replayed until fixed.

BLAS and OpenMP run one thread in the test process and the processes it starts (set here,
before numpy is first imported; a test that needs more raises the limit itself, as
``test_blas_limit.py`` does). The tests' matrices are small (a few hundred rows): a second
thread gains little on them, and on a shared 2-core machine — the simulator's own prefetch and
writer threads, worker processes, other people's jobs — each call waits for its second thread
to be scheduled: the step-scan tests of ``test_identify_hops.py`` took 200 s at load 12 with
two threads and 19 s with one (10x the CPU: a waiting OpenBLAS thread spins). The simulator,
the identification and Monte Carlo workers limit BLAS to one thread themselves already.
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


#: Test modules run on one xdist worker, one after the other, as if they were one module
#: (``--dist loadscope`` otherwise hands out whole modules, each to whichever worker is free).
#: Their first test compiles the same large numba kernels (the vehicle trajectory's: about 8 s
#: of CPU on a cold cache, the suite's costliest compile); on two workers at once each compiled
#: them, where the second now loads the first one's cache.
SHARED_COMPILE_MODULES = ("tests/test_trajectory.py", "tests/test_trajectory_runs.py",
                          "tests/test_fuzz_vehicle_scenarios.py")


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadscope`` with :data:`SHARED_COMPILE_MODULES` in one scope; any other
    ``--dist`` is xdist's own."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class _Scheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split("::", 1)[0]
            if module in SHARED_COMPILE_MODULES:
                return SHARED_COMPILE_MODULES[0]
            return super()._split_scope(nodeid)

    return _Scheduling(config, log)
