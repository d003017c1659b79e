"""The rlgsim command line: list, info, run, one-line errors with exit 2 (``rlgsim demo`` end to
end: test_studies.py, whose demo tests read that run)."""

from __future__ import annotations

import os
import subprocess
import sys
import pathlib
import time

import pytest

from rlgsim.lab.cli.main import main
from scenario_helpers import one_line

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _cli(*args: str, cwd: pathlib.Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "rlgsim.lab.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)


def test_list_shows_shipped_scenarios_and_devices(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in ("quickstart", "rlg_imu_000", "trplg_001", "rlg_002", "rlg8_003"):
        assert name in out


def test_run_then_info(tmp_path, capsys):
    out = tmp_path / "q.h5"
    assert main(["run", "quickstart", "-o", str(out), "--quiet"]) == 0
    assert out.is_file()
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "chamber_setpoint" in text and "seed: 20260101" in text


@pytest.mark.parametrize("args, expected", [
    (["run", "no_such_scenario"], "unknown scenario 'no_such_scenario'"),
    (["run", "quickstart", "--chunk-s", "-5"], "must be a number of seconds > 0"),
    (["info", "/no/such/file.h5"], "no such file"),
    (["info", "a\0b.h5"], "a file name cannot contain a NUL character"),
    (["frobnicate"], "invalid choice"),
    ([], "required"),
])
def test_user_mistakes_are_one_line_exit_2(args, expected, capsys):
    assert expected in one_line(capsys, args)


def test_error_in_a_subprocess_has_no_traceback(tmp_path):
    r = _cli("run", "quickstrat", cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [r.stderr.strip()]
    assert "did you mean 'quickstart'" in r.stderr and "Traceback" not in r.stderr


def test_a_sigterm_landing_in_a_finaliser_prints_no_traceback(capsys):
    """The SIGTERM handler's SystemExit can land inside a finaliser, where Python only reports
    it ("Exception ignored in ...", with a traceback): after a SIGTERM that report is silenced,
    any other unraisable exception is still reported."""
    import importlib
    import sys
    cli_main = importlib.import_module("rlgsim.lab.cli.main")

    class Finaliser:
        def __del__(self):
            raise SystemExit(143)

    hook = sys.unraisablehook
    sys.unraisablehook = cli_main._quiet_unraisable
    try:
        cli_main._stop_signal[:] = [15]
        Finaliser()
        assert capsys.readouterr().err == ""
        cli_main._stop_signal.clear()
        Finaliser()
        assert "SystemExit" in capsys.readouterr().err
    finally:
        sys.unraisablehook = hook
        cli_main._stop_signal.clear()


def test_a_frame_inside_numbas_compiler_counts_as_locking_code():
    """A SIGTERM landing while numba compiles or loads a kernel (under its compiler lock) is
    deferred like one inside an import: the frame numba's compile event hands its listener is
    on such a stack (a SystemExit there left the lock held, and the IMU worker loading its own
    kernel hung the clean-up's join: 2 of 4 killed runs before)."""
    import importlib
    import sys

    from numba import njit
    from numba.core import event
    cli_main = importlib.import_module("rlgsim.lab.cli.main")
    frames = []

    class Listener(event.Listener):
        def on_start(self, ev):
            frames.append(sys._getframe())

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", Listener()):
        njit(lambda x: x + 1)(1)
    assert frames and all(cli_main._inside_locking_code(f) for f in frames)


def test_a_sigterm_inside_an_import_is_raised_again_after_it(tmp_path, monkeypatch):
    """A SIGTERM landing while the main thread runs importlib's code is not raised there (an
    exception in the module locks' bookkeeping can leave a lock held, and a worker importing
    that module then hangs the run's clean-up: 5 of 30 killed runs hung before); the signal is
    simulated again a moment later, reaching whatever handler is installed then."""
    import importlib
    import signal
    import sys
    import threading
    cli_main = importlib.import_module("rlgsim.lab.cli.main")
    (tmp_path / "frame_during_import.py").write_text("import sys\nFRAME = sys._getframe()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    importing = importlib.import_module("frame_during_import").FRAME
    assert cli_main._inside_locking_code(importing)
    assert not cli_main._inside_locking_code(sys._getframe())

    again = threading.Event()
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: again.set())
    try:
        assert cli_main._terminated(signal.SIGTERM, importing) is None    # deferred
        assert cli_main._stop_signal == [signal.SIGTERM]
        deadline = time.monotonic() + 10
        while not again.is_set() and time.monotonic() < deadline:
            time.sleep(0.01)        # the simulated signal runs its handler between bytecodes
        assert again.is_set()
        with pytest.raises(SystemExit) as exc:
            cli_main._terminated(signal.SIGTERM, sys._getframe())
        assert exc.value.code == 128 + signal.SIGTERM
    finally:
        signal.signal(signal.SIGTERM, previous)
        cli_main._stop_signal.clear()


def test_a_sigterm_turned_into_another_exception_exits_as_terminated(monkeypatch, capsys):
    """The SIGTERM handler's SystemExit raised inside a C extension's callback comes back as
    another exception (h5py's ``visititems`` returns it as a SystemError, seen once in 30 killed
    runs under load): after a SIGTERM that is exit 128 + 15 with nothing printed; without one,
    the same exception still propagates."""
    import importlib
    cli_main = importlib.import_module("rlgsim.lab.cli.main")

    def run_hit_by_sigterm(*args):
        cli_main._stop_signal.append(15)
        raise SystemError("<cyfunction FastRLock.__exit__> returned a result with an "
                          "exception set")

    monkeypatch.setattr(cli_main, "_run", run_hit_by_sigterm)
    try:
        assert cli_main._main(["run", "quickstart", "-o", "x.h5"]) == 128 + 15
        assert capsys.readouterr().err == ""
        cli_main._stop_signal.clear()
        monkeypatch.setattr(cli_main, "_run", lambda *a: (_ for _ in ()).throw(SystemError("x")))
        with pytest.raises(SystemError):
            cli_main._main(["run", "quickstart", "-o", "x.h5"])
    finally:
        cli_main._stop_signal.clear()


def _no_space(path: str) -> OSError:
    """An OSError shaped like h5py's when HDF5's write hits a full disk (errno 28, the file
    named only in the text)."""
    import errno
    return OSError(errno.ENOSPC, "Can't write unprocessed chunk data (file write failed: "
                   f"filename = '{path}', file descriptor = 3, errno = 28, error message = "
                   "'No space left on device', offset = 4096)")


def test_a_disk_filling_up_mid_run_is_one_line_exit_1_and_no_file(tmp_path, monkeypatch,
                                                                   capsys):
    """A disk that fills up while the run writes: one line naming the output (not its
    temporary file) and the system's reason, exit status 1, nothing at the output path and no
    temporary file left (whose close fails again on the full disk: that second error must not
    replace the first)."""
    import h5py
    from rlgsim.sim.writer import dataset
    hits = []
    real_append = dataset.GroupWriter.append
    real_close = h5py.File.close

    def append_until_full(self, dim, arrays):
        hits.append(self._g.file.filename)
        if len(hits) > 1:
            raise _no_space(hits[-1])
        real_append(self, dim, arrays)

    def close_on_full_disk(self):
        real_close(self)
        if len(hits) > 1:
            raise _no_space(hits[-1])

    monkeypatch.setattr(dataset.GroupWriter, "append", append_until_full)
    monkeypatch.setattr(h5py.File, "close", close_on_full_disk)
    out = tmp_path / "q.h5"
    code = main(["run", "quickstart", "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 1, err
    assert len(hits) > 1 and hits[-1].startswith(str(out) + ".tmp-")
    assert err.strip().splitlines() == [
        f"rlgsim: error: {out}: the disk filled up while writing (No space left on device); "
        "the file being written was removed — free some space or write elsewhere"]
    assert list(tmp_path.iterdir()) == []


def test_other_os_errors_keep_their_traceback(monkeypatch):
    """Only a full disk (or quota) is turned into one line: any other OSError of a run is a
    bug's and propagates."""
    import importlib
    cli_main = importlib.import_module("rlgsim.lab.cli.main")
    monkeypatch.setattr(cli_main, "_run",
                        lambda *a: (_ for _ in ()).throw(OSError(5, "Input/output error")))
    with pytest.raises(OSError):
        cli_main._main(["run", "quickstart", "-o", "x.h5"])


@pytest.mark.parametrize("named, shown", [
    ("/d/q.h5.tmp-123", "/d/q.h5"),                 # a dataset's temporary file, named by HDF5
    ("/d/.nav.png.tmp-77", "/d/nav.png"),           # rlgsim.ground.atomic's
    ("/d/.a.h5.tmp5", "/d/a.h5"),                   # a derived dataset's
    ("/d/report.md", "/d/report.md"),
])
def test_the_full_disk_line_names_the_output_not_its_temporary_file(named, shown):
    from rlgsim.lab.cli.main import format_no_space
    line = format_no_space(_no_space(named))
    assert line.startswith(f"rlgsim: error: {shown}: the disk filled up while writing (No space")
