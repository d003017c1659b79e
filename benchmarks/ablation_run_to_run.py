"""Ablation of the run-to-run draws (sim/run/run_to_run.py): the paper003 and paper001 studies
with train and test on different days, each mechanism switched off in turn.

    python benchmarks/ablation_run_to_run.py [--study paper003|paper001|both]
                                             [--variants NAME,...] [--rate HZ] [--pso N,ITER]

Variants (``--variants`` picks some; default all):

* ``shipped``     every mechanism as in the device preset's ``[run_to_run]`` table
* ``no_turn_on``  turn_on_bias_deg_per_h = 0
* ``no_lab``      lab_offset_c = 0
* ``no_chamber``  chamber_offset_c = 0
* ``no_film``     film_coefficient_rel = 0
* ``no_mount``    mount_conductance_rel = 0
* ``same_day``    all five 0: every run the same device in the same lab (main before the table)

Each draw has its own stream, so switching one off leaves the others' values as they were.
Every variant runs the whole study recipe from variant copies of the device preset, the
scenarios and the study file in a temporary folder; ``--rate`` sets the IMU sample rate
(100 s statistics do not depend on it; default 10 Hz instead of the study's 100 Hz, for
speed), ``--pso`` paper 003's swarm (default the study's 20 × 50). Printed per test run: the
raw STD, each compensator's STD after compensation and the test-day offset it leaves
(mean of y − ŷ, which an STD does not see). The tables are in docs/studies.md.
"""

from __future__ import annotations

import argparse
import os
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

KEYS = ("turn_on_bias_deg_per_h", "lab_offset_c", "chamber_offset_c", "film_coefficient_rel",
        "mount_conductance_rel")
VARIANTS = {"shipped": (), "no_turn_on": (KEYS[0],), "no_lab": (KEYS[1],),
            "no_chamber": (KEYS[2],), "no_film": (KEYS[3],), "no_mount": (KEYS[4],),
            "same_day": KEYS}
STUDIES = {"paper003": ("rlg8_003", "gradient_selection"),
           "paper001": ("trplg_001", "bias_compensation")}


def _device(device: str, off: tuple[str, ...]) -> str:
    text = (SC / "devices" / f"{device}.toml").read_text()
    for key in off:
        text, n = re.subn(rf"^{key} = [0-9.eE+-]+", f"{key} = 0.0", text, count=1, flags=re.M)
        if n != 1:
            raise SystemExit(f"{device}: key {key} not found")
    return re.sub(r'^thermal_preset = "([^"]*)"',
                  lambda m: f'thermal_preset = "{SC / "thermal" / (m.group(1) + ".toml")}"',
                  text, count=1, flags=re.M)


def run_variant(study: str, name: str, tmp: pathlib.Path, rate_hz: float,
                pso: tuple[int, int] | None) -> dict:
    import importlib

    from rlgsim.lab.study import parse_study
    device, recipe = STUDIES[study]
    (tmp / "device.toml").write_text(_device(device, VARIANTS[name]))
    st = (SC / "studies" / f"{study}.toml").read_text()
    for scen in sorted(set(re.findall(r'"(paper00[13]_[a-z_]+)"', st))):
        text = (SC / f"{scen}.toml").read_text()
        text = re.sub(r'^device = "[^"]*"', f'device = "{tmp / "device.toml"}"', text,
                      count=1, flags=re.M)
        text = re.sub(r"^sample_rate_hz = [0-9.]+", f"sample_rate_hz = {rate_hz:g}", text,
                      count=1, flags=re.M)
        (tmp / f"{scen}.toml").write_text(text)
        st = re.sub(r"^((?:train|test) = \[.*)$",            # the run lists only
                    lambda m: m.group(1).replace(f'"{scen}"', f'"{scen}.toml"'), st, flags=re.M)
    if pso is not None:
        st = st.replace("n_agents = 20, max_iter = 50", f"n_agents = {pso[0]}, max_iter = {pso[1]}")
    (tmp / "study.toml").write_text(st)
    s = parse_study(st, str(tmp / "study.toml"), base_dir=tmp, default_name=study)
    mod = importlib.import_module(f"rlgsim.lab.studies.{recipe}")
    config = mod.check(s)
    t0 = time.perf_counter()
    out = mod.run(s, config, tmp / "out", unit=0, progress=False).details
    from rlgsim.lab.studies.run_days import run_to_run_records
    rows = {}
    for spec in config.test:
        ys = out.runs[spec.key].series.y
        for comp, sc in out.per_test[spec.label].items():
            pred = out.predictions.get(spec.label, {}).get(comp)
            offset = float(np.mean(ys - pred)) if pred is not None else float("nan")
            rows[(spec.label, comp)] = (sc["stability_before"], sc["stability_after"], offset)
    return {"rows": rows, "draws": run_to_run_records(out.runs, config.train, config.test),
            "wall": time.perf_counter() - t0}


def main(argv: list[str] | None = None) -> int:
    from _machine import machine
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--study", default="both", choices=("paper003", "paper001", "both"))
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--pso", default=None, help="N,ITER (paper003's swarm)")
    a = ap.parse_args(argv)
    names = [v.strip() for v in a.variants.split(",") if v.strip()]
    bad = [v for v in names if v not in VARIANTS]
    if bad:
        print(f"--variants: unknown {', '.join(bad)}; allowed: {', '.join(VARIANTS)}",
              file=sys.stderr)
        return 2
    pso = tuple(int(x) for x in a.pso.split(",")) if a.pso else None
    studies = ("paper003", "paper001") if a.study == "both" else (a.study,)
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.2f}; IMU at {a.rate:g} Hz"
          + (f"; PSO {pso[0]}×{pso[1]}" if pso else ""))
    for study in studies:
        for name in names:
            with tempfile.TemporaryDirectory() as d:
                res = run_variant(study, name, pathlib.Path(d), a.rate, pso)
            print(f"## {study} {name} ({res['wall']:.0f} s; load {os.getloadavg()[0]:.2f})")
            for r in res["draws"]:
                print("   draw " + ", ".join(f"{k} {v}" for k, v in r.items()))
            print("   | test run | compensator | STD before | STD after | test-day offset |")
            for (label, comp), (b, s, o) in res["rows"].items():
                print(f"   | {label} | {comp} | {b:.5f} | {s:.5f} | {o:+.5f} |")
            sys.stdout.flush()
    print(f"load average at the end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
