"""Regressors whose hyper-parameters are tuned inside ``fit`` by a population optimiser.

* :class:`HHORVR` — paper 000 §3.2: the RBF width of a relevance vector regression
  (:class:`rlgsim.estimators.rvr.RVR`) tuned by Harris hawks optimisation (30 hawks, 500 iterations)
  with the 5-fold cross-validation RMSE as fitness.
* :class:`PSOSVR` — paper 003 §3.2-3.3: scikit-learn's epsilon-SVR with C and gamma (and
  optionally epsilon) tuned by particle swarm optimisation on a validation RMSE.

Both share :class:`OptimizerTunedRegressor`: every hyper-parameter is searched in log10 between
its bounds, mapped affinely onto the box [-1, 1]^d the optimiser sees (so the optimiser's
coordinates do not depend on the units of X or y — HHO's rules are drawn towards the origin of
its box, which is then the geometric middle of the bounds, not "width = 1 unit"); the fitness of
a population is the validation RMSE (units of y) of one model per member; the best point is
refitted on all the data. Validation defaults to contiguous-in-time folds (estimators/cv.py);
``shuffle=True`` gives the randomly split folds of paper 000.

``optimizer`` may be "hho" or "pso" for either model (HHO-tuned SVR, PSO-tuned RVR), with
``n_agents``, ``max_iter`` and ``max_evals`` passed to it.

Why this file is long: both regressors share :class:`OptimizerTunedRegressor` and its kernel
buffers, and an exported compensator records its fitted model's class path
(``rlgsim.estimators.tuned.HHORVR``, ``…PSOSVR``; :mod:`rlgsim.estimators.model_export`), so
moving a class would change every exported file.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import warnings
from numbers import Integral, Real

import numpy as np
from joblib import delayed
from sklearn import config_context
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.compose import TransformedTargetRegressor
from sklearn.exceptions import ConvergenceWarning
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVR
from sklearn.utils import check_random_state
from sklearn.utils.validation import check_is_fitted, validate_data

from rlgsim.estimators._validation import check_positive, check_positive_range, validate_fit_input
from rlgsim.estimators.cv import validation_splits
from rlgsim.estimators.kernels import squared_distances
from rlgsim.estimators.optimize import harris_hawks, particle_swarm
from rlgsim.estimators.rvr import RVR, basis_centres, rbf_from_sqdist, scale_width, sparse_bayes_fit

OPTIMIZERS = {"hho": harris_hawks, "pso": particle_swarm}
_MAX_CACHED_CELLS = 20_000_000      # squared-distance cells PSO-SVR caches (160 MB of float64)
#: PSOSVR's choice of the refitted point among the validated ones (its docstring)
SELECTIONS = ("best", "one_se", "paired_se")


class OptimizerTunedRegressor(RegressorMixin, BaseEstimator):
    """Base: tune log10 hyper-parameters by an optimiser on a validation RMSE, then refit.

    Subclasses define ``_search_space(X, y) -> (names, log10_low, log10_high)``,
    ``_make_fitness(X, y, splits) -> f(log10_params (m, d)) -> (m,) RMSE`` and
    ``_refit(X, y, params) -> fitted estimator``.

    Attributes after ``fit``: ``best_params_`` (dict, natural units), ``best_score_``
    (validation RMSE at the best point, units of y), ``optimize_result_`` (the optimiser's
    :class:`~rlgsim.estimators.optimize.OptimizeResult`: evaluations, best-so-far curve), ``n_iter_``
    (optimiser iterations run), ``n_fits_``
    (validation model fits actually run), ``estimator_`` (the refitted model).
    """

    _model_name = "tuned regressor"

    def _check_common_params(self) -> None:
        if self.optimizer not in OPTIMIZERS:
            raise ValueError(f"optimizer must be one of {sorted(OPTIMIZERS)}, "
                             f"got {self.optimizer!r}")
        check_positive(self.n_agents, "n_agents", integer=True, minimum=2)
        check_positive(self.max_iter, "max_iter", integer=True, allow_none=True)
        check_positive(self.max_evals, "max_evals", integer=True, allow_none=True)
        if self.max_iter is None and self.max_evals is None:
            raise ValueError("give max_iter, max_evals or both")

    def fit(self, X, y):
        """Tune on (X, y) — rows in time order — then refit on all of it; returns self."""
        self._check_common_params()
        self._check_params()
        X, y = validate_fit_input(self, X, y, model=self._model_name)
        rs = check_random_state(self.random_state)
        fold_seed, opt_seed = rs.randint(np.iinfo(np.int32).max, size=2)
        splits = validation_splits(X.shape[0], self.validation, self.shuffle, fold_seed)
        names, lo, hi = self._search_space(X, y)
        lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        self.n_fits_ = 0
        fitness_log = self._make_fitness(X, y, splits)

        def fitness(U: np.ndarray) -> np.ndarray:
            return fitness_log(lo + (U + 1.0) * 0.5 * (hi - lo))

        result = OPTIMIZERS[self.optimizer](
            fitness, [(-1.0, 1.0)] * len(names), self.n_agents, self.max_iter, self.max_evals,
            random_state=np.random.default_rng(opt_seed))
        best_log, best_score = self._choose(lo + (result.x + 1.0) * 0.5 * (hi - lo),
                                            float(result.fun))
        self.best_params_ = {n: float(10.0 ** v) for n, v in zip(names, best_log)}
        self.best_score_ = best_score
        self.optimize_result_ = result
        self.n_iter_ = result.nit
        self.estimator_ = self._refit(X, y, self.best_params_)
        return self

    def _snap(self, log_params: np.ndarray) -> np.ndarray:
        """The point the fitness actually evaluated for the optimiser's best position."""
        return log_params

    def _choose(self, best_log: np.ndarray, best_score: float) -> tuple[np.ndarray, float]:
        """The log10 point refitted and its validation score, given the optimiser's best
        position and score (default: that point, snapped to what the fitness evaluated)."""
        return self._snap(best_log), best_score

    def predict(self, X):
        """Predictions of the refitted model (units of y)."""
        check_is_fitted(self)
        X = validate_data(self, X, reset=False, dtype=np.float64)
        return self.estimator_.predict(X)


