"""Which terms of a law does the recording support? Best-subset selection by the Bayesian
information criterion, then a joint refinement with uncertainties.

A law is ``y ≈ β₀ + Σ_t β_t·f_t(θ_t)``: each candidate term ``t`` is one feature column that may
depend on a few nonlinear parameters ``θ_t`` (a knee's centre and width, a step's), with a grid
of starting values. Criterion (Schwarz 1978):

    BIC = n·ln(SSR/n) + k·ln n,     k = 1 + (number of terms) + (nonlinear parameters)

Linear terms: every subset of up to ``max_linear`` candidates is fitted (least squares) and the
one of lowest BIC kept — not forward selection, because the thermal features of a gyro are
strongly collinear (a temperature rate, the gradients a ramp drives, the UHFO that follows
both) and a greedy first step then locks in a stand-in for the true term. Nonlinear terms are
added one at a time on top (each at the best θ of its grid, polished with the linear
coefficients profiled out — variable projection, Golub & Pereyra 1973), the linear subset
re-chosen after each, while the BIC falls. The nonlinear parameters count in ``k``, so a knee
is only chosen when it pays for its centre and width. (An effective sample size from the
residual autocorrelation was tried in the BIC and rejected: the residual of an incomplete law
is smooth, so it shrinks n until no missing term can enter.)

Selection uncertainty (Buckland, Burnham & Augustin 1997; Hoeting et al. 1999; quasi-likelihood
criteria with an overdispersion ĉ, Burnham & Anderson 2002 §6.2): when rate and the gradients a
ramp drives are nearly the same signal, several subsets have nearly the same BIC and the chosen
one is a coin toss whose coefficients are not the physical ones. With the nonlinear terms of the
choice held, every linear subset (up to ``max_linear``) gets the weight
``w ∝ exp(−QAIC/2)``, ``QAIC = n·ln(SSR/n)/ĉ + 2k`` (Akaike weights, :data:`AVERAGING_PENALTY`;
ĉ ≥ 1 the batch-means long-run / independent variance ratio of the chosen model's residual:
windows carrying flicker hold fewer independent pieces of information than their count). Reported for every linear candidate: the
model-averaged coefficient ``Σ w_S β_S`` (0 where the term is out), its standard error
``√Σ w_S (se_S² + (β_S − β̄)²)`` (each ``se_S`` the batch-means sandwich of subset S) and its
inclusion probability ``Σ_{S∋t} w_S``; :meth:`SelectedLaw.predict` averages predictions the
same way. Terms whose inclusion is undecided (between 5 % and 95 %) are grouped with the
candidates whose window features they nearly repeat (|r| ≥ 0.9 after the chosen model's other
terms are removed) as ``unseparable``, each group with a one-line reason naming the programme
feature that would separate it. The variance inflation factors of the chosen terms are
``vif``. A subset in which a term's variance inflation factor exceeds :data:`MAX_VIF` (100,
partial |r| ≈ 0.995) is neither selected nor averaged: two terms that nearly repeat each other
get huge opposite coefficients there, which extrapolate wildly to another programme (their
difference is then what the recording cannot determine, and the group is named instead).

Refinement: every coefficient and every nonlinear parameter of the chosen terms are fitted
together by :func:`rlgsim.estimators.identify.lsq_stats.fit`, whose standard errors are
inflated for the residual autocorrelation (window series of a gyro bias carry flicker noise).

Generalised least squares: given the modelled covariance C of the target's noise
(``noise_cov``, e.g. :mod:`rlgsim.estimators.identify.window_noise` for the window means of a
gyro's flicker), everything above runs on the problem whitened by the Cholesky factor of C —
the BIC, the subset weights (ĉ then the whitened residual's variance per degree of freedom),
the variance inflation factors, the unseparable groups — and the standard errors are the
modelled ``(XᵀC⁻¹X)⁻¹`` instead of batch means.

Fixed regressors (``fixed``): linear columns that are in every model — e.g. the piecewise
offsets of detected mode hops (:mod:`rlgsim.lab.identify.hop_fit`) — are part of the base
beside the intercept: not selected, not counted in the BIC's comparison (every subset carries
them), refined jointly with the chosen terms (parameters named as the fixed terms) and held in
every averaged model (inclusion 1).

Combined effect of an unseparable group: the one thing the recording determines about it, the
law's dependence along the members' common direction in units of the most included member
(:func:`_combined`), with a model-averaged standard error.

Stand-ins: how the combined effect splits among a group's members is *not* determined, and the
subset weights above do not express that — they concentrate on whichever member the noise
favoured, so the members' averaged coefficients and the law's prediction on another programme
(where the members no longer follow each other) covered the truth too rarely. Each member ``h``
alone carrying the combined effect (coefficient ``b_h``, :func:`_standins`) is a law the
recording cannot tell from the others; they are taken as equally likely, since the recording
does not choose. A member's coefficient gets the variance of those splits about its averaged
value, ``mean_h (b_h·[g = h] − β̄_g)²``, added to its own; a prediction the variance of
``u_h = b_h·d_h`` about the averaged law's ``Σ β̄_g d_g`` (mean over the members), where
``d_h`` is the member's feature on the new programme less its regression, fitted on the
recording, on the intercept, the fixed and nonlinear terms, the chosen law's other terms and
the lead: zero where the new programme keeps the recording's relation between the members,
large where it breaks it. When the true law is a same-signed mixture of members, its prediction
lies inside the span of the stand-ins'.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

from rlgsim.estimators.identify.lsq_stats import LsqFit, fit

__all__ = ["Term", "SelectedLaw", "select_terms"]


@dataclass(frozen=True)
class Term:
    """A candidate term: ``name``; ``feature(theta) -> (n,)`` column; ``theta_names`` of its
    nonlinear parameters with a ``grid`` of starting values (list of arrays) and ``lower`` /
    ``upper`` bounds; a linear term has no theta."""

    name: str
    feature: Callable[[np.ndarray], np.ndarray]
    theta_names: tuple[str, ...] = ()
    grid: Sequence[np.ndarray] = field(default_factory=lambda: [np.zeros(0)])
    lower: Sequence[float] = ()
    upper: Sequence[float] = ()

    @property
    def k(self) -> int:
        return len(self.theta_names)


@dataclass(frozen=True)
class SelectedLaw:
    """The chosen ``terms``, the refined ``fit`` (parameters ``intercept``, ``<term>``,
    ``<term>.<theta>``), the selection ``steps`` (best linear subset of each size and each
    added nonlinear term, with its BIC) and the final ``bic``."""

    terms: tuple[str, ...]
    fit: LsqFit
    steps: tuple[tuple[str, float], ...]
    bic: float
    candidates: tuple[str, ...]
    #: {term or "intercept": (model-averaged value, its standard error, inclusion probability)}
    averaged: dict = field(default_factory=dict)
    #: ((terms, one-line reason), ...) groups the recording cannot separate
    unseparable: tuple = ()
    #: variance inflation factor of each chosen linear term; overdispersion ĉ of the weights
    vif: dict = field(default_factory=dict)
    c_hat: float = 1.0
    #: averaged models: (base names, subset, coefficients, covariance, weight)
    models: tuple = ()
    #: window residual of the refined law, prediction − target (not whitened)
    residual: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: True when fitted by generalised least squares with a modelled noise covariance
    gls: bool = False
    #: {unseparable group: (lead term, combined coefficient in its units, standard error,
    #: {member: slope on the lead})}
    combined: dict = field(default_factory=dict)
    #: names of the fixed regressors (in every model, not selected)
    fixed: tuple[str, ...] = ()
    #: {unseparable group: {member: (stand-in coefficient, regressor names, coefficients)}}:
    #: the member alone carrying the group's combined effect, and the member's feature
    #: regressed on the intercept, the fixed and nonlinear terms, the chosen law's other terms
    #: and the lead (:func:`_standins`)
    standins: dict = field(default_factory=dict)

    def value(self, name: str) -> float:
        return float(self.fit.x[self.fit.names.index(name)])

    def se(self, name: str) -> float:
        return float(self.fit.se[self.fit.names.index(name)])

    def predict(self, cols: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Model-averaged prediction and its standard error (selection included) from the
        feature columns ``cols`` {term: (m,)} (nonlinear terms at their chosen parameters)."""
        m = next(iter(cols.values())).shape[0]
        preds, vars_, ws = [], [], []
        for base, subset, beta, cov, w in self.models:
            X = np.column_stack([np.ones(m)] + [cols[c] for c in base[1:]]
                                + [cols[c] for c in subset])
            preds.append(X @ beta)
            vars_.append(np.einsum("ij,jk,ik->i", X, cov, X))
            ws.append(w)
        P, V, W = np.array(preds), np.array(vars_), np.array(ws)[:, None]
        mean = (W * P).sum(axis=0)
        var = (W * (V + (P - mean) ** 2)).sum(axis=0)
        return mean, np.sqrt(var + self.standin_variance(cols))

    def standin_variance(self, cols: dict[str, np.ndarray]) -> np.ndarray:
        """The prediction variance along the directions the recording cannot separate
        (module docstring, *Stand-ins*): for each unseparable group, the part of every member's
        feature on ``cols`` that its regression on the recording's other columns does not
        reproduce, ``d_h``; each member alone carrying the group's combined effect predicts
        ``u_h = b_h·d_h`` there, the averaged law ``ū = Σ β̄_g d_g``; the variance is the mean of
        ``(u_h − ū)²`` over the members (equal weights: the recording does not choose)."""
        m = next(iter(cols.values())).shape[0]
        out = np.zeros(m)
        for group, members in self.standins.items():
            d = {}
            for g, (_, names, coef) in members.items():
                fit_g = sum((np.ones(m) if n == "intercept" else np.asarray(cols[n], float)) * a
                            for n, a in zip(names, coef))
                d[g] = np.asarray(cols[g], dtype=float) - fit_g
            u_bar = sum(self.averaged[g][0] * d[g] for g in group)
            out = out + np.mean([(members[h][0] * d[h] - u_bar) ** 2 for h in group], axis=0)
        return out


