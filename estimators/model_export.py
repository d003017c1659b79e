"""Fitted compensators to a portable JSON file and back: coefficients, inputs with units,
standardisation, training range, kind and library version.

Every built-in compensator is, once fitted, one of two closed forms in standardised inputs
``z_i = (x_i − center_i) / scale_i``:

* ``"polynomial"`` (least-squares polynomial, stepwise regression, MLR with BIC)::

      y = intercept + Σ_k a_k · Π_i z_i^{p_ki}

  with the estimators' own scaling (:mod:`rlgsim.estimators.term_model`; the raw-unit
  coefficients of the printed equation are ill-conditioned and are not what is evaluated);
* ``"gaussian_kernel"`` (LS-SVM, IR-LSSVM, RVR, HHO-RVR, PSO-SVR, both RBF networks)::

      y = output_offset + output_scale · (intercept + Σ_j a_j · exp(−kernel_factor · ‖z − c_j‖²))

  with the centres ``c_j`` in standardised coordinates: LS-SVM ``kernel_factor = 1/(2σ²)``
  (paper 001 eq. 11), RVR ``1/width²`` (no standardisation: ``center = 0``, ``scale = 1``),
  RBF networks ``ln 2/spread²``, PSO-SVR scikit-learn's ``gamma`` with the target
  standardisation of its ``TransformedTargetRegressor`` as ``output_offset``/``output_scale``.

:func:`export_compensator` reads the fitted attributes of a model and returns an
:class:`ExportedCompensator`: a predict-only scikit-learn regressor holding that closed form.
Its ``predict`` follows the operations of the source estimator (same scaling, same
``design_matrix``; squared distances formed as ``‖a‖² − 2a·b + ‖b‖²`` by scikit-learn's
``rbf_kernel`` for LS-SVM and IR-LSSVM, from exact differences for the others), so every
kind predicts bit-identically except PSO-SVR (libsvm sums its kernel terms one after the other,
as done here, but with the C library's ``exp``, not numpy's: agreement to ~1e-13 of the
predictions' scale). It warns (:class:`OutOfTrainingRangeWarning`) when an input lies outside the range it
was trained on: the hold-out runs showed learnt laws 2.4 times worse off the training range.
:meth:`ExportedCompensator.to_json` / :func:`load_json` write and read the file; a damaged file
gives one :class:`~rlgsim.ground.errors.UserInputError` line naming the file and the key.
:mod:`rlgsim.estimators.c_codegen` turns the same object into C.

Why not pickle/joblib or ONNX: a pickle is neither readable nor portable to the gyro's
microprocessor and breaks across library versions; skl2onnx converts scikit-learn classes, not
these estimators, and an ONNX runtime is not what a microprocessor runs. The format here is
small enough to read and to re-implement in any language.

Why this file is long: the JSON format is written and read here (:func:`export_compensator`,
:class:`ExportedCompensator`, :func:`load_json` with its one-line check of every key), so that
the writer and the reader cannot drift apart; the C code is generated in
:mod:`rlgsim.estimators.c_codegen`.
"""

from __future__ import annotations

import json
import math
import pathlib
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy.spatial.distance import cdist
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.metrics.pairwise import rbf_kernel
from sklearn.utils.validation import check_array, check_is_fitted

from rlgsim.ground.atomic import atomic_file
from rlgsim.estimators.columns import Columns
from rlgsim.estimators.compensator_kinds import KINDS as COMPENSATOR_KINDS
from rlgsim.estimators.terms import (design_matrix, format_equation, raw_coefficients,
                                     term_label, term_pretty)
from rlgsim.ground.errors import UserInputError

__all__ = ["FORMAT", "FORMAT_VERSION", "KINDS", "ExportedCompensator",
           "OutOfTrainingRangeWarning", "export_compensator", "load_json"]

FORMAT = "rlgsim-compensator"
FORMAT_VERSION = 1
FORMS = ("polynomial", "gaussian_kernel")
#: Kinds whose estimator forms squared distances as ``‖a‖² − 2a·b + ‖b‖²`` (scikit-learn's
#: ``rbf_kernel``); the others use exact differences (``cdist``), as the C code does.
EXPANDED_DISTANCE_KINDS = tuple(k for k, s in COMPENSATOR_KINDS.items() if s.closed_form == "lssvm")
#: Kinds whose kernel sum is accumulated term by term in centre order (libsvm's predict).
SEQUENTIAL_SUM_KINDS = tuple(k for k, s in COMPENSATOR_KINDS.items() if s.closed_form == "svr")
#: Rows per block when kernel values are formed (memory: rows x centres doubles).
CHUNK_ROWS = 4096

