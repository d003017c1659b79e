"""Monte Carlo campaigns: one task per simulated unit, on local processes or a Dask cluster.

A campaign runs a *unit function* ``fn(payload, unit) -> {"rows": [(compensator, metric,
value), ...], "params": {name: value, ...}}`` for units ``0 .. N-1``. Unit ``i``'s result may
depend only on (payload, i) — the study and its seed travel in ``payload`` and every random draw
is keyed by the unit index (``rlgsim.sim.rng``) — so the results are the same bytes on one worker, two
workers or a cluster.

Execution goes through the :class:`concurrent.futures.Executor` interface: a local
:class:`~concurrent.futures.ProcessPoolExecutor` by default, or the executor of a
``dask.distributed.Client`` (``client.get_executor()``) for a cluster — Dask's scheduler, not a
home-made one.

Each finished unit is committed atomically as its own JSON file under ``DIR/units/`` by the
coordinating process (so it works when workers do not share the file system). A campaign that
was interrupted (Ctrl-C, a killed worker, a lost node) is resumed by running the same command:
only missing units run. A unit that raises is recorded with its error and does not stop the
campaign. Merging the unit files, sorted by unit, gives the results tables.
"""

from __future__ import annotations

import concurrent.futures as cf
import csv
import io
import json
import multiprocessing
import os
import pathlib
import re
import sys
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Sequence

from rlgsim.lab.report import write_atomic

UNIT_DIR = "units"
MANIFEST = "campaign.json"


@dataclass
class UnitRecord:
    """The committed outcome of one unit."""

    unit: int
    status: str                                   # "ok" or "failed"
    rows: list[tuple[str, str, float]] = field(default_factory=list)
    params: dict[str, float] = field(default_factory=dict)
    error: str = ""
    seconds: float = 0.0

    def to_json(self) -> str:
        return json.dumps({"unit": self.unit, "status": self.status,
                           "rows": [list(r) for r in self.rows], "params": self.params,
                           "error": self.error, "seconds": self.seconds},
                          sort_keys=True, allow_nan=True)

    @classmethod
    def from_json(cls, text: str) -> "UnitRecord":
        d = json.loads(text)
        return cls(unit=int(d["unit"]), status=d["status"],
                   rows=[(str(c), str(m), float(v)) for c, m, v in d["rows"]],
                   params={k: float(v) for k, v in d["params"].items()},
                   error=d.get("error", ""), seconds=float(d.get("seconds", 0.0)))


def run_unit_safely(fn: Callable[[Any, int], dict], payload: Any, unit: int) -> UnitRecord:
    """Run one unit in a worker; an exception becomes a ``failed`` record, never a crash."""
    start = time.perf_counter()
    try:
        out = fn(payload, unit)
        rows = [(str(c), str(m), float(v)) for c, m, v in out.get("rows", [])]
        params = {str(k): float(v) for k, v in out.get("params", {}).items()}
        return UnitRecord(unit, "ok", rows, params, seconds=time.perf_counter() - start)
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - a failing unit is data, not a crash
        tb = traceback.format_exc(limit=4)      # (sys.exit in a user's compensator included)
        return UnitRecord(unit, "failed", error=f"{type(exc).__name__}: {exc}\n{tb}",
                          seconds=time.perf_counter() - start)


def unit_path(out_dir: pathlib.Path, unit: int) -> pathlib.Path:
    return pathlib.Path(out_dir) / UNIT_DIR / f"unit_{unit:06d}.json"


#: Name of a committed unit record: ``unit_`` and at least six digits.
_UNIT_NAME = re.compile(r"unit_(\d{6,})\.json")


def _warn(message: str) -> None:
    """One line on stderr about something in the output folder that was skipped."""
    print(f"rlgsim: warning: {' '.join(message.split())}", file=sys.stderr)