def _bic(y: np.ndarray, X: np.ndarray, k_extra: int) -> float:
    """BIC of the least-squares fit of ``y`` on the columns of ``X`` (intercept included)."""
    beta = np.linalg.lstsq(X, y, rcond=None)[0]
    r = y - X @ beta
    n = y.size
    ssr = max(float(r @ r), 1e-300)
    return n * np.log(ssr / n) + (X.shape[1] + k_extra) * np.log(n)


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

#: largest variance inflation factor of a subset's terms (partial |r| ≈ 0.995): beyond it the
#: recording cannot tell the terms' coefficients apart and the subset is not considered
MAX_VIF = 100.0


def _without(v: np.ndarray, ones: np.ndarray) -> np.ndarray:
    """``v`` with its projection on the intercept column ``ones`` removed (centring, for an
    intercept of ones; the whitened intercept under generalised least squares)."""
    return v - ones * (float(v @ ones) / float(ones @ ones))


def _corr_matrix(lcols: dict, names: Sequence[str], ones: np.ndarray) -> dict:
    if not names:
        return {"names": [], "R": np.zeros((0, 0))}
    Z = np.column_stack([_without(lcols[c], ones) for c in names])
    Z = Z / np.linalg.norm(Z, axis=0)
    return {"names": list(names), "R": Z.T @ Z}


