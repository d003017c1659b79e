"""Several parameter sets of one thermal network integrated at once (the finite-difference
Jacobian of the thermal fit).

A network with a controlled heater is integrated step by step
(:meth:`rlgsim.sim.thermal.integrator.ThermalIntegrator._stepwise_loop`: the PI controller
reads its sensor at each grid point); the per-step cost there is Python overhead, so ``B``
parameter sets cost almost ``B`` times one. Here the same recurrence runs with the modal
state of every set as one ``(B, n)`` array: one pass over the steps for all columns of the
Jacobian. The arithmetic is the integrator's (the same coefficients, the same update
``w ← μ·w + g + c_h·P`` with the PI law and anti-windup, the power clipped to
``[0, max]``), vectorised over the sets; rounding may differ from the scalar loop in the last
bits, which is why the Jacobian's base point is evaluated in the same batch.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.integrator import ThermalIntegrator
from rlgsim.sim.thermal.thermometers import ProbeSet

__all__ = ["batchable", "twin_readings_batch"]


def batchable(network: ThermalNetwork) -> bool:
    """Networks this module integrates: controlled heaters, no nonlinear links (without
    heaters the integrator's per-mode filters are fast already)."""
    return bool(network.heaters) and not network.nonlinear_links


def _forcing(integ: ThermalIntegrator, s: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Modal forcing g (n, m) of ``_advance`` with ``air_tau_s = 0``."""
    sk, ds = s[:-1], np.diff(s)
    g = np.multiply.outer(integ._c_s, sk)
    g += np.multiply.outer(integ._c_ds, ds)
    g += np.multiply.outer(integ._c_u, u)
    if integ.boundaries:
        m = u.size
        tk = integ.step_s * np.arange(0, m + 1, dtype=float)
        b = integ.network.boundary_temperatures_c(tk)
        db = np.diff(b, axis=0)
        for j in range(b.shape[1]):
            g += np.multiply.outer(integ._c_b[j], b[:-1, j])
            g += np.multiply.outer(integ._c_db[j], db[:, j])
    return g


def twin_readings_batch(models: list[tuple[ThermalNetwork, ProbeSet]], air_c: np.ndarray,
                        power: np.ndarray, step_s: float) -> list[np.ndarray]:
    """Noise-free probe readings (m, p) of each ``(network, probes)`` (same topology, heaters
    and probes; different values) driven as in :func:`rlgsim.lab.identify.thermal_fit.
    twin_response`: chamber air ``air_c`` (m,) at the ends of the steps, linear in between,
    power (m,) held over each step, from the equilibrium at ``air_c[0]``."""
    B = len(models)
    integs = [ThermalIntegrator(net, step_s, 0.0) for net, _ in models]
    powered0 = bool(power[0] > 0.5)
    sts = [it.initial_state(float(air_c[0]), powered0) for it in integs]
    s = np.concatenate(([air_c[0]], air_c)).astype(float)
    u = np.asarray(power, dtype=float)
    m = u.size
    n = integs[0].n_nodes
    H = len(integs[0].heaters)
    # every set's modal state in one flat vector (B·n,); the sensors read it and the heaters
    # feed it through block-diagonal matrices (one matrix-vector product per step for all)
    mu = np.concatenate([it._mu for it in integs])                 # (B·n,)
    g = np.stack([_forcing(it, s, u).T for it in integs], axis=1).reshape(m, B * n)
    CH = np.zeros((B * n, B * H))
    RS = np.zeros((B * H, B * n))
    RT = np.zeros((B * H, B * n))
    for b, it in enumerate(integs):
        CH[b * n:(b + 1) * n, b * H:(b + 1) * H] = it._c_h
        RS[b * H:(b + 1) * H, b * n:(b + 1) * n] = it._r_s
        RT[b * H:(b + 1) * H, b * n:(b + 1) * n] = it._r_t
    kp = np.concatenate([it._h_kp for it in integs])               # (B·H,)
    ki = np.concatenate([it._h_ki for it in integs])
    aw = np.concatenate([it._h_aw for it in integs])
    pmax = np.concatenate([it._h_max for it in integs])
    sp0 = np.concatenate([it._h_sp for it in integs])
    tg = np.concatenate([it._h_tg for it in integs])
    track = bool(np.any(tg != 0.0))
    I = np.concatenate([np.asarray(st.heaters if st.heaters is not None else np.zeros(H),
                                   dtype=float) for st in sts])    # (B·H,)
    w = np.concatenate([np.asarray(st.modal_if_valid()) for st in sts])
    W = np.empty((m, B * n))
    on = (u > 0).tolist()
    ts, e, v, P, tmp = (np.empty(B * H) for _ in range(5))
    sp = sp0.copy()
    for k in range(m):
        wk = W[k]
        np.multiply(mu, w, out=wk)
        wk += g[k]
        if on[k]:
            np.dot(RS, w, out=ts)
            if track:
                np.dot(RT, w, out=sp)
                sp *= tg
                sp += sp0
            np.subtract(sp, ts, out=e)
            np.multiply(kp, e, out=v)
            v += I
            np.maximum(v, 0.0, out=P)
            np.minimum(P, pmax, out=P)
            np.multiply(ki, e, out=tmp)
            I += tmp
            np.subtract(P, v, out=tmp)
            tmp *= aw
            I += tmp
            wk += CH @ P
        else:
            I[:] = 0.0
        w = wk
    W = W.reshape(m, B, n)
    out = []
    for b, ((net, probes), it) in enumerate(zip(models, integs)):
        nodes = W[:, b, :] @ it._to_nodes_T
        quiet = replace(probes, noise_sigma_c=np.zeros(probes.n_probes),
                        resolution_c=np.zeros(probes.n_probes))
        ps = quiet.initial_state(np.asarray(sts[b])[1:])
        reading, _ = quiet.read(ps, nodes, step_s, np.random.default_rng(0))
        out.append(reading)
    return out