def scan_units(out_dir: pathlib.Path, *, report: bool = False) -> dict[int, UnitRecord]:
    """The readable committed records under ``out_dir/units/``, by unit.

    A folder edited by hand or by a file manager is tolerated: files whose names are not
    ``unit_NNNNNN.json`` (``unit_abc.json``, ``unit_000001 (copy).json``) are ignored, and an
    empty, truncated or otherwise unreadable record (or one holding another unit) counts as
    missing, so its unit runs again and the record is replaced. With ``report`` each is one
    warning line on stderr. A *directory* named like a record cannot be replaced: that is a
    :class:`~rlgsim.ground.errors.UserInputError` naming it. Good records are never touched."""
    from rlgsim.ground.errors import UserInputError

    folder = pathlib.Path(out_dir) / UNIT_DIR
    if not folder.is_dir():
        if folder.exists() or folder.is_symlink():
            raise UserInputError(f"{folder}: expected a folder of unit records, found a file; "
                                 f"remove it or use another output folder")
        return {}
    records: dict[int, UnitRecord] = {}
    stray: list[str] = []
    for path in sorted(folder.iterdir()):
        match = _UNIT_NAME.fullmatch(path.name)
        if match is None:
            if path.name.startswith("unit_") and not path.name.startswith("."):
                stray.append(path.name)
            continue
        if path.is_dir():
            raise UserInputError(f"{path}: a directory named like a unit record; remove or "
                                 f"rename it to resume the campaign")
        unit = int(match.group(1))
        try:
            if not path.is_file():
                raise ValueError("not a regular file")
            if path.stat().st_size > _MAX_RECORD_BYTES:
                raise ValueError(f"larger than {_MAX_RECORD_BYTES} bytes")
            record = UnitRecord.from_json(path.read_text(encoding="utf-8"))
            if record.unit != unit or record.status not in ("ok", "failed"):
                raise ValueError(f"holds unit {record.unit} with status {record.status!r}")
        except (OSError, ValueError, TypeError, KeyError, AttributeError,
                UnicodeDecodeError) as exc:
            if report:
                why = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
                _warn(f"{path}: unreadable unit record ({why}); unit {unit} runs again")
            continue
        records[unit] = record
    if report and stray:
        shown = ", ".join(stray[:5]) + (f" and {len(stray) - 5} more" if len(stray) > 5 else "")
        _warn(f"{folder}: ignored {len(stray)} file(s) not named unit_NNNNNN.json: {shown}")
    return records


#: Temporary files of :func:`rlgsim.lab.report.write_atomic`: ``.<name>.tmp<pid>``.
_TEMPORARY = re.compile(r"\..+\.tmp(\d+)")


def remove_stale_temporaries(folder: pathlib.Path) -> None:
    """Delete the temporary files a killed coordinator left in ``folder`` (those whose process
    is gone); a live process's are kept."""
    from rlgsim.ground.lifeline import process_alive
    try:
        entries = list(pathlib.Path(folder).iterdir())
    except OSError:
        return
    for p in entries:
        match = _TEMPORARY.fullmatch(p.name)
        if match is None or int(match.group(1)) == os.getpid():
            continue
        if not process_alive(int(match.group(1))):
            try:
                if p.is_file() and not p.is_symlink():
                    p.unlink()
            except OSError:
                pass


#: A unit record is a few kB; anything much larger is not one (never read it whole).
_MAX_RECORD_BYTES = 64 << 20


def finished_units(out_dir: pathlib.Path) -> set[int]:
    """Units whose record is already committed (and readable) in ``out_dir``."""
    return set(scan_units(out_dir))


def load_records(out_dir: pathlib.Path, n_units: int) -> list[UnitRecord]:
    """The committed records of units ``0..n_units-1`` that exist, sorted by unit."""
    records = scan_units(out_dir)
    return [records[u] for u in sorted(records) if u < n_units]


def commit(out_dir: pathlib.Path, record: UnitRecord) -> None:
    path = unit_path(out_dir, record.unit)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, record.to_json())


def check_manifest(out_dir: pathlib.Path, identity: dict[str, Any]) -> None:
    """Refuse to resume a folder that holds a different campaign (other study or seed)."""
    from rlgsim.ground.errors import UserInputError

    path = pathlib.Path(out_dir) / MANIFEST
    if path.exists() or path.is_symlink():
        try:
            if not path.is_file():
                raise ValueError("not a regular file")
            if path.stat().st_size > _MAX_RECORD_BYTES:
                raise ValueError(f"larger than {_MAX_RECORD_BYTES} bytes")
            old = json.loads(path.read_text(encoding="utf-8"))
            if not isinstance(old, dict):
                raise ValueError(f"expected a JSON object, got {type(old).__name__}")
        except (OSError, ValueError) as exc:
            why = " ".join(str(exc).split())[:120]
            raise UserInputError(
                f"{path}: unreadable campaign file ({why}); the units in this folder cannot be "
                f"matched to a study: use another output folder, or delete {MANIFEST} to adopt "
                f"them for this study") from None
        if old != identity:
            diff = [k for k in sorted(set(old) | set(identity)) if old.get(k) != identity.get(k)]
            raise UserInputError(
                f"{out_dir}: holds a different campaign (differs in {', '.join(diff)}); "
                "use another output folder or remove it")
    else:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, json.dumps(identity, sort_keys=True, indent=1))


