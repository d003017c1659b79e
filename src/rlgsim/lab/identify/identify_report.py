"""The identification report (report.md / report.html with figures, through
:class:`rlgsim.lab.report.Report`): what was fitted, how well, what was refused and why."""

from __future__ import annotations

import math

from typing import Any

import numpy as np

from rlgsim.lab.report import Report, Table

__all__ = ["build_report", "gyro_sections"]


def _law_tables(rep: Report, sel, title: str, unit: str) -> None:
    rep.table(Table.from_records(f"{title}: selection by BIC", [
        {"step": i, "term": t, "BIC": round(b, 2)} for i, (t, b) in enumerate(sel.steps)],
        note="each step adds the term that lowers the BIC most (a '-' removes one); the "
             "candidates were " + ", ".join(sel.candidates)))
    rep.table(Table.from_records(f"{title}: coefficients", [
        {"parameter": n, "estimate": float(v), "standard error": float(s),
         "unit": unit if n in ("intercept",) else ""}
        for n, v, s in zip(sel.fit.names, sel.fit.x, sel.fit.se)],
        note=(f"standard errors: generalised least squares with the window-mean covariance of "
              f"the fitted noise model (white, flicker over the template's band, random walk, "
              f"quantisation), ×{sel.fit.inflation:.2f} for a whitened residual larger than "
              f"modelled; given the chosen terms (selection uncertainty: next table)"
              if sel.gls else
              f"standard errors: sandwich with batch means, ×{sel.fit.inflation:.2f} the "
              f"independent-residual value (residual lag-one correlation {sel.fit.rho:.2f}); "
              f"given the chosen terms (selection uncertainty: next table)")))
    if sel.averaged:
        rep.table(Table.from_records(f"{title}: model-averaged over the term subsets", [
            {"term": n, "model-averaged": v, "standard error (selection included)": se,
             "inclusion probability": p,
             "VIF in the chosen law": sel.vif.get(n)}
            for n, (v, se, p) in sel.averaged.items()],
            note=f"Akaike weights of every linear subset with the likelihood divided by the "
                 f"overdispersion ĉ = {sel.c_hat:.2f} of the "
                 f"{'whitened windows' if sel.gls else 'windows (flicker)'}: the spread "
                 f"of the coefficients across near-equally supported subsets is in the "
                 f"standard errors; a term out of a subset counts as 0"))
    for _, reason in sel.unseparable:
        rep.paragraph(f"**Not identified separately:** {reason}.")


