"""Speed of the exact thermal propagation on the paper-000 chamber programme.

Paper 000: the RLG-IMU soaks at −5 °C for 4 h, then the chamber ramps to 65 °C over 7000 min —
434,400 one-second thermal steps of the 42-node ``rlg_imu`` network plus the chamber air.
Printed: wall time and speed (simulated time / wall time) of

* one :meth:`ThermalIntegrator.propagate` call over the whole programme,
* the same in 600 s blocks with the state carried (what ``rlgsim.sim.run.simulate`` does),
* the probes (``ProbeSet.read``) over the whole programme,

each the median of 5 runs with its spread, with the machine line from ``benchmarks/_machine.py``
and the load average before and after. Run: ``python benchmarks/bench_thermal_core.py``.
"""

from __future__ import annotations

import pathlib
import statistics
import sys
import time
import tomllib

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _machine import MIN_PAIRS, load_text, machine, spread  # noqa: E402

from rlgsim.sim.thermal.chamber import ChamberProgram  # noqa: E402
from rlgsim.sim.config import Ctx  # noqa: E402
from rlgsim.sim.thermal.network import ThermalNetwork  # noqa: E402
from rlgsim.sim.thermal.integrator import ThermalIntegrator  # noqa: E402
from rlgsim.sim.thermal.thermometers import ProbeSet  # noqa: E402

BLOCK_S = 600
REPEATS = MIN_PAIRS
#: the spread of each figure's runs, printed at the end
SPREADS: dict[str, str] = {}


def best_of(fn, repeats: int = REPEATS, label: str = "") -> tuple[float, object]:
    """The median wall seconds of ``repeats`` runs of ``fn`` and its last result (the name is
    kept from when the best run was reported; the median is steadier against others' load)."""
    walls, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t0)
    if label:
        SPREADS[label] = spread(walls, ".4f", " s")
    return statistics.median(walls), out


def main() -> None:
    print(f"load average before: {load_text()}", flush=True)
    with open(ROOT / "scenarios" / "thermal" / "rlg_imu.toml", "rb") as fh:
        data = tomllib.load(fh)
    net = ThermalNetwork.from_config(data["thermal"], Ctx("rlg_imu.toml", "thermal"))
    probes = ProbeSet.from_config(data["probes"], net, Ctx("rlg_imu.toml", "probes"))
    chamber = ChamberProgram.from_config(
        {"start_c": -5.0, "air_tau_s": 60.0,
         "segments": [{"type": "hold", "duration_h": 4},
                      {"type": "ramp", "to_c": 65.0, "duration_min": 7000}]},
        Ctx("paper000", "chamber"))
    setpoint = chamber.rate_limited(chamber.setpoint(None))
    step = 1.0
    m = int(round(setpoint.end_s / step))
    t = np.arange(m + 1) * step
    s = setpoint(t)
    u = np.ones(m)

    t_build, integ = best_of(lambda: ThermalIntegrator(net, step, chamber.air_tau_s),
                             label="set-up")
    x0 = integ.initial_state(-5.0, True)
    t_one, (states, _) = best_of(lambda: integ.propagate(x0, s, u), label="one call")

    def blockwise():
        state, last = x0, None
        for k0 in range(0, m, BLOCK_S):
            k1 = min(m, k0 + BLOCK_S)
            last, state = integ.propagate(state, s[k0:k1 + 1], u[k0:k1])
        return last

    t_blocks, last = best_of(blockwise, label="blocks")
    assert np.array_equal(last[-1], states[-1])          # split calls are bit-identical
    nodes = states[:, 1:]
    t_probes, _ = best_of(lambda: probes.read(probes.initial_state(x0[1:]), nodes, step,
                                              np.random.default_rng(0)), label="probes")

    sim_s = m * step
    print("bench_thermal_core: paper-000 programme (-5 °C 4 h, ramp to 65 °C over 7000 min)")
    print(f"  machine: {machine()}")
    print(f"  network: rlg_imu, {net.n_nodes} nodes + chamber air; {m} steps of {step:g} s "
          f"({sim_s / 3600:.1f} h simulated)")
    print(f"  integrator set-up (eigh + {net.n_nodes} expm)     {t_build * 1e3:8.2f} ms")
    print(f"  propagate, one call                      {t_one:8.3f} s   "
          f"{sim_s / t_one:12.3g} x real time")
    print(f"  propagate, {BLOCK_S} s blocks ({-(-m // BLOCK_S)} calls)       {t_blocks:8.3f} s   "
          f"{sim_s / t_blocks:12.3g} x real time")
    print(f"  probes ({probes.n_probes}), one call                    {t_probes:8.3f} s   "
          f"{sim_s / t_probes:12.3g} x real time")
    print(f"  (median of {REPEATS} runs each; block-wise result bit-identical to the single call)")
    for label, text in SPREADS.items():
        print(f"  {label:<10} {text}")
    print(f"  load average after: {load_text()}  (no target here, so no verdict)")


if __name__ == "__main__":
    main()
