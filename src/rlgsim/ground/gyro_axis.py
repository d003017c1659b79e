"""Which gyro of a dataset or recording a caller means: the one it names, else the only one.

The callers (the public API's window tables, a study's recording runs) word their one-line
errors differently — one names a keyword, the other a study-file key and the recording — so
the messages are their templates, filled here.
"""

from __future__ import annotations

from typing import Any, Sequence

from rlgsim.ground.errors import UserInputError

__all__ = ["choose_gyro"]


def choose_gyro(axes: Sequence[str], gyro: str | None, *, unknown: str, several: str,
                **fields: Any) -> str:
    """``gyro`` if it is one of ``axes``, or the only axis when ``gyro`` is ``None``; otherwise
    a :class:`UserInputError` with the message ``unknown`` (``gyro`` not among ``axes``) or
    ``several`` (no ``gyro`` and not exactly one axis). The messages are :meth:`str.format`
    templates with the fields ``{gyro}``, ``{axes}`` (comma-separated, ``none`` if empty),
    ``{n}`` (number of axes) and ``fields``."""
    said = dict(fields, gyro=gyro, axes=", ".join(axes) or "none", n=len(axes))
    if gyro is not None:
        if gyro not in axes:
            raise UserInputError(unknown.format(**said))
        return gyro
    if len(axes) != 1:
        raise UserInputError(several.format(**said))
    return axes[0]
