"""Monte Carlo campaigns under abuse (issue 15): a coordinator killed with SIGKILL leaves no
process behind, and a hand-damaged output folder (stray files, file-manager copies, truncated
or empty records, a corrupt campaign.json, a directory named like a record) is resumed with one
warning line per problem or refused with one error line — never a traceback, never a lost
good unit."""

from __future__ import annotations

import json
import os
import pathlib
import signal
import subprocess
import sys
import textwrap
import time

import psutil
import pytest

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.montecarlo import (finished_units, results_csv, run_campaign, scan_units,
                                   unit_path)

from mc_toy_units import toy_unit
from process_helpers import wait_gone
from scenario_helpers import one_line

TESTS = pathlib.Path(__file__).resolve().parent
PAYLOAD = {"seed": 7}
IDENTITY = {"kind": "toy", "seed": 7}


def test_sigkill_of_the_coordinator_leaves_no_process(tmp_path):
    script = tmp_path / "coordinator.py"
    script.write_text(textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(TESTS)!r})
        from mc_toy_units import toy_unit
        from rlgsim.lab.montecarlo import run_campaign
        if __name__ == "__main__":
            run_campaign(toy_unit, {{"seed": 1, "sleep_s": 0.3}}, 40, sys.argv[1], workers=2,
                         progress=False)
    """))
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, str(script), str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while len(finished_units(out)) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        kids = psutil.Process(proc.pid).children(recursive=True)
        assert len(kids) >= 3, kids           # resource tracker, forkserver, workers
    finally:
        os.kill(proc.pid, signal.SIGKILL)     # the coordinator only, not its group
        proc.wait(timeout=30)
    survivors = wait_gone(kids)
    assert not survivors, [" ".join(p.cmdline())[:80] for p in survivors]
    # the campaign resumes from what was committed
    done = finished_units(out)
    records = run_campaign(toy_unit, {"seed": 1}, 6, out, progress=False)
    assert {r.unit for r in records} == set(range(6)) and done


def _campaign(tmp_path: pathlib.Path, n: int = 6) -> tuple[pathlib.Path, str]:
    out = tmp_path / "mc"
    ref = results_csv(run_campaign(toy_unit, PAYLOAD, n, out, progress=False,
                                   identity=IDENTITY))
    return out, ref


def test_stray_files_and_corrupt_records_are_skipped_with_one_line(tmp_path, capsys):
    out, ref = _campaign(tmp_path)
    units = out / "units"
    (units / "unit_abc.json").write_text("{}")
    (units / "unit_000001 (copy).json").write_bytes(unit_path(out, 1).read_bytes())
    unit_path(out, 2).write_text("")                                     # empty
    text = unit_path(out, 3).read_text()
    unit_path(out, 3).write_text(text[: len(text) // 2])                 # truncated
    unit_path(out, 4).write_text(json.dumps([1, 2, 3]))                  # not a record
    unit_path(out, 6).write_text(unit_path(out, 5).read_text())          # holds unit 5
    good = {u: unit_path(out, u).stat().st_mtime_ns for u in (0, 1, 5)}
    capsys.readouterr()
    records = run_campaign(toy_unit, PAYLOAD, 6, out, progress=False, identity=IDENTITY)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert all(line.startswith("rlgsim: warning: ") for line in lines), lines
    assert sum("runs again" in line for line in lines) == 4          # units 2, 3, 4 and 6
    assert sum("unit_abc.json" in line and "(copy)" in line for line in lines) == 1
    assert results_csv(records) == ref                               # nothing lost or changed
    assert {u: unit_path(out, u).stat().st_mtime_ns for u in good} == good
    assert (units / "unit_abc.json").exists()                        # user's files kept


def test_directory_named_like_a_record_is_one_error(tmp_path):
    out, _ = _campaign(tmp_path, 3)
    unit_path(out, 1).unlink()
    unit_path(out, 1).mkdir()
    before = {u: unit_path(out, u).read_bytes() for u in (0, 2)}
    with pytest.raises(UserInputError, match="directory named like a unit record"):
        run_campaign(toy_unit, PAYLOAD, 3, out, progress=False, identity=IDENTITY)
    assert {u: unit_path(out, u).read_bytes() for u in (0, 2)} == before
    unit_path(out, 1).rmdir()
    assert set(scan_units(out)) == {0, 2}


@pytest.mark.parametrize("content", ["", "{\"kind\": ", "[1]", "\xff\xfe"])
def test_corrupt_campaign_file_is_one_error_and_keeps_the_units(tmp_path, content):
    out, _ = _campaign(tmp_path, 3)
    (out / "campaign.json").write_bytes(content.encode("latin-1"))
    before = {u: unit_path(out, u).read_bytes() for u in range(3)}
    with pytest.raises(UserInputError, match="unreadable campaign file") as info:
        run_campaign(toy_unit, PAYLOAD, 3, out, progress=False, identity=IDENTITY)
    assert "\n" not in str(info.value)
    assert {u: unit_path(out, u).read_bytes() for u in range(3)} == before


def test_cli_on_a_damaged_folder_exit_2_one_line(tmp_path, capsys):
    # through the command's entry point in this process (a process start cost seconds of the
    # suite, issue 30; python -m rlgsim's one-line errors as a process: test_cli.py)
    out = tmp_path / "mc"
    (out / "units").mkdir(parents=True)
    (out / "campaign.json").write_text("{")
    one_line(capsys, ["montecarlo", "demo", "--units", "1", "-o", str(out), "--quiet"])


def test_temporaries_of_a_dead_coordinator_are_removed(tmp_path):
    import subprocess as sp
    out, ref = _campaign(tmp_path, 3)
    dead = sp.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = [out / f".results.csv.tmp{dead.pid}",
             out / "units" / f".unit_000001.json.tmp{dead.pid}"]
    live = out / "units" / f".unit_000002.json.tmp{os.getppid()}"
    for p in (*stale, live):
        p.write_text("partial")
    records = run_campaign(toy_unit, PAYLOAD, 3, out, progress=False, identity=IDENTITY)
    assert results_csv(records) == ref
    assert not any(p.exists() for p in stale) and live.exists()


def _exits(payload, unit):
    import sys as _sys
    if unit == 1:
        _sys.exit(0)
    return toy_unit(payload, unit)


def test_a_unit_calling_sys_exit_is_a_failed_unit(tmp_path):
    records = run_campaign(_exits, PAYLOAD, 3, tmp_path / "mc", progress=False, workers=1)
    assert [r.status for r in records] == ["ok", "failed", "ok"]
    assert records[1].error.startswith("SystemExit")
