"""Thermal grey-box identification: the template's network with a few physically meaningful
multipliers fitted so the twin's probes follow the recorded ones, given the recorded chamber
air and power state.

Parameters (derived from the template's structure, each a multiplier ``m = exp(x)`` of design
values, so a parameter is always positive and ``x`` is its relative change):

==========================================  ===================================================
``<template>.capacity``                     every node capacity of every instance of a template
                                            (the gyro block's glass, discharge, ballasts, board)
``<template>.power``                        its heat sources (discharge, ballasts, pre-amplifier)
``<template>.power.<node>``                 each source but the largest on its own (ballast
                                            against ballast: a real block's arm asymmetry)
``<template>.internal_conductance``         links between its own nodes (the glass web, bonds)
``<template>.<port>_conductance``           its links to a port (``air``: its faces to the
                                            cabinet; ``mount``: the dither mount and standoffs)
``<node>.capacity``, ``<node>.power``       a top-level node (housing, electronics)
``chamber_air_conductance``                 every link to the chamber air (the convection and
                                            radiation of the housing, a mounting flange)
``internal_conductance``                    the other top-level links
``probe_lag.<group or point>``              the lag ``tau_s`` of a probe group or point
==========================================  ===================================================

The network topology is the template's; the multipliers are written back into the preset in
its own vocabulary (instance ``capacitance_factors`` / ``power_factors`` / ``link_factors``,
scaled masses, volumes, areas and conductances of top-level nodes and links, probe ``tau_s``),
so the fitted preset is an ordinary thermal preset that :func:`ThermalNetwork.from_config`
reads — the same text the fit evaluated.

Model of a recording: :class:`~rlgsim.sim.thermal.integrator.ThermalIntegrator` with the
recorded chamber air as its input (``air_tau_s = 0``: the air *is* the input, piecewise linear
between its samples, the integrator's exact first-order hold) and the recorded power state
(held over each step), from the equilibrium at the first air sample; the probe lags of
:class:`~rlgsim.sim.thermal.thermometers.ProbeSet` without noise or quantisation. During the fit the
network is integrated on a grid of at most 15,000 steps, 2,500 for a network with a
controlled heater (every k-th recorded sample, linear in between: the integrator's exact
first-order hold of those samples; the air is smooth, and a heater's PI controller then acts
every k·step seconds: for trplg_001_cabinet through the 20 h programme of
benchmarks/bench_identify.py, 29 s steps against the 1 s integration differ by at most 7 mK in
a probe reading, 0.35 mK RMS — 10 s steps: 0.8 mK, 0.04 mK — beside probe residuals of
27–140 mK RMS after the fit; its fastest mode 7.7 s) and at most 10,000 probe residuals are
used (every j-th grid point, 87 s apart there): the probes' lags and the network's time
constants make neighbouring samples redundant — the residuals' lag-one correlation is still
0.76 at 87 s, and the standard errors, from batch means, are those of the 30 s spacing to
2 %. The final twin runs on the recorded grid. Residuals are
twin − recorded probe readings (missing readings carry zero weight). Fit:
:func:`rlgsim.estimators.identify.lsq_stats.fit` on the log-multipliers; identifiability:
:func:`rlgsim.estimators.identify.lsq_stats.screen` first at the template (Jacobian at ``x = 0``),
then at the solution, where a parameter that ran to its bound (a factor 10 either way) or whose
log-multiplier has a standard error above 1 (more than a factor e) is refused too; a refused
parameter keeps the template's value and the reason is
reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from rlgsim.estimators.identify.lsq_stats import LsqFit, fit, screen
from rlgsim.estimators.identify.quantisation import quantised_intervals, quantised_scores
from rlgsim.lab.identify.thermal_params import (CHAMBER_AIR, ThermalParam, apply_multipliers,
                                                thermal_parameters)
from rlgsim.lab.identify.thermal_problem import (_BOUND, _JOB, _Problem, _workers, build,
                                                 twin_response)
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.thermometers import ProbeSet

__all__ = ["ThermalParam", "ThermalFit", "thermal_parameters", "apply_multipliers",
           "build", "twin_response", "fit_thermal", "CHAMBER_AIR"]

@dataclass
class ThermalFit:
    """Result: ``fitted`` preset dict and its ``changes``; the fitted parameters (``fit``,
    log-multipliers) and ``multipliers`` with relative standard errors; ``refused``
    {parameter: reason}; per-probe RMS of the twin at the template and after the fit;
    the twin's ``nodes_c`` and ``network``/``probes``."""

    params: list[ThermalParam]
    fit: LsqFit | None
    multipliers: dict[str, float]
    rel_se: dict[str, float]
    refused: dict[str, str]
    probe_names: tuple[str, ...]
    rms_template_c: dict[str, float]
    rms_fitted_c: dict[str, float]
    fitted: dict
    changes: dict
    network: ThermalNetwork
    probes: ProbeSet
    nodes_c: np.ndarray
    probe_fit_c: np.ndarray
    notes: list[str] = field(default_factory=list)
    #: standard errors of the log-multipliers from the probes' error model alone
    #: (:func:`rlgsim.estimators.identify.quantisation.quantised_covariance`); ``rel_se`` is
    #: the larger of these and the batch-means sandwich (``fit.se``)
    se_quantised: dict = field(default_factory=dict)
    #: half-widths of the log-multipliers' central 68.3 % and 95.4 % intervals (the coverage
    #: of ±1 and ±2 standard deviations of a Gaussian): the wider of the batch-means
    #: sandwich's Gaussian ±1, ±2 ``fit.se`` and the percentile interval of the probes' error
    #: model (:func:`rlgsim.estimators.identify.quantisation.quantised_intervals`), whose error
    #: is flatter than Gaussian
    interval_68: dict = field(default_factory=dict)
    interval_95: dict = field(default_factory=dict)


