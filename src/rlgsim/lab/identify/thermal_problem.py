"""The thermal fit's problem (:mod:`rlgsim.lab.identify.thermal_fit`, whose docstring gives the
method): the twin of a thermal preset — its network and probes (:func:`build`) driven by the
recorded chamber air and power (:func:`twin_response`, also used by the probe mapping and the
next-experiment planner) — and the residuals and Jacobians of the multipliers on the fit's
grid (:class:`_Problem`), batched over processes for a network with a controlled heater.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.identify.batch_twin import batchable, twin_readings_batch
from rlgsim.lab.identify.thermal_params import apply_multipliers, thermal_parameters
from rlgsim.sim.config import Ctx
from rlgsim.sim.thermal.integrator import ThermalIntegrator
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.thermometers import ProbeSet


#: log-multiplier bounds: a factor of 10 either way of the design
_BOUND = math.log(10.0)
#: most residuals used per fit (probes × time, decimated in time beyond this)
MAX_RESIDUALS = 10_000
#: most integration steps per evaluation during the fit (a coarser grid beyond this)
MAX_FIT_STEPS = 15_000
#: the same for a network integrated step by step (a controlled heater): its evaluations cost
#: several times a linear network's, and its fit runs on the coarser grid (29 s steps for a
#: 20 h recording; thermal_fit's docstring gives what that costs in accuracy)
MAX_FIT_STEPS_STEPWISE = 2_500
#: evaluate the finite-difference Jacobian of a heater network in one batch
#: (:mod:`rlgsim.lab.identify.batch_twin`); False: scipy's column by column
BATCH_JACOBIAN = True
#: the batch is cut into this many fixed parts (whatever the number of workers, so the result
#: does not depend on it); each part runs in its own process when workers allow
BATCH_PARTS = 2

#: the batch job of the fit in progress, inherited by forked workers
_JOB: dict = {}


def _batch_part(args: tuple[list[str], list[np.ndarray], int]) -> None:
    """One fixed part of a batch, run in a worker: the residuals at the part's points, written
    into the rows from ``start`` of the shared buffer (:meth:`_Problem.residuals_batch`)."""
    names, xs, start = args
    buf = _JOB["buf"]
    for i, r in enumerate(_JOB["fun"](names, xs)):
        buf[start + i] = r


def _shared_rows(rows: int, cols: int) -> np.ndarray:
    """A (rows, cols) float64 array in anonymous shared memory: a forked worker's writes are
    seen by its parent (the batch's residuals come back without being pickled: 5 MB a
    Jacobian of the 20 h identification, 9 ms of the parent's time each)."""
    import mmap
    mem = mmap.mmap(-1, max(rows * cols, 1) * 8)
    return np.frombuffer(mem, dtype=np.float64, count=rows * cols).reshape(rows, cols)


def _workers() -> int:
    """Processes for the batched Jacobian: the available cores, at most BATCH_PARTS."""
    import os
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:                          # pragma: no cover (not Linux)
        n = os.cpu_count() or 1
    return max(1, min(BATCH_PARTS, n))


def build(data: dict, source: str = "twin") -> tuple[ThermalNetwork, ProbeSet]:
    """Network and probes of a preset dict."""
    ctx = Ctx(source, "")
    net = ThermalNetwork.from_config(data["thermal"], ctx.child("thermal"))
    probes = ProbeSet.from_config(data["probes"], net, ctx.child("probes"))
    return net, probes


def twin_response(network: ThermalNetwork, probes: ProbeSet, air_c: np.ndarray,
                  power: np.ndarray, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Node temperatures (m, n) and noise-free probe readings (m, p) of ``network`` driven by
    the chamber air samples ``air_c`` (m,) at the ends of the steps and the power (m,) held
    over each step, from the equilibrium at ``air_c[0]``."""
    integ = ThermalIntegrator(network, step_s, 0.0)
    st = integ.initial_state(float(air_c[0]), bool(power[0] > 0.5))
    setpoint = np.concatenate(([air_c[0]], air_c))
    states, _ = integ.propagate(st, setpoint, power)
    nodes = np.asarray(states[:, 1:])
    quiet = replace(probes, noise_sigma_c=np.zeros(probes.n_probes),
                    resolution_c=np.zeros(probes.n_probes))
    ps = quiet.initial_state(np.asarray(st)[1:])
    reading, _ = quiet.read(ps, nodes, step_s, np.random.default_rng(0))
    return nodes, reading


class _Problem:
    """The fit's residuals and Jacobians: the template's twin with multipliers on the fit's
    coarser grid (and on the recorded grid for the result), one residual series per probe,
    forward-difference Jacobians batched over processes for a heater network."""

    def __init__(self, template: dict, air_c: np.ndarray, power: np.ndarray, step_s: float,
                 probe_names: tuple[str, ...], probes_c: np.ndarray, *, source: str,
                 workers: int) -> None:
        net0, pr0 = build(template, "thermal template")
        unknown = [n for n in probe_names if n not in pr0.names]
        if unknown:
            raise UserInputError(f"{source}: probe {unknown[0]!r} of the recording is not a probe "
                                 f"of the thermal template (its probes: {', '.join(pr0.names)}); "
                                 f"name the probes as the template does or give another "
                                 f"--thermal-template")
        cols = np.array([pr0.names.index(n) for n in probe_names])
        m_full = air_c.size
        # the fit integrates on a coarser grid (every `coarse` recorded steps): the air is
        # smooth and its first-order hold stays within mK of the full grid's (thermal_fit's
        # docstring); the final twin is on the full grid
        batched = BATCH_JACOBIAN and batchable(net0)
        most = MAX_FIT_STEPS_STEPWISE if batchable(net0) else MAX_FIT_STEPS
        coarse = max(1, int(math.ceil(m_full / most)))
        sel = np.arange(coarse - 1, m_full, coarse)
        air_f, power_f, step_f = air_c[sel], power[sel], step_s * coarse
        m = sel.size
        stride = max(1, int(math.ceil(m * len(probe_names) / MAX_RESIDUALS)))
        rows = np.arange(stride - 1, m, stride)
        obs = probes_c[sel][rows]
        mask = np.isfinite(obs)
        obs0 = np.where(mask, obs, 0.0)
        params = thermal_parameters(template, probe_names)

        self.template, self.air_c, self.power, self.step_s = template, air_c, power, step_s
        self.probe_names, self.probes_c, self.pr0, self.cols = probe_names, probes_c, pr0, cols
        self.air_f, self.power_f, self.step_f, self.batched = air_f, power_f, step_f, batched
        self.rows, self.obs, self.mask, self.obs0 = rows, obs, mask, obs0
        self.params = params
        pool = None
        self.scaled = None
        if batched:                 # compiled once here (numba's cache), before any fork
            from rlgsim.lab.identify import _batch_twin_kernel  # noqa: F401
            from rlgsim.lab.identify.scaled_twin import ScaledTwin
            scaled = ScaledTwin(template, params, build)
            self.scaled = scaled if scaled.ok else None
        if batched and workers > 1:
            import multiprocessing
            _JOB["fun"] = self.residuals_part
            _JOB["buf"] = _shared_rows(len(params) + 1, self.obs.size)
            try:
                pool = multiprocessing.get_context("fork").Pool(workers)
                _JOB["pool"] = pool                      # closed by fit_thermal
            except (ValueError, OSError, AssertionError):   # no fork, or a daemon: one process
                pool = None

        self.pool = pool

    def model(self, mult: dict[str, float], full: bool = False):
        d, _ = apply_multipliers(self.template, self.params, mult)
        net, pr = build(d)
        if full:
            nodes, read = twin_response(net, pr, self.air_c, self.power, self.step_s)
        else:
            nodes, read = twin_response(net, pr, self.air_f, self.power_f, self.step_f)
        return nodes, read[:, self.cols], net, pr, d

    def residual_for(self, names: list[str]):
        """The residual vector as a function of the log-multipliers of ``names``: for a heater
        network through the batched integration the Jacobian uses (:meth:`residuals_part`, one
        set; the same arithmetic as the Jacobian's points), otherwise a full build."""
        if self.batched:
            return lambda x: self.residuals_part(names, [np.asarray(x, dtype=float)])[0]

        def fun(x: np.ndarray) -> np.ndarray:
            _, read, *_ = self.model(dict(zip(names, np.exp(x))))
            r = np.where(self.mask, read[self.rows] - self.obs0, 0.0)
            return r.T.reshape(-1)               # probe-major: one series per probe
        return fun

    def residuals_part(self, names: list[str], xs: list[np.ndarray]) -> list[np.ndarray]:
        """Residual vectors at several points, integrated together (a heater network)."""
        models = []
        for x in xs:
            mult = dict(zip(names, np.exp(x)))
            if self.scaled is not None:          # the template's arrays scaled (scaled_twin)
                models.append(self.scaled.model(mult))
            else:
                models.append(build(apply_multipliers(self.template, self.params, mult)[0]))
        out = []
        for read in twin_readings_batch(models, self.air_f, self.power_f, self.step_f):
            r = np.where(self.mask, read[:, self.cols][self.rows] - self.obs0, 0.0)
            out.append(r.T.reshape(-1))
        return out

    def residuals_batch(self, names: list[str], xs: list[np.ndarray]) -> list[np.ndarray]:
        """The points in BATCH_PARTS fixed parts, in parallel when there is a pool."""
        k = int(math.ceil(len(xs) / BATCH_PARTS))
        if self.pool is not None:      # the rows of the shared buffer, valid until the next call
            buf = _JOB["buf"]
            self.pool.map(_batch_part, [(names, xs[i:i + k], i) for i in range(0, len(xs), k)],
                          chunksize=1)
            return [buf[i] for i in range(len(xs))]
        done = [self.residuals_part(names, xs[i:i + k]) for i in range(0, len(xs), k)]
        return [r for part in done for r in part]

    def fd_jac(self, names: list[str], x: np.ndarray, rel: float, bounded: bool) -> np.ndarray:
        """Forward differences with scipy's 2-point step (``rel·max(1, |x|)``, sign of x,
        reversed at an upper bound), the base point and every column in one batch."""
        x = np.asarray(x, dtype=float)
        h = rel * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
        if bounded:
            h = np.where((x + h > _BOUND) | (x + h < -_BOUND), -h, h)
        pts = [x]
        dx = []
        for j in range(x.size):
            xp = x.copy()
            xp[j] += h[j]
            dx.append(xp[j] - x[j])
            pts.append(xp)
        res = self.residuals_batch(names, pts)
        JT = np.empty((x.size, res[0].size))     # columns as contiguous rows, then transposed:
        for j in range(x.size):                  # the same differences, 2 ms less a Jacobian
            np.divide(np.subtract(res[j + 1], res[0], out=JT[j]), dx[j], out=JT[j])
        return np.ascontiguousarray(JT.T)

    def jac_at(self, names: list[str], x: np.ndarray, h: float = 1e-4) -> np.ndarray:
        if self.batched:
            J = np.empty((self.obs.size, len(names)))
            pts = [x] + [x + h * np.eye(len(names))[j] for j in range(len(names))]
            res = self.residuals_batch(names, pts)
            for j in range(len(names)):
                J[:, j] = (res[j + 1] - res[0]) / h
            return J
        fun = self.residual_for(names)
        r0 = fun(x)
        J = np.empty((r0.size, len(names)))
        for j in range(len(names)):
            xp = x.copy()
            xp[j] += h
            J[:, j] = (fun(xp) - r0) / h
        return J
