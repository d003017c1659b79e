"""The rankings of the ``bias_compensation`` report (paper 001): the paper's ranking
(IR-LSSVM ≥ LSSVM > stepwise > LS; UHFO the strongest single input) checked against our numbers
claim by claim, by the paper's score and by the truth, and which mechanism of the simulated
device decides each. All text is generated from the numbers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rlgsim.lab.studies.bias_compensation_config import Config
from rlgsim.lab.studies.compensators import ORACLE, RAW
from rlgsim.lab.studies.fitting import Fitted
from rlgsim.lab.studies.report_text import anomaly_events, weight_spread
from rlgsim.lab.studies.runs import RunSeries


def rankings(config: Config, fitted: list[Fitted], sc: dict, n_train: int,
             train: list[RunSeries]) -> list[str]:
    """The paper's ranking (IR-LSSVM ≥ LSSVM > stepwise > LS; UHFO the strongest single
    input) checked against our numbers, claim by claim, by the paper's score and by the truth;
    with the train runs' labelled anomalies, which mechanism of the device decides each."""
    events = anomaly_events([rs.path for rs in train])
    spikes = [abs(e[2]) for e in events if e[1] == "pulse_spike"]
    hops = [e for e in events if e[1].startswith("mode_hop")]
    sco = _Scores(fitted, sc)
    raw, floor, truth = sco.raw, sco.floor, sco.truth
    out = [f"Reference points: raw bias stability {raw:.5f} °/h; the oracle (true "
           f"temperature law removed) reaches {floor:.5f} °/h — the flicker, random walk "
           f"and white noise that no input-driven model can remove. Differences between "
           f"compensators that are small against (raw − floor) = {raw - floor:.5f} °/h are "
           f"within what one realisation of that noise decides." if truth else
           f"Reference point: raw bias stability {raw:.5f} °/h. The test run is a "
           f"recording: no oracle floor, no truth; margins below are in % of the raw "
           f"bias stability."]
    out += _ladder(sco, config, n_train, train, spikes)
    singles = [(f.spec.inputs[0], f) for f in fitted
               if f.spec.kind == "polynomial" and len(f.spec.inputs) == 1]
    out += _single_inputs(sco, singles)
    out += _weights_and_uhfo(sco)
    out += _published_offsets(sco, config)
    if events:
        out.append(_mechanisms(train[0], spikes, hops, {f.spec.kind for f in fitted},
                               len(singles) >= 2))
    out.append("Nothing here was tuned to reproduce the paper's ranking: the device preset was "
               "fitted to the paper's Tables 1-2 (docs/sensors.md), the compensators use the "
               "settings in the study file, and the text above is generated from the numbers.")
    return out


@dataclass(frozen=True)
class _Scores:
    """The test run's scores of every fitted compensator, with the raw and oracle references
    (``floor`` 0 and ``truth`` False for a recorded test run, judged by the paper's score)."""

    fitted: list[Fitted]
    sc: dict

    @property
    def raw(self) -> float:
        return self.sc[RAW]["stability_after"]

    @property
    def truth(self) -> bool:
        return bool(np.isfinite(self.sc[ORACLE]["stability_after"]))

    @property
    def floor(self) -> float:
        return self.sc[ORACLE]["stability_after"] if self.truth else 0.0

    def best(self, kind: str, n_inputs: int | None = None) -> Fitted | None:
        cands = [f for f in self.fitted if f.spec.kind == kind
                 and (n_inputs is None or len(f.spec.inputs) == n_inputs)]
        return min(cands, key=lambda f: self.sc[f.spec.name]["stability_after"]) if cands \
            else None

    def s(self, f: Fitted, key: str = "stability_after") -> float:
        return self.sc[f.spec.name][key]


