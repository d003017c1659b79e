"""``python -m rlgsim ...`` is the ``rlgsim`` command."""

import sys

from rlgsim.lab.cli import main

sys.exit(main())
