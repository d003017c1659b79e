"""Ablation of the paper-002 gyro: each mechanism of the re-derived device switched off in turn
(everything else as shipped) → Table 1's measurement (raw σ per environment), the oracle floor
and the ranking of the paper002 study.

    python benchmarks/ablation_rlg_002.py [--variants NAME,...] [--rate HZ]

Mechanisms (docs/thermal.md §4.2a, docs/sensors.md rlg_002): the real chamber of the six
scenarios (``[chamber.controller]``: PI loop, authority limits, ripple), its ripple alone, the
mount path of ``rlg_002_fixture`` (the static fixture's floor-insulation leak to the laboratory;
and, for comparison, the 2.2 W/K column of paper 003's fixture it replaced), the nominal ballast
asymmetry, and the reading of Table 1 the preset is fitted to (benchmarks/fit_rlg_002.py: "before"
= mean bias, "after" = σ; the variant ``sigma_reading`` restores the preset and study settings of
the previous reading, both rows σ).
Every variant runs the whole paper002 study recipe (six environments, train and test, the
study's seeds and device_seed) from variant copies of the presets, scenarios and study file in
a temporary folder. ``--rate`` sets the IMU sample rate of the variant runs (100 s statistics
do not depend on it; default 10 Hz instead of 100 Hz, for speed). The table it prints is in
docs/studies.md (Paper 002).
"""

from __future__ import annotations

import argparse
import pathlib
import re
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

SC = ROOT / "scenarios"
ENVS = ("const_m40", "const_20", "const_60", "cycle_1cpm", "cycle_3cpm", "cycle_5cpm")
#: the preset under the previous reading of Table 1 (both rows σ: no mean bias, the design law
#: × 0.16, the noise fitted to 6.8e-3 °/h per 100 s window, 2.14 pulses/arcsec) ...
SIGMA_READING = {"value_deg_per_h": "0.0", "c1_deg_per_h_per_k": "6.4e-6",
                 "c2_deg_per_h_per_k2": "1.9e-7", "gyro_arw_deg_per_sqrt_h": "0.00096",
                 "gyro_bias_instability_deg_per_h": "0.002",
                 "scale_factor_pulses_per_arcsec": "2.14"}
#: ... and its modified RBFNN threshold (ρ = goal / (6.8e-3)², the study file's comment)
SIGMA_READING_RHO = "0.0225"
TIE = 0.005          # as the study: closer than 0.5 % of the raw σ

VARIANTS = {
    "nominal": "as shipped",
    "no_chamber": "no chamber loop (air = the setpoint through a 60 s lag: no ripple, "
                  "no overshoot, rate limit 10 K/min)",
    "no_ripple": "chamber loop without its ripple (ripple_amplitude_c = 0)",
    "no_mount": "no mount path (the fixture not linked to the laboratory)",
    "warm_mount": "the fixture on paper 003's 2.2 W/K column to the laboratory (the value "
                  "rlg_002_fixture carried before the static floor mount)",
    "no_asymmetry": "no nominal ballast asymmetry",
    "rlg_single": "the previous thermal preset rlg_single (cabinet on chamber air)",
    "sigma_reading": "the preset and modified-RBFNN ρ of the previous reading (both rows of "
                     "Table 1 σ: no mean bias, noise ×5, 2.14 pulses/arcsec, ρ = 0.0225)",
}


def _parts(name: str) -> set[str]:
    return {name}


def _thermal(parts: set[str]) -> str:
    if "rlg_single" in parts:
        return (SC / "thermal" / "rlg_single.toml").read_text()
    t = (SC / "thermal" / "rlg_002_fixture.toml").read_text()
    if "no_mount" in parts:
        t = re.sub(r'\[\[thermal\.links\]\]\nbetween = \["table", "lab"\]\n[^\n]*\n', "", t)
    if "warm_mount" in parts:
        t, n = re.subn(r'(between = \["table", "lab"\]\nconductance_w_per_k = )[0-9.eE+-]+',
                       r"\g<1>2.2", t)
        assert n == 1, "rlg_002_fixture: table-lab link not found"
    if "no_asymmetry" in parts:
        t = re.sub(r"power_factors = \{[^}]*\}[^\n]*\n", "", t)
    return t


def _device(parts: set[str]) -> str:
    d = (SC / "devices" / "rlg_002.toml").read_text()
    d = re.sub(r'thermal_preset = "[^"]*"', 'thermal_preset = "thermal.toml"', d)
    if "sigma_reading" in parts:
        for key, value in SIGMA_READING.items():
            d, n = re.subn(rf"(?m)^{key} = [^\s#]+", f"{key} = {value}", d, count=1)
            assert n == 1, f"rlg_002: {key} not found"
    return d


def _scenario(env: str, parts: set[str], rate_hz: float) -> str:
    t = (SC / f"paper002_{env}.toml").read_text().replace('device = "rlg_002"',
                                                          'device = "rlg_002.toml"')
    t = re.sub(r"sample_rate_hz = \d+", f"sample_rate_hz = {rate_hz:g}", t)
    if "no_chamber" in parts:
        t = re.sub(r"\[chamber\.controller\]\n(?:[a-z_]+ = [^\n]*\n)+", "", t)
    if "no_ripple" in parts:
        t = re.sub(r"ripple_amplitude_c = [^\n]*", "ripple_amplitude_c = 0.0", t)
    return t


