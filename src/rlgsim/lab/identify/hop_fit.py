"""Mode hops in a recording: bias steps the temperature law cannot explain, found, carried as
known regressors of the law fit, and mapped onto the simulator's mode-hop model for the twin
(docs/identify.md "Mode hops"; the model: :mod:`rlgsim.sim.sensors.anomalies`, docs/sensors.md
"Anomalies", eq. (A1)).

Detection (:func:`fit_hops`): on the 100 s window bias, under the generalised-least-squares
noise model of the law fit (white, flicker over the template's band, random walk, quantisation:
:mod:`rlgsim.estimators.identify.window_noise`), a likelihood-ratio step scan on the whitened
residual of the chosen law (:func:`rlgsim.estimators.identify.step_detection.detect_steps`)
at family false-alarm level :data:`HOP_ALPHA` per recording (Bonferroni over the candidate
positions). The found steps become fixed regressors of the law (piecewise offsets,
``select_terms(..., fixed=...)``), the law's terms are chosen again on the hop-free bias, the
scan runs again given the new law, until the set of steps no longer changes (at most
:data:`MAX_ROUNDS` rounds). Each hop's size and standard error are its coefficient in the final
generalised-least-squares law.

With a template mode-hop model, two more searches at level α/4 each (:func:`find_hops`): each
hop the template predicts, near where it predicts it; and the template's whole pattern as one
column over its lock point and κ (:func:`_pattern_search`), which finds hops at two mode levels
whose staircase the law's c1 term would otherwise absorb.

Where a found hop happened, its direction and the simulator's ``[anomalies.mode_hop]`` keys
mapped from the hops: :mod:`rlgsim.lab.identify.hop_mapping`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rlgsim.estimators.identify.step_detection import StepFit, detect_steps, step_columns
from rlgsim.estimators.identify.term_selection import SelectedLaw, Term, select_terms
from rlgsim.estimators.identify.whitening import jittered_cholesky
from rlgsim.lab.identify.node_names import node_column

__all__ = ["HOP_ALPHA", "Hop", "HopFit", "fit_hops", "find_hops", "hop_per_step", "hop_name"]

#: family false-alarm level of the hop scan per recording: the probability of one or more false
#: hops in a hop-free recording whose noise the model describes is at most 1 % (Bonferroni)
HOP_ALPHA = 0.01

#: rounds of (scan, refit the law with the found hops) before the set of hops is taken as it is
MAX_ROUNDS = 4

#: |T_c change| over ±10 min [K] below which a hop's direction is taken from its step's sign
STEADY_K = 0.05


def hop_name(i: int) -> str:
    """Name of the ``i``-th hop's regressor in the law (``hop1``, ``hop2``, …)."""
    return f"hop{i + 1}"


@dataclass(frozen=True)
class Hop:
    """One found hop: time [s] and its standard error, bias step [°/h] ± standard error and its
    z, the twin's ``T_c`` there [°C] ± standard error, ``direction`` +1 (mode up) / −1 (down),
    ``from_trend`` whether the direction came from the temperature trend, and the mode before
    it (the start mode is 0)."""

    time_s: float
    time_se_s: float
    size_deg_per_h: float
    size_se_deg_per_h: float
    z: float
    temperature_c: float
    temperature_se_c: float
    direction: int
    from_trend: bool
    mode_before: int


@dataclass
class HopFit:
    """The hops of a recording and what the twin gets from them (module docstring)."""

    hops: tuple[Hop, ...]
    threshold_z: float
    alpha: float
    candidates: int
    scan_max_z: float
    rounds: int
    nodes: tuple[str, ...]
    t_range_c: tuple[float, float]
    #: (index of the hop down, index of the hop up back to the same mode, width [K], se [K])
    pairs: tuple[tuple[int, int, float, float], ...] = ()
    #: the twin's ``[anomalies.mode_hop]`` (simulator keys) or None, comments per key
    mode_hop: dict | None = None
    comments: dict = field(default_factory=dict)
    #: one line per decision or what could not be mapped
    notes: list = field(default_factory=list)
    #: the mapped (or kept template) model's hops on the twin's T_c: (time [s], ±1)
    predicted: tuple[tuple[float, int], ...] = ()
    #: the template-guided search: (((z, threshold) per predicted hop searched), hops the
    #: template predicts, hops it found) or None without a template model
    pattern: tuple | None = None


def _law_design(sel: SelectedLaw, cands: list[Term], n: int) -> np.ndarray:
    """The chosen law's window columns (intercept first), nonlinear terms at their fit."""
    by = {t.name: t for t in cands}
    cols = [np.ones(n)]
    for t in sel.terms:
        th = np.array([sel.value(f"{t}.{tn}") for tn in by[t].theta_names])
        cols.append(np.asarray(by[t].feature(th), dtype=float))
    return np.column_stack(cols)


