"""Datasets: netCDF-4 layout readable by xarray/h5netcdf, units, chunk-size independence,
atomic writes (a killed run leaves nothing at the output path), the format marker."""

from __future__ import annotations

import os
import pathlib
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
import xarray as xr

from rlgsim.ground import dataset_format as fmt
from rlgsim.ground.dataset_format import FORMAT, open_dataset
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.writer import dataset
from rlgsim.sim.run.scenario import load_scenario, parse_scenario
import rlgsim.sim.run.simulate as simulate_module
from rlgsim.sim.stages.base import Stage
from rlgsim.sim.run.simulate import BLOCK_S, simulate

ROOT = pathlib.Path(__file__).resolve().parents[1]
QUICKSTART = ROOT / "scenarios" / "quickstart.toml"


def _quickstart_text(**top: str) -> str:
    """The quickstart scenario with top-level keys replaced (values are TOML literals)."""
    lines = QUICKSTART.read_text().splitlines()
    out = []
    for line in lines:
        key = line.split("=", 1)[0].strip()
        if key in top and not line.startswith((" ", "[")):
            out.append(f"{key} = {top.pop(key)}")
        else:
            out.append(line)
    head = [f"{k} = {v}" for k, v in top.items()]
    return "\n".join(head + out) + "\n"


@pytest.fixture(scope="module")
def quick_file(tmp_path_factory) -> pathlib.Path:
    out = tmp_path_factory.mktemp("ds") / "quick.h5"
    simulate(load_scenario("quickstart"), out, progress=False)
    return out


def _groups(path: pathlib.Path) -> list[str]:
    with h5py.File(path) as f:
        return [k for k, v in f.items() if isinstance(v, h5py.Group)]


def test_every_group_opens_with_xarray_h5netcdf(quick_file):
    groups = _groups(quick_file)
    assert {"thermal", "timeline"} <= set(groups)
    for g in groups:
        with xr.open_dataset(quick_file, engine="h5netcdf", group=g) as ds:
            assert ds.sizes, g
            for name, var in ds.variables.items():
                assert "description" in var.attrs, (g, name)
                if var.dtype.kind == "f":
                    assert var.attrs.get("units"), (g, name)


def test_quickstart_writes_the_format_names_and_only_its_boundary(quick_file):
    """The quickstart's device has no heaters and no [anomalies]; its thermal preset has one
    further boundary (the laboratory). Every group is one of VARIABLES', its names in
    VARIABLES' order (device-dependent ones may be absent), followed by exactly the boundary's
    optional names (tests/test_dataset_optional.py: a run with every part on)."""
    optional = {fmt.THERMAL: ["boundary", "boundary_temperature"]}
    assert set(optional[fmt.THERMAL]) <= set(fmt.OPTIONAL_VARIABLES[fmt.THERMAL])
    with open_dataset(quick_file) as ds:
        assert ds.groups() == list(fmt.VARIABLES)
        for group in ds.groups():
            names = [v.name for v in ds.variables(group)]
            assert names == ([n for n in fmt.VARIABLES[group] if n in names]
                             + optional.get(group, [])), group
        assert ds.strings(fmt.THERMAL, "boundary") == ["lab"]


def test_thermal_group_contents(quick_file):
    with xr.open_dataset(quick_file, engine="h5netcdf", group="thermal") as ds:
        t = ds["time"].values
        step = 1.0
        np.testing.assert_array_equal(t, np.arange(1, len(t) + 1) * step)
        assert ds["time"].attrs["units"] == "s"
        assert ds["chamber_setpoint"].attrs["units"] == "degC"
        assert set(np.unique(ds["power_on"].values)) <= {0, 1}
        sp = ds["chamber_setpoint"].values
        assert sp[0] == pytest.approx(20.0) and sp.max() == pytest.approx(40.0)
        if "node_temperature" in ds:
            assert ds["node_temperature"].dims == ("time", "node")
            assert ds["node_temperature"].attrs["units"] == "degC"


def test_root_attributes_embed_the_scenario(quick_file):
    with open_dataset(quick_file) as f:
        assert f.attrs["rlgsim_format"] == FORMAT
        assert f.attrs["scenario_text"] == QUICKSTART.read_text()
        assert int(f.attrs["seed"]) == 20260101
        assert f.attrs["software_version"]