class HHORVR(OptimizerTunedRegressor):
    """RVR whose RBF width is tuned by Harris hawks optimisation on the k-fold CV RMSE
    (paper 000 §3.2: 30 hawks, 500 iterations, 5 folds).

    Parameters
    ----------
    width_bounds : (low, high) or None
        Search range of the width in units of X (log-uniform). ``None``: 0.01 to 10 times
        sqrt(n_features var(X)) (paper 000's range was lost in the text extraction).
    fit_intercept, rvr_max_iter, max_basis : passed to :class:`~rlgsim.estimators.rvr.RVR`
        (``max_iter``, ``max_basis``); in each fold the candidate basis functions are those of
        its training rows (at most ``max_basis`` of them, evenly spaced).
    optimizer : "hho" (default) or "pso".
    n_agents, max_iter, max_evals : population size, iterations, evaluation budget.
    validation : int k >= 2 for k-fold CV (default 5) or a hold-out fraction in (0, 1).
    shuffle : shuffle the folds (default False: contiguous in time).
    width_resolution : float or None, default 1e-6
        Resolution of the width search in decades (1e-6 decade = 2.3 ppm of width): positions
        that round to the same grid point share one cross-validation (cached). Late in an HHO
        run most hawks sit within that distance of the rabbit, so this removes most repeated
        RVR fits without changing the answer at any physically meaningful resolution. ``None``
        evaluates every position exactly.
    random_state : seed for the optimiser and shuffled folds.

    Attributes
    ----------
    width_ : tuned width (units of X); ``best_params_ = {"width": width_}``.
    best_score_ : CV RMSE at ``width_`` (units of y), pooled over all held-out points.
    estimator_ : the :class:`~rlgsim.estimators.rvr.RVR` refitted on all data.
    n_fits_ : distinct widths cross-validated (cache misses); ``optimize_result_.nfev`` counts
        fitness evaluations as the optimiser sees them.
    """

    _model_name = "HHO-RVR"

    def __init__(self, width_bounds=None, fit_intercept: bool = True, rvr_max_iter: int = 10000,
                 max_basis: int | None = 1000, optimizer: str = "hho", n_agents: int = 30, max_iter: int | None = 500,
                 max_evals: int | None = None, validation=5, shuffle: bool = False,
                 width_resolution: float | None = 1e-3, random_state=None):
        self.width_bounds = width_bounds
        self.fit_intercept = fit_intercept
        self.rvr_max_iter = rvr_max_iter
        self.max_basis = max_basis
        self.optimizer = optimizer
        self.n_agents = n_agents
        self.max_iter = max_iter
        self.max_evals = max_evals
        self.validation = validation
        self.shuffle = shuffle
        self.width_resolution = width_resolution
        self.random_state = random_state

    def _check_params(self) -> None:
        if self.width_bounds is not None:
            check_positive_range(self.width_bounds, "width_bounds")
        check_positive(self.rvr_max_iter, "rvr_max_iter", integer=True)
        check_positive(self.max_basis, "max_basis", integer=True, allow_none=True)
        r = self.width_resolution
        if r is not None and not (isinstance(r, Real) and np.isfinite(r) and r > 0):
            raise ValueError(f"width_resolution must be a positive number of decades or None, "
                             f"got {r!r}")

    def _search_space(self, X, y):
        if self.width_bounds is None:
            s = scale_width(X)
            lo, hi = 0.05 * s, 10.0 * s
        else:
            lo, hi = check_positive_range(self.width_bounds, "width_bounds")
        return ["width"], [np.log10(lo)], [np.log10(hi)]

    def _make_fitness(self, X, y, splits):
        # candidate centres of each fold, as columns of one cached squared-distance matrix
        fold_centres = [tr[basis_centres(tr.size, self.max_basis)] for tr, _ in splits]
        used = np.unique(np.concatenate(fold_centres))
        column = np.full(X.shape[0], -1, dtype=np.intp)
        column[used] = np.arange(used.size)
        D2 = squared_distances(X, X[used])     # cached across all evaluations
        n_test = sum(te.size for _, te in splits)
        blocks = [(tr, te, np.ix_(tr, column[c]), column[c])
                  for (tr, te), c in zip(splits, fold_centres)]
        cache: dict = {}
        res = self.width_resolution

        def cv_rmse(log_w: float) -> float:
            K = rbf_from_sqdist(D2, 10.0 ** log_w)
            sse = 0.0
            for tr, te, fit_block, cols in blocks:
                try:
                    fit = sparse_bayes_fit(K[fit_block], y[tr], self.fit_intercept,
                                           self.rvr_max_iter)
                except FloatingPointError:      # a diverged fit scores worst
                    self.n_fits_ += 1
                    return np.inf
                pred = K[np.ix_(te, cols[fit.relevant])] @ fit.weights + fit.bias
                sse += float(np.sum((pred - y[te]) ** 2))
            self.n_fits_ += 1
            return float(np.sqrt(sse / n_test))

        def fitness(L: np.ndarray) -> np.ndarray:
            out = np.empty(L.shape[0])
            for i, log_w in enumerate(L[:, 0]):
                if res is None:
                    out[i] = cv_rmse(log_w)
                    continue
                key = int(np.rint(log_w / res))
                if key not in cache:
                    cache[key] = cv_rmse(key * res)
                out[i] = cache[key]
            return out

        return fitness

    def _refit(self, X, y, params):
        return RVR(width=params["width"], fit_intercept=self.fit_intercept,
                   max_iter=self.rvr_max_iter, max_basis=self.max_basis).fit(X, y)

    def fit(self, X, y):
        super().fit(X, y)
        if self.width_resolution is not None:   # the width actually cross-validated
            res = self.width_resolution
            w = 10.0 ** (np.rint(np.log10(self.best_params_["width"]) / res) * res)
            self.best_params_ = {"width": float(w)}
            self.estimator_ = self._refit(X, y, self.best_params_)
        self.width_ = self.best_params_["width"]
        return self

    def predict(self, X, return_std: bool = False):
        """Predictive mean (units of y); with ``return_std`` also the RVR predictive std."""
        check_is_fitted(self)
        X = validate_data(self, X, reset=False, dtype=np.float64)
        return self.estimator_.predict(X, return_std=return_std)


