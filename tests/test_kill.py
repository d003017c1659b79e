"""kill -9 in the middle of ``rlgsim run``, ``calibrate``, ``study`` and ``montecarlo``
(issue 15): nothing at the final path, no process left behind, the next run to the same place
cleans up the dead run's temporary files and loses nothing that was finished."""

from __future__ import annotations

import contextlib
import csv
import io
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import psutil
from process_helpers import wait_gone
from rlgsim.lab.cli.main import main
from scenario_helpers import CAL_SCENARIO, TINY_STUDY, one_line, tiny_cycle

ROOT = pathlib.Path(__file__).resolve().parents[1]

SCENARIO = (ROOT / "scenarios" / "quickstart.toml").read_text()




def _cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "rlgsim", *args]


def _run(capfd, *args: str, cwd: pathlib.Path) -> None:
    """``rlgsim ARGS`` in ``cwd`` through the command's entry point, in this process: the runs
    before and after a kill (only the killed command needs a process of its own; starting one
    cost seconds of the suite each, issue 30). Exit status 0 and no traceback on stderr —
    ``capfd``'s, which holds what the command's worker processes wrote, too."""
    with contextlib.chdir(cwd):
        code = main(list(args))
    err = capfd.readouterr().err
    assert code == 0, err
    assert "Traceback" not in err, err