def _ladder(sco: _Scores, config: Config, n_train: int, train: list[RunSeries],
            spikes: list[float]) -> list[str]:
    """The paper's ladder IR-LSSVM ≥ LSSVM > stepwise > LS, pair by pair, with why."""
    out = []
    raw, floor, truth, best, s = sco.raw, sco.floor, sco.truth, sco.best, sco.s
    ladder = [("ir_lssvm", "IR-LSSVM"), ("lssvm", "LSSVM"), ("stepwise", "stepwise"),
              ("polynomial", "LS")]
    have = [(k, lab, best(k)) for k, lab in ladder if best(k) is not None]
    for (k1, l1, f1), (k2, l2, f2) in zip(have, have[1:]):
        a, b = s(f1), s(f2)
        ta, tb = s(f1, "resid_std_true"), s(f2, "resid_std_true")
        rel = "≥ (not worse than)" if k1 == "ir_lssvm" and k2 == "lssvm" else ">"
        margin = abs(a - b) / max(raw - floor, 1e-12) * 100
        tie = margin < 0.5
        holds = a <= b if rel.startswith("≥") else a < b
        truth_holds = ta <= tb
        text = (f"Paper: {l1} {rel} {l2}. Ours (best of each): {l1} {f1.spec.name!r} "
                f"{a:.5f} °/h vs {l2} {f2.spec.name!r} {b:.5f} °/h — "
                f"{'a tie' if tie else 'holds' if holds else 'does NOT hold'} by bias "
                f"stability (margin "
                f"{margin:.1f} % of raw − floor)"
                + (f"; by the truth (std of ŷ − b) {ta:.5f} vs {tb:.5f} °/h, "
                   f"{'holds' if truth_holds else 'does not hold'}." if truth else "."))
        if not tie and margin < 5 and not (k1 == "ir_lssvm" and k2 == "lssvm"):
            text += (" The margin is small enough for another realisation of the noise to "
                     "reverse it; a Monte Carlo over units tells how often it holds.")
        if k1 == "ir_lssvm" and k2 == "lssvm" and spikes:
            text += (f" Why: the train run{'s hold' if len(train) > 1 else ' holds'} "
                     f"{len(spikes)} read-out spikes (±{min(spikes, default=0):g} … "
                     f"{max(spikes, default=0):g} pulses in one sample: up to "
                     f"{max(spikes, default=0) * _deg_per_h_per_pulse(train[0], config):.4f} °/h "
                     f"in its {config.window_s:g} s window) — outliers the robust weights "
                     "down-weight, which the unweighted fit follows; re-weighting moves the "
                     f"all-input fit by {abs(a - b):.5f} °/h "
                     f"({abs(a - b) / max(raw - floor, 1e-12) * 100:.1f} % of raw − floor).")
        elif k1 == "ir_lssvm" and k2 == "lssvm":
            text += (" Why: the simulated bias noise is Gaussian (white + flicker + random "
                     "walk), without the gross outliers robust weights are built to reject, so "
                     "re-weighting can only trade ordinary tail samples; IR-LSSVM and LSSVM "
                     f"should differ by noise only (here by {abs(a - b):.5f} °/h, "
                     f"{abs(a - b) / max(raw - floor, 1e-12) * 100:.1f} % of raw − floor).")
        elif tie:
            text += " A tie is not the paper's strict ranking, nor its reversal."
        elif not holds and truth:
            la, lb = s(f1, "law_resid_std"), s(f2, "law_resid_std")
            text += (f" Why: by the truth, {l2}'s learnt law is "
                     f"{'closer to' if lb < la else 'as far from'} the true temperature law "
                     f"(law_resid_std {lb:.5f} vs {la:.5f} °/h). ")
            if k1 in ("lssvm", "ir_lssvm"):
                text += ("The simulated bias law (docs/sensors.md) is linear in dT/dt and UHFO "
                         "plus a linear term and a tanh knee in T (and steps at mode hops), "
                         "most of "
                         "which a second-order regression represents directly, while the kernel "
                         f"model has to learn its shape from {n_train} "
                         "auto-correlated windows that also carry the train run's "
                         "slow noise; the paper's gyro may hold non-linearities the simulator "
                         "lacks.")
            else:
                text += ("The extra terms the selection keeps fit the train run's noise as well "
                         "as its law.")
        out.append(text)
    return out


