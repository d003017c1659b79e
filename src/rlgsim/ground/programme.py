"""A commanded turntable programme as a CSV table (docs/recordings.md, "Turntable programme").

The calibration of a recording needs what the turntable was told to do — which a simulated
dataset keeps in its timeline and a recording does not. One row per motion, times in the
recording's clock (the same seconds as its ``time_s``)::

    t0_s,t1_s,kind,axis,rate_deg_per_s,outer_deg,inner_deg,position,window,label
    0,120,static,,0,0,0,1,0,P01
    120,124.5,rotate,outer,20,0,0,-1,0,R01 outer +90°

``kind`` is ``static`` or ``rotate``; ``axis`` ``outer``/``inner`` (empty when static);
``rate_deg_per_s`` the signed table rate; ``outer_deg``/``inner_deg`` the angles at ``t0_s``;
``position`` the static position number (−1 or empty for a rotation); ``window`` the
calibration window the motion belongs to (−1 or empty: none). A calibration window spans its
motions (first ``t0_s`` to last ``t1_s``).

:func:`read_programme` returns timeline segments (dicts ``t0``, ``t1``, ``track``, ``label``,
``attrs``) — the form :func:`rlgsim.estimators.calibration.find_windows` reads from a dataset.
"""

from __future__ import annotations

import csv
import math
import os
import pathlib
from typing import Iterable, Mapping

from rlgsim.ground.atomic import atomic_file
from rlgsim.ground.errors import UserInputError

__all__ = ["PROGRAMME_COLUMNS", "read_programme", "write_programme", "programme_rows"]

PROGRAMME_COLUMNS = ["t0_s", "t1_s", "kind", "axis", "rate_deg_per_s", "outer_deg", "inner_deg",
                     "position", "window", "label"]
_REQUIRED = ["t0_s", "t1_s", "kind"]


def _num(path, row, col, text, *, integer=False, default=None):
    text = (text or "").strip()
    if text == "":
        if default is not None:
            return default
        raise UserInputError(f"{path}: column {col!r}, row {row}: empty value not allowed; must "
                             f"be a number")
    try:
        v = float(text)
    except ValueError:
        raise UserInputError(f"{path}: column {col!r}, row {row}: value {text!r} not allowed; "
                             f"must be a number") from None
    if not math.isfinite(v) or (integer and v != int(v)):
        raise UserInputError(f"{path}: column {col!r}, row {row}: value {text!r} not allowed; "
                             f"must be a {'whole' if integer else 'finite'} number")
    return int(v) if integer else v


def read_programme(path: str | os.PathLike) -> list[dict]:
    """Read a programme CSV into timeline segments (turntable motions and calibration windows).
    UserInputError (file, column, row, what is allowed) for anything else."""
    p = pathlib.Path(path)
    try:
        fh = open(p, newline="", encoding="utf-8")
    except FileNotFoundError:
        raise UserInputError(f"{p}: no such programme file") from None
    with fh:
        reader = csv.DictReader(fh)
        cols = [c.strip() for c in reader.fieldnames or []]
        for c in _REQUIRED:
            if c not in cols:
                raise UserInputError(f"{p}: column {c!r} missing; a programme has the columns "
                                     f"{', '.join(PROGRAMME_COLUMNS)}")
        for c in cols:
            if c not in PROGRAMME_COLUMNS:
                raise UserInputError(f"{p}: column {c!r}: unknown column; allowed: "
                                     f"{', '.join(PROGRAMME_COLUMNS)}")
        motions = []
        for i, raw in enumerate(reader, start=1):
            r = {k.strip(): v for k, v in raw.items() if k is not None}
            t0 = _num(p, i, "t0_s", r.get("t0_s"))
            t1 = _num(p, i, "t1_s", r.get("t1_s"))
            if t1 <= t0:
                raise UserInputError(f"{p}: column 't1_s', row {i}: value {t1!r} not allowed; "
                                     f"must be > t0_s = {t0!r}")
            if motions and t0 < motions[-1]["t1"] - 1e-9:
                raise UserInputError(f"{p}: column 't0_s', row {i}: value {t0!r} not allowed; "
                                     f"motions must follow each other (the previous ends at "
                                     f"{motions[-1]['t1']!r})")
            kind = (r.get("kind") or "").strip()
            if kind not in ("static", "rotate"):
                raise UserInputError(f"{p}: column 'kind', row {i}: value {kind!r} not allowed; "
                                     f"must be static or rotate")
            axis = (r.get("axis") or "").strip()
            if kind == "rotate" and axis not in ("outer", "inner"):
                raise UserInputError(f"{p}: column 'axis', row {i}: value {axis!r} not allowed; "
                                     f"a rotation is about the outer or inner axis")
            rate = _num(p, i, "rate_deg_per_s", r.get("rate_deg_per_s"), default=0.0)
            if kind == "rotate" and rate == 0:
                raise UserInputError(f"{p}: column 'rate_deg_per_s', row {i}: value 0 not "
                                     f"allowed for a rotation")
            position = _num(p, i, "position", r.get("position"), integer=True, default=-1)
            window = _num(p, i, "window", r.get("window"), integer=True, default=-1)
            attrs = dict(kind=kind, axis=axis or None, rate_deg_s=rate if kind == "rotate" else 0.0,
                         outer_deg=_num(p, i, "outer_deg", r.get("outer_deg"), default=0.0),
                         inner_deg=_num(p, i, "inner_deg", r.get("inner_deg"), default=0.0),
                         position=position if position >= 0 else None,
                         window=window if window >= 0 else None, duration_s=t1 - t0)
            motions.append(dict(t0=t0, t1=t1, track="turntable",
                                label=(r.get("label") or "").strip() or f"M{i:02d}", attrs=attrs))
    if not motions:
        raise UserInputError(f"{p}: no motion rows; a programme needs at least one")
    windows: dict[int, list[dict]] = {}
    for m in motions:
        if m["attrs"]["window"] is not None:
            windows.setdefault(m["attrs"]["window"], []).append(m)
    cal = [dict(t0=ms[0]["t0"], t1=ms[-1]["t1"], track="calibration",
                label=f"calibration window {w}", attrs=dict(window=w,
                                                             motions=len(ms)))
           for w, ms in sorted(windows.items(), key=lambda kv: kv[1][0]["t0"])]
    return motions + cal


def programme_rows(segments: Iterable[Mapping]) -> list[dict]:
    """Programme rows (:data:`PROGRAMME_COLUMNS`) from timeline segments' turntable track."""
    rows = []
    for s in segments:
        if s["track"] != "turntable":
            continue
        a = s["attrs"]
        rows.append(dict(t0_s=float(s["t0"]), t1_s=float(s["t1"]), kind=a.get("kind", "static"),
                         axis=a.get("axis") or "", rate_deg_per_s=float(a.get("rate_deg_s") or 0),
                         outer_deg=float(a.get("outer_deg") or 0),
                         inner_deg=float(a.get("inner_deg") or 0),
                         position=-1 if a.get("position") is None else int(a["position"]),
                         window=-1 if a.get("window") is None else int(a["window"]),
                         label=s["label"]))
    return rows


def write_programme(path: str | os.PathLike, segments: Iterable[Mapping]) -> pathlib.Path:
    """Write the turntable track of ``segments`` as a programme CSV (full float precision)."""
    p = pathlib.Path(path)
    with atomic_file(p) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, PROGRAMME_COLUMNS, lineterminator="\n")
        w.writeheader()
        for r in programme_rows(segments):
            w.writerow({k: repr(float(v)) if isinstance(v, float) else v  # np.float64 too
                        for k, v in r.items()})
    return p