def _conditioned(R: dict, combo: Sequence[str]) -> bool:
    """All variance inflation factors of the subset ``combo`` at most :data:`MAX_VIF`."""
    if len(combo) < 2:
        return True
    idx = [R["names"].index(c) for c in combo]
    sub = R["R"][np.ix_(idx, idx)]
    try:
        vif = np.diag(np.linalg.inv(sub))
    except np.linalg.LinAlgError:
        return False
    return bool(np.all(np.isfinite(vif)) and np.all(vif <= MAX_VIF))


def _averaging(y, base, base_names, lin_names, lcols, chosen_lin, max_linear, batches,
               gls=False):
    """Selection uncertainty of the linear subset (module docstring)."""
    n = y.size
    R = _corr_matrix(lcols, lin_names, base[:, 0])
    Xb = np.column_stack([base] + [lcols[c] for c in chosen_lin])
    _, _, r_best = _ols(y, Xb, batches, gls)
    c_hat = _overdispersion(r_best, batches, gls, Xb.shape[1])
    fits = []
    for size in range(0, min(max_linear, len(lin_names)) + 1):
        for combo in itertools.combinations(lin_names, size):
            if not _conditioned(R, combo):
                continue
            X = np.column_stack([base] + [lcols[c] for c in combo])
            beta = np.linalg.lstsq(X, y, rcond=None)[0]
            ssr = max(float(np.sum((y - X @ beta) ** 2)), 1e-300)
            fits.append((n * np.log(ssr / n) / c_hat + X.shape[1] * AVERAGING_PENALTY, combo))
    q = np.array([f[0] for f in fits])
    w = np.exp(-(q - q.min()) / 2.0)
    w /= w.sum()
    order = np.argsort(-w)
    keep = order[np.cumsum(w[order]) <= 1 - 1e-4 + 1e-12]
    keep = order[:max(keep.size + 1, 1)][:1000]
    wk = w[keep] / w[keep].sum()
    models = []
    for i, wi in zip(keep, wk):
        combo = fits[i][1]
        X = np.column_stack([base] + [lcols[c] for c in combo])
        beta, cov, _ = _ols(y, X, batches, gls)
        models.append((tuple(base_names), tuple(combo), beta, cov, float(wi)))
    averaged = {}
    for name in list(base_names) + list(lin_names):
        vals, vars_, ws = [], [], []
        for bn, combo, beta, cov, wi in models:
            names = list(bn) + list(combo)
            if name in names:
                j = names.index(name)
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
    # unseparable groups: undecided terms with the candidates whose features they repeat
    undecided = [c for c in lin_names if 0.05 < averaged[c][2] < 0.95]
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
    groups: list[tuple[tuple[str, ...], str]] = []
    combined: dict = {}
    standins: dict = {}
    seen: set[str] = set()
    for c in undecided:                     # connected groups of terms that repeat each other
        if c in seen or not edges[c]:
            continue
        group, todo, pairs = [], [c], {}
        while todo:
            a = todo.pop()
            if a in group:
                continue
            group.append(a)
            for o, rr in edges[a]:
                pairs[tuple(sorted((a, o)))] = rr
                todo.append(o)
        group = [g for g in lin_names if g in group]
        seen.update(group)
        corr = ", ".join(f"{a}/{b} {rr:+.3f}" for (a, b), rr in pairs.items())
        incl = ", ".join(f"{g} {averaged[g][2]:.2f}" for g in group)
        lead, value, se, slopes = _combined(group, averaged, base, lcols, chosen_lin, models)
        combined[tuple(group)] = (lead, value, se, slopes)
        standins[tuple(group)] = _standins(group, lead, value, base, base_names, lcols,
                                           chosen_lin)
        for g in group:              # the member's coefficient over the stand-in splits
            v, se_g, p = averaged[g]
            hyp = [standins[tuple(group)][g][0] if h == g else 0.0 for h in group]
            averaged[g] = (v, float(np.sqrt(se_g ** 2 + np.mean((np.array(hyp) - v) ** 2))), p)
        per = ", ".join(f"{g} × {slopes[g]:.3g}" for g in group if g != lead)
        groups.append((tuple(group), (
            f"{', '.join(group)} cannot be separated by this recording (correlation of their "
            f"window features after the other chosen terms: {corr}; inclusion probabilities "
            f"{incl}): their separate coefficients are not identified and are reported "
            f"model-averaged with the selection and the stand-in splits (each member alone "
            f"carrying the combined effect) in their standard errors; what the recording "
            f"does determine is their combined effect, in units of {lead}: {value:.4g} ± "
            f"{se:.2g} (standard error, selection included; {per} {lead}-equivalents); "
            f"{_separating_feature(group)} would separate them")))
    return averaged, tuple(groups), c_hat, tuple(models), combined, standins


