"""Exact discrete-time propagation of the thermal network and the chamber air.

State ``x = [T_air, T_1 … T_n]`` (column 0 the chamber air, docs/architecture.md). Continuous
model (docs/thermal.md, eqs. (1)–(2))::

    τ_air dT_air/dt = s(t) − T_air                      (first-order air lag, τ_air ≥ 0)
    C dT/dt = −K T + g T_air + u(t) P                   (the network, rlgsim.sim.thermal.network)

with the rate-limited chamber setpoint ``s(t)`` linear between grid points (first-order hold,
FOH) and the power state ``u(t)`` constant over each step (zero-order hold, ZOH). Between grid
points this is a linear time-invariant system with polynomial input, so its discrete form is
exact (no Euler, no step-size error):

* Modal decomposition: ``C⁻¹K`` is similar to the symmetric ``S = C^-½ K C^-½ = V Λ Vᵀ``
  (C diagonal, K symmetric positive definite), so the node part splits into ``n`` independent
  real modes ``w = Vᵀ C^½ T`` with ``dw_i/dt = −λ_i w_i + β_i T_air + π_i u``
  (``β = Vᵀ C^-½ g``, ``π = Vᵀ C^-½ P``). The air is one more first-order mode that drives them
  (the coupling is one-way).
* Exact discretisation: for each mode the 5×5 augmented system ``[w, T_air, s, ṡ, u]`` is
  integrated over one step with ``scipy.linalg.expm`` (Van Loan's construction for the FOH
  ramp); this gives per-mode coefficients
  ``w[k+1] = μ w[k] + a_T T_air[k] + a_s s[k] + a_Δ (s[k+1] − s[k]) + a_u u[k]``
  with ``μ = e^{−λh}``, and the same for the air. Computing them with ``expm`` (instead of the
  closed forms, which contain ``(e^{−λh} − e^{−h/τ})/(1/τ − λ)``) stays accurate when a mode's
  rate coincides with the air's.
* Vectorised: each mode is a first-order recurrence, run over the whole block at once by
  :func:`scipy.signal.lfilter` with its internal state ``zi`` carried between calls; node
  temperatures are ``T = C^-½ V w`` (one matrix product per block of rows). Heaters and
  nonlinear links make the input depend on the state: the recurrence then runs step by step
  (:meth:`ThermalIntegrator._stepwise_loop`); for heaters alone in compiled code once numba is
  loaded (:mod:`rlgsim.sim.thermal._heater_kernel`, the same operations and BLAS calls).

Splitting one call into several (carrying the returned state) gives bit-identical results: the
returned state is a :class:`ThermalState` — an ordinary ``(1 + n,)`` array ``[T_air, T_nodes]``
that also carries the modal coordinates, so nothing is lost in a physical ↔ modal round trip
(a plain array works as well; it is then converted to modal coordinates, exact to rounding).
The product with ``C^-½ V`` is done on fixed-shape row blocks so BLAS takes the same path for
every row whatever the call length (a plain ``W @ P`` is not row-independent in OpenBLAS), with
BLAS limited to one thread (threadpoolctl): the products are small, and multi-threaded
OpenBLAS on a busy machine is many times slower than one thread.

Why this file is over 400 lines: it is one solver, the exact propagation of the network: the
modal set-up, the vectorised path and the step-by-step path for the state-dependent inputs
(heaters, nonlinear links, airflow, the chamber's own loop), which share the per-mode
coefficients; the compiled heater loop is apart (_heater_kernel.py).
"""

from __future__ import annotations

import contextlib
import sys
import threading
from typing import Any, Iterator

import numpy as np
import scipy.linalg
import scipy.signal

from rlgsim.sim.thermal.heater_terms import heater_terms
from rlgsim.sim.thermal.network import ThermalNetwork

#: Rows per matrix product when mapping modal to node temperatures (fixed, see module doc).
_ROW_BLOCK = 200
#: Steps per internal chunk of a long propagate call (bounds the temporaries).
_CHUNK = 8000

