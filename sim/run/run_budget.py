"""Will a run finish? Estimates made before the first block, and the refusals they lead to.

:func:`rlgsim.sim.run.simulate.simulate` asks two questions before it simulates anything:

1. :func:`check_motions` — before the timeline is built: the turntable programme expanded over
   the run must stay under :data:`MAX_MOTIONS` motion segments (a continuous programme repeating
   a 1 ms hold for a day would hold 86 million segments, all in memory). Each motion also lasts
   at least :data:`rlgsim.sim.motion.turntable.MIN_MOTION_S` (checked when the scenario is read).
2. :func:`check_budget` — after every group has declared its variables: the output size (exact
   bytes per row of every growing variable × rows; an upper bound, since pulse counts are
   stored packed), the memory one block needs (working arrays of one 600 s block — or of the
   whole run when it is shorter: its only block is that long — plus the rows buffered for
   ``chunk_s``, which cannot split a block) and the wall time. A run whose output does not fit the free disk
   space, or whose block needs more than :data:`MAX_BLOCK_BYTES` (or more than the memory
   available), is refused with one line naming the scenario, the key and what to change; a run
   expected to take longer than :data:`LONG_RUN_S` or to write more than
   :data:`BIG_OUTPUT_BYTES` prints its estimate first (unless quiet).

The per-sample and per-step costs are measured figures (quickstart at 100 Hz - 10 kHz and the
six-channel ``rlg_imu_000`` at 1 kHz on a 2-core AMD EPYC, peak RSS and wall time): about
``160 + 32·channels`` bytes and ``0.25·(1 + channels)`` µs per IMU sample, three times the stored
row and 11 µs per thermal step. They are estimates, good to a factor of about two — enough to
tell a run of minutes from one of days, or 2 GB from 800 GB.
"""

from __future__ import annotations

import itertools
import math
import os
import pathlib
import shutil
import sys
from dataclasses import dataclass
from typing import Any, Iterable

import h5py

from rlgsim.ground.errors import UserInputError

#: Most turntable motion segments a run may hold (paper000_campaign, 120 h: 6 476).
MAX_MOTIONS = 200_000
#: Most memory one block (working arrays + rows buffered for a write) may need [bytes].
MAX_BLOCK_BYTES = 4 << 30
#: Runs expected to take longer than this [s] print their estimate first.
LONG_RUN_S = 60.0
#: Runs expected to write more than this [bytes] print their estimate first.
BIG_OUTPUT_BYTES = 1 << 30

#: Working memory per IMU sample [bytes]: fixed part and per stored channel (measured).
SAMPLE_WORK_BYTES = 160.0
CHANNEL_WORK_BYTES = 32.0
#: Working memory per thermal step, as a multiple of the stored row (measured).
STEP_WORK_FACTOR = 3.0
#: Wall time per IMU sample and channel and per thermal step [s] (measured, one core).
SAMPLE_SECONDS = 0.25e-6
STEP_SECONDS = 11e-6


@dataclass(frozen=True)
class Estimate:
    """What a run will cost: ``output_bytes`` (upper bound), ``block_bytes`` (memory of one
    block incl. the write buffer), ``seconds`` (wall time) and the counts behind them."""

    output_bytes: float
    block_bytes: float
    seconds: float
    n_steps: int
    n_samples: int
    steps_per_block: int
    samples_per_block: int
    buffered_blocks: int
    step_row_bytes: int
    sample_row_bytes: int