def test_same_arrays_whatever_the_chunk_size(tmp_path):
    # 2 h 3 min 20 s: not a whole number of blocks, so the last block is partial.
    sc = parse_scenario(_quickstart_text(duration_h="2.0555555555555554"),
                        str(QUICKSTART), default_name="q")
    assert sc.duration_s % BLOCK_S != 0
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    simulate(sc, a, chunk_s=BLOCK_S, progress=False)            # one block per write
    simulate(sc, b, chunk_s=5 * 3600.0, progress=False)         # everything in one write
    with h5py.File(a) as fa, h5py.File(b) as fb:
        names: list[str] = []
        fa.visit(names.append)
        other: list[str] = []
        fb.visit(other.append)
        assert names == other
        for n in names:
            if isinstance(fa[n], h5py.Dataset):
                assert fa[n].dtype == fb[n].dtype
                np.testing.assert_array_equal(fa[n][()], fb[n][()], err_msg=n)
        assert dict(fa.attrs) == dict(fb.attrs)


def test_writer_streams_and_renames_only_on_success(tmp_path):
    out = tmp_path / "w.h5"
    with dataset.DatasetWriter(out, {"seed": 1}) as w:
        g = w.group("g", "test group")
        g.coordinate("time", growing=True, units="s", description="t")
        g.coordinate("chan", ["a", "b"], description="channel")
        g.variable("x", ("time", "chan"), units="m", description="x")
        for k in range(3):
            assert not out.exists()
            g.append("time", {"time": np.arange(k * 5, k * 5 + 5, dtype=float),
                              "x": np.full((5, 2), k, dtype=float)})
        with pytest.raises(ValueError, match="missing"):
            g.append("time", {"time": np.zeros(1)})
    with xr.open_dataset(out, engine="h5netcdf", group="g") as ds:
        assert ds["x"].shape == (15, 2)
        assert list(ds["chan"].values) == ["a", "b"]
        assert ds["x"].attrs["units"] == "m"
    assert list(tmp_path.iterdir()) == [out]

    bad = tmp_path / "bad.h5"
    with pytest.raises(RuntimeError):
        with dataset.DatasetWriter(bad, {}) as w:
            w.group("g", "x")
            raise RuntimeError("boom")
    assert not bad.exists()
    assert list(tmp_path.iterdir()) == [out]


def test_reader_rejects_other_files(tmp_path):
    plain = tmp_path / "plain.h5"
    with h5py.File(plain, "w") as f:
        f["x"] = np.arange(3)
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    for p in (plain, text):
        with pytest.raises(UserInputError, match="not an rlgsim dataset"):
            open_dataset(p)
    with pytest.raises(UserInputError, match="no such file"):
        open_dataset(tmp_path / "missing.h5")


