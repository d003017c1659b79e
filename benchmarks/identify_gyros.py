"""Several gyros into one twin (issue 28; src/rlgsim/lab/identify/twin_gyros.py): over drawn
three-gyro units whose gyros have different bias laws (the truth of
tests/test_identify_gyros.py: x linear, y linear + quadratic, z through its UHFO only; the lab
CSV keeps ``uhfo_z_v`` alone), how often each true coefficient lies within 1 and 2 of its
stated standard errors (model-averaged, selection included; nominal 68 / 95 %), and the CPU
time of the three-gyro identification against a one-gyro identification of the same
recording (``--gyro z``): the thermal network is fitted once, so the ratio should stay well
under 3 (three separate identifications).

    python benchmarks/identify_gyros.py [--units 5] [--pairs 2]

Run it alone on a quiet machine for a verdict (benchmarks/_machine.py): a timing figure with
the others' load above the limit is printed with "no verdict".
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]

import identify_truth as IT                     # noqa: E402
from _machine import LoadWatch, alternate, machine, own_cpu, spread   # noqa: E402

#: one bias law per gyro (x, y, z): tests/test_identify_gyros.py's truth
TRUTH = IT.THREE_GYRO_BIAS
TERMS = IT.BIAS_TERMS
#: the ratio of CPU times (three gyros / one gyro) below which sharing the thermal fit pays
RATIO_TARGET = 3.0


def coverage(units: int, work: pathlib.Path) -> pathlib.Path:
    """Part A; returns the first unit's recording (for part B)."""
    from rlgsim.lab.identify import identify
    rows: dict[str, list[float]] = {}
    first = None
    print(f"A. coverage over {units} drawn three-gyro units (4.9 h, 1 Hz, rlg_single, "
          f"PROGRAMME_A; every coefficient of the truth's keys that a gyro's law holds, a "
          f"true 0 included; z = (estimate − truth) / model-averaged SE)")
    for u in range(units):
        f = work / f"unit{u}"
        f.mkdir()
        lab = IT.three_gyro_lab_csv(f, TRUTH, seed=11 + u, device_seed=11 + u)
        first = first or lab
        r = identify(str(lab), f / "twin", overwrite=True)
        line = []
        for i, g in enumerate(r.gyros):
            sel = g.laws.bias
            for key, term in TERMS.items():
                true = TRUTH[key][i]
                if term not in sel.averaged:
                    if true != 0.0:
                        rows.setdefault(f"{g.axis}.{term}", []).append(float("inf"))
                    continue
                v, se, _ = sel.averaged[term]
                z = (v - true) / se
                rows.setdefault(f"{g.axis}.{term}", []).append(z)
                line.append(f"{g.axis}.{term} {z:+.2f}")
        print(f"   unit {u + 1}: {r.seconds:.1f} s wall; " + ", ".join(line))
    zs = [abs(z) for v in rows.values() for z in v]
    n = len(zs)
    c1 = 100.0 * sum(z <= 1 for z in zs) / n
    c2 = 100.0 * sum(z <= 2 for z in zs) / n
    print(f"   per coefficient (|z| ≤ 1 / ≤ 2 of {units}): " + "; ".join(
        f"{k} {sum(abs(z) <= 1 for z in v)}/{sum(abs(z) <= 2 for z in v)}"
        for k, v in rows.items()))
    print(f"   pooled over {n} estimates: 1σ {c1:.0f} % (nominal 68), 2σ {c2:.0f} % "
          f"(nominal 95); with {n} estimates of few units the binomial spread is "
          f"±{100 * (0.68 * 0.32 / n) ** 0.5:.0f} / ±{100 * (0.95 * 0.05 / n) ** 0.5:.0f} "
          f"points (1 SE), and the units share one truth")
    return first


def timing(lab: pathlib.Path, pairs: int, work: pathlib.Path, watch: LoadWatch) -> None:
    """Part B: CPU (this process and its reaped workers) and wall of the three-gyro
    identification and of the one-gyro one, alternated."""
    from rlgsim.lab.identify import identify
    walls: dict[str, list[float]] = {"three": [], "one": []}

    def run(kind: str) -> float:
        t, c = time.perf_counter(), own_cpu()
        identify(str(lab), work / f"t_{kind}", gyro=None if kind == "three" else "z",
                 overwrite=True)
        walls[kind].append(time.perf_counter() - t)
        return own_cpu() - c
    three, one = alternate(lambda: run("three"), lambda: run("one"), pairs)
    ratios = [a / b for a, b in zip(three, one)]
    print(f"\nB. CPU time, three gyros vs one gyro (--gyro z) on unit 1, {pairs} alternated "
          f"pairs")
    for what, cpu, wall in (("three gyros", three, walls["three"]),
                            ("one gyro", one, walls["one"])):
        print(f"   {what}: CPU {spread(cpu, '.1f', ' s')}; wall {spread(wall, '.1f', ' s')}")
    med = sorted(ratios)[len(ratios) // 2]
    print(f"   ratio (three / one, CPU): {spread(ratios, '.2f')}; target < {RATIO_TARGET:g} "
          f"(three separate identifications ≈ 3): "
          f"{watch.verdict(med < RATIO_TARGET, runs=pairs)}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--units", type=int, default=5, help="drawn units for part A")
    p.add_argument("--pairs", type=int, default=2, help="alternated timing pairs for part B "
                                                        "(5 for a verdict)")
    a = p.parse_args(argv)
    watch = LoadWatch()
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        work = pathlib.Path(tmp)
        lab = coverage(a.units, work)
        timing(lab, a.pairs, work, watch)
    print(watch.line())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
