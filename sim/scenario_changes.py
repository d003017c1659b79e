"""A scenario with some keys changed, whose embedded TOML text says exactly what was run.

``Scenario`` is frozen and ``dataclasses.replace`` would leave ``scenario.text`` (the TOML
embedded in every dataset) stale. :func:`with_changes` changes the *parsed TOML* instead,
writes it back as TOML and parses that text again, so the result is validated like any
scenario and its ``text`` parses to exactly the data it was built from::

    sc = load_scenario("quickstart")
    short = with_changes(sc, {"duration_h": 0.5, "chamber.segments[1].to_c": 35.0}, seed=7)

Keys are dotted paths into the TOML (``chamber.start_c``, ``site.latitude_deg``); a list
element is ``[i]`` (``chamber.segments[1].rate_c_per_min``); keyword arguments change
top-level keys. A value of ``None`` removes the key (e.g. ``duration_h=None`` to let the
chamber programme set the duration). Unknown keys and bad values are reported by the scenario
validator as for a file.

The TOML writer is a few lines here rather than a dependency: the standard library reads TOML
but does not write it, and a scenario holds only tables, arrays of tables, arrays and scalars.
Comments of the original file are not kept (the text starts with a comment naming the source
and the changes).
"""

from __future__ import annotations

import copy
import datetime as _dt
import math
import re
from typing import Any, Mapping

from rlgsim.ground.errors import UserInputError

__all__ = ["with_changes", "changed_text", "dumps_toml"]

_PART = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def _path(key: str) -> list[str | int]:
    parts: list[str | int] = []
    pos = 0
    for m in _PART.finditer(key):
        if m.start() != pos and key[pos:m.start()] != ".":
            raise UserInputError(f"change {key!r}: not a key path such as 'chamber.start_c' or "
                                 f"'chamber.segments[1].to_c'")
        parts.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if not parts or pos != len(key):
        raise UserInputError(f"change {key!r}: not a key path such as 'chamber.start_c' or "
                             f"'chamber.segments[1].to_c'")
    return parts


def _apply(data: dict, key: str, value: Any) -> None:
    parts = _path(key)
    node: Any = data
    for i, part in enumerate(parts[:-1]):
        nxt = parts[i + 1]
        if isinstance(part, int):
            if not isinstance(node, list) or part >= len(node):
                raise UserInputError(f"change {key!r}: {'.'.join(map(str, parts[:i]))} has no "
                                     f"element [{part}]")
            node = node[part]
            continue
        if not isinstance(node, dict):
            raise UserInputError(f"change {key!r}: {part!r} is not inside a table")
        if part not in node:
            node[part] = [] if isinstance(nxt, int) else {}
        node = node[part]
    last = parts[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last > len(node):
            raise UserInputError(f"change {key!r}: no element [{last}] to set")
        if value is None:
            del node[last]
        elif last == len(node):
            node.append(value)
        else:
            node[last] = value
        return
    if not isinstance(node, dict):
        raise UserInputError(f"change {key!r}: {last!r} is not inside a table")
    if value is None:
        node.pop(last, None)
    else:
        node[last] = value


# ------------------------------------------------------------------------- TOML writer

def _key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else _scalar(k)


def _scalar(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        out = v.replace("\\", "\\\\").replace('"', '\\"')
        out = out.replace("\n", "\\n").replace("\t", "\\t").replace("\r", "\\r")
        return f'"{out}"'
    if isinstance(v, (_dt.datetime, _dt.date, _dt.time)):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(_inline(x) for x in v) + "]"
    if hasattr(v, "item"):                       # numpy scalars
        return _scalar(v.item())
    if hasattr(v, "tolist"):                     # numpy arrays
        return _scalar(v.tolist())
    raise UserInputError(f"cannot write a {type(v).__name__} value to TOML: {v!r}")


def _inline(v: Any) -> str:
    if isinstance(v, Mapping):
        return "{" + ", ".join(f"{_key(k)} = {_inline(x)}" for k, x in v.items()) + "}"
    return _scalar(v)


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, Mapping) for x in v)


def _emit(table: Mapping, prefix: str, out: list[str]) -> None:
    for k, v in table.items():                   # scalars and arrays first
        if not isinstance(v, Mapping) and not _is_table_array(v):
            out.append(f"{_key(k)} = {_scalar(v)}")
    for k, v in table.items():
        name = f"{prefix}.{_key(k)}" if prefix else _key(k)
        if isinstance(v, Mapping):
            out.append(f"\n[{name}]")
            _emit(v, name, out)
        elif _is_table_array(v):
            for item in v:
                out.append(f"\n[[{name}]]")
                _emit(item, name, out)


def dumps_toml(data: Mapping) -> str:
    """TOML text for a parsed-TOML mapping (tables, arrays of tables, arrays, scalars)."""
    out: list[str] = []
    _emit(data, "", out)
    return "\n".join(out).lstrip("\n") + "\n"


# ------------------------------------------------------------------------- the change

def changed_text(scenario, changes: Mapping[str, Any]) -> str:
    """The TOML text of ``scenario`` (its parsed tables) with the dotted ``changes`` applied,
    headed by a comment naming the source and the changes. Parsing it is the caller's job
    (:meth:`rlgsim.sim.scenario.Scenario.with_changes`), so this module imports no scenario
    code."""
    data = copy.deepcopy(scenario.tables)
    for key, value in changes.items():
        _apply(data, key, value)
    said = ", ".join(f"{k} = {_inline(v) if v is not None else '(removed)'}"
                     for k, v in changes.items())
    return f"# scenario {scenario.name}, from {scenario.source}, with {said}\n" + dumps_toml(data)


def with_changes(scenario, changes: Mapping[str, Any] | None = None, /, **keys: Any):
    """A new, validated :class:`~rlgsim.sim.scenario.Scenario`: ``scenario`` with the dotted
    ``changes`` and top-level ``keys`` applied; its ``text`` is the changed TOML."""
    return scenario.with_changes(changes, **keys)
