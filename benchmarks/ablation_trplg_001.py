"""Ablation of the paper-001 device: each mechanism of trplg_001 / trplg_001_cabinet switched off
in turn (everything else as shipped) → paper 001's Table 1 correlations, the raw bias stability
and the rankings of the paper001 (or demo) study.

    python benchmarks/ablation_trplg_001.py [--study paper001|demo] [--variants NAME,...]
                                            [--rate HZ]

Variants (``--variants`` picks some; default all):

* ``shipped``      the presets as shipped
* ``no_heater``    no frequency-stabilisation heater (the X3 channel is passive glass)
* ``no_airflow``   the chamber's airflow the same on every face (face factors 1)
* ``no_mount``     the mounting plate follows the chamber air: 0.1 kg, no link to the laboratory
* ``no_hops``      no mode hops (the heater still saturates; the bias has no steps)
* ``no_spikes``    no read-out spikes
* ``no_anomalies`` neither hops nor spikes
* ``previous``     the presets before the re-derivation (rlg_single, smooth hot-side step, no
                   heater, no anomalies; commit PREVIOUS)

Every variant runs the whole study recipe (train on one cycle, test on the other) from
variant copies of the presets, the scenarios and the study file in a temporary folder.
``--rate`` sets the IMU sample rate of the variant runs (100 s statistics do not depend on it;
default 10 Hz instead of the study's 100 Hz, for speed). The table it prints is in
docs/studies.md (paper 001 and demo sections).
"""

from __future__ import annotations

import argparse
import csv
import pathlib
import re
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

SC = ROOT / "scenarios"
PREVIOUS = "ff840f7"          # main before the paper-001 re-derivation
TABLE1 = {"T": 0.71, "dT/dt": -0.43, "U": -0.82}


def _drop_table(t: str, header: str) -> str:
    """Remove ``[header]`` and its keys/comments up to the next table header."""
    pat = r"^\[" + re.escape(header) + r"\]\n(?:(?!\[).*\n|\n)*"
    out, n = re.subn(pat, "", t, count=1, flags=re.M)
    if n != 1:
        raise SystemExit(f"table [{header}] not found")
    return out


def _no_heater(th: str, dev: str) -> tuple[str, str]:
    return _drop_table(th, "thermal.heaters.frequency_stabilisation"), dev


def _no_airflow(th: str, dev: str) -> tuple[str, str]:
    return re.sub(r"face_factors = \{[^}]*\}",
                  "face_factors = { windward = 1.0, leeward = 1.0, side = 1.0 }", th), dev


def _no_mount(th: str, dev: str) -> tuple[str, str]:
    th = re.sub(r"^mass_kg = [0-9.]+(\s+# judgement: mounting-plate mass)", r"mass_kg = 0.1\1", th,
                flags=re.M)
    th = re.sub(r'\[\[thermal\.links\]\]\nbetween = \["plate", "lab"\]\n[^\n]*\n', "", th)
    return th, dev


def _no_hops(th: str, dev: str) -> tuple[str, str]:
    return th, _drop_table(dev, "anomalies.mode_hop")


def _no_spikes(th: str, dev: str) -> tuple[str, str]:
    return th, _drop_table(dev, "anomalies.pulse_spikes")


def _no_anomalies(th: str, dev: str) -> tuple[str, str]:
    dev = _drop_table(_drop_table(_drop_table(dev, "anomalies.mode_hop"),
                                  "anomalies.pulse_spikes"), "anomalies")
    return th, dev


def _previous(th: str, dev: str) -> tuple[str, str]:
    def show(path: str) -> str:
        return subprocess.run(["git", "show", f"{PREVIOUS}:{path}"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout
    return show("scenarios/thermal/rlg_single.toml"), show("scenarios/devices/trplg_001.toml")


VARIANTS = {"shipped": lambda th, dev: (th, dev), "no_heater": _no_heater,
            "no_airflow": _no_airflow, "no_mount": _no_mount, "no_hops": _no_hops,
            "no_spikes": _no_spikes, "no_anomalies": _no_anomalies, "previous": _previous}


def run_variant(name: str, study: str, rate_hz: float, tmp: pathlib.Path) -> dict:
    th, dev = VARIANTS[name]((SC / "thermal" / "trplg_001_cabinet.toml").read_text(),
                             (SC / "devices" / "trplg_001.toml").read_text())
    (tmp / "thermal.toml").write_text(th)
    dev = re.sub(r'^thermal_preset = "[^"]*"', f'thermal_preset = "{tmp / "thermal.toml"}"', dev,
                 count=1, flags=re.M)
    (tmp / "device.toml").write_text(dev)
    st = (SC / "studies" / f"{study}.toml").read_text()
    for scen in sorted(set(re.findall(r'"((?:paper001_|demo_)\w+)"', st))):
        text = (SC / f"{scen}.toml").read_text()
        text = re.sub(r'^device = "[^"]*"', f'device = "{tmp / "device.toml"}"', text, count=1,
                      flags=re.M)
        text = re.sub(r"^sample_rate_hz = [0-9.]+", f"sample_rate_hz = {rate_hz:g}", text,
                      count=1, flags=re.M)
        (tmp / f"{scen}.toml").write_text(text)
        st = st.replace(f'"{scen}"', f'"{tmp / (scen + ".toml")}"')
    (tmp / "study.toml").write_text(st)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "rlgsim", "study", str(tmp / "study.toml"), "-q",
                    "-o", str(tmp / "out")], check=True, cwd=tmp)
    wall = time.perf_counter() - t0
    corr = {r["input"]: float(r["ours (train, measured y)"])
            for r in csv.DictReader(open(tmp / "out" / "correlation.csv"))}
    scores = next((tmp / "out").glob("scores_*.csv"))
    sc = {r["compensator"]: r for r in csv.DictReader(open(scores))}
    return {"corr": corr, "scores": sc, "wall": wall}