def _holdout_sse(Xs: np.ndarray, ys: np.ndarray, splits, max_iter: int, tol: float, dist,
                 C: float, gamma: float, eps: float) -> tuple[float, int, np.ndarray]:
    """Squared validation error summed over the splits of one (C, gamma, epsilon) point
    (standardised units), how many of its fits stopped at ``max_iter``, and the squared
    residuals themselves (the splits' test rows one after the other). ``tol``: libsvm's
    stopping tolerance. ``dist``: per split the squared distances (train x train, test x
    train) for libsvm's precomputed kernel exp(-gamma D2) — 10-25 % faster per fit than its
    own RBF evaluations — or None (RBF)."""
    sse, capped, sq = 0.0, 0, []
    for k, (tr, te) in enumerate(splits):
        kernel = "rbf" if dist is None else "precomputed"
        svr = SVR(kernel=kernel, C=C, gamma=gamma, epsilon=eps, tol=tol, max_iter=max_iter,
                  cache_size=500)
        if dist is None:
            A_tr, A_te = Xs[tr], Xs[te]
        else:
            A_tr = _rbf_into(dist[k][0], gamma, 0)
            A_te = _rbf_into(dist[k][1], gamma, 1)
        # the kernels are finite by construction: scikit-learn's finiteness scan of the
        # 20-30 MB of them (~2.5 ms a point) is skipped
        with warnings.catch_warnings(), config_context(assume_finite=True):
            warnings.simplefilter("ignore", ConvergenceWarning)
            svr.fit(A_tr, ys[tr])
            r2 = (svr.predict(A_te) - ys[te]) ** 2
        if max_iter > 0 and np.max(svr.n_iter_) >= max_iter:
            capped += 1
        sse += float(np.sum(r2))
        sq.append(r2)
    return sse, capped, np.concatenate(sq)


