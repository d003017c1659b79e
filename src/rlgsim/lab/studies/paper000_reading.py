"""Reading paper 000's surviving summary numbers: what its Table 2 averages and maxima say about
the shapes of its parameter-vs-temperature curves, and where a run's curves stand (issue 27).

Paper 000's Figures 2-3 and Tables 1-3 did not survive in the text copy
(``shared/papers/000_*.txt``); what survives is §4.2's prose and the averages and maxima of
Table 2. Those numbers constrain the data, because both scores are in-sample scores of the same
fits to the same 175 points (the recipe scores them the same way, Table 2 of the report):

* **Share of the variance a cubic leaves.** For a least-squares fit with an intercept,
  ``R² = 1 − RMSE² / Var(y)`` (population variance; the paper's eq. (34)). With
  ``a = RMSE_LSM² / Var(y)`` (what the cubic leaves) and the RMSE improvement
  ``g = 1 − RMSE_RVR / RMSE_LSM``, the R² improvement as the paper counts it is::

      h = (R²_RVR − R²_LSM) / R²_LSM = a · (1 − (1 − g)²) / (1 − a)                    (R1)

  so ``a = h / (1 − (1 − g)² + h)``. The paper's maxima, g = 80.12 % with h = 9.15 % (if one
  parameter holds both), give a = 8.70 %: a cubic R² of 0.913, RVR leaving 0.34 % of the
  variance.
* **Structure against scatter.** If RVR follows everything but the calibration scatter σ_e
  (the std of estimate − truth) and the cubic misses structure of std ``n`` on top,
  ``1 − g = σ_e / √(σ_e² + n²)`` — the "ceiling" a perfect model reaches — so
  ``n/σ_e = √(1/(1 − g)² − 1)`` (4.9 at the paper's maximum, 1.18 at its average), and the
  trend the cubic does capture has ``trend/σ_e = √((1 − a) / (a (1 − g)²))`` (16 at the maximum:
  the structure is 30 % of the trend's std there).
* **Classes of §4.2.** Of nine plotted curves, three have "relatively simple" trends and small
  dispersion (the methods tie), four "large dispersion, obvious fluctuations, and complex
  nonlinearity" (RVR follows the fluctuations, the cubic only the trend), two small dispersion
  with an obvious trend (RVR more accurate). :func:`classify` sorts a run's parameters by the
  two properties these phrases name, measured on the data rather than on the gains: the share
  ``a`` a cubic leaves (dispersion about the curve; visible on a plot above
  :data:`DISPERSION_SHARE`) and ``n/σ_e`` (structure standing out of the scatter, above
  :data:`STRUCTURE_RATIO`). Both thresholds are judgements, stated where they are used.

Nothing here is fitted or simulated; numpy only (the algebra is closed form).
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from rlgsim.lab.studies.paper000_config import PAPER_AVG_IMPROVEMENT, PAPER_MAX_IMPROVEMENT

#: Share of the variance a cubic leaves above which a curve's dispersion about its trend is
#: plain on a plot of the whole range (RMSE_LSM ≥ 14 % of the data's std); judgement.
DISPERSION_SHARE = 0.02
#: Structure beyond a cubic, in units of the calibration scatter, above which it stands out of
#: the scatter on a plot (n/σ_e = 1.5: a perfect model gains 45 % in RMSE); judgement.
STRUCTURE_RATIO = 1.5

#: §4.2's classes (a, b, c) and the one the paper names none of (d).
CLASSES = {
    "a": "simple trend, small dispersion: the methods tie",
    "b": "large dispersion and structure beyond a cubic: RVR follows what the cubic cannot",
    "c": "small dispersion, obvious trend, structure beyond a cubic: RVR more accurate",
    "d": "large dispersion without structure beyond a cubic (no such class in §4.2)",
}


def unexplained_share(rmse_gain_pct: float, r2_gain_pct: float) -> float:
    """``a`` = RMSE_LSM²/Var(y) from the RMSE and R² improvements [%] (inverse of eq. (R1))."""
    g, h = rmse_gain_pct / 100.0, r2_gain_pct / 100.0
    return h / (1.0 - (1.0 - g) ** 2 + h)


def r2_gain_pct(share: float, rmse_gain_pct: float) -> float:
    """The R² improvement [%] a curve whose cubic leaves ``share`` of the variance gets from
    an RMSE improvement ``rmse_gain_pct`` [%] (eq. (R1))."""
    g = rmse_gain_pct / 100.0
    return 100.0 * share * (1.0 - (1.0 - g) ** 2) / (1.0 - share)


def structure_ratio(rmse_gain_pct: float) -> float:
    """n/σ_e for which a perfect model's RMSE improvement is ``rmse_gain_pct`` [%]."""
    g = rmse_gain_pct / 100.0
    return math.sqrt(1.0 / (1.0 - g) ** 2 - 1.0)


