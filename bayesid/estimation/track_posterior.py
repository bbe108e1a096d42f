"""The posterior of a fitted model's parameters given a user's tracks (``bayesid sample``).

The objective is the one ``bayesid fit`` minimises (:class:`bayesid.estimation.windows.WindowObjective`:
the same windows, start rule, scored channels), read as a likelihood that does not count
serially correlated samples as independent evidence.

Error model
-----------
Per scored channel ``c`` the simulation errors ``e`` over the windows are Gaussian with an
unknown scale ``sigma_c`` and serially correlated within a window. At the fit's optimum the
integrated autocorrelation time ``k_c`` of the errors within windows (:func:`integrated_time`;
for AR(1) errors it is ``(1 + rho_c) / (1 - rho_c)``, :func:`ar1_noise` reports ``rho_c``) gives
the variance inflation, at most the samples per window (a window then counts as one independent
error per channel): the channel's ``n_c`` errors carry the evidence of ``n_eff,c = n_c / k_c``
independent ones. The lag-1 reading alone is too narrow: a persistent structural error under
white noise has a small lag-1 correlation, yet correlates at every lag. The
likelihood is tempered accordingly, ``p(e | theta, sigma)^(1 / k_c)`` (a power likelihood;
Grünwald & van Ommen 2017, Bayesian Analysis 12(4); for the AR(1) inflation of the variance of
a mean, Box, Jenkins & Reinsel, *Time Series Analysis*, Sec. 2.1), and ``sigma_c`` is
integrated out under the Jeffreys prior ``1 / sigma``:

    log p(theta | data) = sum_c -(n_eff,c / 2) log SSR_c(theta) + log p(theta) + const.

``sigma_c`` is then drawn for each posterior draw from its conditional posterior,
``sigma_c^2 = SSR_c / (k_c chi2(n_eff,c))`` (:meth:`ErrorModel.sigma_draws`). Window start
states of the fitted start rule are *profiled*, as in the fits: 6 per window, hundreds on a
real data set, fitted for every parameter vector by the objective (variable projection); the
per-track nuisances of effects (e.g. a wave phase) are held at their fitted values.

Prior: Gaussian where the vehicle file's ``[prior]`` section names the parameter (towing-tank
values with their error, :mod:`bayesid.data.priors`), uniform inside the model's bounds
otherwise (improper and flat along an unbounded parameter).

Sampling
--------
1. Mode and Laplace covariance of this posterior: a least-squares fit from the ``fit`` optimum
   with channel weights ``1 / (s_c sqrt(k_c))`` and the prior's residuals (the Gauss-Newton form
   of the log posterior at fixed ``SSR_c``), and ``(J^T J + prior precision)^-1`` of that fit.
2. Importance-reweighted Laplace (:func:`importance_laplace`): draws from a multivariate
   Student-t around the mode with the Laplace covariance, Pareto-smoothed importance weights
   and their diagnostic k-hat (Vehtari, Simpson, Gelman, Yao & Gabry 2024, JMLR 25(72); ArviZ
   ``psislw``): k-hat < 0.7 means the weighted draws estimate the posterior reliably.
3. Otherwise (or on request) MCMC: independent emcee ensembles
   (:func:`bayesid.estimation.sampling.run_ensembles`) started from the Laplace ball, run until
   the convergence verdict holds or the budget ends.

The draws are evaluated in chunks as tasks (:func:`bayesid.tasks.run_tasks`), journaled, so a
killed run resumes where it stopped and gives the same draws and weights, bit for bit.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..models import context as ctxmod
from ..tasks import Runner, Task, TaskError
from . import windows as wf
from .fit import FitResult
from .laplace import gauss_newton_covariance, psd_covariance
from .sampling import (
    ESS_BULK_MIN,
    Checkpoint,
    SamplerConfig,
    burn_in,
    diagnostics,
    run_ensembles,
    to_inference_data,
)

__all__ = [
    "KHAT_MAX",
    "ErrorModel",
    "ParameterPrior",
    "TrackPosterior",
    "StartLinearisation",
    "ar1_noise",
    "residual_layout",
    "integrated_time",
    "error_model",
    "posterior_mode",
    "importance_laplace",
    "resample",
    "evaluate_chunk",
    "jackknife_factor",
    "sample_tracks",
    "inference_data",
    "ImportanceOptions",
    "SampleOptions",
    "TrackPosteriorResult",
    "TRACK_SAMPLER",
    "METHODS",
]

#: Sokal's window constant of :func:`integrated_time`.
SOKAL_C = 5.0
#: Pareto k-hat above which importance weights are unreliable (Vehtari et al. 2024, Sec. 3.2.4).
KHAT_MAX = 0.7
#: Fewest importance draws that give a verdict (the least :class:`ImportanceOptions` accepts).
MIN_IMPORTANCE_DRAWS = 100


def ar1_noise(e: np.ndarray, win: np.ndarray) -> dict:
    """Lag-1 autocorrelation and scale of errors that restart every window (AR(1) within windows).

    Box, Jenkins & Reinsel, *Time Series Analysis*, Sec. 7.1 (AR(1) estimation).

    Parameters
    ----------
    e : ndarray, shape (n,)
        Errors of one channel in time order (NaN where not measured).
    win : ndarray, shape (n,)
        Window index of each error; pairs of consecutive errors count only inside one window.

    Returns
    -------
    dict
        ``rho`` (conditional least-squares estimate, clipped to [0, 0.999]), ``rho_se`` (its
        asymptotic standard error ``sqrt((1 - rho^2) / pairs)``), ``sigma`` (RMS of the errors,
        the marginal sd), ``innovation_sd`` (``sigma sqrt(1 - rho^2)``), ``n`` (finite errors),
        ``pairs``.

    Raises
    ------
    ValueError
        When ``e`` and ``win`` differ in shape or are not 1-D.
    """
    e, win = np.asarray(e, float), np.asarray(win)
    if e.shape != win.shape or e.ndim != 1:
        raise ValueError(f"errors {e.shape} and window indices {win.shape} must be equal 1-D shapes")
    ok = np.isfinite(e)
    same = (win[1:] == win[:-1]) & ok[1:] & ok[:-1]
    a, b = e[:-1][same], e[1:][same]
    n = int(ok.sum())
    sigma = float(np.sqrt(np.mean(e[ok] ** 2))) if n else float("nan")
    den = float(a @ a)
    rho = float(np.clip(a @ b / den, 0.0, 0.999)) if a.size > 2 and den > 0 else 0.0
    return {
        "rho": rho,
        "rho_se": float(math.sqrt(max(1.0 - rho**2, 0.0) / max(a.size, 1))),
        "sigma": sigma,
        "innovation_sd": float(sigma * math.sqrt(1.0 - rho**2)),
        "n": n,
        "pairs": int(a.size),
    }


def integrated_time(e: np.ndarray, win: np.ndarray, max_lag: int | None = None) -> float:
    """Integrated autocorrelation time of errors that restart every window: ``1 + 2 sum_k rho_k``
    over the pooled within-window autocorrelation ``rho_k`` (pairs ``k`` samples apart inside one
    window), summed up to a lag window whose length is chosen by Sokal's rule (the first lag
    ``M >= 5 tau(M)``; Sokal 1997, "Monte Carlo methods in statistical mechanics", as in emcee's
    ``integrated_time``).

    Unlike the AR(1) reading ``(1 + rho_1) / (1 - rho_1)``, it sees a persistent structural error
    under white noise: the lag-1 correlation of such a mixture is small, yet every lag keeps the
    structural share of the variance.

    Parameters
    ----------
    e : ndarray, shape (n,)
        Errors of one channel in time order (NaN where not measured).
    win : ndarray, shape (n,)
        Window index of each error.
    max_lag : int, optional
        Largest lag summed; default ``n - 1``.

    Returns
    -------
    float
        The time in samples (>= 1).

    Raises
    ------
    ValueError
        When ``e`` and ``win`` differ in shape or are not 1-D.
    """
    e, win = np.asarray(e, float), np.asarray(win)
    if e.shape != win.shape or e.ndim != 1:
        raise ValueError(f"errors {e.shape} and window indices {win.shape} must be equal 1-D shapes")
    x = np.where(np.isfinite(e), e, 0.0)
    ok = np.isfinite(e)
    var = float(x @ x)
    if var <= 0:
        return 1.0
    n = e.size
    L = n - 1 if max_lag is None else min(max_lag, n - 1)
    rho = np.zeros(L)
    for k in range(1, L + 1):
        same = (win[k:] == win[:-k]) & ok[k:] & ok[:-k]
        if not same.any():
            rho = rho[: k - 1]
            break
        # normalised per pair, so lags with fewer pairs inside the windows are not biased low
        rho[k - 1] = float(x[k:][same] @ x[:-k][same]) / same.sum() / (var / ok.sum())
    taus = 1.0 + 2.0 * np.cumsum(rho)
    # Sokal's automatic window: the first lag M with M >= c tau(M), c = 5
    m = np.arange(1, rho.size + 1) >= SOKAL_C * taus
    tau = taus[np.argmax(m)] if m.any() else (taus[-1] if taus.size else 1.0)
    return float(max(1.0, tau))


def residual_layout(ob) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
    """Which channel, window and measurement each column of ``ob``'s data residuals is.

    The columns follow :func:`bayesid.estimation.windows.window_residuals`: per track, per scored
    channel, one column per sample.

    Parameters
    ----------
    ob : WindowObjective
        The objective.

    Returns
    -------
    channels : list of str
        The scored channels, in order of appearance.
    channel_index : ndarray, shape (n_res,)
        Index into ``channels`` of each column.
    window_id : ndarray, shape (n_res,)
        Window of each column, unique over tracks.
    measured : ndarray of bool, shape (n_res,)
        Whether the column's sample is measured.
    """
    names, ci, wid, meas = [], [], [], []
    off = 0
    for ctx, w in zip(ob.ctxs, ob.wts):
        for c in ctx.channels:
            if c not in w:
                continue
            if c not in names:
                names.append(c)
            m = np.asarray(ctx.meas[c], float)
            ci.append(np.full(m.size, names.index(c)))
            wid.append(off + np.asarray(ctx.win))
            meas.append(np.isfinite(m))
        off += int(np.max(ctx.win)) + 1 if ctx.ts.size else 0
    return names, np.concatenate(ci), np.concatenate(wid), np.concatenate(meas)


@dataclass
class ErrorModel:
    """Per-channel error model of a fit's residuals (module docstring).

    Parameters
    ----------
    channels : tuple of str
        The C scored channel names.
    column : ndarray, shape (n_res,)
        Channel index of each residual column (-1: not measured, left out).
    n : ndarray, shape (C,)
        Measured errors per channel.
    rho : ndarray, shape (C,)
        Lag-1 autocorrelation within windows.
    rho_se : ndarray, shape (C,)
        Its standard error.
    inflation : ndarray, shape (C,)
        ``min(integrated autocorrelation time, samples per window)``.
    unit : ndarray, shape (C,)
        SI size of one residual unit (the fit's channel sd: residuals are errors / unit).
    sigma : ndarray, shape (C,)
        RMS error at the estimate (SI).
    """

    channels: tuple
    column: np.ndarray
    n: np.ndarray
    rho: np.ndarray
    rho_se: np.ndarray
    inflation: np.ndarray
    unit: np.ndarray
    sigma: np.ndarray

    @property
    def n_eff(self) -> np.ndarray:
        """(C,) effective independent errors per channel, ``n / inflation``."""
        return self.n / self.inflation

    def ssr(self, R: np.ndarray) -> np.ndarray:
        """Sum of squared residuals per channel.

        Parameters
        ----------
        R : ndarray, shape (B, n_res)
            Residual rows (residual units).

        Returns
        -------
        ndarray, shape (B, C)
            The sums of squares.
        """
        R = np.atleast_2d(R)
        if getattr(self, "_cols", None) is None:  # each channel's columns, found once
            self._cols = [np.flatnonzero(self.column == j) for j in range(len(self.channels))]
        out = np.empty((R.shape[0], len(self.channels)))
        for j, cols in enumerate(self._cols):
            Rj = R[:, cols]
            out[:, j] = np.einsum("ij,ij->i", Rj, Rj)
        return out

    def log_likelihood(self, ssr: np.ndarray) -> np.ndarray:
        """The tempered log-likelihood ``sum_c -(n_eff,c / 2) log SSR_c``.

        Parameters
        ----------
        ssr : ndarray, shape (B, C)
            Sums of squares per channel.

        Returns
        -------
        ndarray, shape (B,)
            The log-likelihood (non-positive or non-finite SSR: ``-inf``).
        """
        ssr = np.atleast_2d(ssr)
        with np.errstate(divide="ignore", invalid="ignore"):
            ll = -0.5 * np.log(ssr) @ self.n_eff
        return np.where(np.all(np.isfinite(ssr) & (ssr > 0), axis=1), ll, -np.inf)

    def sigma_draws(self, ssr: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Draws of each channel's error sd given the draws' sums of squares:
        ``sigma^2 = unit^2 SSR / (inflation chi2(n_eff))``, the conditional posterior of the
        tempered likelihood under the Jeffreys prior.

        Parameters
        ----------
        ssr : ndarray, shape (B, C)
            Sums of squares per channel.
        rng : numpy.random.Generator
            The random generator.

        Returns
        -------
        ndarray, shape (B, C)
            The sds, SI.
        """
        ssr = np.atleast_2d(ssr)
        chi = rng.chisquare(self.n_eff, size=ssr.shape)
        return self.unit * np.sqrt(ssr / (self.inflation * chi))

    def fit_sd(self) -> dict:
        """Channel sds whose squared inverse weights a least-squares fit like this posterior.

        Returns
        -------
        dict
            ``{channel: sigma_c sqrt(inflation_c)}``, SI.
        """
        return {c: float(s * math.sqrt(k)) for c, s, k in zip(self.channels, self.sigma, self.inflation)}

    def to_dict(self) -> dict:
        """JSON-able summary per channel.

        Returns
        -------
        dict
            ``{channel: {n, rho, rho_se, inflation, n_eff, sigma_at_mode}}``.
        """
        return {
            c: {
                "n": int(self.n[j]),
                "rho": float(self.rho[j]),
                "rho_se": float(self.rho_se[j]),
                "inflation": float(self.inflation[j]),
                "n_eff": float(self.n_eff[j]),
                "sigma_at_mode": float(self.sigma[j]),
            }
            for j, c in enumerate(self.channels)
        }


def error_model(ob, x) -> ErrorModel:
    """The error model of an objective's residuals.

    Parameters
    ----------
    ob : WindowObjective
        A :class:`~bayesid.estimation.windows.WindowObjective` without a prior.
    x : array_like
        Its variables (parameters and nuisances).

    Returns
    -------
    ErrorModel
        The per-channel error model at ``x``.

    Raises
    ------
    ValueError
        When a scored channel has no measured error at all.
    """
    names, ci, wid, meas = residual_layout(ob)
    R = ob.residuals_batch(np.asarray(x, float)[None])[0][0]
    unit = np.empty(len(names))
    for ctx, w in zip(ob.ctxs, ob.wts):
        for c in w:
            if c in names:
                unit[names.index(c)] = 1.0 / w[c]
    col = np.where(meas, ci, -1)
    rows = []
    for j, c in enumerate(names):
        sel = col == j
        if not sel.any():
            raise ValueError(f"channel {c}: no measured sample in any window")
        a = ar1_noise(R[sel], wid[sel])
        per_window = sel.sum() / max(np.unique(wid[sel]).size, 1)
        k = min(integrated_time(R[sel], wid[sel], max_lag=int(np.ceil(per_window))), max(1.0, float(per_window)))
        rows.append((a["n"], a["rho"], a["rho_se"], k, a["sigma"] * unit[j]))
    n, rho, rse, k, sig = (np.array(v, float) for v in zip(*rows))
    return ErrorModel(tuple(names), col, n, rho, rse, k, unit, sig)


@dataclass(frozen=True)
class ParameterPrior:
    """Prior of a model's parameters: Gaussian where ``gaussian`` is True (mean, sd), uniform on
    ``[lo, hi]`` otherwise (flat, improper along an unbounded parameter); the model's bounds hold
    for every parameter (the Gaussian is truncated there, as in the fits).

    Parameters
    ----------
    names : tuple of str
        The P parameter names.
    gaussian : ndarray of bool, shape (P,)
        Which parameters have a Gaussian prior.
    mean, sd : ndarray, shape (P,)
        The Gaussian priors' means and sds (NaN elsewhere).
    lo, hi : ndarray, shape (P,)
        The bounds.
    """

    names: tuple
    gaussian: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    @classmethod
    def of_model(cls, model, use_file: bool = True) -> ParameterPrior:
        """Gaussian priors from the vehicle file's ``[prior]`` section, uniform in
        ``model.bounds()`` otherwise.

        Parameters
        ----------
        model : SimulationModel
            The model.
        use_file : bool, default True
            Use the file's ``[prior]`` section (False: uniform everywhere).

        Returns
        -------
        ParameterPrior
            The prior.
        """
        gp = wf.GaussianPrior.of_model(model) if use_file else None
        P = model.n_params
        g, mean, sd = np.zeros(P, bool), np.full(P, np.nan), np.full(P, np.nan)
        if gp is not None and gp.idx.size:
            g[gp.idx], mean[gp.idx], sd[gp.idx] = True, gp.mean, gp.sd
        lo, hi = model.bounds()
        return cls(tuple(model.param_names), g, mean, sd, np.asarray(lo, float), np.asarray(hi, float))

    def logpdf(self, P: np.ndarray) -> np.ndarray:
        """Log density (up to a constant).

        Parameters
        ----------
        P : ndarray, shape (B, P)
            Parameter rows.

        Returns
        -------
        ndarray, shape (B,)
            The log density; ``-inf`` outside the bounds.
        """
        P = np.atleast_2d(P)
        inside = np.all((P >= self.lo) & (P <= self.hi), axis=1)
        z = (P[:, self.gaussian] - self.mean[self.gaussian]) / self.sd[self.gaussian]
        return np.where(inside, -0.5 * np.sum(z * z, axis=1), -np.inf)

    def marginal_sd(self) -> np.ndarray:
        """Prior sd of each parameter.

        Returns
        -------
        ndarray, shape (P,)
            The Gaussian's, or a uniform's width / sqrt(12) (inf when unbounded).
        """
        with np.errstate(invalid="ignore"):
            uni = (self.hi - self.lo) / math.sqrt(12.0)
        return np.where(self.gaussian, self.sd, np.where(np.isfinite(uni), uni, np.inf))

    def marginal_mean(self) -> np.ndarray:
        """Prior mean of each parameter.

        Returns
        -------
        ndarray, shape (P,)
            The mean (NaN for an unbounded uniform).
        """
        with np.errstate(invalid="ignore"):
            mid = 0.5 * (self.lo + self.hi)
        return np.where(self.gaussian, self.mean, np.where(np.isfinite(mid), mid, np.nan))

    def gaussian_prior(self) -> wf.GaussianPrior:
        """The Gaussian part as fit residuals (weight 1).

        Returns
        -------
        GaussianPrior
            The Gaussian priors (:class:`~bayesid.estimation.windows.GaussianPrior`).
        """
        idx = np.flatnonzero(self.gaussian)
        names = tuple(self.names[i] for i in idx)
        return wf.GaussianPrior(names, idx, self.mean[idx], self.sd[idx], 1.0)

    def precision(self, scales) -> np.ndarray:
        """Prior precision of the Laplace approximation: ``1 / sd^2`` of a Gaussian, a uniform's
        ``12 / width^2`` stand-in, and ``1 / (100 scale)^2`` along an unbounded parameter (a weak
        ridge that keeps the matrix invertible where the data say nothing).

        Parameters
        ----------
        scales : array_like, shape (P,)
            Typical sizes of the parameters.

        Returns
        -------
        ndarray, shape (P,)
            The precisions.
        """
        sd = self.marginal_sd()
        sd = np.where(np.isfinite(sd), sd, 100.0 * np.abs(np.asarray(scales, float)))
        return 1.0 / sd**2

    def to_dict(self) -> dict:
        """JSON-able: per parameter its kind and numbers.

        Returns
        -------
        dict
            ``{name: {"kind": "normal", "mean", "sd"} or {"kind": "uniform", "lower", "upper"}}``.
        """
        out = {}
        for j, n in enumerate(self.names):
            if self.gaussian[j]:
                out[n] = {"kind": "normal", "mean": float(self.mean[j]), "sd": float(self.sd[j])}
            else:
                out[n] = {"kind": "uniform", "lower": float(self.lo[j]), "upper": float(self.hi[j])}
        return out


#: Log posterior (nats) a draw's fitted start states may still gain by a Gauss-Newton step when
#: :class:`StartLinearisation` accepts them: the profile can read low by about this much.
START_TOL_NATS = 0.01
#: Gauss-Newton steps with the carried start-state Jacobian (:class:`StartLinearisation`) before a
#: draw falls back to the full start-state fit.
CHORD_STEPS = 2
#: Log-likelihood (nats) below the mode's beyond which :class:`StartLinearisation` fits a row's
#: start states fully: far in the tails the carried start-state Jacobian misleads the step.
FAR_NATS = 500.0
#: How window start states are profiled at each draw (:attr:`SampleOptions.start_profile`).
START_PROFILES = ("linearised", "full")


class StartLinearisation:
    """The fitted window start states of parameter rows near the posterior mode, continued from
    the mode's start states instead of fitted from scratch.

    The full profile fits every row's start offsets (6 per window) from the measured guess by
    Levenberg-Marquardt (:func:`bayesid.estimation.shooting.fit_starts`: up to 12 iterations of
    7 batched simulations). Near the mode ``p*`` the optimal offsets of a window move smoothly
    with the parameters; to first order ``D(p) = D* + S (p - p*)`` with
    ``S = -(J_d^T J_d)^+ J_d^T J_p`` (the implicit function theorem on the window's normal
    equations ``J_d^T r = 0``; ``J_d``, ``J_p`` the Jacobians of its residuals by its start
    offsets and by the parameters at ``(p*, D*)``; e.g. Golub & Pereyra 2003, Inverse Problems
    19(2), Sec. 2). Each row is simulated once from that prediction. A Gauss-Newton step with the
    start-state Jacobian carried to the row to first order, ``J_d(p) = J_d* + sum_k (p - p*)_k
    dJ_d/dp_k`` (secants along ``(e_k, S e_k)`` measured once at the mode: a chord step whose
    matrix follows the parameters; Kelley 1995, *Iterative Methods for Linear and Nonlinear
    Equations*, Ch. 5), then predicts how much log-likelihood the start states could still gain:
    below :data:`START_TOL_NATS` the row is done. Otherwise the step is taken (one more
    simulation; each window keeps the lower of its two costs), up to :data:`CHORD_STEPS` times.
    A row that would still gain more, or whose log-likelihood lies more than :data:`FAR_NATS`
    below the mode's (there the carried Jacobian, and with it the step's fixed point, drifts from
    the row's own), gets the full profile's own fit from the measured guess, each window keeping
    the better of that fit and where the continuation got: its start-state cost (the weighted
    sum of squares both fits minimise) never exceeds the full profile's. The profile is a minimum
    over the start states, so a row accepted early can only read low.

    Measured (``benchmarks/sample.py``, four synthetic KVLCC2 runs at 5 Hz without a velocity log,
    18 parameters, 108 windows): about 1.7 simulations per draw, 2.6 times the cost of a draw
    with a velocity log where the full profile costs 44 times; the log posterior within 0.01 nats
    of the full profile's for the draws within 30 nats of the best. Under a structural error the
    full profile's own 12 iterations are often the less converged fit
    (``tests/test_sample_budget.py``).

    Parameters
    ----------
    ob : WindowObjective
        The objective (:class:`~bayesid.estimation.windows.WindowObjective`, no prior) whose
        fitted start states are profiled; its weights are the start fits'.
    p : array_like, shape (n_params,)
        The mode.
    nuisance : array_like, shape (n_nuisance_total,)
        The held nuisances (may be empty).
    cov : ndarray, shape (n_params, n_params), optional
        The Laplace covariance: the secants of ``dJ_d/dp`` span half its sds (default
        ``1e-4 * model.scales()``).

    Attributes
    ----------
    stats : dict
        ``rows`` evaluated, ``simulated`` (row simulations, the first included; a full fit not
        counted), ``fallback`` (rows fitted fully) since construction, in this process.

    Raises
    ------
    ValueError
        A context whose start states are fitted on a lead-in rather than on its scored samples
        (a held-out context; the continuation reuses the scored residuals), or none with the
        fitted start rule.
    """

    def __init__(self, ob, p, nuisance, cov=None):
        from scipy import sparse

        from . import shooting

        model = ob.model
        self.p = np.asarray(p, float).copy()
        n_p = self.p.size
        x = np.concatenate([self.p, np.asarray(nuisance, float).ravel()])
        P1, nus = ob.split_rows(x[None])
        self.tracks = []
        held = [None] * len(ob.ctxs)
        off = 0
        for i, (ctx, w) in enumerate(zip(ob.ctxs, ob.wts)):
            n_i = sum(ctx.meas[c].size for c in ctx.channels if c in w)
            sl = slice(off, off + n_i)
            off += n_i
            if ctx.start != "fitted":
                continue
            if ctx.lead_steps:
                raise ValueError(
                    f"track {ctx.name!r}: start states fitted on a {ctx.leadin_s:g} s lead-in; the linearised "
                    "profile needs them fitted on the scored samples (a training context)"
                )
            D, _, rwin = shooting.fit_starts(model, ctx, P1, nus[i], w, return_jacobian=True)
            if rwin.size != n_i:
                raise ValueError(f"track {ctx.name!r}: {rwin.size} start-fit residuals, {n_i} scored ones")
            Jd = _start_jacobian(model, ctx, P1, nus[i], D, w)[0]  # (n_i, 6)
            W = ctx.W
            kr, kc, kv = [], [], []
            for wi in range(W):
                idx = np.flatnonzero(rwin == wi)
                if idx.size == 0:
                    continue
                U, sv, Vt = shooting.window_svd(Jd[idx])
                Kw = (Vt.T / sv) @ U.T  # (6, n_w): the pseudo-inverse of J_d
                kr.append(np.repeat(6 * wi + np.arange(6), idx.size))
                kc.append(np.tile(idx, 6))
                kv.append(Kw.ravel())
            self.tracks.append(
                {
                    "i": i,
                    "slice": sl,
                    "W": W,
                    "D": D[0].ravel(),
                    "K": sparse.csr_matrix(
                        (np.concatenate(kv), (np.concatenate(kr), np.concatenate(kc))), shape=(6 * W, n_i)
                    ),
                    "Jd": Jd,
                    "G": sparse.csr_matrix((np.ones(n_i), (rwin, np.arange(n_i))), shape=(W, n_i)),
                    "rwin": rwin,
                }
            )
            held[i] = D
        if not self.tracks:
            raise ValueError("no track has fitted start states: nothing to linearise")
        # J_p: forward differences of the residuals with the start states held at the mode's,
        # the steps of WindowObjective.jacobian
        hi = np.asarray(model.bounds()[1], float)
        h = 1e-6 * np.maximum(np.asarray(model.scales(), float), 1e-8)
        sign = np.where(self.p + h > hi, -1.0, 1.0)
        X = np.repeat(x[None], n_p + 1, axis=0)
        X[1:, :n_p] += np.diag(sign * h)
        Pp, nup = ob.split_rows(X)
        R = wf.window_residuals(
            model, ob.ctxs, ob.wts, Pp, nup, [None if d is None else np.repeat(d, n_p + 1, axis=0) for d in held]
        )[0]
        for tr in self.tracks:
            sl = tr["slice"]
            Jp = ((R[1:, sl] - R[:1, sl]) / (sign * h)[:, None]).T  # (n_i, P)
            tr["S"] = -np.asarray(tr["K"] @ Jp)  # (6W, P)
        self.r_mode = R[:1].copy()  # the residuals at the mode (1, n_res)
        # dJ_d/dp_k: secants of the start-state Jacobian along (e_k, S e_k)
        if cov is not None and np.all(np.diag(cov) > 0):
            h2 = 0.5 * np.sqrt(np.diag(np.asarray(cov, float)))
        else:
            h2 = 1e-4 * np.maximum(np.abs(np.asarray(model.scales(), float)), 1e-8)
        h2 = np.where(self.p + h2 > hi, -h2, h2)
        X = np.repeat(x[None], n_p, axis=0)
        X[:, :n_p] += np.diag(h2)
        Pk, nuk = ob.split_rows(X)
        for tr in self.tracks:
            i = tr["i"]
            Dk = (tr["D"][None] + (tr["S"] * h2[None]).T).reshape(n_p, tr["W"], 6)
            Jk = _start_jacobian(model, ob.ctxs[i], Pk, nuk[i], Dk, ob.wts[i])  # (P, n_i, 6)
            _carry(tr, (Jk - tr["Jd"][None]) / h2[:, None, None])
        self.stats = {"rows": 0, "simulated": 0, "fallback": 0}

    def _step(self, tr, r, dP):
        """The Gauss-Newton step of one track's start offsets for residual rows ``r`` (b, n_i)
        with the Jacobian carried to ``dP`` (b, P): (step (b, 6W), predicted residuals (b, n_i))."""
        b, W, P = r.shape[0], tr["W"], dP.shape[1]
        idx, pad = tr["pad"], tr["pad_ok"]
        rw = np.where(pad[None], r[:, idx], 0.0).transpose(1, 2, 0)  # (W, m, b): each window's rows
        # per window J^T r and J^T J of J = J_d* + sum_k dP_k dJ_k, as batched matrix products
        g = np.matmul(tr["Jw"].transpose(0, 2, 1), rw).transpose(2, 0, 1)  # (b, W, 6)
        g += np.einsum("wkib,bk->bwi", np.matmul(tr["dJw"], rw).reshape(W, P, 6, b), dP)
        A = (
            tr["M0"].reshape(1, -1) + dP @ tr["M1"] + (dP[:, :, None] * dP[:, None]).reshape(b, -1) @ tr["M2"]
        ).reshape(b, W, 6, 6)
        # a ridge of 1e-10 of the diagonal keeps a window whose start is not observable solvable
        A += (1e-10 * np.einsum("bwii->bw", A)[..., None, None] + 1e-300) * np.eye(6)
        try:
            d = -np.linalg.solve(A, g[..., None])[..., 0]  # (b, W, 6)
        except np.linalg.LinAlgError:
            d = -np.einsum("bwij,bwj->bwi", np.linalg.pinv(A, rcond=1e-10, hermitian=True), g)
        d[~np.isfinite(d)] = 0.0
        # the residuals the step predicts, r + J d
        V = np.einsum("bk,bwi->wkib", dP, d).reshape(W, P * 6, b)
        Jd = np.matmul(tr["Jw"], d.transpose(1, 2, 0)) + np.matmul(tr["dJw"].transpose(0, 2, 1), V)  # (W, m, b)
        rp = r.copy()
        rp[:, idx[pad]] += Jd.transpose(2, 0, 1)[:, pad]
        return d.reshape(b, 6 * W), rp

    def _keep_better(self, ob, rows, P, nus, trial, starts, R, Rraw) -> None:
        """Simulate ``rows`` (indices into ``R``; their parameters ``P`` and nuisances ``nus``)
        from the ``trial`` start offsets (per track (b, W, 6)) and, window by window, keep them
        where they lower the window's cost: ``starts``, ``R`` and ``Rraw`` updated in place."""
        from .shooting import PENALTY

        for tr in self.tracks:
            i, sl = tr["i"], tr["slice"]
            ctx, w = ob.ctxs[i], ob.wts[i]
            S = ob.model.simulate(ctx, P, nus[i], starts=trial[i])
            new = np.concatenate([e * w[c] for c, e in ctxmod.errors(ctx, S).items() if c in w], axis=1)
            rn = np.where(np.isfinite(new), new, PENALTY)
            ro = R[rows, sl]
            acc = np.asarray(tr["G"] @ (rn * rn).T).T < np.asarray(tr["G"] @ (ro * ro).T).T  # (b, W)
            starts[i][rows] = np.where(acc[..., None], trial[i], starts[i][rows])
            cols = acc[:, tr["rwin"]]
            R[rows, sl] = np.where(cols, rn, ro)
            Rraw[rows, sl] = np.where(cols, new, Rraw[rows, sl])

    def residuals(self, ob, X, errors: ErrorModel) -> tuple[np.ndarray, np.ndarray]:
        """Residuals of rows of ``ob``'s variables with the start states profiled as above.

        Parameters
        ----------
        ob : WindowObjective
            The objective the linearisation was made for.
        X : ndarray, shape (B, n)
            Variables (parameters and the held nuisances).
        errors : ErrorModel
            The error model that turns sums of squares into log-likelihood (the tolerance is in
            nats).

        Returns
        -------
        R : ndarray, shape (B, n_res)
            The residuals (a diverged window's samples hold ``PENALTY``).
        diverged : ndarray of bool, shape (B,)
            The rows with a diverged window.
        """
        from . import shooting

        X = np.atleast_2d(X)
        P, nus = ob.split_rows(X)
        B = P.shape[0]
        dP = P - self.p
        starts = [None] * len(ob.ctxs)
        for tr in self.tracks:
            starts[tr["i"]] = (tr["D"] + dP @ tr["S"].T).reshape(B, tr["W"], 6)
        Rraw = np.concatenate(
            [
                e * w[c]
                for ctx, w, nu, st in zip(ob.ctxs, ob.wts, nus, starts)
                for c, e in ctxmod.errors(ctx, ob.model.simulate(ctx, P, nu, starts=st)).items()
                if c in w
            ],
            axis=1,
        )
        R = np.where(np.isfinite(Rraw), Rraw, shooting.PENALTY)
        self.stats["rows"] += B
        self.stats["simulated"] += B
        active = np.arange(B)
        ll = errors.log_likelihood(errors.ssr(R))
        for step in range(CHORD_STEPS + 1):
            # the step and the log-likelihood it would gain, from the residuals alone
            Rp = R[active]
            deltas = {}
            with _one_blas_thread():  # small products: threads only contend (and sum in another order)
                for tr in self.tracks:
                    deltas[tr["i"]], Rp[:, tr["slice"]] = self._step(tr, Rp[:, tr["slice"]], dP[active])
            pred = errors.log_likelihood(errors.ssr(Rp)) - ll[active]
            need = ~(pred < START_TOL_NATS)
            active = active[need]
            if active.size == 0 or step == CHORD_STEPS:
                break
            trial = [None] * len(ob.ctxs)
            for tr in self.tracks:
                trial[tr["i"]] = starts[tr["i"]][active] + deltas[tr["i"]][need].reshape(-1, tr["W"], 6)
            self._keep_better(
                ob, active, P[active], [None if v is None else v[active] for v in nus], trial, starts, R, Rraw
            )
            self.stats["simulated"] += active.size
            ll[active] = errors.log_likelihood(errors.ssr(R[active]))
        # far in the tails the carried Jacobian (and the step's fixed point) drifts from the row's own
        far = np.flatnonzero(ll < errors.log_likelihood(errors.ssr(self.r_mode))[0] - FAR_NATS)
        active = np.union1d(active, far)
        if active.size:
            # the full profile's own fit (from the measured guess), each window keeping the better
            # of it and where the continuation got: a cost never above the full profile's
            Pa = P[active]
            nua = [None if v is None else v[active] for v in nus]
            cold = [None] * len(ob.ctxs)
            for tr in self.tracks:
                i = tr["i"]
                cold[i] = shooting.fit_starts(ob.model, ob.ctxs[i], Pa, nua[i], ob.wts[i])
            self._keep_better(ob, active, Pa, nua, cold, starts, R, Rraw)
            self.stats["fallback"] += active.size
        return R, ~np.all(np.isfinite(Rraw), axis=1)


_BLAS = None


def _one_blas_thread():
    """A context that runs BLAS on one thread (threadpoolctl; the controller made once)."""
    global _BLAS
    if _BLAS is None:
        from threadpoolctl import ThreadpoolController

        _BLAS = ThreadpoolController()
    return _BLAS.limit(limits=1, user_api="blas")


def _carry(tr: dict, dJ: np.ndarray) -> None:
    """Store in a track's entry of :class:`StartLinearisation` what its steps need of the carried
    Jacobian ``J = J_d* + sum_k dP_k dJ_k``, window by window (rows padded to the longest
    window, ``m``): ``pad`` (W, m) the residual row of each slot and ``pad_ok`` whether it holds
    one; ``Jw`` (W, m, 6) of ``J_d*`` and ``dJw`` (W, 6 P, m) of the ``dJ_k``; the moments
    ``M0`` (W 36,) ``= J_d*^T J_d*``, ``M1`` (P, W 36) ``= J_d*^T dJ_k + dJ_k^T J_d*`` and ``M2``
    (P P, W 36) ``= dJ_k^T dJ_l`` (``J^T J``, exact in ``dP``)."""
    Jd, rwin, W = tr["Jd"], tr["rwin"], tr["W"]
    P = dJ.shape[0]
    rows = [np.flatnonzero(rwin == wi) for wi in range(W)]
    m = max(max((r.size for r in rows), default=1), 1)
    pad = np.zeros((W, m), np.int64)
    ok = np.zeros((W, m), bool)
    for wi, r in enumerate(rows):
        pad[wi, : r.size], ok[wi, : r.size] = r, True
    Jw = np.where(ok[..., None], Jd[pad], 0.0)  # (W, m, 6)
    dJw = np.where(ok[None, ..., None], dJ[:, pad], 0.0)  # (P, W, m, 6)
    tr["pad"], tr["pad_ok"], tr["Jw"] = pad, ok, Jw
    tr["dJw"] = np.ascontiguousarray(dJw.transpose(1, 0, 3, 2).reshape(W, P * 6, m))
    tr["M0"] = np.einsum("wmi,wmj->wij", Jw, Jw).ravel()
    M = np.einsum("wmi,kwmj->kwij", Jw, dJw)
    tr["M1"] = (M + np.transpose(M, (0, 1, 3, 2))).reshape(P, -1)
    tr["M2"] = np.einsum("kwmi,lwmj->klwij", dJw, dJw).reshape(P * P, -1)


def _start_jacobian(model, ctx, P, nu, D, weights) -> np.ndarray:
    """(B, n_rows, 6) Jacobian of :func:`~bayesid.estimation.shooting.lead_residuals` by the
    start offsets at rows ``P`` (B, n_params), nuisances ``nu`` and offsets ``D`` (B, W, 6):
    forward differences with ``START_STEP``, as :func:`~bayesid.estimation.shooting.fit_starts`
    takes them (entries of a diverged window 0)."""
    from .shooting import PENALTY, START_STEP, lead_residuals

    P = np.atleast_2d(P)
    B, W = P.shape[0], ctx.W
    Dp = np.repeat(np.asarray(D, float), 7, axis=0).reshape(B, 7, W, 6)
    for j in range(6):
        Dp[:, j + 1, :, j] += START_STEP[j]
    nu7 = None if nu is None else np.repeat(np.atleast_2d(nu), 7, axis=0)
    R = lead_residuals(model, ctx, np.repeat(P, 7, axis=0), nu7, Dp.reshape(B * 7, W, 6), weights).reshape(B, 7, -1)
    J = (R[:, 1:] - R[:, :1]) / START_STEP[None, :, None]  # (B, 6, n)
    J[~np.isfinite(J) | (np.abs(R[:, 1:]) >= PENALTY)] = 0.0
    return np.transpose(J, (0, 2, 1))


class TrackPosterior:
    """Vectorised log posterior ``(B, P) -> (B,)`` of a model's parameters on tracks (module
    docstring); :meth:`evaluate` also returns the per-channel sums of squares.

    Parameters
    ----------
    ob : WindowObjective
        :class:`~bayesid.estimation.windows.WindowObjective` of the tracks (no prior; its
        nuisances are held at ``nuisance``).
    errors : ErrorModel
        The error model of ``ob``.
    prior : ParameterPrior
        The prior over ``ob.model.param_names``.
    nuisance : array_like, shape (n_nuisance_total,), optional
        Fixed nuisance variables appended to each row (may be empty).

    Attributes
    ----------
    linear : StartLinearisation or None
        Set by :meth:`linearise_starts`: fitted start states are then profiled from the mode's
        linearisation; None: fitted from the measured guess for every row (the full profile).

    Raises
    ------
    ValueError
        When the prior's names differ from the model's parameters.
    """

    def __init__(self, ob, errors: ErrorModel, prior: ParameterPrior, nuisance=None):
        if list(prior.names) != list(ob.model.param_names):
            raise ValueError(f"prior over {list(prior.names)}, model parameters {ob.model.param_names}")
        self.ob, self.errors, self.prior = ob, errors, prior
        self.nuisance = np.zeros(0) if nuisance is None else np.asarray(nuisance, float).ravel()
        self.names = list(ob.model.param_names)
        self.linear = None

    def linearise_starts(self, p, cov=None) -> StartLinearisation | None:
        """Profile fitted window start states from their linearisation at ``p`` from now on
        (:class:`StartLinearisation`), or fully again with ``p`` None.

        Parameters
        ----------
        p : array_like, shape (P,), or None
            The posterior mode (None: back to the full profile).
        cov : ndarray, shape (P, P), optional
            The Laplace covariance (sets the secants of the carried start-state Jacobian).

        Returns
        -------
        StartLinearisation or None
            The linearisation (None when ``p`` is None).

        Raises
        ------
        ValueError
            As :class:`StartLinearisation` (no fitted start rule, or one fitted on a lead-in).
        """
        self.linear = None if p is None else StartLinearisation(self.ob, p, self.nuisance, cov)
        return self.linear

    def evaluate(self, P) -> tuple[np.ndarray, np.ndarray]:
        """Log posterior and per-channel sums of squares of parameter rows. Rows outside the
        prior's support are not simulated (-inf, SSR NaN); a diverged window gives -inf.

        Parameters
        ----------
        P : array_like, shape (B, P)
            Parameter rows.

        Returns
        -------
        log_prob : ndarray, shape (B,)
            The log posterior.
        ssr : ndarray, shape (B, C)
            The per-channel SSR.
        """
        P = np.atleast_2d(np.asarray(P, float))
        lp = self.prior.logpdf(P)
        ssr = np.full((P.shape[0], len(self.errors.channels)), np.nan)
        ok = np.isfinite(lp)
        if ok.any():
            X = np.hstack([P[ok], np.repeat(self.nuisance[None], ok.sum(), axis=0)])
            if self.linear is None:
                R, diverged = self.ob.residuals_batch(X)
            else:
                R, diverged = self.linear.residuals(self.ob, X, self.errors)
            s = self.errors.ssr(R)
            s[diverged] = np.nan
            ssr[ok] = s
            lp[ok] = lp[ok] + self.errors.log_likelihood(s)
        return np.where(np.isfinite(lp), lp, -np.inf), ssr

    def __call__(self, P) -> np.ndarray:
        return self.evaluate(P)[0]


def posterior_mode(post: TrackPosterior, p0, max_nfev: int = 30) -> dict:
    """Mode and Laplace covariance of a posterior (module docstring, step 1).

    Parameters
    ----------
    post : TrackPosterior
        The posterior.
    p0 : array_like, shape (P,)
        The start.
    max_nfev : int, default 30
        Least-squares iterations.

    Returns
    -------
    dict
        ``p`` (P,), ``cov`` (P, P) symmetric PSD, ``fisher`` (P, P) the data's information
        ``J^T J`` (without the prior), ``jac`` (n_res, P) the weighted data Jacobian, and ``fit``
        (the :class:`~bayesid.estimation.fit.FitResult`).
    """
    ob, em = post.ob, post.errors
    model = ob.model
    gp = post.prior.gaussian_prior()
    nu0 = None
    if post.nuisance.size:
        nu0 = [post.nuisance[i * model.n_nuisance : (i + 1) * model.n_nuisance] for i in range(len(ob.ctxs))]
    f = wf.fit_model(
        wf.WindowProblem(
            model, ob.ctxs, em.fit_sd(), channels=ob.channels, max_nfev=max_nfev, prior=gp if gp.idx.size else None
        ),
        np.asarray(p0, float),
        nu0,
    )
    n = model.n_params
    J = f.jac[:, :n]
    J = J.toarray() if hasattr(J, "toarray") else np.asarray(J)
    if gp.idx.size:
        J = J[: J.shape[0] - gp.idx.size]
    # the measured columns only: an unmeasured sample's residual is a constant
    Jm = J[np.flatnonzero(em.column >= 0)] if J.shape[0] == em.column.size else J
    F = Jm.T @ Jm
    cov = psd_covariance(gauss_newton_covariance(Jm, prior_precision=post.prior.precision(model.scales())))
    return {"p": np.array(f.p), "cov": cov, "fisher": F, "jac": Jm, "fit": f}


def jackknife_factor(fold_estimates, cov, min_folds: int = 3) -> dict:
    """How much more the estimate moves between runs than the posterior says: the delete-a-group
    jackknife variance ``(G - 1) s^2`` of the leave-one-run-out estimates, their scatter ``s`` read
    robustly as 1.4826 x the median absolute deviation (Efron & Stein 1981, Ann. Stat. 9(3);
    the folds of :func:`bayesid.estimation.calibration.leave_one_run_out`) against the posterior
    variance, per parameter, median over the parameters, at least 1.

    Under a structural error the coefficients that fit best depend on which manoeuvres were run
    (a pseudo-true value per data set): the scatter of the posterior means across independent
    data sets then exceeds any within-data error model's widths. The folds measure that scatter
    on the user's own runs; dividing every channel's effective sample count by the factor (a
    temperature of the likelihood) widens the posterior to it.

    Parameters
    ----------
    fold_estimates : array_like, shape (G, P)
        Estimates with one group of runs left out each.
    cov : ndarray, shape (P, P)
        The posterior covariance to compare with.
    min_folds : int, default 3
        Fewest folds for a factor.

    Returns
    -------
    dict
        ``factor``, ``median_ratio``, ``per_parameter`` (P,) ratios, ``n_folds``; factor 1 with
        fewer than ``min_folds`` folds.
    """
    F = np.asarray(fold_estimates, float)
    if F.ndim != 2 or F.shape[0] < min_folds:
        return {
            "factor": 1.0,
            "median_ratio": None,
            "per_parameter": [],
            "n_folds": int(F.shape[0]) if F.ndim == 2 else 0,
        }
    G = F.shape[0]
    # (G - 1) s^2, the jackknife variance, with s the folds' scatter read robustly (1.4826 MAD):
    # one fold whose refit failed (a run whose absence leaves the rest unidentifiable) must not
    # flatten the posterior
    mad = np.median(np.abs(F - np.median(F, axis=0)), axis=0)
    v = (G - 1) * (1.4826 * mad) ** 2
    d = np.diag(cov)
    ok = d > 0
    ratio = np.where(ok, v / np.where(ok, d, 1.0), np.nan)
    med = float(np.nanmedian(ratio)) if ok.any() else float("nan")
    return {
        "factor": max(1.0, med) if ok.any() else 1.0,
        "median_ratio": med,
        "per_parameter": [float(r) for r in ratio],
        "n_folds": int(G),
    }


def evaluate_chunk(post: TrackPosterior, rows) -> dict:
    """Task: log posterior and per-channel SSR of parameter rows, JSON-able.

    Parameters
    ----------
    post : TrackPosterior
        The posterior.
    rows : list of list of float
        Parameter rows.

    Returns
    -------
    dict
        ``log_prob`` (list) and ``ssr`` (list of lists), None for a non-finite value.
    """
    lp, ssr = post.evaluate(np.asarray(rows, float))
    return {
        "log_prob": [float(v) if np.isfinite(v) else None for v in lp],
        "ssr": [[float(v) if np.isfinite(v) else None for v in r] for r in ssr],
    }


def _as_array(values) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], float)


