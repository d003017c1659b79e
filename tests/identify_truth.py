"""Truth units for the identification tests and benchmark: a thermal preset made from a template
with known multipliers, a device preset with a known law, a scenario through a chamber programme,
simulated into a dataset (the recording the twin is identified from)."""

from __future__ import annotations

import copy
import pathlib

from rlgsim.sim import presets
from rlgsim.lab.identify.preset_text import dumps
from rlgsim.lab.identify.thermal_fit import apply_multipliers, thermal_parameters

#: multipliers a 3-5 h programme identifies on rlg_single (the screen keeps them all)
IDENTIFIABLE = ("rlg_block.power", "rlg_block.internal_conductance", "rlg_block.air_conductance",
                "rlg_block.mount_conductance", "electronics.power", "probe_lag.housing")

#: a programme with two soaks and three ramps at different rates
PROGRAMME_A = [{"type": "hold", "duration_min": 20}, {"type": "ramp", "to_c": 45.0,
               "rate_c_per_min": 1.0}, {"type": "hold", "duration_min": 50},
               {"type": "ramp", "to_c": 0.0, "rate_c_per_min": 1.5},
               {"type": "hold", "duration_min": 50}, {"type": "ramp", "to_c": 25.0,
               "rate_c_per_min": 0.7}, {"type": "hold", "duration_min": 20}]
#: a different programme (validation of a twin on what it was not identified from)
PROGRAMME_B = [{"type": "hold", "duration_min": 30}, {"type": "ramp", "to_c": -5.0,
               "rate_c_per_min": 0.8}, {"type": "hold", "duration_min": 40},
               {"type": "ramp", "to_c": 35.0, "rate_c_per_min": 2.0},
               {"type": "hold", "duration_min": 60}, {"type": "ramp", "to_c": 20.0,
               "rate_c_per_min": 0.5}, {"type": "hold", "duration_min": 30}]


def thermal_truth(folder: pathlib.Path, mult: dict[str, float], *, template: str = "rlg_single",
                  probe_noise: bool = True, name: str = "truth_thermal.toml") -> pathlib.Path:
    data = presets.load_thermal_file(template).data
    d, _ = apply_multipliers(data, thermal_parameters(data), mult)
    if not probe_noise:
        d = copy.deepcopy(d)
        d["probes"]["defaults"]["noise_sigma_c"] = 0.0
        d["probes"]["defaults"]["resolution_c"] = 0.0
    path = folder / name
    path.write_text(dumps(d), encoding="utf-8")
    return path


def device_truth(folder: pathlib.Path, thermal: pathlib.Path, *, template: str = "trplg_001",
                 bias: dict | None = None, noise: dict | None = None, uhfo: dict | None = None,
                 keep_uhfo: bool = True, scale_factor: float | None = None,
                 name: str = "truth_device.toml") -> pathlib.Path:
    d = copy.deepcopy(presets.load_device_file(template).data)
    d["device"]["name"] = pathlib.Path(name).stem
    d["device"]["thermal_preset"] = thermal.name
    d.pop("anomalies", None)     # a truth unit without mode hops and read-out spikes
    d.pop("run_to_run", None)    # one day; its mount links name the template's own nodes
    if bias is not None:
        d["gyro"]["bias"] = bias
        d.get("tolerance", {}).get("gyro", {}).pop("bias", None)
    if noise is not None:
        d["noise"] = noise
    if not keep_uhfo:
        d.pop("uhfo", None)
        d.get("tolerance", {}).pop("uhfo", None)
    elif uhfo is not None:
        d["uhfo"].update(uhfo)
    if scale_factor is not None:
        d["gyro"]["scale_factor_pulses_per_arcsec"] = scale_factor
    path = folder / name
    path.write_text(dumps(d), encoding="utf-8")
    return path


def scenario(folder: pathlib.Path, device: pathlib.Path, *, programme=PROGRAMME_A,
             sample_rate_hz: float = 1.0, seed: int = 1, device_seed: int | None = None,
             start_c: float = 20.0, name: str = "truth_run") -> pathlib.Path:
    sc = {"name": name, "description": "identification truth run", "device": device.name,
          "seed": seed, "acquisition": {"sample_rate_hz": sample_rate_hz, "thermal_step_s": 1.0},
          "power": {"on_at_s": 0.0},
          "chamber": {"start_c": start_c, "segments": programme}}
    if device_seed is not None:
        sc["device_seed"] = device_seed
    path = folder / f"{name}.toml"
    path.write_text(dumps(sc), encoding="utf-8")
    return path


def simulate(scenario_path: pathlib.Path, out: pathlib.Path) -> pathlib.Path:
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate as _sim
    return _sim(load_scenario(str(scenario_path)), str(out), progress=False)


#: three gyros with different bias laws (°/h; x = T − 25 °C at node A; U − U₀ in V):
#: x linear, y linear + quadratic, z through its UHFO only (tests/test_identify_gyros.py,
#: benchmarks/identify_gyros.py)
THREE_GYRO_BIAS = {"value_deg_per_h": [0.01, -0.02, 0.0],
                   "c1_deg_per_h_per_k": [-3.0e-4, 4.0e-4, 0.0],
                   "c2_deg_per_h_per_k2": [0.0, 2.0e-5, 0.0],
                   "uhfo_deg_per_h_per_v": [0.0, 0.0, -0.0273],
                   "langmuir_deg_per_h_per_ma": 0.0}
#: the bias keys of THREE_GYRO_BIAS → the law fit's term names
BIAS_TERMS = {"value_deg_per_h": "intercept", "c1_deg_per_h_per_k": "c1",
              "c2_deg_per_h_per_k2": "c2", "uhfo_deg_per_h_per_v": "uhfo"}


def three_gyro_lab_csv(folder: pathlib.Path, bias: dict, *, seed: int = 1,
                       device_seed: int | None = None, uhfo_axes: tuple[str, ...] = ("z",)
                       ) -> pathlib.Path:
    """A three-gyro unit (trplg_001 gyros x, y, z on ``rlg_single``'s one block, each with its
    own bias law: ``bias`` keys with one value per gyro) through PROGRAMME_A, exported as a lab
    CSV that keeps the UHFO columns of ``uhfo_axes`` only, with a sidecar whose [identify]
    table names the templates (no gyro). Returns the CSV's path."""
    import tomllib

    import pandas as pd

    from rlgsim.ground.recording_export import export
    th = thermal_truth(folder, {})
    dev = device_truth(folder, th, bias=bias)
    d = tomllib.loads(dev.read_text())
    d["gyro"].update(axes=["x", "y", "z"], blocks=["g"] * 3)
    dev.write_text(dumps(d), encoding="utf-8")
    rec = simulate(scenario(folder, dev, seed=seed, device_seed=device_seed), folder / "r.h5")
    out = export(str(rec), "csv", str(folder / "export.csv"))
    t = pd.read_csv(out.table).drop(columns=[f"uhfo_{a}_v" for a in "xyz"
                                             if a not in uhfo_axes])
    t.to_csv(folder / "lab.csv", index=False)
    (folder / "lab.toml").write_text(
        out.sidecar.read_text().replace("export.csv", "lab.csv")
        + '\n[identify]\ndevice_template = "trplg_001"\nthermal_template = "rlg_single"\n',
        encoding="utf-8")
    return folder / "lab.csv"
