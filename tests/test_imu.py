"""The IMU stage end to end (sim/sensors/imu.py): model vs realisation, dataset groups, chunk
independence, truth that reproduces the pulses, and physical plausibility of every preset."""

from __future__ import annotations

import dataclasses
import math
import re

import h5py
import numpy as np
import pytest
import xarray as xr

from rlgsim.ground import dataset_format as fmt
from rlgsim.ground import units
from rlgsim.ground.dataset_format import open_dataset
from rlgsim.sim import presets
from rlgsim.sim.motion.recorded import true_increments
from rlgsim.sim.sensors.imu_model import ImuModel
from rlgsim.sim.rng import generator
from rlgsim.sim.writer.schema import DESCRIPTIONS
from rlgsim.sim.run.scenario import load_device, parse_scenario
from rlgsim.sim.run.simulate import simulate

SHORT = """
name = "imu_short"
device = "rlg_imu_000"
seed = 77
duration_s = 1500

[acquisition]
sample_rate_hz = 100
thermal_step_s = 1
chunk_s = {chunk}
truth_samples = {samples}

[chamber]
start_c = 10.0

[[chamber.segments]]
type = "ramp"
to_c = 30.0
rate_c_per_min = 2.0

[turntable]
program = "calibration19"
first_dwell_s = 60
dwell_s = 30
"""


def _run(tmp_path, chunk: float, samples: bool = True, name: str = "run") -> str:
    sc = parse_scenario(SHORT.format(chunk=chunk, samples=str(samples).lower()), "short.toml")
    return str(simulate(sc, tmp_path / f"{name}.h5", progress=False))


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("imu"), 600.0)


# --------------------------------------------------------------------------- model / realisation


def test_model_versus_realisation():
    """The model keeps nominal values; realisations spread them by the tolerance (1σ), with
    keyed draws (a unit's draw of one coefficient does not depend on the other tolerances)."""
    dev = load_device("rlg_imu_000")
    model = ImuModel.from_device(dev)
    assert np.all(model.gyro.bias.nominal["value"] == 0.0)
    draws = np.array([model.realise(generator(5, u, "realisation", "imu", 0))
                      .gyros.bias.coef["value"] for u in range(400)])
    assert draws.mean() == pytest.approx(0.0, abs=0.004)
    assert draws.std() == pytest.approx(0.02, rel=0.15)              # [tolerance.gyro.bias]
    arw = np.array([model.realise(generator(5, u, "realisation", "imu", 0)).levels["gyro_arw"]
                    for u in range(400)])
    assert arw.std() / arw.mean() == pytest.approx(0.1, rel=0.2)    # gyro_arw_rel = 0.1
    # keyed draws: dropping the accelerometer tolerances leaves the gyro draws alone
    tables = {k: v for k, v in dev.tables.items()}
    tables["tolerance"] = {k: v for k, v in tables["tolerance"].items() if k != "accelerometer"}
    other = ImuModel.from_tables(tables, "x.toml")
    a = model.realise(generator(9, 0, "realisation", "imu", 0)).gyros.bias.coef["c1"]
    b = other.realise(generator(9, 0, "realisation", "imu", 0)).gyros.bias.coef["c1"]
    np.testing.assert_array_equal(a, b)


def test_device_cross_checks(tmp_path):
    from rlgsim.ground.errors import UserInputError
    bad = {"gyro": {"bias": {"uhfo_deg_per_h_per_v": -0.01}}}
    with pytest.raises(UserInputError, match="depends on UHFO but the device has no"):
        ImuModel.from_tables(bad, "d.toml")
    with pytest.raises(UserInputError, match="needs a \\[gyro\\] table"):
        ImuModel.from_tables({"noise": {}}, "d.toml")
    model = ImuModel.from_tables({"gyro": {"node": "Q"}}, "d.toml")
    real = model.realise(generator(1, 0, "realisation", "imu", 0))
    with pytest.raises(UserInputError, match="thermal node 'gx.Q'"):
        real.bind(["gx.A"], "d.toml")


# --------------------------------------------------------------------------- dataset


