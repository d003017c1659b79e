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

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