def _hop_terms(n: int, index: tuple[int, ...]) -> list[Term]:
    cols = step_columns(n, np.array(index, dtype=int))
    return [Term(hop_name(i), (lambda th, v=cols[:, i].copy(): v)) for i in range(len(index))]


def fit_hops(y: np.ndarray, cands: list[Term], cov: np.ndarray, *,
             alpha: float = HOP_ALPHA) -> tuple[StepFit, tuple[int, ...], int, SelectedLaw]:
    """The blind scan for hops of the window bias ``y`` under the noise covariance ``cov``
    (module docstring). The scan's law is the best subset of the *linear* candidates (chosen
    again with the hops found so far as fixed regressors, until the set of hops no longer
    changes): the nonlinear knee and step terms are sigmoids in temperature, and a hop pair
    is a sigmoid in temperature everywhere but inside its hysteresis loop — with them in the
    scan's law a pair is absorbed before it can be tested (seen: a 0.04 °/h pair taken as a
    knee). Returns the last scan, the hops' window indices (the first window after each), the
    number of rounds and the scan's linear law (the full law with the hops as fixed
    regressors is chosen by :func:`find_hops`)."""
    n = y.size
    lin = [c for c in cands if not c.k]
    index: tuple[int, ...] = ()
    rounds = 0
    sel_lin = select_terms(y, lin, noise_cov=cov)
    scan = detect_steps(y, _law_design(sel_lin, lin, n), cov, alpha=alpha)
    while rounds < MAX_ROUNDS and scan.index != index:
        rounds += 1
        index = scan.index
        sel_lin = select_terms(y, lin, noise_cov=cov, fixed=_hop_terms(n, index))
        scan = detect_steps(y, _law_design(sel_lin, lin, n), cov, alpha=alpha)
    return scan, index, rounds, sel_lin


def _t_stat(y: np.ndarray, X: np.ndarray, col: np.ndarray, L: np.ndarray
            ) -> tuple[float, float]:
    """z of the column ``col`` given ``X`` and its size's standard error."""
    from scipy.linalg import solve_triangular
    from rlgsim.estimators.identify.step_detection import _scan
    yw, Xw, cw = (solve_triangular(L, v, lower=True) for v in (y, X, col[:, None]))
    z, _, se, _ = _scan(yw, Xw, cw)
    return float(z[0]), float(se[0])


def find_hops(y: np.ndarray, cands: list[Term], cov: np.ndarray, sel: SelectedLaw,
              te: np.ndarray, window_s: float, t_s: np.ndarray, nodes_c: np.ndarray,
              node_names: tuple[str, ...], block: str, law_node: str, device: dict, *,
              alpha: float = HOP_ALPHA):
    """The hops of the window bias ``y`` (window end times ``te``): the blind scan
    (:func:`fit_hops`) at level α/2, then — when the device template has a mode-hop model — the
    template-guided test at level α/2 (module docstring), both given the linear law. Returns the law with the hops as
    fixed regressors, the blind scan, the hops' window indices, the rounds and the
    template-guided search ``(((z, threshold) per predicted hop not found blind), hops the
    template predicts, hops found by it)`` (None without a template model)."""
    from scipy.stats import norm
    n = y.size
    scan, idx, rounds, sel_lin = fit_hops(y, cands, cov, alpha=alpha / 2.0)
    lin = [c for c in cands if not c.k]
    template = (device.get("anomalies", {}) or {}).get("mode_hop")
    nodes = tc_nodes(device, law_node)
    tc = nodes_c[:, [node_column(block, nd, node_names) for nd in nodes]].mean(axis=1)
    t = np.asarray(t_s, dtype=float)
    pred = ([p for p in simulated_hops(template, nodes, t, nodes_c, node_names, block)]
            if template else [])
    if template:                        # the template's whole pattern, its lock point free
        pat = _pattern_search(y, lin, sel_lin, idx, cov, template, nodes, t, nodes_c,
                              node_names, block, te - window_s, alpha / 4.0)
        if pat:
            idx = tuple(sorted(set(idx) | set(pat)))
    if not pred:
        idx = _without_laws(idx, te, window_s, t, tc)
        if idx:
            sel = select_terms(y, cands, noise_cov=cov, fixed=_hop_terms(n, idx))
        return sel, scan, idx, rounds, (((), 0, 0) if template else None)
    # each predicted hop's local range: where T_c is within the template's unit-to-unit spread
    # of the predicted hop temperature, between the neighbouring predicted hops
    starts = te - window_s
    kappa = float(template["modes_per_k"])
    t_ref = float(template.get("reference_c", 20.0))
    rel = float(template.get("modes_per_k_rel", 0.0))
    phase = 0.5 / kappa if template.get("phase_per_unit", True) else 0.0
    local = []
    for h, (t_h, _) in enumerate(pred):
        T_h = float(np.interp(t_h, t, tc))
        dT = 2.0 * rel * abs(T_h - t_ref) + phase + 1.0
        lo = 0.5 * (pred[h - 1][0] + t_h) if h else -np.inf
        hi = 0.5 * (pred[h + 1][0] + t_h) if h + 1 < len(pred) else np.inf
        Tj = np.interp(starts, t, tc)
        ok = (np.abs(Tj - T_h) <= dT) & (starts > lo) & (starts < hi)
        ok[:2] = False
        ok[n - 1:] = False
        js = np.flatnonzero(ok)
        j0 = int(np.searchsorted(starts, t_h))
        local.append(js if js.size else np.array([min(max(j0, 2), n - 2)]))
    L = jittered_cholesky(np.asarray(cov, dtype=float))
    # a predicted hop whose range holds a hop the blind scan found is that hop
    todo = [h for h, js in enumerate(local) if not (set(js.tolist()) & set(idx))]
    found, zs = [], []
    for h in todo:
        X = np.column_stack([_law_design(sel_lin, lin, n)]
                            + [step_columns(n, np.array(list(idx) + found, dtype=int))])
        thr_h = float(norm.isf(alpha / (4.0 * len(todo) * max(local[h].size, 1))))
        zse = np.array([_t_stat(y, X, step_columns(n, np.array([j]))[:, 0], L)
                        for j in local[h]])
        z = zse[:, 0]
        k = int(np.argmax(np.abs(z)))
        zs.append((float(z[k]), thr_h, float(np.median(zse[:, 1]))))
        if abs(z[k]) >= thr_h:
            found.append(int(local[h][k]))
    idx = tuple(sorted(set(idx) | set(found)))
    idx = _without_laws(idx, te, window_s, t, tc)
    if idx:
        sel = select_terms(y, cands, noise_cov=cov, fixed=_hop_terms(n, idx))
    return sel, scan, idx, rounds, (tuple(zs), len(pred), len(found))


