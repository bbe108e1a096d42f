"""The one fit function and the one result type of the package.

Every fit -- the paper's whole-track cases (:class:`bayesid.estimation.objective.Problem`),
multiple shooting on real runs and every candidate of the gap diagnosis
(:class:`bayesid.estimation.windows.WindowObjective`) -- minimises a sum of squared residuals
``V(x) = r(x)^T r(x)`` of an *objective* over bounded parameters ``x`` with :func:`fit`, and
gets a :class:`FitResult` back (modelled on ``scipy.optimize.OptimizeResult``: ``x``, cost,
``success``, ``message``, counters, Jacobian).

An objective is any object with

* ``names`` : list of the parameter names of ``x``;
* ``residuals_batch(X)`` : (B, n) parameter vectors -> ((B, n_res) residuals, (B,) diverged);
* ``residuals(x)`` : (n,) -> ((n_res,) residuals, diverged bool); may differ from one row of
  ``residuals_batch`` where the objective keeps state (warm-started window start states);
* ``jacobian(x, r0=None)`` : -> (residuals (n_res,), Jacobian (n_res, n)); ``r0`` the
  residuals at ``x`` when already known (an objective may ignore it);
* ``cache_residuals`` : bool, True when ``residuals`` is a pure function of ``x`` (the fit then
  reuses the residuals of a point it evaluated before, e.g. for the Jacobian);
* ``n_simulations`` : int counter of the parameter vectors the objective simulated;
* ``sim_seconds`` : float, wall time inside the simulator so far (NaN when not measured);
* ``n_residuals`` : int, length of the residual vector;
* ``result_fields(x)`` : dict of the :class:`FitResult` fields that describe ``x`` in the
  objective's own terms (``p``, ``theta``, ``model``, ``nuisance``, ``k`` ...).
* optionally ``accepted_residuals(x)`` : for a stateful objective, the residuals at ``x`` as the
  solver saw them when ``x`` is the last point it accepted (else None); the fit reports its cost
  from them rather than from an evaluation that may land elsewhere.

Solvers: SLSQP (``method="slsqp"``; the paper's SQP, Furlong et al. 2003, Sec. 3) and
trust-region reflective least squares (``method="least_squares"``, scipy's ``trf``), both with the
objective's batched finite-difference Jacobian.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

__all__ = ["FitResult", "fit", "METHODS"]

#: Solvers of :func:`fit`.
METHODS = ("least_squares", "slsqp")


@dataclass
class FitResult:
    """Outcome of one fit (in the spirit of ``scipy.optimize.OptimizeResult``), with the SQP
    activity monitor of the paper (Furlong et al. 2003, Sec. 3, point 2).

    Model fits (:mod:`bayesid.estimation.windows`) also carry ``model``, ``p`` (the model's
    parameter vector), ``nuisance`` (per-track nuisances), ``channels`` and ``n_starts``; the
    paper's fits ``p`` (scaled ratios) and ``theta`` (prime coefficients).

    Parameters
    ----------
    method : str
        Solver label.
    names : list of str
        Parameter names of ``x`` (and of ``p``).
    x : ndarray, shape (n,)
        Optimum in the objective's variables.
    cost : float
        ``V(x)``, the final sum of squares.
    start_cost : float, default NaN
        ``V`` at the start (NaN when not evaluated).
    success : bool, default True
        The solver's success flag.
    message : str, default ""
        The solver's message.
    n_iterations : int, default 0
        Accepted iterates.
    n_simulations : int, default 0
        Parameter vectors simulated by the fit.
    n_sim_cost : int, default 0
        Simulations at accepted iterates.
    n_sim_gradient : int, default 0
        Simulations for finite-difference Jacobians.
    n_sim_linesearch : int, default 0
        Simulations at rejected trial points.
    wall_s : float, default 0.0
        Wall time of the fit, s.
    sim_s : float, default NaN
        Of it inside the simulator, s (NaN: not measured).
    at_bound : list of str
        Names of parameters at a bound at the optimum.
    history : list of dict
        Per iterate: cost, step and active bounds. For a stateful objective (fitted window starts
        warm-started from the previous evaluation) the cost as the solver evaluated it at that
        iterate, NaN where it did not.
    jac : ndarray, shape (n_res, n), optional
        Jacobian at the optimum when the solver has one.
    n_residuals : int, default 0
        Length of the residual vector.
    k : int, default 0
        Number of estimated parameters (those of ``x`` plus any the objective eliminated, e.g.
        window start states).
    model : SimulationModel, optional
        The model of a model fit.
    p : ndarray, optional
        The model's parameter vector (model fits), or the scaled ratios (the paper's fits).
    theta : ndarray, optional
        Prime coefficients (the paper's fits).
    nuisance : list of ndarray
        Per-track nuisance parameters (model fits).
    channels : tuple of str, optional
        The channels fitted (model fits).
    n_starts : int, default 0
        Number of window start states fitted (model fits).
    window_starts : list, optional
        Per track, the (W, 6) fitted window start offsets at the optimum (None for a track with
        measured starts; model fits with fitted starts): a refit of the same windows warm-starts
        from them (:func:`bayesid.estimation.windows.fit_model`), because from a cold start the
        start-state problem of a model bent to follow its tracks can settle in another optimum.
    """

    method: str
    names: list
    x: np.ndarray
    cost: float
    start_cost: float = float("nan")
    success: bool = True
    message: str = ""
    n_iterations: int = 0
    n_simulations: int = 0
    n_sim_cost: int = 0
    n_sim_gradient: int = 0
    n_sim_linesearch: int = 0
    wall_s: float = 0.0
    sim_s: float = float("nan")
    at_bound: list = field(default_factory=list)
    history: list = field(default_factory=list)
    jac: np.ndarray | None = None
    n_residuals: int = 0
    k: int = 0
    # model fits
    model: object = None
    p: np.ndarray | None = None
    theta: np.ndarray | None = None
    nuisance: list = field(default_factory=list)
    channels: tuple | None = None
    n_starts: int = 0
    window_starts: list | None = None

    @classmethod
    def fixed(cls, model, p, n_tracks: int, message: str = "fixed", nuisance=None) -> FitResult:
        """A model at given parameters, not fitted (e.g. the nominal or the true model),
        usable wherever a fit result of ``model`` is.

        Parameters
        ----------
        model : SimulationModel
            The model.
        p : array_like, shape (n_params,)
            Its parameter vector.
        n_tracks : int
            Number of tracks.
        message : str, default "fixed"
            The result's message.
        nuisance : sequence of array_like, optional
            One (n_nuisance,) array per track; default zeros.

        Returns
        -------
        FitResult
            Method ``"none"``, cost 0, ``k`` the model's number of parameters.
        """
        p = np.asarray(p, float)
        nu = [np.zeros(model.n_nuisance)] * n_tracks if nuisance is None else list(nuisance)
        return cls(
            "none", list(model.param_names), p, 0.0, message=message, model=model, p=p, nuisance=nu, k=model.n_params
        )

    @property
    def sim_share(self) -> float:
        """Share of the wall time spent in the simulator."""
        return self.sim_s / self.wall_s if self.wall_s > 0 else float("nan")

    @property
    def bic(self) -> float:
        """Schwarz criterion ``V + k ln n`` of the residuals (for noise-scaled residuals, the
        Gaussian likelihood with the assumed sds; the constant is dropped)."""
        return float(self.cost + self.k * math.log(max(self.n_residuals, 1)))

    def coefficients(self) -> dict:
        """The fitted free coefficients.

        Returns
        -------
        dict
            ``{coefficient: fitted value}`` (prime form).
        """
        if self.model is None:
            return {n: float(v) for n, v in zip(self.names, self.theta)}
        return {n: float(v) for n, v in zip(self.model.free, self.p[: self.model.n_theta])}

    def effect_parameters(self) -> dict:
        """The fitted parameters of a model fit's effects.

        Returns
        -------
        dict
            ``{effect: {parameter: value}}``, with ``per_track_nuisance`` (a list) where the
            effect has one.
        """
        th, qs = self.model.split_params(self.p[None])
        out = {}
        for e, q in zip(self.model.effects, qs):
            out[e.name] = {p: float(v) for p, v in zip(e.params, q[0])}
            if e.n_nuisance:
                out[e.name]["per_track_nuisance"] = [float(v[0]) for v in self.nuisance]
        return out

    def summary(self) -> dict:
        """JSON-ready summary (no per-iteration history, no arrays).

        Returns
        -------
        dict
            ``method``, ``start_cost``, ``final_cost``, the iteration and simulation counters,
            ``wall_s``, ``sim_share``, ``success``, ``message`` and ``at_bound``.
        """
        return dict(
            method=self.method,
            start_cost=self.start_cost,
            final_cost=self.cost,
            n_iterations=self.n_iterations,
            n_simulations=self.n_simulations,
            n_sim_cost=self.n_sim_cost,
            n_sim_gradient=self.n_sim_gradient,
            n_sim_linesearch=self.n_sim_linesearch,
            wall_s=self.wall_s,
            sim_share=self.sim_share,
            success=bool(self.success),
            message=self.message,
            at_bound=list(self.at_bound),
        )


def _active(p, lo, hi, tol=1e-6):
    """Indices of ``p`` on a finite bound (an infinite bound is never reached: ``inf <= inf`` put
    every unbounded coefficient "at bound", issue 69)."""
    return [
        i
        for i in range(p.size)
        if (np.isfinite(lo[i]) and p[i] - lo[i] <= tol * max(1.0, abs(lo[i])))
        or (np.isfinite(hi[i]) and hi[i] - p[i] <= tol * max(1.0, abs(hi[i])))
    ]


class _Monitor:
    """Counts the fit's simulations by purpose and, for a pure objective, reuses the residuals
    of the last point evaluated."""

    def __init__(self, objective):
        self.ob = objective
        self.evals = []  # (x, cost) of every single-point evaluation
        self.n_grad_tracks = 0
        self._last = None  # (x, r)
        self.t0 = time.perf_counter()
        self.sim0 = objective.sim_seconds
        self.n0 = objective.n_simulations

    def residuals(self, x):
        x = np.array(x, dtype=float)
        if self.ob.cache_residuals and self._last is not None and np.array_equal(self._last[0], x):
            return self._last[1]
        r, diverged = self.ob.residuals(x)
        self._last = (x, r)
        self.evals.append((x, np.inf if diverged else float(r @ r)))
        return r

    def cost(self, x):
        r = self.residuals(x)
        return float(r @ r)

    def jac(self, x):
        x = np.array(x, dtype=float)
        cached = self.ob.cache_residuals and self._last is not None and np.array_equal(self._last[0], x)
        r, J = self.ob.jacobian(x, self._last[1] if cached else None)
        self.n_grad_tracks += x.size + (0 if cached else 1)
        if self.ob.cache_residuals:
            self._last = (x, r)
        return r, J


@dataclass(frozen=True)
class SolverOptions:
    """The solver and its budgets and tolerances (:func:`fit`), grouped as scipy groups a
    method's ``options``.

    Parameters
    ----------
    method : str, default "least_squares"
        ``"least_squares"`` (scipy ``least_squares``, trust-region reflective, on the residual
        vector) or ``"slsqp"`` (scipy ``minimize(method="SLSQP")`` on ``V(x)/V(x0)``: on the raw
        cost, gradients of order 1e6 in scaled units make scipy's SLSQP stop after its first QP
        subproblem without moving -- seen with scipy 1.17 on the paper's Case 3; normalising
        changes no minimiser and every reported cost is ``V`` itself).
    max_nfev : int, default 300
        Least-squares evaluation budget.
    maxiter : int, default 300
        SLSQP iteration budget.
    ftol : float, optional
        Tolerance on the cost (None: 1e-15 for least squares, 1e-16 for SLSQP, on the
        normalised cost there).
    xtol : float, default 1e-15
        Least-squares step tolerance.
    gtol : float, default 1e-15
        Least-squares gradient tolerance.
    x_scale : float or array_like, shape (n,), default 1.0
        Least-squares variable scales.

    Raises
    ------
    ValueError
        An unknown ``method`` (named with the known ones).
    """

    method: str = "least_squares"
    max_nfev: int = 300
    maxiter: int = 300
    ftol: float | None = None
    xtol: float = 1e-15
    gtol: float = 1e-15
    x_scale: object = 1.0

    def __post_init__(self):
        if self.method not in METHODS:
            raise ValueError(f"unknown fit method {self.method!r}; choose from {', '.join(METHODS)}")


def fit(
    objective,
    x0,
    bounds,
    options: SolverOptions = SolverOptions(),
    *,
    bar: str | None = None,
    quiet: bool = False,
) -> FitResult:
    """Minimise ``V(x) = r(x)^T r(x)`` of an objective (module docstring) over bounds.

    Parameters
    ----------
    objective : object
        See the module docstring.
    x0 : array_like, shape (n,)
        The start, clipped to the bounds.
    bounds : tuple
        ``(lo (n,), hi (n,))``, +-inf allowed.
    options : SolverOptions, default SolverOptions()
        The solver (least squares or SLSQP), its budgets and tolerances.
    bar : str, optional
        A label to show a progress bar (tqdm, on stderr) of the residual evaluations.
    quiet : bool, default False
        Silence the solver's warnings (e.g. a diverged trial point).

    Returns
    -------
    FitResult
        With the iterates (``history``), simulations by purpose, the wall-time share in
        simulation, and for least squares the Jacobian at the optimum. ``cost`` is ``V`` at the
        optimum, taken from the fit's own evaluation when the objective is pure, else evaluated
        once more.
    """
    lo, hi = (np.asarray(b, dtype=float) for b in bounds)
    x0 = np.clip(np.asarray(x0, dtype=float), lo, hi)
    mon = _Monitor(objective)
    iterates = [x0.copy()]
    resid = mon.residuals
    pbar = None
    if bar:
        from tqdm import tqdm

        pbar = tqdm(total=options.max_nfev, desc=bar, unit=" evaluations", leave=True)

        def resid(x):
            pbar.update(1)
            return mon.residuals(x)

    try:
        with warnings.catch_warnings():
            if quiet:
                warnings.simplefilter("ignore")
            solver = _slsqp if options.method == "slsqp" else _least_squares
            x, res, label, success, nit, jac_out = solver(mon, resid, x0, (lo, hi), options, iterates)
    finally:
        if pbar is not None:
            pbar.close()
    return _result(objective, mon, x, (lo, hi), iterates, (res, label, success, nit, jac_out))


def _slsqp(mon, resid, x0, bounds, options: SolverOptions, iterates) -> tuple:
    """scipy's SLSQP on the normalised cost ``V(x)/V(x0)``: (x, result, label, success, nit, None)."""
    lo, hi = bounds
    V0 = mon.cost(x0)
    norm = V0 if np.isfinite(V0) and V0 > 0 else 1.0

    def grad(x):
        r, J = mon.jac(x)
        return 2.0 * (J.T @ r) / norm

    def cost_n(x):
        r = resid(x)
        return float(r @ r) / norm

    res = optimize.minimize(
        cost_n,
        x0,
        jac=grad,
        method="SLSQP",
        bounds=list(zip(lo, hi)),
        callback=lambda xk: iterates.append(np.array(xk, dtype=float)),
        options=dict(maxiter=options.maxiter, ftol=1e-16 if options.ftol is None else options.ftol),
    )
    return np.clip(res.x, lo, hi), res, "SLSQP", res.success, res.nit, None


def _least_squares(mon, resid, x0, bounds, options: SolverOptions, iterates) -> tuple:
    """scipy's trust-region reflective least squares: (x, result, label, success, nit, Jacobian)."""

    def cb(intermediate_result):
        iterates.append(np.array(intermediate_result.x, dtype=float))

    res = optimize.least_squares(
        resid,
        x0,
        jac=lambda x: mon.jac(x)[1],
        bounds=bounds,
        method="trf",
        x_scale=options.x_scale,
        ftol=1e-15 if options.ftol is None else options.ftol,
        xtol=options.xtol,
        gtol=options.gtol,
        max_nfev=options.max_nfev,
        callback=cb,
    )
    x = res.x
    if not np.array_equal(iterates[-1], x):
        iterates.append(np.array(x, dtype=float))
    return x, res, "least_squares (trf)", res.status > 0, len(iterates) - 1, res.jac


def _result(objective, mon, x, bounds, iterates, solved) -> FitResult:
    """The :class:`FitResult` of a finished solve: costs of the iterates, counters, wall times."""
    res, label, success, nit, jac_out = solved
    lo, hi = bounds
    if not objective.cache_residuals:  # a stateful objective: its residuals at the optimum as the solver saw them
        accepted = getattr(objective, "accepted_residuals", None)
        r_final = accepted(x) if accepted is not None else None
        if r_final is None:
            r_final = objective.residuals(x)[0]
    wall = time.perf_counter() - mon.t0
    sim_s = objective.sim_seconds - mon.sim0  # before the bookkeeping evaluations below
    n_sims = objective.n_simulations - mon.n0
    iter_set = {tuple(v) for v in iterates}
    n_cost = sum(1 for v, _ in mon.evals if tuple(v) in iter_set)
    known = {tuple(v): c for v, c in mon.evals} if objective.cache_residuals else {}
    # a stateful objective cannot be evaluated again as it was: its iterates' costs as the solver saw them
    seen = {tuple(v): c for v, c in mon.evals}

    def cost(v):
        if tuple(v) in known:
            return known[tuple(v)]
        R, div = objective.residuals_batch(np.asarray(v)[None])
        return float("inf") if div[0] else float(R[0] @ R[0])

    hist, prev = [], None
    for k, v in enumerate(iterates):
        hist.append(
            dict(
                iteration=k,
                cost=cost(v) if objective.cache_residuals else float(seen.get(tuple(v), float("nan"))),
                step=float(np.linalg.norm(v - prev)) if prev is not None else 0.0,
                active_bounds=[objective.names[i] for i in _active(v, lo, hi)],
            )
        )
        prev = v
    if objective.cache_residuals:
        final, n_res = cost(x), objective.n_residuals
    else:
        final, n_res = float(r_final @ r_final), r_final.size
    start = hist[0]["cost"] if objective.cache_residuals else (mon.evals[0][1] if mon.evals else float("nan"))
    out = FitResult(
        label,
        list(objective.names),
        np.array(x, dtype=float),
        final,
        float(start),
        bool(success),
        str(res.message),
        nit,
        n_sims,
        n_cost,
        mon.n_grad_tracks,
        len(mon.evals) - n_cost,
        wall,
        sim_s,
        [objective.names[i] for i in _active(x, lo, hi)],
        hist,
        jac_out,
        n_res,
        x.size,
    )
    for k, v in objective.result_fields(out.x).items():
        setattr(out, k, v)
    return out
