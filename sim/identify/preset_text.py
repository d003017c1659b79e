"""TOML text of the identified presets and of the replay scenario, with a comment on every
fitted number (its standard error and where it came from).

The standard library reads TOML but does not write it, and a writer that keeps per-key comments
is what the fitted presets need (every fitted number commented with its standard error), so this
small writer is here: tables as ``[a.b]`` headers, arrays of tables as ``[[a.b]]``, link parts
(``conduction = {…}``), instance factors and gradient lists as inline tables; strings through
:func:`json.dumps` (a JSON string is a valid TOML basic string). The output is read back with
:func:`tomllib.loads` by the tests and by every scenario that names the preset.
"""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = ["dumps", "fmt", "piecewise_programme"]

#: tables written inline (``key = {…}``): link parts, instance factors, port bindings
INLINE = {"conduction", "convection", "radiation", "radiation_exact", "natural_convection",
          "ports", "capacitance_factors", "power_factors", "link_factors", "face_factors",
          "published", "correlation"}
#: lists of tables written as inline arrays (``key = [{…}, …]``)
INLINE_ARRAYS = {"gradients"}


def fmt(v: Any) -> str:
    """One TOML value."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(float(f"{v:.10g}"))
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {fmt(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    if hasattr(v, "item"):
        return fmt(v.item())
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _key(k: Any) -> str:
    k = str(k)
    if k and all(c.isalnum() or c in "_-" for c in k):
        return k
    return json.dumps(k, ensure_ascii=False)


def _is_table(v: Any, key: str) -> bool:
    return isinstance(v, dict) and key not in INLINE


def _is_table_array(v: Any, key: str) -> bool:
    return (isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)
            and key not in INLINE_ARRAYS)


def dumps(data: dict, comments: dict[tuple, str] | None = None, header: str = "") -> str:
    """TOML text of ``data``; ``comments`` maps a key path (tuple of keys and list indices, e.g.
    ``("thermal", "links", 3, "convection", "area_cm2")``) to a comment put at the end of the
    line that holds it."""
    comments = comments or {}
    lines: list[str] = [f"# {h}" if h else "#" for h in header.splitlines()] if header else []

    def comment_for(path: tuple, value: Any) -> str:
        notes = []
        if path in comments:
            notes.append(comments[path])
        if isinstance(value, dict):
            for k, x in value.items():
                notes += [c for c in [comments.get(path + (k,))] if c]
        if isinstance(value, list):
            for i, x in enumerate(value):
                if isinstance(x, dict):
                    notes += [c for k in x for c in [comments.get(path + (i, k))] if c]
                elif path + (i,) in comments:
                    notes.append(comments[path + (i,)])
        return ("  # " + "; ".join(notes)) if notes else ""

    def table(path: tuple, name: str, body: dict, array: bool = False) -> None:
        scalars = [(k, v) for k, v in body.items()
                   if not _is_table(v, k) and not _is_table_array(v, k)]
        subs = [(k, v) for k, v in body.items() if _is_table(v, k)]
        arrays = [(k, v) for k, v in body.items() if _is_table_array(v, k)]
        if name and (scalars or array or not (subs or arrays)):
            if lines and lines[-1] != "":
                lines.append("")
            lines.append(f"[[{name}]]" if array else f"[{name}]")
        for k, v in scalars:
            if isinstance(v, list) and k in INLINE_ARRAYS and v and isinstance(v[0], dict):
                lines.append(f"{_key(k)} = [")
                for i, x in enumerate(v):
                    c = comment_for(path + (k, i), x)
                    lines.append(f"  {fmt(x)},{c}")
                lines.append("]")
            else:
                lines.append(f"{_key(k)} = {fmt(v)}{comment_for(path + (k,), v)}")
        for k, v in subs:
            table(path + (k,), f"{name}.{_key(k)}" if name else _key(k), v)
        for k, v in arrays:
            for i, x in enumerate(v):
                table(path + (k, i), f"{name}.{_key(k)}" if name else _key(k), x, array=True)

    table((), "", data)
    return "\n".join(lines).rstrip() + "\n"


def piecewise_programme(t_s, air_c, tol_k: float = 0.05, decimate_s: float = 60.0
                        ) -> tuple[float, list[tuple[float, float]]]:
    """Breakpoints of a piecewise-linear approximation of a recorded air temperature within
    ``tol_k`` (greedy: each segment as long as the straight line stays within the tolerance,
    on samples every ``decimate_s``). Returns the start value and ``[(duration_s, to_c), …]``."""
    import numpy as np
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(air_c, dtype=float)
    step = max(1, int(round(decimate_s / max(t[1] - t[0], 1e-9)))) if t.size > 1 else 1
    idx = np.unique(np.concatenate((np.arange(0, t.size, step), [t.size - 1])))
    tt = np.concatenate(([0.0], t[idx]))
    yy = np.concatenate(([y[0]], y[idx]))
    out: list[tuple[float, float]] = []
    i = 0
    while i < tt.size - 1:
        j = i + 1
        while j + 1 < tt.size:
            k = j + 1
            line = yy[i] + (yy[k] - yy[i]) * (tt[i:k + 1] - tt[i]) / (tt[k] - tt[i])
            if np.max(np.abs(line - yy[i:k + 1])) > tol_k:
                break
            j = k
        out.append((float(tt[j] - tt[i]), float(yy[j])))
        i = j
    return float(yy[0]), out