def _without_laws(idx: tuple[int, ...], te: np.ndarray, window_s: float, t: np.ndarray,
                  tc: np.ndarray) -> tuple[int, ...]:
    """``idx`` without the step pairs that are a temperature law, not hops: two consecutive
    steps back and forth (``T_c`` moving in opposite directions through them) whose hysteresis
    (the temperature of the one on heating minus that of the one on cooling) is not positive
    by two standard errors. A steep knee of the law is a step in time on every ramp through
    its centre, at the same temperature both ways; a mode hop pair has a loop (eq. (A1))."""
    def at(j):
        t_h = float(te[j] - window_s)
        lo, hi = float(te[j - 1] - window_s), float(te[j])
        T = float(np.interp(t_h, t, tc))
        se = abs(float(np.interp(hi, t, tc) - np.interp(lo, t, tc))) / math.sqrt(12.0)
        d = float(np.interp(t_h + 600.0, t, tc) - np.interp(t_h - 600.0, t, tc))
        return T, max(se, 0.05), (int(np.sign(d)) if abs(d) > STEADY_K else 0)
    keep = list(idx)
    changed = True
    while changed:
        changed = False
        for a in range(len(keep) - 1):
            (Ta, sa, da), (Tb, sb, db) = at(keep[a]), at(keep[b := a + 1])
            if da and db and da == -db:
                width = (Ta - Tb) if da > 0 else (Tb - Ta)
                if width <= 2.0 * math.hypot(sa, sb):
                    del keep[b], keep[a]
                    changed = True
                    break
    return tuple(keep)


def hop_per_step(t_s: np.ndarray, times_s: tuple[float, ...]) -> dict:
    """Per-step regressors {hop name: f(theta) -> 0 before the hop, 1 after} on the grid ``t_s`` (ends of
    the thermal steps); a hop time on a window boundary makes their window means the law's
    window columns exactly."""
    t = np.asarray(t_s, dtype=float)
    return {hop_name(i): (lambda th, v=(t > ts + 1e-9).astype(float): v)
            for i, ts in enumerate(times_s)}


def tc_nodes(device: dict, law_node: str) -> tuple[str, ...]:
    mh = (device.get("anomalies", {}) or {}).get("mode_hop")
    return tuple(mh["nodes"]) if mh and mh.get("nodes") else (law_node,)