def ceiling_pct(noise: float, beyond: float) -> float:
    """RMSE improvement [%] over a cubic of a model that follows the truth exactly."""
    return 100.0 * (1.0 - noise / math.hypot(noise, beyond))


def paper_maximum() -> dict[str, float]:
    """What the paper's maxima imply for one parameter holding both (module docstring)."""
    g, h = PAPER_MAX_IMPROVEMENT["rmse"], PAPER_MAX_IMPROVEMENT["r2"]
    a = unexplained_share(g, h)
    keep = (1.0 - g / 100.0) ** 2
    return {"cubic share %": 100.0 * a, "cubic R²": 1.0 - a, "RVR share %": 100.0 * a * keep,
            "n/σ_e": structure_ratio(g), "trend/σ_e": math.sqrt((1.0 - a) / (a * keep))}


def class_b_profile(gains_pct: tuple[float, float] = (55.0, 80.0), n_b: int = 4,
                    others_r2_pct: float = 0.1, n_params: int = 15) -> dict[str, tuple]:
    """What §4.2's class b must look like if its ``n_b`` curves carry the R² average (the other
    curves' trends dwarf their scatter, R² improvement ≤ ``others_r2_pct`` each, as every
    accelerometer parameter of ours): their mean R² improvement and, at RMSE gains spanning
    ``gains_pct``, the cubic's share [%], n/σ_e and trend/σ_e (ranges, low gain first)."""
    h = (PAPER_AVG_IMPROVEMENT["r2"] * n_params - others_r2_pct * (n_params - n_b)) / n_b
    shares = [unexplained_share(g, h) for g in gains_pct]
    trends = [math.sqrt((1.0 - a) / (a * (1.0 - g / 100.0) ** 2))
              for a, g in zip(shares, gains_pct)]
    return {"R² impr %": (h, h), "cubic share %": tuple(100.0 * a for a in shares),
            "n/σ_e": tuple(structure_ratio(g) for g in gains_pct), "trend/σ_e": tuple(trends)}


def classify(share: float, ratio: float) -> str:
    """§4.2's class of a curve from its cubic share ``a`` and structure ratio n/σ_e."""
    if not (math.isfinite(share) and math.isfinite(ratio)):
        return "?"
    wide = share >= DISPERSION_SHARE
    if ratio >= STRUCTURE_RATIO:
        return "b" if wide else "c"
    return "d" if wide else "a"


def parameter_reading(t: np.ndarray, est: np.ndarray, truth: np.ndarray, rvr: np.ndarray,
                      lsm: np.ndarray, degree: int = 3) -> dict[str, Any]:
    """One parameter's reading: window temperatures ``t`` [°C], calibration estimates, true
    window means, and the in-sample predictions of both models (all (m,)). σ_e and n need the
    truth (NaN without it)."""
    var = float(np.var(est))
    rmse = {m: float(np.sqrt(np.mean((p - est) ** 2))) for m, p in (("rvr", rvr), ("lsm", lsm))}
    share = rmse["lsm"] ** 2 / var
    gain = 100.0 * (1.0 - rmse["rvr"] / rmse["lsm"])
    r2 = {m: 1.0 - rmse[m] ** 2 / var for m in rmse}
    noise = beyond = float("nan")
    if np.all(np.isfinite(truth)):
        x = t - t.mean()
        cubic = np.polyval(np.polyfit(x, truth, degree), x)
        noise = float(np.std(est - truth, ddof=1))
        beyond = float(np.std(truth - cubic, ddof=1))
    ratio = beyond / noise if noise > 0 else float("nan")
    r2_gain = 100.0 * (r2["rvr"] - r2["lsm"]) / abs(r2["lsm"])
    return {"σ_e": noise, "n beyond cubic": beyond, "n/σ_e": ratio,
            "ceiling %": ceiling_pct(noise, beyond) if noise > 0 else float("nan"),
            "trend/σ_e": math.sqrt(var - rmse["lsm"] ** 2) / noise if noise > 0
            else float("nan"),
            "cubic share %": 100.0 * share, "R² LSM": r2["lsm"], "RMSE impr %": gain,
            "R² impr %": r2_gain,
            "within paper's R² max": bool(r2_gain <= PAPER_MAX_IMPROVEMENT["r2"]),
            "class": classify(share, ratio)}


