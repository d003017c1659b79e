"""Ablation of the paper-000 IMU: its temperature control (``[thermal.heaters.thermostat]`` of
scenarios/thermal/rlg_imu.toml) and the thermal grid it runs on, switched in turn → what paper
000 measures: the IMU temperature between calibrations (§4.1: "about 0.4 °C"), Table 2 (HHO-RVR
against the cubic LSM: average RMSE improvement, parameters where RVR wins, and the same against
the truth) and Table 3 (residual variance after system-level compensation to 50 °C).

    python benchmarks/ablation_rlg_imu_000.py [--variants NAME,...] [--hho N,ITER]
                                             [--rate HZ] [--scenario NAME]

Every variant runs the paper000 study recipe on the full 175-calibration campaign from variant
copies of the thermal preset, the device preset, the scenario and the study file in a temporary
folder (``--scenario paper000_short`` for a quick check). ``--hho`` sets the Harris-hawks search (default 10 hawks × 60 iterations instead of the
study's 30 × 500, for time: the widths it finds are within a few percent); ``--rate`` the IMU
sample rate (default the study's 100 Hz). The table it prints is in docs/studies.md (Paper 000).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import re
import sys
import tempfile
import time

import h5py
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

SC = ROOT / "scenarios"
PARAMS = ([f"gyro_bias_{a}" for a in "xyz"] + [f"gyro_sf_{a}" for a in "xyz"]
          + [f"accel_bias_{a}" for a in "xyz"] + [f"accel_sf_pos_{a}" for a in "xyz"]
          + [f"accel_sf_neg_{a}" for a in "xyz"])
WINDOW_S = 2400.0           # one 40-min calibration

VARIANTS = {
    "nominal": "as shipped (thermostat 50 °C / 10 W on the base plate, 5 s thermal grid)",
    "no_thermostat": "no temperature control (heater table removed), 5 s grid",
    "grid_1s": "as shipped on the 1 s thermal grid the scenarios had (controller every 1 s)",
    "previous": "before issue 12: no temperature control, 1 s grid",
}


def _no_heater(text: str) -> str:
    out = re.sub(r"\n\[thermal\.heaters\.[^\]]+\]\n(?:[^\[\n].*\n|\n)*?(?=\n?\[)", "\n", text)
    assert "[thermal.heaters" not in out
    return out


def run_variant(name: str, tmp: pathlib.Path, hho: tuple[int, int], rate_hz: float,
                scenario: str = "paper000_campaign") -> dict:
    from rlgsim.lab.study import parse_study, recipe_module

    d = tmp / name
    d.mkdir()
    thermal = (SC / "thermal" / "rlg_imu.toml").read_text()
    if name in ("no_thermostat", "previous"):
        thermal = _no_heater(thermal)
    (d / "thermal.toml").write_text(thermal)
    dev = (SC / "devices" / "rlg_imu_000.toml").read_text()
    (d / "rlg_imu_000.toml").write_text(
        re.sub(r'thermal_preset = "[^"]*"', 'thermal_preset = "thermal.toml"', dev))
    sc = (SC / f"{scenario}.toml").read_text().replace('device = "rlg_imu_000"',
                                                      'device = "rlg_imu_000.toml"')
    sc = re.sub(r"sample_rate_hz = \d+", f"sample_rate_hz = {rate_hz:g}", sc)
    if name in ("grid_1s", "previous"):
        sc = re.sub(r"thermal_step_s = [\d.]+", "thermal_step_s = 1", sc)
    (d / f"{scenario}.toml").write_text(sc)
    study = (SC / "studies" / "paper000.toml").read_text()
    study = study.replace('scenario = "paper000_campaign"', f'scenario = "{scenario}.toml"')
    study = re.sub(r"(?m)^hawks = \d+", f"hawks = {hho[0]}", study)
    study = re.sub(r"(?m)^iterations = \d+", f"iterations = {hho[1]}", study)
    (d / "study.toml").write_text(study)
    s = parse_study(study, str(d / "study.toml"), base_dir=d, default_name="paper000")
    recipe = recipe_module(s)
    cfg = recipe.check(s)
    out = d / "out"
    res = recipe.run(s, cfg, out, unit=0, progress=False)
    rows = {(c, m): v for c, m, v in res.rows}
    row = {"variant": name}
    row["RVR/LSM RMSE improvement %"] = rows[("hho_rvr", "avg_improvement_rmse_pct")]
    row["RVR wins (RMSE)"] = sum(rows[("hho_rvr", f"{p}.rmse")] < rows[("lsm", f"{p}.rmse")]
                                 for p in PARAMS)
    row["same vs truth %"] = rows[("hho_rvr", "avg_improvement_truth_rmse_pct")]
    row["RVR wins (truth)"] = sum(rows[("hho_rvr", f"{p}.truth_rmse")]
                                  < rows[("lsm", f"{p}.truth_rmse")] for p in PARAMS)
    row["residual variance improvement %"] = rows[("hho_rvr",
                                                   "avg_improvement_residual_variance_pct")]
    data = next((out / "data").glob(f"{scenario}*_u0.h5"))
    with h5py.File(data) as f:
        names = [n.decode() for n in f["probes/probe"][()]]
        t = f["probes/time"][()]
        base = f["probes/temperature"][:, names.index("base")]
        heater = f["thermal/heater_power"][()][:, 0] if "heater_power" in f["thermal"] else None
        sp = f["thermal/chamber_setpoint"][()]
        ts = f["thermal/time"][()]
    soak = float(ts[np.argmax(np.abs(sp - sp[0]) > 1e-9)] - (ts[1] - ts[0]))   # ramp start
    k = np.floor((t - soak) / WINDOW_S).astype(int)
    n = int((t[-1] - soak) // WINDOW_S)
    ok = (t >= soak) & (k < n)
    means = np.array([base[ok & (k == i)].mean() for i in range(n)])
    step = np.diff(means)
    row["ΔT per calibration mean / min / max °C"] = (f"{step.mean():.3f} / {step.min():.3f} / "
                                                     f"{step.max():.3f}")
    row["calibrations with ΔT < 0.2 °C"] = int(np.sum(step < 0.2))
    row["base probe span °C"] = f"{means[0]:.1f} … {means[-1]:.1f}"
    if heater is not None:
        row["heater W (min … max)"] = f"{heater.min():.1f} … {heater.max():.1f}"
    return row


def main(argv: list[str]) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--variants", default=",".join(VARIANTS))
    p.add_argument("--hho", default="10,60", help="HAWKS,ITERATIONS")
    p.add_argument("--rate", type=float, default=100.0)
    p.add_argument("--scenario", default="paper000_campaign",
                   help="paper000_short for a quick check (8 calibrations)")
    args = p.parse_args(argv)
    from _machine import machine
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.2f}")
    names = args.variants.split(",")
    for n in names:
        if n not in VARIANTS:
            raise SystemExit(f"--variants: unknown variant {n!r}; allowed: {', '.join(VARIANTS)}")
    hho = tuple(int(x) for x in args.hho.split(","))
    rows = []
    with tempfile.TemporaryDirectory(prefix="ablation000-") as tmp:
        for n in names:
            t0 = time.perf_counter()
            rows.append(run_variant(n, pathlib.Path(tmp), hho, args.rate, args.scenario))
            print(f"  {n}: {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    cols = [c for c in rows[0] if c != "variant"] + ["heater W (min … max)"]
    cols = list(dict.fromkeys(cols))
    print("\n| variant | " + " | ".join(cols) + " |")
    print("|---|" + "---|" * len(cols))
    for row in rows:
        cells = [row.get(c, "—") for c in cols]
        print(f"| {row['variant']} | " + " | ".join(
            f"{c:.1f}" if isinstance(c, float) else str(c) for c in cells) + " |")
    print("\nvariants:")
    for n in names:
        print(f"  {n}: {VARIANTS[n]}")


if __name__ == "__main__":
    main(sys.argv[1:])
