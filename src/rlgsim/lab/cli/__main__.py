"""``python -m rlgsim.lab.cli ...`` is the ``rlgsim`` command."""

import sys

from rlgsim.lab.cli.main import main

sys.exit(main())
