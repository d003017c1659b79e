"""The run-to-run section of a study report: which day each run was, and what that day drew.

Every run of a study whose scenario has a ``run_seed`` and whose device has a ``[run_to_run]``
table got its own turn-on bias, laboratory and chamber offsets, film and mount factors
(:mod:`rlgsim.sim.run.run_to_run`). The report prints them per run, so a reader sees how far
the test day was from the training day before reading any ranking; the values are drawn again
from the scenario (the same function the simulator called), not read back from the dataset.
"""

from __future__ import annotations

from typing import Any

from rlgsim.lab.report import Report, Table
from rlgsim.sim.run import run_to_run

__all__ = ["run_to_run_records", "run_to_run_section"]


def run_to_run_records(runs: dict, train: tuple, test: tuple) -> list[dict[str, Any]]:
    """One record per simulated run (``runs``: RunSpec.key → LoadedRun): its role, label, run
    seed and the drawn values (empty when no run has a run seed)."""
    out = []
    for spec in dict.fromkeys(tuple(train) + tuple(test)):
        scenario = runs[spec.key].scenario
        if scenario is None:
            continue
        d = run_to_run.draw(scenario)
        if d is None:
            continue
        out.append({"role": "train" if spec in train else "test", "run": spec.label,
                    "run_seed": d.run_seed,
                    "turn-on bias [°/h]": ", ".join(f"{v:+.5f}"
                                                    for v in d.turn_on_bias_deg_per_h),
                    "lab offset [K]": round(d.lab_offset_c, 3),
                    "chamber offset [K]": round(d.chamber_offset_c, 3),
                    "film factor": round(d.film_factor, 4),
                    "mount factor": round(d.mount_factor, 4)})
    return out


def run_to_run_section(rep: Report, runs: dict, train: tuple, test: tuple) -> None:
    """Add the "Run to run" heading, a paragraph and the table (nothing when no run drew)."""
    records = run_to_run_records(runs, train, test)
    if not records:
        return
    spec = next(runs[s.key].scenario for s in dict.fromkeys(tuple(train) + tuple(test))
                if runs[s.key].scenario is not None).device.parts.get("run_to_run")
    rep.heading("Run to run: each run's day", 2)
    spreads = ("" if spec is None else
               f" (1σ: turn-on bias {spec.turn_on_bias_deg_per_h:g} °/h, laboratory "
               f"{spec.lab_offset_c:g} K, chamber {spec.chamber_offset_c:g} K, film "
               f"{spec.film_coefficient_rel:g}, mount {spec.mount_conductance_rel:g} "
               "relative)")
    rep.paragraph("Train and test are different turn-ons of the same unit on different days: "
                  "each run's run_seed draws a turn-on bias offset, a laboratory and a chamber "
                  "air offset and factors on the film coefficient to the chamber air and on the "
                  f"mount conductance{spreads}. A constant turn-on offset does not change a "
                  "bias-stability (STD) figure; it shifts a test run's mean, which a model "
                  "trained on another day cannot know.")
    rep.table(Table.from_records("Run-to-run draws per run", records))
