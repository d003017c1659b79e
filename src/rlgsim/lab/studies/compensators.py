"""The ``[[compensator]]`` tables of a single-gyro study: the registry of built-in kinds, a
user's own scikit-learn regressor (``kind = "custom"``), and the estimator a table builds.

Study-file piece parsed here::

    [[compensator]]
    name = "LS cubic T"               # unique label in the report (not "raw" nor the oracle's)
    kind = "polynomial"               # see KINDS (rlgsim.estimators.compensator_kinds), or
                                      # "custom" with estimator = "..."
    inputs = ["T"]                    # feature names ([features], :mod:`.study_tables`)
    params = { degree = 3 }           # estimator constructor keywords
    table = "Table 2"                 # optional: groups compensators into a paper table
    published = { ... }               # optional: the paper's numbers (keys: the recipe's)

Besides the study's compensators every test run is scored with two references: :data:`RAW`
(no compensation, ŷ = the train mean) and :data:`ORACLE` (ŷ = b − r, the true temperature law),
whose names a compensator may not take.
"""

from __future__ import annotations

import dataclasses
import pathlib
from dataclasses import dataclass
from typing import Any

from rlgsim.estimators.compensator_kinds import KINDS, estimator_class
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_str, get_table
from rlgsim.lab.studies.study_tables import str_list

COMPENSATOR_KEYS = ("name", "kind", "inputs", "params", "table", "published", "estimator")
CUSTOM = "custom"   # kind of a user's own scikit-learn regressor (key ``estimator``)

#: Kinds whose fitted model prints an equation (rlgsim.estimators.term_model).
EQUATION_KINDS = tuple(k for k, spec in KINDS.items() if spec.closed_form == "polynomial")

#: The reference compensators every test run is scored with (reserved names).
ORACLE = "truth: temperature law"
RAW = "raw"


@dataclass(frozen=True)
class CompensatorSpec:
    """One validated ``[[compensator]]`` table (``ctx`` names it in messages)."""

    name: str
    kind: str
    inputs: tuple[str, ...]
    params: dict
    table: str
    published: dict
    ctx: Ctx
    estimator: str = ""                       # kind "custom": "module:Class" or "file.py:Class"
    base_dir: pathlib.Path | None = None      # where a "file.py" estimator is looked up


def spec_class(spec: CompensatorSpec):
    """The estimator class of a compensator: a built-in kind, or the user's own."""
    if spec.kind == CUSTOM:
        return load_custom_estimator(spec.estimator, spec.base_dir, spec.ctx)
    return estimator_class(spec.kind)


def load_custom_estimator(ref: str, base_dir: pathlib.Path | None, ctx: Ctx):
    """Import a user's regressor class from ``"package.module:Class"`` (importable) or
    ``"path/to/file.py:Class"`` (relative to the study file). It must follow the scikit-learn
    regressor contract: constructible without arguments, ``get_params``, ``fit(X, y)`` and
    ``predict(X)``; X is a 2-D float array of the inputs in the order the study lists them
    (an :class:`rlgsim.estimators.columns.Columns`, which also carries their names)."""
    import importlib.util
    import sys

    where, sep, name = ref.rpartition(":")
    if not sep or not where or not name.isidentifier():
        raise ctx.error("estimator", f"value {ref!r} not allowed; give 'package.module:Class' "
                                     "or 'file.py:Class' (relative to the study file)")
    try:
        if where.endswith(".py"):
            path = pathlib.Path(where)
            if not path.is_absolute() and base_dir is not None:
                path = base_dir / path
            if not path.is_file():
                raise ctx.error("estimator", f"file {str(path)!r} not found (value {ref!r})")
            mod_name = f"rlgsim_custom_{abs(hash(str(path.resolve())))}"
            module = sys.modules.get(mod_name)
            if module is None:
                spec = importlib.util.spec_from_file_location(mod_name, path)
                module = importlib.util.module_from_spec(spec)
                sys.modules[mod_name] = module
                try:
                    spec.loader.exec_module(module)
                except BaseException:
                    del sys.modules[mod_name]
                    raise
        else:
            module = importlib.import_module(where)
    except UserInputError:
        raise
    except (Exception, SystemExit) as exc:   # the user's module failed to import: say why
        raise ctx.error("estimator", f"cannot import {where!r} (value {ref!r}): "
                                     f"{type(exc).__name__}: {' '.join(str(exc).split())}"
                        ) from None
    cls = getattr(module, name, None)
    if cls is None or not isinstance(cls, type):
        raise ctx.error("estimator", f"{where!r} has no class {name!r} (value {ref!r})")
    missing = [m for m in ("fit", "predict", "get_params") if not callable(getattr(cls, m, None))]
    if missing:
        raise ctx.error("estimator", f"class {name!r} lacks {', '.join(missing)}; a compensator "
                                     "must be a scikit-learn regressor (derive from "
                                     "sklearn.base.BaseEstimator and RegressorMixin)")
    return cls