def local_executor(workers: int) -> cf.Executor:
    """A process pool; 'forkserver' so workers do not inherit the parent's threads. Its workers
    exit when this process dies, even by SIGKILL (:mod:`rlgsim.ground.lifeline`); call
    :func:`close_executor` after ``shutdown``."""
    from rlgsim.ground.lifeline import process_pool
    return process_pool(workers, mp_context=multiprocessing.get_context("forkserver"))


def close_executor(pool: cf.Executor) -> None:
    """Release the lifeline of a pool made by :func:`local_executor` (after shutdown)."""
    from rlgsim.ground.lifeline import release
    release(pool)


class Progress:
    """Console progress: done / failed / remaining and ETA (tqdm)."""

    def __init__(self, total: int, already: int, enabled: bool) -> None:
        from tqdm import tqdm

        self.failed = 0
        self.bar = tqdm(total=total, initial=already, disable=not enabled, unit="unit",
                        desc="montecarlo", dynamic_ncols=True)

    def update(self, record: UnitRecord) -> None:
        self.failed += record.status != "ok"
        remaining = self.bar.total - self.bar.n - 1
        self.bar.set_postfix(failed=self.failed, remaining=remaining, refresh=False)
        self.bar.update(1)                   # refreshes with the postfix just set

    def close(self) -> None:
        self.bar.close()


def run_campaign(fn: Callable[[Any, int], dict], payload: Any, n_units: int,
                 out_dir: str | os.PathLike, *, executor: cf.Executor | None = None,
                 workers: int = 1, identity: dict[str, Any] | None = None,
                 progress: bool = True, max_pool_restarts: int = 2) -> list[UnitRecord]:
    """Run every missing unit of ``0..n_units-1`` and return all records sorted by unit.

    ``executor`` (e.g. ``dask.distributed.Client(...).get_executor()``) is used as given and not
    shut down; without one a local process pool of ``workers`` processes is created (``workers
    == 1`` still uses one worker process, so a crashing unit cannot take the campaign down). A
    local pool broken by a killed worker is restarted up to ``max_pool_restarts`` times; units it
    was running are simply not committed and run again.
    """
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if identity is not None:
        check_manifest(out_dir, identity)
    remove_stale_temporaries(out_dir)
    remove_stale_temporaries(out_dir / UNIT_DIR)
    done = set(scan_units(out_dir, report=True))
    todo = [u for u in range(n_units) if u not in done]
    bar = Progress(n_units, n_units - len(todo), progress)
    restarts = 0
    try:
        while todo:
            own = executor is None
            pool = local_executor(workers) if own else executor
            try:
                futures = {pool.submit(run_unit_safely, fn, payload, u): u for u in todo}
                for fut in cf.as_completed(futures):
                    try:
                        record = fut.result()
                    except cf.process.BrokenProcessPool:
                        continue            # the pool died; remaining units stay missing
                    except Exception as exc:  # noqa: BLE001 - e.g. dask KilledWorker
                        record = UnitRecord(futures[fut], "failed",
                                            error=f"{type(exc).__name__}: {exc}")
                    commit(out_dir, record)
                    bar.update(record)
            finally:
                if own:
                    pool.shutdown(wait=True, cancel_futures=True)
                    close_executor(pool)
            todo = [u for u in range(n_units) if u not in finished_units(out_dir)]
            if todo:
                restarts += 1
                if not own or restarts > max_pool_restarts:
                    break
    finally:
        bar.close()
    return load_records(out_dir, n_units)


# -- tables ------------------------------------------------------------------------------------
def results_csv(records: Sequence[UnitRecord]) -> str:
    """One row per (unit, compensator, metric); values in round-trip ``repr`` form."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["unit", "compensator", "metric", "value"])
    for rec in records:
        for comp, metric, value in rec.rows:
            w.writerow([rec.unit, comp, metric, repr(float(value))])
    return buf.getvalue()


def params_csv(records: Sequence[UnitRecord]) -> str:
    """One row per unit with its status, drawn parameters and error (if any)."""
    names: list[str] = sorted({k for rec in records for k in rec.params})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["unit", "status", *names, "error"])
    for rec in records:
        first_line = rec.error.splitlines()[0] if rec.error else ""
        w.writerow([rec.unit, rec.status,
                    *[repr(rec.params[n]) if n in rec.params else "" for n in names], first_line])
    return buf.getvalue()


def write_tables(out_dir: str | os.PathLike, records: Iterable[UnitRecord]) -> None:
    records = sorted(records, key=lambda r: r.unit)
    out_dir = pathlib.Path(out_dir)
    write_atomic(out_dir / "results.csv", results_csv(records))
    write_atomic(out_dir / "units.csv", params_csv(records))
