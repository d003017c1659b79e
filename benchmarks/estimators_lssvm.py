"""LS-SVM / IR-LSSVM fit times, side by side with scikit-learn's KernelRidge at the same N.

Run: ``python benchmarks/bench_estimators.py lssvm`` (or this file directly).

Data: three paper-001-like inputs in their own units (temperature °C, rate K/s, U_HFO V) and a
smooth nonlinear bias (deg/h) with white noise; for IR-LSSVM 10 % of the targets get gross errors.
Each fit is timed with ``time.perf_counter`` (the median of ``repeats``), predictions are scored
against the noise-free truth on 2000 fresh inputs. KernelRidge gets the same standardised inputs,
``alpha = 1/gamma`` and ``gamma = 1/(2 sigma2)`` (the documented mapping; it has no bias term).
At N = 1e5 a dense kernel matrix would take 80 GB, so the low-rank LS-SVM is compared with
scikit-learn's low-rank counterpart, ``Nystroem`` + ``Ridge`` with the same number of landmarks.

Targets (issue 5): dense LS-SVM no slower than KernelRidge at equal N; low-rank N = 1e5 < 2 s.
The machine is shared; the load average is printed with the figures.
"""

from __future__ import annotations

import os
import pathlib
import sys
import time
import warnings

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from _machine import MIN_PAIRS, machine, shared_watch, spread  # noqa: E402
from sklearn.kernel_approximation import Nystroem  # noqa: E402
from sklearn.kernel_ridge import KernelRidge  # noqa: E402
from sklearn.linear_model import Ridge  # noqa: E402
from sklearn.pipeline import make_pipeline  # noqa: E402
from sklearn.preprocessing import StandardScaler  # noqa: E402

from rlgsim.estimators.lssvm import LSSVMRegressor  # noqa: E402
from rlgsim.estimators.lssvm_cv import LSSVMRegressorCV  # noqa: E402
from rlgsim.estimators.robust_lssvm import RobustLSSVMRegressor  # noqa: E402

GAMMA, SIGMA2 = 100.0, 1.0
NOISE = 0.003  # deg/h


def truth(X: np.ndarray) -> np.ndarray:
    T, dT, U = X[:, 0], X[:, 1], X[:, 2]
    return 0.02 * np.sin(T / 15.0) + 2.0 * dT + 0.01 * (U - 11.0) ** 2 + 1e-5 * T * (U - 11.0)


def data(n: int, seed: int, outliers: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(-40.0, 70.0, n), rng.uniform(-1 / 60, 1 / 60, n),
                         rng.uniform(10.0, 12.0, n)])
    y = truth(X) + NOISE * rng.standard_normal(n)
    k = int(outliers * n)
    bad = rng.choice(n, k, replace=False)
    y[bad] += rng.choice([-1.0, 1.0], k) * rng.uniform(20 * NOISE, 50 * NOISE, k)
    return X, y


X_TEST, _ = data(2000, seed=999)


def timed_fit(make, X, y, repeats: int):
    """Median fit time [s] of ``repeats`` fits and the last fitted model (the spread of the
    times in ``timed_fit.spread``)."""
    times, model = [], None
    for _ in range(repeats):
        model = make()
        t0 = time.perf_counter()
        model.fit(X, y)
        times.append(time.perf_counter() - t0)
    timed_fit.spread = spread(times, ".3f", " s")
    return float(np.median(times)), model


def rmse(model, Xt=X_TEST) -> float:
    return float(np.sqrt(np.mean((model.predict(Xt) - truth(Xt)) ** 2)))


def row(n: int, name: str, t: float, err: float | None, ref: float | None = None,
        note: str = "") -> None:
    ratio = f"{t / ref:6.2f}" if ref else "     -"
    e = f"{err * 1e3:9.3f}" if err is not None else "        -"
    print(f"{n:>8d}  {name:<34s} {t:9.3f}  {ratio}  {e}  {note}")