@dataclass(frozen=True)
class ImportanceOptions:
    """The importance-reweighted Laplace stage of :func:`sample_tracks` (:func:`importance_laplace`).

    Parameters
    ----------
    n_draws : int, default 4000
        Student-t proposal draws (at least 100).
    df : float, default 5.0
        Their degrees of freedom (positive).
    chunk : int, default 16
        Draws evaluated per task (per-row cost is lowest at batches of 13-19 on the real data sets).

    Raises
    ------
    ValueError
        Fewer than 100 draws, ``df`` not positive, or ``chunk`` below 1.
    """

    n_draws: int = 4000
    df: float = 5.0
    chunk: int = 16

    def __post_init__(self):
        if int(self.n_draws) < MIN_IMPORTANCE_DRAWS or not self.df > 0 or int(self.chunk) < 1:
            raise ValueError(
                f"importance sampling needs at least 100 draws, df > 0 and chunks of 1 or more, got "
                f"{self.n_draws}, {self.df} and {self.chunk}"
            )


@dataclass(frozen=True)
class SampleOptions:
    """How :func:`sample_tracks` samples.

    Parameters
    ----------
    method : {"auto", "importance", "mcmc"}, default "auto"
        ``"importance"`` (importance-reweighted Laplace), ``"mcmc"`` (emcee ensembles), or
        ``"auto"``: importance first, MCMC when its k-hat or ESS fails.
    use_prior : bool, default True
        Gaussian priors of the vehicle file's ``[prior]`` section (else uniform in the bounds).
    seed : int, default 0
        The one seed of every random draw (proposal, resampling, noise scales, ensembles).
    max_minutes : float, default 20.0
        Wall budget of the whole sampling (mode, importance draws, MCMC), from the start of
        :func:`sample_tracks`. The mode always finishes; the importance stage stops drawing when
        its share is spent (all that is left with ``method="importance"``; with ``"auto"``
        half of it, or all when the draws so far already pass the verdict, the MCMC getting the
        rest) and weights the draws it has; the MCMC stops after its first block past its share. The result's ``budget`` says what was cut.
    max_steps : int, optional
        Step budget of the MCMC refinement (steps per walker); None: that of
        :data:`TRACK_SAMPLER`. A run that stops on it gives the same chains on any machine from
        the same seed; one that stops on ``max_minutes`` depends on the machine's speed.
    start_profile : {"linearised", "full"}, default "linearised"
        How fitted window start states are profiled at each draw: ``"linearised"`` from the
        mode's start states and their sensitivity to the parameters, refined only where a
        Gauss-Newton step would still gain (:class:`StartLinearisation`; about one simulation per
        draw); ``"full"``: fitted from the measured guess for every draw (about 60 simulations).
        Measured start states are not profiled: no difference then.

    Raises
    ------
    ValueError
        An unknown method or start profile, or a budget that is not positive.
    """

    method: str = "auto"
    use_prior: bool = True
    seed: int = 0
    max_minutes: float = 20.0
    max_steps: int | None = None
    start_profile: str = "linearised"

    def __post_init__(self):
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, not {self.method!r}")
        if not self.max_minutes > 0:
            raise ValueError(f"max_minutes must be positive, not {self.max_minutes}")
        if self.max_steps is not None and not int(self.max_steps) >= 1:
            raise ValueError(f"max_steps must be a positive number of steps, not {self.max_steps}")
        if self.start_profile not in START_PROFILES:
            raise ValueError(f"start_profile must be one of {', '.join(START_PROFILES)}, not {self.start_profile!r}")


