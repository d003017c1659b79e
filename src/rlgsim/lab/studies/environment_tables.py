"""The study tables of the ``environments`` recipe (paper 002): ``[[environment]]`` with its
train/test runs and the paper's numbers, validated into a :class:`Config` (the file format is
in :mod:`rlgsim.lab.studies.environments`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rlgsim.sim.config import (Ctx, check_known_keys, get_float, get_list, get_section, get_str,
                               get_table)
from rlgsim.lab.study import Study
from rlgsim.lab.studies.compensators import CompensatorSpec, parse_compensators
from rlgsim.lab.studies.study_tables import (FeatureSpec, RunSpec, check_features_on_devices,
                                             check_scenarios, parse_data, parse_features,
                                             parse_metrics, parse_runs)

TOP_KEYS = ("study", "data", "features", "compensator", "environment", "metrics",
            "navigation")
DATA_KEYS = ("window_s", "gyro")
ENVIRONMENT_KEYS = ("name", "train", "test", "published")
ENV_PUBLISHED_KEYS = ("stability_before_deg_per_h", "stability_after_deg_per_h",
                      "improvement_factor", "running_time_s")
#: Per-compensator tables of ``[environment.published]`` (key → what it holds, for messages).
PER_COMPENSATOR = {"stability_after_deg_per_h": "σ after compensation [°/h]",
                   "improvement_factor": "before/after", "running_time_s": "seconds"}
COMPENSATOR_PUBLISHED_KEYS = ("equation",)
METRIC_KEYS = ("cluster_s", "ddof", "published_before")
#: What the paper's "before" figure (``stability_before_deg_per_h``) measures: a bias
#: stability σ, or the mean bias of the run (paper 002's reading, docs/studies.md).
PUBLISHED_BEFORE = ("sigma", "mean")


@dataclass(frozen=True)
class EnvPublished:
    """The paper's numbers for one environment (°/h, before/after ratio, s); None/empty where
    the paper gives none."""

    stability_before: float | None = None
    stability_after: dict[str, float] = field(default_factory=dict)
    improvement_factor: dict[str, float] = field(default_factory=dict)
    running_time_s: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Environment:
    """One environment: its train runs (data set 1), test runs (data set 2), paper numbers."""

    name: str
    train: tuple[RunSpec, ...]
    test: tuple[RunSpec, ...]
    published: EnvPublished
    ctx: Ctx


@dataclass(frozen=True)
class Config(FeatureSpec):
    """A validated environments study."""

    environments: tuple[Environment, ...] = ()
    compensators: tuple[CompensatorSpec, ...] = ()
    cluster_s: float = 100.0
    ddof: int = 1
    published_before: str = "sigma"   # what the paper's "before" figure is (PUBLISHED_BEFORE)


def _parse_published(env: dict, ectx: Ctx, names: list[str]) -> EnvPublished:
    """``[environment.published]``: numbers > 0 (running time >= 0), per-compensator tables
    keyed by compensator name."""
    ptable, pctx = get_section(env, "published", ectx, ENV_PUBLISHED_KEYS, {})
    before = get_float(ptable, "stability_before_deg_per_h", pctx, None, min=0.0,
                       min_exclusive=True)
    per: dict[str, dict[str, float]] = {}
    for key in PER_COMPENSATOR:
        table = get_table(ptable, key, pctx, {})
        tctx = pctx.child(key)
        check_known_keys(table, names, tctx)
        timing = key == "running_time_s"
        per[key] = {n: get_float(table, n, tctx, min=0.0, min_exclusive=not timing)
                    for n in table}
    return EnvPublished(stability_before=before, stability_after=per["stability_after_deg_per_h"],
                        improvement_factor=per["improvement_factor"],
                        running_time_s=per["running_time_s"])


def _parse_environment(item: Any, i: int, ctx: Ctx, names: list[str]) -> Environment:
    """One ``[[environment]]`` table (``ctx``: the array)."""
    ectx = ctx.item(i)
    if not isinstance(item, dict):
        raise Ctx(ctx.source).error(ectx.path, f"expected a table, got {item!r}")
    check_known_keys(item, ENVIRONMENT_KEYS, ectx)
    name = get_str(item, "name", ectx)
    if not name.strip() or "@" in name or ":" in name:
        raise ectx.error("name", f"value {name!r} not allowed; give a non-empty name without "
                                 "'@' or ':' (results are named metric@environment)")
    return Environment(name=name, train=parse_runs(item, "train", ectx),
                       test=parse_runs(item, "test", ectx),
                       published=_parse_published(item, ectx, names), ctx=ectx)


def _parse_environments(data: dict, ctx: Ctx, names: list[str]) -> tuple[Environment, ...]:
    """Every ``[[environment]]`` table (at least one; names unique)."""
    if "environment" not in data:
        raise ctx.error("environment", "missing: give at least one [[environment]] table "
                                       "(name, train, test)")
    items = get_list(data, "environment", ctx, min_len=1)
    envs = tuple(_parse_environment(item, i, ctx.child("environment"), names)
                 for i, item in enumerate(items))
    seen: set[str] = set()
    for env in envs:
        if env.name in seen:
            raise env.ctx.error("name", f"environment {env.name!r} is named twice")
        seen.add(env.name)
    return envs


def parse_config(study: Study) -> Config:
    """Validate the recipe's tables into a :class:`Config`;
    :class:`~rlgsim.ground.errors.UserInputError` naming file/key/value."""
    data = study.tables
    ctx = study.ctx()
    check_known_keys(data, TOP_KEYS, ctx)
    d = parse_data(study, DATA_KEYS, runs=False)
    window_s, gyro = d.window_s, d.gyro
    features = parse_features(data, ctx, window_s, gyro)
    comps = parse_compensators(data, ctx, features.feature_names(), COMPENSATOR_PUBLISHED_KEYS,
                               base_dir=study.base_dir)
    envs = _parse_environments(data, ctx, [c.name for c in comps])
    from rlgsim.lab.studies.imu_axes import parse_navigation
    parse_navigation(study, [c.name for c in comps])    # the three-gyro IMU's [navigation]
    for env in envs:
        check_scenarios(study, env.train + env.test)
        check_features_on_devices(study, env.train + env.test, features)
    mtable, mctx, cluster_s, ddof = parse_metrics(data, ctx, window_s, METRIC_KEYS)
    before = get_str(mtable, "published_before", mctx, "sigma")
    if before not in PUBLISHED_BEFORE:
        raise mctx.error("published_before", f"value {before!r} not allowed; allowed: "
                                             f"{', '.join(PUBLISHED_BEFORE)}")
    return Config(**vars(features), environments=envs, compensators=comps,
                  cluster_s=cluster_s, ddof=ddof, published_before=before)