def run() -> None:
    print(f"machine: {machine()}")
    print(f"load average at start: {' '.join(f'{v:.2f}' for v in os.getloadavg())} "
          f"(shared machine; other jobs inflate every figure)")
    print(f"gamma={GAMMA:g}, sigma2={SIGMA2:g} (standardised inputs), 3 inputs, noise "
          f"{NOISE * 1e3:g} mdeg/h; fit times are medians of the repeats shown")
    print(f"{'N':>8s}  {'model':<34s} {'fit [s]':>9s}  {'/KRR':>6s}  {'RMSE mdeg/h':>9s}")

    # dense LS-SVM vs KernelRidge, same N, same run; alternate who goes first
    for n, repeats in ((1_000, 5), (10_000, 2)):
        X, y = data(n, seed=n)
        Xs = StandardScaler().fit_transform(X)
        t_krr, krr = timed_fit(lambda: KernelRidge(alpha=1 / GAMMA, kernel="rbf",
                                                   gamma=1 / (2 * SIGMA2)), Xs, y, repeats)
        t_ls, ls = timed_fit(lambda: LSSVMRegressor(GAMMA, SIGMA2, solver="dense"), X, y, repeats)
        t_krr2, _ = timed_fit(lambda: KernelRidge(alpha=1 / GAMMA, kernel="rbf",
                                                  gamma=1 / (2 * SIGMA2)), Xs, y, 1)
        t_krr = min(t_krr, t_krr2)
        scaler = StandardScaler().fit(X)
        krr_err = float(np.sqrt(np.mean((krr.predict(scaler.transform(X_TEST))
                                         - truth(X_TEST)) ** 2)))
        row(n, "KernelRidge (no bias)", t_krr, krr_err, t_krr)
        row(n, "LSSVMRegressor dense", t_ls, rmse(ls), t_krr,
            f"target <= 1.00: {shared_watch().verdict(t_ls <= t_krr, repeats)}")
        if n == 1_000:
            t, m = timed_fit(lambda: LSSVMRegressor(GAMMA, SIGMA2, solver="dense",
                                                    compute_loo=True), X, y, repeats)
            row(n, "  + closed-form LOO residuals", t, rmse(m), t_krr)
            t, m = timed_fit(lambda: LSSVMRegressorCV(), X, y, 1)
            row(n, "LSSVMRegressorCV LOO 7x9 grid", t, rmse(m), t_krr,
                f"chose gamma={m.gamma_:g} sigma2={m.sigma2_:g}")
            t, m = timed_fit(lambda: LSSVMRegressorCV(cv=10, random_state=0), X, y, 1)
            row(n, "LSSVMRegressorCV 10-fold 7x9 grid", t, rmse(m), t_krr,
                f"chose gamma={m.gamma_:g} sigma2={m.sigma2_:g}")
        del ls, krr

    # low rank at N = 1e5 (dense would need 80 GB)
    n = 100_000
    X, y = data(n, seed=n)
    t_ls, ls = timed_fit(lambda: LSSVMRegressor(GAMMA, SIGMA2, solver="nystroem",
                                                n_landmarks=300, random_state=0), X, y,
                         MIN_PAIRS)
    ls_spread = timed_fit.spread
    t_sk, sk = timed_fit(lambda: make_pipeline(
        StandardScaler(), Nystroem(gamma=1 / (2 * SIGMA2), n_components=300, random_state=0),
        Ridge(alpha=1 / GAMMA)), X, y, 3)
    print(f"{n:>8d}  {'KernelRidge':<34s} {'n/a':>9s}  (dense kernel would be "
          f"{8 * n * n / 1e9:.0f} GB)")
    row(n, "sklearn Nystroem(300)+Ridge", t_sk, rmse(sk))
    row(n, "LSSVMRegressor nystroem m=300", t_ls, rmse(ls), None,
        f"target < 2 s: {shared_watch().verdict(t_ls < 2, MIN_PAIRS)}; x{t_ls / t_sk:.2f} of "
        f"Nystroem+Ridge; {ls_spread}")
    t, m = timed_fit(lambda: LSSVMRegressor(GAMMA, SIGMA2, solver="nystroem", n_landmarks=300,
                                            random_state=0, compute_loo=True), X, y, 1)
    row(n, "  + closed-form LOO residuals", t, rmse(m))

    # IR-LSSVM on data with 10 % gross outliers, KernelRidge at the same N for scale
    for n in (1_000, 10_000):
        X, y = data(n, seed=n + 1, outliers=0.10)
        Xs = StandardScaler().fit_transform(X)
        t_krr, _ = timed_fit(lambda: KernelRidge(alpha=1 / GAMMA, kernel="rbf",
                                                 gamma=1 / (2 * SIGMA2)), Xs, y, 1)
        t_ls, ls = timed_fit(lambda: LSSVMRegressor(GAMMA, SIGMA2, solver="dense"), X, y, 1)
        row(n, "KernelRidge, 10 % outliers", t_krr, None, t_krr)
        row(n, "LSSVMRegressor, 10 % outliers", t_ls, rmse(ls), t_krr)
        configs = [("hampel", {}), ("huber", {"weight_param": 1.345})]
        if n == 1_000:
            configs += [("huber", {"cv": 10, "random_state": 0}),
                        ("myriad", {"cv": 10, "random_state": 0})]
        for weight, kw in configs:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t, m = timed_fit(lambda: RobustLSSVMRegressor(GAMMA, SIGMA2, weight=weight, **kw),
                                 X, y, 1)
            label = f"IR-LSSVM {weight}" + (" tuned 10-fold" if "cv" in kw else "")
            row(n, label, t, rmse(m), t_krr,
                f"{m.n_iter_} weighted solves, param={m.weight_param_}")
            del m
        del ls


if __name__ == "__main__":
    run()
