"""Where the mode hops a recording shows happened, and the simulator's mode-hop model they map
onto (docs/identify.md "Mode hops"; the model: :mod:`rlgsim.sim.sensors.anomalies`,
docs/sensors.md "Anomalies", eq. (A1)). The hops themselves are found by
:mod:`rlgsim.lab.identify.hop_fit`.

Where and how (:func:`describe_hops`): the hop's time is the boundary between the two windows
the step falls between (it happened in the window before or the one after: standard error the
two windows' span / √12); its temperature is the twin's ``T_c`` there — the mean of the mode-hop
nodes of the device template's ``[anomalies.mode_hop]`` (the law node without one), on the
fitted network — with the standard error of ``T_c``'s change over that span / √12 (the twin's own
thermal error, the probe residual RMS of the report, comes on top). Direction: up (mode
``k → k + 1``) when ``T_c`` rises through the hop (over ±10 min), down when it falls; a hop at
a steady temperature takes its direction from the sign of its step against the others'.

Mapping onto the simulator's keys (eq. (A1), start mode 0, ``a = 1/κ``, ``b = T_ref``,
``c = R/(2κ)``): a hop up from mode ``m`` happens at ``T = b + m·a + c``, a hop down from mode
``m`` at ``T = b + m·a − c``; the hop temperatures give ``(a, b, c)`` by weighted least
squares. Hops at two mode levels determine all three; hops of both directions at one level (a
hysteresis pair) determine ``b`` and ``c`` with ``κ`` from the template (``1/κ``, the spacing of
the hop temperatures between successive modes, needs two levels); hops of one direction only
determine ``b`` with ``κ`` and ``R`` from the template. The bias step per mode ``Δb`` is the
weighted mean of ``direction × size``. The unit-to-unit spreads (``modes_per_k_rel``,
``bias_step_rel``) stay the template's; ``phase_per_unit = false`` (the lock point is what was
identified). The mapped model is then run through the simulator's own hop logic on the twin's
``T_c`` (:meth:`rlgsim.sim.sensors.anomalies.Anomalies.mode_hops`) and its hops compared with the found
ones (``predicted``).

Without a hop: the template's mode-hop model (if any) is run on the twin's ``T_c``; if it would
have hopped in this recording with a step the recording resolves — even the smallest a unit
within 2σ of the template's ``bias_step_rel`` has, at (threshold + 2) standard errors of a step
where it predicts the hops — it is contradicted and dropped, otherwise it is kept (not reached,
or below the detection limit).
"""

from __future__ import annotations

import math

import numpy as np

from rlgsim.estimators.identify.step_detection import StepFit
from rlgsim.estimators.identify.term_selection import SelectedLaw
from rlgsim.lab.identify.hop_fit import (HOP_ALPHA, STEADY_K, Hop, HopFit, simulated_hops,
                                         tc_nodes, hop_name)
from rlgsim.lab.identify.node_names import node_column

__all__ = ["KAPPA_GLASS", "describe_hops", "anomalies_table"]

#: mode spacings per kelvin without a template value: the glass alone of a 0.36 m Zerodur class-1
#: cavity, 0.36 m × 0.05·10⁻⁶/K / 632.8 nm ≈ 0.03 (docs/sensors.md "Anomalies")
KAPPA_GLASS = 0.03


def _hysteresis_pairs(hops: tuple[Hop, ...]) -> tuple[tuple[int, int, float, float], ...]:
    """Each hop and the next one back to the same mode: (index of the hop down, index of the
    hop up, width [K] = T_up − T_down, its standard error [K])."""
    pairs = []
    for a in range(len(hops) - 1):
        h, g = hops[a], hops[a + 1]
        if h.direction == -g.direction and g.mode_before == h.mode_before + h.direction:
            down, up = (h, g) if h.direction < 0 else (g, h)
            pairs.append((a if h.direction < 0 else a + 1, a + 1 if h.direction < 0 else a,
                          up.temperature_c - down.temperature_c,
                          math.hypot(up.temperature_se_c, down.temperature_se_c)))
    return tuple(pairs)


