"""The compensator kinds: the one registry of the estimators a study can fit by ``kind`` and of
how each one's fitted model is exported.

A study's ``[[compensator]]`` names a kind (:mod:`rlgsim.lab.studies.compensators` builds the
estimator of :attr:`Kind.estimator` from it); :mod:`rlgsim.estimators.model_export` finds the
kind of a fitted model from its class and reads its closed form by :attr:`Kind.closed_form`:

* ``polynomial`` — a polynomial in the standardised inputs (``intercept_scaled_``,
  ``powers_``, ``coef_scaled_``);
* ``lssvm`` — an LS-SVM's Gaussian kernel expansion (``support_``, ``dual_coef_``,
  ``sigma2``; squared distances expanded as ``‖a‖² − 2a·b + ‖b‖²``, as scikit-learn's
  ``rbf_kernel`` forms them);
* ``rvr`` — a relevance vector machine's expansion (``relevance_vectors_``, ``width_``);
* ``svr`` — a scikit-learn SVR behind a scaler and a target transform (kernel sum accumulated
  term by term, as libsvm predicts);
* ``rbf`` — a radial-basis network (``centers_``, ``weights_``, ``spread``; MATLAB newrb's
  0.5 at ``spread``).

A model that wraps a tuned inner estimator (HHO-RVR, the cross-validated LS-SVMs) exposes it as
``estimator_``; the export reads that one.

To add a kind: its estimator in one new file of ``estimators/`` and one line in :data:`KINDS`
(a new closed form also needs its reader in ``model_export._form_of`` and the C generator).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

__all__ = ["CLOSED_FORMS", "KINDS", "Kind", "estimator_class", "kind_of_class"]

#: The closed forms an exported compensator can take (see the module docstring).
CLOSED_FORMS = ("polynomial", "lssvm", "rvr", "svr", "rbf")


@dataclass(frozen=True)
class Kind:
    """One compensator kind."""

    estimator: str                          # "module.Class" a study fits
    closed_form: str                        # its exported closed form (:data:`CLOSED_FORMS`)
    recipe_keys: tuple[str, ...] = ()       # ``params`` keys the recipe uses itself (tuning)
    also: tuple[str, ...] = ()              # other classes whose fitted models export as it

    @property
    def classes(self) -> tuple[str, ...]:
        """Every estimator class (module.Class) whose fitted model is of this kind."""
        return (self.estimator, *self.also)


_E = "rlgsim.estimators."
#: kind (the study files' ``kind``) → its estimator and export.
KINDS: dict[str, Kind] = {
    "polynomial": Kind(_E + "polynomial.PolynomialRegressor", "polynomial"),
    "stepwise": Kind(_E + "stepwise.StepwiseRegressor", "polynomial"),
    "mlr_bic": Kind(_E + "mlr.MLRBICRegressor", "polynomial"),
    "lssvm": Kind(_E + "lssvm_cv.LSSVMRegressorCV", "lssvm", also=(_E + "lssvm.LSSVMRegressor",)),
    "ir_lssvm": Kind(_E + "robust_lssvm.RobustLSSVMRegressor", "lssvm",
                     recipe_keys=("gammas", "sigma2s", "tune_cv", "tune_scoring")),
    "rvr": Kind(_E + "rvr.RVR", "rvr"),
    "hho_rvr": Kind(_E + "tuned.HHORVR", "rvr"),
    "pso_svr": Kind(_E + "tuned.PSOSVR", "svr"),
    "rbf": Kind(_E + "rbf_network.RBFNetwork", "rbf"),
    "rbf_modified": Kind(_E + "rbf_modified.ModifiedRBFNetwork", "rbf"),
}


def estimator_class(kind: str) -> type:
    """The estimator class of ``kind`` (imported on first use)."""
    module, _, cls = KINDS[kind].estimator.rpartition(".")
    return getattr(importlib.import_module(module), cls)


def kind_of_class(path: str) -> str | None:
    """The kind of a fitted model of class ``path`` ("module.Class"), or None."""
    return next((k for k, spec in KINDS.items() if path in spec.classes), None)