def _anomaly_section(rep: Report, laws) -> None:
    """Mode hops (lab/identify/hop_fit.py, hop_mapping.py) and read-out spikes (spike_fit.py)."""
    hf, sp = laws.hops, laws.spikes
    rep.heading("Mode hops and read-out spikes")
    if hf is not None:
        how = (f"a likelihood-ratio step scan of the bias windows under the law's noise model "
               f"(flicker included), Bonferroni threshold |z| ≥ {hf.threshold_z:.2f} over "
               f"{hf.candidates} positions (family false-alarm level {hf.alpha / 2:g} per "
               f"recording)")
        if hf.pattern is not None:
            zs, n_pred, n_found = hf.pattern
            how += (f", then a search near the {n_pred} hop(s) the template's mode-hop model "
                    f"makes on the twin's T_c (level {hf.alpha / 2:g}; found {n_found}"
                    + (": best |z| " + ", ".join(f"{abs(z):.2f} of {t:.2f}" for z, t, _ in zs)
                       if zs else "") + ")")
        if not hf.hops:
            rep.paragraph(f"No mode hops found ({how}; largest |z| of the last scan "
                          f"{hf.scan_max_z:.2f}). T_c (mean of {', '.join(hf.nodes)}) spanned "
                          f"{hf.t_range_c[0]:.1f}–{hf.t_range_c[1]:.1f} °C.")
        else:
            rep.paragraph(f"{len(hf.hops)} mode hop(s) found ({how}); each is a fixed "
                          f"piecewise offset of the bias law, so the temperature terms are "
                          f"chosen on the hop-free bias. T_c is the twin's mean of "
                          f"{', '.join(hf.nodes)}.")
            rep.table(Table.from_records("Mode hops", [
                {"hop": i + 1, "time [h]": h.time_s / 3600, "± [s]": h.time_se_s,
                 "step [°/h]": h.size_deg_per_h, "standard error [°/h]": h.size_se_deg_per_h,
                 "z": h.z, "T_c [°C]": h.temperature_c, "± [°C]": h.temperature_se_c,
                 "direction": ("up" if h.direction > 0 else "down")
                              + ("" if h.from_trend else " (from the step's sign)"),
                 "mode before": h.mode_before} for i, h in enumerate(hf.hops)],
                note="time: the boundary of the two windows the step falls between; T_c's "
                     "standard error from its change over them (the twin's thermal error "
                     "comes on top)"))
            for a, b, w, se in hf.pairs:
                rep.paragraph(f"Hops {a + 1} (down) and {b + 1} (up) are a hysteresis pair: "
                              f"width {w:.2f} ± {se:.2f} K.")
        if hf.mode_hop is not None:
            mh = hf.mode_hop
            when = ", ".join(f"{t / 3600:.2f} h ({'up' if d > 0 else 'down'})"
                             for t, d in hf.predicted) or "no time"
            rep.paragraph(f"The twin's `[anomalies.mode_hop]`: κ {mh['modes_per_k']:.4g} /K, "
                          f"R {mh['range_modes']:.4g}, T_ref {mh['reference_c']:.2f} °C, "
                          f"Δb {mh['bias_step_deg_per_h']:.4g} °/h; on the twin's T_c it "
                          f"hops at {when} of this recording.")
        for note in hf.notes:
            rep.paragraph(f"Mode hops: {note}.")
    if sp is not None:
        n = len(sp.sizes)
        lo, hi = sp.rate_ci95_per_h
        rep.paragraph(
            f"Read-out spikes: {n} sample(s) at least {sp.threshold_pulses} pulses from their "
            f"neighbours' median in {sp.powered_h:.1f} powered h"
            + (f" (sizes {', '.join(str(s) for s in sp.sizes)} pulses, at "
               f"{', '.join(f'{t / 3600:.2f} h' for t in sp.times_s)}): rate "
               f"{sp.rate_per_h:.3g} per h, 95 % interval [{lo:.3g}, {hi:.3g}] (exact Poisson, "
               f"scaled for the sizes too small to see), max_pulses {sp.max_pulses} — the "
               f"twin's `[anomalies.pulse_spikes]`" if n else
               f": none; rate below {hi:.3g} per h (95 %); the twin has no read-out spikes")
            + f". {len(laws.outlier_windows_s)} bias window(s) were left out of the law as "
              f"outliers (innovation beyond 5.5σ).")


def notes_paragraphs(rep: Report, result: Any) -> None:
    """The identification's notes, then the probe glitches left out (one paragraph each)."""
    for note in result.notes:
        rep.paragraph(note[0].upper() + note[1:] + ".")
    if result.data.probe_glitches:
        rep.paragraph(f"{result.data.probe_glitches} probe reading(s) more than 5 K from the "
                      f"median of their ±5 neighbours were taken as glitches and left out.")


def _intro(rep: Report, result: Any, device_name: str, thermal_name: str) -> None:
    """What was identified from what, the probe glitches left out, the scale factor's line."""
    d = result.data
    rep.paragraph(
        f"Identified from `{d.source}` ({d.duration_s / 3600:.2f} h, probes every {d.step_s:g} s, "
        f"gyro `{d.gyro_axis}` at {d.sample_rate_hz:g} Hz, {len(d.windows)} windows of "
        f"{d.window_s:g} s) with the device template `{device_name}` and the thermal template "
        f"`{thermal_name}` in {result.seconds:.1f} s. Files: `thermal.toml`, `device.toml`, "
        f"`{result.scenario_path.name}` (the recorded chamber programme on the twin: "
        f"`rlgsim run {result.scenario_path.name}`).")
    notes_paragraphs(rep, result)
    from rlgsim.lab.identify.recording_data import scale_factor_line
    if result.scale_factor is None:
        rep.paragraph(scale_factor_line(d)[0].upper() + scale_factor_line(d)[1:] + ".")
    else:
        rep.paragraph(result.scale_factor.lines[0][0].upper() + result.scale_factor.lines[0][1:]
                      + " (section Scale factor).")


