"""The ``rlgsim`` command line.

    rlgsim run SCENARIO [-o out.h5] [--chunk-s S] [--quiet]   simulate to an HDF5 dataset
    rlgsim info FILE                                         summarise a dataset
    rlgsim demo                                              the demo study, into ./rlgsim-demo/
    rlgsim study STUDY [-o DIR] | --list                     run a study into a report folder
    rlgsim list                                              shipped scenarios and devices
    rlgsim montecarlo STUDY --units N [--workers K | --scheduler ADDR] [-o DIR]
                                                             a study over N drawn units
    rlgsim identify RECORDING [--device-template P] -o DIR   a digital twin of the recorded device
    rlgsim navigate DATASET|RECORDING [--models ...] [-o DIR] align and navigate free-inertially

Every user mistake (:class:`~rlgsim.ground.errors.UserInputError`, bad arguments) is printed as one line
``rlgsim: error: ...`` with exit code 2 and no traceback. A disk that fills up while a command
writes (ENOSPC, EDQUOT: not a user mistake, not a bug) is one line too, with exit code 1; the
file being written is removed (what a study wrote before it stays). Anything else is a bug and
keeps its traceback.
"""

from __future__ import annotations

import _thread
import argparse
import errno
import math
import os
import pathlib
import re
import signal
import sys
import threading
import time
from typing import Sequence

from rlgsim.ground.errors import UserInputError

PROG = "rlgsim"
DEMO_DIR = "rlgsim-demo"


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage mistake is one line and exit code 2."""

    def error(self, message: str):  # type: ignore[override]
        raise UserInputError(f"{message} (see '{self.prog} --help')")


def _positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"value {text!r} not allowed; must be a number of "
                                         f"seconds > 0")
    return value


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog=PROG, description="Simulated ring-laser-gyro IMU in a temperature chamber "
                                       "on a turntable, with ground truth.")
    from rlgsim import __version__
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    r = sub.add_parser("run", help="simulate a scenario into an HDF5 dataset")
    r.add_argument("scenario", metavar="SCENARIO",
                   help="a shipped scenario's name (see 'rlgsim list') or a path to a .toml file")
    r.add_argument("-o", "--output", metavar="OUT.h5",
                   help="output file (default: ./<scenario name>.h5)")
    r.add_argument("--chunk-s", type=_positive_seconds, metavar="S",
                   help="simulated seconds buffered per write (default: the scenario's "
                        "acquisition.chunk_s); never changes the data")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar, no summary")
    i = sub.add_parser("info", help="summarise an rlgsim dataset or a recording")
    i.add_argument("file", metavar="FILE")
    d = sub.add_parser("demo", help=f"run the demo study into ./{DEMO_DIR}/ (report.md, "
                                    f"report.html)")
    d.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    sub.add_parser("list", help="list the shipped scenarios and device presets")
    from rlgsim.lab.cli.calibrate import add_subparser as add_calibrate
    add_calibrate(sub)                     # rlgsim calibrate (src/rlgsim/lab/cli/calibrate.py)
    from rlgsim.lab.cli.montecarlo import add_subparser as add_montecarlo
    add_montecarlo(sub)                    # rlgsim montecarlo (src/rlgsim/lab/cli/montecarlo.py)
    from rlgsim.lab.cli.study import add_subparser as add_study
    add_study(sub)                         # rlgsim study (src/rlgsim/lab/cli/study.py)
    from rlgsim.lab.cli.export import add_subparser as add_export
    add_export(sub)                        # rlgsim export (src/rlgsim/lab/cli/export.py)
    from rlgsim.lab.cli.identify import add_subparser as add_identify
    add_identify(sub)                      # rlgsim identify (src/rlgsim/lab/cli/identify.py)
    from rlgsim.lab.cli.navigate import add_subparser as add_navigate
    add_navigate(sub)                      # rlgsim navigate (src/rlgsim/lab/cli/navigate.py)
    return p


def _run(scenario_ref: str, output: str | None, chunk_s: float | None, quiet: bool
         ) -> pathlib.Path:
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    from rlgsim.lab.cli.paths import name_path, output_file
    scenario = load_scenario(scenario_ref)
    inputs = [scenario.source, scenario.device.source, scenario.device.thermal.source]
    output = output_file(output if output is not None else
                         name_path(scenario.name, suffix=".h5", source=scenario.source),
                         inputs=inputs)
    t0 = time.perf_counter()
    path = simulate(scenario, output, chunk_s=chunk_s, progress=not quiet,
                    should_stop=_stop_requested)
    wall = time.perf_counter() - t0
    if not quiet:
        sim_s = scenario.duration_s
        print(f"wrote {path}: scenario {scenario.name}, {sim_s / 3600:.4g} h simulated in "
              f"{wall:.2f} s ({sim_s / max(wall, 1e-9):,.0f}× real time)")
    return path


def _list() -> None:
    from rlgsim.sim import presets
    for kind, title in (("scenario", "scenarios"), ("device", "device presets")):
        print(f"{title}:")
        names = presets.list_names(kind)
        width = max((len(n) for n in names), default=0)
        for name in names:
            f = presets.load(name, kind)
            table = f.data.get("device", {}) if kind == "device" else f.data
            desc = table.get("description", "") if isinstance(table, dict) else ""
            print(f"  {name:<{width}}  {' '.join(str(desc).split())}")


def format_error(exc: UserInputError) -> str:
    """The one line printed for a user mistake."""
    return f"{PROG}: error: {' '.join(str(exc).split())}"


#: the errors of a file system with no room left (the device's or the user's quota)
_NO_SPACE = (errno.ENOSPC, errno.EDQUOT)

#: the file named in an HDF5 error's text (h5py's OSError carries no ``filename``)
_HDF5_FILENAME = re.compile(r"filename = '([^']*)'")

#: the name of a temporary file an output is written through before it is moved into place:
#: ``<name>.tmp-<pid>`` (a dataset) or ``.<name>.tmp[-]<pid>`` (rlgsim.ground.atomic)
_TMP_NAME = re.compile(r"^(?:\.(?P<hidden>.+)|(?P<plain>.+))\.tmp-?\d+$")


def format_no_space(exc: OSError) -> str:
    """The one line printed when the disk fills up during a write: the output's path (a
    temporary file named by HDF5 is given as the file it becomes) and the system's reason."""
    name = exc.filename
    if name is None:
        found = _HDF5_FILENAME.search(str(exc))
        name = found.group(1) if found else None
    where = ""
    if name:
        path = pathlib.Path(os.fsdecode(name))
        tmp = _TMP_NAME.match(path.name)
        where = f"{path.with_name(tmp['hidden'] or tmp['plain']) if tmp else path}: "
    reason = os.strerror(exc.errno) if exc.errno is not None else "no space left"
    return (f"{PROG}: error: {where}the disk filled up while writing ({reason}); the file being "
            f"written was removed — free some space or write elsewhere")