def test_groups_open_with_xarray(short_run):
    for group in ("imu", "turntable", "truth"):
        with xr.open_dataset(short_run, engine="h5netcdf", group=group) as ds:
            for name, var in ds.variables.items():
                assert "description" in var.attrs or name == "sample", (group, name)
    with xr.open_dataset(short_run, engine="h5netcdf", group="imu") as ds:
        assert ds.gyro_pulses.dtype == np.int32 and ds.gyro_pulses.dims == ("sample", "gyro")
        assert ds.sizes["sample"] == 150_000 and ds.sizes["time"] == 1500
        assert ds.accel_pulses.dtype == np.int32 and ds.uhfo.dtype == np.float32
    with xr.open_dataset(short_run, engine="h5netcdf", group="truth") as ds:
        assert ds.dtheta.dims == ("sample", "body") and ds.gyro_installation.shape == (1500, 3, 3)
        assert ds.coefficient.size == ds.coefficient_value.size > 100


def test_schema_room_declares_the_ground_names(short_run):
    """A device with every optional part (accelerometers, UHFO, per-sample truth): the groups
    and variables on disk are exactly rlgsim.ground.dataset_format's names, in its order, each
    group described by the schema room and every variable documented (units unless a string)."""
    with open_dataset(short_run) as ds:
        assert ds.groups() == [fmt.TIMELINE, fmt.THERMAL, fmt.PROBES, fmt.IMU, fmt.TURNTABLE,
                               fmt.TRUTH]
        for group in ds.groups():
            assert ds.group_attrs(group)["description"] == DESCRIPTIONS[group]
            info = ds.variables(group)
            # plus the optional variables of the preset's parts (rlg_imu's thermostat: the
            # heater coordinate and its power), after the fixed ones
            optional = tuple(n for n in fmt.OPTIONAL_VARIABLES.get(group, ())
                             if n in {v.name for v in info})
            assert tuple(v.name for v in info) == fmt.VARIABLES[group] + optional, group
            for v in info:
                if v.name == fmt.SAMPLE:            # dimension without a stored coordinate
                    continue
                assert v.description, (group, v.name)
                assert v.units is not None or v.dtype.kind == "O", (group, v.name)


def test_same_bytes_whatever_the_chunk(tmp_path, short_run):
    other = _run(tmp_path, 1500.0, name="chunk1500")
    with h5py.File(short_run) as a, h5py.File(other) as b:
        for group in ("imu", "turntable", "truth", "probes", "thermal"):
            for name, ds in a[group].items():
                if ds.dtype.kind in "OS":
                    assert list(ds[...]) == list(b[group][name][...])
                else:
                    np.testing.assert_array_equal(ds[...], b[group][name][...],
                                                  err_msg=f"{group}/{name}")


BLOCK = 60_000                       # samples per 600 s block at 100 Hz


def _blocks(n: int) -> list[slice]:
    return [slice(a, min(a + BLOCK, n)) for a in range(0, n, BLOCK)]


def _count(inc: np.ndarray) -> np.ndarray:
    """Independent re-implementation of the documented counter (rlgsim.sim.sensors.pulses): int64 fixed point
    with 30 fractional bits, remainder carried from block to block."""
    out = np.empty(inc.shape, dtype=np.int64)
    rem = np.zeros(inc.shape[1], dtype=np.int64)
    for sl in _blocks(inc.shape[0]):
        q = np.rint(inc[sl] * 2.0 ** 30).astype(np.int64)
        q[0] += rem
        phase = np.cumsum(q, axis=0)
        c = phase >> 30
        out[sl] = np.diff(c, axis=0, prepend=0)
        rem = phase[-1] - (c[-1] << 30)
    return out