#: Estimator class (module.qualname) -> compensator kind (the study files' ``kind``), from the
#: one registry :data:`rlgsim.estimators.compensator_kinds.KINDS`.
KINDS: dict[str, str] = {cls: kind for kind, spec in COMPENSATOR_KINDS.items()
                         for cls in spec.classes}


class OutOfTrainingRangeWarning(UserWarning):
    """An exported compensator was asked to predict outside the input range it was trained on."""


def _library_version() -> str:
    from rlgsim import __version__
    return __version__


def _class_path(model: Any) -> str:
    cls = type(model)
    return f"{cls.__module__}.{cls.__qualname__}"


def _floats(values: Any) -> list:
    """Nested lists of Python floats (JSON writes them with ``repr``: exact round trip)."""
    return np.asarray(values, dtype=np.float64).tolist()


def _json_params(model: Any) -> dict:
    """The estimator's constructor parameters that JSON can hold (for the record only)."""
    out = {}
    for key, value in model.get_params(deep=False).items():
        if isinstance(value, (np.integer, np.floating)):
            value = value.item()
        if value is None or isinstance(value, (bool, int, str)) or (
                isinstance(value, float) and math.isfinite(value)):
            out[key] = value
        elif isinstance(value, (tuple, list)) and all(
                isinstance(v, (bool, int, str)) or (isinstance(v, float) and math.isfinite(v))
                for v in value):
            out[key] = list(value)
    return out


# ------------------------------------------------------------------------------ from a model
def _form_of(model: Any, kind: str) -> tuple[np.ndarray, np.ndarray, dict, Any]:
    """``(center, scale, model-table, svr)`` of a fitted model of ``kind`` (see module doc);
    ``svr`` is the fitted scikit-learn SVR of a PSO-SVR (for the C generator), else None."""
    form = COMPENSATOR_KINDS[kind].closed_form if kind in COMPENSATOR_KINDS else None
    if form == "polynomial":
        check_is_fitted(model, "coef_scaled_")
        table = {"form": "polynomial", "intercept": float(model.intercept_scaled_),
                 "powers": [list(p) for p in model.powers_],
                 "coefficients": _floats(model.coef_scaled_)}
        return model.center_, model.scale_, table, None
    if form == "lssvm":
        inner = model.estimator_ if hasattr(model, "estimator_") else model
        check_is_fitted(inner, "dual_coef_")
        return inner.x_mean_, inner.x_scale_, _kernel_table(        # paper 001 eq. 11
            inner.support_, inner.dual_coef_, inner.intercept_,
            1.0 / (2.0 * float(inner.sigma2))), None
    if form == "rvr":
        inner = model.estimator_ if hasattr(model, "estimator_") else model
        check_is_fitted(inner, "dual_coef_")
        width = float(inner.width_)
        n = inner.relevance_vectors_.shape[1]
        b = float(inner.intercept_) if inner.fit_intercept else 0.0
        return np.zeros(n), np.ones(n), _kernel_table(
            inner.relevance_vectors_, inner.dual_coef_, b, 1.0 / (width * width)), None
    if form == "svr":
        check_is_fitted(model, "estimator_")
        ttr = model.estimator_
        scaler, svr = ttr.regressor_[0], ttr.regressor_[-1]
        target = ttr.transformer_
        table = _kernel_table(svr.support_vectors_, svr.dual_coef_[0], svr.intercept_[0],
                              float(svr._gamma))
        table["output_offset"] = float(target.mean_[0])
        table["output_scale"] = float(target.scale_[0])
        return scaler.mean_, scaler.scale_, table, svr
    if form == "rbf":
        check_is_fitted(model, "weights_")
        spread = float(model.spread)
        centres = (model.centers_ - model.x_mean_) / model.x_scale_
        return model.x_mean_, model.x_scale_, _kernel_table(        # newrb: 0.5 at ``spread``
            centres, model.weights_, model.intercept_, math.log(2.0) / spread**2), None
    raise ValueError(f"no export for compensator kind {kind!r}")


