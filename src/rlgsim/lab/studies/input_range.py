"""Extrapolation made visible: the share of a test run's windows whose inputs lie outside the
range a compensator was trained on, and by how much.

A compensator fitted on one run knows its inputs only between their training minimum and
maximum (per input); outside that box an RBF model falls back to its constant, a polynomial
runs away, and the ranking of two models can be decided by which one extrapolates less badly
rather than by which learnt the law better. For each compensator and test run this module gives

* ``outside_pct``: the share of test windows in which at least one input is outside its
  training interval [min, max] (%);
* ``max_excess_pct``: the largest distance beyond the interval over all windows and inputs, in
  % of that input's training span (max − min), and the input it belongs to.

Only the marginal intervals are checked (the bounding box): a window inside every interval can
still lie where no training window was (another combination of T and dT/dt), so the share is a
lower bound of the extrapolation, never an over-count. Reports print it beside every ranking
(:func:`range_records`), Monte Carlo summaries per unit.
"""

from __future__ import annotations

from typing import Any, Iterable

import numpy as np

__all__ = ["outside_range", "range_records", "range_note", "range_section"]


def outside_range(X_train: Any, X_test: Any, names: Iterable[str]) -> tuple[float, float, str]:
    """(share of test windows with any input outside its training interval [%], largest excess
    in % of the training span, the input of that excess; "" when none) for the inputs
    ``names`` (columns of both :class:`~rlgsim.estimators.columns.Columns`)."""
    names = list(names)
    if not names:
        return 0.0, 0.0, ""
    out = None
    worst, worst_name = 0.0, ""
    for name in names:
        tr = np.asarray(X_train[name], dtype=float)
        te = np.asarray(X_test[name], dtype=float)
        lo, hi = float(np.min(tr)), float(np.max(tr))
        excess = np.maximum(np.maximum(lo - te, te - hi), 0.0)
        span = max(hi - lo, 1e-12 * max(1.0, abs(lo)))   # a constant input: finite, huge
        rel = excess / span
        out = excess > 0 if out is None else out | (excess > 0)
        m = float(np.max(rel)) if rel.size else 0.0
        if m > worst:
            worst, worst_name = m, name
    share = 100.0 * float(np.mean(out)) if out.size else 0.0
    return share, 100.0 * worst, worst_name


def range_records(fitted: list, runs: dict[str, Any]) -> list[dict[str, Any]]:
    """One record per (test run, compensator): ``runs`` maps a test label to its
    :class:`~rlgsim.lab.studies.runs.RunSeries`; ``fitted`` the
    :class:`~rlgsim.lab.studies.fitting.Fitted` compensators (their ``X_train``)."""
    records = []
    for label, rs in runs.items():
        for f in fitted:
            if f.X_train is None or not hasattr(f.X_train, "names"):
                continue
            share, excess, name = outside_range(f.X_train, rs.X, f.X_train.names)
            records.append({"test run": label, "compensator": f.spec.name,
                            "inputs": ", ".join(f.X_train.names),
                            "windows outside the training range %": round(share, 2),
                            "largest excess % of span": round(excess, 1),
                            "input": name or "—"})
    return records


def range_note(records: list[dict[str, Any]]) -> str:
    """One sentence for beside a ranking: how many compensators extrapolate on which run."""
    outside = [r for r in records if r["windows outside the training range %"] > 0]
    if not outside:
        return ("Every test window of every compensator lies inside the training range of its "
                "inputs (per-input intervals): the rankings below compare interpolation.")
    worst = max(outside, key=lambda r: r["windows outside the training range %"])
    return (f"{len(outside)} of {len(records)} compensator–test-run pairs extrapolate: up to "
            f"{worst['windows outside the training range %']:g} % of the windows of "
            f"{worst['test run']} lie outside the training range ({worst['compensator']}, "
            f"largest excess {worst['largest excess % of span']} % of the span of "
            f"{worst['input']}); a ranking on those runs partly ranks extrapolation (table "
            "'Inputs outside the training range').")


def range_section(rep, groups: list[tuple[list, dict[str, Any]]]) -> list[dict[str, Any]]:
    """Add the note and the table "Inputs outside the training range" to report ``rep`` for
    ``groups`` of (fitted compensators, {test label: RunSeries}) — one group per set of models
    fitted together (an environment of paper 002); nothing when there are no compensators.
    Returns the records."""
    from rlgsim.lab.report import Table
    records = [r for fitted, runs in groups for r in range_records(fitted, runs)]
    if records:
        rep.heading("Inputs outside the training range (read with the rankings below)", 2)
        rep.paragraph(range_note(records) + " A window counts as outside when any input lies "
                      "beyond its training [min, max] (a lower bound: combinations of inputs "
                      "inside every interval can still be new).")
        rep.table(Table.from_records("Inputs outside the training range", records))
    return records