def _single_inputs(sco: _Scores, singles: list[tuple[str, Fitted]]) -> list[str]:
    """UHFO the strongest single input (LS cubic and IR-LSSVM single-input models)."""
    out = []
    truth, s, fitted = sco.truth, sco.s, sco.fitted
    if len(singles) >= 2:
        order = sorted(singles, key=lambda t: s(t[1]))
        strongest = order[0][0]
        listing = ", ".join(f"{name} {s(f):.5f}" for name, f in order)
        truth_order = sorted(singles, key=lambda t: s(t[1], "resid_std_true"))
        text = (f"Paper: UHFO is the strongest single input (LS: U 40.5 % > T 35.5 % > dT/dt "
                f"8.0 %). Ours, LS cubic bias stability after (°/h): {listing} — "
                f"{'holds' if strongest == 'U' else 'does NOT hold'} (strongest: "
                f"{strongest}" + (f"; by the truth: {truth_order[0][0]})." if truth else ")."))
        if strongest != "U":
            text += (" Why: in the simulated TRPLG the UHFO follows the discharge temperature "
                     "and its rate, plus a slow wander no thermometer sees; the bias law has a "
                     "UHFO term, but if the wander is small against the temperature-driven "
                     "part, the voltage carries little information beyond T.")
        out.append(text)
    irs = [(f.spec.inputs[0], f) for f in fitted
           if f.spec.kind == "ir_lssvm" and len(f.spec.inputs) == 1]
    if len({x for x, _ in irs}) >= 2:
        best_in: dict[str, float] = {}
        for name, f in irs:
            best_in[name] = min(best_in.get(name, np.inf), s(f))
        strongest = min(best_in, key=best_in.get)
        out.append("IR-LSSVM single inputs (best weight, °/h): "
                   + ", ".join(f"{k} {v:.5f}" for k, v in sorted(best_in.items(),
                                                                   key=lambda t: t[1]))
                   + f" — UHFO strongest {'holds' if strongest == 'U' else 'does NOT hold'}.")
    return out


def _weights_and_uhfo(sco: _Scores) -> list[str]:
    """The spread of the IR-LSSVM weight functions, and UHFO in the composite LS-SVM models."""
    out = []
    truth, s, fitted = sco.truth, sco.s, sco.fitted
    groups: dict[str, list[str]] = {}
    for f in fitted:
        if f.spec.kind == "ir_lssvm":
            groups.setdefault(", ".join(f.spec.inputs), []).append(f.spec.name)
    if any(len(v) > 1 for v in groups.values()):
        spread, where = weight_spread({f.spec.name: s(f) for f in fitted}, groups)
        out.append(f"IR-LSSVM weight functions: their bias stabilities differ by up to "
                   f"{spread:.1f} % within one input set ({where}; (max − min)/min); paper: up "
                   f"to 26 % (Table 4 dT/dt: Huber 0.01712 vs Hampel 0.01357 °/h).")
    multi = [f for f in fitted if f.spec.kind in ("ir_lssvm", "lssvm") and len(f.spec.inputs) > 1]
    with_u = [f for f in multi if "U" in f.spec.inputs]
    without_u = [f for f in multi if "U" not in f.spec.inputs]
    if with_u and without_u:
        fu = min(with_u, key=s)
        fn = min(without_u, key=s)
        holds = s(fu) < s(fn)
        out.append(f"Paper: UHFO improves the composite LS-SVM models (all inputs 61.19 % vs "
                   f"T, dT/dt 59.35 %). Ours: best with U {fu.spec.name!r} {s(fu):.5f} °/h vs "
                   f"best without U {fn.spec.name!r} {s(fn):.5f} °/h — "
                   f"{'holds' if holds else 'does NOT hold'}"
                   + (f"; by the truth {s(fu, 'resid_std_true'):.5f} vs "
                      f"{s(fn, 'resid_std_true'):.5f} °/h." if truth else "."))
    return out