def human_bytes(n: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def human_seconds(s: float) -> str:
    if s >= 86400:
        return f"{s / 86400:.3g} days"
    if s >= 3600:
        return f"{s / 3600:.3g} h"
    if s >= 60:
        return f"{s / 60:.3g} min"
    return f"{s:.2g} s"


def _where(scenario) -> str:
    return f"{scenario.source}" if getattr(scenario, "source", None) else str(scenario.name)


# --------------------------------------------------------------------------- motions


def _motions_bound(program, duration_s: float) -> int | None:
    """An upper bound of the motion segments ``program`` makes over ``duration_s`` [s] from
    one repetition's steps (each repetition makes at most as many as it has flat steps; a lead-in
    one more), or None when one repetition alone holds more than :data:`MAX_MOTIONS` steps."""
    steps = sum(1 for _ in itertools.islice(program._expand(program.steps), MAX_MOTIONS + 1))
    if steps > MAX_MOTIONS:
        return None
    reps = 1
    if program.continuous:                   # finite, positive duration (checked when made)
        reps = max(0, math.ceil((duration_s - program.lead_in_s) / program.duration_s)) + 1
    return 1 + reps * steps


def check_motions(scenario) -> None:
    """Refuse a turntable programme that makes more than :data:`MAX_MOTIONS` motion segments
    over the run: passed at once when the upper bound :func:`_motions_bound` is within the
    limit (one repetition's steps: ~0.1 ms, where walking paper000's 6 700 motions took ~12 ms
    before the first block), else by walking the motions, stopping past the limit."""
    program = scenario.turntable
    bound = _motions_bound(program, float(scenario.duration_s))
    if bound is not None and bound <= MAX_MOTIONS:
        return
    n = 0
    for _ in program.motions(until_s=float(scenario.duration_s)):
        n += 1
        if n > MAX_MOTIONS:
            raise UserInputError(
                f"{_where(scenario)}: turntable: the programme makes more than {MAX_MOTIONS} "
                f"motion segments over the run ({scenario.duration_s:g} s; one repetition "
                f"lasts {program.duration_s:.3g} s); at most {MAX_MOTIONS} allowed: use "
                f"longer motions or a shorter run")


# --------------------------------------------------------------------------- size and memory


def _row_bytes(f: h5py.File) -> tuple[int, int]:
    """Bytes per row of every growing variable of an open dataset being written: along the
    thermal-grid dimension ``time`` and along the IMU-sample dimension ``sample``."""
    per = {"time": 0, "sample": 0}

    def visit(name: str, obj) -> None:
        if not isinstance(obj, h5py.Dataset) or not obj.maxshape or obj.maxshape[0] is not None:
            return
        dim = name.rsplit("/", 1)[-1]
        if obj.dims[0] and len(obj.dims[0]):
            dim = obj.dims[0][0].name.rsplit("/", 1)[-1]
        if obj.is_scale and obj.name.rsplit("/", 1)[-1] == "sample":
            return                                    # a dimension without values: no bytes
        key = "sample" if dim == "sample" else "time"
        per[key] += int(obj.dtype.itemsize * math.prod(obj.shape[1:]))

    f.visititems(visit)
    return per["time"], per["sample"]


def row_bytes_of(groups: Iterable[Any]) -> tuple[int, int]:
    """:func:`_row_bytes` from the group writers that declared the dataset
    (:attr:`rlgsim.sim.writer.dataset.GroupWriter.row_bytes`: the same sums, counted as each
    growing dataset was made) — visiting the file's ~80 objects through h5py cost ~10 ms of a
    run (a 1 h run at 100 Hz takes ~0.1 s)."""
    per = {"time": 0, "sample": 0}
    for g in groups:
        for dim, row in g.row_bytes.items():
            per["sample" if dim == "sample" else "time"] += row
    return per["time"], per["sample"]


def _available_memory() -> float:
    try:
        import psutil
        return float(psutil.virtual_memory().available)
    except Exception:                                 # noqa: BLE001 - no psutil: no check
        try:
            return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            return math.inf


def estimate(f: h5py.File | None, scenario, *, n_steps: int, steps_per_block: int,
             buffered_blocks: int, block_s: float,
             row_bytes: tuple[int, int] | None = None) -> Estimate:
    """The cost of simulating ``scenario`` into the declared (still empty) dataset ``f``
    (``row_bytes``: its :func:`_row_bytes` when known, :func:`row_bytes_of`)."""
    rate = float(scenario.acquisition.sample_rate_hz)
    step_row, sample_row = row_bytes if row_bytes is not None else _row_bytes(f)
    samples_per_block = int(round(block_s * rate)) if sample_row else 0
    n_samples = int(round(n_steps * float(scenario.acquisition.thermal_step_s) * rate)
                    ) if sample_row else 0
    channels = max(1, sample_row // 4) if sample_row else 0
    output = float(n_steps) * step_row + float(n_samples) * sample_row
    work = (steps_per_block * step_row * STEP_WORK_FACTOR
            + samples_per_block * (SAMPLE_WORK_BYTES + CHANNEL_WORK_BYTES * channels))
    buffered = buffered_blocks * (steps_per_block * step_row + samples_per_block * sample_row)
    seconds = (n_samples * SAMPLE_SECONDS * (1 + channels) + n_steps * STEP_SECONDS)
    return Estimate(output_bytes=output, block_bytes=work + buffered, seconds=seconds,
                    n_steps=n_steps, n_samples=n_samples, steps_per_block=steps_per_block,
                    samples_per_block=samples_per_block, buffered_blocks=buffered_blocks,
                    step_row_bytes=step_row, sample_row_bytes=sample_row)


def check_budget(scenario, out: pathlib.Path, *, n_steps: int, steps_per_block: int,
                 buffered_blocks: int, block_s: float, progress: bool,
                 row_bytes: tuple[int, int]) -> Estimate:
    """Refuse a run that cannot fit the free disk space or the per-block memory bound (one
    line naming the scenario, the key and what to change); print the estimate of a long or
    big run when ``progress``. ``row_bytes``: the declared dataset's (:func:`row_bytes_of`),
    before any file exists."""
    n_blocks = max(1, math.ceil(n_steps / max(1, steps_per_block)))
    est = estimate(None, scenario, n_steps=n_steps, steps_per_block=steps_per_block,
                   buffered_blocks=min(buffered_blocks, n_blocks), block_s=block_s,
                   row_bytes=row_bytes)
    acq = scenario.acquisition
    where = _where(scenario)
    limit = min(float(MAX_BLOCK_BYTES), _available_memory())
    if est.block_bytes > limit:
        step_out = est.steps_per_block * est.step_row_bytes
        sample_out = est.samples_per_block * est.sample_row_bytes
        parts = {
            "chunk": (est.buffered_blocks - 1) * (step_out + sample_out),
            "step": step_out * (STEP_WORK_FACTOR + 1),
            "sample": est.block_bytes - step_out * (STEP_WORK_FACTOR + 1)
            - (est.buffered_blocks - 1) * (step_out + sample_out)}
        worst = max(parts, key=parts.get)
        if worst == "chunk":
            key = (f"acquisition.chunk_s (or --chunk-s): {est.buffered_blocks} blocks buffered "
                   f"per write; use a smaller chunk (at least one {block_s:g} s block)")
        elif worst == "step":
            key = (f"acquisition.thermal_step_s = {acq.thermal_step_s:g} "
                   f"({est.steps_per_block} steps per block); use a larger step")
        else:
            key = (f"acquisition.sample_rate_hz = {acq.sample_rate_hz:g} "
                   f"({est.samples_per_block} samples per block, whatever the chunk); use a "
                   f"lower rate" + (f" or a run shorter than {block_s:g} s" if
                                    est.n_steps > est.steps_per_block else ""))
        raise UserInputError(
            f"{where}: {key}: one {block_s:g} s block would need about "
            f"{human_bytes(est.block_bytes)} of memory; at most {human_bytes(limit)} allowed")
    folder = out.parent
    try:
        free = float(shutil.disk_usage(folder).free)
    except OSError:
        free = math.inf
    if est.output_bytes > free:
        raise UserInputError(
            f"{out}: the run of {where} would write about {human_bytes(est.output_bytes)} "
            f"(duration {scenario.duration_s:g} s, sample_rate_hz = {acq.sample_rate_hz:g}, "
            f"thermal_step_s = {acq.thermal_step_s:g}) but {folder} has "
            f"{human_bytes(free)} free; shorten the run or write elsewhere with -o")
    if progress and (est.seconds > LONG_RUN_S or est.output_bytes > BIG_OUTPUT_BYTES):
        print(f"rlgsim: estimate for {scenario.name}: about {human_bytes(est.output_bytes)} "
              f"to {out}, {human_bytes(est.block_bytes)} of memory per block, about "
              f"{human_seconds(est.seconds)}", file=sys.stderr, flush=True)
    return est
