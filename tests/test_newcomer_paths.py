"""Paths a newcomer gives (issue 29): every command checks its inputs and every file it writes
— the sidecar, programme, presets and replay scenario beside the output too — as ``run`` does:
never rewrite an input, never follow a link, refuse special files, replace a file it did not
write only when asked, sweep the temporaries of killed processes. Each case: one line and exit
status 2 (or it works), and no input file changes a byte."""

from __future__ import annotations

import hashlib
import os
import pathlib
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from rlgsim.lab.cli.main import main

SIDECAR = """\
# hand-written: the logger's column names
[recording]
sample_rate_hz = 10

[gyro]
axes = ["x"]
scale_factor_pulses_per_arcsec = 2.14

[columns]
"Zeit [s]" = "time_s"
"""


def _log(folder: pathlib.Path, stem: str = "m") -> pathlib.Path:
    folder.mkdir(parents=True, exist_ok=True)
    n = 30
    pd.DataFrame({"Zeit [s]": np.arange(1, n + 1) / 10.0,
                  "gyro_x_pulses": np.arange(n) % 7}).to_csv(folder / f"{stem}.csv", index=False)
    (folder / f"{stem}.toml").write_text(SIDECAR)
    return folder / f"{stem}.csv"


def _digest(folder: pathlib.Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.iterdir()) if p.is_file() and not p.is_symlink()}


def _refused(args, capsys, expected: str) -> None:
    code = main(args)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, err
    assert len(err) == 1 and "Traceback" not in err[0], err
    assert expected in err[0], err[0]


# ----------------------------------------------------------------------------- export

def test_export_never_rewrites_the_inputs_sidecar(tmp_path, capsys):
    src = _log(tmp_path)
    before = _digest(tmp_path)
    assert main(["export", str(src), "--format", "parquet", "-q"]) == 0   # the default -o
    assert {k: v for k, v in _digest(tmp_path).items() if k in before} == before
    assert (tmp_path / "m_recording.parquet").is_file()
    assert main(["info", str(src)]) == 0                  # the hand-written sidecar still reads
    capsys.readouterr()
    _refused(["export", str(src), "--format", "parquet", "-o", str(tmp_path / "m.parquet")],
             capsys, "m.toml: is also an input of this command")
    assert not (tmp_path / "m.parquet").exists()
    assert {k: v for k, v in _digest(tmp_path).items() if k in before} == before


def test_export_csv_then_parquet_keeps_both(tmp_path, capsys):
    src = _log(tmp_path)
    assert main(["export", str(src), "-q"]) == 0
    first = _digest(tmp_path)
    assert main(["export", str(src), "--format", "parquet", "-q"]) == 0
    assert {k: v for k, v in _digest(tmp_path).items() if k in first} == first
    assert (tmp_path / "m_recording_parquet.parquet").is_file()
    for table in ("m_recording.csv", "m_recording_parquet.parquet"):
        assert main(["info", str(tmp_path / table)]) == 0
    capsys.readouterr()
    # an explicit -o onto the other export's sidecar is refused
    _refused(["export", str(src), "--format", "parquet", "-o",
              str(tmp_path / "m_recording.parquet")], capsys,
             "m_recording.toml: is the sidecar of the table m_recording.csv")
    assert main(["export", str(src), "-q"]) == 0          # re-export: its own files replaced


def test_export_programme_not_overwritten_unless_asked(tmp_path, capsys):
    from _turntable_pulses import random_truth, write_dataset
    from rlgsim.sim.motion.turntable import TurntableProgram
    prog = TurntableProgram.calibration19(dwell_s=2.0, first_dwell_s=2.0)
    h5 = tmp_path / "run.h5"
    write_dataset(h5, random_truth(np.random.default_rng(1)), prog, prog.duration_s, seed=2)
    mine = tmp_path / "run_recording_programme.csv"
    mine.write_text("my own notes\n")
    before = _digest(tmp_path)
    _refused(["export", str(h5)], capsys, "run_recording_programme.csv: exists and was not "
                                          "written by this command (the programme); give "
                                          "--overwrite")
    assert _digest(tmp_path) == before                    # nothing written at all
    assert main(["export", str(h5), "-q", "--overwrite"]) == 0
    assert mine.read_text().startswith("t0_s,")
    assert main(["export", str(h5), "-q"]) == 0           # its own earlier export: replaced


def test_export_refuses_links_and_special_files(tmp_path, capsys):
    src = _log(tmp_path)
    target = tmp_path / "real.csv"
    target.write_text("keep\n")
    (tmp_path / "link.csv").symlink_to(target)
    _refused(["export", str(src), "-o", str(tmp_path / "link.csv")], capsys,
             "link.csv: is a symbolic link")
    assert target.read_text() == "keep\n" and (tmp_path / "link.csv").is_symlink()
    os.mkfifo(tmp_path / "fifo.csv")
    _refused(["export", str(src), "-o", str(tmp_path / "fifo.csv")], capsys,
             "fifo.csv: is a FIFO (named pipe); an output must be a regular file")
    # a sidecar beside the output that is a link is refused as well
    (tmp_path / "x.toml").symlink_to(target)
    _refused(["export", str(src), "-o", str(tmp_path / "x.csv")], capsys,
             "x.toml: is a symbolic link")
    # inputs: a FIFO recording (would hang), a link to /dev/zero (never ends)
    os.mkfifo(tmp_path / "in.csv")
    (tmp_path / "in.toml").write_text(SIDECAR)
    _refused(["export", str(tmp_path / "in.csv")], capsys, "in.csv: is a FIFO (named pipe), "
                                                             "not a regular file")
    (tmp_path / "z.csv").symlink_to("/dev/zero")
    (tmp_path / "z.toml").write_text(SIDECAR)
    _refused(["export", str(tmp_path / "z.csv")], capsys, "z.csv: is a character device")
    (tmp_path / "s.csv").write_bytes(src.read_bytes())
    os.mkfifo(tmp_path / "s.toml")                          # a FIFO sidecar
    for cmd in (["export", str(tmp_path / "s.csv")], ["info", str(tmp_path / "s.csv")]):
        _refused(cmd, capsys, "s.toml: is a FIFO (named pipe), not a regular file")