def batch_means_se(values: np.ndarray) -> float:
    """Standard error of the mean of a time-ordered, serially correlated series by
    non-overlapping batch means: floor(sqrt(n)) contiguous batches of (nearly) equal size,
    SE = std(batch means, ddof=1) / sqrt(number of batches) (batch size ~ sqrt(n): Flegal &
    Jones 2010, "Batch means and spectral variance estimators in Markov chain Monte Carlo",
    Ann. Statist. 38(2)). Correlation shorter than a batch is accounted for; the plain
    std/sqrt(n) would understate the SE of residuals that drift together over many rows.
    NaN for fewer than 4 values."""
    v = np.asarray(values, dtype=float)
    if v.size < 4:              # fewer than 2 batches of 2: no estimate (NaN, without warnings)
        return float("nan")
    b = max(2, int(np.sqrt(v.size)))
    means = np.array([c.mean() for c in np.array_split(v, b)])
    return float(np.std(means, ddof=1) / np.sqrt(b))


#: per process, the kernel buffers of the last shapes seen (train x train, test x train)
_KERNEL_BUFFERS: dict = {}


def _rbf_into(D2: np.ndarray, gamma: float, slot: int) -> np.ndarray:
    """exp(-gamma D2) written into a buffer this process keeps for the shape (``slot`` 0: the
    training block, 1: the validation block). The same values as ``np.exp(D2 * -gamma)``;
    reusing the memory spares two fresh 20-30 MB arrays per fit, whose page faults cost more
    than the exponentials (3.5 x the time at 1773 x 2216 on the shared 2-core machine). The
    buffer is overwritten by the next call: use it before then (``_holdout_sse`` fits and
    predicts with it at once)."""
    buf = _KERNEL_BUFFERS.get(slot)
    if buf is None or buf.shape != D2.shape:
        buf = _KERNEL_BUFFERS[slot] = np.empty(D2.shape)
    np.multiply(D2, -gamma, out=buf)
    return np.exp(buf, out=buf)


def _n_jobs(n_jobs, n_rows: int) -> int:
    """Worker processes for the fitness: ``None`` = the cores (at most 8), 1 for fewer than 500
    rows or inside a worker process (a Monte Carlo unit or another pool: no nested pools)."""
    import multiprocessing
    import os
    if n_jobs is None:
        if multiprocessing.parent_process() is not None or n_rows < 500:
            return 1
        return max(1, min(8, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                          else (os.cpu_count() or 1)))
    return max(1, int(n_jobs))


def _parallel(n_jobs: int):
    from joblib import Parallel
    return Parallel(n_jobs=n_jobs, backend="loky", batch_size=1, pre_dispatch="all")


def _ready() -> bool:
    """A worker's first task: unpickling it imports this module (scikit-learn's SVR)."""
    return True


def start_search_workers(n_rows: int, n_jobs: int | None = None) -> int:
    """Start the worker processes a :class:`PSOSVR` search of ``n_rows`` rows will use (the
    same joblib pool, :func:`_parallel`), so that their start-up — a fresh interpreter
    importing scikit-learn and this module, ~1.5 s of CPU each — overlaps the caller's own
    work (a study simulating its test runs) instead of stalling the search's first
    iteration. Blocks until they are ready (call it from a thread); returns how many."""
    n = _n_jobs(n_jobs, n_rows)
    if n > 1:
        _parallel(n)(delayed(_ready)() for _ in range(n))
    return n


def _new_shared_folder() -> str:
    """A temporary folder (in /dev/shm where there is one) for arrays the worker processes
    map, registered with joblib's resource tracker so that it is removed even when this
    process is killed before ``fit`` removes it (as joblib does with its own folders)."""
    from joblib.externals.loky.backend import resource_tracker
    shm = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None
    folder = tempfile.mkdtemp(prefix="rlgsim-psosvr-", dir=shm)
    resource_tracker.register(folder, "folder")
    return folder


def _remove_shared_folder(folder: str) -> None:
    from joblib.externals.loky.backend import resource_tracker
    shutil.rmtree(folder, ignore_errors=True)
    resource_tracker.unregister(folder, "folder")


def _shared_arrays(arrays, folder: str):
    """The arrays written once to ``folder`` and opened read-only memory-mapped: joblib hands a
    ``numpy.memmap`` to its worker processes by file name, so the squared distances (25 MB at
    1600 training rows) are not dumped again for every swarm iteration (0.1 s per iteration,
    10 s of a 100-iteration search, when they were passed as plain arrays)."""
    out = []
    for k, a in enumerate(arrays):
        path = os.path.join(folder, f"d{k}.npy")
        np.save(path, a)
        out.append(np.load(path, mmap_mode="r"))
    return out