METHODS = ("auto", "importance", "mcmc")

#: The MCMC refinement of :func:`sample_tracks`: two emcee ensembles (between-ensemble R-hat),
#: differential-evolution moves, run until converged (or the wall budget), stranded walkers redrawn.
TRACK_SAMPLER = SamplerConfig(
    n_ensembles=2,
    moves="de",
    min_steps=500,
    max_steps=200_000,
    until_converged=True,
    redraw_stranded=True,
)


def importance_laplace(
    post: TrackPosterior,
    center,
    cov,
    rng: np.random.Generator,
    options: ImportanceOptions = ImportanceOptions(),
    *,
    runner: Runner = Runner(),
    max_seconds: float | None = None,
    soft_seconds: float | None = None,
) -> dict:
    """Importance-reweighted Laplace approximation of ``post`` (module docstring, step 2).

    Draws ``options.n_draws`` rows from a multivariate Student-t (``options.df`` degrees of
    freedom) with location ``center`` and shape ``cov`` (scipy.stats.multivariate_t) truncated to
    the prior's bounds (draws outside are redrawn), evaluates ``post`` on them in chunks of
    ``options.chunk`` rows as tasks of ``runner`` (:class:`bayesid.tasks.Runner`, whose journal
    resumes a killed run) and weights them by ``post / proposal`` with Pareto smoothing
    (``arviz.psislw``).

    The chunks run in waves: the first chunk alone, whose wall time gives the estimate of the
    whole stage (said through ``runner.say``), then waves of a few seconds each. With
    ``max_seconds``, no wave starts that would end past it: the stage stops drawing and weights
    the draws evaluated so far (the first ones drawn, so a cut run's draws are a prefix of an
    uncut one's), and says so in ``cut``. With ``soft_seconds`` the stage stops there already,
    unless the draws so far pass the verdict (Pareto k-hat below :data:`KHAT_MAX`, ESS at least
    :data:`~bayesid.estimation.sampling.ESS_BULK_MIN`, 100 draws or more): then it goes on to
    ``max_seconds``. The first chunk always runs.

    Parameters
    ----------
    post : TrackPosterior
        The posterior.
    center : array_like, shape (P,)
        Location of the proposal (the mode).
    cov : ndarray, shape (P, P)
        Its shape (the Laplace covariance).
    rng : numpy.random.Generator
        Draws the proposal.
    options : ImportanceOptions, default ImportanceOptions()
        Draws, degrees of freedom and chunk size (which check ``n_draws`` >= 100 and ``df`` > 0).
    runner : Runner, default Runner()
        Runs the chunks as tasks, says the estimate and shows a progress bar over the draws.
    max_seconds : float, optional
        Wall budget of the stage, s (None: all draws).
    soft_seconds : float, optional
        Where the stage stops unless its draws already pass the verdict, s (``sample_tracks``'
        ``method="auto"``, whose MCMC needs the rest of the budget only after a failed verdict).

    Returns
    -------
    dict
        ``draws`` (N, P), ``log_prob`` (N,), ``ssr`` (N, C), ``log_proposal`` (N,),
        ``log_weights`` (N,) smoothed and normalised, ``weights`` (N,), ``k_hat``, ``ess``
        (``1 / sum w^2``), ``reliable`` (k-hat < :data:`KHAT_MAX`), ``finite`` (draws with a
        finite posterior); ``planned`` (``options.n_draws``), ``done`` (N, the draws evaluated),
        ``cut`` (the budget stopped the stage before ``planned``), ``seconds`` and
        ``seconds_per_draw`` (one worker's, measured on the first chunk and updated wave by wave).

    Raises
    ------
    ValueError
        Fewer than 1 % of the proposal inside the bounds, a chunk task failed (named), or fewer
        than 10 draws with a finite posterior (after a cut: naming the budget).
    """
    from scipy.stats import multivariate_t

    t0 = time.perf_counter()
    n_draws, df, chunk = options.n_draws, options.df, options.chunk
    center = np.asarray(center, float)
    scale = np.where(np.diag(cov) > 0, np.sqrt(np.clip(np.diag(cov), 0, None)), 1.0)
    # drawn in units of the Laplace sds: the shape matrix is then a correlation matrix, well scaled
    corr = cov / np.outer(scale, scale) + 1e-12 * np.eye(center.size)
    dist = multivariate_t(loc=np.zeros(center.size), shape=corr, df=df, allow_singular=True)
    # the proposal truncated to the prior's support (the parameters' bounds): draws outside are
    # redrawn; the truncated density is q / P(inside), a constant the self-normalised weights ignore
    lo, hi = post.prior.lo, post.prior.hi
    kept, drawn = [], 0
    while sum(k.shape[0] for k in kept) < n_draws:
        V = dist.rvs(size=n_draws, random_state=rng).reshape(n_draws, -1)
        drawn += n_draws
        kept.append(V[np.all((center + V * scale >= lo) & (center + V * scale <= hi), axis=1)])
        if drawn >= 100 * n_draws and sum(k.shape[0] for k in kept) < n_draws:
            raise ValueError(
                "fewer than 1 % of the proposal's draws lie inside the parameters' bounds: the mode sits "
                "outside or on a bound the Laplace approximation cannot describe (use --method mcmc)"
            )
    U = np.vstack(kept)[:n_draws]
    draws = center + U * scale
    logq = dist.logpdf(U) - np.sum(np.log(scale))
    tasks = [
        Task(f"draws{i:05d}", {"first": i, "n": min(chunk, n_draws - i)}, (post, draws[i : i + chunk].tolist()))
        for i in range(0, n_draws, chunk)
    ]

    def passes(res) -> bool:  # the verdict on the draws evaluated so far
        lp = np.concatenate([_as_array(r["log_prob"]) for r in res if not isinstance(r, TaskError)])
        raw = np.where(np.isfinite(lp), lp, -np.inf) - logq[: lp.size]
        if lp.size < MIN_IMPORTANCE_DRAWS or np.isfinite(raw).sum() < 10:
            return False
        w, k = _psis(raw)
        return bool(k < KHAT_MAX and 1.0 / np.sum(w**2) >= ESS_BULK_MIN)

    res, per_chunk = _run_in_waves(tasks, n_draws, runner, t0, (max_seconds, soft_seconds, passes))
    failed = [r for r in res if isinstance(r, TaskError)]
    if failed:
        raise ValueError(f"{len(failed)} chunk(s) of posterior draws failed; first: {failed[0]}")
    done = sum(t.params["n"] for t in tasks[: len(res)])
    cut = done < n_draws
    draws, logq = draws[:done], logq[:done]
    lp = np.concatenate([_as_array(r["log_prob"]) for r in res])
    ssr = np.vstack([np.array([[np.nan if v is None else v for v in row] for row in r["ssr"]]) for r in res])
    lp = np.where(np.isfinite(lp), lp, -np.inf)
    raw = lp - logq
    finite = np.isfinite(raw)
    if finite.sum() < 10:
        if cut:
            raise ValueError(
                f"the wall budget ({max_seconds:.0f} s for the importance stage) ended it after {done} of {n_draws} "
                f"draws, {int(finite.sum())} of them with a finite posterior: too few for any weights; one chunk of "
                f"{chunk} draws took {per_chunk:.1f} s, so give --max-minutes of at least "
                f"{max(1, math.ceil(per_chunk * 100 / chunk / 60))} for 100 draws"
            )
        raise ValueError(
            f"only {int(finite.sum())} of {done} draws have a finite posterior: the Laplace approximation "
            "is far from the posterior's support (check the fit, or use --method mcmc)"
        )
    w, k = _psis(raw)
    return {
        "draws": draws,
        "log_prob": lp,
        "ssr": ssr,
        "log_proposal": logq,
        "log_weights": np.log(np.where(w > 0, w, np.finfo(float).tiny)),
        "weights": w,
        "k_hat": k,
        "ess": float(1.0 / np.sum(w**2)),
        "reliable": bool(k < KHAT_MAX),
        "finite": int(finite.sum()),
        "planned": int(n_draws),
        "done": int(done),
        "cut": bool(cut),
        "seconds": time.perf_counter() - t0,
        "seconds_per_draw": per_chunk / max(tasks[0].params["n"], 1),  # the last pace
    }