@pytest.mark.parametrize("out, expected", [
    ("/sys/x.csv", "/sys/x.csv: cannot write output"),
    ("/proc/self/x.csv", "/proc/self/x.csv: cannot write output"),
    ("LONG", "file name too long"),
    ("/no/such/dir/x.csv", "directory /no/such/dir does not exist"),
])
def test_export_to_places_that_cannot_take_a_file(tmp_path, capsys, out, expected):
    src = _log(tmp_path)
    before = _digest(tmp_path)
    out = str(tmp_path / ("a" * 296 + ".csv")) if out == "LONG" else out
    _refused(["export", str(src), "-o", out], capsys, expected)
    assert _digest(tmp_path) == before


def test_stale_temporaries_of_dead_processes_are_swept(tmp_path, capsys):
    src = _log(tmp_path)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    live = os.getppid()
    stale = [tmp_path / f".m_recording.csv.tmp-{dead.pid}",
             tmp_path / f".m_recording.toml.tmp-{dead.pid}"]
    kept = tmp_path / f".m_recording.csv.tmp-{live}"
    for p in stale + [kept]:
        p.write_text("half")
    assert main(["export", str(src), "-q"]) == 0
    assert not any(p.exists() for p in stale) and kept.exists()


# ----------------------------------------------------------------------------- identify

def _chamber(folder: pathlib.Path) -> pathlib.Path:
    folder.mkdir(parents=True, exist_ok=True)
    n = 200
    pd.DataFrame({"time_s": np.arange(1, n + 1, dtype=float),
                  "gyro_x_rate_deg_per_h": np.zeros(n), "probe_A_c": np.full(n, 20.0),
                  "chamber_air_c": np.full(n, 20.0)}).to_csv(folder / "device.csv", index=False)
    (folder / "device.toml").write_text("[recording]\nsample_rate_hz = 1\n[gyro]\naxes = "
                                        "[\"x\"]\nscale_factor_pulses_per_arcsec = 2.14\n")
    return folder / "device.csv"


def test_identify_never_replaces_the_recordings_sidecar(tmp_path, capsys):
    src = _chamber(tmp_path / "dev")
    before = _digest(tmp_path / "dev")
    _refused(["identify", str(src), "--device-template", "trplg_001", "-o",
              str(tmp_path / "dev")], capsys, "device.toml: is also an input of this command")
    assert _digest(tmp_path / "dev") == before


@pytest.mark.parametrize("name", ["../../x", "..", "a/b", "n" * 300])
def test_identify_name_must_stay_in_the_output_folder(tmp_path, capsys, name):
    src = _chamber(tmp_path / "dev")
    _refused(["identify", str(src), "--device-template", "trplg_001", "--name", name, "-o",
              str(tmp_path / "twin")], capsys, "--name: value")
    assert not (tmp_path / "twin").exists() and not (tmp_path.parent / "x_replay.toml").exists()


def test_identify_output_checks(tmp_path, capsys):
    src = _chamber(tmp_path / "dev")
    (tmp_path / "file").write_text("x")
    _refused(["identify", str(src), "--device-template", "trplg_001", "-o",
              str(tmp_path / "file")], capsys, "file: is a regular file, not a folder")
    out = tmp_path / "twin"
    out.mkdir()
    (out / "thermal.toml").symlink_to(tmp_path / "file")
    _refused(["identify", str(src), "--device-template", "trplg_001", "-o", str(out)], capsys,
             "thermal.toml: is a symbolic link")
    (out / "thermal.toml").unlink()
    (out / "device.toml").write_text("# my notes\n")
    _refused(["identify", str(src), "--device-template", "trplg_001", "-o", str(out)], capsys,
             "device.toml: exists and was not written by this command")
    _refused(["identify", str(src), "--device-template", "trplg_001", "-o", "/sys/twin"],
             capsys, "/sys/twin: cannot write output")
    os.mkfifo(tmp_path / "f.csv")
    _refused(["identify", str(tmp_path / "f.csv"), "-o", str(out)], capsys,
             "f.csv: is a FIFO (named pipe), not a regular file")
    assert (tmp_path / "file").read_text() == "x"


def test_parquet_without_pyarrow_is_one_line(tmp_path, capsys, monkeypatch):
    src = _log(tmp_path)
    monkeypatch.setitem(sys.modules, "pyarrow", None)        # as if not installed
    before = _digest(tmp_path)
    _refused(["export", str(src), "--format", "parquet"], capsys,
             "writing Parquet needs pyarrow, which is not installed; pip install "
             "\"rlgsim[parquet]\"")
    assert _digest(tmp_path) == before
    (tmp_path / "p.parquet").write_bytes(b"PAR1")
    (tmp_path / "p.toml").write_text(SIDECAR)
    _refused(["info", str(tmp_path / "p.parquet")], capsys, "reading Parquet needs pyarrow")
