"""``rlgsim montecarlo``: run a study over many simulated units and summarise the spread.

    rlgsim montecarlo STUDY --units N [--workers K | --scheduler ADDRESS] [-o DIR] [--quiet]
                      [--chamber-offset-c S] [--chamber-rate-rel R]

Unit ``i`` is the study run for Monte Carlo unit ``i`` (:func:`rlgsim.lab.study.study_unit`): another
device drawn from the presets' tolerance models (IMU realisation and thermal network, keyed by
``(device_seed, i)``) and other noise (keyed by ``(seed, i)``); optionally its own chamber-profile
variation (:mod:`rlgsim.sim.run.unit_variations`). The campaign engine is
:mod:`rlgsim.lab.montecarlo` (one task per unit through :class:`concurrent.futures.Executor`: a local
process pool, or ``dask.distributed.Client(ADDRESS).get_executor()``; per-unit atomic commits;
resumption; failure records). This module adds the command line, the unit function used by it
(:func:`montecarlo_unit`: one BLAS thread per worker, timing rows left out so the table is the
same bytes everywhere, the thermal realisation's summary among the unit's parameters) and the
summary report (:func:`summary_report`). docs/montecarlo.md is the user guide.

Output folder: ``results.csv`` (unit, compensator, metric, value), ``units.csv`` (unit, status,
drawn parameters, error), ``units/`` (one JSON record per finished unit), ``campaign.json`` (the
campaign's identity: resuming another study in the same folder is refused) and the summary
report (``report.md``, ``report.html``, CSV tables, PNG figures).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time
from typing import Any, Callable, Sequence

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.cli.arg_types import number, whole_number

#: Metrics that are wall-clock timings: not a property of the unit, so never in results.csv
#: (they would make the table depend on the machine and its load).
TIMING_METRICS = ("fit_s",)

#: Metrics shown first (figures, worst units) when a study reports them.
PRIMARY_METRICS = ("stability_after", "improvement_pct", "resid_std_true", "rmse_true",
                   "law_resid_std", "r2_true")

#: How many box/violin figures the summary draws at most (one per metric).
MAX_FIGURES = 6
#: Navigation scores drawn beside them whenever the units navigated (docs/navigation.md)
NAV_FIGURE_METRICS = ("nav_radial_rate_nmi_per_h", "nav_heading_end_arcmin")
#: How many drawn parameters the worst-units tables show (units.csv has them all).
MAX_PARAMS = 10


# ------------------------------------------------------------------------------ the unit
def _is_timing(metric: str) -> bool:
    return metric.split("@")[0] in TIMING_METRICS


def thermal_params(study, unit: int) -> dict[str, float]:
    """Summary of unit ``unit``'s drawn thermal network (:func:`rlgsim.sim.stages.thermal.thermal_summary`)
    when every scenario of the study simulates the same physical unit (the study sets
    ``device_seed``, or all its scenarios share device preset and realisation seed); else {}."""
    from rlgsim.sim.stages.thermal import realised_network, thermal_summary
    from rlgsim.lab.study import scenario_for, scenario_refs

    keys = set()
    first = None
    for ref in scenario_refs(study.tables):
        try:
            sc = scenario_for(study, ref, unit=unit)
        except UserInputError:
            return {}
        keys.add((sc.device.thermal.text, sc.realisation_seed))
        first = first or sc
    if first is None or (len(keys) != 1 and study.device_seed is None):
        return {}
    return thermal_summary(realised_network(first))


def chamber_params(study, unit: int, variation) -> dict[str, float]:
    """The chamber variation drawn for the study's first scenario (rlgsim.sim.run.unit_variations)."""
    from rlgsim.lab.study import scenario_for, scenario_refs
    from rlgsim.sim.run.unit_variations import draw

    refs = scenario_refs(study.tables)
    if not variation.active or not refs:
        return {}
    try:
        sc = scenario_for(study, refs[0], unit=unit)
    except UserInputError:
        return {}
    offset, factor = draw(sc.seed, unit, variation)
    return {"chamber.offset_c": offset, "chamber.rate_factor": factor}


