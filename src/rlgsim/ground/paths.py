"""Checks of every command's input and output paths, made before any work (and by the API
functions that write files, so ``rlgsim.export`` and ``rlgsim.identify`` refuse what the
commands refuse).

Inputs (``rlgsim info FILE``, ``rlgsim calibrate DATASET``, a recording's table and its
sidecar) must be regular files: a FIFO would hang the reader, ``/dev/zero`` never ends, a
directory is no dataset. Outputs:

* an existing output *file* must be a regular file: ``-o /dev/null`` (or any device, FIFO,
  socket, directory) is refused, never replaced;
* a *symbolic link* as an output file is refused (saying so): the dataset is written to a
  temporary file and renamed, which would replace the link itself, so give the link's target;
  output *folders* (``rlgsim study -o``, ``rlgsim montecarlo -o``) may be symlinks to folders
  and are written through;
* an output equal to one of the command's inputs (``rlgsim run my.toml -o my.toml``) is refused;
* a default output name derived from a scenario's or study's ``name`` (``./<name>.h5``,
  ``./<name>-study/``, ``./montecarlo-<name>/``) must stay in the working folder: a name with a
  path separator, ``.``/``..`` or more than :data:`MAX_NAME` characters is refused (give ``-o``);
* a name too long for the file system is one line, not an ``OSError``;
* the files a command writes *beside* its output (a recording's sidecar and programme, a twin's
  presets and replay scenario) get the same checks as the output, through
  :func:`output_files`: none may be an input (a recording's own sidecar is one), a link or a
  special file, and an existing file the command did not write itself is replaced only when
  asked (``--overwrite``); the folder must be writable (``/sys``, ``/proc`` are one line);
* temporary files (``.<name>.tmp-<pid>``, ``.<name>.tmp<pid>``, ``<name>.tmp-<pid>``) that a
  killed process left beside an output are removed (:func:`sweep_temporaries`); a live
  process's are kept.

Every refusal is a one-line :class:`~rlgsim.ground.errors.UserInputError`.
"""

from __future__ import annotations

import errno
import os
import pathlib
import re
import stat
from typing import Callable, Iterable, Mapping

from rlgsim.ground.errors import UserInputError

__all__ = ["MAX_NAME", "file_kind", "input_file", "output_file", "output_folder", "output_files",
           "name_path", "check_writable", "sweep_temporaries"]

#: Longest file name component written [characters] (file systems allow 255 bytes; the
#: temporary file adds ``.tmp-<pid>``).
MAX_NAME = 200


_KINDS_OF_FILE = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                  (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                  (stat.S_ISSOCK, "a socket"))


def file_kind(mode: int) -> str:
    """What a non-regular file is, in words (for messages)."""
    for test, words in _KINDS_OF_FILE:
        if test(mode):
            return words
    return "not a regular file"


_kind = file_kind


def _os_error(path: pathlib.Path | str, exc: OSError, doing: str) -> UserInputError:
    if exc.errno == errno.ENAMETOOLONG:
        return UserInputError(f"{str(path)[:80]}...: file name too long ({len(str(path))} "
                              f"characters); use a shorter name")
    return UserInputError(f"{path}: cannot {doing} ({exc.strerror or exc})")


def _check_length(path: pathlib.Path) -> None:
    for part in path.parts:
        if len(part.encode("utf-8", "surrogateescape")) > MAX_NAME:
            raise UserInputError(f"{str(path)[:80]}...: file name too long ({len(part)} "
                                 f"characters in one name; at most {MAX_NAME}); use a shorter "
                                 f"name")


def input_file(path: str | os.PathLike, what: str = "an rlgsim dataset", *,
               missing: str = "no such file") -> pathlib.Path:
    """A regular file to read; anything else is a one-line error naming it."""
    p = pathlib.Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise UserInputError(f"{p}: {missing}") from None
    except OSError as exc:
        raise _os_error(p, exc, "read it") from None
    except ValueError:                          # os.stat: "embedded null byte"
        raise UserInputError(f"{str(p)!r}: a file name cannot contain a NUL character; "
                             f"expected {what}") from None
    if stat.S_ISDIR(st.st_mode):
        raise UserInputError(f"{p}: is a directory, expected {what}")
    if not stat.S_ISREG(st.st_mode):
        raise UserInputError(f"{p}: is {_kind(st.st_mode)}, not a regular file; expected "
                             f"{what}")
    return p