class PSOSVR(OptimizerTunedRegressor):
    """epsilon-SVR (scikit-learn, RBF kernel) with C and gamma (and optionally epsilon) tuned
    by particle swarm optimisation on a validation RMSE (paper 003 §3.3).

    Inputs and target are standardised (statistics of the whole training set), so C, gamma and
    epsilon refer to the standardised problem: gamma in 1/(standard deviation)^2 of the inputs,
    epsilon in standard deviations of y, C in standard deviations of y per unit weight.

    Parameters
    ----------
    C_bounds, gamma_bounds : (low, high) log-uniform search ranges; defaults (1e-2, 1e3) and
        (1e-3, 1e2) — their log-centres C ~ 3 and gamma ~ 0.3 are the usual starting values
        for standardised data (Cherkassky & Ma 2004: C ~ 3 sigma_y).
    epsilon : tube half-width when not tuned (default 0.1).
    tune_epsilon : also tune epsilon within ``epsilon_bounds`` (default (1e-3, 1)).
    optimizer : "pso" (default) or "hho"; n_agents, max_iter, max_evals as for the optimiser
        (defaults 30 particles x 100 iterations).
    validation : hold-out fraction (default 0.2: the last 20 % of the rows in time order) or
        an integer k for k-fold CV; ``shuffle`` randomises either.
    search_max_iter : int, default 10 000
        SMO iterations after which a search fit stops (libsvm ``max_iter``; -1 for none); a
        stopped fit is scored as it stands. This cap is part of the estimator's definition:
        the fitness the swarm minimises is the validation RMSE of an SVR trained by at most
        10 000 SMO steps (early stopping), not of the exact dual optimum. The final refit on
        all data is never capped. Why: near the paper-003 optimum (C ~ 1e2-1e3) libsvm needs
        0.3-2.5 million iterations (1-13 s at 1600 rows) to reach its tolerance, and no
        cheaper exact solver was found (the free-set kernel blocks are numerically singular
        there, so active-set/Newton polishing fails); capped, a fit costs about 0.1 s (the
        first SMO iterations cost ~12 µs each at 1600 rows: the working-set selection scans
        every variable until shrinking starts), against 0.2-0.7 s at 100 000. The cost
        in quality is measured, not assumed: on the paper-003 benchmark
        (benchmarks/estimators_optimizers.py, 30 x 100, N = 2000) the optimum chosen with the
        cap, re-fitted to convergence, scores a validation RMSE 0.12 % above the converged
        score of the optimum the former 100 000 cap chose (0.7 % with a 3 000 cap, 0.4 % with
        1 000: the valley is flat in C). That search takes 116 s on the 2 shared cores at load
        average 1.9-2.4 (165 s CPU in all processes; 1733 distinct points, 1506 of them
        capped) with the former 0.02-decade grid — above the 30 s the issue asks for; the
        0.1-decade grid (``resolution``) brings it to 15.5 s.
        Capped fits can score a little *below* their converged value (the former 100 000 cap
        reported 4.942e-4 °/h at its optimum, whose converged score is 5.020e-4), so compare
        converged re-scores, not search scores.
        Why not 1 000, which meets the benchmark's targets (benchmarks/pso_svr_search_cap.py,
        one run at load 1.6-2.3: 29.1 s against 94.7 s for 10 000, converged ratio 1.0036
        against 1.0012; at load 3-5: 50.5 s against 169.3 s)? The
        valley is flat in C, the choice inside it is noisy, and over ten PSO seeds of the
        paper-003 study (20 x 50, benchmarks/pso_svr_study_seeds.py, paired by seed) the
        1 000 cap leaves the multi-point model's Table 5 STD after compensation worse in
        distribution — 0.00295 ± 0.00020 °/h against 0.00272 ± 0.00002 (mean ± standard
        error; two of ten seeds pick gamma ~ 0.06, whose early-stopped fits validate well and
        extrapolate badly, 0.0039-0.0044) — and the 3-point model's too (0.00775 ± 0.00034
        against 0.00729 ± 0.00033). The issue's "no loss of result quality" is not met with
        it, so 10 000 stays.
    search_tol : float, default 1e-3
        libsvm's stopping tolerance of the search fits (its default; standardised targets).
        Measured on the paper-003 benchmark in the run above: 0.1 (cap 10 000) takes 74.7 s
        (750 of 1713 points capped, against 1506 of 1733), converged ratio 0.9968; 0.1 with
        cap 1 000 takes 28.3 s, ratio 1.0146 (outside 1 %). Neither is the default: the
        first is not fast enough, the second not good enough.
    selection : {"best", "one_se", "paired_se"}, default "best"
        Which validated point is refitted. "best": the lowest search score. The other two
        choose inside the set of points whose validation error cannot be told from the
        lowest — the most regularised one: smallest C, then smallest gamma, then largest
        epsilon (the one-standard-error rule, Hastie, Tibshirani & Friedman, *The Elements of
        Statistical Learning*, 2nd ed., §7.10). The standard errors are batch means over the
        validation rows in time order (:func:`batch_means_se`), because the residuals of
        drift data are serially correlated. "one_se": points whose validation MSE is within
        one SE of the lowest MSE (SE of the lowest point's mean squared residual, ESL's
        rule). "paired_se": points whose mean squared-residual difference from the lowest
        point is within one SE of that difference (the paired comparison of two predictors
        on the same rows, Diebold & Mariano 1995, J. Bus. Econ. Stat. 13(3)) — a narrower set,
        since two nearby models' errors move together. Cost: one pass over the validated
        points' squared residuals (kept: n_fits_ x validation rows floats). Measured, not
        the default: on the paper-003 benchmark (cap 1 000) "one_se" refits a point whose
        converged validation RMSE is 2.4 % above the reference optimum's (C = 0.29: the
        batch-means SE of the MSE there is ~8 % of it) and "paired_se" one 1.2 % above it
        (C = 1.2), both outside the issue's 1 % (the search minimum: 0.36 %); over ten
        PSO seeds of the paper-003 study (cap 1 000, against the default) "paired_se"
        improves the 3-point model's Table 5 STD after compensation (0.00697 ± 0.00012 °/h
        against 0.00729 ± 0.00033) but not the multi-point model's (0.00289 ± 0.00017
        against 0.00272 ± 0.00002: on the study's own seed it picks C = 5.5, gamma = 0.14,
        0.0044), and "one_se" makes the multi-point model worse on every seed (0.00288 ±
        0.00002). Smallest C first is a crude order of regularisation for an RBF kernel,
        whose flexibility grows with gamma too.
    resolution : float or None, default 0.1
        Resolution of the search in decades of every tuned parameter (0.1 decade = 26 %, ten
        grid points per decade): positions that round to the same grid point share one
        validation (cached), and the point evaluated is the grid point. ``None`` evaluates
        every position exactly. Why 0.1 (it was 0.02 = 4.7 %): the validation valley is flat
        over decades of C, so a finer grid buys no validation error and only more distinct
        points, nearly all of them capped large-C fits. Measured in one run on the paper-003
        benchmark (benchmarks/pso_svr_search_cap.py, 30 x 100, N = 2000, load 0.9-1.9):
        0.1 takes 15.5 s (382 distinct points, 229 capped), converged ratio 0.9993; 0.05
        takes 37.0-37.5 s (854 points), ratio 1.0010; 0.02 takes 82.2 s (1 733 points),
        ratio 1.0012 — the issue's targets (30 s, 1 %) are met at 0.1 only. Over ten PSO
        seeds of the paper-003 study (benchmarks/pso_svr_study_seeds.py cap10000 grid0.1,
        paired by seed, load 1.8-2.4; mean ± standard error of the difference 0.1 − 0.02):
        Table 5 STD after compensation, 3-point −0.00079 ± 0.00034 °/h (0.00650 against
        0.00729), multi-point −0.000032 ± 0.000020 (0.00269 against 0.00272); Table 4 3-point
        −0.000014 ± 0.000003; Table 4 multi-point +0.000015 ± 0.000006 (0.002384 against
        0.002369, 0.6 % worse: the one figure that is worse); the study's PSO-SVR fits 17.7 s
        against 37.3 s. On the small problem of tests/test_tuned.py the search's score is
        0.55 % above the exact (ungridded) search's (0.13 % at 0.02).
    n_jobs : int or None
        Processes that validate the distinct new points of a swarm iteration in parallel
        (joblib); ``None``: the available cores (at most 8) for problems of 500 rows or more,
        1 below that (process start-up would dominate) and inside a worker process (a Monte
        Carlo unit: no nested pools). Results do not depend on it.
    random_state : seed for the optimiser and shuffled splits.

    Attributes
    ----------
    best_params_ : {"C", "gamma", "epsilon"} of the standardised problem.
    best_score_ : validation RMSE at the best point (units of y).
    n_capped_fits_ : search fits (per fold) stopped by ``search_max_iter``.
    min_score_, min_params_ : the lowest search score and its point (C, gamma[, epsilon]).
    score_se_ : batch-means SE of the lowest point's validation MSE (units of y squared);
        ``one_se_score_`` the RMSE at one SE above it.
    search_points_, search_scores_ : every validated point (n_fits_, d: C, gamma[, epsilon])
        and its validation RMSE (units of y).
    n_fits_ : distinct grid points validated (cache misses); ``optimize_result_.nfev``
        counts fitness evaluations as the optimiser sees them.
    estimator_ : ``TransformedTargetRegressor(Pipeline(StandardScaler, SVR), StandardScaler)``
        refitted on all data.
    """

    _model_name = "PSO-SVR"

    def __init__(self, C_bounds=(1e-2, 1e3), gamma_bounds=(1e-3, 1e2), epsilon: float = 0.1,
                 tune_epsilon: bool = False, epsilon_bounds=(1e-3, 1.0), optimizer: str = "pso",
                 n_agents: int = 30, max_iter: int | None = 100, max_evals: int | None = None,
                 validation=0.2, shuffle: bool = False, search_max_iter: int = 10_000,
                 search_tol: float = 1e-3, selection: str = "best",
                 resolution: float | None = 0.1, n_jobs: int | None = None,
                 random_state=None):
        self.C_bounds = C_bounds
        self.gamma_bounds = gamma_bounds
        self.epsilon = epsilon
        self.tune_epsilon = tune_epsilon
        self.epsilon_bounds = epsilon_bounds
        self.optimizer = optimizer
        self.n_agents = n_agents
        self.max_iter = max_iter
        self.max_evals = max_evals
        self.validation = validation
        self.shuffle = shuffle
        self.search_max_iter = search_max_iter
        self.search_tol = search_tol
        self.selection = selection
        self.resolution = resolution
        self.n_jobs = n_jobs
        self.random_state = random_state

    def _check_params(self) -> None:
        check_positive_range(self.C_bounds, "C_bounds")
        check_positive_range(self.gamma_bounds, "gamma_bounds")
        if self.tune_epsilon:
            check_positive_range(self.epsilon_bounds, "epsilon_bounds")
        e = self.epsilon
        if isinstance(e, bool) or not isinstance(e, Real) or not (np.isfinite(e) and e >= 0):
            raise ValueError(f"epsilon must be a finite number >= 0, got {e!r}")
        m = self.search_max_iter
        if isinstance(m, bool) or not isinstance(m, Integral) or (m < 1 and m != -1):
            raise ValueError(f"search_max_iter must be an integer >= 1 or -1, got {m!r}")
        check_positive(self.search_tol, "search_tol")
        if self.selection not in SELECTIONS:
            raise ValueError(f"selection must be one of {list(SELECTIONS)}, "
                             f"got {self.selection!r}")
        check_positive(self.resolution, "resolution", allow_none=True)
        check_positive(self.n_jobs, "n_jobs", integer=True, allow_none=True)

    def _search_space(self, X, y):
        names = ["C", "gamma"]
        bounds = [check_positive_range(self.C_bounds, "C_bounds"),
                  check_positive_range(self.gamma_bounds, "gamma_bounds")]
        if self.tune_epsilon:
            names.append("epsilon")
            bounds.append(check_positive_range(self.epsilon_bounds, "epsilon_bounds"))
        b = np.log10(np.array(bounds))
        return names, b[:, 0], b[:, 1]

    def _make_fitness(self, X, y, splits):
        Xs = StandardScaler().fit_transform(X)
        y_mean, y_std = float(np.mean(y)), float(np.std(y))
        y_std = y_std if y_std > 0 else 1.0
        ys = (y - y_mean) / y_std
        n_test = sum(te.size for _, te in splits)
        tune_eps = self.tune_epsilon
        res = self.resolution
        max_iter = int(self.search_max_iter)
        n_jobs = _n_jobs(self.n_jobs, X.shape[0])
        # the squared distances of every split, computed once (unless they would exceed
        # ~160 MB); each worker process receives them once per swarm iteration (joblib
        # memory-maps large arrays)
        n_cells = sum(tr.size * (tr.size + te.size) for tr, te in splits)
        dist = None
        if n_cells <= _MAX_CACHED_CELLS:
            dist = [(squared_distances(Xs[tr], Xs[tr]), squared_distances(Xs[te], Xs[tr]))
                    for tr, te in splits]
            if n_jobs > 1:
                self._shared_folder = _new_shared_folder()      # removed by fit
                flat = _shared_arrays([a for pair in dist for a in pair], self._shared_folder)
                dist = [(flat[2 * k], flat[2 * k + 1]) for k in range(len(dist))]
        data = (Xs, ys, tuple(splits), max_iter, float(self.search_tol), dist)
        self.n_capped_fits_ = 0
        cache: dict = {}
        # the squared residuals of every point, in time order of the validation rows
        time_order = np.argsort(np.concatenate([te for _, te in splits]), kind="stable")
        residuals: dict = {}
        self._search = (cache, residuals, y_std)     # read by _choose, removed by fit

        def params_of(logp: np.ndarray) -> tuple[float, float, float]:
            eps = 10.0 ** logp[2] if tune_eps else float(self.epsilon)
            return 10.0 ** logp[0], 10.0 ** logp[1], eps

        def fitness(L: np.ndarray) -> np.ndarray:
            keys = [tuple(np.rint(p / res).astype(np.int64)) if res is not None else
                    tuple(p) for p in L]
            todo = list(dict.fromkeys(k for k in keys if k not in cache))
            points = [params_of(np.asarray(k, float) * res if res is not None else
                                np.asarray(k, float)) for k in todo]
            if n_jobs > 1 and len(points) > 1:
                # largest C first, one point per task: the slow (large-C) fits start at once
                # and the cheap ones fill the other workers (the swarm waits for the slowest)
                first = sorted(range(len(points)), key=lambda i: -points[i][0])
                res_ = _parallel(n_jobs)(delayed(_holdout_sse)(*data, *points[i])
                                         for i in first)
                out = [None] * len(points)
                for i, r in zip(first, res_):
                    out[i] = r
            else:
                out = [_holdout_sse(*data, *p) for p in points]
            for k, (sse, capped, sq) in zip(todo, out):
                cache[k] = float(np.sqrt(sse / n_test)) * y_std
                residuals[k] = sq[time_order]
                self.n_capped_fits_ += capped
                self.n_fits_ += 1
            return np.array([cache[k] for k in keys])

        return fitness

    def _refit(self, X, y, params):
        eps = params.get("epsilon", float(self.epsilon))
        svr = SVR(kernel="rbf", C=params["C"], gamma=params["gamma"], epsilon=eps,
                  cache_size=500)
        model = TransformedTargetRegressor(regressor=make_pipeline(StandardScaler(), svr),
                                           transformer=StandardScaler())
        return model.fit(X, y)

    def _snap(self, log_params):
        if self.resolution is None:
            return log_params
        return np.rint(log_params / self.resolution) * self.resolution

    def _key(self, log_params) -> tuple:
        res = self.resolution
        return tuple(np.rint(log_params / res).astype(np.int64)) if res is not None else \
            tuple(log_params)

    def _choose(self, best_log, best_score):
        """``selection="best"``: the lowest search score. ``"one_se"``: among the validated
        points whose squared-error mean is within one standard error (batch means over the
        validation rows in time order) of the lowest, the most regularised — smallest C,
        then smallest gamma, then largest epsilon."""
        cache, residuals, y_std = self._search
        snapped = self._snap(best_log)
        key = self._key(best_log)
        sq = residuals[key]
        se = batch_means_se(sq) if sq.size >= 2 else 0.0
        self.min_score_ = best_score
        self.min_params_ = self._natural(snapped)
        self.score_se_ = se * y_std ** 2
        self.one_se_score_ = float(np.sqrt(np.mean(sq) + se)) * y_std
        keys = list(cache)
        grid = np.array(keys, dtype=float).reshape(len(keys), -1)
        self.search_points_ = 10.0 ** (grid * self.resolution if self.resolution is not None
                                       else grid)
        self.search_scores_ = np.array([cache[k] for k in keys])
        if self.selection == "best":
            return snapped, best_score
        if self.selection == "one_se":
            limit = np.mean(sq) + se
            within = [k for k, r in residuals.items() if np.mean(r) <= limit]
        else:
            within = [k for k, r in residuals.items()
                      if np.mean(r - sq) <= batch_means_se(r - sq)]
        order = (lambda k: (k[0], k[1], -k[2])) if self.tune_epsilon else \
            (lambda k: (k[0], k[1]))
        chosen = min(within, key=order)
        log = np.asarray(chosen, float)
        if self.resolution is not None:
            log = log * self.resolution
        return log, cache[chosen]

    def _natural(self, log_params) -> dict[str, float]:
        names = ["C", "gamma"] + (["epsilon"] if self.tune_epsilon else [])
        return {n: float(10.0 ** v) for n, v in zip(names, log_params)}

    def fit(self, X, y):
        try:
            super().fit(X, y)
        finally:
            self.__dict__.pop("_search", None)
            # the folder of the distances the worker processes mapped, if the search made one
            folder = self.__dict__.pop("_shared_folder", None)
            if folder is not None:
                _remove_shared_folder(folder)
        if not self.tune_epsilon:
            self.best_params_["epsilon"] = float(self.epsilon)
        return self
