"""The files ``rlgsim identify`` writes, checked before any fitting and again before writing
(:mod:`rlgsim.ground.paths`, the checks every command shares): ``thermal.toml``,
``device.toml``, ``<name>_replay.toml``, ``report.md`` and ``report.html`` in the output
folder. None may be an input (the recording, its sidecar, a template file: a recording's
sidecar is often ``device.toml``-like and sits in the same folder), a link or a special file;
an existing file that an earlier identification did not write is replaced only with
``overwrite``. The twin's ``name`` becomes a file name, so it must stay in the folder.
"""

from __future__ import annotations

import os
import pathlib

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.paths import (MAX_NAME, check_writable, output_files, output_folder)

__all__ = ["check_name", "make_folder", "planned_outputs", "MARKERS"]

#: Text near the top of each file an identification writes (how an earlier one is known).
MARKERS = {"thermal": "identified by rlgsim identify", "device": "identified by rlgsim identify",
           "replay": "Replays the recorded chamber air", "report_md": "Digital twin of",
           "report_html": "Digital twin of", "next": "rlgsim identify --suggest-programme"}


def check_name(name: str) -> str:
    """The twin's name: it names ``<name>_replay.toml``, so no path separator, ``.``/``..``,
    NUL or over-long name."""
    suffix = "_replay.toml"
    if (not name or name in (".", "..") or "/" in name or os.sep in name
            or (os.altsep and os.altsep in name) or "\0" in name):
        raise UserInputError(f"--name: value {name!r} not allowed; the twin's name becomes the "
                             f"file <name>{suffix} in the output folder (no '/', '.' or '..')")
    if len((name + suffix).encode("utf-8", "surrogateescape")) > MAX_NAME:
        raise UserInputError(f"--name: value {name[:40]!r}... is {len(name)} characters; at "
                             f"most {MAX_NAME - len(suffix)}")
    return name


def make_folder(out_dir: str | os.PathLike) -> pathlib.Path:
    """The output folder (``~`` expanded), created with its parents; one line naming it when it
    cannot be."""
    out = pathlib.Path(out_dir).expanduser()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserInputError(f"{out}: cannot create the output folder ({exc.strerror or exc})"
                             ) from None
    return out


def _own(role: str, path: pathlib.Path) -> bool:
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096).decode("utf-8", "replace")
    except OSError:
        return False
    return MARKERS[role] in head


def planned_outputs(out_dir: str | os.PathLike, name: str, inputs: list, *,
                    overwrite: bool = False, next_file: bool = False
                    ) -> dict[str, pathlib.Path]:
    """The checked output paths by role (``next``: ``<name>_next.toml`` of
    ``--suggest-programme``, when ``next_file``); a folder that does not exist yet is checked
    to be creatable (its nearest existing parent writable) and its files are not checked
    further."""
    out = output_folder(out_dir, inputs=inputs)
    files = {"thermal": out / "thermal.toml", "device": out / "device.toml",
             "replay": out / f"{check_name(name)}_replay.toml",
             "report_md": out / "report.md", "report_html": out / "report.html"}
    if next_file:
        files["next"] = out / f"{name}_next.toml"
    if not out.is_dir():
        parent = out.parent
        while not parent.is_dir() and parent != parent.parent:
            parent = parent.parent
        check_writable(parent / out.name)
        return files
    return output_files(files, inputs=inputs, overwrite=overwrite, own=_own)
