"""Paper 002's Table 1 under the reading ``[metrics] published_before = "mean"`` of the
``environments`` recipe: the paper's "before" figure is the run's *mean* zero bias, its "after"
figures a σ of the compensated 100 s means, and its improvement factor their ratio
(docs/studies.md, Paper 002, gives the evidence: §4.1 quotes the same three numbers as the
"average zero bias"; every factor in Table 1 is before/after to its printed digits).

Under that reading ours is computed the same way: the mean of the raw 100 s bias of the test
run (data set 2) beside the paper's "before"; the σ (std, ddof, of ``cluster_s`` means) of
y − ŷ on the test run *and* on the train run (in-sample: the model's own data set) beside the
paper's "after"; and |mean before| / σ after beside the paper's factor. The paper does not say
whether its "after" is in- or out-of-sample; printing both lets the reader see which of ours
lands where the paper's does. :func:`evidence` states what the published numbers themselves
show (each factor = before/after; the "after" figures' spread over the environments against the
expected range of independent σ estimates); :func:`add_section` puts it all in the report.
"""

from __future__ import annotations

import numpy as np

from rlgsim.lab.report import Report, Table
from rlgsim.lab.studies.compensators import ORACLE
from rlgsim.lab.studies.environment_fits import EnvResult
from rlgsim.lab.studies.environment_tables import Config
from rlgsim.lab.studies.report_text import fmt


def mean_before(r: EnvResult, train: bool = False) -> float:
    """Mean raw bias [°/h] of the environment's test runs (or train runs), averaged over runs."""
    return float(np.mean([rs.y.mean() for rs in (r.train if train else r.tests)]))


def _factor(mean: float, sigma: float) -> float | None:
    return abs(mean) / sigma if sigma > 0 else None


def reading_table(results: list[EnvResult], config: Config) -> Table:
    """One row per (environment, compensator): the paper's mean before / σ after / factor
    beside ours, σ after on the test run and in-sample on the train run."""
    recs = []
    for r in results:
        pub = r.env.published
        m_test, m_train = mean_before(r), mean_before(r, train=True)
        for c in config.compensators:
            n = c.name
            after = r.scores[n]["stability_after"]
            ins = r.train_after[n]
            recs.append({
                "environment": r.env.name, "compensator": n,
                "paper before: mean (×10⁻³ °/h)": fmt(None if pub.stability_before is None
                                                      else 1e3 * pub.stability_before),
                "ours: mean, test (×10⁻³ °/h)": fmt(1e3 * m_test),
                "paper after σ (×10⁻⁴ °/h)": fmt(None if n not in pub.stability_after
                                                 else 1e4 * pub.stability_after[n]),
                "ours σ after, test (×10⁻⁴ °/h)": fmt(1e4 * after),
                "ours σ after, train in-sample (×10⁻⁴ °/h)": fmt(1e4 * ins),
                "oracle floor, test (×10⁻⁴ °/h)": fmt(1e4 * r.scores[ORACLE]["stability_after"])
                if ORACLE in r.scores else None,
                "paper factor": fmt(pub.improvement_factor.get(n)),
                "ours factor, test": fmt(_factor(m_test, after)),
                "ours factor, in-sample": fmt(_factor(m_train, ins)),
            })
    return Table.from_records(
        "Table 1 under the reading: 'before' = mean bias, 'after' = σ", recs,
        csv_name="table1_reading.csv",
        note=f"Ours: the mean of the raw {config.window_s:g} s bias; σ = std "
             f"(ddof={config.ddof}) of {config.cluster_s:g} s means of y − ŷ on the test run "
             f"(data set 2) and on the train run the model was fitted on (in-sample); factor "
             f"= |mean before| / σ after, the paper's arithmetic (5.17 = 7.218/1.3953). "
             f"Oracle floor: σ after removing the true temperature law (truth).")


def expected_range(k: int) -> float:
    """Expected range (max − min) of ``k`` independent standard normal draws,
    ∫ 1 − Φ(x)^k − (1 − Φ(x))^k dx (the d2 constant of control charts: 2.534 for k = 6)."""
    from scipy import integrate, stats
    f = lambda x: 1.0 - stats.norm.cdf(x) ** k - stats.norm.sf(x) ** k  # noqa: E731
    return float(integrate.quad(f, -np.inf, np.inf)[0])


