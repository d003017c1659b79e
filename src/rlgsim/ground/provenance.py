"""Which software made a dataset or a report: the versions of rlgsim and of the libraries
whose arithmetic reaches the stored numbers (numpy, scipy, h5py, numba), so a dataset can be
remade bit for bit with the same set (the lock file in the repository pins them all).

Read from the installed distributions' metadata (:mod:`importlib.metadata`): nothing is
imported, and a library that is not installed reads ``"not installed"``.
"""

from __future__ import annotations

import json
from importlib.metadata import PackageNotFoundError, version

__all__ = ["PROVENANCE_PACKAGES", "software_versions", "versions_json", "versions_line"]

#: The distributions whose versions every dataset and report records, in this order.
PROVENANCE_PACKAGES = ("rlgsim", "numpy", "scipy", "h5py", "numba")


def software_versions() -> dict[str, str]:
    """``{distribution: version}`` for :data:`PROVENANCE_PACKAGES` (rlgsim run from an
    uninstalled tree: ``0+unknown``)."""
    out = {}
    for name in PROVENANCE_PACKAGES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "0+unknown" if name == "rlgsim" else "not installed"
    return out


def versions_json() -> str:
    """:func:`software_versions` as compact JSON (the dataset attribute ``software_versions``)."""
    return json.dumps(software_versions(), separators=(",", ":"))


def versions_line() -> str:
    """One human line: ``rlgsim 0.1.0, numpy 2.3.4, scipy 1.16.2, h5py 3.15.1, numba 0.62.1``."""
    return ", ".join(f"{k} {v}" for k, v in software_versions().items())
