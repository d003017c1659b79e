"""TOML text written with tomlkit: a mapping as a document, one value as TOML, and keys changed
in an existing document so that its comments and layout survive.

The standard library reads TOML (:mod:`tomllib`) but does not write it; tomlkit writes it and
keeps the comments, order and whitespace of a document it parsed. This module adds only what
tomlkit leaves to its caller:

- :func:`plain` — numpy scalars and arrays as Python values; a value TOML cannot hold is a
  one-line :class:`~rlgsim.ground.errors.UserInputError`;
- :func:`dumps` — a mapping as a document: scalars and arrays before the sub-tables, chosen
  tables written inline, an optional header comment and a comment at the end of the line that
  holds a key path (as a fitted preset notes each number's standard error);
- :func:`value_text` — one value as inline TOML (for messages and one-line documents);
- :func:`with_values` — a document with dotted key paths (``chamber.segments[1].to_c``) set or
  removed, edited in place; its text parses to exactly the original data with the changes (if
  tomlkit cannot edit a layout in place, the changed data is written afresh).
"""

from __future__ import annotations

import datetime as _dt
import re
import tomllib
from typing import Any, Collection, Mapping, MutableMapping

import tomlkit
from tomlkit.items import AoT, Item, Table

from rlgsim.ground.errors import UserInputError

__all__ = ["plain", "dumps", "value_text", "key_path", "set_value", "with_values"]

_SCALARS = (bool, int, float, str, _dt.datetime, _dt.date, _dt.time)