def _published_offsets(sco: _Scores, config: Config) -> list[str]:
    """The improvements more than 5 points from the published ones, and why."""
    out = []
    raw, sc, fitted = sco.raw, sco.sc, sco.fitted
    off = []
    ratios = [sc[f.spec.name]["stability_after"] / f.spec.published["stability_deg_per_h"]
              for f in fitted if f.spec.published.get("stability_deg_per_h")]
    for f in fitted:
        pub = f.spec.published.get("improvement_pct")
        if pub is not None and abs(sc[f.spec.name]["improvement_pct"] - pub) > 5:
            off.append(f"{f.spec.name} {sc[f.spec.name]['improvement_pct']:.1f} % (paper "
                       f"{pub:.1f} %)")
    if off:
        out.append("Improvements more than 5 points from the published ones: " + "; ".join(off)
                   + f". Our raw stability on the test run is {raw:.5f} °/h against the "
                     f"paper's {config.published.get('stability_before', float('nan')):.5f}; "
                     "the percentages depend on how much slow noise one realisation holds"
                   + (f"; the compensated stabilities themselves are closer: ours / paper "
                      f"= {np.median(ratios):.2f} (median), {min(ratios):.2f} … "
                      f"{max(ratios):.2f}." if ratios else "."))
    return out


def _deg_per_h_per_pulse(rs: RunSeries, config: Config) -> float:
    """What one extra pulse does to its window's measured bias [°/h]."""
    k0 = next((v for k, v in rs.coefficients.items() if k.startswith("gyro.k0[")), np.nan)
    return float(np.degrees(1.0 / (k0 * config.window_s)) * 3600.0)


def _mechanisms(rs: RunSeries, spikes: list[float], hops: list, kinds: set[str],
                singles: bool) -> str:
    """Which mechanism of the simulated device decides each of the study's rankings (paper 001;
    the ablation in docs/studies.md switches each off and shows it), from the unit's drawn
    coefficients and the train run's labelled events."""
    c = rs.coefficients

    def coef(name: str) -> float:
        return next((abs(v) for k, v in c.items() if k.startswith(name + "[")), 0.0)
    parts = []
    if singles:
        wander = coef("gyro.bias.uhfo") * coef("uhfo.wander_v")
        parts.append("UHFO strongest — the discharge wander only UHFO sees (|uhfo coefficient| "
                     f"× wander = {wander:.4f} °/h, 1σ)")
    if {"stepwise", "polynomial"} <= kinds:
        parts.append(f"stepwise > LS — the rate term ({coef('gyro.bias.rate'):.4f} °/h per "
                     "°C/min) that no single-input LS model represents beside T or U"
                     + (", with the mode hops' heating/cooling difference widening the margin"
                        if hops else ""))
    if "stepwise" in kinds and kinds & {"lssvm", "ir_lssvm"}:
        hop_t = ", ".join(f"{e[0] / 3600:.1f} h" for e in hops)
        parts.append("LSSVM vs stepwise — no mechanism: what a second-order polynomial cannot "
                     f"follow, the cold knee ({coef('gyro.bias.knee'):.4f} °/h) and the mode-hop "
                     f"steps with hysteresis ({len(hops)} in the train run"
                     + (f", at {hop_t}" if hops else "") + "), is small against the noise: "
                     "whichever mechanism the paper-001 ablation switches off, the margin stays "
                     "within ±1.8 % of raw − floor")
    if {"lssvm", "ir_lssvm"} <= kinds:
        parts.append(f"IR-LSSVM vs LSSVM — the {len(spikes)} read-out spikes in the train "
                     "windows (without them the two tie)")
    return ("Which mechanism decides each ranking (docs/studies.md, paper 001 ablation: each "
            "mechanism switched off): " + "; ".join(parts) + ". The frequency-stabilisation "
            "heater, the one-sided airflow and the mounting plate shape the temperature field "
            "but enter the bias only through T, dT/dt and UHFO, which every model sees.")
