"""Several parameter sets of one thermal network integrated at once (the finite-difference
Jacobian of the thermal fit).

A network with a controlled heater is integrated step by step
(:meth:`rlgsim.sim.thermal.integrator.ThermalIntegrator._stepwise_loop`: the PI controller
reads its sensor at each grid point); the per-step cost there is Python overhead, so ``B``
parameter sets cost almost ``B`` times one. Here the same recurrence runs with the modal
state of every set as one ``(B, n)`` array: one pass over the steps for all columns of the
Jacobian, compiled (:mod:`rlgsim.lab.identify._batch_twin_kernel`; the NumPy loop
:func:`_loop_numpy` is its reference). The arithmetic is the integrator's (its coefficients —
computed here for all sets from one batched eigendecomposition and the closed-form exponential
weights, :func:`_coefficients`, equal to the integrator's to a few ε — and the same update
``w ← μ·w + g + c_h·P`` with the PI law and anti-windup, the power clipped to ``[0, max]``),
per set; rounding differs from the scalar loop in the last bits, which is why the fit's
residuals are evaluated by this module too (one set) and the Jacobian's base point in the
same batch.
"""

from __future__ import annotations

import numpy as np

from rlgsim.sim.thermal.heater_terms import heater_terms
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.thermometers import ProbeSet

__all__ = ["batchable", "twin_readings_batch"]


def batchable(network: ThermalNetwork) -> bool:
    """Networks this module integrates: controlled heaters, no nonlinear links (without
    heaters the integrator's per-mode filters are fast already)."""
    return bool(network.heaters) and not network.nonlinear_links


def _forcing_coef(integ: _Coefs) -> np.ndarray:
    """The modal forcing's coefficients ``coef`` (nt, n) of ``_advance`` with ``air_tau_s = 0``
    (``g_ik = Σ_t coef[t, i]·inputs[t, k]``, summed in the order of ``t``): the setpoint, its
    step, the power, then each boundary and its step."""
    coef = [integ._c_s, integ._c_ds, integ._c_u]
    for j in range(len(integ.boundaries)):
        coef += [integ._c_b[j], integ._c_db[j]]
    return np.array(coef, dtype=float)