def parse_compensator(item: Any, i: int, ctx: Ctx, features: list[str],
                      published_keys: tuple[str, ...], *, min_inputs: int = 1,
                      base_dir: pathlib.Path | None = None) -> CompensatorSpec:
    """One ``[[compensator]]`` table (``ctx`` names the array); ``published_keys``: what its
    ``published`` table may hold (numbers, or ``equation``: text); ``min_inputs``: 0 where the
    recipe adds inputs itself; ``base_dir``: the study file's folder (custom estimators)."""
    cctx = ctx.item(i)
    if not isinstance(item, dict):
        raise Ctx(ctx.source).error(cctx.path, f"expected a table, got {item!r}")
    check_known_keys(item, COMPENSATOR_KEYS, cctx)
    name = get_str(item, "name", cctx)
    if not name.strip() or name in (RAW, ORACLE):
        raise cctx.error("name", f"value {name!r} not allowed (empty or reserved)")
    kind = get_str(item, "kind", cctx, choices=[*KINDS, CUSTOM])
    estimator = get_str(item, "estimator", cctx, "")
    if kind == CUSTOM and not estimator:
        raise cctx.error("estimator", "missing: kind = \"custom\" needs estimator = "
                                      "'package.module:Class' or 'file.py:Class'")
    if kind != CUSTOM and estimator:
        raise cctx.error("estimator", f"only with kind = \"custom\" (this one is {kind!r})")
    inputs = str_list(item, "inputs", cctx, min_len=min_inputs)
    for x in inputs:
        if x not in features:
            raise cctx.error("inputs", f"unknown input {x!r}; the [features] table gives: "
                                       f"{', '.join(features) or '(none)'}")
    params = get_table(item, "params", cctx, {})
    spec = CompensatorSpec(name=name, kind=kind, inputs=inputs, params=params, table="",
                           published={}, ctx=cctx, estimator=estimator, base_dir=base_dir)
    cls = spec_class(spec)
    try:
        allowed = set(cls().get_params()) | set(KINDS[kind].recipe_keys if kind in KINDS else ())
    except Exception as exc:
        raise cctx.error("estimator", f"{cls.__name__}() failed: {type(exc).__name__}: "
                                      f"{' '.join(str(exc).split())} (a scikit-learn "
                                      "regressor must be constructible without arguments)"
                         ) from None
    allowed.discard("feature_names")
    check_known_keys(params, sorted(allowed), cctx.child("params"))
    published = get_table(item, "published", cctx, {})
    pctx = cctx.child("published")
    check_known_keys(published, published_keys, pctx)
    for k in published:
        if k == "equation":
            get_str(published, k, pctx)
        else:
            get_float(published, k, pctx)
    return dataclasses.replace(spec, table=get_str(item, "table", cctx, ""),
                               published=published)


def parse_compensators(data: dict, ctx: Ctx, features: list[str],
                       published_keys: tuple[str, ...], *, min_inputs: int = 1,
                       base_dir: pathlib.Path | None = None) -> tuple[CompensatorSpec, ...]:
    """Every ``[[compensator]]`` table (at least one; names unique)."""
    items = data.get("compensator")
    if not isinstance(items, list) or not items:
        raise ctx.error("compensator", "missing: give at least one [[compensator]] table")
    comps = tuple(parse_compensator(item, i, ctx.child("compensator"), features, published_keys,
                                    min_inputs=min_inputs, base_dir=base_dir)
                  for i, item in enumerate(items))
    names = [c.name for c in comps]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ctx.error("compensator", f"name {sorted(dup)[0]!r} is used twice")
    return comps


def make_estimator(spec: CompensatorSpec, random_state: int):
    """The estimator of ``spec`` (ir_lssvm: its (gamma, sigma2) are tuned in :func:`fit`)."""
    cls = spec_class(spec)
    extra = KINDS[spec.kind].recipe_keys if spec.kind in KINDS else ()
    params = {k: v for k, v in spec.params.items() if k not in extra}
    if "random_state" in cls().get_params() and "random_state" not in params:
        params["random_state"] = random_state
    return cls(**params)
