"""``python -m rlgsim ...`` is the ``rlgsim`` command."""

import sys

from rlgsim.sim.cli import main

sys.exit(main())