def _thermal_tables(rep: Report, th: Any) -> None:
    """The thermal multipliers with their status, and the strongest correlations of the fit."""
    rows = []
    for p in th.params:
        if p.name in th.multipliers:
            m = th.multipliers[p.name]
            h = th.interval_95.get(p.name)
            rows.append({"parameter": p.name, "what": p.description, "multiplier": m,
                         "standard error": th.rel_se[p.name] * m,
                         "95 % interval": (f"{m * math.exp(-h):.5g} – {m * math.exp(h):.5g}"
                                           if h is not None else ""), "status": "fitted"})
        else:
            rows.append({"parameter": p.name, "what": p.description, "multiplier": 1.0,
                         "standard error": None, "95 % interval": "",
                         "status": "kept at the template: " + th.refused.get(p.name, "")})
    rep.table(Table.from_records("Thermal multipliers (× template)", rows,
                                 note="a multiplier scales the template's design values of "
                                      "that group; refused parameters keep the template; the "
                                      "95 % interval (95.4 %, ±2σ of a Gaussian) is the wider of "
                                      "±2 batch-means standard errors and the probes' error "
                                      "model's percentile interval"))
    if th.fit is not None:
        names = th.fit.names
        c = th.fit.corr
        pairs = [{"a": names[i], "b": names[j], "correlation": float(c[i, j])}
                 for i in range(len(names)) for j in range(i + 1, len(names))
                 if abs(c[i, j]) > 0.8]
        rep.table(Table.from_records("Strongest correlations of the fitted multipliers",
                                     pairs or [{"a": "-", "b": "-", "correlation": None}],
                                     note="pairs with |r| > 0.8; above 0.99 a parameter is "
                                          "refused"))
        rep.paragraph(f"Standard errors: the larger of two — the sandwich covariance with "
                      f"batch means of the scores (8 per probe), ×{th.fit.inflation:.2f} the "
                      f"independent-residual value (residual lag-one correlation "
                      f"{th.fit.rho:.3f}), and the probes' error model (the template's "
                      f"resolution and noise, the quantisation grid at a random offset) carried "
                      f"through the Jacobian; {th.fit.nfev} evaluations of the network over the "
                      f"whole recording in the last fit.")


def _thermal_section(rep: Report, result: Any, plt: Any) -> None:
    """Multipliers, correlations, probe lines, residual RMS and the probes' figure."""
    d, th = result.data, result.thermal
    rep.heading("Thermal network")
    _thermal_tables(rep, th)
    for line in result.probe_lines:
        rep.paragraph(line[0].upper() + line[1:] + ".")
    rep.table(Table.from_records("Probe residual RMS [°C]", [
        {"probe": n, "template": th.rms_template_c[n], "fitted twin": th.rms_fitted_c[n]}
        for n in th.probe_names]))
    fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    t_h = d.t_s / 3600
    ax[0].plot(t_h, d.air_c, color="0.6", lw=0.8, label="chamber air")
    for j in range(min(3, len(th.probe_names))):
        ax[0].plot(t_h, d.probes_c[:, j], lw=0.8, label=f"{th.probe_names[j]} recorded")
        ax[0].plot(t_h, th.probe_fit_c[:, j], "--", lw=0.8, label=f"{th.probe_names[j]} twin")
        ax[1].plot(t_h, d.probes_c[:, j] - th.probe_fit_c[:, j], lw=0.6,
                   label=th.probe_names[j])
    ax[0].set_ylabel("°C")
    ax[0].legend(fontsize=7, ncol=2)
    ax[1].set_ylabel("recorded − twin [°C]")
    ax[1].set_xlabel("time [h]")
    rep.figure(fig, "probes", "Probes: recorded and twin; residuals")