#: The signal that asked the CLI to stop (SIGTERM), if any.
_stop_signal: list[int] = []


#: Seconds after which a SIGTERM that landed inside the import machinery or numba's compiler is
#: raised again.
_RETRY_S = 0.05

#: the packages whose module-wide locks a SystemExit could leave held: numba's (its compiler
#: lock, taken to compile a kernel or load it from the cache) and llvmlite's
_LOCKING_PACKAGES = ("numba", "llvmlite")


def _inside_locking_code(frame) -> bool:
    """Whether the interrupted main thread is running importlib's own code (a module being
    imported, or the module locks' bookkeeping) or numba's/llvmlite's (a kernel being compiled
    or loaded under numba's compiler lock) anywhere on its stack. A kernel running is machine
    code, not a frame: a signal waits for it to return, so it is not counted here."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib._bootstrap") \
                or frame.f_globals.get("__name__", "").partition(".")[0] in _LOCKING_PACKAGES:
            return True
        frame = frame.f_back
    return False


def _terminated(signum, frame):
    """SIGTERM: stop, deleting the temporary file of a run being written. The SystemExit raised
    here can be lost when the signal lands inside a finaliser (``__del__``), so a run also polls
    :func:`_stop_requested` before every block.

    Not inside an import or numba's compiler: an exception raised in importlib's module-lock
    bookkeeping can leave a module's lock held, and one raised while numba compiles or loads a
    kernel can leave its compiler lock held; a worker thread importing that module (the IMU's
    normal-deviate worker loads numba lazily) or loading a kernel of its own (the same worker's
    compiled draws check themselves on first use) then waits forever while the run's clean-up
    joins it. There the signal is simulated again in the main thread a moment later
    (``_thread.interrupt_main``, which does nothing once the CLI has put the previous handler
    back: a command that finished before then exits with 128 + the signal all the same)."""
    if signum not in _stop_signal:
        _stop_signal.append(signum)
    if _inside_locking_code(frame):
        retry = threading.Timer(_RETRY_S, _thread.interrupt_main, args=(signum,))
        retry.daemon = True
        retry.start()
        return
    raise SystemExit(128 + signum)


def _stop_requested() -> bool:
    return bool(_stop_signal)


def _quiet_unraisable(unraisable) -> None:
    """The SystemExit of :func:`_terminated` landing inside a finaliser is "ignored" by Python,
    which prints it with a traceback; the run stops at its next poll anyway, so say nothing.
    Every other unraisable exception is reported as usual."""
    if _stop_signal and isinstance(unraisable.exc_value, SystemExit):
        return
    sys.__unraisablehook__(unraisable)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``rlgsim`` console script; returns the exit code."""
    previous = None
    _stop_signal.clear()
    previous_hook = sys.unraisablehook
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _terminated)
        sys.unraisablehook = _quiet_unraisable
    try:
        code = _main(argv)
        # a SIGTERM deferred (inside an import or numba's compiler) whose repeat came after the
        # command's last poll: the command finished, but it was asked to stop — say so
        return 128 + _stop_signal[0] if _stop_signal and code == 0 else code
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
            sys.unraisablehook = previous_hook


def _main(argv: Sequence[str] | None) -> int:
    try:
        args = _parser().parse_args(argv)
        if args.command == "run":
            _run(args.scenario, args.output, args.chunk_s, args.quiet)
        elif args.command == "info":
            from rlgsim.lab.cli.paths import input_file
            from rlgsim.lab.recordings import info
            print(info(input_file(args.file, "an rlgsim dataset or a recording")))
        elif args.command == "demo":
            from rlgsim.lab.cli.study import demo
            demo(args.quiet)
        elif args.command == "montecarlo":
            return args.handler(args)
        elif args.command == "list":
            _list()
        elif args.command in ("calibrate", "study", "export", "identify", "navigate"):
            return args.handler(args)
        return 0
    except UserInputError as exc:
        print(format_error(exc), file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        if _stop_signal:                 # SIGTERM noticed between two blocks
            return 128 + _stop_signal[0]
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:              # e.g. `rlgsim list | head`: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except Exception as exc:
        # the SIGTERM's SystemExit raised inside a C extension's callback, which turned it into
        # another exception (h5py: SystemError); the run has cleaned up already
        if _stop_signal:
            return 128 + _stop_signal[0]
        if isinstance(exc, OSError) and exc.errno in _NO_SPACE:
            print(format_no_space(exc), file=sys.stderr)
            return 1
        raise
