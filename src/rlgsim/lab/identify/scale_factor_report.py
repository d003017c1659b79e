"""The scale-factor section of the identification report: the one-line summary and refusals,
the law's coefficients with their standard errors, the rate segments, and a figure of the
segment values K − K₀ against the law node's temperature with the fitted law."""

from __future__ import annotations

import numpy as np

from rlgsim.lab.report import Report, Table

__all__ = ["scale_factor_section"]


def scale_factor_section(rep: Report, sf, device_template: dict) -> None:
    """Append the section for the fit ``sf`` (:class:`~.scale_factor_fit.ScaleFactorFit`)."""
    import matplotlib.pyplot as plt

    from rlgsim.lab.identify.scale_factor_fit import SF_KEYS, _features, _template_law
    rep.heading("Scale factor (turntable rate segments)")
    rep.bullets(sf.lines)
    if sf.law is None:
        return
    law, _, _ = _template_law(device_template)
    rows = [{"key": "value_ppm", "estimate": sf.values["value_ppm"][0],
             "standard error": sf.values["value_ppm"][1], "status": "fitted"}]
    for t in sf.candidates:
        key = SF_KEYS[t]
        if key in sf.values:
            rows.append({"key": key, "estimate": sf.values[key][0],
                         "standard error": sf.values[key][1], "status": "BIC-selected"})
        elif t in sf.kept:
            rows.append({"key": key, "estimate": float(law.get(key, 0.0)),
                         "standard error": None, "status": "kept from the template"})
        else:
            rows.append({"key": key, "estimate": 0.0, "standard error": None,
                         "status": "not selected by BIC"})
    rep.table(Table.from_records(
        f"Scale-factor law K − K₀ [ppm] on node {sf.node}, t_ref {sf.t_ref_c:g} °C", rows,
        note=f"generalised least squares with the segments' noise and bias-law covariance; "
             f"constant resolved by the segments alone to ± {sf.resolution_ppm:.3g} ppm"))
    s = sf.segments
    rep.attachment(Table.from_records("Rate segments", [
        {"t0_s": a, "t1_s": b, "rate_deg_s": r, "temp_c": T, "k_ppm": k, "se_ppm": e,
         "residual_ppm": res} for a, b, r, T, k, e, res in
        zip(s["t0_s"], s["t1_s"], s["rate_deg_s"], s["temp_c"], s["k_ppm"], s["se_ppm"],
            s.get("residual_ppm", np.full(len(s["k_ppm"]), np.nan)))]))
    fig, ax = plt.subplots(figsize=(7, 4))
    pos = s["rate_deg_s"] > 0
    for mask, lab in ((pos, "+ rate"), (~pos, "− rate")):
        ax.errorbar(s["temp_c"][mask], s["k_ppm"][mask], yerr=s["se_ppm"][mask], fmt="o",
                    ms=3, label=f"segments, {lab}")
    T = np.linspace(s["temp_c"].min() - 1, s["temp_c"].max() + 1, 200)
    feats = _features(T, sf.t_ref_c, law)
    y = np.full(T.shape, sf.values["value_ppm"][0])
    for t in sf.candidates:
        key = SF_KEYS[t]
        c = sf.values[key][0] if key in sf.values else (float(law.get(key, 0.0))
                                                         if t in sf.kept else 0.0)
        y = y + c * feats[t]
    ax.plot(T, y, "k-", label="identified law")
    ax.set_xlabel(f"node {sf.node} temperature [°C]")
    ax.set_ylabel("K − K₀ [ppm]")
    ax.legend(fontsize=8)
    rep.figure(fig, "scale_factor", "Scale factor per rate segment and the identified law")