def kill_when(args: list[str], cwd: pathlib.Path, ready, timeout_s: float = 120.0
              ) -> list[psutil.Process]:
    """Start ``rlgsim ARGS``, SIGKILL the command's own process (not its group) as soon as
    ``ready(process)`` holds, and return the processes it had started (to check none
    survives)."""
    proc = subprocess.Popen(_cmd(*args), cwd=cwd, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    seen: dict[int, psutil.Process] = {}
    try:
        me = psutil.Process(proc.pid)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                for child in me.children(recursive=True):
                    seen.setdefault(child.pid, child)
            except psutil.NoSuchProcess:
                break
            if ready(me):
                break
            time.sleep(0.02)
        assert proc.poll() is None, "the command finished before it could be killed"
        assert ready(me), "not ready in time"
        for child in me.children(recursive=True):      # those that ready() saw, too
            seen.setdefault(child.pid, child)
    finally:
        try:
            os.kill(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=30)
    return list(seen.values())


def assert_no_survivors(procs, timeout_s: float = 20.0) -> None:
    left = wait_gone(procs, timeout_s)
    assert not left, [p.pid for p in left]


def temporaries(folder: pathlib.Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if ".tmp" in p.name)


def test_kill_run(tmp_path, capfd):
    # 48 h at 100 Hz: a few seconds of writing, time to kill it (8 h could finish first)
    (tmp_path / "long.toml").write_text(SCENARIO.replace("duration_h = 2.0", "duration_h = 48"))
    out = tmp_path / "long.h5"
    kids = kill_when(["run", "long.toml", "-o", "long.h5", "-q"], tmp_path,
                     lambda me: any(p.stat().st_size > 2 << 20
                                 for p in tmp_path.glob("long.h5.tmp-*")))
    assert_no_survivors(kids)
    assert not out.exists()
    left = temporaries(tmp_path)
    assert left, "the killed run's temporary file was expected"
    assert "incomplete" in one_line(capfd, ["info", str(tmp_path / left[0])])
    # the next runs to the same place: 2 h are enough to show the clean-up and that the
    # output is a fresh run's bytes (48 h twice more cost most of this test's time)
    (tmp_path / "long.toml").write_text(SCENARIO)
    _run(capfd, "run", "long.toml", "-o", "long.h5", "-q", cwd=tmp_path)
    assert temporaries(tmp_path) == []                 # the next run cleaned up
    _run(capfd, "run", "long.toml", "-o", "again.h5", "-q", cwd=tmp_path)
    assert out.read_bytes() == (tmp_path / "again.h5").read_bytes()


def test_kill_calibrate(tmp_path, capfd):
    (tmp_path / "cal.toml").write_text(CAL_SCENARIO)
    _run(capfd, "run", "cal.toml", "-o", "cal.h5", "-q", cwd=tmp_path)
    shutil.copyfile(tmp_path / "cal.h5", tmp_path / "ref.h5")   # the same bytes as a 2nd run
    _run(capfd, "calibrate", "ref.h5", "-o", "ref.csv", "-q", "--workers", "2", cwd=tmp_path)
    before = (tmp_path / "cal.h5").read_bytes()
    kids = kill_when(["calibrate", "cal.h5", "-o", "cal.csv", "-q", "--workers", "2"], tmp_path,
                     lambda me: len(me.children()) >= 2)
    assert len(kids) >= 2
    assert_no_survivors(kids)
    assert not (tmp_path / "cal.csv").exists()
    assert (tmp_path / "cal.h5").read_bytes() == before      # the dataset is untouched
    _run(capfd, "calibrate", "cal.h5", "-o", "cal.csv", "-q", "--workers", "2", cwd=tmp_path)
    assert _table(tmp_path / "cal.csv") == _table(tmp_path / "ref.csv")
    assert temporaries(tmp_path) == []


def _table(path: pathlib.Path) -> list[dict[str, str]]:
    rows = list(csv.DictReader(io.StringIO(path.read_text())))
    return [{k: v for k, v in r.items() if "seconds" not in k and not k.endswith("_s_wall")}
            for r in rows]


def test_kill_study(tmp_path, capfd):
    study = tmp_path / "study"
    study.mkdir()
    (study / "tiny_cycle.toml").write_text(tiny_cycle(1500))
    (study / "tiny.toml").write_text(TINY_STUDY)
    out = tmp_path / "report"
    data = out / "data"
    kids = kill_when(["study", str(study / "tiny.toml"), "-o", str(out), "-q"], tmp_path,
                     lambda me: (data / "tiny_cycle-seed21.h5").exists())
    assert_no_survivors(kids)
    assert not (out / "report.md").exists()
    done = {p.name: p.stat().st_mtime_ns for p in data.glob("*.h5")}
    assert "tiny_cycle-seed21.h5" in done
    _run(capfd, "study", str(study / "tiny.toml"), "-o", str(out), "-q", cwd=tmp_path)
    assert (out / "report.md").is_file()
    assert {n: (data / n).stat().st_mtime_ns for n in done} == done   # finished data reused
    assert temporaries(out) == []


def test_kill_montecarlo(tmp_path, capfd):
    """The CLI process killed once a unit is finished (its workers left to their lifeline):
    none survives, no table is written; the next run to the same folder runs only the units
    left, and its tables are the bytes of an uninterrupted campaign; the folder refuses another
    study. (One kill for what were two tests, this one and test_montecarlo.py's killed
    campaign, which killed the whole process group instead: the suite's time, issue 30.)"""
    from rlgsim.lab.montecarlo import finished_units
    study = tmp_path / "study"
    study.mkdir()
    (study / "tiny_cycle.toml").write_text(tiny_cycle(40))
    (study / "tiny.toml").write_text(TINY_STUDY)
    n = 3                   # two workers: killed after one unit, at least one is left to resume
    args = ["montecarlo", str(study / "tiny.toml"), "--units", str(n), "--workers", "2", "-q"]
    _run(capfd, *args, "-o", "ref", cwd=tmp_path)
    out = tmp_path / "mc"
    kids = kill_when([*args, "-o", str(out)], tmp_path, lambda me: len(finished_units(out)) >= 1)
    assert_no_survivors(kids)
    assert not (out / "results.csv").exists()
    done = finished_units(out)
    assert 1 <= len(done) < n, f"not killed mid-way: {sorted(done)}"
    before = {u: (out / "units" / f"unit_{u:06d}.json").stat().st_mtime_ns for u in done}
    _run(capfd, *args, "-o", str(out), cwd=tmp_path)
    after = {u: (out / "units" / f"unit_{u:06d}.json").stat().st_mtime_ns for u in done}
    assert before == after, "finished units were recomputed"
    units = (out / "units.csv").read_text().splitlines()
    assert [line.split(",")[:2] for line in units[1:]] == [[str(u), "ok"] for u in range(n)]
    for name in ("results.csv", "units.csv"):
        assert (out / name).read_bytes() == (tmp_path / "ref" / name).read_bytes(), name
    assert temporaries(out) == []
    other = study / "other.toml"                      # the same folder refuses another study
    other.write_text(TINY_STUDY.replace("device_seed = 5", "device_seed = 6"))
    assert "different campaign" in one_line(
        capfd, ["montecarlo", str(other), "--units", str(n), "-o", str(out), "-q"])
