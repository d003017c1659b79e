"""Fitting the compensators of a study on the train windows and predicting a run's bias.

A ValueError/TypeError of a built-in estimator (a bad parameter value in the study file) and any
exception of a custom one become a :class:`~rlgsim.ground.errors.UserInputError` naming the
compensator. IR-LSSVM's (c, σ²) are tuned once per input set on the unweighted LS-SVM and
shared by its weight functions (paper 001 §2.3).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.studies.compensators import CUSTOM, CompensatorSpec, make_estimator
from rlgsim.lab.studies.runs import RunSeries


@dataclass
class Fitted:
    spec: CompensatorSpec
    model: Any
    fit_s: float
    hyper: dict[str, float]
    X_train: Any = None         # the inputs it was fitted on (their range: the export's)


def fit(spec: CompensatorSpec, X, y: np.ndarray, random_state: int,
        tuned: dict | None = None) -> Fitted:
    """Fit ``spec`` on the train windows. A ValueError from the estimator (a bad parameter
    value in the study file) becomes a UserInputError naming the compensator. ``tuned`` caches
    the (gamma, sigma2) of IR-LSSVM's unweighted tuning per inputs and tuning settings, so the
    four weight functions of one input set share one cross-validation (as in paper 001 §2.3,
    where the weights are applied to the one tuned LS-SVM)."""
    import warnings

    from sklearn.exceptions import ConvergenceWarning
    t0 = time.perf_counter()
    Xi = X.select(spec.inputs)
    hyper: dict[str, float] = {}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            model = make_estimator(spec, random_state)
            key = _tuning_key(spec)
            if key is not None:
                from rlgsim.estimators.lssvm_cv import LSSVMRegressorCV
                p = spec.params
                kw = {k: p[k] for k in ("gammas", "sigma2s") if k in p}
                if tuned is None or key not in tuned:
                    tuner = LSSVMRegressorCV(cv=p.get("tune_cv", 10),
                                             scoring=p.get("tune_scoring", "mse"),
                                             random_state=random_state, **kw).fit(Xi, y)
                    pair = (tuner.gamma_, tuner.sigma2_)
                    if tuned is not None:
                        tuned[key] = pair
                else:
                    pair = tuned[key]
                model.set_params(gamma=pair[0], sigma2=pair[1])
            model.fit(Xi, y)
    except SystemExit as exc:       # sys.exit() in the user's fit: not a silent exit 0
        if spec.kind != CUSTOM:
            raise
        raise spec.ctx.error("estimator", f"compensator {spec.name!r} (custom) called "
                                          f"sys.exit({exc.code!r}) in fit instead of returning "
                                          f"self") from None
    except Exception as exc:        # built-in kinds: a bad value; custom: the user's code
        if spec.kind != CUSTOM and not isinstance(exc, (ValueError, TypeError)):
            raise
        what = "" if spec.kind != CUSTOM else f"{type(exc).__name__}: "
        raise spec.ctx.error("params", f"compensator {spec.name!r} ({spec.kind}) could not be "
                                       f"fitted: {what}{' '.join(str(exc).split())}") from None
    for attr, key in (("gamma_", "c"), ("sigma2_", "sigma2"), ("weight_param_", "weight_param"),
                      ("width_", "width"), ("n_centers_", "centres")):
        v = getattr(model, attr, None)
        if isinstance(v, (int, float, np.floating, np.integer)) and v is not None:
            hyper[key] = float(v)
    if spec.kind == "ir_lssvm":
        hyper["c"], hyper["sigma2"] = float(model.gamma), float(model.sigma2)
    if hasattr(model, "best_params_"):
        hyper.update({k: float(v) for k, v in model.best_params_.items()})
    return Fitted(spec, model, time.perf_counter() - t0, hyper, Xi)


def _tuning_key(spec: CompensatorSpec) -> tuple | None:
    """The key of IR-LSSVM's unweighted tuning that ``spec`` shares (:func:`fit`), or None."""
    if spec.kind != "ir_lssvm" or ("gamma" in spec.params and "sigma2" in spec.params):
        return None
    p = spec.params
    kw = {k: p[k] for k in ("gammas", "sigma2s") if k in p}
    return (spec.inputs, repr(sorted(kw.items())), repr(p.get("tune_cv", 10)),
            repr(p.get("tune_scoring", "mse")))


def _fit_group(specs: list[CompensatorSpec], X, y: np.ndarray, random_state: int
               ) -> list[Fitted]:
    """Fit ``specs`` in order sharing one tuning cache (a task of :func:`fit_all`)."""
    tuned: dict = {}
    return [fit(spec, X, y, random_state, tuned) for spec in specs]


