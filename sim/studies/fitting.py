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

from rlgsim.sim.studies.compensators import CUSTOM, CompensatorSpec, make_estimator
from rlgsim.sim.studies.runs import RunSeries


@dataclass
class Fitted:
    spec: CompensatorSpec
    model: Any
    fit_s: float
    hyper: dict[str, float]


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
            if spec.kind == "ir_lssvm" and not ("gamma" in spec.params and "sigma2" in spec.params):
                from rlgsim.estimators.lssvm_cv import LSSVMRegressorCV
                p = spec.params
                kw = {k: p[k] for k in ("gammas", "sigma2s") if k in p}
                key = (spec.inputs, repr(sorted(kw.items())), repr(p.get("tune_cv", 10)),
                       repr(p.get("tune_scoring", "mse")))
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
    return Fitted(spec, model, time.perf_counter() - t0, hyper)


def fit_all(specs, X, y: np.ndarray, random_state: int, *, progress: bool,
            desc: str = "fitting", prepare=None) -> list[Fitted]:
    """Fit every compensator on the train windows (a progress bar unless ``progress`` is
    false). ``prepare(spec) -> spec`` may change a spec first (e.g. add selected inputs); the
    IR-LSSVM tuning is shared between the specs of one call (see :func:`fit`)."""
    from tqdm import tqdm
    fitted: list[Fitted] = []
    tuned: dict = {}
    bar = tqdm(specs, desc=desc, unit="model", disable=not progress, leave=False)
    for spec in bar:
        bar.set_postfix_str(spec.name[:30])
        fitted.append(fit(prepare(spec) if prepare else spec, X, y, random_state, tuned))
    bar.close()
    return fitted


def predict(f: Fitted, rs: RunSeries) -> np.ndarray:
    """A fitted compensator's prediction ŷ on a run's windows [°/h]."""
    return np.asarray(f.model.predict(rs.X.select(f.spec.inputs)), dtype=float)