def montecarlo_unit(payload: dict[str, Any], unit: int) -> dict[str, Any]:
    """The unit function of ``rlgsim montecarlo``: :func:`rlgsim.lab.study.study_unit` with one BLAS
    thread (so K workers on K cores do not oversubscribe), without timing rows, and with the
    thermal realisation's summary added to the unit's parameters."""
    import numpy  # noqa: F401  - load the BLAS libraries before limiting them
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    from rlgsim.lab.study import parse_study, study_unit
    from rlgsim.sim.run.unit_variations import ChamberVariation, varied

    variation = ChamberVariation(**payload.get("chamber_variation", {}))
    with threadpool_limits(limits=1, user_api="blas"), varied(variation):
        out = study_unit(payload, unit)
        study = parse_study(payload["text"], payload["source"],
                            base_dir=pathlib.Path(payload["base_dir"]) if payload.get("base_dir")
                            else None, default_name=payload.get("name", "study"))
        params = {**out.get("params", {}), **thermal_params(study, unit),
                  **chamber_params(study, unit, variation)}
    rows = [r for r in out.get("rows", []) if not _is_timing(str(r[1]))]
    return {"rows": rows, "params": params}


# ------------------------------------------------------------------------------ executors
def _blas_one_thread_env() -> None:
    """Worker processes started from here load their BLAS with one thread."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def connect(address: str, timeout_s: float = 10.0):
    """A ``dask.distributed.Client`` for ``address`` (tcp://host:port); a bad or unreachable
    address is a :class:`UserInputError`."""
    if "://" not in address or not address.split("://", 1)[1]:
        raise UserInputError(f"--scheduler: value {address!r} not allowed; expected a scheduler "
                             f"address such as tcp://host:8786")
    try:
        from distributed import Client
    except ImportError:
        raise UserInputError("--scheduler needs Dask's distributed scheduler, an optional extra: "
                             "pip install 'rlgsim[cluster]' (without --scheduler the units run "
                             "in local processes)") from None
    scheme, _, rest = address.partition("://")
    if scheme == "tcp":                 # fail fast on a refused or unknown host:port
        import socket
        host, _, port = rest.rpartition(":")
        try:
            socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s).close()
        except ValueError:
            raise UserInputError(f"--scheduler: value {address!r} not allowed; expected "
                                 f"tcp://host:port") from None
        except OSError as exc:
            raise UserInputError(f"--scheduler: cannot connect to {address!r} "
                                 f"({exc.strerror or type(exc).__name__})") from None
    try:
        return Client(address, timeout=timeout_s)
    except (OSError, TimeoutError, ValueError) as exc:
        raise UserInputError(f"--scheduler: cannot connect to {address!r} "
                             f"({type(exc).__name__}: {' '.join(str(exc).split())[:160]})"
                             ) from None


# ------------------------------------------------------------------------------ campaign
def study_payload(study) -> dict[str, Any]:
    """What a worker needs to rebuild the study (no access to the user's files)."""
    return {"text": study.text, "source": study.source,
            "base_dir": str(study.base_dir) if study.base_dir is not None else "",
            "name": study.name}


def identity(payload: dict[str, Any], unit_fn: Callable) -> dict[str, Any]:
    """The campaign's identity (``campaign.json``): the study text (its seeds included) and the
    unit function. A folder holding another identity is refused."""
    out = {"kind": "rlgsim montecarlo", "study_text": payload.get("text", repr(payload)),
           "unit_function": f"{unit_fn.__module__}.{unit_fn.__qualname__}"}
    if payload.get("chamber_variation"):
        out["chamber_variation"] = payload["chamber_variation"]
    return out


def run(payload: dict[str, Any], n_units: int, out_dir: str | os.PathLike, *,
        workers: int = 1, scheduler: str | None = None, executor=None, quiet: bool = False,
        unit_fn: Callable[[Any, int], dict] = montecarlo_unit, title: str = "study",
        baseline: str | None = "raw") -> pathlib.Path:
    """Run (or resume) a campaign and write tables and summary; returns report.md's path."""
    from rlgsim.lab.montecarlo import run_campaign, write_tables

    if n_units < 1:
        raise UserInputError(f"--units: value {n_units} not allowed; must be >= 1")
    if workers < 1:
        raise UserInputError(f"--workers: value {workers} not allowed; must be >= 1")
    from rlgsim.lab.report import output_folder
    _blas_one_thread_env()
    client = connect(scheduler) if scheduler and executor is None else None   # before the
    t0 = time.perf_counter()                     # folder: an unreachable one leaves none
    try:
        out = output_folder(out_dir)
        if client is not None:
            executor = client.get_executor()
        records = run_campaign(unit_fn, payload, n_units, out, executor=executor,
                               workers=workers, identity=identity(payload, unit_fn),
                               progress=not quiet)
    finally:
        if client is not None:
            client.close()
    wall = time.perf_counter() - t0
    write_tables(out, records)
    report = summary_report(records, n_units, title=title, baseline=baseline)
    path = report.write(out)
    if not quiet:
        failed = sum(r.status != "ok" for r in records)
        missing = n_units - len(records)
        print(f"wrote {out}/results.csv, units.csv and {path.name}: {len(records) - failed} "
              f"units ok, {failed} failed, {missing} missing ({wall:.1f} s)")
    return path


# ------------------------------------------------------------------------------ summary
def _metric_order(metrics: Sequence[str]) -> list[str]:
    def key(m: str) -> tuple[int, str]:
        base = m.split("@")[0]
        return (PRIMARY_METRICS.index(base) if base in PRIMARY_METRICS else len(PRIMARY_METRICS),
                m)
    return sorted(set(metrics), key=key)


def summary_report(records, n_units: int, *, title: str, baseline: str | None):
    """The campaign's report: distributions per compensator and metric, box/violin plots, the
    worst units of each compensator with their drawn parameters, failed units."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from rlgsim.lab.montecarlo_summary import (clean_tiny, metric_matrix, metric_unit, summarise,
                                               worst_units)
    from rlgsim.lab.report import Report, Table

    ok = [r for r in records if r.status == "ok"]
    failed = [r for r in records if r.status != "ok"]
    matrix = metric_matrix(records)
    comps = list(dict.fromkeys(c for r in ok for c, _, _ in r.rows))
    if baseline not in comps:
        baseline = "raw" if "raw" in comps else None
    metrics = _metric_order([m for _, m in matrix])
    rep = Report(f"Monte Carlo: {title}")
    rep.paragraph(f"{n_units} units requested; {len(ok)} ok, {len(failed)} failed, "
                  f"{n_units - len(records)} missing. Unit i is the study run on device "
                  f"realisation i (tolerance models of the presets) with its own noise; "
                  f"baseline for 'beats baseline': {baseline or 'none'}.")
    rows = []
    summaries = [s for s in summarise(records, baseline) if not s.same_as_baseline]
    scale = {}                  # per metric: the largest magnitude over the compensators
    for s in summaries:
        mags = [abs(v) for v in (s.median, s.p5, s.p95) if np.isfinite(v)]
        scale[s.metric] = max([scale.get(s.metric, 0.0), *mags])
    for s in summaries:
        med, p5, p95 = clean_tiny([s.median, s.p5, s.p95], scale[s.metric])
        rows.append([s.compensator, s.metric, metric_unit(s.metric), s.n_units, med, p5, p95,
                     None if np.isnan(s.beats_baseline) else s.beats_baseline])
    rows.sort(key=lambda r: (comps.index(r[0]) if r[0] in comps else len(comps),
                             metrics.index(r[1]) if r[1] in metrics else len(metrics)))
    rep.heading("Distribution per compensator and metric", 2)
    rep.table(Table("Distributions", ["compensator", "metric", "unit", "units", "median", "p5",
                                      "p95", "beats baseline"], rows,
                    note="p5/p95: 5th and 95th percentiles over the units; 'beats baseline': "
                         "share of units (0-1) where the compensator does better than the "
                         "baseline on that metric (larger is better for r2 and improvement, "
                         "smaller otherwise). A metric equal to the baseline's on every unit "
                         "(the stability before compensation) is shown for the baseline only; "
                         "values below 1e-9 of the metric's largest are shown as 0 (rounding).",
                    csv_name="summary.csv"))

    rep.heading("Spread over the units", 2)
    drawn = metrics[:MAX_FIGURES]
    drawn += [m for m in metrics if m.split("@")[0] in NAV_FIGURE_METRICS
              and m not in drawn]            # paper 002: one per environment (m@env)
    for metric in drawn:
        names = [c for c in comps if matrix.get((c, metric))]
        data = [np.asarray(list(matrix[(c, metric)].values()), float) for c in names]
        data = [d[np.isfinite(d)] for d in data]
        keep = [(n, d) for n, d in zip(names, data) if d.size]
        if not keep:
            continue
        fig, ax = plt.subplots(figsize=(max(5.0, 1.2 * len(keep) + 2), 3.6))
        pos = np.arange(1, len(keep) + 1)
        if all(d.size > 1 and np.ptp(d) > 0 for _, d in keep):
            ax.violinplot([d for _, d in keep], positions=pos, showextrema=False)
        ax.boxplot([d for _, d in keep], positions=pos, widths=0.25, showfliers=True)
        ax.set_xticks(pos)
        ax.set_xticklabels([n for n, _ in keep], rotation=25, ha="right", fontsize=8)
        unit = metric_unit(metric)
        ax.set_ylabel(f"{metric} [{unit}]" if unit else metric)
        ax.grid(True, axis="y", alpha=0.3)
        rep.figure(fig, f"spread_{metric}", f"{metric} over {len(ok)} units: violin (density) "
                                           f"and box (median, quartiles, 1.5 IQR whiskers)")

    primary = metrics[0] if metrics else None
    shown = varying_params(ok)
    if primary is not None:
        rep.heading(f"Worst units per compensator ({primary})", 2)
        for comp in comps:
            worst = worst_units(records, comp, primary, count=5)
            if not worst:
                continue
            pnames = shown[:MAX_PARAMS]
            rep.table(Table(f"Worst units: {comp}", ["unit", primary, *pnames],
                            [[u, v, *[p.get(k) for k in pnames]] for u, v, p in worst],
                            csv_name=f"worst_{_slug(comp)}.csv"))
    if failed:
        rep.heading("Failed units", 2)
        rep.table(Table("Failed units", ["unit", "error"],
                        [[r.unit, r.error.splitlines()[0] if r.error else ""] for r in failed],
                        csv_name="failed_units.csv"))
    return rep


def varying_params(records) -> list[str]:
    """Parameter names whose value differs between units (constant ones say nothing about why
    a unit fails), chamber variation and thermal summary first, then by name."""
    values: dict[str, set[float]] = {}
    for r in records:
        for k, v in r.params.items():
            values.setdefault(k, set()).add(v)
    names = [k for k, vs in values.items() if len(vs) > 1]
    return sorted(names, key=lambda k: (not k.startswith(("chamber.", "thermal.")), k))


def _slug(text: str) -> str:
    from rlgsim.lab.report import slug
    return slug(text)


# ------------------------------------------------------------------------------ command line
def add_subparser(sub) -> None:
    """Register ``rlgsim montecarlo`` on the CLI's subparsers."""
    units, sigma = whole_number("a whole number of units"), number(0.0, strict=False)
    m = sub.add_parser("montecarlo", help="run a study over N simulated units (local processes "
                                          "or a Dask cluster) and summarise the spread")
    m.add_argument("study", metavar="STUDY",
                   help="a shipped study's name or a path to a study .toml file")
    m.add_argument("--units", type=units, required=True, metavar="N",
                   help="number of units (0 .. N-1); re-running only runs missing units")
    where = m.add_mutually_exclusive_group()
    where.add_argument("--workers", type=units, default=1, metavar="K",
                       help="local worker processes (default 1)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="a Dask scheduler (tcp://host:port): run the units on its cluster")
    m.add_argument("--chamber-offset-c", type=sigma, default=0.0, metavar="S",
                   help="per-unit chamber temperature offset, 1 sigma [K] (default 0)")
    m.add_argument("--chamber-rate-rel", type=sigma, default=0.0, metavar="R",
                   help="per-unit relative spread of the chamber ramp rates, 1 sigma "
                        "(log-normal; default 0)")
    m.add_argument("-o", "--output", metavar="DIR",
                   help="output folder (default: ./montecarlo-<study name>)")
    m.add_argument("-q", "--quiet", action="store_true", help="no progress bar, no summary line")
    m.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from rlgsim.lab.study import load_study

    study = load_study(args.study)
    baseline = None
    metrics = study.tables.get("metrics")
    if isinstance(metrics, dict) and isinstance(metrics.get("baseline"), str):
        baseline = metrics["baseline"]
    from rlgsim.lab.cli.paths import name_path, output_folder
    out = output_folder(args.output or name_path(study.name, prefix="montecarlo-",
                                                 source=study.source, key="study.name"),
                        inputs=[study.source])
    payload = study_payload(study)
    if args.chamber_offset_c or args.chamber_rate_rel:
        payload["chamber_variation"] = {"offset_c": args.chamber_offset_c,
                                        "rate_rel": args.chamber_rate_rel}
    run(payload, args.units, out, workers=args.workers, scheduler=args.scheduler,
        quiet=args.quiet, title=study.name, baseline=baseline or "raw")
    return 0
