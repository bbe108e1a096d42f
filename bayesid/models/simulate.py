"""Batched simulation: a vehicle, a manoeuvre and B coefficient vectors in, B tracks out.

The expensive part is one call of the compiled kernel :func:`bayesid.models.dynamics.simulate_batch`;
everything that does not change between calls (active terms, scales, inputs) is prepared once in
:class:`Simulator`, so an optimiser or a sampler pays only for the integration.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numba
import numpy as np

from .._numba import use_package_threading_layer
from ..data import terms
from ..data.track import INPUT_NAMES, STATE_NAMES, Track
from . import codegen, dynamics

MODES = ("6dof", "horizontal")
_PLANE = [0, 1, 5]  # u, v, r rows/columns of the mass matrix


@dataclass(frozen=True)
class Manoeuvre:
    """Input time history on the integration grid.

    Parameters
    ----------
    name : str
        Short id, e.g. ``"spiral"``.
    dt : float
        Integration step, s; input k is held over [k*dt, (k+1)*dt).
    inputs : array_like, shape (n_steps, 4)
        ``delta_r, delta_s, delta_b`` (rad), ``n`` (rpm); finite.
    initial_state : array_like, shape (12,)
        State at t = 0; finite.
    description : str, default ""
        The exact sequence in words (for reports).
    parameters : dict
        The generator's parameters (JSON-serialisable).

    Raises
    ------
    ValueError
        Inputs of another shape or not finite (naming channel and step), an initial state that
        is not 12 finite numbers, a non-positive step.
    """

    name: str
    dt: float
    inputs: np.ndarray
    initial_state: np.ndarray
    description: str = ""
    parameters: dict = field(default_factory=dict)

    def __post_init__(self):
        inp = np.asarray(self.inputs, dtype=float)
        if inp.ndim != 2 or inp.shape[1] != 4:
            raise ValueError(f"manoeuvre {self.name}: inputs must be (n_steps, 4), got {inp.shape}")
        for j, ch in enumerate(INPUT_NAMES):
            bad = np.flatnonzero(~np.isfinite(inp[:, j]))
            if bad.size:
                raise ValueError(
                    f"manoeuvre {self.name}: input {ch} is not finite at step {bad[0]} (t = {bad[0] * self.dt:g} s)"
                )
        s0 = np.asarray(self.initial_state, dtype=float)
        if s0.shape != (12,) or not np.all(np.isfinite(s0)):
            raise ValueError(f"manoeuvre {self.name}: initial_state must be 12 finite numbers")
        if not (self.dt > 0):
            raise ValueError(f"manoeuvre {self.name}: dt must be positive")
        object.__setattr__(self, "inputs", np.ascontiguousarray(inp))
        object.__setattr__(self, "initial_state", s0)

    @property
    def n_steps(self) -> int:
        """Number of integration steps (rows of ``inputs``)."""
        return self.inputs.shape[0]

    @property
    def t(self) -> np.ndarray:
        """(n_steps + 1,) times of the states, s."""
        return np.arange(self.n_steps + 1) * self.dt

    @property
    def duration(self) -> float:
        """Length of the manoeuvre, s."""
        return self.n_steps * self.dt


@dataclass
class SimResult:
    """Output of one batched simulation.

    Parameters
    ----------
    t : ndarray, shape (n_samples,)
        Sample times, s.
    states : ndarray, shape (B, n_samples, 12)
        States, NaN after a divergence.
    inputs : ndarray, shape (n_samples, 4)
        The input applied from each sample time on.
    status : ndarray of int64, shape (B,)
        0 ok, 1 non-finite, 2 out of physical bounds.
    fail_step : ndarray of int64, shape (B,)
        First diverged step of each track, or -1.
    name : str, default ""
        The manoeuvre's name.
    """

    t: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    status: np.ndarray
    fail_step: np.ndarray
    name: str = ""

    @property
    def diverged(self) -> np.ndarray:
        """(B,) bool."""
        return self.status != dynamics.OK

    def track(self, b: int = 0, name: str | None = None) -> Track:
        """One simulated track as a :class:`~bayesid.data.track.Track`.

        Parameters
        ----------
        b : int, default 0
            Index of the track in the batch.
        name : str, optional
            Track name; default the manoeuvre's.

        Returns
        -------
        Track
            All 12 states and the 4 inputs.
        """
        data = {n: self.states[b, :, i].copy() for i, n in enumerate(STATE_NAMES)}
        data.update({n: self.inputs[:, j].copy() for j, n in enumerate(INPUT_NAMES)})
        return Track(self.t.copy(), data, name=name if name is not None else self.name)


class Simulator:
    """Prepared simulation of one manoeuvre for a vehicle with some coefficients free.

    Attributes ``n_tracks`` and ``sim_seconds`` count the work done (for the SQP monitor).

    Parameters
    ----------
    vehicle : Vehicle
        The :class:`~bayesid.data.vehicle.Vehicle`; its coefficients are the fixed values.
    manoeuvre : Manoeuvre
        The manoeuvre simulated.
    free : sequence of str, default ()
        Names of the coefficients that :meth:`run` sets per track (SNAME names).
    mode : {"6dof", "horizontal"}, default "6dof"
        ``"horizontal"``: paper Sec. 4, only surge, sway, yaw evolve.
    sample_every : int, default 1
        Store every k-th integration step; must divide the number of steps.
    kernel : {"generated", "interpreted"}, default "generated"
        ``"generated"``: a right-hand side generated for this model's active terms
        (:mod:`bayesid.models.codegen`); ``"interpreted"``: the term-table loop of
        :mod:`bayesid.models.dynamics`, the baseline and test oracle. Same equations, results
        equal to round-off.

    Raises
    ------
    UnknownCoefficientError
        A free name not in the term library.
    ValueError
        Bad mode or kernel; a free name given twice; ``sample_every`` not dividing the steps;
        horizontal mode with non-zero w, p, q, phi or theta initially, a free coefficient outside
        the horizontal plane, or stern or bow planes moving.
    """

    def __init__(
        self,
        vehicle,
        manoeuvre: Manoeuvre,
        free=(),
        mode: str = "6dof",
        sample_every: int = 1,
        kernel: str = "generated",
    ):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if kernel not in codegen.KINDS:
            raise ValueError(f"kernel must be one of {codegen.KINDS}, got {kernel!r}")
        free = list(free)
        terms.check_names(free, "free coefficients")
        if len(set(free)) != len(free):
            raise ValueError(f"duplicate free coefficient names in {free}")
        s0 = manoeuvre.initial_state.copy()
        if mode == "horizontal":
            bad = [STATE_NAMES[i] for i in (3, 4, 8, 9, 10) if s0[i] != 0.0]
            if bad:
                raise ValueError(f"horizontal mode needs {', '.join(bad)} = 0 initially")
            for name in free:
                if not terms.term(name).horizontal:
                    raise ValueError(f"coefficient {name} does not act in the horizontal plane")
            planes = np.flatnonzero(np.any(manoeuvre.inputs[:, 1:3] != 0.0, axis=0))
            if planes.size:
                raise ValueError(
                    f"manoeuvre {manoeuvre.name}: horizontal mode ignores stern and bow "
                    f"planes, but {INPUT_NAMES[1 + planes[0]]} is non-zero; use mode='6dof'"
                )
        self.vehicle, self.manoeuvre, self.mode = vehicle, manoeuvre, mode
        self.free = free
        self.sample_every = int(sample_every)
        if self.sample_every < 1 or manoeuvre.n_steps % self.sample_every:
            raise ValueError(f"sample_every={sample_every} must divide n_steps={manoeuvre.n_steps}")
        self.s0 = s0
        self.base = vehicle.coefficient_vector()  # (n_terms,) prime
        free_set = set(free)
        self.force_names = [
            t.name
            for t in terms.TERMS
            if t.kind == "force"
            and (self.base[terms.INDEX[t.name]] != 0.0 or t.name in free_set)
            and (mode == "6dof" or t.horizontal)
        ]
        # free terms the vehicle lacks (a discovery candidate): a generated kernel takes them at
        # run time, so one compile serves every candidate (codegen.Open)
        self.further_names = [n for n in self.force_names if self.base[terms.INDEX[n]] == 0.0]
        # term encoding of the interpreted kernels (closed-loop manoeuvres use them directly)
        self.tfac, self.tdof = terms.factor_table(self.force_names)
        self.kernel_kind = kernel
        self._kernel = None
        self.tscale = terms.prime_scale(self.force_names, vehicle.rho, vehicle.L)
        self.force_idx = np.array([terms.INDEX[n] for n in self.force_names], dtype=np.int64)
        self._free_idx = np.array([terms.INDEX[n] for n in free], dtype=np.int64)
        self._am = [(terms.INDEX[n], terms.term(n)) for n in terms.names_where(kind="added_mass")]
        self._M0 = vehicle.mass_matrix({})  # rigid body only
        self._am_scale = np.array([0.5 * vehicle.rho * vehicle.L**t.L_power for _, t in self._am])
        self.vp = dynamics.vehicle_params(vehicle)
        self.xs, self.ws = dynamics.crossflow_strips(vehicle)
        self.n_samples = manoeuvre.n_steps // self.sample_every + 1
        self.t = manoeuvre.t[:: self.sample_every]
        self.inputs_sampled = np.vstack([manoeuvre.inputs, manoeuvre.inputs[-1:]])[:: self.sample_every]
        self.n_tracks = 0
        self.sim_seconds = 0.0

    def __getstate__(self):
        """Pickle (joblib, Dask, deepcopy) without the compiled kernel module; it is loaded again
        from the cache on first use."""
        state = dict(self.__dict__)
        state["_kernel"] = None
        return state

    @property
    def kernel(self):
        """The compiled drivers for this model's active terms and mode
        (:func:`bayesid.models.codegen.kernel`; generated on first use; the free terms the
        vehicle lacks are taken at run time, :class:`bayesid.models.codegen.Open`)."""
        if self._kernel is None:
            self._kernel = codegen.kernel(self.force_names, self.mode, self.kernel_kind, self.further_names)
        return self._kernel

    def coefficient_matrix(self, theta_free=None) -> np.ndarray:
        """Full prime coefficient vectors: the vehicle's values with the free ones replaced.

        Parameters
        ----------
        theta_free : array_like, shape (B, P) or (P,), optional
            Values of the free coefficients; None (or no free coefficients) keeps the vehicle's.

        Returns
        -------
        ndarray, shape (B, n_terms)
            The coefficient vectors (B = 1 without ``theta_free``).

        Raises
        ------
        ValueError
            When ``theta_free`` has another number of columns than free coefficients.
        """
        if theta_free is None or len(self.free) == 0:
            return self.base[None, :].copy()
        th = np.atleast_2d(np.asarray(theta_free, dtype=float))
        if th.shape[1] != len(self.free):
            raise ValueError(f"theta_free has {th.shape[1]} columns for {len(self.free)} free coefficients")
        C = np.repeat(self.base[None, :], th.shape[0], axis=0)
        C[:, self._free_idx] = th
        return C

    def mass_matrices(self, C: np.ndarray) -> np.ndarray:
        """Mass matrices ``M_RB - M_A`` of prime coefficient vectors.

        Parameters
        ----------
        C : ndarray, shape (B, n_terms)
            Prime coefficient vectors (:meth:`coefficient_matrix`).

        Returns
        -------
        ndarray, shape (B, 6, 6)
            The mass matrices, SI.
        """
        M = np.repeat(self._M0[None], C.shape[0], axis=0)
        for (idx, t), sc in zip(self._am, self._am_scale):
            M[:, t.dof, t.accel] -= sc * C[:, idx]
        return M

    def inverse_mass_matrices(self, C: np.ndarray, M: np.ndarray | None = None) -> np.ndarray:
        """Inverse mass matrices (restricted to u, v, r in horizontal mode).

        A singular mass matrix gives NaN entries, which the kernel flags as a divergence.

        Parameters
        ----------
        C : ndarray, shape (B, n_terms)
            Prime coefficient vectors.
        M : ndarray, shape (B, 6, 6), optional
            The mass matrices; default :meth:`mass_matrices` of ``C``.

        Returns
        -------
        ndarray, shape (B, 6, 6)
            The inverses (zero outside the u, v, r block in horizontal mode).
        """
        if M is None:
            M = self.mass_matrices(C)
        B = M.shape[0]
        Minv = np.zeros((B, 6, 6))
        if self.mode == "horizontal":
            sub = M[:, _PLANE][:, :, _PLANE]
            inv = _safe_inv(sub)
            for a, i in enumerate(_PLANE):
                for c, j in enumerate(_PLANE):
                    Minv[:, i, j] = inv[:, a, c]
        else:
            Minv[:] = _safe_inv(M)
        return Minv

    def kernel_arrays(self, theta_free=None) -> tuple[np.ndarray, np.ndarray]:
        """What the compiled kernels take per track.

        Parameters
        ----------
        theta_free : array_like, shape (B, P) or (P,), optional
            Values of the free coefficients (:meth:`coefficient_matrix`).

        Returns
        -------
        tcoef : ndarray, shape (B, n_force_terms)
            Dimensional force-term coefficients.
        Minv : ndarray, shape (B, 6, 6)
            Inverse mass matrices.
        """
        C = self.coefficient_matrix(theta_free)
        return np.ascontiguousarray(C[:, self.force_idx] * self.tscale), self.inverse_mass_matrices(C)

    def run(self, theta_free=None, initial_states=None) -> SimResult:
        """Simulate one track per row of ``theta_free`` -- or the vehicle as is.

        Never raises on divergence: diverged tracks are flagged in ``status`` and NaN-filled.

        Parameters
        ----------
        theta_free : array_like, shape (B, P) or (P,), optional
            Values of the free coefficients; None simulates the vehicle as is (B = 1).
        initial_states : array_like, shape (B, 12) or (12,), optional
            Initial states; default the manoeuvre's.

        Returns
        -------
        SimResult
            The B tracks.
        """
        tcoef, Minv = self.kernel_arrays(theta_free)
        B = tcoef.shape[0]
        s0 = (
            np.repeat(self.s0[None], B, axis=0)
            if initial_states is None
            else np.ascontiguousarray(np.broadcast_to(initial_states, (B, 12)), dtype=float)
        )
        out = np.empty((B, self.n_samples, 12))
        status = np.empty(B, dtype=np.int64)
        fail = np.empty(B, dtype=np.int64)
        tic = time.perf_counter()
        # No more threads than tracks: an idle worker has nothing to do (with the OpenMP layer
        # it even busy-waits and steals CPU from a single track; bayesid selects workqueue).
        use_package_threading_layer()
        n_threads = numba.get_num_threads()
        numba.set_num_threads(max(1, min(B, numba.config.NUMBA_NUM_THREADS)))
        try:
            self.kernel.simulate_batch(
                s0,
                self.manoeuvre.inputs,
                self.manoeuvre.dt,
                self.sample_every,
                self.vp,
                tcoef,
                Minv,
                self.xs,
                self.ws,
                out,
                status,
                fail,
            )
        finally:
            numba.set_num_threads(n_threads)
        self.sim_seconds += time.perf_counter() - tic
        self.n_tracks += B
        return SimResult(self.t, out, self.inputs_sampled, status, fail, name=self.manoeuvre.name)


def _safe_inv(M: np.ndarray) -> np.ndarray:
    out = np.full(M.shape, np.nan)
    ok = np.isfinite(M).all(axis=(1, 2))
    ok[ok] = np.abs(np.linalg.det(M[ok])) > 1e-300
    if ok.any():
        out[ok] = np.linalg.inv(M[ok])
    return out


def simulate(vehicle, manoeuvre: Manoeuvre, mode: str = "6dof", sample_every: int = 1) -> SimResult:
    """Simulate the vehicle as it is (B = 1). See :class:`Simulator`.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.
    manoeuvre : Manoeuvre
        The manoeuvre.
    mode : {"6dof", "horizontal"}, default "6dof"
        Degrees of freedom.
    sample_every : int, default 1
        Store every k-th integration step.

    Returns
    -------
    SimResult
        The one track.
    """
    return Simulator(vehicle, manoeuvre, (), mode, sample_every).run()