def _kernel_table(centres, coef, intercept, factor: float) -> dict:
    centres = np.asarray(centres, dtype=np.float64)
    return {"form": "gaussian_kernel", "kernel_factor": float(factor),
            "intercept": float(intercept), "output_offset": 0.0, "output_scale": 1.0,
            "coefficients": _floats(np.ravel(coef)), "centres": _floats(centres)}


def _is_frame(X: Any) -> bool:
    """A pandas-like table: named columns selectable with ``X[list_of_names]``."""
    return hasattr(X, "columns") and hasattr(X, "iloc")


def _select(X: Any, names: Sequence[str]) -> Any:
    """The named inputs of a Columns or DataFrame (``ValueError`` naming missing ones), in
    order; any other ``X`` unchanged."""
    if isinstance(X, Columns) or _is_frame(X):
        have = X.names if isinstance(X, Columns) else [str(c) for c in X.columns]
        missing = [n for n in names if n not in have]
        if missing:
            raise ValueError(f"X lacks the input(s) {', '.join(missing)}; X has "
                             f"{', '.join(have)}")
        return X.select(names) if isinstance(X, Columns) else X[list(names)]
    return X


def _input_names(model: Any, X_train: Any, input_names: Sequence[str] | None,
                 n: int) -> tuple[str, ...]:
    if input_names is not None:
        names = tuple(str(v) for v in input_names)
    elif hasattr(model, "input_names_"):
        names = tuple(model.input_names_)
    elif hasattr(model, "feature_names_in_"):                 # fitted on a DataFrame
        names = tuple(str(c) for c in model.feature_names_in_)
    elif isinstance(X_train, Columns):
        names = X_train.names
    elif _is_frame(X_train):
        names = tuple(str(c) for c in X_train.columns)
    else:
        names = tuple(f"x{i}" for i in range(n))
    if len(names) != n or len(set(names)) != n:
        raise ValueError(f"need {n} distinct input names for this model, got {list(names)}")
    return names


def export_compensator(model: Any, X_train: Any, *, name: str = "",
                       input_names: Sequence[str] | None = None,
                       input_units: Mapping[str, str] | Sequence[str] | None = None,
                       target: str = "y", target_unit: str = "") -> ExportedCompensator:
    """The closed form of a fitted compensator, ready for JSON and C.

    Parameters
    ----------
    model
        A fitted built-in compensator (:data:`KINDS`); others raise ``ValueError``.
    X_train
        The inputs it was fitted on (array or :class:`~rlgsim.estimators.columns.Columns`; a
        table may hold extra columns): their per-input minimum and maximum are the training
        range. The estimators themselves do not keep it.
    name
        A label for the compensator (e.g. the study's compensator name).
    input_names
        Names of the inputs in model order (default: the model's ``input_names_``, else the
        table's names, else ``x0, x1, ...``).
    input_units
        Unit of each input: a ``{name: unit}`` mapping or a sequence in input order ("°C",
        "K/s", "V"); missing ones are "".
    target, target_unit
        Name and unit of the predicted quantity (e.g. "B", "°/h").
    """
    kind = KINDS.get(_class_path(model))
    if kind is None:
        raise ValueError(f"cannot export a {type(model).__name__}: only the built-in "
                         f"compensators ({', '.join(sorted(set(KINDS.values())))}) have an "
                         "export")
    center, scale, table, svr = _form_of(model, kind)
    n = len(center)
    names = _input_names(model, X_train, input_names, n)
    X = check_array(_select(X_train, names), dtype=np.float64)
    if X.shape[1] != n:
        raise ValueError(f"X_train has {X.shape[1]} columns, the model {n} inputs")
    if isinstance(input_units, Mapping):
        units = [str(input_units.get(nm, "")) for nm in names]
    elif input_units is None:
        units = [""] * n
    else:
        units = [str(u) for u in input_units]
        if len(units) != n:
            raise ValueError(f"input_units has {len(units)} units for {n} inputs")
    lo, hi = X.min(axis=0), X.max(axis=0)
    doc = {
        "format": FORMAT, "format_version": FORMAT_VERSION,
        "library_version": _library_version(),
        "name": name or kind, "kind": kind, "estimator": _class_path(model),
        "params": _json_params(model),
        "target": {"name": target, "unit": target_unit},
        "inputs": [{"name": nm, "unit": u, "train_min": float(a), "train_max": float(b)}
                   for nm, u, a, b in zip(names, units, lo, hi)],
        "standardisation": {"center": _floats(center), "scale": _floats(scale)},
        "model": table,
    }
    out = ExportedCompensator.from_dict(doc)
    out._svr = svr
    return out