#: largest standard error of a log-multiplier still reported as identified (a factor e)
MAX_LOG_SE = 1.0


def _undetermined(res: LsqFit, names: list[str]) -> tuple[int, str] | None:
    """A parameter that ended on its bound or whose standard error exceeds a factor e."""
    at_bound = np.flatnonzero(np.abs(np.abs(res.x) - _BOUND) < 1e-6)
    if at_bound.size:
        i = int(at_bound[np.argmax(res.se[at_bound])])
        return i, (f"the fit ran to its bound (×{math.exp(res.x[i]):.3g} of the template): the "
                   f"recording does not determine it")
    i = int(np.argmax(res.se))
    if res.se[i] > MAX_LOG_SE:
        return i, (f"standard error of its logarithm {res.se[i]:.2f} > {MAX_LOG_SE:g} (more than "
                   f"a factor e): the recording does not determine it")
    return None


SCALE_REASON = ("multiplying every capacity, conductance and heat source by one factor leaves "
                "every temperature unchanged (divide the heat equation by it): the overall scale "
                "is invisible in temperatures; the capacities (masses and materials of the "
                "design) are the best known of the three, so this one keeps the template's "
                "value and the other multipliers are relative to it")


def _overall_scale(names: list[str], residual: Callable[[list[str], np.ndarray], np.ndarray]
                   ) -> int | None:
    """Index of the capacity parameter to keep at the template when the recording cannot see
    the network's overall scale, else ``None``.

    Tested exactly rather than through the Jacobian's conditioning (whose near-degeneracies
    would pick an arbitrary member): every capacity, conductance and heat-source multiplier
    (not the probe lags nor the single-source refinements, which are relative to their
    template's block-wide source) × 1.01 must change no probe reading by more than 10⁻⁷ °C. It holds
    for a network of capacities, linear links, constant sources and fixed-temperature
    boundaries; a controlled heater or a nonlinear link breaks it, and then nothing is pinned
    here (the screen still refuses what the recording cannot separate). The capacity pinned
    is the first one (the gyro block's, for a template with one)."""
    # not the probe lags, nor the single-source refinements (relative to the block-wide one)
    scale = [i for i, n in enumerate(names)
             if not n.startswith("probe_lag.") and ".power." not in n]
    caps = [i for i in scale if n_is_capacity(names[i])]
    if not caps:
        return None
    x = np.zeros(len(names))
    r0 = residual(names, x)
    x[scale] = math.log(1.01)
    if np.max(np.abs(residual(names, x) - r0)) > 1e-7:
        return None
    return caps[0]


def n_is_capacity(name: str) -> bool:
    return name.endswith(".capacity")


def fit_thermal(template: dict, air_c: np.ndarray, power: np.ndarray, step_s: float,
                probe_names: tuple[str, ...], probes_c: np.ndarray, *, source: str = "",
                max_corr: float = 0.99, workers: int | None = None) -> ThermalFit:
    """Fit the multipliers of ``template`` (a thermal preset dict) to the recorded probes
    ``probes_c`` (m, p) named ``probe_names`` (module docstring). ``workers``: processes for
    the batched Jacobian of a heater network (default: up to 2 of the available cores; the
    result does not depend on it)."""
    if workers is None:
        workers = _workers()
    try:
        return _fit_thermal(template, air_c, power, step_s, probe_names, probes_c,
                            source=source, max_corr=max_corr, workers=workers)
    finally:
        if _JOB.get("pool") is not None:
            _JOB["pool"].terminate()
            _JOB["pool"].join()
        _JOB.clear()


def _optional(names: list[str]) -> list[bool]:
    """Which parameters the screen may drop first (the heat sources' powers)."""
    return [n.count(".power.") > 0 for n in names]