def _psis(raw: np.ndarray) -> tuple[np.ndarray, float]:
    """Pareto-smoothed, normalised importance weights of log ratios ``raw`` (N,) (-inf: weight
    0) and their k-hat (``arviz.psislw``)."""
    import warnings

    import arviz as az

    finite = np.isfinite(raw)
    lw = np.full(raw.size, -np.inf)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ArviZ warns on k-hat > 0.7; the verdict reports it
        sm, k = az.psislw(raw[finite] - raw[finite].max())
    lw[finite] = np.asarray(sm, float)
    w = np.exp(lw - np.max(lw))
    return w / w.sum(), float(np.asarray(k))


#: Wall time of one wave of importance chunks, s: the granularity of the budget and the bar.
WAVE_SECONDS = 5.0


def _run_in_waves(tasks, n_draws: int, runner: Runner, t0: float, limits) -> tuple[list, float]:
    """Run the chunk tasks of :func:`importance_laplace` in waves within its budget from ``t0``,
    ``limits`` = (``max_seconds``, ``soft_seconds``, ``passes(results)``; docstring of
    :func:`importance_laplace`): the results of the tasks run (a prefix) and the seconds of one
    chunk on one worker (the first chunk's, averaged with each wave's pace)."""
    max_seconds, soft_seconds, passes = limits
    limit = max_seconds if soft_seconds is None else soft_seconds

    say = runner.say
    label = runner.bar("importance draws")
    bar = None
    seconds = {}

    def on_done(task, result, secs):
        seconds[task.key] = secs

    res: list = []
    try:
        first = runner.run(evaluate_chunk, tasks[:1], on_done=on_done)
        res += first
        key = tasks[0].key
        rec = runner.journal.get(tasks[0]) if runner.journal is not None else None
        per_chunk = seconds.get(key, rec["seconds"] if rec is not None else time.perf_counter() - t0)
        per_chunk = per_chunk if np.isfinite(per_chunk) else time.perf_counter() - t0
        n1 = tasks[0].params["n"]
        workers = 1 if runner.scheduler is not None else int(runner.jobs)
        est = per_chunk * (len(tasks) - 1) / max(workers, 1)
        msg = (
            f"importance: {n_draws} draws, about {est + per_chunk:.0f} s ({per_chunk / n1:.3g} s per draw measured on "
            f"the first chunk of {n1}" + (f", {workers} workers" if workers > 1 else "") + ")"
        )
        left = None if limit is None else limit - (time.perf_counter() - t0)
        if left is not None and est > left:
            fit = int(max(left, 0.0) / max(per_chunk, 1e-9) * max(workers, 1)) * tasks[0].params["n"]
            msg += f"; its budget of {max(left, 0.0):.0f} s more allows about {min(fit, n_draws - n1) + n1} draws"
        say(msg)
        if label is not None:  # after the estimate, so that the bar stays the last line
            from tqdm import tqdm

            bar = tqdm(total=n_draws, initial=n1, desc=label, unit="draw", file=sys.stderr)
        wave = max(workers, int(WAVE_SECONDS / max(per_chunk, 1e-9)) // max(workers, 1) * max(workers, 1))
        i = 1
        while i < len(tasks):
            n = min(wave, len(tasks) - i)
            if limit is not None:
                left = limit - (time.perf_counter() - t0)
                # whole rounds of the workers that end within the budget (half a chunk of slack)
                rounds = int((left + 0.5 * per_chunk) / max(per_chunk, 1e-9))
                n = min(n, rounds * max(workers, 1))
                if n < 1:
                    if limit != max_seconds and passes(res):
                        done = sum(t.params["n"] for t in tasks[:i])
                        say(f"importance: reliable already after {done} draws; going on within the whole budget")
                        limit = max_seconds
                        continue
                    break
            tw = time.perf_counter()
            part = runner.run(evaluate_chunk, tasks[i : i + n], on_done=on_done)
            res += part
            if all(t.key in seconds for t in tasks[i : i + n]):  # none from the journal: this machine's pace now
                pace = (time.perf_counter() - tw) / max(1, -(-n // max(workers, 1)))
                per_chunk = 0.5 * (per_chunk + pace)
            if bar is not None:
                bar.update(sum(t.params["n"] for t in tasks[i : i + n]))
            i += n
    finally:
        if bar is not None:
            bar.close()
    return res, float(per_chunk)


def resample(weights, n: int, rng: np.random.Generator) -> np.ndarray:
    """Indices drawn with probabilities ``weights`` by systematic resampling (Kitagawa 1996,
    J. Comput. Graph. Stat. 5(1)): the importance-weighted draws as an unweighted sample.

    Parameters
    ----------
    weights : array_like, shape (N,)
        Non-negative weights (normalised here).
    n : int
        Number of indices.
    rng : numpy.random.Generator
        The random generator (one uniform draw).

    Returns
    -------
    ndarray, shape (n,)
        Indices into the weights.
    """
    w = np.asarray(weights, float)
    c = np.cumsum(w / w.sum())
    c[-1] = 1.0
    u = (rng.random() + np.arange(n)) / n
    return np.searchsorted(c, u, side="left")


@dataclass
class TrackPosteriorResult:
    """What :func:`sample_tracks` found.

    Parameters
    ----------
    names : list of str
        The parameter names, ``(P,)``.
    prior : ParameterPrior
        The prior used.
    errors : ErrorModel
        The per-channel error model (AR(1) inflation, effective samples).
    mode : dict
        :func:`posterior_mode`: ``p`` (P,), ``cov`` (P, P), ``fisher``, ``jac``.
    method : str
        The method that gave the draws (``"importance"`` or ``"mcmc"``).
    importance : dict or None
        :func:`importance_laplace`'s result.
    mcmc : dict or None
        ``{"result", "idata", "diagnostics", "burn"}`` of the emcee refinement.
    draws : ndarray, shape (N, P)
        Unweighted posterior draws.
    log_prob : ndarray, shape (N,)
        Their log posterior.
    sigma : ndarray, shape (N, C)
        Noise-scale draws per channel (SI).
    verdict : dict
        ``converged``, ``text`` and the criteria of the method used.
    seconds : dict
        Wall time per stage (s).
    seconds_per_evaluation : float
        One parameter row of the objective (s).
    n_windows : int
        Windows of the objective.
    between_runs : dict
        :func:`jackknife_factor` of the leave-one-run-out estimates.
    budget : dict
        What the wall budget allowed: ``max_minutes``, ``seconds`` (the whole sampling),
        ``start_profile`` (``"linearised"``, ``"full"``, or ``"measured"`` when no start state is
        fitted) and ``stages``, per stage run (``mode``, ``importance``, ``mcmc``, ``noise_scales``) a dict
        ``{"unit", "planned", "done", "seconds", "estimate_s", "cut"}``: ``cut`` True when the
        budget stopped the stage before ``planned`` (``done`` of them ran; a skipped MCMC has
        ``done`` 0); ``estimate_s`` the time the stage was expected to need in full (None when
        not estimated).
    """

    names: list
    prior: object
    errors: object
    mode: dict
    method: str
    importance: dict | None
    mcmc: dict | None
    draws: np.ndarray
    log_prob: np.ndarray
    sigma: np.ndarray
    verdict: dict
    seconds: dict
    seconds_per_evaluation: float
    n_windows: int
    between_runs: dict
    budget: dict = dataclasses.field(default_factory=dict)

    @property
    def p(self) -> np.ndarray:
        """The posterior mode, shape (P,), in the order of :attr:`names`: the same convention as
        a fit's :attr:`bayesid.estimation.fit.FitResult.p` (``mode["p"]``)."""
        return np.asarray(self.mode["p"], float)

    @property
    def cov(self) -> np.ndarray:
        """The Laplace covariance at the mode, shape (P, P) (``mode["cov"]``); the draws'
        spread is ``np.cov(draws, rowvar=False)``."""
        return np.asarray(self.mode["cov"], float)


#: Share of the budget left after the mode that the importance stage may use under
#: ``method="auto"`` unless its draws already pass the verdict (the MCMC refinement gets the rest).
IMPORTANCE_SHARE_AUTO = 0.5
#: Fewest MCMC steps per walker worth starting within the budget: with less time left the MCMC is
#: skipped (and recorded as cut).
MIN_MCMC_STEPS = 20


def sample_tracks(
    problem: wf.WindowProblem,
    p0,
    options: SampleOptions = SampleOptions(),
    *,
    importance: ImportanceOptions = ImportanceOptions(),
    sampler: SamplerConfig = TRACK_SAMPLER,
    folds=None,
    checkpoint: Checkpoint | None = None,
    runner: Runner = Runner(),
) -> TrackPosteriorResult:
    """The posterior of a fitted model's parameters given its training tracks (module docstring),
    from the fit's optimum ``p0``.

    Parameters
    ----------
    problem : WindowProblem
        The fit's objective: the model (e.g. from a ``model.json``), the contexts of the training
        tracks (the fit's windows and start rule), its channel weights and scored channels
        (:class:`~bayesid.estimation.windows.WindowProblem`; its prior and iterations are not used:
        the prior is ``options.use_prior``'s).
    p0 : array_like, shape (P,)
        The fit's estimate.
    options : SampleOptions, default SampleOptions()
        Method, prior, seed, the wall budget of the whole sampling and the start-state profile.
    importance : ImportanceOptions, default ImportanceOptions()
        The importance stage's draws, their Student-t degrees of freedom and chunk size.
    sampler : SamplerConfig, default TRACK_SAMPLER
        The MCMC refinement's ensembles (:data:`TRACK_SAMPLER`); its wall budget is what
        ``options.max_minutes`` leaves, its progress bar from the runner (and its blocks are
        shortened when one would take more than a fifth of that budget).
    folds : array_like, shape (G, P), optional
        Leave-one-run-out estimates (``model.json``'s calibration folds): with 3 or more, the
        effective sample counts are divided by :func:`jackknife_factor`.
    checkpoint : Checkpoint, optional
        The MCMC's HDF5 checkpoint and its identity (:class:`bayesid.estimation.sampling.Checkpoint`).
    runner : Runner, default Runner()
        Where the importance draws and the MCMC ensembles run (its journal records the importance
        draws), and where progress messages go: before each stage, what it will do and how long
        it should take.

    Returns
    -------
    TrackPosteriorResult
        The mode, the draws, the noise scales, the verdict of the method used and what the
        budget cut (``budget``).

    Raises
    ------
    ValueError
        An unreadable or foreign checkpoint or journal; too few finite draws.

    Examples
    --------
    The posterior of the coefficients :func:`~bayesid.estimation.identification.identify` fitted,
    given its training tracks, as ``bayesid sample`` computes it (``method="auto"``, the default,
    refines by MCMC when the importance stage is not reliable):

    >>> import bayesid
    >>> vehicle = bayesid.load_any_vehicle("nps_auv2")
    >>> train = [bayesid.read_csv(f) for f in ("z10.csv", "z20.csv")]
    >>> res = bayesid.identify(vehicle, train, bayesid.FitOptions(free=("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"), dt=0.1))
    >>> ctxs = [res.model.context(t, res.window_s, start=res.start_rule) for t in train]
    >>> problem = bayesid.WindowProblem(res.model, ctxs, res.fit_sd, res.channels)
    >>> post = bayesid.sample_tracks(problem, res.fit.p, bayesid.SampleOptions(method="importance"))
    >>> post.method, post.draws.shape
    ('importance', (4000, 6))
    >>> print(post.verdict["text"])  # doctest: +SKIP
    """
    say = runner.say
    clock = _Budget(60.0 * float(options.max_minutes))
    secs, stages = clock.secs, clock.stages
    post, per_eval, sim_row = _track_posterior(problem, p0, options.use_prior, say)
    P = len(post.names)
    fit_iter = per_eval + (P + 1) * sim_row  # a profiled residual and a Jacobian with held starts
    say(
        f"posterior mode and Laplace covariance: up to 30 least-squares iterations of about {fit_iter:.2g} s, "
        f"at most about {30 * fit_iter:.0f} s"
    )
    mode = posterior_mode(post, p0)
    between = jackknife_factor(folds if folds is not None else np.zeros((0, len(post.names))), mode["cov"])
    if between["factor"] > 1.0:
        say(
            f"between-run scatter (jackknife of {between['n_folds']} folds): effective samples divided by "
            f"{between['factor']:.2f}"
        )
        post.errors.inflation = post.errors.inflation * between["factor"]
        mode = posterior_mode(post, mode["p"])
    row_s = per_eval
    if post.ob.vp and options.start_profile == "linearised":
        try:
            post.linearise_starts(mode["p"], mode["cov"])
        except ValueError as exc:  # a lead-in context: the full profile
            say(f"start states profiled in full: {exc}")
        else:
            row_s = _row_seconds(post, mode)
            say(
                f"start states from the mode's linearisation: {1e3 * row_s:.1f} ms per parameter row near the mode "
                f"(the full profile: {1e3 * per_eval:.1f} ms)"
            )
    secs["mode"] = clock.elapsed()
    stages["mode"] = _stage("fits", 1, 1, secs["mode"], 30 * fit_iter, False)
    seeds = np.random.SeedSequence(options.seed).spawn(4)  # proposal, resampling, noise scales, ensembles
    imp, mc, verdict = None, None, None
    used = options.method
    if options.method in ("importance", "auto"):
        imp, verdict, row_s = _importance_stage(post, mode, (options, importance), seeds[0], clock, runner, row_s)
        used = "importance"
    if options.method == "mcmc" or (options.method == "auto" and not verdict["converged"]):
        mc, verdict = _mcmc_stage(
            post, mode, (options, importance, sampler), seeds[3], clock, runner, checkpoint, (row_s, verdict, imp)
        )
        used = "mcmc" if mc is not None else used
    if used == "mcmc" and imp is None and mc is None:
        raise ValueError(
            f"the {clock.seconds / 60:g} min budget was spent before the MCMC could start (the mode took "
            f"{secs['mode']:.0f} s); give a larger --max-minutes"
        )
    rng_r, rng_s = np.random.default_rng(seeds[1]), np.random.default_rng(seeds[2])
    draws, lp, ssr = _kept_draws(
        post, imp if used == "importance" else None, mc, importance.n_draws, rng_r, clock, runner, row_s
    )
    sigma = post.errors.sigma_draws(ssr, rng_s)
    secs["total"] = clock.elapsed()
    return TrackPosteriorResult(
        names=post.names,
        prior=post.prior,
        errors=post.errors,
        mode=mode,
        method=used,
        importance=imp,
        mcmc=mc,
        draws=draws,
        log_prob=lp,
        sigma=sigma,
        verdict=verdict,
        seconds=secs,
        seconds_per_evaluation=row_s,
        n_windows=int(sum(c.W for c in problem.ctxs)),
        between_runs=between,
        budget={
            "max_minutes": float(options.max_minutes),
            "seconds": secs["total"],
            "start_profile": "measured" if not post.ob.vp else ("linearised" if post.linear is not None else "full"),
            "stages": stages,
        },
    )


@dataclass
class _Budget:
    """The wall budget of one :func:`sample_tracks` run (``seconds``, from its start) and what
    each stage took (``secs``) and did (``stages``, :func:`_stage`)."""

    seconds: float
    t0: float = dataclasses.field(default_factory=time.perf_counter)
    secs: dict = dataclasses.field(default_factory=dict)
    stages: dict = dataclasses.field(default_factory=dict)

    def elapsed(self) -> float:
        """Seconds since the start."""
        return time.perf_counter() - self.t0

    def left(self) -> float:
        """Seconds of the budget left (negative when overrun)."""
        return self.seconds - self.elapsed()


def _importance_stage(post, mode: dict, opts: tuple, seed, clock: _Budget, runner: Runner, row_s: float) -> tuple:
    """The importance-reweighted Laplace stage of :func:`sample_tracks` within the budget left
    (``opts``: ``(SampleOptions, ImportanceOptions)``): ``(result, verdict, seconds per row)``."""
    options, importance = opts
    say, budget_s, secs, stages = runner.say, clock.seconds, clock.secs, clock.stages
    t = time.perf_counter()
    limit = max(0.0, clock.left())
    soft = IMPORTANCE_SHARE_AUTO * limit if options.method == "auto" else None
    say(
        f"importance-reweighted Laplace: {importance.n_draws} Student-t draws (budget {limit:.0f} s of "
        f"{budget_s / 60:g} min"
        + ("" if soft is None else f"; {soft:.0f} s unless the draws so far already pass the verdict")
        + ")"
    )
    imp = importance_laplace(
        post,
        mode["p"],
        mode["cov"],
        np.random.default_rng(seed),
        importance,
        runner=runner,
        max_seconds=limit,
        soft_seconds=soft,
    )
    secs["importance"] = time.perf_counter() - t
    row_s = imp["seconds_per_draw"] or row_s
    stages["importance"] = _stage(
        "draws",
        imp["planned"],
        imp["done"],
        secs["importance"],
        imp["seconds_per_draw"] * imp["planned"] / _workers(runner),
        imp["cut"],
    )
    if imp["cut"]:
        say(
            f"importance: the budget ended the stage after {imp['done']} of {imp['planned']} draws "
            f"({secs['importance']:.0f} s)"
        )
    return imp, _importance_verdict(imp, importance.n_draws), row_s


def _mcmc_stage(post, mode: dict, opts: tuple, seed, clock: _Budget, runner: Runner, checkpoint, prior: tuple) -> tuple:
    """The MCMC stage of :func:`sample_tracks` on the budget left, less the time the noise
    scales of the kept draws will take (``opts``: ``(SampleOptions, ImportanceOptions,
    SamplerConfig)``; ``prior``: ``(seconds per row, the importance verdict or None, its result
    or None)``): ``(result or None when the budget cannot pay for it, verdict)``."""
    options, importance, sampler = opts
    row_s, verdict, imp = prior
    say, budget_s, secs, stages = runner.say, clock.seconds, clock.secs, clock.stages
    P = len(post.names)
    mc = None
    t = time.perf_counter()
    steps = sampler.max_steps if options.max_steps is None else int(options.max_steps)
    W, E = sampler.walkers(P), sampler.n_ensembles
    step_s = E * W * row_s  # one step of every walker of every ensemble
    # the noise scales of the kept draws are evaluated afterwards: keep time for them
    reserve = min(importance.n_draws * row_s / _workers(runner), 0.25 * max(clock.left(), 0.0))
    wall = clock.left() - reserve
    if wall < MIN_MCMC_STEPS * step_s:
        say(
            f"MCMC skipped: {max(wall, 0.0):.0f} s of the {budget_s / 60:g} min budget left, "
            f"{MIN_MCMC_STEPS} steps of {E} ensembles x {W} walkers need about {MIN_MCMC_STEPS * step_s:.0f} s"
        )
        stages["mcmc"] = _stage("steps", steps, 0, 0.0, steps * step_s, True)
        if verdict is not None:  # without an importance stage the caller says the budget was spent
            verdict = dict(
                verdict,
                text=verdict["text"] + f" MCMC was not run: the {budget_s / 60:g} min budget was spent.",
            )
    else:
        check_every = sampler.check_every
        if check_every * step_s > 0.2 * wall:  # a block must not overrun the budget by much
            check_every = max(1, int(0.2 * wall / step_s))
        say(
            f"MCMC: {E} emcee ensembles x {W} walkers until converged, {steps} steps or {wall / 60:.1f} min; "
            f"about {step_s:.3g} s per step ({1e3 * row_s:.1f} ms per walker), {sampler.min_steps} steps "
            f"about {sampler.min_steps * step_s:.0f} s; the budget allows about {int(wall / step_s)} steps"
        )
        cfg = dataclasses.replace(
            sampler,
            max_wall_s=wall,
            min_steps=min(sampler.min_steps, steps),
            max_steps=steps,
            check_every=check_every,
            progress=runner.bar("mcmc") is not None,
        )
        mc = _mcmc(post, mode, cfg, np.random.default_rng(seed), checkpoint, runner)
        secs["mcmc"] = time.perf_counter() - t
        r = mc["result"]
        stages["mcmc"] = _stage(
            "steps", steps, int(r.n_steps), secs["mcmc"], steps * step_s, r.stop_reason == "max_wall_s"
        )
        diag = mc["diagnostics"]
        verdict = dict(
            {k: v for k, v in diag.items() if not isinstance(v, dict)},
            method="mcmc",
            text=diag["verdict"],
            per_parameter={k: diag[k] for k in ("rhat", "ess_bulk", "ess_tail")},
            importance_first=None if imp is None else {"k_hat": imp["k_hat"], "ess": imp["ess"]},
        )
    return mc, verdict


def _kept_draws(
    post, imp: dict | None, mc: dict | None, n_draws: int, rng, clock: _Budget, runner: Runner, row_s: float
) -> tuple:
    """The draws :func:`sample_tracks` returns: ``n_draws`` resampled from the importance
    stage's weighted draws (``imp``), or thinned from the MCMC chains (``mc``) with the SSR of
    as many as the budget left allows for the noise scales: ``(draws, log posterior, SSR)``."""
    say, stages = runner.say, clock.stages
    if imp is not None:
        idx = resample(imp["weights"], n_draws, rng)
        draws, lp, ssr = imp["draws"][idx], imp["log_prob"][idx], imp["ssr"][idx]
    else:
        t = time.perf_counter()
        res = mc["result"]
        flat = res.chains[:, mc["burn"] :].reshape(-1, len(post.names))
        keep = np.unique(np.linspace(0, flat.shape[0] - 1, min(n_draws, flat.shape[0])).astype(int))
        draws = flat[keep]
        # the SSR of the kept draws, for the noise scales, as many as the budget allows (their
        # log posterior is the chains')
        fits = max(100, int(max(clock.left(), 0.0) / max(row_s, 1e-9)))
        if fits >= keep.size:
            lp, ssr = post.evaluate(draws)
            done = keep.size
        else:
            lp = res.log_prob[:, mc["burn"] :].reshape(-1)[keep]
            sub = np.unique(np.linspace(0, keep.size - 1, fits).astype(int))
            ssr = post.evaluate(draws[sub])[1]
            done = sub.size
            say(f"noise scales from {done} of the {keep.size} kept draws: the budget is spent")
        stages["noise_scales"] = _stage(
            "draws", int(keep.size), int(done), time.perf_counter() - t, keep.size * row_s, done < keep.size
        )
    return draws, lp, ssr


def _stage(unit: str, planned: int, done: int, seconds: float, estimate_s, cut: bool) -> dict:
    """One stage's entry of :attr:`TrackPosteriorResult.budget`."""
    est = None if estimate_s is None or not np.isfinite(estimate_s) else float(estimate_s)
    return {
        "unit": unit,
        "planned": int(planned),
        "done": int(done),
        "seconds": float(seconds),
        "estimate_s": est,
        "cut": bool(cut),
    }


def _workers(runner: Runner) -> int:
    """Worker processes the runner's tasks share (1 on a Dask scheduler: unknown here)."""
    return 1 if runner.scheduler is not None else max(1, int(runner.jobs))


def _row_seconds(post: TrackPosterior, mode: dict, n: int = 8) -> float:
    """Seconds per row of :meth:`TrackPosterior.evaluate` on ``n`` rows of the Laplace
    approximation around the mode (a generator of its own: no draw of the run changes)."""
    rng = np.random.default_rng(20260)
    X = rng.multivariate_normal(mode["p"], mode["cov"], size=n, method="eigh")
    X = np.clip(X, post.prior.lo, post.prior.hi)
    t = time.perf_counter()
    post.evaluate(X)
    return (time.perf_counter() - t) / n


def _track_posterior(problem, p0, use_prior: bool, say) -> tuple:
    """(:class:`TrackPosterior` of the fit's objective at ``p0`` with its error model and prior,
    seconds of one evaluation per parameter row, seconds of one row's simulation with its start
    states given: what a least-squares Jacobian column costs)."""
    model, ctxs = problem.model, problem.ctxs
    ob = wf.WindowObjective(model, ctxs, problem.sd, p0, channels=problem.channels)
    nuisance = np.zeros(0)
    if model.n_nuisance:
        fixed = FitResult.fixed(model, p0, len(ctxs))
        nuisance = np.concatenate(wf.heldout_nuisance(model, fixed, ctxs, problem.sd))
    x0 = np.concatenate([np.asarray(p0, float), nuisance])
    post = TrackPosterior(ob, error_model(ob, x0), ParameterPrior.of_model(model, use_prior), nuisance)
    X = np.repeat(x0[None], 8, axis=0)
    held = None
    if ob.vp:  # the start states at p0, fitted once and held for the 8 rows
        from .shooting import fit_starts

        P1, nus = ob.split_rows(x0[None])
        held = [
            np.repeat(fit_starts(model, c, P1, nus[i], ob.wts[i]), 8, axis=0) if c.start == "fitted" else None
            for i, c in enumerate(ctxs)
        ]
    t = time.perf_counter()
    ob.residuals_batch(X, held)
    sim_row = (time.perf_counter() - t) / 8
    if ob.vp:
        t = time.perf_counter()
        post.evaluate(np.repeat(np.asarray(p0, float)[None], 8, axis=0))
        per_eval = (time.perf_counter() - t) / 8
    else:
        per_eval = sim_row
    say(f"one evaluation: {1e3 * per_eval:.1f} ms per parameter row (batch of 8)")
    return post, per_eval, sim_row


def _importance_verdict(imp: dict, n_draws: int) -> dict:
    """The verdict of an importance stage: reliable when k-hat < :data:`KHAT_MAX` and the
    importance ESS reaches :data:`~bayesid.estimation.sampling.ESS_BULK_MIN`; after a budget cut
    with fewer draws than :class:`ImportanceOptions` allows at least, too few for a verdict."""
    ok_k, ok_e = imp["k_hat"] < KHAT_MAX, imp["ess"] >= ESS_BULK_MIN
    done = imp.get("done", n_draws)
    cut = f" The wall budget ended the importance stage after {done} of {n_draws} draws." if imp.get("cut") else ""
    if done < MIN_IMPORTANCE_DRAWS:
        return {
            "method": "importance",
            "converged": False,
            "k_hat": imp["k_hat"],
            "k_hat_max": KHAT_MAX,
            "ess": imp["ess"],
            "ess_min": int(ESS_BULK_MIN),
            "text": (
                f"Too few draws for a verdict: {done} of {n_draws} evaluated (at least {MIN_IMPORTANCE_DRAWS} "
                f"needed); Pareto k-hat {imp['k_hat']:.2f} and importance ESS {imp['ess']:.0f} are not reliable." + cut
            ),
        }
    return {
        "method": "importance",
        "converged": bool(ok_k and ok_e),
        "k_hat": imp["k_hat"],
        "k_hat_max": KHAT_MAX,
        "ess": imp["ess"],
        "ess_min": int(ESS_BULK_MIN),
        "text": (
            f"{'Reliable' if ok_k and ok_e else 'Not reliable'}: Pareto k-hat {imp['k_hat']:.2f} "
            f"{'<' if ok_k else '>='} {KHAT_MAX} and importance ESS {imp['ess']:.0f} "
            f"{'>=' if ok_e else '<'} {ESS_BULK_MIN:.0f} of {done} draws ({imp['finite']} with a finite posterior)."
            + cut
        ),
    }


def _mcmc(post, mode: dict, cfg: SamplerConfig, rng, checkpoint, runner) -> dict:
    """The emcee refinement from the mode: ``{"result", "idata", "diagnostics", "burn"}``."""
    res = run_ensembles(post, mode["p"], mode["cov"], post.names, cfg, rng, checkpoint=checkpoint, runner=runner)
    burn = burn_in(res)
    idata = to_inference_data(res, burn=burn)
    return {"result": res, "idata": idata, "diagnostics": diagnostics(idata, res), "burn": burn}


def inference_data(res: TrackPosteriorResult, attrs: dict | None = None):
    """ArviZ InferenceData of a :func:`sample_tracks` result: ``posterior`` (one variable per
    parameter; MCMC: every walker a chain; importance: the resampled draws as one chain),
    ``sample_stats`` (``lp``), ``noise_scale`` (``sigma_<channel>`` draws, SI, dim ``sample``) and,
    for importance sampling, ``importance`` (the raw proposal draws, their log posterior, log
    proposal density and smoothed log weights, dim ``proposal``).

    Parameters
    ----------
    res : TrackPosteriorResult
        The result.
    attrs : dict, optional
        Attributes put on the posterior group (None values left out).

    Returns
    -------
    arviz.InferenceData
        The groups above.
    """
    import warnings

    import arviz as az
    import xarray as xr

    if res.method == "mcmc":
        idata = res.mcmc["idata"]
    else:
        d = res.draws
        idata = az.from_dict(
            posterior={n: d[None, :, j] for j, n in enumerate(res.names)},
            sample_stats={"lp": res.log_prob[None]},
        )
    idata.posterior.attrs.update({k: v for k, v in (attrs or {}).items() if v is not None})
    groups = {
        "noise_scale": xr.Dataset(
            {f"sigma_{c}": ("sample", res.sigma[:, j]) for j, c in enumerate(res.errors.channels)}
        )
    }
    imp = res.importance
    if imp is not None:
        groups["importance"] = xr.Dataset(
            {
                **{n: ("proposal", imp["draws"][:, j]) for j, n in enumerate(res.names)},
                "log_prob": ("proposal", imp["log_prob"]),
                "log_proposal": ("proposal", imp["log_proposal"]),
                "log_weight": ("proposal", imp["log_weights"]),
            },
            attrs={"k_hat": imp["k_hat"], "ess": imp["ess"]},
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # groups outside ArviZ's schema are allowed, with a warning
        idata.add_groups(groups)
    return idata