# ------------------------------------------------------------------------------ the estimator
class ExportedCompensator(RegressorMixin, BaseEstimator):
    """A compensator read back from its export: predicts, warns off the training range, writes
    JSON (:meth:`to_json`; C: :func:`rlgsim.estimators.c_codegen.generate_c`). It cannot be
    re-fitted (``fit`` raises).

    Build it with :func:`export_compensator` or :func:`load_json`. Attributes: ``name_``,
    ``kind_``, ``input_names_``, ``input_units_``, ``train_min_``, ``train_max_``,
    ``center_``, ``scale_``, ``target_``, ``target_unit_``, ``form_`` and the arrays of the
    form (module docstring): ``powers_``, ``coef_``, ``intercept_`` (polynomial) or
    ``centres_``, ``coef_``, ``intercept_``, ``kernel_factor_``, ``output_offset_``,
    ``output_scale_`` (gaussian_kernel); ``document_`` the JSON document.
    """

    _svr = None          # the fitted scikit-learn SVR of a PSO-SVR export (C via m2cgen)

    def fit(self, X, y=None):
        raise TypeError("an exported compensator is frozen: fit the original estimator and "
                        "export it again")

    @classmethod
    def from_dict(cls, doc: Mapping, source: str = "") -> ExportedCompensator:
        """Validate a JSON document (:func:`load_json`'s errors) and build the estimator."""
        return _parse(doc, source or "<document>")

    # -- prediction ------------------------------------------------------------------------
    def _check_range(self, X: np.ndarray) -> None:
        below = X < self.train_min_
        above = X > self.train_max_
        out = below | above
        if not out.any():
            return
        parts = []
        for i in np.flatnonzero(out.any(axis=0)):
            unit = f" {self.input_units_[i]}" if self.input_units_[i] else ""
            col = X[out[:, i], i]
            parts.append(f"{self.input_names_[i]} {col.min():.6g}…{col.max():.6g}{unit} in "
                         f"{int(out[:, i].sum())} of {X.shape[0]} rows, trained on "
                         f"{self.train_min_[i]:.6g}…{self.train_max_[i]:.6g}{unit}")
        warnings.warn(f"compensator {self.name_!r} extrapolates outside its training range: "
                      + "; ".join(parts), OutOfTrainingRangeWarning, stacklevel=3)

    def predict(self, X) -> np.ndarray:
        """Predicted target (``target_unit_``) for inputs ``X``: an array in input order, or a
        :class:`~rlgsim.estimators.columns.Columns` or DataFrame holding the inputs by name.
        Warns with :class:`OutOfTrainingRangeWarning` when an input is outside its training
        range."""
        check_is_fitted(self, "form_")
        X = check_array(_select(X, self.input_names_), dtype=np.float64)
        if X.shape[1] != len(self.input_names_):
            raise ValueError(f"X has {X.shape[1]} columns, the compensator "
                             f"{len(self.input_names_)} inputs ({', '.join(self.input_names_)})")
        self._check_range(X)
        Z = (X - self.center_) / self.scale_
        if self.form_ == "polynomial":
            return self.intercept_ + design_matrix(Z, self.powers_) @ self.coef_
        out = np.zeros(Z.shape[0])
        n_rows = Z.shape[0] if self.coef_.size else 0     # no centre: the constant model
        for start in range(0, n_rows, CHUNK_ROWS):
            block = Z[start:start + CHUNK_ROWS]
            if self.kind_ in EXPANDED_DISTANCE_KINDS:       # as the LS-SVM estimators do
                K = rbf_kernel(block, self.centres_, gamma=self.kernel_factor_)
            else:
                K = np.exp(cdist(block, self.centres_, "sqeuclidean") * (-self.kernel_factor_))
            if self.kind_ in SEQUENTIAL_SUM_KINDS:          # libsvm: one term after the other
                out[start:start + CHUNK_ROWS] = np.cumsum(K * self.coef_, axis=1)[:, -1]
            else:
                out[start:start + CHUNK_ROWS] = K @ self.coef_
        out += self.intercept_
        if self.output_scale_ != 1.0 or self.output_offset_ != 0.0:
            out = out * self.output_scale_ + self.output_offset_
        return out

    def raw_equation(self, precision: int = 6, ascii: bool = False) -> str:
        """The polynomial in the inputs' own units, as the estimators print it
        (``B = 1.427×10⁻³ + 4.906×10⁻⁴·T − ...``; polynomial form only). For reading: its
        raw-unit coefficients can be large and cancelling, prediction uses the scaled form."""
        if self.form_ != "polynomial":
            raise ValueError(f"a {self.form_} model has no polynomial equation")
        raw = raw_coefficients(self.powers_, self.coef_, self.intercept_, self.center_,
                               self.scale_)
        zero = (0,) * len(self.input_names_)
        powers = [p for p in raw if p != zero]
        powers.sort(key=lambda p: (sum(p), [-e for e in p]))
        names = self.input_names_
        labels = [term_label(p, names) if ascii else term_pretty(p, names) for p in powers]
        return format_equation(self.target_, raw[zero], [raw[p] for p in powers], labels,
                               precision, ascii)

    # -- files -----------------------------------------------------------------------------
    def to_json(self, path: str | pathlib.Path) -> pathlib.Path:
        """Write the JSON document (UTF-8, floats exact); returns the path."""
        path = pathlib.Path(path)
        text = json.dumps(self.document_, indent=1, ensure_ascii=False, allow_nan=False) + "\n"
        with atomic_file(path) as tmp:                  # whole or not at all
            tmp.write_text(text, encoding="utf-8")
        return path