def test_truth_reproduces_the_pulses(short_run):
    """Push the stored truth back through eqs. 17 and 20 (parameters held over their thermal
    step, the documented white-noise draws) and count: every pulse is reproduced."""
    with h5py.File(short_run) as f:
        tr, imu = f["truth"], f["imu"]
        n = imu["gyro_pulses"].shape[0]
        dth, dv = tr["dtheta"][...], tr["dv"][...]
        # the per-sample truth is what the timeline's programme gives, bit for bit
        dth2, dv2 = true_increments(short_run, 0.0, n)
        np.testing.assert_array_equal(dth, dth2)
        np.testing.assert_array_equal(dv, dv2)
        # summed per thermal step too
        np.testing.assert_allclose(dth.reshape(-1, 100, 3).sum(1), tr["dtheta_step"][...],
                                   rtol=0, atol=1e-15)
        seed, unit = int(tr.attrs["seed"]), int(tr.attrs["unit"])
        dt = 0.01

        def z(purpose, axes):
            return np.stack([np.concatenate([
                generator(seed, unit, purpose, a, b).standard_normal(sl.stop - sl.start,
                                                                     dtype=np.float32)
                for b, sl in enumerate(_blocks(n))]) for a in axes], axis=1).astype(np.float64)

        hold = lambda x: np.repeat(x, 100, axis=0)                   # noqa: E731
        E = hold(tr["gyro_installation"][...])
        u = ((E[:, :, 0] * dth[:, [0]] + E[:, :, 1] * dth[:, [1]]) + E[:, :, 2] * dth[:, [2]])
        u = u + hold(tr["gyro_bias"][...] * dt)
        u = u + z("gyro.white", "xyz") * tr["gyro_white_sigma"][...]
        inc = hold(tr["gyro_scale_factor"][...]) * u
        np.testing.assert_array_equal(_count(inc), imu["gyro_pulses"][...])
        E = hold(tr["accel_installation"][...])
        u = ((E[:, :, 0] * dv[:, [0]] + E[:, :, 1] * dv[:, [1]]) + E[:, :, 2] * dv[:, [2]])
        u = u + hold(tr["accel_bias"][...] * dt)
        u = u + z("accel.white", "xyz") * tr["accel_white_sigma"][...]
        k = np.where(u >= 0, hold(tr["accel_scale_factor_pos"][...]),
                     hold(tr["accel_scale_factor_neg"][...]))
        np.testing.assert_array_equal(_count(k * u), imu["accel_pulses"][...])


# --------------------------------------------------------------------------- plausibility


def _paper_run(tmp_path, name: str, rate_hz: int, static: bool = False,
               step_s: float | None = None, device_seed: int | None = None) -> str:
    """A paper's shipped scenario at a lower sample rate (``rate_hz``: the 100 s statistics do
    not depend on it — white noise and the pulse step average the same way), optionally on a
    static mount instead of its turntable programme and with a coarser thermal step."""
    text = presets.load_scenario_file(name).text
    text = re.sub(r"sample_rate_hz\s*=\s*\d+", f"sample_rate_hz = {rate_hz}", text)
    if step_s is not None:
        text = re.sub(r"thermal_step_s\s*=\s*[\d.]+", f"thermal_step_s = {step_s}", text)
    if static:
        text = text[:text.index("[turntable]")] + '[turntable]\nprogram = "static"\n'
    sc = parse_scenario(text, f"{name}.toml")
    if device_seed is not None:
        sc = dataclasses.replace(sc, device_seed=device_seed)
    return str(simulate(sc, tmp_path / f"{name}.h5", progress=False))


def _hundred_s(path: str, powered_from_s: float = 0.0):
    """Non-overlapping 100 s means: gyro rate [°/h] (pulses/K over 100 s), the probe at the
    cathode region A, dT/dt from successive 100 s temperatures [°C/min], UHFO [V]."""
    with h5py.File(path) as f:
        rate = float(f.attrs["sample_rate_hz"])
        per = int(round(100 * rate))
        p = f["imu/gyro_pulses"][...].astype(float)
        k = f["truth/gyro_scale_factor"][...].mean(axis=0)
        first = int(math.ceil(powered_from_s / 100.0))
        nw = p.shape[0] // per
        w = p[:nw * per].reshape(nw, per, -1).sum(axis=1)[first:]
        rate_degh = w / k / 100.0 / units.deg_per_h_to_rad_per_s(1.0)
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in f["probes/probe"][...]]
        probe = next(i for i, n in enumerate(names) if n.endswith(".A"))
        temp = f["probes/temperature"][:, probe]
        step = int(round(100 / float(f.attrs["thermal_step_s"])))
        t100 = temp[:nw * step].reshape(nw, step).mean(axis=1)[first:]
        out = {"rate": rate_degh, "T": t100, "dTdt": np.gradient(t100) * 60.0 / 100.0}
        if "uhfo" in f["imu"]:
            u = f["imu/uhfo"][:, 0]
            out["U"] = u[:nw * step].reshape(nw, step).mean(axis=1)[first:]
    return out