def class_summary(rows: Mapping[str, Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per class: the parameters, their mean RMSE and R² improvements [%]."""
    out = []
    for c, text in CLASSES.items():
        names = [p for p, r in rows.items() if r["class"] == c]
        out.append({"class": c, "reading": text, "parameters": ", ".join(names) or "—",
                    "count": len(names),
                    "mean RMSE impr %": float(np.mean([rows[p]["RMSE impr %"] for p in names]))
                    if names else None,
                    "mean R² impr %": float(np.mean([rows[p]["R² impr %"] for p in names]))
                    if names else None})
    return out


def summary_text(rows: Mapping[str, Mapping[str, Any]]) -> str:
    """The reading's verdict in one paragraph, from the numbers."""
    mx = paper_maximum()
    over = [p for p, r in rows.items() if not r["within paper's R² max"]]
    n_b = sum(r["class"] == "b" for r in rows.values())
    text = (f"Paper 000's Table 2 survives only as averages and maxima (RMSE "
            f"{PAPER_AVG_IMPROVEMENT['rmse']} / {PAPER_MAX_IMPROVEMENT['rmse']} %, R² "
            f"{PAPER_AVG_IMPROVEMENT['r2']} / {PAPER_MAX_IMPROVEMENT['r2']} %); both are "
            f"in-sample, as ours. With R² = 1 − RMSE²/Var, the parameter with the maxima has a "
            f"cubic leaving {mx['cubic share %']:.1f} % of its variance (cubic R² "
            f"{mx['cubic R²']:.3f}) and RVR {mx['RVR share %']:.2f} %: structure beyond the cubic "
            f"{mx['n/σ_e']:.1f}× the scatter, trend {mx['trend/σ_e']:.0f}×. No parameter can "
            f"exceed an R² improvement of {PAPER_MAX_IMPROVEMENT['r2']} %, and the average "
            f"{PAPER_AVG_IMPROVEMENT['r2']} % leaves room for only a few curves whose cubic "
            f"leaves several % of the variance: §4.2's four curves of 'large dispersion' and "
            f"'obvious fluctuations' (class b). This run has {n_b} parameter(s) in class b")
    if over:
        text += ("; " + ", ".join(over) + " exceed the paper's maximum R² improvement: their "
                 "trend is small against their scatter, so the structure beyond a cubic a "
                 "model could follow is at most the scatter's size, not several times it")
    return text + "."


def paper_table(rows: Mapping[str, Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The paper's surviving figures, what each implies, and ours beside them."""
    mx, cb = paper_maximum(), class_b_profile()
    gain = [r["RMSE impr %"] for r in rows.values()]
    r2 = {p: r["R² impr %"] for p, r in rows.items()}
    ceil = [r["ceiling %"] for r in rows.values()]
    count = {c: sum(r["class"] == c for r in rows.values()) for c in CLASSES}
    over = [p for p, r in rows.items() if not r["within paper's R² max"]]
    return [
        {"paper's figure": "RMSE improvement, average", "paper": PAPER_AVG_IMPROVEMENT["rmse"],
         "reading": f"structure beyond a cubic ≈ {structure_ratio(35.27):.2f} × the scatter "
                    f"on average (ceiling relation)",
         "ours": f"{np.mean(gain):.1f} % (ceiling {np.nanmean(ceil):.1f} %)"},
        {"paper's figure": "RMSE improvement, maximum", "paper": PAPER_MAX_IMPROVEMENT["rmse"],
         "reading": f"one curve with structure {mx['n/σ_e']:.1f} × its scatter",
         "ours": f"{max(gain):.1f} % (ceiling up to {np.nanmax(ceil):.1f} %)"},
        {"paper's figure": "R² improvement, maximum", "paper": PAPER_MAX_IMPROVEMENT["r2"],
         "reading": f"with the RMSE maximum in one curve: the cubic leaves "
                    f"{mx['cubic share %']:.2f} % of the variance (R² {mx['cubic R²']:.3f}), "
                    f"trend {mx['trend/σ_e']:.0f} × the scatter; no curve above it",
         "ours": f"{max(r2.values()):.2f} %" + (f"; above the paper's: {', '.join(over)}"
                                                 if over else "")},
        {"paper's figure": "R² improvement, average", "paper": PAPER_AVG_IMPROVEMENT["r2"],
         "reading": f"carried by class b: {cb['R² impr %'][0]:.1f} % each, the cubic leaving "
                    f"{min(cb['cubic share %']):.1f}–{max(cb['cubic share %']):.1f} %, structure "
                    f"{cb['n/σ_e'][0]:.1f}–{cb['n/σ_e'][1]:.1f} and trend "
                    f"{cb['trend/σ_e'][0]:.0f}–{cb['trend/σ_e'][1]:.0f} × the scatter "
                    f"(at RMSE gains 55–80 %)",
         "ours": f"{np.mean(list(r2.values())):.2f} %"},
        {"paper's figure": "§4.2 classes of the 9 plotted curves (a / b / c)", "paper": "3 / 4 / 2",
         "reading": "; ".join(f"{k}: {v}" for k, v in CLASSES.items() if k != "d"),
         "ours": " / ".join(str(count[c]) for c in "abc") + f" (d: {count['d']}; all 15)"},
    ]


def readings(o, degree: int = 3) -> dict[str, dict[str, Any]]:
    """:func:`parameter_reading` of every paper parameter of a run (``o``: the recipe's
    :class:`~rlgsim.lab.studies.paper000_config.Outcome`)."""
    from rlgsim.estimators.calibration import PAPER_PARAMETERS
    return {p: parameter_reading(o.xs[p], o.ys[p], o.raw.column(f"{p}_true")[o.ok],
                                 o.pred[p]["hho_rvr"], o.pred[p]["lsm"], degree)
            for p in PAPER_PARAMETERS}


def add_section(rep, o, degree: int = 3) -> None:
    """The report's section: the verdict, one row per parameter, one per class."""
    from rlgsim.lab.report import Table
    rows = readings(o, degree)
    rep.heading("Reading the paper's summary numbers: shapes and classes (issue 27)", 2)
    rep.paragraph(summary_text(rows))
    rep.table(Table.from_records(
        "The paper's surviving figures (Table 2, §4.2), what they imply, ours", paper_table(rows),
        csv_name="paper_reading.csv",
        note="In-sample, both. Improvements as the paper counts them (R² relative to the "
             "LSM's). Class b's row assumes the other eleven curves add ≤ 0.1 % each to the "
             "R² average (as every accelerometer parameter of ours)."))
    rep.table(Table.from_records(
        "Per parameter: scatter, structure beyond a cubic, the share a cubic leaves, class",
        [{"parameter": p, **r} for p, r in rows.items()], csv_name="shapes_reading.csv",
        note=f"σ_e: std of calibration estimate − true window mean; n: std of the truth minus "
             f"its own least-squares cubic; ceiling: the RMSE improvement of a model that "
             f"follows the truth, 1 − σ_e/√(σ_e² + n²); trend/σ_e: std of the cubic fit over "
             f"σ_e; cubic share: RMSE_LSM²/Var (1 − R²_LSM). Class (§4.2): dispersion plain "
             f"when the cubic share ≥ {100 * DISPERSION_SHARE:g} %, structure plain when "
             f"n/σ_e ≥ {STRUCTURE_RATIO:g} (judgements; paper000_reading.py)."))
    rep.table(Table.from_records(
        "Per class of §4.2: ours (the paper plots 3 of class a, 4 of b, 2 of c; which "
        "parameters its text does not say)", class_summary(rows), csv_name="shapes_classes.csv"))
