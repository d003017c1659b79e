"""Typed, validating access to TOML tables.

Every getter takes the table, the key and a :class:`Ctx` (the file and the dotted path of the
table) and raises :class:`~rlgsim.ground.errors.UserInputError` with one line naming file, key, value and
what is allowed. Modules that read a part of a scenario or preset use these instead of
indexing dictionaries, so that every user mistake reads the same way.
"""

from __future__ import annotations

import difflib
import math
from collections import abc
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

from rlgsim.ground.errors import UserInputError

_MISSING = object()


@dataclass(frozen=True)
class Ctx:
    """Where a table came from: ``source`` file (or scenario name) and dotted ``path``."""

    source: str | None = None
    path: str = ""

    def key(self, key: str) -> str:
        """Dotted key for messages, e.g. ``chamber.segments[2].rate_c_per_min``; ``key`` ""
        names the table itself (``chamber.segments[2]``, no stray dot)."""
        if not key:
            return self.path
        return f"{self.path}.{key}" if self.path else key

    def child(self, key: str) -> "Ctx":
        return Ctx(self.source, self.key(key))

    def item(self, index: int) -> "Ctx":
        return Ctx(self.source, f"{self.path}[{index}]")

    def error(self, key: str, message: str) -> UserInputError:
        where = f"{self.source}: " if self.source else ""
        return UserInputError(f"{where}{self.key(key)}: {message}")


def _type_name(value: Any) -> str:
    return {bool: "boolean", int: "integer", float: "number", str: "string",
            list: "array", dict: "table"}.get(type(value), type(value).__name__)


def check_known_keys(table: Mapping[str, Any], allowed: Iterable[str], ctx: Ctx) -> None:
    """Reject keys not in ``allowed`` (misspelt keys), suggesting the closest allowed one."""
    allowed = list(allowed)
    for key in table:
        if key not in allowed:
            with_unit = [a for a in allowed if a.startswith(f"{key}_")]
            close = difflib.get_close_matches(key, allowed, n=1)
            if with_unit:
                hint = (f" (missing unit: write the unit in the key name, one of "
                        f"{', '.join(with_unit)})")
            elif close:
                hint = f" (did you mean '{close[0]}'?)"
            else:
                hint = ""
            raise ctx.error(key, f"unknown key{hint}; allowed keys: {', '.join(sorted(allowed))}")


def _is_table(value: Any) -> bool:
    """``isinstance(value, Mapping)``, a parsed TOML table (a dict) first: typing.Mapping's
    check goes through typing's and the ABC's __instancecheck__ every time (~1 µs; a scenario
    and its presets read ~1 300 keys)."""
    return type(value) is dict or isinstance(value, abc.Mapping)


def _get(table: Mapping[str, Any], key: str, ctx: Ctx, default: Any) -> Any:
    if not _is_table(table):
        raise UserInputError(f"{ctx.source + ': ' if ctx.source else ''}{ctx.path or 'top level'}: "
                             f"expected a table, got {_type_name(table)}")
    if key in table:
        return table[key]
    if default is _MISSING:
        raise ctx.error(key, "missing required key")
    return default


