"""The scale factor and its temperature law from a recording's turntable rate segments — the
rate-table scale-factor test (IEEE Std 1431-2004 §§ on scale factor; IEEE Std 647-2006 §A.1
"scale factor") at the temperatures the chamber programme visits.

Measurement (the simulator's eq. 17, :mod:`rlgsim.sim.sensors.gyro`): the rate from the pulses through
the nominal scale factor K₀ is ``r = (1 + s)(ω + D) + n`` with ``s = (K(T) − K₀)/K₀`` the
scale-factor law in ppm (:mod:`rlgsim.sim.sensors.temperature_laws`, held per thermal step), ω the
true input on the gyro axis (table rate + Earth rate through the table attitude,
:mod:`.table_motion`), D the bias and n the noise. Over one constant-rate segment

    k = 10⁶ · (Σ r − Σ ω − Σ D̂) / Σ ω   [ppm]

estimates the ω-weighted mean of s over the segment's samples (``s·D`` is below 10⁻¹⁰ of ω),
with D̂ the fitted bias law (:mod:`.law_fit`, identified on the stationary windows only).
Segments at +ω and −ω at one temperature cancel the bias law's error, as the classic
reversal does. The candidate terms of the law are the simulator's family on the template's
node and ``t_ref_c``: ``c1``, ``c2`` (``c3`` when the template has it) and ``knee`` when the
template has one, at the template's centre and width (a handful of temperature levels cannot
place a knee); each is the ω-weighted mean of its per-step feature over the segment's samples,
so the fit sees exactly what the simulator applies.

Uncertainty: the covariance of the segment values is the gyro noise over each segment
(white, flicker, rate random walk and quantisation of the fitted Allan model, with the
template's flicker band: :mod:`rlgsim.estimators.identify.segment_noise`) plus the bias law's
error (its linear coefficients' covariance through the segment's features), both divided by
``ω̄_i ω̄_j``. The terms are chosen by BIC and refined by generalised least squares with that
covariance (:func:`rlgsim.estimators.identify.term_selection.select_terms`, as for the bias).

Refusals, each one line; the refused part keeps the template's value (its contribution is
taken off the segment values before the fit): no rate segment, fewer than
:data:`MIN_SEGMENTS`; a resolution of the constant (its standard error from the segments alone)
no better than half the template's unit-to-unit spread of ``value_ppm`` (1 ppm without one);
a temperature term the segments' temperature levels (:data:`LEVEL_K` apart) cannot support
(``c1``: 2 levels over :data:`MIN_SPAN_K`; ``c2``: 3; ``c3``: 4; ``knee``: 4 levels reaching
both sides of the knee's width).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rlgsim.estimators.identify.segment_noise import segment_covariance_from_fit
from rlgsim.estimators.identify.term_selection import SelectedLaw, Term, select_terms
from rlgsim.sim.sensors.gyro import pulses_per_arcsec
from rlgsim.lab.identify.law_fit import LawFit, _bias_extra, _flicker_band, _per_step
from rlgsim.lab.identify.node_names import node_column
from rlgsim.lab.identify.recording_data import RecordingData

__all__ = ["ScaleFactorFit", "fit_scale_factor", "scale_factor_table", "SF_KEYS",
           "MIN_SEGMENTS", "LEVEL_K", "MIN_SPAN_K"]

#: preset key of each term of the scale-factor law [ppm]
SF_KEYS = {"c1": "c1_ppm_per_k", "c2": "c2_ppm_per_k2", "c3": "c3_ppm_per_k3",
           "knee": "knee_ppm"}
#: fewest rate segments an identification uses (a ± pair and one more)
MIN_SEGMENTS = 3
#: segment temperatures closer than this [K] are one temperature level
LEVEL_K = 2.0
#: smallest span of the levels [K] for a temperature coefficient
MIN_SPAN_K = 5.0
#: levels a term needs
_LEVELS = {"c1": 2, "c2": 3, "c3": 4, "knee": 4}


@dataclass
class ScaleFactorFit:
    """The identified scale-factor law: ``law`` (the BIC-selected law of the terms the
    segments support, or None when refused), ``node``/``t_ref_c``, ``values`` {preset key:
    (value, standard error)} of what was identified (a supported term BIC left out is 0 and not
    listed), ``kept`` {term or "value": one-line reason it keeps the template's value},
    ``lines`` the one-line summary and refusals, the per-segment table ``segments`` (arrays:
    ``t0_s``, ``t1_s``, ``rate_deg_s`` on the gyro axis, ``temp_c`` at the law node,
    ``k_ppm``, ``se_ppm``, ``residual_ppm``), ``levels_c`` the temperature levels and
    ``resolution_ppm`` the constant's standard error from the segments alone."""

    law: SelectedLaw | None
    node: str
    t_ref_c: float
    values: dict[str, tuple[float, float]]
    kept: dict[str, str]
    lines: list[str]
    segments: dict[str, np.ndarray] = field(default_factory=dict)
    levels_c: tuple[float, ...] = ()
    resolution_ppm: float = float("nan")
    total_angle_deg: float = 0.0
    candidates: tuple[str, ...] = ()

    @property
    def identified(self) -> bool:
        return self.law is not None


def _levels(temps: np.ndarray) -> list[float]:
    """Temperature levels: the segment temperatures clustered by gaps above :data:`LEVEL_K`."""
    if temps.size == 0:
        return []
    t = np.sort(temps)
    cuts = np.flatnonzero(np.diff(t) > LEVEL_K) + 1
    return [float(np.mean(g)) for g in np.split(t, cuts)]


def _template_law(device: dict) -> tuple[dict, str, float]:
    gyro = device.get("gyro", {})
    law = dict(gyro.get("scale_factor", {}) or {})
    node = str(law.get("node", gyro.get("node", "A")))
    t_ref = float(law.get("t_ref_c", gyro.get("t_ref_c", 20.0)))
    return law, node, t_ref


def _features(T: np.ndarray, t_ref: float, law: dict) -> dict[str, np.ndarray]:
    """Per-step features of the scale-factor law's temperature terms (ppm per unit
    coefficient)."""
    x = T - t_ref
    out = {"c1": x, "c2": x ** 2, "c3": x ** 3}
    kc = float(law.get("knee_c", 25.0))
    kw = float(law.get("knee_width_k", 5.0))
    out["knee"] = np.tanh((T - kc) / kw)
    return out


def _bias_design(rec: RecordingData, nodes_c: np.ndarray, node_names: tuple[str, ...],
                 block: str, gyro: dict, laws: LawFit) -> tuple[np.ndarray, np.ndarray]:
    """The bias law's linear part per step, (m, p) columns of the intercept and its chosen
    terms at their fitted parameters, and the covariance of those coefficients (its error
    enters the segment covariance)."""
    bsel = laws.bias
    m = nodes_c.shape[0]
    bT = nodes_c[:, node_column(block, laws.bias_node, node_names)]
    blaw = dict(gyro.get("bias", {}))
    extra, _ = _bias_extra(rec, nodes_c, node_names, block, blaw, laws.bias_node, laws.u0_v)
    bfun = _per_step(bT, laws.t_ref_c, rec.step_s, extra)
    bcols = [np.ones(m)]
    for t in bsel.terms:
        th = np.array([bsel.value(n) for n in bsel.fit.names if n.startswith(f"{t}.")])
        bcols.append(np.asarray(bfun[t](th), dtype=float))
    bX = np.column_stack(bcols)                                       # (m, p)
    bidx = [bsel.fit.names.index(n) for n in ["intercept", *bsel.terms]]
    bcov = (bsel.fit.corr * np.outer(bsel.fit.se, bsel.fit.se))[np.ix_(bidx, bidx)]
    return bX, bcov


def _segment_rows(rec: RecordingData, laws: LawFit, T_step: np.ndarray, feats: dict,
                  bX: np.ndarray) -> list[dict]:
    """One row per powered constant-rate segment with finite rates: its scale-factor error
    k [ppm] (rate sum less the input and the bias law, over the input), its ω-weighted
    temperature and features, and the bias design's weighted rows ``bx``."""
    table = rec.motion
    per = max(1, int(round(rec.sample_rate_hz * rec.step_s)))   # gyro samples per thermal step
    m = T_step.size
    rows = []
    for (i0, i1), rate_s in zip(table.segments, table.segment_rate_deg_s):
        k = np.arange(i0, i1) // per
        if k[-1] >= m or np.any(rec.power[k] < 0.5):
            continue
        r = rec.rate_deg_per_h[i0:i1]
        if not np.all(np.isfinite(r)):
            continue
        w = table.input_deg_per_h[i0:i1]
        sw = float(w.sum())
        wk = np.bincount(k - k[0], weights=w)                 # ω-weight of each step
        ks = np.arange(k[0], k[-1] + 1)
        d_hat = float(np.bincount(k - k[0]) @ laws.per_step_bias_deg_per_h[ks])
        y = 1e6 * (float(r.sum()) - sw - d_hat) / sw
        row = {"i0": i0, "i1": i1, "rate": rate_s, "w_mean": sw / (i1 - i0), "k": y,
               "T": float(wk @ T_step[ks]) / sw,
               "bx": 1e6 * (np.bincount(k - k[0]) @ bX[ks]) / sw}
        for name, v in feats.items():
            row[name] = float(wk @ v[ks]) / sw
        rows.append(row)
    return rows


def _segment_covariance(rows: list[dict], laws: LawFit, device: dict, f: float,
                        bcov: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Segment starts and lengths [s], the covariance [ppm²] of their k (the noise model's,
    or the pulse quantisation alone without one, plus the bias law's error) and the
    resolution [ppm] of their common value."""
    n_s = len(rows)
    starts = np.array([r["i0"] for r in rows]) / f
    lengths = np.array([r["i1"] - r["i0"] for r in rows]) / f
    wbar = np.array([r["w_mean"] for r in rows])
    scale = 1e6 / wbar
    cov = np.zeros((n_s, n_s))
    if laws.noise is not None:
        band = _flicker_band(device)
        cov += segment_covariance_from_fit(laws.noise, starts, lengths, tau_min_s=band[0],
                                           tau_max_s=band[1], per_decade=band[2])
    cov *= np.outer(scale, scale)
    BX = np.array([r["bx"] for r in rows])
    cov += BX @ bcov @ BX.T
    # no noise model (its fit failed): the pulse quantisation alone, one pulse of 1/K₀ arcsec
    # uniform over Σω (2Q²/T² with Q² = q²/12)
    if not np.all(np.diag(cov) > 0):
        q = 1.0 / pulses_per_arcsec(device)
        cov[np.diag_indices(n_s)] += (scale * q / lengths) ** 2 / 6.0
    ones = np.ones(n_s)
    try:
        ci = np.linalg.solve(cov, ones)
        resolution = float(1.0 / np.sqrt(ones @ ci))
    except np.linalg.LinAlgError:
        resolution = float("nan")
    return starts, lengths, cov, resolution


def _supported_terms(family: list[str], levels: list[float], law: dict,
                     kept: dict[str, str]) -> list[str]:
    """The temperature terms the segments' levels support (enough levels, span, both sides of
    the knee); the others get their reason in ``kept``."""
    span = (max(levels) - min(levels)) if levels else 0.0
    free = []
    for t in family:
        ok = len(levels) >= _LEVELS[t] and span >= MIN_SPAN_K
        if t == "knee" and ok:
            kc, kw = float(law.get("knee_c", 25.0)), float(law.get("knee_width_k", 5.0))
            ok = min(levels) <= kc - kw and max(levels) >= kc + kw
        if ok:
            free.append(t)
        else:
            need = (f"{_LEVELS[t]} temperature levels ≥ {LEVEL_K:g} K apart spanning "
                    f"≥ {MIN_SPAN_K:g} K" + (f" and reaching both sides of the knee "
                                            f"({float(law.get('knee_c', 25.0)):g} ± "
                                            f"{float(law.get('knee_width_k', 5.0)):g} °C)"
                                            if t == "knee" else ""))
            kept[t] = (f"the rate segments lie at {len(levels)} temperature level(s) "
                       f"({', '.join(f'{v:.1f}' for v in levels)} °C); {t} needs {need}")
    return free


def _identify(base: ScaleFactorFit, rows: list[dict], y: np.ndarray, cov: np.ndarray,
              family: list[str], free: list[str], law: dict, levels: list[float],
              angle: float) -> ScaleFactorFit:
    """The law fitted on the segments (the refused terms at the template's values taken off
    first; the free ones chosen by BIC under the segment covariance), with its report
    lines."""
    y_fit = y.copy()
    for t in family:
        if t not in free:
            y_fit = y_fit - float(law.get(SF_KEYS[t], 0.0)) * np.array([r[t] for r in rows])
    cands = [Term(t, (lambda th, v=np.array([r[t] for r in rows]): v)) for t in free]
    sel = select_terms(y_fit, cands, noise_cov=cov)
    values = {"value_ppm": (sel.value("intercept"), sel.se("intercept"))}
    for t in sel.terms:
        values[SF_KEYS[t]] = (sel.value(t), sel.se(t))
    base.segments["residual_ppm"] = np.asarray(sel.residual, dtype=float)
    rates = sorted({round(abs(r["rate"]), 6) for r in rows})
    rate_txt = ", ".join(f"±{v:g}" for v in rates[:4]) + (" …" if len(rates) > 4 else "")
    where = (f"one temperature level ({levels[0]:.1f} °C)" if len(levels) == 1 else
             f"{len(levels)} temperature levels {min(levels):.1f}–{max(levels):.1f} °C")
    terms = (f"temperature terms chosen by BIC from {', '.join(free)}: "
             f"{', '.join(sel.terms) or 'none (a constant)'}" if free else
             "no temperature term identifiable (below)")
    base.lines.append(
        f"scale factor: identified from {len(rows)} turntable rate segments ({rate_txt} °/s on "
        f"the gyro axis, total {angle:.4g}°) at {where}: value {values['value_ppm'][0]:.4g} ± "
        f"{values['value_ppm'][1]:.2g} ppm; {terms}")
    for t, why in base.kept.items():
        base.lines.append(f"scale factor {t}: kept from the template — {why}")
    base.law = sel
    base.values = values
    return base


def fit_scale_factor(rec: RecordingData, nodes_c: np.ndarray, node_names: tuple[str, ...],
                     device: dict, laws: LawFit) -> ScaleFactorFit | None:
    """Identify the scale-factor law from the rate segments of ``rec`` (module docstring);
    None when the recording has no usable turntable motion."""
    if rec.motion is None:
        return None
    law, node, t_ref = _template_law(device)
    gyro = device.get("gyro", {})
    block = (gyro.get("blocks") or [""])[0]
    T_step = nodes_c[:, node_column(block, node, node_names)]
    feats = _features(T_step, t_ref, law)
    family = ["c1", "c2"] + [t for t in ("c3", "knee") if float(law.get(SF_KEYS[t], 0.0))]
    bX, bcov = _bias_design(rec, nodes_c, node_names, block, gyro, laws)
    rows = _segment_rows(rec, laws, T_step, feats, bX)
    lines: list[str] = []
    kept: dict[str, str] = {}
    tol = device.get("tolerance", {}).get("gyro", {}).get("scale_factor", {}) or {}
    target = 0.5 * float(tol.get("value_ppm", 2.0))
    if len(rows) < MIN_SEGMENTS:
        why = (f"the recording has turntable motion but only {len(rows)} powered constant-rate "
               f"segment(s) with a rate on the gyro axis; identifying it needs at least "
               f"{MIN_SEGMENTS} (rotations at + and − rate, at several temperatures)")
        kept["value"] = why
        lines.append(f"scale factor: kept from the template — {why}")
        return ScaleFactorFit(law=None, node=node, t_ref_c=t_ref, values={}, kept=kept,
                              lines=lines, candidates=tuple(family))
    starts, lengths, cov, resolution = _segment_covariance(rows, laws, device,
                                                           rec.sample_rate_hz, bcov)
    y = np.array([r["k"] for r in rows])
    temps = np.array([r["T"] for r in rows])
    angle = float(np.sum(np.abs(np.array([r["rate"] for r in rows])) * lengths))
    levels = _levels(temps)
    seg_tab = {"t0_s": starts, "t1_s": starts + lengths,
               "rate_deg_s": np.array([r["rate"] for r in rows]), "temp_c": temps, "k_ppm": y,
               "se_ppm": np.sqrt(np.diag(cov))}
    base = ScaleFactorFit(law=None, node=node, t_ref_c=t_ref, values={}, kept=kept,
                          lines=lines, segments=seg_tab, levels_c=tuple(levels),
                          resolution_ppm=resolution, total_angle_deg=angle,
                          candidates=tuple(family))
    if not resolution <= target:
        need = angle * (resolution / target) ** 2
        why = (f"the {len(rows)} rate segments (total turned angle {angle:.4g}°) resolve K − K₀ "
               f"only to ± {resolution:.3g} ppm, no better than half the template's "
               f"unit-to-unit spread ({2 * target:.3g} ppm); identifying it needs more or "
               f"faster rate segments, a total turned angle of about {need:.3g}° or more")
        kept["value"] = why
        lines.append(f"scale factor: kept from the template — {why}")
        return base
    free = _supported_terms(family, levels, law, kept)
    return _identify(base, rows, y, cov, family, free, law, levels, angle)


def scale_factor_table(template: dict, fit: ScaleFactorFit) -> tuple[dict, dict[str, str]]:
    """The ``[gyro.scale_factor]`` table of the twin and its comments {key: comment}: the
    identified value and chosen terms (standard errors in the comments), the refused terms at
    the template's values, the knee's centre and width the template's."""
    law = dict(template.get("gyro", {}).get("scale_factor", {}) or {})
    if fit.law is None:
        return law, {}
    out: dict = {}
    comments: dict[str, str] = {}
    for key in ("node", "t_ref_c"):
        if key in law:
            out[key] = law[key]
    out["value_ppm"] = fit.values["value_ppm"][0]
    comments["value_ppm"] = (f"fitted from {len(fit.segments['k_ppm'])} rate segments, standard "
                             f"error {fit.values['value_ppm'][1]:.3g}")
    avg = fit.law.averaged
    for t, key in SF_KEYS.items():
        if key in fit.values:
            out[key] = fit.values[key][0]
            comments[key] = f"fitted, standard error {fit.values[key][1]:.3g}; BIC-selected"
            if t in avg:
                v, se, p = avg[t]
                comments[key] += f"; model-averaged {v:.4g} ± {se:.2g} (inclusion {p:.2f})"
        elif t in fit.kept and key in law:
            out[key] = law[key]
            comments[key] = "kept from the template (the rate segments cannot identify it)"
    if "knee_ppm" in out:
        for key in ("knee_c", "knee_width_k"):
            if key in law:
                out[key] = law[key]
                comments[key] = "the template's (not fitted)"
    return out, comments
