"""TOML text of the identified presets and of the replay scenario, with a comment on every
fitted number (its standard error and where it came from).

Written with :func:`rlgsim.ground.toml_text.dumps` (tomlkit), which keeps a comment at the end of
the line of each key path: tables as ``[a.b]`` headers, arrays of tables as ``[[a.b]]``, and
the parts listed in :data:`INLINE` / :data:`INLINE_ARRAYS` (link parts ``conduction = {…}``,
instance factors, gradient lists) inline. Floats are written to 10 significant digits, which is
more than any fitted number's standard error resolves. The output is read back with
:func:`tomllib.loads` by the tests and by every scenario that names the preset.
"""

from __future__ import annotations

import math
from typing import Any

from rlgsim.ground import toml_text

__all__ = ["dumps", "rounded", "piecewise_programme"]

#: tables written inline (``key = {…}``): link parts, instance factors, port bindings
INLINE = {"conduction", "convection", "radiation", "radiation_exact", "natural_convection",
          "ports", "capacitance_factors", "power_factors", "link_factors", "face_factors",
          "published", "correlation"}
#: lists of tables written as inline arrays (``key = [{…}, …]``)
INLINE_ARRAYS = {"gradients"}


def rounded(v: Any) -> Any:
    """``v`` with every float to 10 significant digits (numpy scalars made plain)."""
    if isinstance(v, dict):
        return {k: rounded(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [rounded(x) for x in v]
    if hasattr(v, "item") and not isinstance(v, (bool, int, float, str)):
        v = v.item()
    if isinstance(v, float) and math.isfinite(v):
        return float(f"{v:.10g}")
    return v


def dumps(data: dict, comments: dict[tuple, str] | None = None, header: str = "") -> str:
    """TOML text of ``data``; ``comments`` maps a key path (tuple of keys and list indices, e.g.
    ``("thermal", "links", 3, "convection", "area_cm2")``) to a comment put at the end of the
    line that holds it."""
    return toml_text.dumps(rounded(data), header=header, comments=comments,
                           inline=INLINE | INLINE_ARRAYS)


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