def _no_hop(out: HopFit, template: dict, pattern: tuple | None, pred: tuple) -> None:
    """No hop found with a template mode-hop model: contradicted (dropped) when the template's
    hops ``pred`` on the twin's T_c would have been resolved, else kept from the template, with
    the note and the comments that say which (module docstring, *Without a hop*)."""
    db_t = abs(float(template["bias_step_deg_per_h"]))
    # the smallest step a unit of the template plausibly has (2σ of its unit-to-unit spread)
    db_min = db_t * max(0.0, 1.0 - 2.0 * float(template.get("bias_step_rel", 0.0)))
    searched = pattern[0] if pattern else ()
    # would the template's hops have been seen? (found with ≥ 98 % probability at
    # |Δb| ≥ (threshold + 2) standard errors of a step there)
    seen = [db_min >= (thr + 2.0) * se for _, thr, se in searched]
    if pred and any(seen):
        out.notes.append(
            f"no hop found, but the template's mode-hop model would hop {len(pred)} time(s) "
            f"on the twin's T_c in this recording with a step (Δb {db_t:.3g} °/h, at least "
            f"{db_min:.3g} °/h for a unit within 2σ of the template's spread) this "
            f"recording resolves: the recording contradicts it, and the twin has no mode "
            f"hops")
    elif pred:
        lim = ", ".join(f"{(thr + 2.0) * se:.2g}" for _, thr, se in searched)
        out.mode_hop = dict(template)
        out.notes.append(
            f"no hop found; the template's mode-hop model would hop {len(pred)} time(s) on "
            f"the twin's T_c, but its step (Δb {db_t:.3g} °/h, as small as {db_min:.3g} °/h "
            f"for a unit within 2σ of the template's spread) is below what this recording "
            f"reliably detects there ((threshold + 2) × standard error: {lim} °/h): not "
            f"contradicted, "
            f"kept from the template, not identified")
        out.comments = {k: "kept from the template (not identified: its hops are below "
                           "this recording's detection limit)"
                        for k in template if k not in ("source", "nodes")}
    else:
        out.mode_hop = dict(template)
        out.notes.append(
            f"no hop found; the template's mode-hop model makes none on the twin's T_c "
            f"either (T_c {out.t_range_c[0]:.1f}–{out.t_range_c[1]:.1f} °C does not reach "
            f"its hop temperatures): kept from the template, not identified")
        out.comments = {k: "kept from the template (not identified: no hop recorded)"
                        for k in template if k not in ("source", "nodes")}