def summarise(name: str, res: dict) -> str:
    corr, sc = res["corr"], res["scores"]

    def s(n: str, key: str = "stability_after") -> float:
        return float(sc[n][key])
    raw, floor = s("raw"), s("truth: temperature law")
    kinds = {"ir_lssvm": [n for n in sc if n.startswith("IR-LSSVM")],
             "lssvm": [n for n in sc if n.startswith("LSSVM")],
             "stepwise": [n for n in sc if n.startswith("Stepwise")],
             "ls": [n for n in sc if n.startswith("LS cubic")]}
    best = {k: min(v, key=s) for k, v in kinds.items() if v}
    singles = {n.split()[-1]: s(n) for n in kinds["ls"]}
    strongest = min(singles, key=singles.get) if len(singles) > 1 else "—"
    order = abs(corr["U"]) > abs(corr["T"]) > abs(corr["dT/dt"])
    signs = all((corr[k] > 0) == (v > 0) for k, v in TABLE1.items())
    spread = 0.0
    groups: dict[str, list[float]] = {}
    for n in kinds["ir_lssvm"]:
        groups.setdefault(n.split(" ", 2)[2], []).append(s(n))
    for v in groups.values():
        spread = max(spread, (max(v) - min(v)) / min(v) * 100)

    def rank(a: str, b: str) -> str:
        if a not in best or b not in best:
            return "—"
        m = (s(best[b]) - s(best[a])) / max(raw - floor, 1e-12) * 100
        return f"{'tie' if abs(m) < 0.5 else 'holds' if m > 0 else 'fails'} ({m:+.1f} %)"
    ir_vs = "—"
    if "lssvm" in best:
        allin = [n for n in kinds["ir_lssvm"] if n.endswith("T, dT/dt, U")]
        if allin:
            a = min(s(n) for n in allin)
            m = (s(best["lssvm"]) - a) / max(raw - floor, 1e-12) * 100
            ir_vs = f"{'tie' if abs(m) < 0.5 else 'holds' if m > 0 else 'fails'} ({m:+.1f} %)"
    return (f"| {name} | {corr['T']:+.2f} / {corr['dT/dt']:+.2f} / {corr['U']:+.2f} "
            f"({'order ✓' if order else 'order ✗'}{'' if signs else ', signs ✗'}) | {raw:.5f} | "
            f"{floor:.5f} | {strongest} | {rank('stepwise', 'ls')} | "
            f"{rank('lssvm', 'stepwise')} | {ir_vs} | "
            + (f"{spread:.1f} %" if groups else "—") + " |")


def main(argv: list[str] | None = None) -> int:
    import os

    from _machine import machine
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--study", default="paper001", choices=("paper001", "demo"))
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--rate", type=float, default=10.0)
    a = ap.parse_args(argv)
    names = [v.strip() for v in a.variants.split(",") if v.strip()]
    bad = [v for v in names if v not in VARIANTS]
    if bad:
        print(f"--variants: unknown {', '.join(bad)}; allowed: {', '.join(VARIANTS)}",
              file=sys.stderr)
        return 2
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.2f}")
    print(f"study {a.study}, IMU at {a.rate:g} Hz; Table 1 correlations on the train run "
          f"(paper {TABLE1['T']:+.2f} / {TABLE1['dT/dt']:+.2f} / {TABLE1['U']:+.2f}); stabilities "
          f"on the test run [°/h]; rankings by bias stability, margin in % of raw − floor")
    print("| variant | r_T / r_dT/dt / r_U | raw | oracle floor | strongest LS input | "
          "stepwise > LS | LSSVM > stepwise | IR-LSSVM ≥ LSSVM (all inputs) | "
          "IR-LSSVM weight spread (max over input sets) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in names:
        with tempfile.TemporaryDirectory() as d:
            res = run_variant(name, a.study, a.rate, pathlib.Path(d))
        print(summarise(name, res), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