def _forcing_inputs(integ: _Coefs, s: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The forcing's inputs (nt, m) in the order of :func:`_forcing_coef`: the setpoint ``s``
    (m + 1,), its step, the power ``u`` (m,), each boundary's temperature and its step."""
    inputs = [s[:-1], np.diff(s), u]
    if integ.boundaries:
        m = u.size
        tk = integ.step_s * np.arange(0, m + 1, dtype=float)
        b = integ.network.boundary_temperatures_c(tk)
        db = np.diff(b, axis=0)
        for j in range(b.shape[1]):
            inputs += [b[:-1, j], db[:, j]]
    return np.array(inputs, dtype=float)


def _shared_inputs(integs: list[_Coefs], s: np.ndarray, u: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The distinct forcing inputs (U, nt, m) and each set's row ``src`` (B,): the sets of a
    Jacobian share their boundaries (the same objects, scaled_twin.py), so their inputs are
    computed once; sets with other boundary objects get their own."""
    rows: list[np.ndarray] = []
    keys: list[tuple] = []
    src = np.empty(len(integs), dtype=np.int64)
    for b, it in enumerate(integs):
        key = tuple(id(x) for x in it.boundaries)
        if key not in keys:
            keys.append(key)
            rows.append(_forcing_inputs(it, s, u))
        src[b] = keys.index(key)
    return np.stack(rows), src


def _phi(lam: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The exact first-order-hold weights of a mode ``dw/dt = −λ·w + f(t)`` over a step ``h``
    [s]: ``a = ∫₀ʰ e^{−λ(h−t)} dt = (1 − e^{−λh})/λ`` (a constant input) and
    ``b = ∫₀ʰ e^{−λ(h−t)}·t/h dt = (h − a)/(λh)`` (an input's ramp over the step), i.e.
    ``a = h·φ₁(−λh)``, ``b = h·φ₂(−λh)`` with φ₁(z) = (eᶻ − 1)/z, φ₂(z) = (eᶻ − 1 − z)/z²
    (e.g. Hochbruck & Ostermann, *Exponential integrators*, Acta Numerica 2010, §2). The
    integrator takes the same entries from the exponential of each mode's augmented 5 × 5
    matrix (:class:`rlgsim.sim.thermal.integrator.ThermalIntegrator`); here they are closed
    forms, with the Taylor series of φ₂ where ``λh < 1e-2`` (its cancellation; five terms,
    truncation below (λh)⁵/720 < 2e-13)."""
    z = lam * h
    a = -np.expm1(-z) / lam
    small = z < 1e-2
    zs = np.where(small, z, 0.0)
    series = 0.5 - zs / 6.0 + zs ** 2 / 24.0 - zs ** 3 / 120.0 + zs ** 4 / 720.0
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.where(small, h * series, (h - a) / np.where(small, 1.0, z))
    return a, b


class _Coefs:
    """One parameter set's step coefficients: the same quantities, named as
    :class:`~rlgsim.sim.thermal.integrator.ThermalIntegrator` names them (``air_tau_s = 0``,
    controlled heaters, no nonlinear links, no airflow), from one batched eigendecomposition
    (:func:`_coefficients`) instead of an integrator per set — the integrator's setup (its
    5 × 5 exponentials, 17 a network) was most of the batched Jacobian's cost at the fit's
    30 s steps — and the equilibrium at the first air sample (``T0`` nodes, ``heaters0`` W)."""

    network: ThermalNetwork
    step_s: float
    boundaries: tuple


def _coefficients(nets: list[ThermalNetwork], step_s: float, air0: float, powered0: bool
                  ) -> list[_Coefs]:
    """Step coefficients of each network (:class:`_Coefs`): ``S = C^-½ K C^-½ = V Λ Vᵀ``,
    ``μ = e^{−λh}``, the forcing weights of the setpoint (chamber air), its ramp, the power
    and each boundary from :func:`_phi`, and the heaters' terms in the modal basis
    ``w = Vᵀ C^½ T`` (:func:`rlgsim.sim.thermal.heater_terms.heater_terms`, the integrator's own
    function, with the closed-form ZOH weight ``a``) — the integrator's formulae."""
    h = float(step_s)
    C = np.stack([np.asarray(n.capacitance_j_per_k, dtype=float) for n in nets])
    d = 1.0 / np.sqrt(C)
    K = np.stack([n.stiffness_w_per_k() for n in nets])
    S = d[:, :, None] * K * d[:, None, :]
    S = 0.5 * (S + np.swapaxes(S, 1, 2))
    lam, V = np.linalg.eigh(S)
    if np.any(lam <= 0):
        raise ValueError("the network's stiffness is not positive definite")
    a, b = _phi(lam, h)
    out = []
    for k, net in enumerate(nets):
        c = _Coefs()
        c.network, c.step_s, c.boundaries = net, h, tuple(net.boundaries)
        Vk, dk = V[k], d[k]
        beta = Vk.T @ (dk * net.ambient_conductance_w_per_k)
        pi = Vk.T @ (dk * net.power_w)
        beta_b = (net.boundary_conductance_w_per_k * dk[None, :]) @ Vk
        c._mu = np.exp(-lam[k] * h)
        c._c_s, c._c_ds, c._c_u = beta * a[k], beta * b[k], pi * a[k]
        c._c_b, c._c_db = beta_b * a[k][None, :], beta_b * b[k][None, :]
        nodes_map = dk[:, None] * Vk
        c._to_nodes_T = np.ascontiguousarray(nodes_map.T)
        c._heat = heater_terms(net.heaters, dk, Vk, a[k], h)
        c.T0 = net.steady_state(air0, powered0)
        c.heaters0 = np.asarray(net.steady_heater_power_w(air0, powered0), dtype=float)
        c.w0 = (Vk.T * np.sqrt(C[k])[None, :]) @ c.T0
        out.append(c)
    return out


def _stacked(models: list[tuple[ThermalNetwork, ProbeSet]], air_c: np.ndarray,
             power: np.ndarray, step_s: float) -> tuple[list, dict]:
    """The coefficients of every set (:func:`_coefficients`) and the same stacked over the
    sets: ``mu``/``w0`` (B, n), the forcing's ``coef`` (B, nt, n), its distinct ``inputs`` (U,
    nt, m) and each set's row of them ``src`` (B,) (:func:`_shared_inputs`), ``ch`` (B, n, H),
    ``rs``/``rt`` (B, H, n), the controller constants (B, H), ``integ`` (B, H), ``on`` (m,)
    bool, ``track`` bool."""
    powered0 = bool(power[0] > 0.5)
    integs = _coefficients([net for net, _ in models], step_s, float(air_c[0]), powered0)
    s = np.concatenate(([air_c[0]], air_c)).astype(float)
    u = np.asarray(power, dtype=float)
    inputs, src = _shared_inputs(integs, s, u)
    c = {"mu": np.stack([it._mu for it in integs]),
         "w0": np.stack([it.w0 for it in integs]),
         "coef": np.stack([_forcing_coef(it) for it in integs]),
         "inputs": inputs, "src": src,
         "ch": np.stack([it._heat.cols for it in integs]),
         "rs": np.stack([it._heat.sensor_rows for it in integs]),
         "rt": np.stack([it._heat.track_rows for it in integs]),
         "kp": np.stack([it._heat.kp for it in integs]),
         "ki": np.stack([it._heat.ki for it in integs]),
         "aw": np.stack([it._heat.aw for it in integs]),
         "pmax": np.stack([it._heat.max_power for it in integs]),
         "sp0": np.stack([it._heat.setpoint for it in integs]),
         "tg": np.stack([it._heat.track_gain for it in integs]),
         "integ": np.stack([it.heaters0 for it in integs]),
         "on": u > 0}
    c["track"] = bool(np.any(c["tg"] != 0.0))
    return integs, c


def _loop_numpy(c: dict) -> np.ndarray:
    """The recurrence in NumPy (the reference of the compiled
    :func:`rlgsim.lab.identify._batch_twin_kernel.batch_heater_loop`): every set's modal
    state in one flat vector (B·n,), the sensors reading it and the heaters feeding it through
    block-diagonal matrices (one matrix-vector product per step for all sets). Modal states
    (B, m, n); ``c["integ"]`` is updated."""
    B, n = c["mu"].shape
    m = c["inputs"].shape[2]
    H = c["kp"].shape[1]
    mu = c["mu"].reshape(-1)
    g = np.empty((m, B, n))
    for b in range(B):                  # numpy's outer products summed in the order of t
        inp = c["inputs"][c["src"][b]]
        gb = np.multiply.outer(inp[0], c["coef"][b, 0])
        for t in range(1, c["coef"].shape[1]):
            gb += np.multiply.outer(inp[t], c["coef"][b, t])
        g[:, b, :] = gb
    g = g.reshape(m, B * n)
    CH = np.zeros((B * n, B * H))
    RS = np.zeros((B * H, B * n))
    RT = np.zeros((B * H, B * n))
    for b in range(B):
        CH[b * n:(b + 1) * n, b * H:(b + 1) * H] = c["ch"][b]
        RS[b * H:(b + 1) * H, b * n:(b + 1) * n] = c["rs"][b]
        RT[b * H:(b + 1) * H, b * n:(b + 1) * n] = c["rt"][b]
    kp, ki, aw, pmax, sp0, tg = (c[k].reshape(-1) for k in ("kp", "ki", "aw", "pmax", "sp0",
                                                            "tg"))
    track = c["track"]
    I = c["integ"].reshape(-1).copy()
    w = c["w0"].reshape(-1).copy()
    W = np.empty((m, B * n))
    on = c["on"].tolist()
    ts, e, v, P, tmp = (np.empty(B * H) for _ in range(5))
    sp = sp0.copy()
    for k in range(m):
        wk = W[k]
        if on[k]:                       # the sensors read the state before the step
            np.dot(RS, w, out=ts)
            if track:
                np.dot(RT, w, out=sp)
                sp *= tg
                sp += sp0
        np.multiply(mu, w, out=wk)
        wk += g[k]
        if on[k]:
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
    c["integ"][...] = I.reshape(B, H)
    return np.ascontiguousarray(W.reshape(m, B, n).transpose(1, 0, 2))


def _loop_compiled(c: dict) -> np.ndarray:
    """The recurrence in compiled code (:mod:`rlgsim.lab.identify._batch_twin_kernel`):
    modal states (B, m, n); ``c["integ"]`` is updated."""
    from rlgsim.lab.identify._batch_twin_kernel import batch_heater_loop
    B, n = c["mu"].shape
    W = np.empty((B, c["inputs"].shape[2], n))
    batch_heater_loop(c["mu"], c["w0"], c["coef"], c["inputs"], c["src"], c["on"], c["ch"],
                      c["rs"], c["rt"], c["track"],
                      c["kp"], c["ki"], c["aw"], c["pmax"], c["sp0"], c["tg"], c["integ"], W)
    return W


def twin_readings_batch(models: list[tuple[ThermalNetwork, ProbeSet]], air_c: np.ndarray,
                        power: np.ndarray, step_s: float, compiled: bool = True
                        ) -> list[np.ndarray]:
    """Noise-free probe readings (m, p) of each ``(network, probes)`` (same topology, heaters
    and probes; different values) driven as in :func:`rlgsim.lab.identify.thermal_fit.
    twin_response`: chamber air ``air_c`` (m,) at the ends of the steps, linear in between,
    power (m,) held over each step, from the equilibrium at ``air_c[0]``. ``compiled``: the
    numba kernel (default) or the NumPy reference loop."""
    from rlgsim.sim.thermal._probe_kernel import read_block
    integs, c = _stacked(models, air_c, power, step_s)
    W = _loop_compiled(c) if compiled else _loop_numpy(c)
    out = []
    for b, ((net, probes), it) in enumerate(zip(models, integs)):
        # only the probed nodes' temperatures, read as ProbeSet.read reads them without noise
        # or resolution (its compiled block: the same operations; its normal draws × 0 add 0)
        probed = W[b] @ np.ascontiguousarray(it._to_nodes_T[:, probes.node_index])
        a, cl = probes._coefficients(float(step_s))
        P = probes.n_probes
        reading, new_state = np.zeros((probed.shape[0], P)), np.empty((2, P))
        read_block(probed, np.arange(P, dtype=np.int64),
                   probes.initial_state(it.T0), a, cl, probes._lagged(),
                   np.zeros(P), np.zeros(P), reading, new_state)
        out.append(reading)
    return out
