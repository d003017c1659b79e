"""The public Python API (docs/api.md): a facade over :mod:`rlgsim.lab.api`, where it lives.

Nothing inside the package imports this module."""

from rlgsim.lab.api import *  # noqa: F401,F403
from rlgsim.lab.api import __all__  # noqa: F401