_controller: Any = None
#: how many ``with`` blocks of :func:`one_blas_thread` are open, in any thread (the BLAS thread
#: count is process-wide too): the limit is applied when the count goes 0 → 1 and restored when
#: it goes 1 → 0, whichever thread that is, so a nested or concurrent ``with`` costs a counter
#: instead of ~0.1 ms of threadpoolctl bookkeeping — a simulation enters it once and
#: propagates 700 blocks inside, and two simulations in threads of one process (Monte Carlo on
#: thread workers) keep the limit until the last one leaves
_users = 0
_limit: Any = None                          # the open threadpoolctl limit, while _users > 0
_users_lock = threading.Lock()


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Limit BLAS/LAPACK to one thread for the duration of a ``with`` block (a no-op without
    threadpoolctl); blocks open at once in any threads share one limit (see ``_users``). The
    controller is built once per process (building it costs ~1 ms)."""
    global _users, _limit
    with _users_lock:
        if _users == 0:
            _limit = _blas_limit()
        _users += 1
    try:
        yield
    finally:
        with _users_lock:
            _users -= 1
            if _users == 0 and _limit is not None:
                _limit.restore_original_limits()
                _limit = None


def _blas_limit() -> Any:
    """A threadpoolctl limit of BLAS to one thread, applied now (``restore_original_limits()``
    undoes it); None without threadpoolctl."""
    global _controller
    if _controller is None:
        try:
            from threadpoolctl import ThreadpoolController
            _controller = ThreadpoolController()
        except Exception:                       # pragma: no cover - optional speed-up only
            _controller = False
    if _controller is False:
        return None
    return _controller.limit(limits=1, user_api="blas")


class ThermalState(np.ndarray):
    """``[T_air, T_1 … T_n]`` [°C] that remembers the integrator's modal coordinates.

    Behaves as a plain float array (slicing, arithmetic and ``np.asarray`` give ordinary
    arrays). :meth:`ThermalIntegrator.propagate` uses ``modal`` when it is present and still
    consistent with the temperatures, which makes split propagation bit-identical.
    """

    modal: np.ndarray | None
    chamber: tuple[float, ...] | None
    time_s: float | None
    heaters: np.ndarray | None
    _check: bytes | None

    def __new__(cls, temperatures: np.ndarray, modal: np.ndarray | None = None,
                chamber: tuple[float, ...] | None = None, time_s: float | None = None,
                heaters: np.ndarray | None = None):
        obj = np.array(temperatures, dtype=float).view(cls)
        obj.modal = None if modal is None else np.array(modal, dtype=float)
        obj.chamber = None if chamber is None else tuple(float(v) for v in chamber)
        obj.time_s = None if time_s is None else float(time_s)
        obj.heaters = None if heaters is None else np.array(heaters, dtype=float)
        obj._check = obj.view(np.ndarray).tobytes() if modal is not None else None
        return obj

    def __array_finalize__(self, obj: Any) -> None:
        # views, copies and results of arithmetic do not inherit the modal coordinates
        self.modal = None
        self.chamber = None
        self.time_s = None
        self.heaters = None
        self._check = None

    def __reduce__(self):
        return (ThermalState, (np.asarray(self), self.modal, self.chamber, self.time_s,
                               self.heaters))

    def modal_if_valid(self) -> np.ndarray | None:
        if self.modal is None or self._check != self.view(np.ndarray).tobytes():
            return None
        return self.modal

    def chamber_if_valid(self) -> tuple[float, ...] | None:
        """The chamber controller's state (:mod:`rlgsim.sim.thermal.chamber_controller`), if any and
        the temperatures were not edited."""
        if self.chamber is None or self._check != self.view(np.ndarray).tobytes():
            return None
        return self.chamber


class ThermalIntegrator:
    """Exact propagation of ``network`` plus chamber air on a grid of ``step_s`` [s].

    ``air_tau_s`` [s] is the chamber-air time constant (0: the air is the setpoint).
    ``controller`` (a :class:`rlgsim.sim.thermal.chamber_controller.ChamberController`, optional)
    replaces the air lag by the chamber's closed air loop: the air is then computed on the grid
    by :class:`~rlgsim.sim.thermal.chamber_controller.ChamberLoop` and drives the network as a
    first-order-hold input (``air_tau_s`` is not used).
    """

    def __init__(self, network: ThermalNetwork, step_s: float, air_tau_s: float,
                 controller: Any = None) -> None:
        with one_blas_thread():
            self._setup(network, step_s, 0.0 if controller is not None else air_tau_s)
        #: run the heater loop compiled (rlgsim.sim.thermal._heater_kernel): True, False, or None
        #: (default) when this process has imported numba already
        self.compiled: bool | None = None
        self._kernel: Any = None
        self._kernel_args: Any = None
        self._kernel_coef: np.ndarray | None = None
        self.chamber_loop = None
        if controller is not None:                 # any kind (chamber_controllers.CONTROLLERS)
            self.chamber_loop = controller.loop(self.step_s)

    def _setup(self, network: ThermalNetwork, step_s: float, air_tau_s: float) -> None:
        if not (np.isfinite(step_s) and step_s > 0):
            raise ValueError("step_s must be > 0")
        if not (np.isfinite(air_tau_s) and air_tau_s >= 0):
            raise ValueError("air_tau_s must be >= 0")
        self.network = network
        self.step_s = float(step_s)
        self.air_tau_s = float(air_tau_s)
        n = network.n_nodes
        self.n_nodes = n
        C = network.capacitance_j_per_k
        d = 1.0 / np.sqrt(C)
        S = d[:, None] * network.stiffness_w_per_k() * d[None, :]
        S = 0.5 * (S + S.T)
        lam, V = np.linalg.eigh(S)
        if np.any(lam <= 0):
            raise ValueError("the network's stiffness is not positive definite")
        self.rates_per_s = lam                                   # λ_i [1/s]
        self._to_modal = V.T * np.sqrt(C)[None, :]               # w = Vᵀ C^½ T
        self._to_nodes_T = np.ascontiguousarray((d[:, None] * V).T)   # T = w @ (C^-½ V)ᵀ
        beta = V.T @ (d * network.ambient_conductance_w_per_k)   # Vᵀ C^-½ g
        pi = V.T @ (d * network.power_w)                         # Vᵀ C^-½ P
        # further boundaries (prescribed temperatures, first-order hold): Vᵀ C^-½ G_b
        self.boundaries = tuple(network.boundaries)
        beta_b = (network.boundary_conductance_w_per_k * d[None, :]) @ V   # (nb, n)
        h = self.step_s
        tau = self.air_tau_s
        # one augmented system per mode: state [w, T_air, s, r, u], r = ds/dt
        M = np.zeros((n, 5, 5))
        M[:, 0, 0] = -lam
        M[:, 0, 4] = 1.0                                         # u enters w with π (=1 here)
        if tau > 0:
            M[:, 0, 1] = 1.0                                     # T_air enters w with β (=1)
            M[:, 1, 1] = -1.0 / tau
            M[:, 1, 2] = 1.0 / tau
        else:
            M[:, 0, 2] = 1.0                                     # T_air ≡ s
        M[:, 2, 3] = 1.0
        E = scipy.linalg.expm(M * h)
        self._mu = E[:, 0, 0].copy()
        if tau > 0:
            self._c_air = beta * E[:, 0, 1]                      # × T_air[k]
        else:
            self._c_air = np.zeros(n)
        self._c_s = beta * E[:, 0, 2]                            # × s[k]
        self._c_ds = beta * E[:, 0, 3] / h                       # × (s[k+1] − s[k])
        self._c_u = pi * E[:, 0, 4]                              # × u[k]
        if beta_b.shape[0]:
            if tau > 0:                  # the FOH coefficients of an input without lag
                M0 = np.zeros((n, 5, 5))
                M0[:, 0, 0] = -lam
                M0[:, 0, 2] = 1.0
                M0[:, 2, 3] = 1.0
                E0 = scipy.linalg.expm(M0 * h)
            else:
                E0 = E
            self._c_b = beta_b * E0[None, :, 0, 2]               # × T_b[k]
            self._c_db = beta_b * E0[None, :, 0, 3] / h          # × (T_b[k+1] − T_b[k])
        else:
            self._c_b = self._c_db = np.zeros((0, n))
        self._setup_state_terms(network, d, V, E, h)   # heaters, nonlinear links, airflow
        #: heater powers [W] (m, H) of the last propagate call (a record for the caller)
        self.last_heater_power_w = np.zeros((0, len(self.heaters)))
        #: further boundaries' temperatures [°C] (m, nb) at the ends of the last call's steps
        self.last_boundary_c = np.zeros((0, len(self.boundaries)))
        if tau > 0:
            self._air_mu = float(E[0, 1, 1])
            self._air_s = float(E[0, 1, 2])
            self._air_ds = float(E[0, 1, 3] / h)
        else:
            self._air_mu = self._air_s = self._air_ds = 0.0

    def _setup_state_terms(self, network: ThermalNetwork, d: np.ndarray, V: np.ndarray,
                           E: np.ndarray, h: float) -> None:
        """The coefficients of the inputs that depend on the state — controlled heaters,
        nonlinear link parts, airflow over the ambient links — from the modal basis (``d`` =
        C^-½, ``V`` the eigenvectors, ``E`` the per-mode step exponentials, ``h`` the step)."""
        # controlled heaters: ZOH power into their node, sensors read from the modal state
        self.heaters = tuple(network.heaters)
        self._heat = heater_terms(self.heaters, d, V, E[:, 0, 4], h) if self.heaters else None
        # nonlinear link parts (exact radiation, natural convection): their residual heat is
        # evaluated at each grid point and held over the step (exponential Euler)
        self.nonlinear_links = tuple(network.nonlinear_links)
        if self.nonlinear_links:
            inv = sorted({ln.a for ln in self.nonlinear_links}
                         | {ln.b for ln in self.nonlinear_links if ln.b >= 0})
            nodes_map = d[:, None] * V
            self._nl_rows = nodes_map[inv]                                  # (ni, n)
            self._nl_cols = (V.T[:, inv] * d[inv][None, :]) * E[:, 0, 4][:, None]   # (n, ni)
            self._nl_ends = [(inv.index(ln.a), inv.index(ln.b) if ln.b >= 0 else ln.b, ln)
                             for ln in self.nonlinear_links]
            self._nl_n = len(inv)
        # airflow over the ambient links (a vehicle's bay, sim/thermal/vehicle_bay.py): the
        # ambient conductances scaled by φ(t) through the residual heat (φ − 1)·g·(T_air − T),
        # evaluated at each grid point and held over the step (exponential Euler, as above)
        g_amb = np.asarray(network.ambient_conductance_w_per_k, dtype=float)
        inv_f = np.flatnonzero(g_amb > 0)
        self._film_rows = (d[:, None] * V)[inv_f]                            # (nf, n)
        self._film_cols = (V.T[:, inv_f] * d[inv_f][None, :]) * E[:, 0, 4][:, None]  # (n, nf)
        self._film_g = g_amb[inv_f]

    # ----------------------------------------------------------------- states

    @property
    def node_names(self) -> tuple[str, ...]:
        return self.network.node_names

    def time_constants_s(self) -> np.ndarray:
        """Node-mode time constants ``1/λ`` [s], longest first."""
        return np.sort(1.0 / self.rates_per_s)[::-1]

    def state(self, air_c: float, node_temps_c: Any, time_s: float = 0.0) -> ThermalState:
        """A state from chamber-air and node temperatures [°C] at run time ``time_s`` [s]
        (the time matters only for further boundaries with a periodic temperature)."""
        T = np.asarray(node_temps_c, dtype=float).reshape(-1)
        if T.shape != (self.n_nodes,):
            raise ValueError(f"expected {self.n_nodes} node temperatures, got {T.shape}")
        w = self._to_modal @ T
        chamber = None
        if self.chamber_loop is not None:
            chamber = (float(air_c),) + self.chamber_loop.initial_state(float(air_c))[1:]
        return ThermalState(np.concatenate(([float(air_c)], self._nodes(w[None, :])[0])), w,
                            chamber, time_s)

    def initial_state(self, ambient_c: float, powered: bool) -> ThermalState:
        """Equilibrium at constant chamber air ``ambient_c`` [°C] with the power on/off:
        ``[T_air, T_nodes]`` (a :class:`ThermalState`). With a chamber controller the loop is
        settled at the setpoint ``ambient_c`` in its periodic ripple state (the air column holds
        the air at ``t0``, within the ripple of ``ambient_c``)."""
        if self.chamber_loop is None:
            st = self.state(ambient_c, self.network.steady_state(ambient_c, powered), 0.0)
            if self.heaters:
                st.heaters = self.network.steady_heater_power_w(ambient_c, powered)
            return st
        chamber = self.chamber_loop.initial_state(float(ambient_c))
        T = self.network.steady_state(ambient_c, powered)
        w = self._to_modal @ T
        heaters = (self.network.steady_heater_power_w(ambient_c, powered) if self.heaters
                   else None)
        return ThermalState(np.concatenate(([chamber[0]], self._nodes(w[None, :])[0])), w,
                            chamber, 0.0, heaters)

    def _nodes(self, W: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Node temperatures (m, n) from modal rows (m, n), in fixed-shape row blocks (into
        ``out`` (m, n) when given)."""
        m, n = W.shape
        if out is None:
            out = np.empty((m, n))
        with one_blas_thread():             # a counter inside a simulation's run
            self._node_blocks(W, out)
        return out

    def _node_blocks(self, W: np.ndarray, out: np.ndarray) -> None:
        m, n = W.shape
        buf = np.zeros((_ROW_BLOCK, n))
        res = np.empty((_ROW_BLOCK, n))
        for r0 in range(0, m, _ROW_BLOCK):
            r1 = min(m, r0 + _ROW_BLOCK)
            buf[: r1 - r0] = W[r0:r1]
            if r1 - r0 < _ROW_BLOCK and r0 > 0:       # (the first block's tail is zero)
                buf[r1 - r0:] = 0.0
            np.matmul(buf, self._to_nodes_T, out=res)
            out[r0:r1] = res[: r1 - r0]

    # ----------------------------------------------------------------- dataset record

    def extra_rows(self) -> dict[str, np.ndarray]:
        """The dataset rows of the optional parts for the last :meth:`propagate` call:
        ``heater_power`` (m, heaters) [W] held over each step and ``boundary_temperature``
        (m, boundaries) [°C] at each step's end, only for the parts the network has (declared
        by :func:`rlgsim.sim.writer.schema.declare_thermal_parts`)."""
        out: dict[str, np.ndarray] = {}
        if self.heaters:
            out["heater_power"] = self.last_heater_power_w.copy()
        if self.boundaries:
            out["boundary_temperature"] = self.last_boundary_c.copy()
        return out

    # ----------------------------------------------------------------- propagation

    def propagate(self, state: Any, setpoint_c: Any, power_on: Any, t0_s: float | None = None,
                  film_factor: Any = None, chamber_noise: Any = None
                  ) -> tuple[np.ndarray, ThermalState]:
        """Advance ``m`` steps exactly.

        ``state``: ``[T_air, T_nodes]`` at ``t0`` (from :meth:`initial_state` or a previous
        call); ``setpoint_c`` (m+1,): rate-limited setpoint at ``t0 … t0 + m·h`` [°C], linear in
        between (FOH); ``power_on`` (m,): power state held over each step (ZOH; 0/1 or a
        fraction). Returns ``states`` (m, 1+n) at ``t0 + h … t0 + m·h`` (column 0 chamber air)
        and the last state (a :class:`ThermalState`). ``t0_s``: run time at the state [s],
        needed only by further boundaries with a periodic temperature (default: the time the
        state carries, 0 for a plain array). ``film_factor`` (m,): φ − 1 per step, the airflow's
        scaling of every ambient conductance held over the step (a vehicle's bay; None: none).
        ``chamber_noise`` (m·n_sub, 2): the chamber loop's standard normal draws per controller
        sample (:meth:`~rlgsim.sim.thermal.chamber_controller.ChamberLoop.run`; None: none).
        """
        s = np.asarray(setpoint_c, dtype=float).reshape(-1)
        u = np.asarray(power_on, dtype=float).reshape(-1)
        m = s.size - 1
        if m < 0 or u.size != m:
            raise ValueError(f"setpoint_c needs m+1 values and power_on m values, got "
                             f"{s.size} and {u.size}")
        x0 = np.asarray(state, dtype=float).reshape(-1)
        n = self.n_nodes
        if x0.shape != (1 + n,):
            raise ValueError(f"state must have {1 + n} entries, got {x0.shape}")
        w0 = state.modal_if_valid() if isinstance(state, ThermalState) else None
        if w0 is None:
            w0 = self._to_modal @ x0[1:]
        chamber = None
        if self.chamber_loop is not None:
            chamber = state.chamber_if_valid() if isinstance(state, ThermalState) else None
            if chamber is None:        # a plain array: the loop settled at its air (phase 0)
                chamber = self.chamber_loop.initial_state(float(x0[0]))
                chamber = (float(x0[0]),) + chamber[1:]
        # the run time as a whole number of steps (bit-identical split calls)
        if t0_s is None:
            t0_s = state.time_s if isinstance(state, ThermalState) else None
            t0_s = 0.0 if t0_s is None else t0_s
        k_start = int(round(float(t0_s) / self.step_s))
        hstate = None
        if self.heaters:
            hstate = state.heaters if isinstance(state, ThermalState) else None
            if hstate is None or np.shape(hstate) != (len(self.heaters),):
                hstate = np.zeros(len(self.heaters))     # controllers start from rest
            hstate = np.array(hstate, dtype=float)
        self.last_heater_power_w = np.zeros((max(m, 0), len(self.heaters)))
        self.last_boundary_c = np.zeros((max(m, 0), len(self.boundaries)))
        if m == 0:
            return np.empty((0, 1 + n)), ThermalState(x0, w0, chamber, k_start * self.step_s,
                                                      hstate)
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(u))):
            raise ValueError("setpoint and power must be finite")
        film = None
        if film_factor is not None:
            film = np.asarray(film_factor, dtype=float).reshape(-1)
            if film.size != m or not np.all(np.isfinite(film)) or np.any(film < -1.0):
                raise ValueError(f"film_factor needs {m} finite values >= -1")
        states = np.empty((m, 1 + n))
        air, w = float(x0[0]), w0
        # long calls run in fixed chunks (bounded temporaries; bit-identical by construction)
        for k0 in range(0, m, _CHUNK):
            k1 = min(m, k0 + _CHUNK)
            sk = s[k0:k1 + 1]
            if self.chamber_loop is not None:
                # the closed air loop gives the air on the grid; it drives the nodes (FOH)
                if chamber_noise is None:
                    air_next, chamber = self.chamber_loop.run(chamber, sk)
                else:
                    per = self.chamber_loop.n_sub
                    air_next, chamber = self.chamber_loop.run(
                        chamber, sk, chamber_noise[k0 * per:k1 * per])
                sk = np.concatenate(([air], air_next))
            bk = None
            if self.boundaries:
                tk = self.step_s * np.arange(k_start + k0, k_start + k1 + 1, dtype=float)
                bk = self.network.boundary_temperatures_c(tk)          # (len, nb)
                self.last_boundary_c[k0:k1] = bk[1:]
            air, w, hstate = self._advance(air, w, sk, u[k0:k1], states[k0:k1], bk, hstate,
                                           self.last_heater_power_w[k0:k1],
                                           None if film is None else film[k0:k1])
        return states, ThermalState(states[-1], w, chamber, (k_start + m) * self.step_s,
                                    hstate)

    def _advance(self, air0: float, w0: np.ndarray, s: np.ndarray, u: np.ndarray,
                 out: np.ndarray, b: np.ndarray | None = None, hstate: Any = None,
                 hpower: Any = None, film: np.ndarray | None = None
                 ) -> tuple[float, np.ndarray, Any]:
        """Propagate ``len(u)`` steps from chamber air ``air0`` and modal state ``w0`` into
        ``out`` (m, 1+n); return the final air temperature and modal state."""
        n = self.n_nodes
        m = u.size
        sk, ds = s[:-1], np.diff(s)
        # chamber air: air[k+1] = μa air[k] + ca s[k] + cd Δs[k]
        if self.air_tau_s > 0:
            forcing = self._air_s * sk + self._air_ds * ds
            air_next, _ = scipy.signal.lfilter([1.0], [1.0, -self._air_mu], forcing,
                                               zi=[self._air_mu * air0])
            air_k = np.concatenate(([air0], air_next[:-1]))      # air at t_k, k = 0..m-1
        else:
            air_next = s[1:]
            air_k = sk
        # modal forcing g_i[k] = Σ_t c_t[i]·x_t[k] (n, m), summed in this order, then one
        # first-order recurrence per mode
        terms = [(self._c_s, sk), (self._c_ds, ds), (self._c_u, u)]
        if self.air_tau_s > 0:
            terms.append((self._c_air, air_k))
        if b is not None:                    # further boundaries: element-wise (no BLAS)
            db = np.diff(b, axis=0)
            for j in range(b.shape[1]):
                terms.append((self._c_b[j], b[:-1, j]))
                terms.append((self._c_db[j], db[:, j]))
        # modal rows by step (m, n): the stepwise loop writes one contiguous row per step
        W = np.empty((m, n)).T
        done = None
        if self.heaters and not self.nonlinear_links and film is None:
            done = self._compiled_heater_loop(w0, terms, u, W, hstate, hpower)
        if done is not None:
            hstate = done
        else:
            g = np.multiply.outer(*terms[0])
            for c, x in terms[1:]:
                g += np.multiply.outer(c, x)
            if self.heaters or self.nonlinear_links or film is not None:
                hstate = self._stepwise_loop(w0, g, u, W, hstate, hpower, air_k,
                                             None if b is None else b[:-1], film)
            else:
                for i in range(n):
                    W[i], _ = scipy.signal.lfilter([1.0], [1.0, -self._mu[i]], g[i],
                                                   zi=[self._mu[i] * w0[i]])
        out[:, 0] = air_next
        self._nodes(W.T, out[:, 1:])
        return float(out[-1, 0]), W[:, -1].copy(), hstate

    def _compiled_heater_loop(self, w0: np.ndarray, terms: list, u: np.ndarray,
                              W: np.ndarray, integ: Any, power_out: Any) -> np.ndarray | None:
        """:meth:`_stepwise_loop` for heaters without nonlinear links in compiled code
        (:mod:`rlgsim.sim.thermal._heater_kernel`, bit-identical), the modal forcing summed from
        ``terms`` ``[(c_t (n,), x_t (m,))]`` inside; the controllers' integrator states, or
        None when it is not used:
        ``compiled`` False, or None (the default) and numba not yet imported by this process
        (importing it costs more than a short run saves), or the kernel unavailable."""
        use = self.compiled
        if use is None:
            use = "numba" in sys.modules
        if not use:
            return None
        if self._kernel is None:
            try:
                from rlgsim.sim.thermal._heater_kernel import kernel
                self._kernel = kernel() or False
            except ImportError:
                self._kernel = False
        if self._kernel is False:
            return None
        if w0.ndim != 1 or w0.dtype != np.float64 or w0.strides[0] <= 0 or \
                w0.strides[0] % 8:            # numpy would not call BLAS: keep its loop
            return None
        H = len(self.heaters)
        n = w0.size
        aux = self._kernel_args
        if aux is None:
            ht = self._heat
            aux = self._kernel_args = (
                np.ascontiguousarray(ht.sensor_rows), np.ascontiguousarray(ht.track_rows),
                np.ascontiguousarray(ht.cols.T), ht.kp.copy(), ht.ki.copy(), ht.aw.copy(),
                ht.max_power.copy(), ht.setpoint.copy(), ht.track_gain.copy(),
                bool(np.any(ht.track_gain != 0.0)))
        rs, rt, cols, kp, ki, aw, pmax, sp0, tg, track = aux
        coef = self._kernel_coef
        if coef is None or coef.shape[0] != len(terms):
            coef = np.array([c for c, _ in terms], dtype=float)
            if len(terms) <= 4:               # no boundaries: the same every call
                self._kernel_coef = coef
        inputs = np.empty((len(terms), u.size))
        for t, (_, x) in enumerate(terms):
            inputs[t] = x
        integ = np.array(integ, dtype=float)
        on = np.asarray(u) > 0
        self._kernel(self._mu, w0, w0.strides[0] // 8, coef, inputs, on, W.T,
                     np.empty((n, 2)), rs, rt, track, cols, kp, ki, aw, pmax, sp0, tg, integ,
                     power_out, np.empty(H), np.empty(H))
        return integ

    def _stepwise_loop(self, w0: np.ndarray, g: np.ndarray, u: np.ndarray, W: np.ndarray,
                       integ: Any, power_out: Any, air_k: np.ndarray,
                       b_k: np.ndarray | None, film: np.ndarray | None = None) -> np.ndarray:
        """The modal recurrence step by step, for inputs that depend on the state
        (docs/thermal.md §1.2b-c): at each grid point the heaters' PI controllers read their
        sensors and set powers limited to [0, max], and the nonlinear link parts give their
        residual heat; both are held over the step (exact ZOH propagation of a constant input;
        for the nonlinear residual this is the exponential Euler method). ``film`` (m,) φ − 1
        per step: the airflow's residual heat over the ambient links, held likewise."""
        mu = self._mu
        H = len(self.heaters)
        if H:
            ht = self._heat
            rs, rt = ht.sensor_rows, ht.track_rows
            cols = [np.ascontiguousarray(ht.cols[:, j]) for j in range(H)]
            kp, ki, aw, pmax = (ht.kp.tolist(), ht.ki.tolist(), ht.aw.tolist(),
                                ht.max_power.tolist())
            sp0, tg = ht.setpoint.tolist(), ht.track_gain.tolist()
            track = any(x != 0.0 for x in tg)
            I = [float(x) for x in integ]
            heat = [np.empty_like(w0) for _ in range(H)]   # cols[j]·P for the last P used
            heat_p = [None] * H
        else:
            I = []
        nl = bool(self.nonlinear_links)
        if nl:
            from rlgsim.sim.thermal.network_parts import nonlinear_flow_w
            rows, ncols, ends = self._nl_rows, self._nl_cols, self._nl_ends
            q = np.zeros(self._nl_n)
        # The per-step Python overhead is the cost here (hundreds of thousands of steps in a
        # long run): each step's modal state is computed in place in its own contiguous row
        # of W.T (no copies), the powered flags are read as Python values, and a heater's
        # heat vector cols[j]·P is recomputed only when P changes (a saturated or idle heater
        # holds it for hours) — the same floating-point operations in the same order.
        film_k = None if film is None else np.asarray(film).tolist()
        film_rows, film_cols, film_g = self._film_rows, self._film_cols, self._film_g
        WT = W.T
        gT = np.ascontiguousarray(g.T)
        on = (np.asarray(u) > 0).tolist()
        # the sensors and nonlinear ends read the state through a strided vector, as they
        # always did: numpy's matrix-vector product of a one-row matrix rounds differently for
        # a contiguous vector (another kernel), and the stored bytes must not change
        scratch = np.empty((w0.size, 2))
        read = scratch[:, 0]
        ws = w0
        wr = w0
        for k in range(g.shape[1]):
            dq = None
            if nl:                              # residual heat at the start of the step
                tn = (rows @ wr).tolist()
                q[:] = 0.0
                for ia, ib, ln in ends:
                    if ib >= 0:
                        tb = tn[ib]
                    elif ib == -1:
                        tb = float(air_k[k])
                    else:
                        tb = float(b_k[k, -2 - ib])
                    f = float(nonlinear_flow_w(ln, tn[ia], tb))
                    q[ia] -= f
                    if ib >= 0:
                        q[ib] += f
                dq = ncols @ q
            powered = on[k]
            if H and powered:
                ts = (rs @ wr).tolist()
                tt = (rt @ wr).tolist() if track else None
            w = WT[k]
            np.multiply(mu, ws, out=w)
            w += gT[k]
            if dq is not None:
                w += dq
            if film_k is not None and film_k[k] != 0.0:     # the airflow over ambient links
                tf = film_rows @ wr
                w += film_cols @ ((film_k[k] * film_g) * (float(air_k[k]) - tf))
            if H:
                if powered:
                    for j in range(H):
                        sp = sp0[j] + tg[j] * tt[j] if track else sp0[j]
                        e = sp - ts[j]
                        v = kp[j] * e + I[j]
                        P = pmax[j] if v > pmax[j] else (0.0 if v < 0.0 else v)
                        I[j] = I[j] + ki[j] * e + aw[j] * (P - v)
                        power_out[k, j] = P
                        if P != 0.0:
                            if heat_p[j] != P:
                                np.multiply(cols[j], P, out=heat[j])
                                heat_p[j] = P
                            w += heat[j]
                else:                           # unpowered: controller off and reset
                    for j in range(H):
                        I[j] = 0.0
                        power_out[k, j] = 0.0
            ws = w
            read[:] = w
            wr = read
        return np.array(I) if H else integ