def _standins(group, lead, value, base, base_names, lcols, chosen_lin) -> dict:
    """For each member ``h`` of an unseparable ``group``: the coefficient ``b_h`` with which
    ``h`` alone reproduces the combined effect ``value`` along the lead (least squares of
    ``value × lead`` on ``h``, both with the intercept, fixed and nonlinear columns and the
    chosen law's other terms removed; ``value`` for the lead itself), and the regression of
    ``h``'s feature on those columns and the lead — what the recording ties ``h`` to; on
    another programme, ``h`` less that regression is the direction the recording did not see
    (:meth:`SelectedLaw.standin_variance`). Columns whitened under GLS: the coefficients are
    GLS coefficients, valid on unwhitened features. Returns {member: (b_h, names, coef)}."""
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
    averaged over the models like a coefficient (mean, variance plus spread). Returns
    ``(lead, value, standard error, {member: slope})``."""
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
        ws.append(wi)
    v, s2, w = np.array(vals), np.array(vars_), np.array(ws)
    mean = float(w @ v)
    return lead, mean, float(np.sqrt(w @ (s2 + (v - mean) ** 2))), slopes


def _vif(base: np.ndarray, lcols: dict, chosen: list[str]) -> dict[str, float]:
    out = {}
    for c in chosen:
        Z = np.column_stack([base] + [lcols[k] for k in chosen if k != c])
        r = lcols[c] - Z @ np.linalg.lstsq(Z, lcols[c], rcond=None)[0]
        d = _without(lcols[c], base[:, 0])
        out[c] = float(d @ d / max(float(r @ r), 1e-300))
    return out


def _refine_theta(y: np.ndarray, base: np.ndarray, t: Term, th0: np.ndarray) -> np.ndarray:
    """Polish the nonlinear parameters of candidate ``t`` from ``th0`` with the linear
    coefficients profiled out (variable projection, Golub & Pereyra 1973)."""
    def resid(th: np.ndarray) -> np.ndarray:
        X = np.column_stack([base, np.asarray(t.feature(th), dtype=float)])
        return y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
    lo, hi = np.asarray(t.lower, dtype=float), np.asarray(t.upper, dtype=float)
    th0 = np.clip(th0, lo + 1e-9 * (1 + np.abs(lo)), hi - 1e-9 * (1 + np.abs(hi)))
    try:
        return least_squares(resid, th0, bounds=(lo, hi), method="trf", x_scale="jac",
                             max_nfev=60).x
    except ValueError:
        return th0


def jittered_cholesky(C: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor of the covariance ``C``, with a relative jitter (starting at
    1e-10 of the mean diagonal, ×100 per try, six tries) on the diagonal when ``C`` is
    numerically singular; ValueError when it is not positive definite even then."""
    from scipy.linalg import cholesky
    n = C.shape[0]
    jitter = 0.0
    for _ in range(6):
        try:
            return cholesky(C + jitter * np.eye(n), lower=True)
        except np.linalg.LinAlgError:
            jitter = max(jitter * 100.0, 1e-10 * float(np.mean(np.diag(C))))
    raise ValueError("the noise covariance is not positive definite")