def get_float(table: Mapping[str, Any], key: str, ctx: Ctx, default: Any = _MISSING, *,
              min: float | None = None, max: float | None = None,
              min_exclusive: bool = False) -> float:
    """A finite number (int or float in TOML) within ``[min, max]`` (``(min, max]`` if exclusive)."""
    value = _get(table, key, ctx, default)
    if value is None:
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ctx.error(key, f"expected a number, got {_type_name(value)} {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ctx.error(key, f"expected a finite number, got {value!r}")
    if min is not None and (value < min or (min_exclusive and value <= min)):
        op = ">" if min_exclusive else ">="
        raise ctx.error(key, f"value {value:g} not allowed; must be {op} {min:g}")
    if max is not None and value > max:
        raise ctx.error(key, f"value {value:g} not allowed; must be <= {max:g}")
    return value


def get_int(table: Mapping[str, Any], key: str, ctx: Ctx, default: Any = _MISSING, *,
            min: int | None = None, max: int | None = None) -> int:
    """An integer within ``[min, max]``."""
    value = _get(table, key, ctx, default)
    if value is None:
        return value
    if isinstance(value, bool) or not isinstance(value, int):
        raise ctx.error(key, f"expected an integer, got {_type_name(value)} {value!r}")
    if min is not None and value < min:
        raise ctx.error(key, f"value {value} not allowed; must be >= {min}")
    if max is not None and value > max:
        raise ctx.error(key, f"value {value} not allowed; must be <= {max}")
    return value


def get_bool(table: Mapping[str, Any], key: str, ctx: Ctx, default: Any = _MISSING) -> bool:
    value = _get(table, key, ctx, default)
    if not isinstance(value, bool):
        raise ctx.error(key, f"expected true or false, got {_type_name(value)} {value!r}")
    return value


def get_str(table: Mapping[str, Any], key: str, ctx: Ctx, default: Any = _MISSING, *,
            choices: Iterable[str] | None = None) -> str:
    """A string, optionally one of ``choices``."""
    value = _get(table, key, ctx, default)
    if value is None:
        return value
    if not isinstance(value, str):
        raise ctx.error(key, f"expected a string, got {_type_name(value)} {value!r}")
    if choices is not None:
        choices = list(choices)
        if value not in choices:
            close = difflib.get_close_matches(value, choices, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise ctx.error(key, f"value {value!r} not allowed{hint}; allowed: {', '.join(choices)}")
    return value


def get_table(table: Mapping[str, Any], key: str, ctx: Ctx, default: Any = _MISSING) -> dict:
    value = _get(table, key, ctx, default)
    if value is None:
        return value
    if not _is_table(value):
        raise ctx.error(key, f"expected a table, got {_type_name(value)} {value!r}")
    return dict(value)


def get_section(table: Mapping[str, Any], key: str, ctx: Ctx, allowed: Iterable[str],
                default: Any = _MISSING) -> tuple[dict, Ctx]:
    """A sub-table whose keys must be among ``allowed``, with the :class:`Ctx` that names
    its keys in messages (``key.<sub-key>``)."""
    value = get_table(table, key, ctx, default)
    sub = ctx.child(key)
    check_known_keys(value, allowed, sub)
    return value, sub


def get_list(table: Mapping[str, Any], key: str, ctx: Ctx, default: Any = _MISSING, *,
             min_len: int = 0) -> list:
    value = _get(table, key, ctx, default)
    if value is None:
        return value
    if not isinstance(value, list):
        raise ctx.error(key, f"expected an array, got {_type_name(value)} {value!r}")
    if len(value) < min_len:
        raise ctx.error(key, f"expected at least {min_len} entries, got {len(value)}")
    return value


def get_float_list(table: Mapping[str, Any], key: str, ctx: Ctx, default: Any = _MISSING, *,
                   length: int | None = None) -> list[float]:
    """An array of finite numbers, optionally of a fixed length."""
    values = get_list(table, key, ctx, default)
    if values is None:
        return values
    if length is not None and len(values) != length:
        raise ctx.error(key, f"expected {length} numbers, got {len(values)}")
    out = []
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
            raise ctx.error(key, f"expected finite numbers, got {v!r}")
        out.append(float(v))
    return out


#: Unit suffixes of time keys and their factor to seconds (``duration_h`` → 3600 s per unit).
TIME_UNITS: dict[str, float] = {"s": 1.0, "min": 60.0, "h": 3600.0}


def unit_keys(base: str, units: Mapping[str, float]) -> list[str]:
    """All spellings of a quantity key: ``unit_keys("duration", TIME_UNITS)`` →
    ``["duration_s", "duration_min", "duration_h"]`` (for :func:`check_known_keys`)."""
    return [f"{base}_{suffix}" for suffix in units]


def get_quantity(table: Mapping[str, Any], base: str, ctx: Ctx, units: Mapping[str, float],
                 default: Any = _MISSING, *, min: float | None = None,
                 max: float | None = None, min_exclusive: bool = False) -> float:
    """A quantity that may be written in any of several units, converted to SI.

    The key is ``<base>_<unit>`` for one unit of ``units`` (suffix → factor to SI), e.g.
    ``duration_h = 4`` → 14400.0 with :data:`TIME_UNITS`. Exactly one spelling may be present;
    ``default`` (already in SI) is returned when none is. ``min``/``max`` are in SI and are
    reported back in the unit the user wrote.
    """
    if not _is_table(table):
        _get(table, base, ctx, default)          # raises "expected a table"
    present = [k for k in unit_keys(base, units) if k in table]
    if len(present) > 1:
        raise ctx.error(present[1], f"give only one of {', '.join(present)}")
    if not present:
        if base in table:
            raise ctx.error(base, f"missing unit: write the unit in the key name, one of "
                                  f"{', '.join(unit_keys(base, units))}")
        if default is _MISSING:
            raise ctx.error(base, f"missing required key; give one of "
                                  f"{', '.join(unit_keys(base, units))}")
        return default
    key = present[0]
    factor = units[key[len(base) + 1:]]
    value = get_float(table, key, ctx,
                      min=None if min is None else min / factor,
                      max=None if max is None else max / factor,
                      min_exclusive=min_exclusive)
    if not math.isfinite(value * factor):
        raise ctx.error(key, f"{value!r} is too large: it overflows when converted to SI "
                             f"({value!r} × {factor:g})")
    return value * factor