def test_unwritable_output_is_a_user_error(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("")
    for target in (afile / "out.h5", tmp_path / "nodir" / "out.h5", tmp_path):
        with pytest.raises(UserInputError, match="output"):
            dataset.check_writable(target)


def _start_long_run(tmp_path):
    scenario = tmp_path / "long.toml"
    scenario.write_text(_quickstart_text(duration_h="5000.0").replace(
        "[acquisition]", "[acquisition]\nchunk_s = 600"))
    out = tmp_path / "long.h5"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    err = open(tmp_path / "stderr.txt", "w+")       # a file: a full pipe would block the run
    proc = subprocess.Popen([sys.executable, "-m", "rlgsim.lab.cli", "run", str(scenario), "-o",
                             str(out), "--quiet"], env=env, cwd=tmp_path, stderr=err)
    proc.err_text = lambda: (err.seek(0), err.read())[1]
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:        # wait until the temporary file is growing
        tmp = list(tmp_path.glob("long.h5.tmp-*"))
        if tmp and tmp[0].stat().st_size > 50_000:
            return proc, out
        if proc.poll() is not None:
            pytest.fail(proc.err_text())
        time.sleep(0.02)
    proc.kill()
    pytest.fail("the run never started writing")


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_killed_run_leaves_no_file_at_the_output_path(tmp_path, sig):
    proc, out = _start_long_run(tmp_path)
    proc.send_signal(sig)
    try:
        proc.wait(timeout=120)
    finally:
        if proc.poll() is None:         # never leave a run behind
            proc.kill()
            proc.wait()
    assert not out.exists()
    if sig == signal.SIGKILL:
        assert proc.returncode == -signal.SIGKILL
    else:       # a terminated run also removes its temporary file
        assert proc.returncode == 128 + signal.SIGTERM
        assert "Traceback" not in proc.err_text()
        assert not list(tmp_path.glob("long.h5.tmp-*"))


class _CountingStage(Stage):
    """A minimal extra stage (the shape the sensor stages take): 10 Hz samples of a seeded
    random walk plus the exact table rate increments, on its own time axis."""

    group = "extra"
    description = "test stage"
    needs_motion = True

    def __init__(self, scenario, timeline):
        self.seed = scenario.seed

    def declare(self, g):
        g.coordinate("time", growing=True, units="s", description="sample end time")
        g.coordinate("axis", ["x", "y", "z"], description="body axis")
        g.variable("walk", ("time",), units="1", description="random walk")
        g.variable("dtheta", ("time", "axis"), units="rad", description="angle increments")

    def initial_state(self):
        return 0.0

    def block(self, state, b, trace, motion):
        from rlgsim.sim.rng import generator
        n = int(round(len(trace.t_s) * trace.step_s * 10))
        t0 = b * BLOCK_S
        walk = state + np.cumsum(generator(self.seed, 0, "test", "walk", b).standard_normal(n))
        inc = motion.increments(t0, n, 10.0)
        t = t0 + np.arange(1, n + 1) / 10.0
        return {"time": {"time": t, "walk": walk, "dtheta": inc.dtheta_rad}}, float(walk[-1])


def test_an_extra_stage_plugs_in_and_stays_chunk_independent(tmp_path, monkeypatch):
    monkeypatch.setattr(simulate_module, "STAGES", [*simulate_module.STAGES,
                                                    _CountingStage])
    sc = parse_scenario(_quickstart_text(duration_h="0.5").replace(
        "[acquisition]", '[turntable]\nprogram = "calibration19"\n\n[acquisition]'),
        str(QUICKSTART), default_name="q")
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    simulate(sc, a, chunk_s=600, progress=False)
    simulate(sc, b, chunk_s=1800, progress=False)
    with xr.open_dataset(a, engine="h5netcdf", group="extra") as da, \
            xr.open_dataset(b, engine="h5netcdf", group="extra") as db:
        assert da.sizes["time"] == 18000
        np.testing.assert_array_equal(da["walk"].values, db["walk"].values)
        np.testing.assert_array_equal(da["dtheta"].values, db["dtheta"].values)
        # the calibration sequence turns the table: some increments are large
        assert np.abs(da["dtheta"].values).max() > 0.01


def test_low_level_dataset_creation_writes_h5py_create_datasets_bytes():
    """sim/writer/_new_dataset.py makes the datasets the writer lays out with h5py's low-level
    calls: the file image must be byte for byte the one ``create_dataset`` makes (growing,
    scale-offset, fixed numeric and text datasets; in-memory files, a few ms)."""
    from rlgsim.sim.writer._new_dataset import new_dataset_id

    text = np.asarray(["a", "bé", ""], dtype=object).view(dataset._STR)
    made = [("t", dict(shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(64,))),
            ("p", dict(shape=(0, 3), maxshape=(None, 3), dtype=np.int32, chunks=(4096, 3),
                       scaleoffset=0)),
            ("n", dict(shape=(0, 2), maxshape=(None, 2), dtype=np.int8, chunks=(512, 2))),
            ("d", dict(shape=(0,), maxshape=(None,), dtype=">f4", chunks=(1 << 16,))),
            ("x", dict(shape=(4,), dtype=np.float64, data=np.arange(4.0) / 3)),
            ("i", dict(shape=(2, 3), dtype=np.int32, data=np.arange(6, dtype=np.int32)
                       .reshape(2, 3))),
            ("s", dict(shape=(3,), dtype=dataset._STR, data=text))]

    def image(low_level: bool) -> bytes:
        with h5py.File(f"mem-{low_level}.h5", "w", driver="core", backing_store=False,
                       libver=("earliest", "v110"), track_order=True) as f:
            g = f.create_group("g", track_order=True)
            for name, kw in made:
                if low_level:
                    new_dataset_id(g, name, **kw)
                else:
                    kw = dict(kw)
                    if "data" in kw:
                        kw.pop("shape")
                    g.create_dataset(name, track_times=False, **kw)
            f.flush()
            return f.id.get_file_image()

    assert image(True) == image(False)