def _fit_shared(specs: list[CompensatorSpec], X, y: np.ndarray, random_state: int,
                bar) -> list[Fitted]:
    """:func:`fit_all` on two cores: the specs grouped by the IR-LSSVM tuning they share (each
    other spec alone), the groups shared with one worker process
    (:class:`rlgsim.lab.studies.task_share.TaskShare`). Every fit is the one :func:`fit_all`
    makes in sequence: a group's first fit makes the tuning its later ones reuse, as the
    first spec of that key does there."""
    import dataclasses

    from rlgsim.lab.studies.task_share import TaskShare
    groups: dict[tuple, list[int]] = {}
    for i, spec in enumerate(specs):
        key = _tuning_key(spec)
        groups.setdefault(("one", i) if key is None else ("tuned", key), []).append(i)
    members = list(groups.values())
    out: list[Any] = [None] * len(specs)

    def landed(g: int, fits: list[Fitted]) -> None:
        for i, f in zip(members[g], fits):     # the caller's own spec objects back in place
            out[i] = dataclasses.replace(f, spec=specs[i])
        bar.update(len(fits))
    share = TaskShare(_fit_group, [([specs[i] for i in m], X, y, random_state) for m in members])
    share.results(landed)
    return out


def fit_all(specs, X, y: np.ndarray, random_state: int, *, progress: bool,
            desc: str = "fitting", prepare=None, share: bool = False) -> list[Fitted]:
    """Fit every compensator on the train windows (a progress bar unless ``progress`` is
    false). ``prepare(spec) -> spec`` may change a spec first (e.g. add selected inputs); the
    IR-LSSVM tuning is shared between the specs of one call (see :func:`fit`). ``share``: the
    fits run on this process and one worker process (:func:`_fit_shared`; the same fits,
    in sequence when there is one core, inside a worker, or with a custom compensator, whose
    class a worker may not be able to import)."""
    from tqdm import tqdm
    if share and not any(spec.kind == CUSTOM for spec in specs):
        specs = [prepare(spec) if prepare else spec for spec in specs]
        bar = tqdm(total=len(specs), desc=desc, unit="model", disable=not progress, leave=False)
        try:
            return _fit_shared(specs, X, y, random_state, bar)
        finally:
            bar.close()
    fitted: list[Fitted] = []
    tuned: dict = {}
    bar = tqdm(specs, desc=desc, unit="model", disable=not progress, leave=False)
    for spec in bar:
        bar.set_postfix_str(spec.name[:30])
        fitted.append(fit(prepare(spec) if prepare else spec, X, y, random_state, tuned))
    bar.close()
    return fitted


def predict(f: Fitted, rs: RunSeries) -> np.ndarray:
    """A fitted compensator's prediction ŷ on a run's windows [°/h]: one finite number per
    window. A custom compensator whose ``predict`` raises, exits or returns anything else
    (NaN, infinities, another length, strings, None) is a one-line
    :class:`~rlgsim.ground.errors.UserInputError` naming it and what it returned."""
    X = rs.X.select(f.spec.inputs)
    spec = f.spec
    custom = spec.kind == CUSTOM
    if not custom:
        return np.asarray(f.model.predict(X), dtype=float)
    n = np.asarray(X, dtype=float).shape[0]

    def refuse(what: str) -> UserInputError:
        return spec.ctx.error("estimator",
                              f"compensator {spec.name!r} ({spec.kind}): predict on run "
                              f"{rs.label!r} {what}")
    try:
        raw = f.model.predict(X)
    except SystemExit as exc:
        raise refuse(f"called sys.exit({exc.code!r})") from None
    except Exception as exc:        # noqa: BLE001 - the user's code
        raise refuse(f"raised {type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
                     ) from None
    try:
        if raw is None or np.asarray(raw).dtype.kind not in "biufO":
            raise TypeError
        y = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise refuse(f"returned {_describe(raw)}, not numbers") from None
    if y.ndim == 2 and y.shape[1] == 1:
        y = y[:, 0]                  # a column vector is one value per window too
    if y.shape != (n,):
        raise refuse(f"returned {y.size} values for {n} windows (shape {y.shape}); expected "
                     f"one number per window")
    bad = ~np.isfinite(y)
    if bad.any():
        kind = "NaN" if np.isnan(y[bad]).any() else "infinite values"
        raise refuse(f"returned {kind} for {int(bad.sum())} of {n} windows (first: window "
                     f"{int(np.flatnonzero(bad)[0])})")
    return y


def _describe(value: Any) -> str:
    """A short description of what a predict returned (for messages)."""
    if value is None:
        return "None"
    text = repr(value)
    return f"{type(value).__name__} {text[:60]}{'...' if len(text) > 60 else ''}"