def evidence(results: list[EnvResult]) -> list[str]:
    """The reading's evidence that the study file's numbers carry (docs/studies.md gives the
    paper's own words): the factors' arithmetic and how repeatable the "after" figures are
    against the standard error of a σ from one run's windows."""
    out = []
    pairs = [(r.env.published.stability_before / r.env.published.stability_after[n], f)
             for r in results if r.env.published.stability_before is not None
             for n, f in r.env.published.improvement_factor.items()
             if n in r.env.published.stability_after]
    if pairs:
        dev = max(abs(q / f - 1.0) for q, f in pairs)
        out.append(f"Every published improvement factor is the 'before' figure over the 'after' "
                   f"one ({len(pairs)} pairs, largest difference {100 * dev:.2f} %, the "
                   f"rounding of the printed digits): the paper divides a mean bias by a σ "
                   f"(§4.1 gives the same 'before' numbers as the 'average zero bias').")
    n = min(rs.y.size for r in results for rs in r.tests)
    se = 1.0 / np.sqrt(2.0 * (n - 1))
    names = sorted({m for r in results for m in r.env.published.stability_after})
    spreads, k = [], 0
    for m in names:
        vals = [r.env.published.stability_after[m] for r in results
                if m in r.env.published.stability_after]
        if len(vals) > 1:
            k = max(k, len(vals))
            spreads.append(f"{m} {100 * (max(vals) - min(vals)) / np.mean(vals):.2f} %")
    if spreads:
        out.append(f"The paper's 'after' figures, max − min over the environments relative to "
                   f"their mean: {', '.join(spreads)}. A σ estimated from one run of {n} "
                   f"windows has a relative standard error of 1/√(2·{n - 1}) = "
                   f"{100 * se:.1f} %, and {k} independent such estimates spread by "
                   f"{100 * se * expected_range(k):.1f} % on average: figures this repeatable "
                   f"are not independent runs' sample statistics (they behave like residuals "
                   f"held at each method's stopping goal).")
    return out


def reading_text(results: list[EnvResult], config: Config) -> list[str]:
    """What the reading's table shows, from the numbers."""
    names = [c.name for c in config.compensators]
    have = [r for r in results if r.env.published.stability_before is not None]
    out = []
    if have:
        ratios = [mean_before(r) / r.env.published.stability_before for r in have]
        out.append(f"Read as the mean zero bias, the paper's 'before' row against our test "
                   f"runs' mean bias: ours/paper {min(ratios):.3f} … {max(ratios):.3f} over "
                   f"{len(have)} environments.")
    for n in names:
        pairs = [(r, r.env.published.stability_after[n]) for r in results
                 if n in r.env.published.stability_after]
        if not pairs:
            continue
        test = [r.scores[n]["stability_after"] / p for r, p in pairs]
        ins = [r.train_after[n] / p for r, p in pairs]
        below = sum(p < r.scores[ORACLE]["stability_after"] for r, p in pairs
                    if ORACLE in r.scores)
        out.append(f"{n}: σ after ours/paper {min(test):.2f} … {max(test):.2f} on the test "
                   f"runs, {min(ins):.2f} … {max(ins):.2f} in-sample; the paper's figure lies "
                   f"below the test run's oracle floor (no model of the inputs can reach it "
                   f"out of sample) in {below} of {len(pairs)} environments.")
    return out


def add_section(rep: Report, results: list[EnvResult], config: Config) -> None:
    """The reading's paragraph, its evidence, the table and what it shows (after Table 1)."""
    rep.paragraph("The paper's 'before' figure is read as the run's mean zero bias and its "
                  "'after' figures as σ of the compensated 100 s means (study file, "
                  "[metrics] published_before = \"mean\"; evidence in docs/studies.md, "
                  "Paper 002). The table above keeps the paper's labels. Evidence in the "
                  "paper's numbers:")
    rep.bullets(evidence(results))
    rep.paragraph("Under the reading:")
    rep.table(reading_table(results, config))
    for para in reading_text(results, config):
        rep.paragraph(para)