def _bias_section(rep: Report, d: Any, laws: Any, plt: Any) -> None:
    """The bias law: its terms, residual, outliers, tables and the window figure."""
    rep.heading("Bias law")
    rep.paragraph(
        f"Law node `{laws.bias_node}`, t_ref {laws.t_ref_c:g} °C. Chosen terms: "
        f"{', '.join(laws.bias.terms) or 'none (constant)'}. Window residual RMS "
        f"{laws.bias_rms_deg_per_h:.5f} °/h against a raw window standard deviation of "
        f"{laws.raw_std_deg_per_h:.5f} °/h."
        + (f" {len(laws.outlier_windows_s)} window(s) left out as outliers (a whitened "
           f"residual beyond 5.5: a read-out spike or a step the law does not hold), ending at "
           + ", ".join(f"{t / 3600:.2f} h" for t in laws.outlier_windows_s) + "."
           if laws.outlier_windows_s else ""))
    _law_tables(rep, laws.bias, "Bias law", "°/h")
    fig, ax = plt.subplots(figsize=(9, 3.5))
    tw = np.asarray(d.windows["time_s"]) / 3600
    y = np.asarray(d.windows["bias_deg_per_h"])
    ax.plot(tw, y, ".", ms=3, label="recorded (100 s windows)")
    kept = ~np.isin(np.asarray(d.windows["time_s"]), laws.outlier_windows_s)
    ax.plot(tw[kept], y[kept] + laws.bias.residual, lw=1, label="twin law")
    ax.set_xlabel("time [h]")
    ax.set_ylabel("bias [°/h]")
    ax.legend(fontsize=8)
    rep.figure(fig, "bias_law", "Window bias and the fitted law")


def _noise_section(rep: Report, laws: Any, plt: Any) -> None:
    """The Allan fit of the law residual: its table and figure (or why there is none)."""
    rep.heading("Noise")
    if laws.noise is None:
        rep.paragraph("The record is too short for an Allan fit; the template's noise is kept.")
        return
    rep.table(Table.from_records("Noise from the Allan deviation of the law residual",
                                 laws.noise.rows(),
                                 note="95 % intervals; a lower end of 0 means the term is "
                                      "not resolved"))
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(laws.noise.taus_s, laws.noise.adev_deg_per_h, "o", ms=3, label="residual")
    ax.loglog(laws.noise.taus_s, laws.noise.model_deg_per_h, label="fitted model")
    ax.set_xlabel("τ [s]")
    ax.set_ylabel("Allan deviation [°/h]")
    ax.legend(fontsize=8)
    rep.figure(fig, "allan", "Allan deviation of the law residual and the fitted noise")


def build_report(result, device_name: str, thermal_name: str) -> Report:
    """The twin's report: the thermal fit, the bias law, anomalies, the UHFO law, the noise
    and the scale factor, with their figures."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rep = Report(f"Digital twin of {result.data.source}")
    _intro(rep, result, device_name, thermal_name)
    _thermal_section(rep, result, plt)
    gyro_sections(rep, result.data, result.laws, result.scale_factor, result.device, plt)
    return rep


def gyro_sections(rep: Report, d: Any, laws: Any, scale_factor: Any, device: dict,
                  plt: Any) -> None:
    """What is fitted per gyro: the bias law, anomalies, the UHFO law, the noise and the scale
    factor, with their figures (once in a single gyro's report, once per gyro in a
    several-gyro twin's, :mod:`.identify_report_gyros`)."""
    _bias_section(rep, d, laws, plt)
    _anomaly_section(rep, laws)
    if laws.uhfo is not None:
        rep.heading("UHFO law")
        rep.paragraph(f"Node `{laws.uhfo_node}`; U₀ = {laws.u0_v:.4f} V. Discharge wander and "
                      f"read-out noise from the residual: " + ", ".join(
                          f"{k} {v:.4g} ± {s:.2g}" for k, (v, s) in laws.uhfo_noise.items()))
        _law_tables(rep, laws.uhfo, "UHFO law", "V")
    _noise_section(rep, laws, plt)
    if scale_factor is not None:
        from rlgsim.lab.identify.scale_factor_report import scale_factor_section
        scale_factor_section(rep, scale_factor, device)
