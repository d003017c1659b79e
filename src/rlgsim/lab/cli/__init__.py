"""The ``rlgsim`` command line: :mod:`.main` parses and dispatches, one module per subcommand
(:mod:`.calibrate`, :mod:`.study`, :mod:`.montecarlo`). Subcommand modules never import
:mod:`.main`."""

from rlgsim.lab.cli.main import format_error, main

__all__ = ["main", "format_error"]
