"""Consistency of the calibration filter over a campaign: NEES per parameter group against the
χ² band.

    python benchmarks/calibration_nees.py TABLE.csv          # a table of 'rlgsim calibrate'
    python benchmarks/calibration_nees.py --run [--dir DIR]   # simulate paper000_campaign and
                                                              # calibrate it twice (minutes)

For every window with status "ok" and a truth column, the normalised error of each parameter
is (estimate − window-mean truth)/σ (σ the filter's 1σ); a group's NEES per window is the sum of
its squares over the group's parameters (the diagonal of the covariance: the table carries the
σ only). Over n windows and k parameters a consistent filter gives a mean NEES per window
inside χ²(k·n)'s central 95 % interval divided by n (scipy.stats.chi2), printed beside it.

``--run`` calibrates the campaign with three filters (docs/calibration.md, "Consistency per
group"): as shipped (the unit's own noise levels per axis and the accelerometer drift states:
what ``rlgsim calibrate`` does on a simulated dataset), without the drift states, and with the
preset's nominal levels and no drift states (the filter before issue 27); with the machine and
the load average.
"""

from __future__ import annotations

import argparse
import pathlib
import subprocess
import sys

import numpy as np


def _column(columns: list[str], name: str, part: str, unit: str) -> str | None:
    """The CSV column of a parameter's part ("", "_sigma", "_true"): with its unit suffix
    (``gyro_bias_x_sigma_deg_per_h``, what 'rlgsim calibrate' writes) or bare (the dataset
    group's names); None when absent."""
    for c in (f"{name}{part}_{unit}", f"{name}{part}"):
        if c in columns:
            return c
    return None


def groups(columns: list[str]) -> dict[str, list[tuple[str, str, str]]]:
    """Parameter groups of a calibration table (the name without its axis suffix): per
    parameter its (estimate, σ, truth) columns."""
    from rlgsim.estimators.calibration import PARAMETERS, UNIT_NAMES
    out: dict[str, list[tuple[str, str, str]]] = {}
    for p in PARAMETERS:
        cols = [_column(columns, p.name, part, UNIT_NAMES[p.unit])
                for part in ("", "_sigma", "_true")]
        if all(cols):
            out.setdefault(p.name.rsplit("_", 1)[0], []).append(tuple(cols))
    return out


def nees_table(path: pathlib.Path) -> list[tuple[str, int, float, float, float]]:
    """(group, k, mean NEES per window, band low, band high) per group and overall."""
    import pandas as pd
    from scipy import stats
    t = pd.read_csv(path)
    t = t[t["status"] == "ok"]
    n = len(t)
    rows, total, k_total = [], np.zeros(n), 0
    for g, ps in groups(list(t.columns)).items():
        z2 = np.sum([((t[e] - t[tr]) / t[s]).to_numpy() ** 2 for e, s, tr in ps], axis=0)
        if not np.all(np.isfinite(z2)):
            continue
        lo, hi = stats.chi2.ppf([0.025, 0.975], len(ps) * n) / n
        rows.append((g, len(ps), float(z2.mean()), float(lo), float(hi)))
        total, k_total = total + z2, k_total + len(ps)
    if k_total == 0:
        raise SystemExit(f"{path}: no parameter with estimate, sigma and truth columns")
    lo, hi = stats.chi2.ppf([0.025, 0.975], k_total * n) / n
    rows.append(("overall", k_total, float(total.mean()), float(lo), float(hi)))
    return rows


def _print(rows) -> None:
    print("| group | k | NEES per window | χ² 95 % band | inside |")
    print("|---|---|---|---|---|")
    for g, k, m, lo, hi in rows:
        print(f"| {g} | {k} | {m:.2f} | {lo:.2f}–{hi:.2f} | {'yes' if lo <= m <= hi else 'NO'} |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("table", nargs="?", type=pathlib.Path)
    ap.add_argument("--run", action="store_true", help="simulate and calibrate paper000_campaign")
    ap.add_argument("--dir", type=pathlib.Path, default=pathlib.Path("."))
    a = ap.parse_args(argv)
    if not a.run:
        if a.table is None:
            ap.error("give a calibration table or --run")
        _print(nees_table(a.table))
        return 0
    import os
    import time
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from _machine import machine

    import dataclasses

    from rlgsim.estimators.calibration import (CampaignSettings, DatasetReader, filter_settings,
                                               run_campaign)
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.2f}")
    data = a.dir / "paper000_campaign.h5"
    if not data.exists():
        a.dir.mkdir(parents=True, exist_ok=True)
        if subprocess.run([sys.executable, "-m", "rlgsim", "run", "paper000_campaign", "-o",
                           str(data), "-q"]).returncode != 0:
            return 2                       # rlgsim has said why in one line
    reader = DatasetReader(data)
    shipped = filter_settings(reader.noise(), unit_levels=reader.unit_noise())
    before = filter_settings(reader.noise())
    reader.close()
    variants = (("shipped", "the unit's own noise levels per axis and the drift states "
                 "(rlgsim calibrate)", shipped),
                ("no_drift", "the unit's own levels, no drift states",
                 dataclasses.replace(shipped, accel_drift=False)),
                ("before", "the preset's nominal levels, no drift states (before issue 27)",
                 dataclasses.replace(before, accel_drift=False)))
    for name, what, settings in variants:
        t0 = time.perf_counter()
        res = run_campaign(data, CampaignSettings(filter=settings))
        table = a.dir / f"paper000_campaign_calibration_{name}.csv"
        res.write_csv(table, units_in_names=True)
        print(f"\n### {name}: {what} — {time.perf_counter() - t0:.0f} s, load average "
              f"{os.getloadavg()[0]:.2f}")
        _print(nees_table(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