def describe_hops(sel: SelectedLaw, scan: StepFit, index: tuple[int, ...], rounds: int,
                  pattern, t_end_s: np.ndarray, window_s: float, t_s: np.ndarray, nodes_c: np.ndarray,
                  node_names: tuple[str, ...], block: str, law_node: str, device: dict
                  ) -> tuple[HopFit, tuple[float, ...]]:
    """The found hops with times, sizes, temperatures and directions, their hysteresis pairs
    and the twin's mode-hop table (module docstring). ``t_end_s`` are the end times of the
    windows the law was fitted on; returns the HopFit and the hop times [s]."""
    nodes = tc_nodes(device, law_node)
    idx = [node_column(block, nd, node_names) for nd in nodes]
    tc = nodes_c[:, idx].mean(axis=1)
    t = np.asarray(t_s, dtype=float)
    te = np.asarray(t_end_s, dtype=float)
    hops: list[Hop] = []
    times: list[float] = []
    raw = []
    for i, j in enumerate(index):
        t_hop = float(te[j] - window_s)                 # start of the first window after it
        lo, hi = float(te[j - 1] - window_s), float(te[j])
        T = float(np.interp(t_hop, t, tc))
        span = abs(float(np.interp(hi, t, tc) - np.interp(lo, t, tc)))
        trend = float(np.interp(t_hop + 600.0, t, tc) - np.interp(t_hop - 600.0, t, tc))
        name = hop_name(i)
        size, se = sel.value(name), sel.se(name)
        raw.append((t_hop, (hi - lo) / math.sqrt(12.0), size, se, T, span / math.sqrt(12.0),
                    trend))
        times.append(t_hop)
    # directions: the temperature trend, else the step's sign against the others' Δb
    d_trend = [int(np.sign(r[6])) if abs(r[6]) > STEADY_K else 0 for r in raw]
    known = [(d * r[2], r[3]) for d, r in zip(d_trend, raw) if d]
    w = np.array([1.0 / s ** 2 for _, s in known])
    db_sign = (np.sign(float(np.dot(w, [v for v, _ in known]))) if known
               else np.sign(raw[0][2]) if raw else 1.0) or 1.0
    mode = 0
    for r, d in zip(raw, d_trend):
        from_trend = d != 0
        if not d:
            d = int(np.sign(r[2]) * db_sign) or 1
        hops.append(Hop(time_s=r[0], time_se_s=r[1], size_deg_per_h=r[2], size_se_deg_per_h=r[3],
                        z=r[2] / r[3] if r[3] > 0 else float("inf"), temperature_c=r[4],
                        temperature_se_c=r[5], direction=d, from_trend=from_trend,
                        mode_before=mode))
        mode += d
    powered = np.isfinite(tc)
    out = HopFit(hops=tuple(hops), threshold_z=scan.threshold, alpha=HOP_ALPHA, pattern=pattern,
                 candidates=scan.candidates, scan_max_z=scan.scan_max_z, rounds=rounds,
                 nodes=nodes, t_range_c=(float(np.min(tc[powered])), float(np.max(tc[powered]))))
    out.pairs = _hysteresis_pairs(hops)
    template = (device.get("anomalies", {}) or {}).get("mode_hop")
    if hops:
        _map(out, template, float(tc[0]))
    elif template:
        _no_hop(out, template, pattern, simulated_hops(template, nodes, t, nodes_c, node_names,
                                                        block))
    if out.mode_hop is not None:
        out.predicted = simulated_hops(out.mode_hop, nodes, t, nodes_c, node_names, block)
    return out, tuple(times)


def _step_per_mode(out: HopFit) -> tuple[float, float]:
    """Δb [°/h] per mode, the weighted mean of direction × size over the hops, and its standard
    error; a note when the hops' steps scatter more than their errors allow (χ², 3σ)."""
    hops = out.hops
    v = np.array([h.direction * h.size_deg_per_h for h in hops])
    s = np.array([h.size_se_deg_per_h for h in hops])
    w = 1.0 / s ** 2
    db = float(w @ v / w.sum())
    db_se = float(1.0 / math.sqrt(w.sum()))
    chi2 = float(w @ (v - db) ** 2)
    if len(hops) > 1 and chi2 > len(hops) - 1 + 3 * math.sqrt(2 * (len(hops) - 1)):
        out.notes.append(f"the hops' steps per mode differ more than their standard errors "
                         f"allow (χ² {chi2:.1f} on {len(hops) - 1} degrees of freedom): one Δb "
                         f"per mode is an average")
    return db, db_se


