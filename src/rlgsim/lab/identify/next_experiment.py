"""The next experiment: a chamber programme that would separate the bias-law terms this
recording could not (``rlgsim identify … --suggest-programme``; docs/identify.md).

What the recording leaves open is named by the law fit (:mod:`.law_fit`): the *unseparable*
groups of terms — typically the rate and the gradients a ramp drives, or the powers of the
temperature — whose separate coefficients it does not determine. A programme separates them when
their window features no longer follow each other: holds after ramps (the rate drops to zero
at once, a gradient decays with the block's time constant), ramps at different rates (the
quasi-steady gradient of a ramp grows with its rate, a transient one does not), soaks at
several temperatures (the powers of T part).

Design (optimal experimental design over a small family, the A-criterion in relative terms;
Atkinson, Donev & Tobias, *Optimum Experimental Designs*, 2007, ch. 10): programmes of the
recording's length (at least 4 h) over the recording's air range — from the middle, a ramp up
at one rate, a hold, a ramp down at another, a hold, back to the middle, a hold — for every
ordered pair of ramp rates from :data:`RATES`. For each, the twin's thermal network (fitted
multipliers) is driven by the programme's air (:func:`~rlgsim.lab.identify.thermal_fit.
twin_response`), the law's candidate features are formed on its 100 s windows exactly as for a
recording (:func:`~rlgsim.lab.identify.law_fit.bias_features`; the UHFO, when the law has it, is
the twin's UHFO law on that thermal state), and the standard error of each coefficient of the
*full* law — the chosen terms outside the unseparable groups and the targets below, all fitted
at once, so that none of them can stand in for another — is the generalised-least-squares
``√diag((XᵀC⁻¹X)⁻¹)`` with the window-mean covariance ``C`` of the fitted noise (white, flicker
over the template's band, random walk, quantisation; :func:`~rlgsim.estimators.identify.
window_noise.covariance_from_fit`), times the recording's overdispersion ĉ. The targets are
the groups' members reduced to one per kind (the rate, the most included gradient, power of T,
UHFO; :func:`_full_model`): gradients among themselves are driven through the same few thermal
modes by any chamber air and no programme separates them. The programme kept is the one whose
predicted standard errors of the targets, relative to the same law's on this recording, have
the least geometric mean. Its predicted shrinkage of each standard error is written into the
scenario's header; simulating the scenario on the twin, identifying the result and computing
the same law's standard errors there (:func:`recorded_se`) checks it
(``tests/test_identify_next_experiment.py``).

Written by hand: the family and the criterion are a few lines over the law fit's own machinery;
an experimental-design library would need the thermal twin wrapped as its model anyway.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pandas as pd

from rlgsim.estimators.identify.whitening import jittered_cholesky
from rlgsim.estimators.identify.window_noise import covariance_from_fit
from rlgsim.lab.identify.recording_data import RecordingData

__all__ = ["Suggestion", "suggest_programme", "programme_air", "RATES"]

#: ramp rates of the family [°C/min] (a lab chamber's usual range)
RATES = (0.5, 1.0, 2.0, 3.0)
#: first hold [s] and shortest hold [s] of a candidate programme
LEAD_S, MIN_HOLD_S = 1200.0, 1800.0


@dataclasses.dataclass(frozen=True)
class Suggestion:
    """The chosen programme (``start_c``, chamber ``segments``), the terms it is meant to
    separate, and per term of the full model ``(reported se now, predicted se)``."""

    start_c: float
    segments: list
    duration_s: float
    targets: tuple[str, ...]
    se: dict
    #: the recording's reported standard error of each term (model-averaged, selection and
    #: stand-in splits included)
    reported: dict = dataclasses.field(default_factory=dict)

    def lines(self) -> list[str]:
        """One line per target: the full law's standard error on this recording and predicted
        on the programme, the ratio, and the standard error the recording reports."""
        return [f"{t}: standard error {a:.3g} now, {b:.3g} predicted (× {b / a:.2f}; this "
                f"recording reports {self.reported.get(t, float('nan')):.3g} with the "
                f"selection)" for t, (a, b) in self.se.items() if t in self.targets]


def programme_air(start_c: float, segments: list, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The programme's air temperature on a grid of ``step_s`` (the ends of the steps) [s, °C]:
    holds and constant-rate ramps, the air taken as the setpoint (the chamber's lag is
    seconds to minutes, below the 100 s windows' resolution of the features)."""
    knots_t, knots_c = [0.0], [start_c]
    for seg in segments:
        if seg["type"] == "hold":
            knots_t.append(knots_t[-1] + float(seg["duration_s"]))
            knots_c.append(knots_c[-1])
        else:
            to = float(seg["to_c"])
            knots_t.append(knots_t[-1] + abs(to - knots_c[-1]) / float(seg["rate_c_per_min"])
                           * 60.0)
            knots_c.append(to)
    t = np.arange(1, int(knots_t[-1] // step_s) + 1) * step_s
    return t, np.interp(t, knots_t, knots_c)


def _candidates(lo: float, hi: float, duration_s: float) -> list[tuple[float, list]]:
    mid = round(0.5 * (lo + hi), 1)
    out = []
    for up, down in itertools.permutations(RATES, 2):
        ramps = ((hi - mid) / up + (hi - lo) / down + (mid - lo) / up) * 60.0
        hold = (duration_s - LEAD_S - ramps) / 3.0
        if hold < MIN_HOLD_S:
            continue
        hold = float(math.floor(hold / 60.0) * 60.0)
        out.append((mid, [{"type": "hold", "duration_s": LEAD_S},
                          {"type": "ramp", "to_c": hi, "rate_c_per_min": up},
                          {"type": "hold", "duration_s": hold},
                          {"type": "ramp", "to_c": lo, "rate_c_per_min": down},
                          {"type": "hold", "duration_s": hold},
                          {"type": "ramp", "to_c": mid, "rate_c_per_min": up},
                          {"type": "hold", "duration_s": hold}]))
    return out


def _design_recording(data: RecordingData, t: np.ndarray, air: np.ndarray) -> RecordingData:
    """A stand-in :class:`RecordingData` of the programme for the feature functions (power on
    throughout, no probes read, windows every ``window_s``)."""
    ends = np.arange(1, int(t[-1] // data.window_s) + 1) * data.window_s
    return dataclasses.replace(
        data, t_s=t, air_c=air, power=np.ones_like(air), uhfo_v=None,
        probes_c=np.full((t.size, len(data.probe_names)), np.nan),
        windows=pd.DataFrame({"time_s": ends}), motion=None, has_motion=False,
        rate_deg_per_h=np.zeros(0))


def _features(data, fit, laws, device, t, air):
    from rlgsim.lab.identify.law_fit import _per_step, bias_features, law_prediction
    from rlgsim.lab.identify.node_names import node_column
    from rlgsim.lab.identify.thermal_fit import twin_response
    rec = _design_recording(data, t, air)
    nodes, _ = twin_response(fit.network, fit.probes, air, rec.power, data.step_s)
    if laws.uhfo is not None:             # the twin's UHFO there: its law on the twin's state
        block = (device.get("gyro", {}).get("blocks") or [""])[0]
        Tu = nodes[:, node_column(block, laws.uhfo_node, fit.network.node_names)]
        rec = dataclasses.replace(rec, uhfo_v=law_prediction(
            laws.uhfo, _per_step(Tu, laws.uhfo_t_ref_c, data.step_s, {})))
    return rec, bias_features(rec, nodes, fit.network.node_names, device, laws)


def _kind(term: str) -> str:
    return ("gradient" if term.startswith("gradient[") else "c" if term in ("c1", "c2", "c3")
            else term)


def _full_model(sel) -> tuple[list[str], tuple[str, ...]]:
    """The law the design is judged on, and its targets: the chosen terms outside the
    unseparable groups, and of each group one member per kind — the rate, the most included
    gradient, the most included power of T, the UHFO. Gradients among themselves are left
    together: every chamber programme drives them through the same few thermal modes of the
    block, so no programme of the air separates them (only the heat sources inside could)."""
    members = {g for group in sel.standins for g in group}
    terms = [t for t in sel.terms if t not in members]
    targets: list[str] = []
    for group in sel.standins:
        best: dict[str, str] = {}
        for g in group:
            k = _kind(g)
            if k not in best or sel.averaged[g][2] > sel.averaged[best[k]][2]:
                best[k] = g
        if len(best) < 2:                 # one kind only: nothing a programme separates
            continue
        targets += [g for g in best.values() if g not in targets]
    return terms + [t for t in targets if t not in terms], tuple(targets)


def predicted_se(c_hat: float, cols: dict, cov: np.ndarray, terms: list[str]
                 ) -> dict[str, float]:
    """GLS standard errors of ``terms`` (with an intercept) on the feature columns ``cols``
    under the window covariance ``cov``, times √ĉ (``c_hat``, at least 1)."""
    from scipy.linalg import solve_triangular
    X = np.column_stack([np.ones(cov.shape[0])] + [cols[t] for t in terms])
    L = jittered_cholesky(cov)
    Xw = solve_triangular(L, X, lower=True)
    c = np.linalg.pinv(Xw.T @ Xw) * max(float(c_hat), 1.0)
    return {t: float(np.sqrt(max(c[i + 1, i + 1], 0.0))) for i, t in enumerate(terms)}


def _window_cov(rec: RecordingData, noise, device: dict) -> np.ndarray:
    from rlgsim.lab.identify.law_fit import _flicker_band
    band = _flicker_band(device)
    starts = np.asarray(rec.windows["time_s"], dtype=float) - rec.window_s
    return covariance_from_fit(noise, starts, rec.window_s, tau_min_s=band[0],
                               tau_max_s=band[1], per_decade=band[2])


def recorded_se(data: RecordingData, nodes_c: np.ndarray, node_names, device: dict, laws,
                noise, c_hat: float, terms: list[str]) -> dict[str, float]:
    """The same standard errors on a recording: its windows' features on the thermal state
    ``nodes_c`` (the law's nonlinear terms at ``laws``' centres and widths), the window
    covariance of ``noise`` — e.g. the full model on the recording a suggestion was made
    from ("now"), or on the run of the suggested programme (the check)."""
    from rlgsim.lab.identify.law_fit import bias_features
    cols = bias_features(data, nodes_c, node_names, device, laws)
    return predicted_se(c_hat, cols, _window_cov(data, noise, device), terms)


def suggest_programme(data: RecordingData, fit, laws, device: dict) -> Suggestion | None:
    """The programme of the family (module docstring) that best separates the recording's
    unseparable terms, or None when there are none (or no noise model to predict with)."""
    sel = laws.bias
    terms, targets = _full_model(sel)
    if not targets or laws.noise is None:
        return None
    now = recorded_se(data, fit.nodes_c, fit.network.node_names, device, laws, laws.noise,
                      sel.c_hat, terms)
    lo, hi = (round(float(v), 1) for v in np.percentile(data.air_c, [2, 98]))
    duration = max(float(data.duration_s), 4 * 3600.0)
    best = None
    for start, segs in _candidates(lo, hi, duration):
        t, air = programme_air(start, segs, data.step_s)
        rec, cols = _features(data, fit, laws, device, t, air)
        se = predicted_se(sel.c_hat, cols, _window_cov(rec, laws.noise, device), terms)
        score = float(np.mean([np.log(se[g] / now[g]) for g in targets]))
        if best is None or score < best[0]:
            best = (score, start, segs, float(t[-1]), se)
    if best is None:
        return None
    _, start, segs, dur, se = best
    return Suggestion(start_c=start, segments=segs, duration_s=dur, targets=targets,
                      se={t: (now[t], se[t]) for t in terms},
                      reported={t: float(sel.averaged[t][1]) for t in terms})


def scenario_text(s: Suggestion, data: RecordingData, name: str) -> str:
    """The suggestion as a scenario TOML on the twin (``device.toml`` beside it), its header
    the promised standard errors."""
    from rlgsim.lab.identify.preset_text import dumps
    sc = {"name": f"{name}_next", "description": "the next experiment suggested by rlgsim "
          "identify: a chamber programme that separates the bias-law terms the recording "
          "could not", "device": "device.toml", "seed": 1,
          "acquisition": {"sample_rate_hz": float(data.sample_rate_hz),
                          "thermal_step_s": float(data.step_s)},
          "power": {"on_at_s": 0.0},
          "chamber": {"start_c": s.start_c, "segments": s.segments}}
    head = [f"The next experiment for {name} (rlgsim identify --suggest-programme): run it "
            f"with `rlgsim run` on the twin, or give the chamber segments to the lab's chamber",
            f"{s.duration_s / 3600:.1f} h; it separates {', '.join(s.targets)}; predicted "
            f"standard errors of the law {' + '.join(s.se)} fitted at once (the unseparable groups "
            f"reduced to one member per kind), on this recording and on the programme:"] + ["  " + line for line in s.lines()]
    return dumps(sc, header="\n".join(head))