def _same(a: pathlib.Path, b: str | os.PathLike) -> bool:
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        try:
            return a.resolve() == pathlib.Path(b).resolve()
        except (OSError, RuntimeError, ValueError):
            return False


def _output(path: str | os.PathLike, doing: str, *, follow: bool
            ) -> tuple[pathlib.Path, os.stat_result | None]:
    """An output path (``~`` expanded, length checked) and its status (``None``: it does not
    exist yet); ``follow``: through a symbolic link (``os.stat``) or of the link (``lstat``)."""
    p = pathlib.Path(path).expanduser()
    _check_length(p)
    try:
        return p, (os.stat(p) if follow else os.lstat(p))
    except FileNotFoundError:
        return p, None
    except OSError as exc:
        raise _os_error(p, exc, doing) from None


def output_file(path: str | os.PathLike, *, inputs: Iterable[str | os.PathLike] = (),
                option: str = "-o") -> pathlib.Path:
    """An output file that may be created or replaced: not a symlink, not a non-regular
    file, not one of ``inputs``, a name the file system takes."""
    p, st = _output(path, "write it", follow=False)
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise UserInputError(f"{p}: is a symbolic link; rlgsim does not replace links "
                                 f"(give its target {os.path.realpath(p)} with {option})")
        if stat.S_ISDIR(st.st_mode):
            raise UserInputError(f"{p}: output path is a directory; give a file name such as "
                                 f"{p / 'out.h5'}")
        if not stat.S_ISREG(st.st_mode):
            raise UserInputError(f"{p}: is {_kind(st.st_mode)}; an output must be a regular "
                                 f"file (it would be replaced), choose another {option}")
        _refuse_an_input(p, inputs, lambda source: f" ({source}); choose another {option}")
    return p


def output_folder(path: str | os.PathLike, *, inputs: Iterable[str | os.PathLike] = (),
                  option: str = "-o") -> pathlib.Path:
    """An output folder: created if missing, written through if a symlink to a folder; an
    existing non-folder, an input or an over-long name is refused."""
    p, st = _output(path, "use it as the output folder", follow=True)
    if st is None and os.path.islink(p):
        raise UserInputError(f"{p}: is a symbolic link to {os.readlink(p)}, which does not "
                             f"exist; create its target or choose another output folder with "
                             f"{option}")
    if st is not None and not stat.S_ISDIR(st.st_mode):
        what = "a regular file" if stat.S_ISREG(st.st_mode) else _kind(st.st_mode)
        raise UserInputError(f"{p}: is {what}, not a folder; choose another output folder "
                             f"with {option}")
    _refuse_an_input(p, inputs, lambda _: f"; choose another output folder with {option}")
    return p


def _refuse_an_input(p: pathlib.Path, inputs: Iterable[str | os.PathLike],
                     advice: Callable[[str | os.PathLike], str]) -> None:
    """Refuse an output ``p`` that is one of the command's ``inputs`` (the same file); the
    message ends with ``advice(that input)``."""
    for source in inputs:
        if source and _same(p, source):
            raise UserInputError(f"{p}: is also an input of this command{advice(source)}")


def name_path(name: str, *, prefix: str = "", suffix: str = "", source: str = "",
              key: str = "name") -> pathlib.Path:
    """The default output ``./<prefix><name><suffix>`` in the working folder; a ``name`` that
    would leave it (path separators, ``.``, ``..``) or is too long is refused (give -o)."""
    where = f"{source}: {key}" if source else key
    bad = (not name or name in (".", "..") or "/" in name or os.sep in name
           or (os.altsep and os.altsep in name) or "\0" in name)
    if bad:
        raise UserInputError(f"{where}: value {name!r} not allowed as the default output name "
                             f"(it must stay in the working folder: no '/', '.' or '..'); "
                             f"give the output with -o")
    if len(prefix + name + suffix) > MAX_NAME:
        raise UserInputError(f"{where}: value {name[:40]!r}... is {len(name)} characters, too "
                             f"long for the default output name (at most "
                             f"{MAX_NAME - len(prefix + suffix)}); give the output with -o")
    return pathlib.Path(f"{prefix}{name}{suffix}")