def _fit_thermal(template: dict, air_c: np.ndarray, power: np.ndarray, step_s: float,
                 probe_names: tuple[str, ...], probes_c: np.ndarray, *, source: str,
                 max_corr: float, workers: int) -> ThermalFit:
    pb = _Problem(template, air_c, power, step_s, probe_names, probes_c, source=source,
                  workers=workers)
    free, refused = _screen_at_template(pb, max_corr)
    res = _fit_screened(pb, free, refused, max_corr)
    return _result(pb, res, free, refused)


def _screen_at_template(pb: _Problem, max_corr: float) -> tuple[list[str], dict[str, str]]:
    """The free parameters after the overall-scale pin and the screen at the template."""
    free = [p.name for p in pb.params]
    refused: dict[str, str] = {}
    pin = _overall_scale(free, lambda names, x: pb.residual_for(names)(x))
    if pin is not None:
        refused[free[pin]] = SCALE_REASON
        free.pop(pin)
    J = pb.jac_at(free, np.zeros(len(free)))
    while free:
        s = screen(J, free, max_corr=max_corr, optional=_optional(free))
        if s is None:
            break
        i, why = s
        refused[free[i]] = why + " (at the template)"
        free.pop(i)
        J = np.delete(J, i, axis=1)
    return free, refused


def _fit_screened(pb: _Problem, free: list[str], refused: dict[str, str], max_corr: float):
    """Fit ``free`` (refusing in place, one refusal per refit, until the screen passes at the
    fitted values); the last fit, or None when nothing is left free."""
    res = None
    x = np.zeros(len(free))
    # one refusal per refit, until the screen passes: every refusal is followed by a fit on
    # the remaining parameters, so the estimates are always those of the reported set (the
    # loop used to stop after 8 fits and could pair the last fit's values with a set that
    # had lost one more name)
    while True:
        if not free:
            res = None
            break
        names = list(free)
        res = fit(pb.residual_for(free), x, free, bounds=(-_BOUND, _BOUND),
                  segments=len(pb.probe_names), diff_step=1e-6, batches=8,
                  jac=(lambda x, names=names: pb.fd_jac(names, x, 1e-6, True)) if pb.batched
                  else None)
        s = (screen(res.jac, free, max_corr=max_corr, optional=_optional(free))
             or _undetermined(res, free))
        if s is None:
            break
        i, why = s
        refused[free[i]] = why + " (at the fitted values)"
        x = np.delete(res.x, i)
        free.pop(i)
    return res


def _result(pb: _Problem, res, free: list[str], refused: dict[str, str]) -> ThermalFit:
    """The fitted twin on the recorded grid, its standard errors and the probes' RMS."""
    template, params, probe_names, probes_c = pb.template, pb.params, pb.probe_names, pb.probes_c
    assert res is None or list(res.names) == free
    mult = dict(zip(free, np.exp(res.x))) if res is not None else {}
    rel_se = dict(zip(free, res.se)) if res is not None else {}
    se_q: dict = {}
    i68: dict = {}
    i95: dict = {}
    if res is not None:
        # the probes' own error model (resolution, noise) carried through the Jacobian; the
        # reported standard error is the larger of it and the batch means (which also see
        # what the error model does not: a template family that cannot follow the unit)
        _, read_fit, *_ = pb.model(mult)
        scores, a_inv = quantised_scores(res.jac, read_fit[pb.rows], pb.mask,
                                         pb.pr0.noise_sigma_c[pb.cols],
                                         pb.pr0.resolution_c[pb.cols])
        cq = a_inv @ (scores.T @ scores / scores.shape[0]) @ a_inv
        se_q = dict(zip(free, np.sqrt(np.clip(np.diag(cq), 0, None))))
        rel_se = {k: max(v, se_q[k]) for k, v in rel_se.items()}
        h68, h95 = quantised_intervals(scores, a_inv)
        i68 = {k: max(float(res.se[j]), float(h68[j])) for j, k in enumerate(free)}
        i95 = {k: max(2.0 * float(res.se[j]), float(h95[j])) for j, k in enumerate(free)}
    nodes, fitted_read, net, pr, fitted = pb.model(mult, full=True)
    _, template_read, *_ = pb.model({}, full=True)
    fitted, changes = apply_multipliers(template, params, mult)

    def rms(pred):
        out = {}
        for j, n in enumerate(probe_names):
            d = pred[:, j] - probes_c[:, j]
            d = d[np.isfinite(d)]
            out[n] = float(np.sqrt(np.mean(d ** 2))) if d.size else float("nan")
        return out
    return ThermalFit(params=params, fit=res, multipliers=mult, rel_se=rel_se, refused=refused,
                      probe_names=tuple(probe_names), rms_template_c=rms(template_read),
                      rms_fitted_c=rms(fitted_read), fitted=fitted, changes=changes,
                      network=net, probes=pr, nodes_c=nodes, probe_fit_c=fitted_read,
                      se_quantised=se_q, interval_68=i68, interval_95=i95)
