"""Find and read the TOML files rlgsim ships: scenarios, device presets, thermal presets.

Shipped files live in the installed ``scenarios`` package (found with
:mod:`importlib.resources`, so they work from a wheel as well as from a source tree)::

    scenarios/<name>.toml            a scenario   (kind "scenario")
    scenarios/devices/<name>.toml    a device     (kind "device")
    scenarios/thermal/<name>.toml    a thermal network preset (kind "thermal")

Anything that looks like a path (contains a path separator or ends in ``.toml``) is read from
disk instead; a relative path is tried against ``base_dir`` (the directory of the file that
refers to it) first and the working directory second.

Every problem — unknown name, missing or unreadable file, TOML syntax error — is raised as a
one-line :class:`~rlgsim.ground.errors.UserInputError` naming the file (and line for syntax errors).
Parsing uses the standard library's :mod:`tomllib`.
"""

from __future__ import annotations

import difflib
import os
import pathlib
import re
import stat
import tomllib
from dataclasses import dataclass
from importlib import resources
from typing import Any

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.paths import file_kind

#: Sub-folder of the ``scenarios`` package for each kind of file ("" = the package itself).
KINDS: dict[str, str] = {"scenario": "", "device": "devices", "thermal": "thermal",
                        "study": "studies"}

_NAME_RE = re.compile(r"^[A-Za-z0-9_.-]+$")


@dataclass(frozen=True)
class TomlFile:
    """One parsed TOML file: its ``name`` (stem), ``source`` (path for messages), the
    directory relative references are resolved against, the raw ``text`` and the ``data``."""

    name: str
    source: str
    base_dir: pathlib.Path | None
    text: str
    data: dict


def _package_dir(kind: str):
    if kind not in KINDS:
        raise ValueError(f"unknown preset kind {kind!r}; known: {', '.join(KINDS)}")
    root = resources.files("rlgsim.scenarios")
    return root.joinpath(KINDS[kind]) if KINDS[kind] else root


def list_names(kind: str) -> list[str]:
    """Names of the shipped files of one kind, sorted."""
    folder = _package_dir(kind)
    try:
        entries = list(folder.iterdir())
    except (FileNotFoundError, NotADirectoryError):
        return []
    return sorted(e.name[:-5] for e in entries if e.name.endswith(".toml") and e.is_file())


def looks_like_path(ref: str) -> bool:
    """A reference is a path if it has a directory separator or a ``.toml`` suffix."""
    return ref.endswith(".toml") or "/" in ref or os.sep in ref


#: Largest TOML file read [bytes]; scenario, preset and study files are a few kB.
MAX_TEXT_BYTES = 8 << 20
#: Deepest nesting of tables and arrays accepted (the shipped files use 4).
MAX_DEPTH = 64


def _depth(data) -> int:
    """Nesting depth of dicts and lists (iterative: no recursion on hostile input)."""
    deepest, stack = 0, [(data, 1)]
    while stack:
        value, level = stack.pop()
        if isinstance(value, dict):
            children = value.values()
        elif isinstance(value, list):
            children = value
        else:
            continue
        deepest = max(deepest, level)
        if deepest > MAX_DEPTH:
            break
        stack.extend((c, level + 1) for c in children if isinstance(c, (dict, list)))
    return deepest


#: Texts up to this many characters are kept parsed (:func:`parse_toml`), the latest
#: :data:`_PARSED_MAX` of them: a Monte Carlo run, a study or a benchmark reads the same device
#: and thermal presets for every run, and parsing them took ~2.5 ms of each (a 1 h run at
#: 100 Hz takes ~0.1 s). The shipped presets hold ~2–20 kB.
_PARSED_MAX_CHARS = 1 << 18
_PARSED_MAX = 64
_PARSED: dict[str, dict] = {}


def _copy(value: Any) -> Any:
    """A copy of parsed TOML whose tables and arrays are new (the values in them — numbers,
    strings, booleans, dates — are immutable); nesting is bounded by :data:`MAX_DEPTH`."""
    if type(value) is dict:
        return {k: _copy(v) for k, v in value.items()}
    if type(value) is list:
        return [_copy(v) for v in value]
    return value


def parse_toml(text: str, source: str) -> dict:
    """Parse TOML text; a syntax error becomes ``source: line L, column C: TOML syntax error``.
    A leading UTF-8 byte-order mark is accepted; tables or arrays nested deeper than
    :data:`MAX_DEPTH` are refused. The same text parsed again (:data:`_PARSED_MAX_CHARS`) is
    a copy of the first parse's tables (the caller may change its own)."""
    text = text.removeprefix("\ufeff")
    kept = _PARSED.get(text)
    if kept is not None:
        return _copy(kept)
    data = _parse_toml(text, source)
    if len(text) <= _PARSED_MAX_CHARS:
        if len(_PARSED) >= _PARSED_MAX:
            _PARSED.pop(next(iter(_PARSED)), None)     # the oldest
        _PARSED[text] = _copy(data)
    return data


def _parse_toml(text: str, source: str) -> dict:
    """:func:`parse_toml` without the kept texts."""
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise UserInputError(f"{source}: tables or arrays nested too deeply (at most "
                             f"{MAX_DEPTH} levels allowed)") from None
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        match = re.search(r"\s*\(at line (\d+), column (\d+)\)\s*$", message)
        if match:
            where = f"line {match.group(1)}, column {match.group(2)}"
            message = message[:match.start()]
        elif message.endswith("(at end of document)"):
            where = f"line {text.count(chr(10)) + 1} (end of file)"
            message = message[:-len("(at end of document)")].rstrip()
        else:
            where = "somewhere"
        message = " ".join(message.split())
        raise UserInputError(f"{source}: {where}: TOML syntax error: {message}") from None
    if _depth(data) > MAX_DEPTH:
        raise UserInputError(f"{source}: tables or arrays nested too deeply (at most "
                             f"{MAX_DEPTH} levels allowed)")
    return data


