"""Output-error identification: fit coefficients so the simulated track matches a target track.

The paper's Section 3 (Furlong et al. 2003): cost

    V(p) = sum_i sum_{c in x, y, z, phi, theta, psi} (c_target(t_i) - c_sim(t_i; p))**2    (paper Eq. 6)

minimised by SQP (SLSQP) over bounded parameters scaled as ratios to a reference value,
``p_j = theta_j / theta_ref_j``. Also trust-region reflective least squares on the residual
vector, the method suited to a sum of squares. Both use a finite-difference Jacobian computed as
*one* batched simulation of P + 1 tracks.

Units: position residuals in metres and angle residuals in radians are summed as they are,
exactly as the paper's V(p) does.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from .simulate import Simulator
from .track import STATE_NAMES, Track

PAPER_CHANNELS = ("x", "y", "z", "phi", "theta", "psi")
#: Residual assigned to every sample of a diverged track, so optimisers see a large finite value
#: (SLSQP and least_squares cannot handle inf/NaN); the honest cost is +inf (see ``cost_batch``).
DIVERGED_RESIDUAL = 1e6


class Problem:
    """One identification problem: simulator with free coefficients, target track, scaling.

    Parameters
    ----------
    simulator : :class:`~bayesid.simulate.Simulator` whose ``free`` names are identified.
    target : :class:`~bayesid.track.Track` whose times lie on the simulator's sample grid.
    reference : (P,) non-zero prime values; the optimiser works on ``p = theta / reference``.
    channels : state columns compared (default the paper's six; absent ones are skipped).
    fd_step : forward-difference step in scaled units.

    Raises
    ------
    ValueError : a reference value is zero or non-finite (a ratio cannot be formed); target
        times off the simulation grid; no channel in common.
    """

    def __init__(self, simulator: Simulator, target: Track, reference, channels=PAPER_CHANNELS,
                 fd_step: float = 1e-7):
        self.sim = simulator
        self.names = list(simulator.free)
        ref = np.asarray(reference, dtype=float)
        if ref.shape != (len(self.names),):
            raise ValueError(f"reference has shape {ref.shape}, expected ({len(self.names)},)")
        for n, r in zip(self.names, ref):
            if not np.isfinite(r) or r == 0.0:
                raise ValueError(f"coefficient {n}: reference value {r} cannot scale a ratio")
        self.reference = ref
        self.channels = [c for c in channels if c in target]
        if not self.channels:
            raise ValueError(f"target track {target.name!r} has none of the channels {channels}")
        self.ch_idx = np.array([STATE_NAMES.index(c) for c in self.channels])
        pos = (target.t - simulator.t[0]) / (simulator.t[1] - simulator.t[0])
        idx = np.round(pos).astype(int)
        if np.any(np.abs(pos - idx) > 1e-6) or idx.min() < 0 or idx.max() >= simulator.n_samples:
            raise ValueError(f"target track {target.name!r}: sample times are not on the simulation grid "
                             f"(dt_sample = {simulator.t[1] - simulator.t[0]:g} s, span {simulator.t[-1]:g} s)")
        self.t_idx = idx
        self.y = np.column_stack([target[c] for c in self.channels])   # (n, C)
        self.mask = np.isfinite(self.y)
        self.y0 = np.where(self.mask, self.y, 0.0)
        self.fd_step = fd_step
        self.n_residuals = self.y.size

    # -- scaled <-> prime ----------------------------------------------------------------------
    def theta(self, p) -> np.ndarray:
        """Prime coefficients from scaled parameters, same shape as ``p``."""
        return np.asarray(p, dtype=float) * self.reference

    def scaled(self, theta) -> np.ndarray:
        return np.asarray(theta, dtype=float) / self.reference

    # -- batched evaluations -------------------------------------------------------------------
    def residuals_batch(self, P) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (target - simulated) for B parameter vectors in one batched simulation.

        Parameters
        ----------
        P : (B, n_free) scaled parameters.

        Returns
        -------
        R : (B, n_residuals), sample-major; zero where the target is missing.
        diverged : (B,) bool; diverged rows hold ``DIVERGED_RESIDUAL``.
        """
        P = np.atleast_2d(P)
        res = self.sim.run(self.theta(P))
        S = res.states[:, self.t_idx][:, :, self.ch_idx]          # (B, n, C)
        R = np.where(self.mask[None], self.y0[None] - S, 0.0)
        div = res.diverged | ~np.isfinite(R).all(axis=(1, 2))
        R[div] = DIVERGED_RESIDUAL
        return R.reshape(R.shape[0], -1), div

    def cost_batch(self, P) -> np.ndarray:
        """V(p) for B parameter vectors, (B,); ``+inf`` for a diverged simulation."""
        R, div = self.residuals_batch(P)
        V = np.einsum("ij,ij->i", R, R)
        V[div] = np.inf
        return V

    def cost(self, p) -> float:
        return float(self.cost_batch(np.asarray(p)[None])[0])

    def jacobian(self, p, r0=None, central: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Residuals at p and their finite-difference Jacobian d r / d p, from ONE batched
        simulation of P + 1 tracks (P if ``r0``, the residuals at p, is given; 2P + 1 for
        ``central`` differences, whose O(h^2) error suits identifiability analysis).

        Returns
        -------
        r : (n_residuals,)   J : (n_residuals, P)
        """
        p = np.asarray(p, dtype=float)
        P_ = p.size
        h = self.fd_step * np.maximum(1.0, np.abs(p))
        if central:
            h = 1e-5 * np.maximum(1.0, np.abs(p))  # truncation O(h^2) ~ 1e-10, round-off ~ 1e-11
            batch = np.vstack([p[None], np.repeat(p[None], P_, axis=0) + np.diag(h),
                               np.repeat(p[None], P_, axis=0) - np.diag(h)])
            R, _ = self.residuals_batch(batch)
            return R[0], ((R[1:P_ + 1] - R[P_ + 1:]) / (2 * h)[:, None]).T
        batch = np.repeat(p[None], P_, axis=0) + np.diag(h)
        if r0 is None:
            R, _ = self.residuals_batch(np.vstack([p[None], batch]))
            r0, Rp = R[0], R[1:]
        else:
            Rp, _ = self.residuals_batch(batch)
        return r0, ((Rp - r0[None]) / h[:, None]).T

    def gradient(self, p, r0=None) -> tuple[float, np.ndarray]:
        """Cost and gradient ``dV/dp = 2 J^T r`` (J = d r / d p) -- differencing the residuals
        avoids the cancellation of differencing V itself. One batched call."""
        r, J = self.jacobian(p, r0)
        return float(r @ r), 2.0 * (J.T @ r)


class _SimGroup:
    """Work counters summed over the simulators of a :class:`JointProblem`."""

    def __init__(self, sims):
        self.sims = list(sims)

    @property
    def sim_seconds(self) -> float:
        return sum(s.sim_seconds for s in self.sims)

    @property
    def n_tracks(self) -> int:
        return sum(s.n_tracks for s in self.sims)


class JointProblem(Problem):
    """Several manoeuvres identified together: one coefficient vector, residuals stacked.

    The cost is the sum of the members' costs (paper Eq. 6 summed over manoeuvres), so
    combining manoeuvres is identification on all their samples at once. Every method of
    :class:`Problem` (cost, batched Jacobian, gradient) works unchanged; one batched evaluation
    runs one batched simulation per member.

    Parameters
    ----------
    problems : list of :class:`Problem` with the same free names, reference and channels.

    Raises
    ------
    ValueError : empty list, or members differing in free names, reference or channels (named).
    """

    def __init__(self, problems):
        problems = list(problems)
        if not problems:
            raise ValueError("JointProblem needs at least one problem")
        first = problems[0]
        for k, p in enumerate(problems[1:], 1):
            for what in ("names", "channels"):
                if list(getattr(p, what)) != list(getattr(first, what)):
                    raise ValueError(f"problem {k} ({p.sim.manoeuvre.name}): {what} {getattr(p, what)} "
                                     f"differ from {getattr(first, what)}")
            if not np.array_equal(p.reference, first.reference):
                raise ValueError(f"problem {k} ({p.sim.manoeuvre.name}): reference values differ")
        self.problems = problems
        self.names, self.reference, self.channels = first.names, first.reference, first.channels
        self.y = np.vstack([p.y for p in problems])
        self.mask = np.vstack([p.mask for p in problems])
        self.y0 = np.where(self.mask, self.y, 0.0)
        self.fd_step = first.fd_step
        self.n_residuals = self.y.size
        self.sim = _SimGroup(p.sim for p in problems)

    def residuals_batch(self, P) -> tuple[np.ndarray, np.ndarray]:
        """Stacked residuals (B, sum of members' n_residuals) and (B,) divergence flags."""
        parts = [p.residuals_batch(P) for p in self.problems]
        R = np.hstack([r for r, _ in parts])
        div = np.any(np.vstack([d for _, d in parts]), axis=0)
        R[div] = DIVERGED_RESIDUAL
        return R, div


@dataclass
class FitResult:
    """Outcome of one fit, in the spirit of ``scipy.optimize.OptimizeResult`` plus the SQP
    activity monitor of the paper (Sec. 3, point 2)."""

    method: str
    names: list
    theta: np.ndarray           # (P,) identified prime coefficients
    p: np.ndarray               # (P,) scaled
    start_cost: float
    final_cost: float
    n_iterations: int
    n_simulations: int
    n_sim_cost: int             # tracks simulated for cost values at accepted iterates
    n_sim_gradient: int         # tracks simulated for finite-difference Jacobians/gradients
    n_sim_linesearch: int       # tracks simulated at rejected trial points
    wall_s: float
    sim_s: float                # wall time inside the batched simulator
    success: bool
    message: str
    at_bound: list
    history: list = field(default_factory=list)   # per iteration: cost, step, active bounds

    @property
    def sim_share(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else float("nan")

    def summary(self) -> dict:
        """JSON-ready summary (no per-iteration history)."""
        return dict(method=self.method, start_cost=self.start_cost, final_cost=self.final_cost,
                    n_iterations=self.n_iterations, n_simulations=self.n_simulations,
                    n_sim_cost=self.n_sim_cost, n_sim_gradient=self.n_sim_gradient,
                    n_sim_linesearch=self.n_sim_linesearch, wall_s=self.wall_s,
                    sim_share=self.sim_share, success=bool(self.success), message=self.message,
                    at_bound=list(self.at_bound))


def _active(p, lo, hi, tol=1e-6):
    return [i for i in range(p.size) if p[i] - lo[i] <= tol * max(1.0, abs(lo[i]))
            or hi[i] - p[i] <= tol * max(1.0, abs(hi[i]))]


class _Monitor:
    """Counts simulations by purpose and caches the last residual vector."""

    def __init__(self, problem: Problem):
        self.pb = problem
        self.evals = []             # (p, cost) of every single-track cost evaluation
        self.n_grad_tracks = 0
        self._last = None           # (p, r)
        self.t0 = time.perf_counter()
        self.sim0 = problem.sim.sim_seconds

    def residuals(self, p):
        p = np.array(p, dtype=float)
        if self._last is not None and np.array_equal(self._last[0], p):
            return self._last[1]
        R, div = self.pb.residuals_batch(p[None])
        r = R[0]
        self._last = (p, r)
        self.evals.append((p, np.inf if div[0] else float(r @ r)))
        return r

    def cost(self, p):
        r = self.residuals(p)
        return float(r @ r)

    def jac(self, p):
        p = np.array(p, dtype=float)
        cached = self._last is not None and np.array_equal(self._last[0], p)
        r0 = self._last[1] if cached else None
        r, J = self.pb.jacobian(p, r0)
        self.n_grad_tracks += p.size + (0 if cached else 1)
        self._last = (p, r)
        return r, J


def _result(method, pb, mon, p, iterates, lo, hi, success, message, nit):
    wall = time.perf_counter() - mon.t0
    sim_s = pb.sim.sim_seconds - mon.sim0  # before the bookkeeping simulations below
    iter_set = {tuple(x) for x in iterates}
    n_cost = sum(1 for x, _ in mon.evals if tuple(x) in iter_set)
    known = {tuple(x): c for x, c in mon.evals}   # every cost the fit already simulated

    def cost(x):
        return known[tuple(x)] if tuple(x) in known else pb.cost(x)

    hist = []
    prev = None
    for k, x in enumerate(iterates):
        c = cost(x)
        hist.append(dict(iteration=k, cost=c, step=float(np.linalg.norm(x - prev)) if prev is not None else 0.0,
                         active_bounds=[pb.names[i] for i in _active(x, lo, hi)]))
        prev = x
    final = cost(p)
    return FitResult(method, pb.names, pb.theta(p), p, float(hist[0]["cost"]) if hist else float("nan"), final,
                     nit, len(mon.evals) + mon.n_grad_tracks, n_cost, mon.n_grad_tracks,
                     len(mon.evals) - n_cost, wall, sim_s, bool(success),
                     str(message), [pb.names[i] for i in _active(p, lo, hi)], hist)


def fit_slsqp(problem: Problem, p0, bounds, maxiter: int = 300, ftol: float = 1e-16) -> FitResult:
    """Minimise V(p) with SLSQP (``scipy.optimize.minimize``), bounds, batched FD gradient.

    SLSQP is given ``V(p) / V(p0)``: on the raw cost (gradients of order 1e6 in scaled units)
    scipy's SLSQP stops after its first QP subproblem without moving (seen with scipy 1.17 on
    the paper's Case 3). Normalising the objective is the usual remedy and changes no minimiser;
    all reported costs are V itself.

    Parameters
    ----------
    p0 : (P,) scaled start.   bounds : (lo (P,), hi (P,)) scaled.
    ftol : SLSQP's precision goal on the normalised cost V/V(p0).

    Returns
    -------
    FitResult (iterates, simulations by purpose, wall-time share in simulation).
    """
    lo, hi = (np.asarray(b, dtype=float) for b in bounds)
    p0 = np.clip(np.asarray(p0, dtype=float), lo, hi)
    mon = _Monitor(problem)
    iterates = [p0.copy()]
    V0 = mon.cost(p0)
    norm = V0 if np.isfinite(V0) and V0 > 0 else 1.0

    def jac(p):
        r, J = mon.jac(p)
        return 2.0 * (J.T @ r) / norm

    res = optimize.minimize(lambda p: mon.cost(p) / norm, p0, jac=jac, method="SLSQP",
                            bounds=list(zip(lo, hi)),
                            callback=lambda xk: iterates.append(np.array(xk, dtype=float)),
                            options=dict(maxiter=maxiter, ftol=ftol))
    p = np.clip(res.x, lo, hi)
    return _result("SLSQP", problem, mon, p, iterates, lo, hi, res.success, res.message, res.nit)


def fit_least_squares(problem: Problem, p0, bounds, max_nfev: int = 300, tol: float = 1e-15) -> FitResult:
    """Trust-region reflective least squares (``scipy.optimize.least_squares``, method "trf")
    on the residual vector, bounds, batched FD Jacobian. Same counters as :func:`fit_slsqp`."""
    lo, hi = (np.asarray(b, dtype=float) for b in bounds)
    p0 = np.clip(np.asarray(p0, dtype=float), lo, hi)
    mon = _Monitor(problem)
    iterates = [p0.copy()]

    def cb(intermediate_result):
        iterates.append(np.array(intermediate_result.x, dtype=float))

    res = optimize.least_squares(mon.residuals, p0, jac=lambda p: mon.jac(p)[1], bounds=(lo, hi),
                                 method="trf", x_scale=1.0, ftol=tol, xtol=tol, gtol=tol,
                                 max_nfev=max_nfev, callback=cb)
    if not np.array_equal(iterates[-1], res.x):
        iterates.append(np.array(res.x, dtype=float))
    return _result("least_squares (trf)", problem, mon, res.x, iterates, lo, hi, res.status > 0,
                   res.message, len(iterates) - 1)


def max_position_error(a: Track, b: Track) -> float:
    """Maximum horizontal distance between two tracks sampled at the same times, m."""
    return float(np.nanmax(np.hypot(a["x"] - b["x"], a["y"] - b["y"])))


__all__ = ["Problem", "JointProblem", "FitResult", "fit_slsqp", "fit_least_squares", "max_position_error",
           "PAPER_CHANNELS"]
