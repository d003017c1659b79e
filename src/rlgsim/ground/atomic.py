"""Files written whole or not at all: a temporary file beside the target, renamed onto it when
the write ends normally and deleted when it does not (a full disk, an interrupt), so a reader
never sees a half-written file at the target's path and a failed write leaves nothing behind.

The temporary file is ``.<name>.tmp<sep><pid>`` in the target's folder (the same file system, so
the rename is atomic); the separator is the caller's, because the Monte Carlo runner and the
recordings clean up stale temporaries by name (``write_atomic``: none, sidecars and tables:
``-``).
"""

from __future__ import annotations

import contextlib
import os
import pathlib
from typing import Iterator


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike, sep: str = "-") -> Iterator[pathlib.Path]:
    """Yield the temporary path to write ``path`` through; on leaving the block normally it is
    renamed onto ``path``, otherwise deleted. An ``OSError`` raised inside that names no file
    (a write's) or the temporary file (its ``open``) is made to name ``path``, the file the user
    asked for; one naming another file (an input read inside the block) keeps it."""
    target = pathlib.Path(path)
    tmp = target.with_name(f".{target.name}.tmp{sep}{os.getpid()}")
    try:
        yield tmp
        os.replace(tmp, target)
    except OSError as exc:
        if exc.filename is None or os.fsdecode(exc.filename) == str(tmp):
            exc.filename = str(target)       # an input's error inside the block keeps its name
        raise
    finally:
        tmp.unlink(missing_ok=True)