def _hop_temperature_fit(hops: tuple[Hop, ...], template: dict | None, kappa_t: float
                         ) -> tuple[dict[str, float], dict[str, float], float, dict[str, float]]:
    """Weighted least squares of the hop temperatures ``T = b + m·a ± c`` (module docstring):
    the columns the hops determine are fitted, the others fixed (``a`` = 1/κ of the template
    or the glass; ``c`` from the template's range or 1.5 modes). Returns (values {b, a, c},
    variances {b, a, c}, cov(a, c), the fixed ones {name: value})."""
    T = np.array([h.temperature_c for h in hops])
    sT = np.array([max(h.temperature_se_c, 0.05) for h in hops])
    m = np.array([h.mode_before for h in hops], dtype=float)
    d = np.array([h.direction for h in hops], dtype=float)
    A = np.column_stack([np.ones_like(T), m, d])
    Wt = 1.0 / sT
    fixed: dict[str, float] = {}
    if np.linalg.matrix_rank(A) == 3:
        cols = [0, 1, 2]
    else:
        fixed["a"] = 1.0 / kappa_t
        cols = [0, 2]
        if np.linalg.matrix_rank(A[:, cols]) < 2:
            fixed["c"] = (float(template["range_modes"]) / (2 * kappa_t) if template
                          else 1.5 / (2 * kappa_t))
            cols = [0]
    rhs = T - sum(A[:, k] * fixed[nm] for k, nm in ((1, "a"), (2, "c")) if nm in fixed)
    Aw = A[:, cols] * Wt[:, None]
    est, *_ = np.linalg.lstsq(Aw, rhs * Wt, rcond=None)
    cov = np.linalg.pinv(Aw.T @ Aw)
    dof = len(hops) - len(cols)
    if dof > 0:
        r = (rhs - A[:, cols] @ est) * Wt
        cov = cov * max(1.0, float(r @ r) / dof)
    full = {"b": 0.0, "a": fixed.get("a", 0.0), "c": fixed.get("c", 0.0)}
    var = {"b": 0.0, "a": 0.0, "c": 0.0}
    cv_ac = 0.0
    names = ["b", "a", "c"]
    for pos, k in enumerate(cols):
        full[names[k]] = float(est[pos])
        var[names[k]] = float(cov[pos, pos])
    if 1 in cols and 2 in cols:
        cv_ac = float(cov[cols.index(1), cols.index(2)])
    return full, var, cv_ac, fixed


def _mapped_notes(out: HopFit, how: dict, fixed: dict, kappa_t: float, kappa: float, b: float,
                  tc0: float) -> None:
    """The notes of a mapped model: the keys taken from elsewhere than the hops, and the mode
    the simulator will lock on at the start against the recorded unit's."""
    if "a" in fixed:
        out.notes.append(f"κ (modes_per_k) {how['a']} value {kappa_t:g} — its inverse is the "
                         f"spacing of the hop temperatures of successive modes, which needs hops "
                         f"at two mode levels")
    if "c" in fixed:
        out.notes.append(f"the control range (range_modes) {how['c']} — the hysteresis width "
                         f"needs a hop up and a hop down")
    k0 = round(kappa * (tc0 - b))
    if k0 != 0:
        out.notes.append(f"the simulator locks at the start on the mode nearest its centre, "
                         f"{k0:+d} for the mapped lock point (T_c {tc0:.2f} °C at the start, "
                         f"T_ref {b:.2f} °C): the twin starts {k0:+d} mode(s) from the recorded "
                         f"unit, its hops shift accordingly")