# ------------------------------------------------------------------------------ reading
class _Doc:
    """Typed look-ups in a JSON document; every error names the file and the dotted key."""

    def __init__(self, source: str):
        self.source = source

    def error(self, key: str, problem: str) -> UserInputError:
        return UserInputError(f"{self.source}: {key}: {problem}")

    def get(self, table: Any, key: str, path: str, kind: type | tuple, what: str):
        full = f"{path}.{key}" if path else key
        if not isinstance(table, Mapping):
            raise self.error(path or "(top level)", "must be a JSON object")
        if key not in table:
            raise self.error(full, f"missing (expected {what})")
        value = table[key]
        if kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value):
                raise self.error(full, f"must be a finite number, got {value!r}")
            return float(value)
        if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
            raise self.error(full, f"must be {what}, got {value!r}"[:200])
        return value

    def array(self, table: Any, key: str, path: str, shape: tuple, what: str) -> np.ndarray:
        full = f"{path}.{key}" if path else key
        value = self.get(table, key, path, list, what)
        try:
            arr = np.array(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise self.error(full, f"must be {what} (numbers only)") from None
        if arr.ndim != len(shape) or any(s is not None and a != s
                                         for a, s in zip(arr.shape, shape)):
            want = " x ".join("n" if s is None else str(s) for s in shape)
            raise self.error(full, f"must be {what} of shape {want}, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise self.error(full, "must hold finite numbers only")
        return arr


def _parse(doc: Any, source: str) -> ExportedCompensator:
    d = _Doc(source)
    fmt = d.get(doc, "format", "", str, f'"{FORMAT}"')
    if fmt != FORMAT:
        raise d.error("format", f'must be "{FORMAT}", got {fmt!r}')
    version = d.get(doc, "format_version", "", int, "an integer")
    if version != FORMAT_VERSION:
        raise d.error("format_version", f"{version} is not readable by this rlgsim (reads "
                                        f"version {FORMAT_VERSION}; update rlgsim)")
    est = ExportedCompensator()
    est.name_ = d.get(doc, "name", "", str, "a string")
    est.kind_ = d.get(doc, "kind", "", str, "a string")
    d.get(doc, "library_version", "", str, "a string")
    tgt = d.get(doc, "target", "", dict, "an object")
    est.target_ = d.get(tgt, "name", "target", str, "a string")
    est.target_unit_ = d.get(tgt, "unit", "target", str, "a string")
    inputs = d.get(doc, "inputs", "", list, "a non-empty list of input objects")
    if not inputs:
        raise d.error("inputs", "must list at least one input")
    names, units, lo, hi = [], [], [], []
    for i, item in enumerate(inputs):
        p = f"inputs[{i}]"
        names.append(d.get(item, "name", p, str, "a string"))
        units.append(d.get(item, "unit", p, str, "a string"))
        lo.append(d.get(item, "train_min", p, float, "a number"))
        hi.append(d.get(item, "train_max", p, float, "a number"))
        if lo[-1] > hi[-1]:
            raise d.error(f"{p}.train_max", f"{hi[-1]!r} is below train_min {lo[-1]!r}")
    if len(set(names)) != len(names):
        raise d.error("inputs", f"repeats an input name: {names}")
    n = len(names)
    est.input_names_, est.input_units_ = tuple(names), tuple(units)
    est.train_min_, est.train_max_ = np.array(lo), np.array(hi)
    est.n_features_in_ = n
    std = d.get(doc, "standardisation", "", dict, "an object")
    est.center_ = d.array(std, "center", "standardisation", (n,), f"a list of {n} numbers")
    est.scale_ = d.array(std, "scale", "standardisation", (n,), f"a list of {n} numbers")
    if np.any(est.scale_ == 0):
        raise d.error("standardisation.scale", "must not hold 0")
    m = d.get(doc, "model", "", dict, "an object")
    form = d.get(m, "form", "model", str, f"one of {', '.join(FORMS)}")
    if form not in FORMS:
        raise d.error("model.form", f"must be one of {', '.join(FORMS)}, got {form!r}")
    est.form_ = form
    est.intercept_ = d.get(m, "intercept", "model", float, "a number")
    if form == "polynomial":
        powers = d.get(m, "powers", "model", list, "a list of exponent lists")
        parsed = []
        for k, p in enumerate(powers):
            if not (isinstance(p, list) and len(p) == n and all(
                    isinstance(e, int) and not isinstance(e, bool) and e >= 0 for e in p)
                    and sum(p) > 0):
                raise d.error(f"model.powers[{k}]", f"must be {n} non-negative integer "
                                                    f"exponents, not all 0, got {p!r}")
            parsed.append(tuple(p))
        est.powers_ = tuple(parsed)
        est.coef_ = d.array(m, "coefficients", "model", (len(parsed),),
                            f"a list of {len(parsed)} numbers (one per term)")
    else:
        est.coef_ = d.array(m, "coefficients", "model", (None,), "a list of numbers")
        if est.coef_.size == 0 and isinstance(m, Mapping) and m.get("centres") == []:
            est.centres_ = np.empty((0, n))             # no centre kept: the constant model
        else:
            est.centres_ = d.array(m, "centres", "model", (est.coef_.size, n),
                                   f"a list of {est.coef_.size} centres of {n} numbers")
        est.kernel_factor_ = d.get(m, "kernel_factor", "model", float, "a number")
        if est.kernel_factor_ <= 0:
            raise d.error("model.kernel_factor", f"must be > 0, got {est.kernel_factor_!r}")
        est.output_offset_ = d.get(m, "output_offset", "model", float, "a number")
        est.output_scale_ = d.get(m, "output_scale", "model", float, "a number")
    est.document_ = json.loads(json.dumps(doc))        # an independent, plain copy
    return est


def load_json(path: str | pathlib.Path) -> ExportedCompensator:
    """Read a compensator written by :meth:`ExportedCompensator.to_json`.

    A missing, unreadable or damaged file raises :class:`~rlgsim.ground.errors.UserInputError`
    with one line naming the file and the key (``model.coefficients``, ``inputs[1].unit`` ...).
    """
    path = pathlib.Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UserInputError(f"{path}: cannot read the compensator file "
                             f"({getattr(exc, 'strerror', None) or exc})") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserInputError(f"{path}: line {exc.lineno}, column {exc.colno}: not valid JSON "
                             f"({exc.msg})") from None
    return _parse(doc, str(path))