def _whitener(noise_cov: np.ndarray | None, n: int) -> Callable[[np.ndarray], np.ndarray]:
    """``v ↦ L⁻¹v`` with ``L`` the Cholesky factor of ``noise_cov`` (:func:`jittered_cholesky`);
    the identity without one."""
    if noise_cov is None:
        return lambda v: v
    from scipy.linalg import solve_triangular
    C = np.asarray(noise_cov, dtype=float)
    if C.shape != (n, n):
        raise ValueError(f"noise_cov must be ({n}, {n}), got {C.shape}")
    L = jittered_cholesky(C)
    return lambda v: solve_triangular(L, np.asarray(v, dtype=float), lower=True)


def select_terms(y: np.ndarray, candidates: Sequence[Term], *, max_linear: int = 6,
                 batches: int = 8, noise_cov: np.ndarray | None = None,
                 fixed: Sequence[Term] = ()) -> SelectedLaw:
    """Choose terms by BIC (module docstring) and refine them jointly.

    ``fixed``: linear terms (no theta) carried in every model beside the intercept (module
    docstring); their names must differ from the candidates'.

    ``noise_cov``: the modelled (n, n) covariance of the target's noise (e.g. the window
    means of a gyro's flicker, :mod:`rlgsim.estimators.identify.window_noise`). With it every
    fit is generalised least squares (Aitken 1935): target, intercept and every feature are
    whitened by its Cholesky factor ``L`` (``L⁻¹y = L⁻¹Xβ + L⁻¹e``, independent unit-variance
    errors if the model holds), the BIC, the weights and the collinearity measures are those
    of the whitened problem, and the standard errors are the modelled ``(XᵀC⁻¹X)⁻¹`` (times the
    whitened residual's variance when above 1) instead of batch means, which cannot see noise
    slower than a batch."""
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or y.size < 3 or not np.all(np.isfinite(y)):
        raise ValueError("select_terms needs a finite 1-D target with at least 3 values")
    y_raw = y
    white = _whitener(noise_cov, y.size)
    gls = noise_cov is not None
    ones = white(np.ones_like(y))
    y = white(y)
    fixed_names = [t.name for t in fixed]
    if any(t.k for t in fixed) or set(fixed_names) & {t.name for t in candidates}:
        raise ValueError("fixed regressors must be linear terms named apart from the candidates")
    fcols = [white(np.asarray(t.feature(np.zeros(0)), dtype=float)) for t in fixed]
    lin = [t for t in candidates if not t.k]
    lcols = {t.name: np.asarray(t.feature(np.zeros(0)), dtype=float) for t in lin}
    lin = [t for t in lin if np.all(np.isfinite(lcols[t.name])) and np.ptp(lcols[t.name]) > 0]
    raw_features = {t.name: t.feature for t in candidates}
    if gls:
        lcols = {k: white(v) for k, v in lcols.items()}
        candidates = [Term(t.name, (lambda th, f=t.feature: white(f(th))), t.theta_names,
                           t.grid, t.lower, t.upper) for t in candidates]
        lin = [next(c for c in candidates if c.name == t.name) for t in lin]
    nonlin = [t for t in candidates if t.k]
    # a column that repeats an earlier one exactly (two gradients of a symmetric twin: A−D and
    # A−E with D, E mirror nodes) carries nothing new: the earlier candidate stands for both
    unit = {}
    for t in list(lin):
        v = _without(lcols[t.name], ones)
        v = v / np.linalg.norm(v)
        if any(abs(float(v @ u)) > 1 - 1e-9 for u in unit.values()):
            lin.remove(t)
        else:
            unit[t.name] = v
    by_name = {t.name: t for t in candidates}
    steps: list[tuple[str, float]] = []

    R = _corr_matrix(lcols, [t.name for t in lin], ones)

    def best_subset(nl: list[np.ndarray], k_extra: int) -> tuple[float, list[str]]:
        base = np.column_stack([ones, *fcols, *nl])
        best = (_bic(y, base, k_extra), [])
        names = [t.name for t in lin]
        for size in range(1, min(max_linear, len(names)) + 1):
            best_k = None
            for combo in itertools.combinations(names, size):
                if not _conditioned(R, combo):
                    continue
                X = np.column_stack([base] + [lcols[c] for c in combo])
                b = _bic(y, X, k_extra)
                if best_k is None or b < best_k[0]:
                    best_k = (b, list(combo))
            if best_k is None:
                continue
            steps.append((" + ".join(best_k[1]), float(best_k[0])))
            if best_k[0] < best[0]:
                best = best_k
        return best

    nl_chosen: list[str] = []
    nl_cols: dict[str, np.ndarray] = {}
    theta: dict[str, np.ndarray] = {}
    bic, lin_chosen = best_subset([], 0)
    while True:
        base = np.column_stack([ones] + fcols + [nl_cols[c] for c in nl_chosen]
                               + [lcols[c] for c in lin_chosen])
        k_now = sum(by_name[c].k for c in nl_chosen)
        best = None
        for t in nonlin:
            if t.name in nl_chosen:
                continue
            for th in t.grid:
                col = np.asarray(t.feature(np.asarray(th, dtype=float)), dtype=float)
                if not np.all(np.isfinite(col)) or np.ptp(col) == 0:
                    continue
                b = _bic(y, np.column_stack([base, col]), k_now + t.k)
                if best is None or b < best[0]:
                    best = (b, t, np.asarray(th, dtype=float))
        if best is None:
            break
        t = best[1]
        th = _refine_theta(y, base, t, best[2])
        col = np.asarray(t.feature(th), dtype=float)
        b = _bic(y, np.column_stack([base, col]), k_now + t.k)
        if min(b, best[0]) >= bic:
            break
        if best[0] < b:
            th = best[2]
            col = np.asarray(t.feature(th), dtype=float)
        nl_chosen.append(t.name)
        nl_cols[t.name], theta[t.name] = col, th
        steps.append((f"+{t.name}", float(min(b, best[0]))))
        bic, lin_chosen = best_subset([nl_cols[c] for c in nl_chosen],
                                      sum(by_name[c].k for c in nl_chosen))
    chosen = [c for c in (t.name for t in candidates) if c in lin_chosen or c in nl_chosen]
    cols = {**lcols, **nl_cols, **dict(zip(fixed_names, fcols))}
    names = ["intercept"] + fixed_names + chosen
    nf = len(fixed_names)
    X0 = np.column_stack([ones] + fcols + [cols[c] for c in chosen])
    beta0 = np.linalg.lstsq(X0, y, rcond=None)[0]
    x0 = list(beta0)
    lo = [-np.inf] * len(x0)
    hi = [np.inf] * len(x0)
    for c in chosen:
        t = by_name[c]
        if not t.k:
            continue
        names += [f"{c}.{tn}" for tn in t.theta_names]
        x0 += list(theta[c])
        lo += list(t.lower)
        hi += list(t.upper)
    lo_a, hi_a = np.array(lo, dtype=float), np.array(hi, dtype=float)
    fin_lo, fin_hi = np.isfinite(lo_a), np.isfinite(hi_a)
    x0a = np.array(x0, dtype=float)
    x0a[fin_lo] = np.maximum(x0a[fin_lo], lo_a[fin_lo] + 1e-9 * (np.abs(lo_a[fin_lo]) + 1))
    x0a[fin_hi] = np.minimum(x0a[fin_hi], hi_a[fin_hi] - 1e-9 * (np.abs(hi_a[fin_hi]) + 1))

    def residual(x: np.ndarray) -> np.ndarray:
        pred = x[0] * ones
        for i, col in enumerate(fcols):
            pred = pred + x[1 + i] * col
        j = 1 + nf + len(chosen)
        for i, c in enumerate(chosen):
            t = by_name[c]
            th = x[j:j + t.k]
            j += t.k
            pred = pred + x[1 + nf + i] * (t.feature(th) if t.k else cols[c])
        return pred - y

    if not any(by_name[c].k for c in chosen):
        # linear: one solve, statistics from the same machinery
        res = fit(residual, x0a, names, bounds=(lo_a, hi_a), max_nfev=5, batches=batches,
                  whitened=gls)
    else:
        res = fit(residual, x0a, names, bounds=(lo_a, hi_a), batches=batches, whitened=gls)
    # the law's residual in the target's own units (not whitened)
    raw_pred = np.full_like(y_raw, res.x[0])
    for i, t in enumerate(fixed):
        raw_pred = raw_pred + res.x[1 + i] * np.asarray(t.feature(np.zeros(0)), dtype=float)
    j = 1 + nf + len(chosen)
    for i, c in enumerate(chosen):
        k = by_name[c].k
        raw_pred = raw_pred + res.x[1 + nf + i] * np.asarray(raw_features[c](res.x[j:j + k]),
                                                             dtype=float)
        j += k
    base = np.column_stack([ones] + fcols + [nl_cols[c] for c in nl_chosen])
    averaged, groups, c_hat, models, combined, standins = _averaging(
        y, base, ["intercept", *fixed_names, *nl_chosen], [t.name for t in lin], lcols,
        lin_chosen, max_linear, batches, gls)
    for name in nl_chosen:                     # held at the choice: its own refined values
        averaged[name] = (float(res.x[names.index(name)]), float(res.se[names.index(name)]), 1.0)
    return SelectedLaw(terms=tuple(chosen), fit=res, steps=tuple(steps), bic=float(bic),
                       candidates=tuple(t.name for t in candidates), averaged=averaged,
                       unseparable=groups, vif=_vif(base, lcols, lin_chosen), c_hat=c_hat,
                       models=models, residual=raw_pred - y_raw, gls=gls, combined=combined,
                       fixed=tuple(fixed_names), standins=standins)
