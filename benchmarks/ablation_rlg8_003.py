"""Ablation of the paper-003 device: each thermal mechanism of scenarios/thermal/rlg8_003_block.toml
switched off in turn (everything else, the bias law included, as shipped) → the Table 3 figures,
the raw bias STD and the 3-point vs multi-point ranking of the paper003 study.

    python benchmarks/ablation_rlg8_003.py [--variants NAME,...] [--rate HZ] [--pso N,ITER]

Every variant runs the whole paper003 study recipe (train on the four-rate cycles, verify on
the same programme with another seed, test on the random-rate profile) from variant copies of
the thermal preset, the device preset, the scenarios and the study file in a temporary folder.
``--rate`` sets the IMU sample rate of the variant runs (100 s statistics do not depend on it;
default 10 Hz instead of the study's 100 Hz, for speed) and ``--pso`` the swarm (default: the
study's 20 particles × 50 iterations). The table it prints is in docs/studies.md.
"""

from __future__ import annotations

import argparse
import pathlib
import re
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

SC = ROOT / "scenarios"


def _no_airflow(t: str) -> str:
    return re.sub(r"face_factors = \{[^}]*\}", "face_factors = { windward = 1.0, leeward = 1.0, "
                                                 "side = 1.0 }", t)


def _no_mount(t: str) -> str:
    # the turntable no longer reaches the laboratory: it follows the chamber air with its lag
    return re.sub(r'\[\[thermal\.links\]\]\nbetween = \["table", "lab"\]\n[^\n]*\n', "", t)


def _no_asymmetry(t: str) -> str:
    return re.sub(r"(power|capacitance|link)_factors = \{[^}]*\}[^\n]*\n", "", t)


def _thermal(name: str) -> str:
    t = (SC / "thermal" / "rlg8_003_block.toml").read_text()
    if name == "rlg_single":
        return (SC / "thermal" / "rlg_single.toml").read_text()
    for part, fn in (("airflow", _no_airflow), ("mount", _no_mount),
                     ("asymmetry", _no_asymmetry)):
        if part in name.split("+") or name == "all_off":
            t = fn(t)
    return t


VARIANTS = {
    "nominal": "as shipped",
    "airflow": "no one-sided airflow (all face factors 1)",
    "mount": "no mount boundary (turntable not linked to the laboratory)",
    "asymmetry": "no nominal arm asymmetry (instance factors 1)",
    "all_off": "all three off (the new cabinet and turntable nodes kept)",
    "rlg_single": "the previous preset rlg_single (symmetric block, cabinet at chamber air)",
    "old_law": "as shipped, but the previous bias law's gradients (A-G 0.0075, A-H 0.012, "
               "A-B 0.010, A-D 0.006 °/h/K)",
}

OLD_GRADIENTS = """gradients = [
  { a = "A", b = "G", coeff_deg_per_h_per_k = 0.0075 },
  { a = "A", b = "H", coeff_deg_per_h_per_k = 0.012 },
  { a = "A", b = "B", coeff_deg_per_h_per_k = 0.010 },
  { a = "A", b = "D", coeff_deg_per_h_per_k = 0.006 },
]
"""


def run_variant(name: str, tmp: pathlib.Path, rate_hz: float, pso: tuple[int, int] | None):
    from rlgsim.lab.studies import gradient_selection as GS
    from rlgsim.lab.study import parse_study

    d = tmp / name
    d.mkdir()
    thermal = _thermal(name) if name not in ("nominal", "old_law") else \
        (SC / "thermal" / "rlg8_003_block.toml").read_text()
    (d / "thermal.toml").write_text(thermal)
    dev = (SC / "devices" / "rlg8_003.toml").read_text()
    dev = re.sub(r'thermal_preset = "[^"]*"', 'thermal_preset = "thermal.toml"', dev)
    if name == "old_law":
        dev = re.sub(r"gradients = \[.*?\n\]\n", OLD_GRADIENTS, dev, flags=re.S)
    (d / "rlg8_003.toml").write_text(dev)
    for sc in ("paper003_cycles", "paper003_random"):
        text = (SC / f"{sc}.toml").read_text().replace('device = "rlg8_003"',
                                                      'device = "rlg8_003.toml"')
        text = re.sub(r"sample_rate_hz = \d+", f"sample_rate_hz = {rate_hz:g}", text)
        (d / f"{sc}.toml").write_text(text)
    study = (SC / "studies" / "paper003.toml").read_text()
    study = study.replace('train = ["paper003_cycles"]', 'train = ["paper003_cycles.toml"]')
    study = study.replace('test = [{ scenario = "paper003_cycles", seed = 3100, '
                          'run_seed = 3110 }, "paper003_random"]',
                          'test = [{ scenario = "paper003_cycles.toml", seed = 3100, '
                          'run_seed = 3110 }, "paper003_random.toml"]')
    if pso is not None:
        study = study.replace("n_agents = 20, max_iter = 50",
                              f"n_agents = {pso[0]}, max_iter = {pso[1]}")
    (d / "study.toml").write_text(study)
    s = parse_study(study, str(d / "study.toml"), base_dir=d, default_name="paper003")
    config = GS.check(s)
    res = GS.run(s, config, d / "out", unit=0, progress=False)
    out = res.details
    figs = {n: o for n, o, _ in GS.table3_figures(config.points, out.corr,
                                                  config.published_matrix)}
    row = {"variant": name, **figs}
    for pt in config.paper_tables:
        sc = out.per_test[pt.test]
        t, p = sc[pt.traditional]["stability_after"], sc[pt.proposed]["stability_after"]
        row[f"raw {pt.test}"] = sc[pt.traditional]["stability_before"]
        row[f"3-pt {pt.test}"] = t
        row[f"multi {pt.test}"] = p
        row[f"3-pt/multi {pt.test}"] = t / p
    row["multi-point inputs"] = ", ".join(
        g for g, _, kept in next(iter(out.listings.values())) if kept)
    return row


def main(argv: list[str]) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--variants", default=",".join(VARIANTS))
    p.add_argument("--rate", type=float, default=10.0)
    p.add_argument("--pso", default=None, help="N,ITER")
    args = p.parse_args(argv)
    from _machine import machine
    print(f"machine: {machine()}")
    pso = tuple(int(x) for x in args.pso.split(",")) if args.pso else None
    with tempfile.TemporaryDirectory() as tmpdir:
        for name in args.variants.split(","):
            t0 = time.perf_counter()
            row = run_variant(name, pathlib.Path(tmpdir), args.rate, pso)
            print(f"## {name}: {VARIANTS[name]} ({time.perf_counter() - t0:.0f} s)")
            for k, v in row.items():
                print(f"   {k}: {v:.4f}" if isinstance(v, float) else f"   {k}: {v}")
            sys.stdout.flush()


if __name__ == "__main__":
    main(sys.argv[1:])
