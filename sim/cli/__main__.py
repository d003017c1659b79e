"""``python -m rlgsim.sim.cli ...`` is the ``rlgsim`` command."""

import sys

from rlgsim.sim.cli.main import main

sys.exit(main())
