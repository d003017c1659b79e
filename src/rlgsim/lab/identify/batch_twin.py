"""Several parameter sets of one thermal network integrated at once (the finite-difference
Jacobian of the thermal fit).

A network with a controlled heater is integrated step by step
(:meth:`rlgsim.sim.thermal.integrator.ThermalIntegrator._stepwise_loop`: the PI controller
reads its sensor at each grid point); the per-step cost there is Python overhead, so ``B``
parameter sets cost almost ``B`` times one. Here the same recurrence runs with the modal
state of every set as one ``(B, n)`` array: one pass over the steps for all columns of the
Jacobian, compiled (:mod:`rlgsim.lab.identify._batch_twin_kernel`; the NumPy loop
:func:`_loop_numpy` is its reference). The arithmetic is the integrator's (the same
coefficients, the same update ``w ← μ·w + g + c_h·P`` with the PI law and anti-windup, the
power clipped to ``[0, max]``), per set; rounding may differ from the scalar loop in the last
bits, which is why the Jacobian's base point is evaluated in the same batch.
"""

from __future__ import annotations

import numpy as np

from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.integrator import ThermalIntegrator
from rlgsim.sim.thermal.thermometers import ProbeSet

__all__ = ["batchable", "twin_readings_batch"]


def batchable(network: ThermalNetwork) -> bool:
    """Networks this module integrates: controlled heaters, no nonlinear links (without
    heaters the integrator's per-mode filters are fast already)."""
    return bool(network.heaters) and not network.nonlinear_links


def _forcing_coef(integ: ThermalIntegrator) -> np.ndarray:
    """The modal forcing's coefficients ``coef`` (nt, n) of ``_advance`` with ``air_tau_s = 0``
    (``g_ik = Σ_t coef[t, i]·inputs[t, k]``, summed in the order of ``t``): the setpoint, its
    step, the power, then each boundary and its step."""
    coef = [integ._c_s, integ._c_ds, integ._c_u]
    for j in range(len(integ.boundaries)):
        coef += [integ._c_b[j], integ._c_db[j]]
    return np.array(coef, dtype=float)


def _forcing_inputs(integ: ThermalIntegrator, s: np.ndarray, u: np.ndarray) -> np.ndarray:
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


def _shared_inputs(integs: list[ThermalIntegrator], s: np.ndarray, u: np.ndarray
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


def _stacked(models: list[tuple[ThermalNetwork, ProbeSet]], air_c: np.ndarray,
             power: np.ndarray, step_s: float) -> tuple[list, list, dict]:
    """The integrators and initial states of every set, and their coefficients stacked over the
    sets: ``mu``/``w0`` (B, n), the forcing's ``coef`` (B, nt, n), its distinct ``inputs`` (U,
    nt, m) and each set's row of them ``src`` (B,) (:func:`_shared_inputs`), ``ch`` (B, n, H),
    ``rs``/``rt`` (B, H, n), the controller constants (B, H), ``integ`` (B, H), ``on`` (m,)
    bool, ``track`` bool."""
    integs = [ThermalIntegrator(net, step_s, 0.0) for net, _ in models]
    powered0 = bool(power[0] > 0.5)
    sts = [it.initial_state(float(air_c[0]), powered0) for it in integs]
    s = np.concatenate(([air_c[0]], air_c)).astype(float)
    u = np.asarray(power, dtype=float)
    H = len(integs[0].heaters)
    inputs, src = _shared_inputs(integs, s, u)
    c = {"mu": np.stack([it._mu for it in integs]),
         "w0": np.stack([np.asarray(st.modal_if_valid(), dtype=float) for st in sts]),
         "coef": np.stack([_forcing_coef(it) for it in integs]),
         "inputs": inputs, "src": src,
         "ch": np.stack([it._c_h for it in integs]),
         "rs": np.stack([it._r_s for it in integs]),
         "rt": np.stack([it._r_t for it in integs]),
         "kp": np.stack([it._h_kp for it in integs]),
         "ki": np.stack([it._h_ki for it in integs]),
         "aw": np.stack([it._h_aw for it in integs]),
         "pmax": np.stack([it._h_max for it in integs]),
         "sp0": np.stack([it._h_sp for it in integs]),
         "tg": np.stack([it._h_tg for it in integs]),
         "integ": np.stack([np.asarray(st.heaters if st.heaters is not None else np.zeros(H),
                                       dtype=float) for st in sts]),
         "on": u > 0}
    c["track"] = bool(np.any(c["tg"] != 0.0))
    return integs, sts, c


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
    integs, sts, c = _stacked(models, air_c, power, step_s)
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
                   probes.initial_state(np.asarray(sts[b])[1:]), a, cl, probes._lagged(),
                   np.zeros(P), np.zeros(P), reading, new_state)
        out.append(reading)
    return out