def _map(out: HopFit, template: dict | None, tc0: float) -> None:
    """The simulator's mode-hop keys from the found hops (module docstring), in place."""
    hops = out.hops
    kappa_t = float(template["modes_per_k"]) if template else KAPPA_GLASS
    src_k = "the template's" if template else "the glass estimate (docs/sensors.md)"
    db, db_se = _step_per_mode(out)
    full, var, cv_ac, fixed = _hop_temperature_fit(hops, template, kappa_t)
    a, b, c = full["a"], full["b"], full["c"]
    if a <= 0:
        out.notes.append(f"the hop temperatures give a non-positive mode spacing 1/κ = {a:.3g} K: "
                         f"not a mode-hop pattern; κ taken from {src_k} value")
        a = 1.0 / kappa_t
        var["a"] = 0.0
    kappa = 1.0 / a
    R = 2.0 * c / a
    kappa_se = math.sqrt(var["a"]) / a ** 2
    # R = 2c/a: gradient (−2c/a², 2/a)
    R_se = math.sqrt(max((2 * c / a ** 2) ** 2 * var["a"] + (2 / a) ** 2 * var["c"]
                         - 2 * (2 * c / a ** 2) * (2 / a) * cv_ac, 0.0))
    how = {"a": "fitted" if "a" not in fixed else f"not identified by hops at one mode level: "
                                                   f"{src_k}",
           "c": "fitted" if "c" not in fixed else "not identified by hops of one direction: "
                                                  + ("the template's" if template else
                                                     "assumed 1.5")}
    if R <= 1.0:
        out.notes.append(f"the hop temperatures give a control range R = {R:.3g} mode spacings "
                         f"(≤ 1: no hysteresis, the hop up below the hop down): not the "
                         f"simulator's mode-hop model; the hops stay in the law fit but the "
                         f"twin gets no mode hops")
        return
    mh = {"nodes": list(out.nodes), "modes_per_k": kappa, "range_modes": R,
          "reference_c": b, "bias_step_deg_per_h": db}
    if template:
        for k in ("modes_per_k_rel", "bias_step_rel"):
            if k in template:
                mh[k] = template[k]
    mh["phase_per_unit"] = False
    out.mode_hop = mh
    out.comments = {
        "modes_per_k": (f"{how['a']}, standard error {kappa_se:.2g}" if "a" not in fixed
                        else how["a"]),
        "range_modes": (f"fitted, standard error {R_se:.2g}" if "c" not in fixed
                        else how["c"]),
        "reference_c": f"fitted (lock point, start mode 0), standard error "
                       f"{math.sqrt(var['b']):.2g}",
        "bias_step_deg_per_h": f"fitted from {len(hops)} hop(s), standard error {db_se:.2g}",
        "phase_per_unit": "the lock point is the identified one",
    }
    for k in ("modes_per_k_rel", "bias_step_rel"):
        if k in mh:
            out.comments[k] = "unit-to-unit spread kept from the template (one unit recorded)"
    _mapped_notes(out, how, fixed, kappa_t, kappa, b, tc0)


def anomalies_table(template: dict | None, hops: HopFit | None, spikes
                    ) -> tuple[dict | None, dict[tuple, str]]:
    """The twin's ``[anomalies]`` table (simulator keys) and a comment per number: the mode
    hops and read-out spikes as identified (``hops``, ``spikes``:
    :class:`rlgsim.lab.identify.spike_fit.SpikeFit`), every other kind kept from the
    template's table."""
    out = {k: v for k, v in (template or {}).items()
           if k not in ("mode_hop", "pulse_spikes", "description", "source")}
    com: dict[tuple, str] = {}
    for k, v in out.items():
        if isinstance(v, dict):
            for key in v:
                com[("anomalies", k, key)] = "kept from the template (not identified)"
    if hops is not None and hops.mode_hop is not None:
        out["mode_hop"] = dict(hops.mode_hop)
        for key, text in hops.comments.items():
            com[("anomalies", "mode_hop", key)] = text
    elif hops is None and template and "mode_hop" in template:   # no search (no noise model)
        out["mode_hop"] = dict(template["mode_hop"])
        for key in out["mode_hop"]:
            com[("anomalies", "mode_hop", key)] = ("kept from the template (not searched: the "
                                                   "record is too short for a noise model)")
    if spikes is not None and spikes.max_pulses is not None:
        lo, hi = spikes.rate_ci95_per_h
        out["pulse_spikes"] = {"rate_per_h": spikes.rate_per_h, "max_pulses": spikes.max_pulses}
        com[("anomalies", "pulse_spikes", "rate_per_h")] = (
            f"{len(spikes.sizes)} spike(s) of ≥ {spikes.threshold_pulses} pulses in "
            f"{spikes.powered_h:.1f} powered h, scaled for the sizes below it; 95 % interval "
            f"[{lo:.3g}, {hi:.3g}] (exact Poisson)")
        com[("anomalies", "pulse_spikes", "max_pulses")] = "the largest spike seen"
    if not out:
        return None, {}
    out = {"description": "identified by rlgsim identify (mode hops, read-out spikes); other "
                          "kinds kept from the template", **out}
    return out, com
