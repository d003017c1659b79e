"""Recordings on the simulator's side: what needs :mod:`rlgsim.sim` to use a recording
(docs/recordings.md) — the commanded turntable programme taken from the scenario a recording
ran, the calibration source of ``rlgsim calibrate RECORDING --programme ...``, and the
dispatch of ``rlgsim info`` between datasets and recordings.

The format itself lives in :mod:`rlgsim.ground.recording` (the estimators read it too).
"""

from __future__ import annotations

import json
import os
import pathlib

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.recording import DATA_SUFFIXES, is_recording, load_recording

__all__ = ["programme_segments", "calibration_source", "info", "recording_path"]


def programme_segments(ref: str | os.PathLike) -> list[dict]:
    """Timeline segments (turntable motions and calibration windows) of a commanded programme:
    a programme CSV (:mod:`rlgsim.ground.programme`) or a scenario (shipped name or ``.toml``
    path) whose turntable programme the recording ran; times in s from the start of the run."""
    text = os.fspath(ref)
    if text.lower().endswith(".csv"):
        from rlgsim.ground.programme import read_programme
        return read_programme(text)
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.schedule import build_timeline
    try:
        scenario = load_scenario(text)
    except UserInputError as exc:
        raise UserInputError(f"--programme: {exc} (give a programme CSV or the scenario the "
                             f"recording ran)") from None
    timeline = build_timeline(scenario)
    # through JSON as the dataset stores it, so a recording sees exactly a dataset's segments
    return [dict(t0=float(s.t0_s), t1=float(s.t1_s), track=s.track, label=s.label,
                 attrs=json.loads(json.dumps(s.attrs, sort_keys=True, default=float)))
            for s in timeline.segments if s.track in ("turntable", "calibration")]


def calibration_source(path: str | os.PathLike, programme: str | os.PathLike | None):
    """What :func:`rlgsim.estimators.calibration.run_campaign` calibrates for a recording and
    its programme (checked here, so mistakes are one line before any work)."""
    from rlgsim.estimators.recording_calibration import RecordingSource
    if programme is None:
        raise UserInputError(f"{path}: a recording has no commanded turntable programme; give "
                             f"it with --programme PROGRAMME.csv or --programme SCENARIO "
                             f"(docs/recordings.md)")
    if not is_recording(path):
        raise UserInputError(f"{path}: --programme is for recordings (a .csv, .parquet or .h5 "
                             f"table with a .toml sidecar); a simulated dataset keeps its own "
                             f"programme")
    from rlgsim.ground.recording_sidecar import need_fixed_site
    need_fixed_site(load_recording(path).sidecar,    # validate once here: one line before
                    "rlgsim calibrate")                # any work
    return RecordingSource(str(pathlib.Path(path)), programme_segments(programme))


def info(path: str | os.PathLike) -> str:
    """What ``rlgsim info`` prints: a recording's summary, or a dataset's."""
    if is_recording(path):
        return load_recording(path).summary()
    from rlgsim.sim.writer.dataset import summary
    return summary(path)


def recording_path(ref: str, base_dir: pathlib.Path | None, source: str) -> pathlib.Path | None:
    """The recording a study's run reference names (relative to the study file's folder
    ``base_dir``, else as given), or None when it names a scenario. A reference ending like a
    table file that does not exist is an error naming the study file ``source``."""
    p = pathlib.Path(ref)
    cands = ([base_dir / p] if base_dir is not None and not p.is_absolute() else []) + [p]
    for c in cands:
        if c.is_file() and c.suffix.lower() in (*DATA_SUFFIXES, ".toml") and is_recording(c):
            return c
    if p.suffix.lower() in DATA_SUFFIXES:
        raise UserInputError(f"{source}: run {ref!r}: no such recording (looked for "
                             f"{', '.join(str(c) for c in cands)})")
    return None
