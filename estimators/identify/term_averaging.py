"""Selection uncertainty of a law's terms: model averaging over the linear subsets, the groups a
recording cannot separate, their combined effects and stand-ins (for
:func:`rlgsim.estimators.identify.term_selection.select_terms`, which fits the subsets
weighed here and calls :func:`averaging` on its choice).

Selection uncertainty (Buckland, Burnham & Augustin 1997; Hoeting et al. 1999; quasi-likelihood
criteria with an overdispersion ĉ, Burnham & Anderson 2002 §6.2): when rate and the gradients a
ramp drives are nearly the same signal, several subsets have nearly the same BIC and the chosen
one is a coin toss whose coefficients are not the physical ones. With the nonlinear terms of the
choice held, every linear subset (up to ``max_linear``) gets the weight
``w ∝ exp(−QAIC/2)``, ``QAIC = n·ln(SSR/n)/ĉ + 2k`` (Akaike weights, :data:`AVERAGING_PENALTY`;
ĉ ≥ 1 the batch-means long-run / independent variance ratio of the chosen model's residual:
windows carrying flicker hold fewer independent pieces of information than their count).
Reported for every linear candidate: the
model-averaged coefficient ``Σ w_S β_S`` (0 where the term is out), its standard error
``√Σ w_S (se_S² + (β_S − β̄)²)`` (each ``se_S`` the batch-means sandwich of subset S) and its
inclusion probability ``Σ_{S∋t} w_S``; :meth:`SelectedLaw.predict
<rlgsim.estimators.identify.term_selection.SelectedLaw.predict>` averages predictions the
same way. Terms whose inclusion is undecided (between 5 % and 95 %) are grouped with the
candidates whose window features they nearly repeat (|r| ≥ 0.9 after the chosen model's other
terms are removed) as ``unseparable``, each group with a one-line reason naming the programme
feature that would separate it. The variance inflation factors of the chosen terms are
``vif``. A subset in which a term's variance inflation factor exceeds ``MAX_VIF`` (100,
partial |r| ≈ 0.995; :mod:`rlgsim.estimators.identify.subset_conditioning`) is neither selected nor averaged: two terms that nearly repeat each other
get huge opposite coefficients there, which extrapolate wildly to another programme (their
difference is then what the recording cannot determine, and the group is named instead).

Combined effect of an unseparable group: the one thing the recording determines about it, the
law's dependence along the members' common direction in units of the most included member
(:func:`_combined`), averaged over the models that hold the group (at least one member), the
weights renormalised — the effect given that the group is in the law, reported beside the
group's inclusion probability. Averaging in the models without the group would put a point
mass at exactly 0 into the estimate: it shrinks the estimate towards 0 by the exclusion weight
and counts the estimate itself as spread, so where the truth is 0 the interval is too wide and
where it is not the estimate is biased — a model-averaged estimator with data-driven weights is
a nonlinear mixture whose ``β̄ ± z·se`` interval lacks the nominal coverage (Hjort & Claeskens,
JASA 98, 2003, §§4–5; Claeskens & Hjort, *Model Selection and Model Averaging*, 2008, ch. 7),
whereas within the models that estimate the effect it is an ordinary estimate. (Averaged
over every model: 87 % / 100 % of |z| below 1 / 2 over 20 coverage units.)

Stand-ins: how the combined effect splits among a group's members is *not* determined, and the
subset weights above do not express that — they concentrate on whichever member the noise
favoured, so the members' averaged coefficients and the law's prediction on another programme
(where the members no longer follow each other) covered the truth too rarely. Each member ``h``
alone carrying the combined effect (coefficient ``b_h``, :func:`_standins`) is a law the
recording cannot tell from the others; they are taken as equally likely, since the recording
does not choose. A member's coefficient gets the variance of those splits about its averaged
value, ``mean_h (b_h·[g = h] − β̄_g)²``, added to its own. (The prediction's band once added
the spread of the stand-ins' predictions on the new programme, equally weighted: too wide, 77 %
/ 95 % of |z| below 1 / 2 over 40 coverage units.)

Prediction band (:func:`_full_model`, :meth:`SelectedLaw.predict
<rlgsim.estimators.identify.term_selection.SelectedLaw.predict>`): the models' spread about the
averaged prediction plus, in place of each subset's own variance, that of the *full* model —
the chosen law's terms and every member of every unseparable group — ``x*ᵀ Σ_full x*``. Each
subset's own variance is computed as if its left-out members were known to be 0, which along
the direction the recording did not separate is exactly what is not known; the full model's
prediction is unbiased whichever split is true and its covariance carries the collinearity, so
its variance grows where the new programme leaves the recording's relation between the members
(Burnham & Anderson 2002 §4.3.2 and §6.3, the unconditional variance; the full model's variance
as the honest one around a model-averaged estimate: Hjort & Claeskens, JASA 98, 2003, §5).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from rlgsim.estimators.identify.subset_conditioning import passing
from rlgsim.estimators.identify.subset_fits import subset_ssr


#: programme features that separate a candidate from the others (for the refusal lines)
_SEPARATES = {"rate": "ramps at several rates", "uhfo": "UHFO changes at steady temperature",
              "c": "soaks at several temperatures", "gradient": "soaks long enough for the "
              "gradients to settle after each ramp"}


def _separating_feature(names: Sequence[str]) -> str:
    kinds = []
    for n in names:
        k = "gradient" if n.startswith("gradient") else "c" if n in (
            "c1", "c2", "c3", "knee", "step") else n
        if k in _SEPARATES and _SEPARATES[k] not in kinds:
            kinds.append(_SEPARATES[k])
    return " and ".join(kinds) or "a programme that moves them independently"


def _ols(y: np.ndarray, X: np.ndarray, batches: int, gls: bool = False
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coefficients, batch-means sandwich covariance (never below the independent-residual
    one) and residual of the least-squares fit of ``y`` on ``X``. ``gls``: ``y`` and ``X`` are
    whitened by the modelled noise covariance; the covariance is the modelled one,
    ``(XᵀX)⁻¹·max(1, s²)``."""
    from rlgsim.estimators.identify.lsq_stats import batch_means_covariance, covariance
    beta = np.linalg.lstsq(X, y, rcond=None)[0]
    r = y - X @ beta
    c0, s2 = covariance(X, r)
    if gls:
        return beta, c0 * (max(s2, 1.0) / s2 if s2 > 0 else 1.0), r
    c1 = batch_means_covariance(X, r, 1, batches)
    d0, d1 = np.sqrt(np.clip(np.diag(c0), 0, None)), np.sqrt(np.clip(np.diag(c1), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.where(d1 > 0, np.maximum(d0, d1) / d1, 1.0)
    return beta, c1 * np.outer(f, f), r


def _overdispersion(r: np.ndarray, batches: int, gls: bool = False, p: int = 0) -> float:
    """ĉ = long-run variance (batch means) / variance of a residual series, at least 1; for a
    whitened residual (``gls``) its variance per degree of freedom, at least 1."""
    if gls:
        r = np.asarray(r, dtype=float)
        return float(max(1.0, float(r @ r) / max(r.size - p, 1)))
    r = np.asarray(r, dtype=float) - np.mean(r)
    L = r.size // batches
    if L < 2:
        return 1.0
    bm = r[:L * batches].reshape(batches, L).mean(axis=1)
    return float(max(1.0, L * np.mean(bm ** 2) / max(np.mean(r ** 2), 1e-300)))


#: penalty per parameter of the model-averaging weights: Akaike's 2 (QAIC weights, Burnham &
#: Anderson 2002 §4.2 and §6.2), not the selection's ln n. BIC weights concentrate on the
#: smallest adequate subset — a two-term stand-in for a three-term law — and their averaged
#: coefficients and predictions covered the truth less often (coverage benchmark, 12 units:
#: model-averaged coefficients 42 % / 78 % of |z| below 1 / 2 with BIC weights, 53 % / 83 %
#: with Akaike weights; predictions on another programme 49 % / 81 % against 56 % / 83 %)
AVERAGING_PENALTY = 2.0


def without_intercept(v: np.ndarray, ones: np.ndarray) -> np.ndarray:
    """``v`` with its projection on the intercept column ``ones`` removed (centring, for an
    intercept of ones; the whitened intercept under generalised least squares)."""
    return v - ones * (float(v @ ones) / float(ones @ ones))


def corr_matrix(lcols: dict, names: Sequence[str], ones: np.ndarray) -> dict:
    if not names:
        return {"names": [], "R": np.zeros((0, 0))}
    Z = np.column_stack([without_intercept(lcols[c], ones) for c in names])
    Z = Z / np.linalg.norm(Z, axis=0)
    return {"names": list(names), "R": Z.T @ Z}


def _subset_weights(y: np.ndarray, base: np.ndarray, lin_names: Sequence[str], lcols: dict,
                    R: dict, c_hat: float, max_linear: int
                    ) -> tuple[list[tuple[str, ...]], np.ndarray]:
    """Every well-conditioned linear subset (up to ``max_linear`` of ``lin_names``) on top of
    ``base``, with its QAIC weight ``w ∝ exp(−QAIC/2)``; the subsets carrying all but 1e-4 of
    the weight (at most 1000, at least one), most weighty first: (subsets, renormalised
    weights). Which subsets pass: :func:`conditioned`, screened a size at once."""
    n, fits = y.size, []
    for size in range(0, min(max_linear, len(lin_names)) + 1):
        combos = passing(R, list(lin_names), size)
        ssr = np.maximum(subset_ssr(y, base, lcols, combos), 1e-300)   # a size at once
        fits += [(n * np.log(v / n) / c_hat + (base.shape[1] + size) * AVERAGING_PENALTY, c)
                 for v, c in zip(ssr.tolist(), combos)]
    q = np.array([f[0] for f in fits])
    w = np.exp(-(q - q.min()) / 2.0)
    w /= w.sum()
    order = np.argsort(-w)
    keep = order[np.cumsum(w[order]) <= 1 - 1e-4 + 1e-12]
    keep = order[:max(keep.size + 1, 1)][:1000]
    wk = w[keep] / w[keep].sum()
    return [fits[i][1] for i in keep], wk


def _average_coefficients(names: Sequence[str], models: list) -> dict:
    """{name: (model-averaged coefficient Σ w_S β_S, its standard error
    √Σ w_S (se_S² + (β_S − β̄)²), inclusion probability Σ_{S∋t} w_S)} over ``models``
    (base names, subset, coefficients, covariance, weight); 0 where a model leaves it out."""
    averaged = {}
    for name in names:
        vals, vars_, ws = [], [], []
        for bn, combo, beta, cov, wi in models:
            names_m = list(bn) + list(combo)
            if name in names_m:
                j = names_m.index(name)
                vals.append(beta[j])
                vars_.append(cov[j, j])
            else:
                vals.append(0.0)
                vars_.append(0.0)
            ws.append(wi)
        v, s2, ww = np.array(vals), np.array(vars_), np.array(ws)
        mean = float(ww @ v)
        incl = float(sum(wi for (bn, combo, _, _, wi) in models if name in bn or name in combo))
        averaged[name] = (mean, float(np.sqrt(ww @ (s2 + (v - mean) ** 2))), incl)
    return averaged


def _repeat_edges(undecided: list[str], lin_names: Sequence[str], base: np.ndarray, lcols: dict,
                  chosen_lin: Sequence[str]) -> dict:
    """{term: [(other, r), ...]}: the pairs of an undecided term and a chosen or undecided one
    whose window features correlate by |r| ≥ 0.9 once the chosen law's other terms and the
    base are removed (both directions listed)."""
    edges: dict[str, list[tuple[str, float]]] = {c: [] for c in lin_names}
    for c in undecided:
        for o in lin_names:
            if o == c or (o not in chosen_lin and o not in undecided):
                continue
            cols = [k for k in chosen_lin if k not in (c, o)]
            Z = np.column_stack([base] + [lcols[k] for k in cols])
            ra = lcols[c] - Z @ np.linalg.lstsq(Z, lcols[c], rcond=None)[0]
            rb = lcols[o] - Z @ np.linalg.lstsq(Z, lcols[o], rcond=None)[0]
            den = np.sqrt(float(ra @ ra) * float(rb @ rb))
            rr = float(ra @ rb) / den if den > 0 else 0.0
            if abs(rr) >= 0.9:
                edges[c].append((o, rr))
                edges[o].append((c, rr))
    return edges


def _connected(c: str, edges: dict, lin_names: Sequence[str]) -> tuple[list[str], dict]:
    """The group of terms connected to ``c`` through ``edges`` (in candidate order) and the
    correlation of each connected pair."""
    group, todo, pairs = [], [c], {}
    while todo:
        a = todo.pop()
        if a in group:
            continue
        group.append(a)
        for o, rr in edges[a]:
            pairs[tuple(sorted((a, o)))] = rr
            todo.append(o)
    return [g for g in lin_names if g in group], pairs


def _group_reason(group: list[str], pairs: dict, averaged: dict, lead: str, value: float,
                  se: float, slopes: dict, group_incl: float = 1.0) -> str:
    """The one-line reason of an unseparable group (its inclusion probabilities, correlations,
    combined effect and the programme feature that would separate it)."""
    corr = ", ".join(f"{a}/{b} {rr:+.3f}" for (a, b), rr in pairs.items())
    incl = ", ".join(f"{g} {averaged[g][2]:.2f}" for g in group)
    per = ", ".join(f"{g} × {slopes[g]:.3g}" for g in group if g != lead)
    return (f"{', '.join(group)} cannot be separated by this recording (correlation of their "
            f"window features after the other chosen terms: {corr}; inclusion probabilities "
            f"{incl}): their separate coefficients are not identified and are reported "
            f"model-averaged with the selection and the stand-in splits (each member alone "
            f"carrying the combined effect) in their standard errors; what the recording "
            f"does determine is their combined effect, in units of {lead}: {value:.4g} ± "
            f"{se:.2g} (standard error, selection included, given the group in the law — "
            f"probability {group_incl:.2f}; {per} {lead}-equivalents); "
            f"{_separating_feature(group)} would separate them")


def averaging(y: np.ndarray, base: np.ndarray, base_names: Sequence[str],
              lin_names: Sequence[str], lcols: dict, chosen_lin: Sequence[str], max_linear: int,
              batches: int, gls: bool = False) -> tuple:
    """Selection uncertainty of the linear subset (module docstring): (averaged, unseparable
    groups with their reasons, ĉ, averaged models, combined effects, stand-ins, the full model
    of the prediction band)."""
    R = corr_matrix(lcols, lin_names, base[:, 0])
    Xb = np.column_stack([base] + [lcols[c] for c in chosen_lin])
    _, _, r_best = _ols(y, Xb, batches, gls)
    c_hat = _overdispersion(r_best, batches, gls, Xb.shape[1])
    models = []
    for combo, wi in zip(*_subset_weights(y, base, lin_names, lcols, R, c_hat, max_linear)):
        X = np.column_stack([base] + [lcols[c] for c in combo])
        beta, cov, _ = _ols(y, X, batches, gls)
        models.append((tuple(base_names), tuple(combo), beta, cov, float(wi)))
    averaged = _average_coefficients(list(base_names) + list(lin_names), models)
    # unseparable groups: undecided terms with the candidates whose features they repeat
    undecided = [c for c in lin_names if 0.05 < averaged[c][2] < 0.95]
    edges = _repeat_edges(undecided, lin_names, base, lcols, chosen_lin)
    groups: list[tuple[tuple[str, ...], str]] = []
    combined: dict = {}
    standins: dict = {}
    seen: set[str] = set()
    for c in undecided:                     # connected groups of terms that repeat each other
        if c in seen or not edges[c]:
            continue
        group, pairs = _connected(c, edges, lin_names)
        seen.update(group)
        lead, value, se, slopes, value_all, incl = _combined(group, averaged, base, lcols,
                                                             chosen_lin, models)
        combined[tuple(group)] = (lead, value, se, slopes)
        # the stand-ins split the effect the averaged law carries (its excluding models
        # included), as the averaged coefficients they widen are
        standins[tuple(group)] = _standins(group, lead, value_all, base, base_names, lcols,
                                           chosen_lin)
        for g in group:              # the member's coefficient over the stand-in splits
            v, se_g, p = averaged[g]
            hyp = [standins[tuple(group)][g][0] if h == g else 0.0 for h in group]
            averaged[g] = (v, float(np.sqrt(se_g ** 2 + np.mean((np.array(hyp) - v) ** 2))), p)
        groups.append((tuple(group), _group_reason(group, pairs, averaged, lead, value, se,
                                                   slopes, incl)))
    return averaged, tuple(groups), c_hat, tuple(models), combined, standins, _full_model(
        y, base, base_names, lin_names, lcols, chosen_lin, groups, batches, gls)


def _full_model(y, base, base_names, lin_names, lcols, chosen_lin, groups, batches, gls
                ) -> tuple:
    """The model holding the chosen law's terms and every member of every unseparable group
    (module docstring, *Prediction band*): (base names, its linear terms, coefficients,
    covariance) — unbiased whichever split of a group's effect is true, its covariance
    carrying the collinearity along the directions the recording did not separate."""
    members = {g for group, _ in groups for g in group}
    terms = tuple(c for c in lin_names if c in chosen_lin or c in members)
    X = np.column_stack([base] + [lcols[c] for c in terms])
    beta, cov, _ = _ols(y, X, batches, gls)
    return tuple(base_names), terms, beta, cov


def _standins(group, lead, value, base, base_names, lcols, chosen_lin) -> dict:
    """For each member ``h`` of an unseparable ``group``: the coefficient ``b_h`` with which
    ``h`` alone reproduces the combined effect ``value`` along the lead (least squares of
    ``value × lead`` on ``h``, both with the intercept, fixed and nonlinear columns and the
    chosen law's other terms removed; ``value`` for the lead itself), and the regression of
    ``h``'s feature on those columns and the lead — what the recording ties ``h`` to; on
    another programme, ``h`` less that regression is the direction the recording did not see
    (the prediction band no longer uses it: :func:`_full_model`). Columns whitened under
    GLS: GLS coefficients, valid on unwhitened features. Returns {member: (b_h, names, coef)}."""
    others = [k for k in chosen_lin if k not in group]
    Z = np.column_stack([base] + [lcols[k] for k in others])
    names = tuple(base_names) + tuple(others)

    def part(c):
        return lcols[c] - Z @ np.linalg.lstsq(Z, lcols[c], rcond=None)[0]
    pl = part(lead)
    out = {}
    for h in group:
        if h == lead:
            out[h] = (float(value), names + (lead,), np.r_[np.zeros(Z.shape[1]), 1.0])
            continue
        ph = part(h)
        b = float(value) * float(ph @ pl) / max(float(ph @ ph), 1e-300)
        coef = np.linalg.lstsq(np.column_stack([Z, lcols[lead]]), lcols[h], rcond=None)[0]
        out[h] = (b, names + (lead,), coef)
    return out


def _combined(group, averaged, base, lcols, chosen_lin, models):
    """The combined effect of an unseparable ``group`` of linear terms: the law's dependence
    along the group's common direction, in units of its ``lead`` (the most often included)
    term. Each member's feature, with the chosen law's other terms and the intercept removed,
    is regressed on the lead's (slope ``s_i``, 1 for the lead); in every averaged model the
    combined coefficient is ``Σ β_i s_i`` over the members it holds, with variance ``sᵀ Σ_β s``;
    averaged like a coefficient (mean, variance plus spread) over the models holding at least
    one member, their weights renormalised (module docstring). Returns ``(lead, value, standard
    error, {member: slope}, value averaged over every model (0 where the group is out),
    inclusion probability of the group)``."""
    lead = max(group, key=lambda g: (averaged[g][2], -list(group).index(g)))
    others = [k for k in chosen_lin if k not in group]
    Z = np.column_stack([base] + [lcols[k] for k in others])

    def part(c):
        return lcols[c] - Z @ np.linalg.lstsq(Z, lcols[c], rcond=None)[0]
    rl = part(lead)
    slopes = {g: (1.0 if g == lead else float(part(g) @ rl) / max(float(rl @ rl), 1e-300))
              for g in group}
    vals, vars_, ws = [], [], []
    for bn, combo, beta, cov, wi in models:
        names = list(bn) + list(combo)
        idx = [names.index(g) for g in group if g in names]
        s = np.array([slopes[names[i]] for i in idx])
        vals.append(float(beta[idx] @ s) if idx else 0.0)
        vars_.append(float(s @ cov[np.ix_(idx, idx)] @ s) if idx else 0.0)
        ws.append(wi if idx else 0.0)
    v, s2, w = np.array(vals), np.array(vars_), np.array(ws)
    incl = float(w.sum())
    unconditional = float(w @ v)
    if incl <= 0:                            # no averaged model holds the group
        return lead, 0.0, 0.0, slopes, 0.0, 0.0
    w = w / incl
    mean = float(w @ v)
    return (lead, mean, float(np.sqrt(w @ (s2 + (v - mean) ** 2))), slopes, unconditional,
            incl)


def vif_of(base: np.ndarray, lcols: dict, chosen: list[str]) -> dict[str, float]:
    out = {}
    for c in chosen:
        Z = np.column_stack([base] + [lcols[k] for k in chosen if k != c])
        r = lcols[c] - Z @ np.linalg.lstsq(Z, lcols[c], rcond=None)[0]
        d = without_intercept(lcols[c], base[:, 0])
        out[c] = float(d @ d / max(float(r @ r), 1e-300))
    return out