def plain(v: Any) -> Any:
    """``v`` as the Python values TOML holds: numpy scalars → ``item()``, arrays → lists,
    tuples → lists, mapping keys → ``str``; anything else TOML cannot write raises
    :class:`UserInputError`."""
    if type(v) in _SCALARS:
        return v
    if isinstance(v, Mapping):
        return {str(k): plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if hasattr(v, "item") and not hasattr(v, "items"):      # numpy scalars (and 0-d arrays)
        try:
            return plain(v.item())
        except (TypeError, ValueError):                       # an array of several elements
            pass
    if hasattr(v, "tolist"):                                  # numpy arrays
        return plain(v.tolist())
    if isinstance(v, _SCALARS):                               # subclasses (IntEnum, str enums)
        return v
    raise UserInputError(f"cannot write a {type(v).__name__} value to TOML: {v!r}")


def _item(v: Any, name: str | None, path: tuple | None, inline: Collection[str],
          notes: Mapping[tuple, str]) -> Item:
    """The tomlkit item of a plain value. ``path`` is None inside an inline value (no line of
    its own); otherwise the value's key path, for its comment."""
    if path is not None and isinstance(v, dict) and name not in inline:
        table = tomlkit.table()
        _fill(table, v, path, inline, notes)
        if path in notes:
            _comment(table, notes[path])
        return table
    if (path is not None and isinstance(v, list) and v and name not in inline
            and all(isinstance(x, dict) for x in v)):
        return _aot(v, name, path, inline, notes)
    if isinstance(v, dict):
        item = tomlkit.inline_table()
        for k, x in v.items():
            item.append(k, _item(x, k, None, inline, notes))
    elif isinstance(v, list):
        item = tomlkit.array()
        for x in v:
            item.append(_item(x, None, None, inline, notes))
    else:
        item = tomlkit.item(v)
    if path is not None:                       # the line's comment: this key and those inside
        said = [c for p, c in notes.items() if p[:len(path)] == path]
        if said:
            _comment(item, "; ".join(said))
    return item


def _comment(item: Item, note: str) -> None:
    item.comment(note)
    item.trivia.comment_ws = "  "              # two spaces before an end-of-line comment


def _aot(v: list, name: str | None, path: tuple, inline: Collection[str],
         notes: Mapping[tuple, str]) -> AoT:
    aot = tomlkit.aot()
    for i, x in enumerate(v):
        aot.append(_item(x, name, path + (i,), inline, notes))
    return aot


def _fill(table: MutableMapping, data: Mapping, path: tuple, inline: Collection[str],
          notes: Mapping[tuple, str]) -> None:
    items = [(k, _item(x, k, path + (k,), inline, notes)) for k, x in data.items()]
    for k, item in sorted(items, key=lambda kv: isinstance(kv[1], (Table, AoT))):
        table.append(k, item)                  # scalars and arrays before the sub-tables


def dumps(data: Mapping, *, header: str = "", comments: Mapping[tuple, str] | None = None,
          inline: Collection[str] = ()) -> str:
    """TOML text of ``data`` (tables, arrays of tables, arrays, scalars; numpy values allowed).

    ``header``: comment lines put first. ``comments``: key path (tuple of keys and list
    indices, e.g. ``("thermal", "links", 3, "convection", "area_cm2")``) → comment put at the end
    of the line that holds it (the notes of an inline value's members are joined by ``"; "``; a
    table's comment goes on its header line). ``inline``: key names of tables (and arrays of
    tables) written inline as ``key = {…}`` / ``key = [{…}, …]``."""
    doc = tomlkit.document()
    for line in header.splitlines():
        doc.add(tomlkit.comment(line) if line else tomlkit.nl())
    _fill(doc, plain(data), (), frozenset(inline), dict(comments or {}))
    return doc.as_string()


def value_text(v: Any) -> str:
    """One value as inline TOML text (tables as ``{k = v}``)."""
    return _item(plain(v), None, None, (), {}).as_string()


_PART = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def key_path(key: str, what: str = "change") -> list[str | int]:
    """``"chamber.segments[1].to_c"`` → ``["chamber", "segments", 1, "to_c"]``."""
    parts: list[str | int] = []
    pos = 0
    for m in _PART.finditer(key):
        if m.start() != pos and key[pos:m.start()] != ".":
            break
        parts.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if not parts or pos != len(key):
        raise UserInputError(f"{what} {key!r}: not a key path such as 'chamber.start_c' or "
                             f"'chamber.segments[1].to_c'")
    return parts


def set_value(data: MutableMapping, key: str, value: Any, what: str = "change") -> None:
    """Set the dotted ``key`` of ``data`` (a parsed TOML mapping or a tomlkit document) to
    ``value`` (``None``: remove it), creating missing tables; ``[i]`` with ``i`` = the length
    of a list appends. A path that does not fit the data raises :class:`UserInputError` naming
    ``what`` and the key."""
    parts = key_path(key, what)
    node: Any = data
    for i, part in enumerate(parts[:-1]):
        nxt = parts[i + 1]
        if isinstance(part, int):
            if not isinstance(node, list) or part >= len(node):
                raise UserInputError(f"{what} {key!r}: {'.'.join(map(str, parts[:i]))} has no "
                                     f"element [{part}]")
            node = node[part]
            continue
        if not isinstance(node, dict):
            raise UserInputError(f"{what} {key!r}: {part!r} is not inside a table")
        if part not in node:
            node[part] = [] if isinstance(nxt, int) else {}
        node = node[part]
    last = parts[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last > len(node):
            raise UserInputError(f"{what} {key!r}: no element [{last}] to set")
        if value is None:
            del node[last]
        elif last == len(node):
            node.append(value)
        else:
            node[last] = value
        return
    if not isinstance(node, dict):
        raise UserInputError(f"{what} {key!r}: {last!r} is not inside a table")
    if value is None:
        node.pop(last, None)
    else:
        node[last] = value


def with_values(text: str, changes: Mapping[str, Any], what: str = "change") -> str:
    """``text`` (a TOML document) with the dotted ``changes`` applied (:func:`set_value`;
    ``None`` removes a key), edited in place so its comments and layout survive. The result
    parses to exactly ``tomllib.loads(text)`` with the changes; where tomlkit cannot edit the
    layout in place to that end, the changed data is written afresh by :func:`dumps`."""
    text = text.removeprefix("\ufeff")
    todo = {k: (None if v is None else plain(v)) for k, v in changes.items()}
    data = tomllib.loads(text)
    for key, value in todo.items():              # errors are raised here, on the plain data
        set_value(data, key, value, what)
    try:
        doc = tomlkit.parse(text)
        for key, value in todo.items():
            set_value(doc, key, value, what)
        out = doc.as_string()
        if tomllib.loads(out) == data:
            return out
    except Exception:        # noqa: BLE001 — tomlkit errors on an unusual layout: write afresh
        pass
    return dumps(data)