def _stability(x: np.ndarray) -> np.ndarray:
    return np.std(x, axis=0, ddof=1)


def test_trplg_preset_correlation_signs_and_stability(tmp_path):
    """Paper 001 (trplg_001 on paper001_train, the full 25.7 h cycle at 10 Hz): the 100 s bias
    correlates positively with temperature, negatively with its rate and with UHFO (Table 1:
    +0.71, −0.43, −0.82), UHFO more strongly than temperature, and the raw bias stability is
    within a factor 1.5 of Table 2's 0.0185 °/h."""
    d = _hundred_s(_paper_run(tmp_path, "paper001_train", 10))
    b = d["rate"][:, 0]
    c_t = np.corrcoef(b, d["T"])[0, 1]
    c_r = np.corrcoef(b, d["dTdt"])[0, 1]
    c_u = np.corrcoef(b, d["U"])[0, 1]
    assert c_t > 0.4 and c_r < -0.2 and c_u < -0.6
    assert abs(c_u) > abs(c_t)
    assert 0.0185 / 1.5 < _stability(b) < 0.0185 * 1.5


@pytest.mark.parametrize("name,mean,sigma", [("paper002_const_20", 6.796e-3, 1.3953e-3),
                                             ("paper002_cycle_5cpm", 6.806e-3, 1.4122e-3)])
def test_rlg002_preset_mean_and_stability(tmp_path, name, mean, sigma):
    """Paper 002 Table 1 read as docs/studies.md does (8 h of 100 s means): 'before' is the mean
    zero bias (6.796e-3 °/h at 20 °C, 6.806e-3 cycling at 5 °C/min), MLR's 'after' the σ of the
    100 s means about their model (1.3953e-3 / 1.4122e-3 °/h). The study's unit (device_seed
    2002), 10 Hz, the first hour left out as in the study: the mean within 20 % (one run's slow
    random bias moves it by a few %), the raw σ within a factor 1.5."""
    d = _hundred_s(_paper_run(tmp_path, name, 10, device_seed=2002), powered_from_s=3600.0)
    b = d["rate"][:, 0]
    assert 0.8 < np.mean(b) / mean < 1.2
    assert sigma / 1.5 < _stability(b) < sigma * 1.5


@pytest.mark.parametrize("name,paper", [("paper003_cycles", 0.0258), ("paper003_random", 0.0283)])
def test_rlg8_003_preset_stability_and_gradients(tmp_path, name, paper):
    """Paper 003 Tables 4-5: raw STD 0.0258 °/h over the four cycles (61.5 h), 0.0283 °/h on the
    random-rate test — within a factor 1.5 (10 Hz); the bias correlates with the gradients from
    the cathode region A (Table 3: > 0.9) more than with the temperature itself."""
    path = _paper_run(tmp_path, name, 10)
    d = _hundred_s(path)
    b = d["rate"][:, 0]
    assert paper / 1.5 < _stability(b) < paper * 1.5
    with h5py.File(path) as f:
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in f["probes/probe"][...]]
        temp = f["probes/temperature"][...]
    nw = b.size
    t100 = temp[:nw * 100].reshape(nw, 100, -1).mean(axis=1)
    grad = t100[:, names.index("g.A")] - t100[:, names.index("g.G")]
    assert np.corrcoef(b, grad)[0, 1] > 0.85
    assert np.corrcoef(b, grad)[0, 1] > abs(np.corrcoef(b, d["T"])[0, 1])


def test_rlg_imu_000_preset_stability(tmp_path):
    """Paper 000 gives no raw bias-stability figure; docs/sensors.md sets the preset's design
    value, 0.014 °/h (100 s, static mount over paper000_ramp's 120.7 h chamber programme), and
    this checks each gyro against it within the same factor 1.5 (1 Hz and a 10 s thermal step
    for speed; static mount instead of the turntable programme, whose rotations would swamp a
    100 s average)."""
    d = _hundred_s(_paper_run(tmp_path, "paper000_ramp", 1, static=True, step_s=10))
    s = _stability(d["rate"])
    assert np.all((0.014 / 1.5 < s) & (s < 0.014 * 1.5)), s