def simulated_hops(mh: dict, nodes: tuple[str, ...], t_s: np.ndarray, nodes_c: np.ndarray,
                    node_names: tuple[str, ...], block: str) -> tuple[tuple[float, int], ...]:
    """The hops the simulator's own model ``mh`` (simulator keys) makes on the twin's node
    temperatures (:meth:`rlgsim.sim.sensors.anomalies.Anomalies.mode_hops`)."""
    from rlgsim.sim.sensors.anomalies import Anomalies
    from rlgsim.sim.sensors.anomaly_model import AnomalyModel, ModeHop
    model = AnomalyModel(mode_hop=ModeHop(
        nodes=tuple(nodes), modes_per_k=float(mh["modes_per_k"]),
        range_modes=float(mh["range_modes"]), reference_c=float(mh.get("reference_c", 20.0)),
        bias_step_deg_per_h=float(mh["bias_step_deg_per_h"])))
    an = Anomalies(model, node_names=node_names, gyro_axes=("gyro",),
                   gyro_blocks=(block or "",))
    state = an.initial_state(nodes_c[0])
    _, ev, _ = an.mode_hops(state, np.asarray(t_s, dtype=float), nodes_c)
    return tuple((float(t), 1 if k == "mode_hop_up" else -1)
                 for t, k in zip(ev.time_s, ev.kind))


#: lock points tried over one mode spacing by the pattern search (a template that draws it per
#: unit); the grid step 1/(κ·PHASES) is 0.5 K for κ = 0.05/K, below a window's T_c change on
#: a 1 °C/min ramp
PHASES = 40
#: windows either side within which a pattern's hop is the blind scan's hop, and over which a
#: pattern's hop is moved to its best position
NEAR = 2


def _pattern_search(y, lin, sel_lin, idx, cov, template, nodes, t, nodes_c, node_names,
                    block, starts, alpha) -> tuple[int, ...]:
    """The template's mode-hop model as one column — the mode level its hops give on the twin's
    T_c (:func:`simulated_hops`), each hop a unit step of its direction at the window
    boundary — tested given the linear law and the hops found so far, over the template's
    unspecified lock point (``reference_c`` moved over one mode spacing ``1/κ`` when
    ``phase_per_unit``, the simulator's draw) and κ at 1 and 1 ± 2·``modes_per_k_rel``; the
    largest |z| against the Bonferroni threshold over that grid at level ``alpha``. Hops at
    two mode levels make a staircase that follows the temperature, which the law's c1 term
    absorbs almost whole, so one step at a time falls below the threshold (docs/identify.md,
    *The template's pattern*); the pattern carries what the staircase does not share with the
    law — the hysteresis. Returns the window indices of the best pattern's hops when
    significant, else ()."""
    from scipy.stats import norm
    n = y.size
    kappa = float(template["modes_per_k"])
    rel = float(template.get("modes_per_k_rel", 0.0))
    t_ref = float(template.get("reference_c", 20.0))
    phases = (np.arange(PHASES) / PHASES - 0.5) / kappa if template.get(
        "phase_per_unit", True) else np.zeros(1)
    kappas = kappa * (np.array([1.0 - 2.0 * rel, 1.0, 1.0 + 2.0 * rel]) if 0 < rel < 0.5
                      else np.ones(1))
    X = np.column_stack([_law_design(sel_lin, lin, n)]
                        + ([step_columns(n, np.array(idx, dtype=int))] if idx else []))
    L = jittered_cholesky(np.asarray(cov, dtype=float))
    best, tried = None, set()
    for k in kappas:
        for ph in phases:
            mh = {**template, "modes_per_k": float(k), "reference_c": t_ref + float(ph)}
            js = tuple((int(np.searchsorted(starts, th)), d) for th, d in
                       simulated_hops(mh, nodes, t, nodes_c, node_names, block))
            js = tuple((j, d) for j, d in js
                       if 2 <= j <= n - 2 and all(abs(j - i) > NEAR for i in idx))
            if not js or js in tried:
                continue
            tried.add(js)
            col = sum(d * step_columns(n, np.array([j]))[:, 0] for j, d in js)
            z = float(_t_stat(y, X, col, L)[0])
            if best is None or abs(z) > abs(best[0]):
                best = (z, js)
    if best is None:
        return ()
    thr = float(norm.isf(alpha / (2.0 * len(tried))))
    if abs(best[0]) < thr:
        return ()
    # each hop of the pattern moved to where its own step fits best (±NEAR windows), the
    # others held: the grid places a hop only to within a window or two of the truth
    pos = [j for j, _ in best[1]]
    for h in range(len(pos)):
        others = [i for i in list(idx) + pos[:h] + pos[h + 1:]]
        Xh = np.column_stack([_law_design(sel_lin, lin, n)]
                             + ([step_columns(n, np.array(others, dtype=int))] if others else []))
        cand = [j for j in range(pos[h] - NEAR, pos[h] + NEAR + 1)
                if 2 <= j <= n - 2 and j not in others]
        zs = [abs(_t_stat(y, Xh, step_columns(n, np.array([j]))[:, 0], L)[0]) for j in cand]
        if zs:
            pos[h] = cand[int(np.argmax(zs))]
    return tuple(sorted(set(pos)))
