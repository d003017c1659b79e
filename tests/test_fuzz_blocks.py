"""Block boundaries, temporary files and byte determinism of ``rlgsim run`` (issue 15):

* a property test over sample rates, thermal steps and durations — the last 600 s block may
  hold no IMU sample (``sample_rate_hz = 0.1``, ``duration_s = 605``) and every run still
  ends with exactly the samples whose interval ends inside the run;
* a killed run's temporary file carries no format marker until it is complete: readers call
  it incomplete, and the next run to the same path removes the temporaries of dead processes
  (never those of a live one);
* the whole file is the same bytes whatever ``--chunk-s``.
"""

from __future__ import annotations

import math
import os
import pathlib
import subprocess
import sys

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.cli.main import main
from rlgsim.sim.run.scenario import parse_scenario
from rlgsim.sim.run.simulate import simulate

ROOT = pathlib.Path(__file__).resolve().parents[1]
QUICK = (ROOT / "scenarios" / "quickstart.toml").read_text()


def scenario(rate: float, step: float, duration_s: float, **extra: str) -> str:
    text = (QUICK.replace("duration_h = 2.0", f"duration_s = {duration_s!r}")
            .replace("sample_rate_hz = 100", f"sample_rate_hz = {rate!r}")
            .replace("thermal_step_s = 1\n", f"thermal_step_s = {step!r}\n"))
    for old, new in extra.items():
        text = text.replace(old, new)
    return text


# ------------------------------------------------------------------------------ item 1

RATES = [0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0]
STEPS = [0.5, 1.0, 2.0, 5.0, 10.0, 30.0, 60.0]


@pytest.mark.parametrize("rate,step,duration", [
    (0.1, 1.0, 605.0), (0.1, 1.0, 5.0), (0.1, 1.0, 1.0), (1.0, 0.5, 0.5), (0.1, 1.0, 615.0),
    (0.1, 5.0, 1205.0)])
def test_last_block_without_a_sample(tmp_path, rate, step, duration):
    check_run(tmp_path, rate, step, duration)


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(rate=st.sampled_from(RATES), step=st.sampled_from(STEPS),
       duration=st.one_of(st.floats(0.5, 1900.0), st.sampled_from([600.0, 1200.0, 601.0,
                                                                    599.5, 1805.0])))
def test_any_rate_step_and_duration_runs(tmp_path, rate, step, duration):
    check_run(tmp_path, rate, step, round(duration, 3))


def check_run(tmp_path: pathlib.Path, rate: float, step: float, duration: float) -> None:
    try:
        sc = parse_scenario(scenario(rate, step, duration), "prop.toml")
    except UserInputError:
        return                                  # e.g. a step that does not divide 600 s
    out = tmp_path / f"r{rate}_s{step}_d{duration}.h5"
    simulate(sc, out, progress=False)
    total = sc.duration_s
    n_steps = int(round(total / step))
    n_samples = int(math.floor(total * rate + 1e-9))
    with h5py.File(out) as f:
        assert f["thermal/time"].shape == (n_steps,)
        assert f["turntable/time"].shape == (n_steps,)
        assert f["imu/gyro_pulses"].shape[0] == n_samples
        assert np.all(np.isfinite(f["turntable/outer_angle"][:]))
        if n_samples:
            assert f["imu/sample"].shape[0] == n_samples
    out.unlink()


# ------------------------------------------------------------------------------ item 8


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_format_marker_is_written_last_and_stale_temporaries_are_removed(tmp_path):
    sc = parse_scenario(scenario(10.0, 1.0, 600.0), "t.toml")
    out = tmp_path / "t.h5"
    dead = tmp_path / f"t.h5.tmp-{_dead_pid()}"
    dead.write_bytes(b"partial")
    alive = tmp_path / f"t.h5.tmp-{os.getpid()}x"          # not a temporary name: kept
    alive.write_bytes(b"other")
    live = tmp_path / f"t.h5.tmp-{os.getppid()}"             # a live process: kept
    live.write_bytes(b"running")
    seen = {}
    from rlgsim.sim.writer import dataset

    real_commit = dataset.DatasetWriter.commit

    def commit(self):
        seen["marker_before_commit"] = "rlgsim_format" in self._file.attrs
        return real_commit(self)
    try:
        dataset.DatasetWriter.commit = commit
        simulate(sc, out, progress=False)
    finally:
        dataset.DatasetWriter.commit = real_commit
    assert not seen["marker_before_commit"]
    with h5py.File(out) as f:
        assert f.attrs["rlgsim_format"] == "rlgsim dataset"
    assert not dead.exists() and alive.exists() and live.exists()


def test_info_on_a_partial_file_says_incomplete(tmp_path, capsys):
    sc = parse_scenario(scenario(10.0, 1.0, 600.0), "t.toml")
    simulate(sc, tmp_path / "t.h5", progress=False)
    partial = tmp_path / "t.h5.tmp-999999"
    with h5py.File(tmp_path / "t.h5") as src, h5py.File(partial, "w") as dst:
        for k, v in src.attrs.items():
            if k != "rlgsim_format":
                dst.attrs[k] = v
    assert main(["info", str(partial)]) == 2
    err = capsys.readouterr().err
    assert "incomplete" in err and len(err.strip().splitlines()) == 1


# ------------------------------------------------------------------------------ item 10


def test_whole_file_bytes_do_not_depend_on_chunk_s(tmp_path):
    text = scenario(100.0, 1.0, 3 * 3600.0)
    (tmp_path / "b.toml").write_text(text)
    paths = []
    for chunk in ("600", "1800", "7200", "100000"):
        out = tmp_path / f"b_{chunk}.h5"
        assert main(["run", str(tmp_path / "b.toml"), "-o", str(out), "--chunk-s", chunk,
                     "-q"]) == 0
        paths.append(out)
    out = tmp_path / "b_default.h5"
    assert main(["run", str(tmp_path / "b.toml"), "-o", str(out), "-q"]) == 0
    paths.append(out)
    first = paths[0].read_bytes()
    for p in paths[1:]:
        assert p.read_bytes() == first, p.name