def check_writable(path: str | os.PathLike, option: str = "-o") -> pathlib.Path:
    """Check, before any work, that ``path`` can be written (its folder exists and takes a
    file: ``/sys``, ``/proc``, a read-only mount are one line); return it absolute."""
    out = pathlib.Path(path).expanduser()
    _check_length(out)
    if out.is_dir():
        raise UserInputError(f"{out}: output path is a directory; give a file name such as "
                             f"{out / 'run.h5'}")
    parent = out.parent if str(out.parent) else pathlib.Path(".")
    if not parent.is_dir():
        raise UserInputError(f"{out}: cannot write output: directory {parent} does not exist")
    probe = parent / f".{out.name[:MAX_NAME]}.probe-{os.getpid()}"
    try:
        with open(probe, "xb"):
            pass
    except OSError as exc:
        if exc.errno == errno.ENAMETOOLONG:
            raise _os_error(out, exc, "write it") from None
        raise UserInputError(f"{out}: cannot write output ({exc.strerror or exc}); "
                             f"choose a writable location with {option}") from None
    finally:
        try:
            probe.unlink()
        except OSError:
            pass
    return out.absolute()


def output_files(outputs: Mapping[str, str | os.PathLike], *,
                 inputs: Iterable[str | os.PathLike] = (), option: str = "-o",
                 overwrite: bool = False,
                 own: Callable[[str, pathlib.Path], bool] | None = None
                 ) -> dict[str, pathlib.Path]:
    """Check every file a command will write — ``outputs`` maps a role (``table``,
    ``sidecar``, ``programme``, ...) to its path — as :func:`output_file` does, and more: no
    two roles on one file; an existing file that ``own(role, path)`` does not recognise as
    this command's earlier output is refused unless ``overwrite``; the folder must be
    writable. Stale temporaries beside each are swept. Returns the checked paths by role."""
    inputs = [i for i in inputs if i]
    out: dict[str, pathlib.Path] = {}
    for role, path in outputs.items():
        p = output_file(path, inputs=inputs, option=option)
        for other, q in out.items():
            if _same(p, q) or p == q:
                raise UserInputError(f"{p}: would be both the {other} and the {role}; choose "
                                     f"another {option}")
        if os.path.lexists(p) and not overwrite and not (own is not None and own(role, p)):
            raise UserInputError(f"{p}: exists and was not written by this command (the "
                                 f"{role}); give --overwrite to replace it, or choose another "
                                 f"{option}")
        out[role] = p
    for p in out.values():
        check_writable(p, option)
        sweep_temporaries(p)
    return out


#: Temporary names beside an output ``NAME``: ``.NAME.tmp-PID`` (tables, sidecars,
#: programmes), ``.NAME.tmpPID`` (reports, presets) and ``NAME.tmp-PID`` (datasets).
def _temporary_pid(name: str, entry: str) -> int | None:
    m = (re.fullmatch(re.escape(f".{name}.tmp") + r"-?(\d+)", entry)
         or re.fullmatch(re.escape(f"{name}.tmp-") + r"(\d+)", entry))
    return int(m.group(1)) if m else None


def sweep_temporaries(path: str | os.PathLike) -> list[pathlib.Path]:
    """Delete the temporary files of ``path`` whose writing process no longer runs (killed
    with SIGKILL, a power cut); a live process's are kept. Returns the files removed."""
    from rlgsim.ground.lifeline import process_alive
    p = pathlib.Path(path)
    removed: list[pathlib.Path] = []
    try:
        entries = list(os.scandir(p.parent if str(p.parent) else "."))
    except OSError:
        return removed
    for e in entries:
        pid = _temporary_pid(p.name, e.name)
        if pid is None or pid == os.getpid() or process_alive(pid):
            continue
        try:
            if e.is_file(follow_symlinks=False):
                os.unlink(e.path)
                removed.append(pathlib.Path(e.path))
        except OSError:
            pass
    return removed
