"""Temperature laws and noise of the twin: given the twin's thermal state (node temperatures of
the fitted network driven by the recorded chamber air), fit the terms of the simulator's law
family (:mod:`rlgsim.sim.sensors.temperature_laws`) to the recorded gyro bias and UHFO, choosing the
terms by BIC, then the noise levels from the Allan deviation of what the law leaves.

Bias law (100 s windows of :func:`rlgsim.lab.api.window_table`, Earth rate removed). Candidate
terms, each evaluated per thermal step on the twin and averaged over the windows exactly as the
simulator's per-step law is averaged by the windows:

- ``c1``, ``c2``, ``c3``: powers of ``x = T − t_ref`` of the law's node (the template's ``node``
  and ``t_ref_c``);
- ``knee``: ``tanh((T − knee_c)/knee_width)``, ``step``: ``1/(1 + exp(−(T − step_c)/step_width))``
  — centres on a grid over the recorded range (and the template's), polished, and kept inside
  the range the recording covers (a sigmoid centred outside it is a constant there);
- ``rate``: the backward-difference rate of ``T`` in °C/min;
- ``gradient[a-b]``: ``T_a − T_b`` for the template's gradient pairs, for the law node against
  every other probed node of the block, and for the anode arms (``arm_nodes``, default D−E:
  the Langmuir-flow term of an asymmetric unit);
- ``uhfo``: ``U − U_0`` with the recorded UHFO and the fitted UHFO law's ``U_0``.

UHFO law (when the recording has UHFO): the same family on the discharge-side node of the
template's ``[uhfo]`` (``c1``–``c3``, ``rate``) fitted to the window means of the recorded UHFO;
what it leaves is the discharge wander, a Gauss–Markov process whose standard deviation and
correlation time come from the window residual (lag-one correlation ρ over a window: τ =
−window/ln ρ), and the read-out noise from the first differences of the 1 s residual.

Noise: the gyro rate per sample minus the fitted law (per thermal step, held over its samples),
powered samples only, into :func:`rlgsim.estimators.identify.allan_noise.fit_allan`. With
turntable motion (:mod:`.table_motion`) the bias windows are the stationary ones
(:mod:`.recording_data`) and the noise takes the samples with the table at rest, less the
Earth rate through the table attitude; the turning samples carry the scale-factor error times
the table rate and go to :mod:`.scale_factor_fit`.

Selection and uncertainties: :func:`rlgsim.estimators.identify.term_selection.select_terms`,
twice: by ordinary least squares, whose residual gives the noise fit, then by generalised least
squares with the covariance of the window means that the fitted noise implies
(:func:`rlgsim.estimators.identify.window_noise.covariance_from_fit`, the flicker band of the
device template) — the flicker's long memory then counts in every standard error. A window whose
whitened residual (its innovation) exceeds :data:`OUTLIER_Z` is left out, the largest first
and the law refitted after each (``outlier_windows_s``); then mode hops — steps the law cannot explain — are searched
for on the innovations and carried as fixed piecewise offsets while the terms are chosen again
(:mod:`rlgsim.lab.identify.hop_fit`, ``hops``); the noise is fitted again from what the final law
(hops included) leaves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from rlgsim.estimators.features import window_average
from rlgsim.estimators.identify.allan_noise import NoiseFit, fit_allan
from rlgsim.estimators.identify.term_selection import SelectedLaw, Term, select_terms
from rlgsim.estimators.identify.window_noise import covariance_from_fit
from rlgsim.sim.sensors.gyro import pulses_per_arcsec as template_pulses_per_arcsec
from rlgsim.lab.identify.feature_memo import remembered as _remembered
from rlgsim.lab.identify.node_names import node_column
from rlgsim.lab.identify.recording_data import RecordingData

__all__ = ["LawFit", "fit_laws", "law_prediction", "bias_features"]


@dataclass
class LawFit:
    """Fitted bias law (``bias``), UHFO law (``uhfo`` or None) with ``u0_v`` and the wander /
    read-out estimates ``uhfo_noise`` {key: (value, se)}; the noise fit; the bias law's window
    RMS residual; node names used."""

    bias: SelectedLaw
    bias_node: str
    t_ref_c: float
    uhfo: SelectedLaw | None
    uhfo_node: str | None
    uhfo_t_ref_c: float
    u0_v: float
    uhfo_noise: dict[str, tuple[float, float]]
    noise: NoiseFit | None
    bias_rms_deg_per_h: float
    raw_std_deg_per_h: float
    per_step_bias_deg_per_h: np.ndarray
    gradient_pairs: dict[str, tuple[str, str]]
    #: end times [s] of the windows left out of the bias law as outliers
    outlier_windows_s: tuple[float, ...] = ()
    #: mode hops found in the bias (:mod:`rlgsim.lab.identify.hop_fit`), None without a GLS fit
    hops: object = None
    #: read-out spikes found in the gyro samples (:mod:`rlgsim.lab.identify.spike_fit`)
    spikes: object = None


#: |innovation| (whitened window residual) beyond which a window is left out of the bias law:
#: 5.5 standard deviations, which independent Gaussian windows exceed once in 26 million, so
#: a 20 h recording (720 windows) loses a sound window once in 36,000 recordings
OUTLIER_Z = 5.5
#: at most this many windows are left out as outliers (one per refit)
MAX_OUTLIERS = 20


def _subset(cands: list[Term], keep: np.ndarray) -> list[Term]:
    """The candidate terms on the windows ``keep`` only."""
    return [Term(t.name, (lambda th, f=t.feature: np.asarray(f(th))[keep]), t.theta_names,
                 t.grid, t.lower, t.upper) for t in cands]


def _rate_c_per_min(T: np.ndarray, step_s: float) -> np.ndarray:
    prev = np.concatenate(([T[0]], T[:-1]))
    return (T - prev) * (60.0 / step_s)


def _window_rows(rec: RecordingData) -> np.ndarray:
    return np.rint(np.asarray(rec.windows["time_s"], dtype=float) / rec.window_s).astype(int) - 1


def _candidates(T: np.ndarray, t_ref: float, step_s: float, win, law: dict,
                extra: dict[str, np.ndarray], nonlinear: bool = True) -> list[Term]:
    """Window-averaged candidate terms; ``win(per_step) -> window values``."""
    x = T - t_ref
    terms = [Term("c1", lambda th, v=win(x): v), Term("c2", lambda th, v=win(x ** 2): v),
             Term("c3", lambda th, v=win(x ** 3): v),
             Term("rate", lambda th, v=win(_rate_c_per_min(T, step_s)): v)]
    for name, series in extra.items():
        terms.append(Term(name, lambda th, v=win(series): v))
    if not nonlinear:
        return terms
    lo, hi = float(np.percentile(T, 2)), float(np.percentile(T, 98))
    span = max(hi - lo, 1e-3)
    centres = list(np.linspace(lo + 0.05 * span, hi - 0.05 * span, 31))
    for key in ("knee", "step"):
        c0 = law.get(f"{key}_c")
        w0 = float(law.get(f"{key}_width_k", 5.0 if key == "knee" else 1.5))
        cs = ([float(c0)] if c0 is not None and lo < float(c0) < hi else []) + centres
        widths = sorted(w for w in {w0, 1.0, 3.0, 8.0, 20.0} if w < span / 2)
        grid = [np.array([c, w]) for c in cs for w in widths]
        if key == "knee":
            def f(th, T=T):
                return win(np.tanh((T - th[0]) / th[1]))
        else:
            def f(th, T=T):
                return win(1.0 / (1.0 + np.exp(-np.clip((T - th[0]) / th[1], -60, 60))))
        terms.append(Term(key, _remembered(f), ("center_c", "width_k"), grid,
                          lower=(lo, 0.2), upper=(hi, span / 2)))
    return terms


def law_prediction(sel: SelectedLaw, candidates_per_step: dict) -> np.ndarray:
    """Per-step value of a selected law from per-step term functions
    ``{term: f(theta) -> (m,)}``."""
    x = sel.fit.x
    names = sel.fit.names
    out = np.full(next(iter(candidates_per_step.values()))(np.zeros(2)).shape, x[0])
    for t in sel.terms:
        th = np.array([x[names.index(n)] for n in names if n.startswith(f"{t}.")])
        out = out + x[names.index(t)] * candidates_per_step[t](th)
    for t in sel.fixed:                       # the mode hops' piecewise offsets
        out = out + x[names.index(t)] * candidates_per_step[t](np.zeros(0))
    return out


def _per_step(T, t_ref, step_s, extra):
    x = T - t_ref
    f = {"c1": lambda th: x, "c2": lambda th: x ** 2, "c3": lambda th: x ** 3,
         "rate": lambda th: _rate_c_per_min(T, step_s),
         "knee": lambda th: np.tanh((T - th[0]) / th[1]),
         "step": lambda th: 1.0 / (1.0 + np.exp(-np.clip((T - th[0]) / th[1], -60, 60)))}
    for k, v in extra.items():
        f[k] = (lambda th, v=v: v)
    return f


def _uhfo_law(rec: RecordingData, nodes_c: np.ndarray, node_names: tuple[str, ...],
              block: str, device: dict, t_ref: float, win: Callable) -> tuple:
    """The UHFO law on its node's temperature (linear terms) and its noise (window wander from
    the lag-1 autocorrelation, sample noise from first differences less the LSB's share):
    (law or None without a UHFO record, u0 [V], node, T_ref [°C], {key: (value, se)})."""
    utab = dict(device.get("uhfo", {}))
    u_t_ref = float(utab.get("t_ref_c", t_ref))
    if rec.uhfo_v is None:
        return None, 0.0, None, u_t_ref, {}
    step = rec.step_s
    uhfo_node = str(utab.get("node", "discharge"))
    Tu = nodes_c[:, node_column(block, uhfo_node, node_names)]
    uw = win(rec.uhfo_v)
    ucands = _candidates(Tu, u_t_ref, step, win, {}, {}, nonlinear=False)
    uhfo_sel = select_terms(uw, ucands)
    u0 = uhfo_sel.value("intercept")
    upred = law_prediction(uhfo_sel, _per_step(Tu, u_t_ref, step, {}))
    res_step = rec.uhfo_v - upred
    powered = rec.power > 0.5
    r_w = uw - win(upred)
    r_w = r_w - r_w.mean()
    rho = float(np.dot(r_w[1:], r_w[:-1]) / max(np.dot(r_w, r_w), 1e-300))
    lsb = float(utab.get("lsb_v", 0.0))
    d = np.diff(res_step[powered])
    noise_v = float(np.sqrt(max(np.var(d) / 2.0 - lsb ** 2 / 12.0, 0.0)))
    wander = float(np.std(r_w))
    tau = float(-rec.window_s / np.log(rho)) if 0 < rho < 1 else float("inf")
    n_eff = max(rec.duration_s / (2.0 * tau), 1.0) if np.isfinite(tau) else 1.0
    uhfo_noise = {"wander_v": (wander, wander / np.sqrt(2.0 * n_eff)),
                  "wander_tau_s": (tau, tau * np.sqrt(2.0 / n_eff)),
                  "noise_v": (noise_v, noise_v / np.sqrt(2.0 * max(d.size, 1)))}
    return uhfo_sel, u0, uhfo_node, u_t_ref, uhfo_noise


def read_out_spikes(rec: RecordingData, device: dict) -> tuple:
    """Read-out spikes in the powered rate samples, for the noise fit to take out (no twin
    needed: ``identify`` runs this beside the thermal fit): (SpikeFit, a pulse's angle [″])."""
    from rlgsim.lab.identify.spike_fit import find_spikes
    pulses_per_arcsec = template_pulses_per_arcsec(device)
    per = int(round(rec.sample_rate_hz * rec.step_s))
    n_s = min(rec.power.size * per, rec.rate_deg_per_h.size)
    rate_s = rec.rate_deg_per_h[:n_s]
    if rec.motion is not None:          # turntable: less the table's input, which the median
        rate_s = rate_s - rec.motion.input_deg_per_h[:n_s]   # of 31 samples would not follow
    spikes = find_spikes(rate_s, rec.sample_rate_hz, pulses_per_arcsec,
                         np.repeat(rec.power > 0.5, per)[:n_s])
    return spikes, 1.0 / pulses_per_arcsec


def _gls_bias(rec: RecordingData, y: np.ndarray, cands: list[Term], noise: NoiseFit,
              device: dict, nodes_c: np.ndarray, node_names: tuple[str, ...], block: str,
              bias_node: str, per_step_terms: dict) -> tuple:
    """The bias law by generalised least squares with the window-mean covariance of ``noise``
    (flicker memory included): windows the noise model cannot explain left out one at a time,
    then the mode hops found and carried (module docstring). Returns (law, outlier window
    times [s], HopFit, per-step terms with the hops' regressors added)."""
    band = _flicker_band(device)
    starts = np.asarray(rec.windows["time_s"], dtype=float) - rec.window_s
    cov = covariance_from_fit(noise, starts, rec.window_s, tau_min_s=band[0],
                              tau_max_s=band[1], per_decade=band[2])
    bias_sel = select_terms(y, cands, noise_cov=cov)
    # windows the noise model cannot explain (a read-out spike, a step): left out one at a
    # time, the largest first, the law refitted in between — the whitening spreads a large
    # residual into the innovations of the windows after it (with the white part no longer
    # inflated by the counter's quantisation, a 40-pulse spike flagged its two successors)
    keep = np.arange(y.size)
    for _ in range(MAX_OUTLIERS):
        z = np.abs(bias_sel.fit.residual)
        if z.size == 0 or z.max() <= OUTLIER_Z:
            break
        keep = np.delete(keep, int(np.argmax(z)))
        bias_sel = select_terms(y[keep], _subset(cands, keep), noise_cov=cov[np.ix_(keep, keep)])
    outliers: tuple[float, ...] = ()
    bad = np.setdiff1d(np.arange(y.size), keep)
    if bad.size:
        outliers = tuple(float(t) for t in np.asarray(rec.windows["time_s"])[bad])
    # mode hops: steps the law cannot explain, then the law on the hop-free bias
    from rlgsim.lab.identify import hop_fit as H
    from rlgsim.lab.identify import hop_mapping as HM
    te = np.asarray(rec.windows["time_s"], dtype=float)[keep]
    bias_sel, scan, idx, rounds, pattern = H.find_hops(
        y[keep], _subset(cands, keep), cov[np.ix_(keep, keep)], bias_sel, te, rec.window_s,
        rec.t_s, nodes_c, node_names, block, bias_node, device)
    hops, hop_times = HM.describe_hops(bias_sel, scan, idx, rounds, pattern, te, rec.window_s,
                                       rec.t_s, nodes_c, node_names, block, bias_node, device)
    per_step_terms.update(H.hop_per_step(rec.t_s, hop_times))
    return bias_sel, outliers, hops, per_step_terms


def fit_laws(rec: RecordingData, nodes_c: np.ndarray, node_names: tuple[str, ...],
             device: dict, spikes: tuple | None = None) -> LawFit:
    """Fit the bias law, the UHFO law and the noise (module docstring). ``device`` is the
    device template dict, ``nodes_c`` (m, n) the twin's node temperatures on the recording's
    grid; ``spikes``: :func:`read_out_spikes` of ``rec`` if found already."""
    gyro = device.get("gyro", {})
    block = (gyro.get("blocks") or [""])[0]
    law = dict(gyro.get("bias", {}))
    bias_node = str(law.get("node", gyro.get("node", "A")))
    t_ref = float(law.get("t_ref_c", gyro.get("t_ref_c", 20.0)))
    step = rec.step_s
    rows = _window_rows(rec)

    def win(v: np.ndarray) -> np.ndarray:
        return np.asarray(window_average(v, 1.0 / step, rec.window_s))[rows]

    uhfo_sel, u0, uhfo_node, u_t_ref, uhfo_noise = _uhfo_law(rec, nodes_c, node_names, block,
                                                             device, t_ref, win)
    spikes, quantum = spikes if spikes is not None else read_out_spikes(rec, device)
    T = nodes_c[:, node_column(block, bias_node, node_names)]             # the bias law
    extra, pairs = _bias_extra(rec, nodes_c, node_names, block, law, bias_node, u0)
    y = np.asarray(rec.windows["bias_deg_per_h"], dtype=float)
    outliers: tuple[float, ...] = ()
    hops, cands = None, _candidates(T, t_ref, step, win, law, extra)
    per_step_terms = _per_step(T, t_ref, step, extra)
    # first pass: ordinary least squares, whose residual gives the noise model ...
    bias_sel = select_terms(y, cands)
    per_step = law_prediction(bias_sel, per_step_terms)
    noise = _noise(rec, per_step, spikes, quantum)
    # ... then generalised least squares with the window-mean covariance of that noise
    # (flicker memory included), and the noise again from what the final law leaves
    if noise is not None:
        bias_sel, outliers, hops, per_step_terms = _gls_bias(
            rec, y, cands, noise, device, nodes_c, node_names, block, bias_node, per_step_terms)
        per_step = law_prediction(bias_sel, per_step_terms)
        noise = _noise(rec, per_step, spikes, quantum) or noise
    rms = float(np.sqrt(np.mean(bias_sel.residual ** 2)))
    return LawFit(bias=bias_sel, bias_node=bias_node, t_ref_c=t_ref, uhfo=uhfo_sel,
                  uhfo_node=uhfo_node, uhfo_t_ref_c=u_t_ref, u0_v=u0, uhfo_noise=uhfo_noise,
                  noise=noise, bias_rms_deg_per_h=rms, raw_std_deg_per_h=float(np.std(y, ddof=1)),
                  per_step_bias_deg_per_h=per_step, gradient_pairs=pairs,
                  outlier_windows_s=outliers, hops=hops, spikes=spikes)


def _flicker_band(device: dict) -> tuple[float, float, int]:
    """The flicker band [s] and processes per decade of the device template's ``[noise]``
    (the simulator's defaults 2 s, 10⁵ s, 2 when it names none): correlation times beyond the
    record are not observable, so the template's band stands for the device's."""
    tab = device.get("noise", {}) or {}
    return (float(tab.get("flicker_tau_min_s", 2.0)), float(tab.get("flicker_tau_max_s", 1e5)),
            int(tab.get("flicker_per_decade", 2)))


def _noise(rec: RecordingData, per_step: np.ndarray, spikes=None,
           quantum_arcsec: float | None = None) -> NoiseFit | None:
    """Allan fit of the gyro rate per sample minus the law ``per_step`` (powered samples), the
    read-out ``spikes`` found (:class:`~rlgsim.lab.identify.spike_fit.SpikeFit`) taken out of
    their samples (a spike of s pulses adds s·quantum·f °/h to one sample: white at short τ,
    it would pass for angle random walk), Q fixed by the counter's ``quantum_arcsec``
    (:func:`~rlgsim.estimators.identify.allan_noise.fit_allan`)."""
    f, rate = rec.sample_rate_hz, rec.rate_deg_per_h
    per = int(round(f * rec.step_s))
    n_steps = min(per_step.size, rate.size // per)
    # the law held over each step's samples: (steps, samples) less a column, no repeated copy
    resid = (rate[:n_steps * per].reshape(n_steps, per) - per_step[:n_steps, None]).reshape(-1)
    if spikes is not None and spikes.times_s and quantum_arcsec is not None:
        out: dict[int, float] = {}               # each spike out of its sample first:
        for t, size in zip(spikes.times_s, spikes.sizes):   # (rate − spike) − law, as before
            i = int(round(t * f)) - 1
            if 0 <= i < resid.size:
                out[i] = out.get(i, rate[i]) - size * quantum_arcsec * f
        for i, v in out.items():
            resid[i] = v - per_step[i // per]
    if rec.motion is not None:          # turntable: the table at rest only, less its Earth rate
        resid = resid - rec.motion.input_deg_per_h[:n_steps * per]
        resid = resid[np.repeat(rec.power[:n_steps] > 0.5, per)
                      & ~rec.motion.moving[:n_steps * per]]
    else:                               # powered steps: whole rows of the (steps, samples) view
        resid = resid.reshape(n_steps, per)[rec.power[:n_steps] > 0.5].reshape(-1)
    resid = resid if np.isfinite(resid).all() else resid[np.isfinite(resid)]   # dropouts
    try:
        return fit_allan(resid, f, quantum_arcsec=quantum_arcsec)
    except ValueError:
        return None


def bias_features(rec: RecordingData, nodes_c: np.ndarray, node_names: tuple[str, ...],
                  device: dict, laws: LawFit) -> dict[str, np.ndarray]:
    """Window features {term: (windows,)} of the fitted bias law's candidates on another
    recording ``rec`` whose twin node temperatures are ``nodes_c`` (nonlinear terms at the
    fitted centre and width) — the input of :meth:`SelectedLaw.predict`, e.g. the law's
    prediction with its uncertainty on a programme it was not identified from."""
    gyro = device.get("gyro", {})
    block = (gyro.get("blocks") or [""])[0]
    law = dict(gyro.get("bias", {}))
    rows = _window_rows(rec)

    def win(v: np.ndarray) -> np.ndarray:
        return np.asarray(window_average(v, 1.0 / rec.step_s, rec.window_s))[rows]
    T = nodes_c[:, node_column(block, laws.bias_node, node_names)]
    extra, _ = _bias_extra(rec, nodes_c, node_names, block, law, laws.bias_node, laws.u0_v)
    sel = laws.bias
    out = {}
    for t in _candidates(T, laws.t_ref_c, rec.step_s, win, law, extra):
        if t.k and t.name in sel.terms:
            out[t.name] = t.feature(np.array([sel.value(f"{t.name}.{n}")
                                              for n in t.theta_names]))
        elif not t.k:
            out[t.name] = t.feature(np.zeros(0))
    for name in sel.fixed:       # mode hops: unknown on another programme, the start mode's law
        out[name] = np.zeros(len(rows))
    return out


def _bias_extra(rec: RecordingData, nodes_c: np.ndarray, node_names: tuple[str, ...],
                block: str, law: dict, bias_node: str, u0: float
                ) -> tuple[dict[str, np.ndarray], dict[str, tuple[str, str]]]:
    """Per-step gradient and UHFO candidates of the bias law and the gradient pairs."""
    extra: dict[str, np.ndarray] = {}
    pairs: dict[str, tuple[str, str]] = {}
    probed = [n.split(".", 1)[1] for n in rec.probe_names if block and n.startswith(f"{block}.")]
    cand_pairs = [(str(g["a"]), str(g["b"])) for g in law.get("gradients", [])]
    cand_pairs += [(bias_node, o) for o in probed if o != bias_node]
    arm = law.get("arm_nodes", ["D", "E"])          # the Langmuir pair: anode-arm difference
    cand_pairs.append((str(arm[0]), str(arm[1])))
    for a, b in cand_pairs:
        key = f"gradient[{a}-{b}]"
        if key in extra or f"gradient[{b}-{a}]" in extra:
            continue
        try:
            ia, ib = node_column(block, a, node_names), node_column(block, b, node_names)
        except ValueError:
            continue
        diff = nodes_c[:, ia] - nodes_c[:, ib]
        if np.ptp(diff) < 1e-6:          # a symmetric pair of the twin: no information
            continue
        extra[key] = diff
        pairs[key] = (a, b)
    if rec.uhfo_v is not None:
        extra["uhfo"] = rec.uhfo_v - u0
    return extra, pairs
