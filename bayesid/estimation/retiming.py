"""When did the rudder move? Movements within single log intervals estimated with the
coefficients, and their uncertainty carried into the coefficients' covariance (issue 50).

A closed-loop zigzag reverses the rudder when the heading passes the check angle, whenever that
is; an actuator faster than the log (or a column that logs the order) then shows each reversal
as a movement within one sample interval, whose time in it no reading of the log knows
(``--inputs rate`` puts it in the middle, :func:`bayesid.models.context.rate_limited_knots`).
That timing alone moved NPS AUV II's coefficients far beyond their intervals at 1-10 Hz
(``reports/benchmark_reversal_timing.txt``), and with the true times the same fits were honest.

Here each such movement's place in its interval (a fraction ``f`` in [0, 1] of the time the gear
held there, :meth:`bayesid.models.context.TrackContext.retime`) is a parameter of the fit beside
the coefficients: the multiple-shooting residuals ``r(p, f)`` minimised over both by the
package's least squares from the fit at the middle, the Jacobian in ``f`` by forward differences
of :data:`FRACTION_STEP`. The coefficients' covariance then counts what the data leave of the
times: the Laplace covariance of ``p`` with the times' directions projected out of the
coefficients' Jacobian (the ``p`` block of the joint inverse, ``(J_p' (I - P_f) J_p)^-1 s^2``
with ``P_f`` the projection on the columns of the times: the Schur complement), so that the
intervals widen by what the timing leaves unknown (1.2-2 x on the benchmark's 5-10 Hz logs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..models.context import lone_moves
from .fit import SolverOptions, fit
from .windows import WindowObjective

__all__ = ["FRACTION_STEP", "MIN_MOVE_DEG", "Retiming", "fit_retimed", "moves_of", "project_timing"]

#: Forward-difference step of a movement's fraction of its interval: large enough that the
#: residuals' change stands above the window start states' inner tolerance.
FRACTION_STEP = 0.1
#: Smallest movement (deg) whose time is estimated; smaller ones stay mid-interval.
MIN_MOVE_DEG = 0.5


@dataclass
class Retiming:
    """The movements of a retimed fit.

    Parameters
    ----------
    moves : list of ndarray
        Per track, the intervals ``i`` (between samples ``i`` and ``i + 1``) of the movements.
    fractions : ndarray, shape (J,)
        Their places in the intervals, all tracks in order.
    jac : ndarray, shape (n_res, J)
        The data residuals' Jacobian in the fractions at the optimum.
    """

    moves: list
    fractions: np.ndarray
    jac: np.ndarray

    def per_track(self) -> list:
        """The fractions of each track, as :meth:`TrackContext.retime` takes them.

        Returns
        -------
        list of dict
            Per track ``{interval: fraction}``.
        """
        return _split(self.moves, self.fractions)

    def times(self, ctxs, sd=None) -> dict:
        """When each movement started, s, per track name (with its sd from ``sd``, the
        fractions' sds), for ``model.json``.

        Parameters
        ----------
        ctxs : list of TrackContext
            The retimed contexts (their tracks and gear rate).
        sd : ndarray, shape (J,), optional
            The fractions' sds.

        Returns
        -------
        dict
            ``{track: [[start s, sd s or None], ...]}``.
        """
        out, k = {}, 0
        for ctx, m in zip(ctxs, self.moves):
            t = np.asarray(ctx.track.t, float)
            u = np.asarray(ctx.track["delta_r"], float)
            rate = math.radians(ctx.model.rudder_rate_deg_s)
            rows = []
            for a, i in enumerate(m):
                span = (t[i + 1] - t[i]) - abs(u[i + 1] - u[i]) / rate
                f = self.fractions[k + a]
                rows.append([float(t[i] + f * span), None if sd is None else float(sd[k + a] * span)])
            out[ctx.name] = rows
            k += m.size
        return out


def _split(moves, fractions) -> list:
    """Per track ``{interval: fraction}`` of the fractions of all tracks in order."""
    out, k = [], 0
    for m in moves:
        out.append({int(i): float(fractions[k + a]) for a, i in enumerate(m)})
        k += m.size
    return out


def moves_of(ctxs) -> list:
    """The rudder's movements within single intervals of each context (``inputs="rate"``),
    larger than :data:`MIN_MOVE_DEG`.

    Parameters
    ----------
    ctxs : list of TrackContext
        Contexts whose model reads the inputs at the gear's rate.

    Returns
    -------
    list of ndarray
        Per track, the intervals of the movements (:func:`bayesid.models.context.lone_moves`).

    Raises
    ------
    ValueError
        A context whose inputs are not reconstructed at the gear's rate (naming the option).
    """
    out = []
    for c in ctxs:
        if c.input_reconstruction != "rate":
            raise ValueError("--retime estimates the rudder's movements at the gear's rate: it needs --inputs rate")
        t = np.asarray(c.track.t, float)
        u = np.asarray(c.track["delta_r"], float).copy()
        bad = ~np.isfinite(u)
        if bad.any():  # filled as the context reads them (interpolated): the same intervals
            u[bad] = np.interp(t[bad], t[~bad], u[~bad])
        out.append(lone_moves(t, u, math.radians(c.model.rudder_rate_deg_s), math.radians(MIN_MOVE_DEG)))
    return out


class _RetimedObjective:
    """The multiple-shooting objective in ``x = [p, fractions]`` (the protocol of
    :func:`bayesid.estimation.fit.fit`)."""

    cache_residuals = False
    sim_seconds = float("nan")

    def __init__(self, problem, moves):
        self.ctxs, self.moves = problem.ctxs, moves
        self.n = problem.model.n_params
        self.J = sum(m.size for m in moves)
        self.ob = WindowObjective(problem.model, problem.ctxs, problem.sd, channels=problem.channels)
        self.names = list(problem.model.param_names) + [f"move{j}" for j in range(self.J)]
        self.n_simulations = 0
        self._placed = None

    def place(self, fractions) -> None:
        fractions = np.asarray(fractions, float)
        if self._placed is not None and np.array_equal(self._placed, fractions):
            return
        for ctx, lone in zip(self.ctxs, _split(self.moves, fractions)):
            ctx.retime(lone)
        self._placed = fractions.copy()

    def residuals(self, x):
        self.place(x[self.n :])
        self.n_simulations += 1
        return self.ob.residuals(x[: self.n])[0], False

    def timing_jacobian(self, x, r0) -> np.ndarray:
        """Forward differences of the residuals in the fractions (backwards near 1)."""
        Jf = np.empty((r0.size, self.J))
        for a in range(self.J):
            f = x[self.n :].copy()
            step = FRACTION_STEP if f[a] + FRACTION_STEP <= 1.0 else -FRACTION_STEP
            f[a] += step
            self.place(f)
            Jf[:, a] = (self.ob.residuals(x[: self.n])[0] - r0) / step
        self.n_simulations += self.J
        self.place(x[self.n :])
        return Jf

    def jacobian(self, x, r0=None):
        self.place(x[self.n :])
        r0, Jp = self.ob.jacobian(x[: self.n])
        self.n_simulations += self.n + 1
        return r0, np.hstack([Jp, self.timing_jacobian(x, r0)])

    def result_fields(self, x) -> dict:
        self.place(x[self.n :])
        return {}


def fit_retimed(problem, p0, moves, max_nfev: int = 60, bar: str | None = None) -> tuple:
    """The coefficients and the times of the movements within single intervals fitted together
    (module docstring), from ``p0`` with every movement mid-interval.

    Parameters
    ----------
    problem : WindowProblem
        The fit's problem (contexts with ``inputs="rate"``, channel weights, channels; its prior
        is not used).
    p0 : array_like, shape (n_params,)
        The start (the fit with the movements mid-interval).
    moves : list of ndarray
        Per track, the movements' intervals (:func:`moves_of`).
    max_nfev : int, default 60
        Least-squares iterations.
    bar : str, optional
        A label to show a progress bar.

    Returns
    -------
    p : ndarray, shape (n_params,)
        The coefficients at the joint optimum.
    retiming : Retiming
        The movements' fractions (the contexts are left retimed at them) and the residuals'
        Jacobian in them.
    """
    ob = _RetimedObjective(problem, moves)
    lo, hi = problem.model.bounds()
    n, J = ob.n, ob.J
    x0 = np.concatenate([np.asarray(p0, float), np.full(J, 0.5)])
    bounds = (np.concatenate([lo, np.zeros(J)]), np.concatenate([hi, np.ones(J)]))
    scale = np.concatenate([problem.model.scales(), np.full(J, 0.2)])
    opts = SolverOptions(max_nfev=max_nfev, ftol=1e-8, xtol=1e-8, gtol=1e-8, x_scale=scale)
    res = fit(ob, x0, bounds, opts, bar=bar, quiet=True)
    x = np.asarray(res.x, float)
    r0 = ob.residuals(x)[0]
    return x[:n], Retiming(moves, x[n:].copy(), ob.timing_jacobian(x, r0))


def project_timing(fitres, jf: np.ndarray) -> np.ndarray:
    """Project the movements' directions out of a fit's Jacobian in the coefficients, in place
    (module docstring: the Laplace covariance computed from it is then the coefficients' block
    of the joint covariance), and return the fractions' covariance factor.

    Parameters
    ----------
    fitres : FitResult
        The fit at the retimed inputs (its ``jac``: data rows first, then any prior's).
    jf : ndarray, shape (n_data_res, J)
        The data residuals' Jacobian in the fractions at the same point.

    Returns
    -------
    ndarray, shape (J,)
        ``sqrt(diag((J_f' (I - P_p) J_f)^-1))``: times the residual scale, the fractions' sds.
    """
    J = fitres.jac.toarray() if hasattr(fitres.jac, "toarray") else np.array(fitres.jac, float)
    n = fitres.model.n_params
    nd = jf.shape[0]
    Jp = J[:nd, :n].copy()
    if jf.shape[1] == 0:
        return np.zeros(0)
    coef = np.linalg.lstsq(jf, Jp, rcond=None)[0]
    J[:nd, :n] = Jp - jf @ coef
    fitres.jac = J
    # the fractions' own sds with the coefficients profiled out
    cf = np.linalg.lstsq(Jp, jf, rcond=None)[0]
    jf_perp = jf - Jp @ cf
    info = jf_perp.T @ jf_perp
    return np.sqrt(np.clip(np.diag(np.linalg.pinv(info)), 0.0, None))