def run_variant(name: str, tmp: pathlib.Path, rate_hz: float) -> dict:
    from rlgsim.lab.studies import environments as ENV
    from rlgsim.lab.study import parse_study

    parts = _parts(name)
    d = tmp / name
    d.mkdir()
    (d / "thermal.toml").write_text(_thermal(parts))
    (d / "rlg_002.toml").write_text(_device(parts))
    study = (SC / "studies" / "paper002.toml").read_text()
    for env in ENVS:
        (d / f"paper002_{env}.toml").write_text(_scenario(env, parts, rate_hz))
        study = study.replace(f'scenario = "paper002_{env}"', f'scenario = "paper002_{env}.toml"')
    if "sigma_reading" in parts:
        study = re.sub(r"rho = [0-9.eE+-]+", f"rho = {SIGMA_READING_RHO}", study)
    (d / "study.toml").write_text(study)
    s = parse_study(study, str(d / "study.toml"), base_dir=d, default_name="paper002")
    config = ENV.check(s)
    res = ENV.run(s, config, d / "out", unit=0, progress=False).details.results
    row: dict = {"variant": name, "envs": {}}
    for r in res:
        sc = r.scores
        raw = sc["raw"]["stability_before"]
        methods = [m for m in sc if m not in ("raw",) and not m.startswith("truth")]
        oracle = next(v for m, v in sc.items() if m.startswith("truth"))
        best = min(methods, key=lambda m: sc[m]["stability_after"])
        best_true = min(methods, key=lambda m: sc[m]["resid_std_true"])
        row["envs"][r.env.name] = {
            "raw": raw, "paper": r.env.published.stability_before,
            "mean": float(np.mean([rs.y.mean() for rs in r.tests])),
            "mlr_after": sc["MLR (BIC)"]["stability_after"],
            "mlr_paper": r.env.published.stability_after["MLR (BIC)"],
            "oracle_factor": raw / oracle["stability_after"],
            "best": best, "best_factor": raw / sc[best]["stability_after"],
            "best_true": best_true,
            "mod>=rbf": sc["Modified RBFNN"]["stability_after"]
            <= sc["RBFNN"]["stability_after"] + TIE * raw,
            "mod>mlr": sc["Modified RBFNN"]["stability_after"]
            < sc["MLR (BIC)"]["stability_after"] - TIE * raw,
        }
    return row


def main(argv: list[str]) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--variants", default=",".join(VARIANTS))
    p.add_argument("--rate", type=float, default=10.0)
    args = p.parse_args(argv)
    from _machine import machine
    import os
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.2f}")
    t_all = time.perf_counter()
    names = args.variants.split(",")
    for n in names:
        if n not in VARIANTS:
            raise SystemExit(f"--variants: unknown variant {n!r}; allowed: {', '.join(VARIANTS)}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="ablation002-") as tmp:
        for n in names:
            t0 = time.perf_counter()
            rows.append(run_variant(n, pathlib.Path(tmp), args.rate))
            print(f"  {n}: {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    envs = list(rows[0]["envs"])
    print("\nmean raw bias ours/paper ('before', read as the mean) per environment; MLR σ after "
          "ours/paper (range); raw σ (range, °/h); oracle factor (raw σ / σ with the true law "
          "removed); best model by σ after (its factor σ/σ); claims by σ after (count of 6)\n")
    print("| variant | " + " | ".join(f"mean/paper {e}" for e in envs)
          + " | MLR σ after/paper | raw σ | oracle factor (range) | best by σ after | "
            "mod ≥ RBF | mod > MLR |")
    print("|---|" + "---|" * (len(envs) + 6))
    for row in rows:
        e = row["envs"]
        ratios = " | ".join(f"{e[k]['mean'] / e[k]['paper']:.3f}" for k in envs)
        mlr = [e[k]["mlr_after"] / e[k]["mlr_paper"] for k in envs]
        raw = [e[k]["raw"] for k in envs]
        ratios += f" | {min(mlr):.3f} … {max(mlr):.3f} | {min(raw):.5f} … {max(raw):.5f}"
        of = [e[k]["oracle_factor"] for k in envs]
        best = ", ".join(f"{k}: {e[k]['best'].replace(' (BIC)', '')} {e[k]['best_factor']:.3f}"
                         for k in envs)
        print(f"| {row['variant']} | {ratios} | {min(of):.3f} … {max(of):.3f} | {best} | "
              f"{sum(e[k]['mod>=rbf'] for k in envs)} | {sum(e[k]['mod>mlr'] for k in envs)} |")
    print(f"\nload average after: {os.getloadavg()[0]:.2f}; {time.perf_counter() - t_all:.0f} s")
    print("\nvariants:")
    for n in names:
        print(f"  {n}: {VARIANTS[n]}")


if __name__ == "__main__":
    main(sys.argv[1:])
