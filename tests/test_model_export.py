"""Fitted-compensator export: JSON round trip, C code compiled with the system compiler, the
out-of-training-range warning and flag, and one-line errors for damaged files."""

from __future__ import annotations

import ctypes
import json
import shutil
import subprocess
import warnings

import numpy as np
import pytest

from rlgsim.estimators.c_codegen import c_identifier, generate_c, write_c
from rlgsim.estimators.columns import Columns
from rlgsim.estimators.model_export import (ExportedCompensator, OutOfTrainingRangeWarning,
                                            export_compensator, load_json)
from rlgsim.ground.errors import UserInputError

NAMES = ("T", "dT/dt", "U")
UNITS = {"T": "°C", "dT/dt": "K/s", "U": "V"}


def _data(n: int = 240, seed: int = 0):
    """Paper-001-like windows: T over −40…70 °C, dT/dt in K/s, U_HFO in V; bias in °/h."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)
    T = 15.0 + 55.0 * np.sin(2 * np.pi * t) + rng.normal(0, 0.5, n)
    dT = 55.0 * 2 * np.pi * np.cos(2 * np.pi * t) / 28_800.0 + rng.normal(0, 2e-4, n)
    U = 2.0 + 0.01 * T + rng.normal(0, 0.02, n)
    y = 0.004 + 3e-4 * T - 2e-6 * T**2 + 0.8 * dT + 0.002 * (U - 2.0) \
        + rng.normal(0, 2e-4, n)
    return Columns({"T": T, "dT/dt": dT, "U": U}), y


def _models():
    from rlgsim.estimators.lssvm import LSSVMRegressor
    from rlgsim.estimators.lssvm_cv import LSSVMRegressorCV
    from rlgsim.estimators.mlr import MLRBICRegressor
    from rlgsim.estimators.polynomial import PolynomialRegressor
    from rlgsim.estimators.rbf_modified import ModifiedRBFNetwork
    from rlgsim.estimators.rbf_network import RBFNetwork
    from rlgsim.estimators.robust_lssvm import RobustLSSVMRegressor
    from rlgsim.estimators.rvr import RVR
    from rlgsim.estimators.stepwise import StepwiseRegressor
    from rlgsim.estimators.tuned import HHORVR, PSOSVR
    return {
        "polynomial": PolynomialRegressor(degree=3),
        "stepwise": StepwiseRegressor(degree=2),
        "mlr_bic": MLRBICRegressor(degree=2),
        "lssvm": LSSVMRegressorCV(gammas=(10.0, 1e3), sigma2s=(0.3, 3.0)),
        "lssvm_nystroem": LSSVMRegressor(gamma=100.0, sigma2=1.0, solver="nystroem",
                                         n_landmarks=50, random_state=0),
        "ir_lssvm": RobustLSSVMRegressor(gamma=100.0, sigma2=1.0),
        "rvr": RVR(width=20.0),
        "hho_rvr": HHORVR(n_agents=4, max_iter=3, random_state=0),
        "pso_svr": PSOSVR(n_agents=4, max_iter=3, random_state=0),
        "rbf": RBFNetwork(spread=1.0, max_centers=25),
        "rbf_modified": ModifiedRBFNetwork(spread=1.0, rho=0.05, random_state=0),
    }


KINDS = list(_models())


@pytest.fixture(scope="module")
def fitted():
    X, y = _data()
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")           # convergence notes of the small fits
        for key, model in _models().items():
            out[key] = model.fit(X, y)
    return X, y, out


def _inside(X: Columns, n: int = 1000, seed: int = 1) -> np.ndarray:
    """``n`` inputs drawn uniformly inside the training box."""
    lo, hi = np.min(X.values, axis=0), np.max(X.values, axis=0)
    return np.random.default_rng(seed).uniform(lo, hi, size=(n, lo.size))


def _export(model, X, name="test model"):
    return export_compensator(model, X, name=name, input_units=UNITS, target="B",
                              target_unit="°/h")


# ------------------------------------------------------------------------------ JSON
@pytest.mark.parametrize("kind", KINDS)
def test_json_round_trip_predicts_like_the_fitted_model(fitted, kind, tmp_path):
    X, _, models = fitted
    model = models[kind]
    Xq = _inside(X)
    ref = model.predict(Xq)
    exported = _export(model, X)
    path = exported.to_json(tmp_path / "model.json")
    loaded = load_json(path)
    assert loaded.kind_ == ("lssvm" if kind == "lssvm_nystroem" else kind)
    assert loaded.input_names_ == NAMES
    assert loaded.input_units_ == ("°C", "K/s", "V")
    np.testing.assert_array_equal(loaded.train_min_, np.min(X.values, axis=0))
    np.testing.assert_array_equal(loaded.train_max_, np.max(X.values, axis=0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", OutOfTrainingRangeWarning)   # inside: no warning
        got = loaded.predict(Xq)
        by_name = loaded.predict(Columns.from_array(Xq, NAMES))
    np.testing.assert_array_equal(got, exported.predict(Xq))
    np.testing.assert_array_equal(by_name, got)
    if kind != "pso_svr":
        np.testing.assert_array_equal(got, ref)           # same operations: bit-identical
    else:       # libsvm's exp is the C library's, numpy's its own: 1 ulp here and there
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * np.max(np.abs(ref)))
    # the file holds what the issue asks for
    doc = json.loads(path.read_text(encoding="utf-8"))
    assert doc["library_version"] and doc["kind"] == loaded.kind_
    assert doc["target"] == {"name": "B", "unit": "°/h"}
    assert set(doc["standardisation"]) == {"center", "scale"}


def test_json_polynomial_terms_and_equation(fitted, tmp_path):
    X, _, models = fitted
    loaded = load_json(_export(models["polynomial"], X).to_json(tmp_path / "p.json"))
    assert len(loaded.powers_) == 19                      # every monomial of degree 1..3 in 3
    for kind in ("polynomial", "stepwise"):               # the estimator's own equation
        model = models[kind]
        loaded = _export(model, X)
        assert loaded.raw_equation(precision=4) == model.equation("B", precision=4)


def test_out_of_range_warns_and_names_the_input(fitted, tmp_path):
    X, _, models = fitted
    loaded = load_json(_export(models["polynomial"], X, "LS cubic").to_json(tmp_path / "m.json"))
    Xq = _inside(X, 10)
    Xq[3, 0] = loaded.train_max_[0] + 5.0
    with pytest.warns(OutOfTrainingRangeWarning, match=r"'LS cubic'.*T 7.*°C in 1 of 10 rows"):
        loaded.predict(Xq)


def test_dataframe_inputs_by_name(fitted, tmp_path):
    pd = pytest.importorskip("pandas")
    X, _, models = fitted
    loaded = load_json(_export(models["rbf"], X).to_json(tmp_path / "m.json"))
    Xq = _inside(X, 20)
    frame = pd.DataFrame({"U": Xq[:, 2], "extra": 0.0, "T": Xq[:, 0], "dT/dt": Xq[:, 1]})
    np.testing.assert_array_equal(loaded.predict(frame), loaded.predict(Xq))
    with pytest.raises(ValueError, match="lacks the input.*dT/dt"):
        loaded.predict(frame.drop(columns="dT/dt"))
    # a model fitted on a DataFrame: names from feature_names_in_, range from the frame
    from rlgsim.estimators.rvr import RVR
    train = pd.DataFrame(X.values, columns=list(NAMES))
    rvr = RVR(width=20.0).fit(train, _data()[1])
    exported = export_compensator(rvr, train.assign(extra=1.0))
    assert exported.input_names_ == NAMES


def test_export_rejects_models_without_export():
    from sklearn.linear_model import LinearRegression
    X, y = _data(30)
    with pytest.raises(ValueError, match="only the built-in compensators"):
        export_compensator(LinearRegression().fit(X.values, y), X)


def test_exported_model_cannot_be_refitted(fitted):
    X, y, models = fitted
    with pytest.raises(TypeError, match="frozen"):
        _export(models["rvr"], X).fit(X.values, y)


def _damaged(tmp_path, fitted, change):
    X, _, models = fitted
    path = _export(models["rbf"], X).to_json(tmp_path / "model.json")
    doc = json.loads(path.read_text(encoding="utf-8"))
    change(doc)
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


@pytest.mark.parametrize("change, key", [
    (lambda d: d["model"].pop("coefficients"), "model.coefficients: missing"),
    (lambda d: d["model"].update(kernel_factor="wide"), "model.kernel_factor: must be a finite"),
    (lambda d: d["inputs"][1].pop("unit"), r"inputs\[1\]\.unit: missing"),
    (lambda d: d["model"]["centres"][0].pop(), "model.centres: must be"),
    (lambda d: d["standardisation"].update(scale=[1.0]), "standardisation.scale: must be"),
    (lambda d: d.update(format_version=99), "format_version: 99 is not readable"),
    (lambda d: d.update(format="other"), "format: must be"),
    (lambda d: d["model"].update(form="spline"), "model.form: must be one of"),
])
def test_damaged_json_gives_one_line_naming_file_and_key(tmp_path, fitted, change, key):
    path = _damaged(tmp_path, fitted, change)
    with pytest.raises(UserInputError) as err:
        load_json(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"{path}: ")
    assert __import__("re").search(key, msg), msg


def test_not_json_and_missing_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "rlgsim-compensator",\n  "kind": }', encoding="utf-8")
    with pytest.raises(UserInputError, match=r"bad\.json: line 2, column 11: not valid JSON"):
        load_json(bad)
    with pytest.raises(UserInputError, match=r"nope\.json: cannot read"):
        load_json(tmp_path / "nope.json")


# ------------------------------------------------------------------------------ C
CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc) on this machine")


def _compile(exported: ExportedCompensator, tmp_path, fn: str = "comp"):
    c_path, h_path = write_c(exported, tmp_path, fn)
    assert h_path.exists()
    lib = tmp_path / f"lib{fn}.so"
    res = subprocess.run([CC, "-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-O2",
                          "-shared", "-fPIC", "-o", str(lib), str(c_path), "-lm"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    so = ctypes.CDLL(str(lib))
    func = getattr(so, fn)
    func.restype = ctypes.c_double
    func.argtypes = [ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_ulonglong)]

    def call(Xq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        out, flags = np.empty(len(Xq)), np.empty(len(Xq), dtype=np.uint64)
        f = ctypes.c_ulonglong()
        for k, row in enumerate(np.ascontiguousarray(Xq, dtype=np.float64)):
            out[k] = func(row.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), ctypes.byref(f))
            flags[k] = f.value
        return out, flags

    return call


MAX_REL: dict[str, float] = {}


@needs_cc
@pytest.mark.parametrize("via_json", [False, True], ids=["fitted", "from_json"])
@pytest.mark.parametrize("kind", KINDS)
def test_c_matches_python_on_1000_inputs(fitted, kind, via_json, tmp_path):
    X, _, models = fitted
    exported = _export(models[kind], X)
    if via_json:
        exported = load_json(exported.to_json(tmp_path / "m.json"))
    call = _compile(exported, tmp_path)
    Xq = _inside(X)
    py = models[kind].predict(Xq)
    c, flags = call(Xq)
    assert not flags.any()
    # relative to each prediction, floored at 1e-6 of the largest (a value crossing zero)
    rel = np.max(np.abs(c - py) / np.maximum(np.abs(py), 1e-6 * np.max(np.abs(py))))
    MAX_REL[f"{kind}/{'json' if via_json else 'fitted'}"] = float(rel)
    assert rel <= 1e-9, f"{kind}: C differs from Python by {rel:.2e} relative"


@needs_cc
def test_c_range_flags(fitted, tmp_path):
    X, _, models = fitted
    exported = _export(models["lssvm"], X)
    call = _compile(exported, tmp_path)
    Xq = _inside(X, 4)
    Xq[1, 0] = exported.train_min_[0] - 1.0            # T below: bit 0
    Xq[2, 2] = exported.train_max_[2] + 0.1            # U above: bit 2
    Xq[3, 1] = np.nan                                  # NaN counts as outside: bit 1
    _, flags = call(Xq)
    assert flags.tolist() == [0, 1, 4, 2]


def test_pso_svr_c_uses_m2cgen_only_when_the_fitted_svr_is_at_hand(fitted, tmp_path):
    X, _, models = fitted
    exported = _export(models["pso_svr"], X)
    assert "generated by m2cgen" in generate_c(exported, "svr").c
    loaded = load_json(exported.to_json(tmp_path / "m.json"))
    assert "m2cgen" not in generate_c(loaded, "svr").c


def test_c_header_lists_inputs_units_and_ranges(fitted):
    X, _, models = fitted
    src = generate_c(_export(models["stepwise"], X, "Stepwise (T, dT/dt, U)"))
    assert src.function_name == "stepwise_t_dt_dt_u"
    assert '"T", "dT/dt", "U"' in src.c and '"degC", "K/s", "V"' in src.c
    assert "STEPWISE_T_DT_DT_U_N_INPUTS 3" in src.h
    assert "range_flags" in src.h and src.c.isascii() and src.h.isascii()


def test_c_identifier():
    assert c_identifier("IR-LSSVM (Huber) T, U") == "ir_lssvm_huber_t_u"
    assert c_identifier("3-point PSO-SVM") == "c_3_point_pso_svm"
    assert c_identifier("---") == "compensator"


@needs_cc
@pytest.mark.parametrize("kind", ["stepwise", "rvr"])
def test_models_that_kept_no_term_export_as_constants(kind, tmp_path):
    """Stepwise with nothing significant, RVR with no relevance vector: a constant model."""
    from rlgsim.estimators.rvr import RVR
    from rlgsim.estimators.stepwise import StepwiseRegressor
    X, _ = _data(60)
    y = np.full(60, 0.25) if kind == "rvr" else \
        np.random.default_rng(3).normal(0.25, 1e-3, 60)
    model = (RVR(width=20.0) if kind == "rvr" else StepwiseRegressor(degree=1, p_enter=1e-9))
    model.fit(X, y)
    exported = _export(model, X)
    assert exported.coef_.size == 0
    loaded = load_json(exported.to_json(tmp_path / "m.json"))
    Xq = _inside(X, 50)
    np.testing.assert_array_equal(loaded.predict(Xq), model.predict(Xq))
    c, _ = _compile(loaded, tmp_path)(Xq)
    np.testing.assert_allclose(c, model.predict(Xq), rtol=1e-12)


def test_save_compensator_writes_json_c_and_h(fitted, tmp_path):
    from rlgsim.estimators.c_codegen import save_compensator
    X, _, models = fitted
    paths = save_compensator(models["rbf_modified"], X, tmp_path / "models",
                             name="Modified RBFNN (T, dT/dt, U)", input_units=UNITS,
                             target="B", target_unit="°/h")
    assert {p.name for p in paths.values()} == {"modified_rbfnn_t_dt_dt_u.json",
                                                "modified_rbfnn_t_dt_dt_u.c",
                                                "modified_rbfnn_t_dt_dt_u.h"}
    assert load_json(paths["json"]).name_ == "Modified RBFNN (T, dT/dt, U)"
    assert "double modified_rbfnn_t_dt_dt_u(" in paths["h"].read_text()
