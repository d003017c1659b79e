"""What a cubic cannot follow in paper 000's 15 parameters, against the calibration noise.

Paper 000 (shared/papers/000_*.txt §4.2) finds HHO-RVR better than the cubic LSM by 35.27 % in
RMSE on average (maximum 80.12 %), and says why: some parameter-vs-temperature curves show
"large dispersion, obvious fluctuations, and complex nonlinearity" that RVR follows and a cubic
cannot. Its figures and tables did not survive in the text copy, so their shapes cannot be read
off; what can be measured is how much shape *beyond a cubic* our presets give each parameter
over the campaign, against the scatter of the per-calibration estimates. For a parameter with
estimate noise σ_e (std of estimate − truth) and true structure a cubic misses, std n (the
truth minus its own least-squares cubic in T), a model that followed the truth exactly would
score RMSE ≈ σ_e against the estimates, the cubic ≈ √(σ_e² + n²); the RMSE improvement is then
at most ``1 − σ_e / √(σ_e² + n²)`` (the "ceiling"). Inverting it, the paper's average 35.27 %
needs n/σ_e ≈ 1.18 on average, its maximum 80.12 % needs n/σ_e ≈ 4.9.

Reads ``model_predictions.csv`` of a paper000 study report (``rlgsim study paper000 -o DIR``):
per parameter and calibration window the probe temperature, the calibration estimate, the true
window-mean parameter and both models' predictions. Nothing is simulated or fitted here but the
cubic of the truth (numpy.polyfit, the same degree as the study's LSM).

Usage: ``python benchmarks/paper000_shapes.py DIR``
"""

from __future__ import annotations

import argparse
import math
import pathlib

import numpy as np
import pandas as pd

#: Paper 000 §4.2, Table 2 (RMSE improvement of HHO-RVR over the cubic LSM): average, maximum.
PAPER_AVERAGE_PCT, PAPER_MAX_PCT = 35.27, 80.12


def ratio_for_gain(gain_pct: float) -> float:
    """n/σ_e for which the ceiling ``1 − 1/√(1 + r²)`` equals ``gain_pct`` [%]."""
    g = gain_pct / 100.0
    return math.sqrt(1.0 / (1.0 - g) ** 2 - 1.0)


def shapes(table: pd.DataFrame) -> pd.DataFrame:
    """One row per parameter: σ_e, n (beyond-cubic std of the truth), n/σ_e, the ceiling [%],
    and ours: RMSE of each model against the estimates and the improvement [%]."""
    rows = []
    for name, d in table.groupby("parameter", sort=False):
        t, est, truth = (d[c].to_numpy(float) for c in ("temperature_c", "estimate", "truth"))
        cubic = np.polyval(np.polyfit(t - t.mean(), truth, 3), t - t.mean())
        noise = float(np.std(est - truth, ddof=1))
        beyond = float(np.std(truth - cubic, ddof=1))
        rmse = {m: float(np.sqrt(np.mean((d[m].to_numpy(float) - est) ** 2)))
                for m in ("hho_rvr", "lsm")}
        rows.append({"parameter": name, "noise σ_e": noise, "beyond cubic n": beyond,
                     "n/σ_e": beyond / noise,
                     "ceiling %": 100.0 * (1.0 - noise / math.hypot(noise, beyond)),
                     "RVR RMSE": rmse["hho_rvr"], "LSM RMSE": rmse["lsm"],
                     "ours %": 100.0 * (1.0 - rmse["hho_rvr"] / rmse["lsm"])})
    return pd.DataFrame(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report", help="output folder of `rlgsim study paper000`")
    args = ap.parse_args()
    path = pathlib.Path(args.report) / "model_predictions.csv"
    if not path.is_file():
        raise SystemExit(f"{path}: not found; give the output folder of `rlgsim study paper000`")
    out = shapes(pd.read_csv(path))
    with pd.option_context("display.width", 160, "display.float_format", "{:.4g}".format):
        print(out.to_string(index=False))
    print(f"\naverage: ours {out['ours %'].mean():.1f} %, ceiling {out['ceiling %'].mean():.1f} %"
          f" (paper {PAPER_AVERAGE_PCT} %); n/σ_e median {out['n/σ_e'].median():.2f}")
    print(f"n/σ_e the paper's average needs: {ratio_for_gain(PAPER_AVERAGE_PCT):.2f}; its "
          f"maximum: {ratio_for_gain(PAPER_MAX_PCT):.2f}")


if __name__ == "__main__":
    main()
