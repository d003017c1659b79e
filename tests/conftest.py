"""Test-suite settings.

Property tests (hypothesis) explore new random examples on every developer run; under CI
(``CI`` set, as ``.ci/run`` is run) they draw a fixed, derandomised set instead, so a landing
never depends on the luck of the draw. A failure found locally is kept in ``.hypothesis/`` and
replayed until fixed.
"""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