def read_regular(path: pathlib.Path, source: str, *, max_bytes: int = MAX_TEXT_BYTES,
                 what: str = "a .toml file", context: str | None = None) -> bytes:
    """The bytes of a *regular* file of at most ``max_bytes``: a directory, FIFO, device or
    socket (which would hang or never end) and a larger file are a one-line
    :class:`UserInputError` naming ``context`` (file and key that referred to it) and the
    file."""
    where = f"{context}: " if context else ""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise UserInputError(f"{where}{source}: no such file") from None
    except OSError as exc:
        raise UserInputError(f"{where}{source}: cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise UserInputError(f"{where}{source}: is a directory, expected {what}")
    if not stat.S_ISREG(st.st_mode):
        raise UserInputError(f"{where}{source}: is {file_kind(st.st_mode)}, not a regular "
                             f"file; expected {what}")
    too_big = UserInputError(f"{where}{source}: larger than {max_bytes >> 20} MiB; "
                             f"expected {what}")
    if st.st_size > max_bytes:
        raise too_big
    try:
        with open(path, "rb") as fh:
            raw = fh.read(max_bytes + 1)
    except OSError as exc:
        raise UserInputError(f"{where}{source}: cannot read ({exc.strerror or exc})") from None
    if len(raw) > max_bytes:
        raise too_big
    return raw


def _read_text(path: pathlib.Path, source: str, context: str | None = None) -> str:
    raw = read_regular(path, source, context=context)
    try:
        return raw.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        where = f"{context}: " if context else ""
        raise UserInputError(f"{where}{source}: not a UTF-8 text file (byte {exc.start}); "
                             f"expected a TOML file") from None


def _unknown_name(kind: str, ref: str, context: str | None) -> UserInputError:
    names = list_names(kind)
    close = difflib.get_close_matches(ref, names, n=1)
    hint = f" (did you mean '{close[0]}'?)" if close else ""
    where = f"{context}: " if context else ""
    label = {"scenario": "scenario", "device": "device preset",
             "thermal": "thermal preset", "study": "study"}[kind]
    return UserInputError(
        f"{where}unknown {label} {ref!r}{hint}; shipped: {', '.join(names) or '(none)'}"
        f" (or give a path to a .toml file)")


def _shipped_hint(kind: str, ref: str) -> str:
    """For a path that does not exist: the shipped name it (nearly) names, if any."""
    stem = pathlib.PurePath(ref).name.removesuffix(".toml")
    names = list_names(kind)
    close = [stem] if stem in names else difflib.get_close_matches(stem, names, n=1)
    if not close:
        return ""
    label = {"scenario": "scenario", "device": "device preset",
             "thermal": "thermal preset", "study": "study"}[kind]
    return f" (did you mean the shipped {label} '{close[0]}'? give its name without a path)"


def locate(ref: str, kind: str, *, base_dir: pathlib.Path | None = None,
           context: str | None = None) -> tuple[str, pathlib.Path | None, object]:
    """Resolve a name or path to ``(name, base_dir, traversable)``. ``context`` prefixes the
    error message (e.g. ``"my.toml: device"``) when the reference came from a file."""
    if not isinstance(ref, str) or not ref.strip():
        where = f"{context}: " if context else ""
        raise UserInputError(f"{where}expected a {kind} name or a path to a .toml file, "
                             f"got {ref!r}")
    if looks_like_path(ref):
        where = f"{context}: " if context else ""
        try:
            path = pathlib.Path(ref).expanduser()
            if not path.is_absolute() and base_dir is not None and (base_dir / path).exists():
                path = base_dir / path
            if not path.exists():
                raise UserInputError(f"{where}{ref}: no such file{_shipped_hint(kind, ref)}")
            folder = path.resolve().parent
        except (OSError, ValueError, RuntimeError) as exc:
            raise UserInputError(f"{where}{ref!r}: not a usable path ({exc})") from None
        name = path.name[:-5] if path.name.endswith(".toml") else path.name
        return name, folder, path
    if not _NAME_RE.match(ref):
        raise _unknown_name(kind, ref, context)
    entry = _package_dir(kind).joinpath(f"{ref}.toml")
    try:
        found = entry.is_file()
    except OSError:             # e.g. a name longer than the file system allows
        found = False
    if not found:
        raise _unknown_name(kind, ref, context)
    return ref, None, entry


def load(ref: str, kind: str, *, base_dir: pathlib.Path | None = None,
         context: str | None = None) -> TomlFile:
    """Find (by name or path) and parse one TOML file of ``kind``."""
    name, folder, entry = locate(ref, kind, base_dir=base_dir, context=context)
    source = str(entry)
    if isinstance(entry, pathlib.Path):
        text = _read_text(entry, source, context)
    else:
        text = entry.read_text(encoding="utf-8")
    return TomlFile(name=name, source=source, base_dir=folder, text=text,
                    data=parse_toml(text, source))


def load_scenario_file(ref: str) -> TomlFile:
    """A scenario by shipped name (``quickstart``) or path (``my/run.toml``)."""
    return load(ref, "scenario")


def load_device_file(ref: str, *, base_dir: pathlib.Path | None = None,
                     context: str | None = None) -> TomlFile:
    """A device preset by shipped name (``rlg_imu_000``) or path."""
    return load(ref, "device", base_dir=base_dir, context=context)


def load_thermal_file(ref: str, *, base_dir: pathlib.Path | None = None,
                      context: str | None = None) -> TomlFile:
    """A thermal network preset by shipped name (``rlg_single``) or path."""
    return load(ref, "thermal", base_dir=base_dir, context=context)
