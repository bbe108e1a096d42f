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
from dataclasses import dataclass

import numpy as np

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
            R, diverged = self.ob.residuals_batch(X)
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
        wf.FitProblem(
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
        if int(self.n_draws) < 100 or not self.df > 0 or int(self.chunk) < 1:
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
        Wall budget of the MCMC refinement (from the start of the sampling).
    max_steps : int, optional
        Step budget of the MCMC refinement (steps per walker); None: that of
        :data:`TRACK_SAMPLER`. A run that stops on it gives the same chains on any machine from
        the same seed; one that stops on ``max_minutes`` depends on the machine's speed.

    Raises
    ------
    ValueError
        An unknown method or a budget that is not positive.
    """

    method: str = "auto"
    use_prior: bool = True
    seed: int = 0
    max_minutes: float = 20.0
    max_steps: int | None = None

    def __post_init__(self):
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, not {self.method!r}")
        if not self.max_minutes > 0:
            raise ValueError(f"max_minutes must be positive, not {self.max_minutes}")
        if self.max_steps is not None and not int(self.max_steps) >= 1:
            raise ValueError(f"max_steps must be a positive number of steps, not {self.max_steps}")


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
) -> dict:
    """Importance-reweighted Laplace approximation of ``post`` (module docstring, step 2).

    Draws ``options.n_draws`` rows from a multivariate Student-t (``options.df`` degrees of
    freedom) with location ``center`` and shape ``cov`` (scipy.stats.multivariate_t) truncated to
    the prior's bounds (draws outside are redrawn), evaluates ``post`` on them in chunks of
    ``options.chunk`` rows as tasks of ``runner`` (:class:`bayesid.tasks.Runner`, whose journal
    resumes a killed run) and weights them by ``post / proposal`` with Pareto smoothing
    (``arviz.psislw``).

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
        Runs the chunks as tasks.

    Returns
    -------
    dict
        ``draws`` (N, P), ``log_prob`` (N,), ``ssr`` (N, C), ``log_proposal`` (N,),
        ``log_weights`` (N,) smoothed and normalised, ``weights`` (N,), ``k_hat``, ``ess``
        (``1 / sum w^2``), ``reliable`` (k-hat < :data:`KHAT_MAX`), ``finite`` (draws with a
        finite posterior).

    Raises
    ------
    ValueError
        Fewer than 1 % of the proposal inside the bounds, a chunk task failed (named), or fewer
        than 10 draws with a finite posterior.
    """
    import warnings

    import arviz as az
    from scipy.stats import multivariate_t

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
    res = runner.run(evaluate_chunk, tasks, label="draws")
    failed = [r for r in res if isinstance(r, TaskError)]
    if failed:
        raise ValueError(f"{len(failed)} chunk(s) of posterior draws failed; first: {failed[0]}")
    lp = np.concatenate([_as_array(r["log_prob"]) for r in res])
    ssr = np.vstack([np.array([[np.nan if v is None else v for v in row] for row in r["ssr"]]) for r in res])
    lp = np.where(np.isfinite(lp), lp, -np.inf)
    raw = lp - logq
    finite = np.isfinite(raw)
    if finite.sum() < 10:
        raise ValueError(
            f"only {int(finite.sum())} of {n_draws} draws have a finite posterior: the Laplace approximation "
            "is far from the posterior's support (check the fit, or use --method mcmc)"
        )
    lw = np.full(n_draws, -np.inf)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ArviZ warns on k-hat > 0.7; the verdict reports it
        sm, k = az.psislw(raw[finite] - raw[finite].max())
    lw[finite] = np.asarray(sm, float)
    w = np.exp(lw - np.max(lw))
    w /= w.sum()
    k = float(np.asarray(k))
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
    }


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


def sample_tracks(
    problem: wf.FitProblem,
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
    problem : FitProblem
        The fit's objective: the model (e.g. from a ``model.json``), the contexts of the training
        tracks (the fit's windows and start rule), its channel weights and scored channels
        (:class:`~bayesid.estimation.windows.FitProblem`; its prior and iterations are not used:
        the prior is ``options.use_prior``'s).
    p0 : array_like, shape (P,)
        The fit's estimate.
    options : SampleOptions, default SampleOptions()
        Method, prior, seed and the MCMC's wall budget.
    importance : ImportanceOptions, default ImportanceOptions()
        The importance stage's draws, their Student-t degrees of freedom and chunk size.
    sampler : SamplerConfig, default TRACK_SAMPLER
        The MCMC refinement's ensembles (:data:`TRACK_SAMPLER`); its wall budget is set from
        ``options.max_minutes`` and its progress bar from the runner.
    folds : array_like, shape (G, P), optional
        Leave-one-run-out estimates (``model.json``'s calibration folds): with 3 or more, the
        effective sample counts are divided by :func:`jackknife_factor`.
    checkpoint : Checkpoint, optional
        The MCMC's HDF5 checkpoint and its identity (:class:`bayesid.estimation.sampling.Checkpoint`).
    runner : Runner, default Runner()
        Where the importance draws and the MCMC ensembles run (its journal records the importance
        draws), and where progress messages go.

    Returns
    -------
    TrackPosteriorResult
        The mode, the draws, the noise scales and the verdict of the method used.

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
    >>> problem = bayesid.FitProblem(res.model, ctxs, res.fit_sd, res.channels)
    >>> post = bayesid.sample_tracks(problem, res.fit.p, bayesid.SampleOptions(method="importance"))
    >>> post.method, post.draws.shape
    ('importance', (4000, 6))
    >>> print(post.verdict["text"])  # doctest: +SKIP
    """
    import time

    say = runner.say
    t0 = time.perf_counter()
    secs = {}
    post, per_eval = _track_posterior(problem, p0, options.use_prior, say)
    say("posterior mode and Laplace covariance")
    mode = posterior_mode(post, p0)
    between = jackknife_factor(folds if folds is not None else np.zeros((0, len(post.names))), mode["cov"])
    if between["factor"] > 1.0:
        say(
            f"between-run scatter (jackknife of {between['n_folds']} folds): effective samples divided by "
            f"{between['factor']:.2f}"
        )
        post.errors.inflation = post.errors.inflation * between["factor"]
        mode = posterior_mode(post, mode["p"])
    secs["mode"] = time.perf_counter() - t0
    seeds = np.random.SeedSequence(options.seed).spawn(4)  # proposal, resampling, noise scales, ensembles
    imp, mc, verdict = None, None, None
    used = options.method
    if options.method in ("importance", "auto"):
        t = time.perf_counter()
        say(f"importance-reweighted Laplace: {importance.n_draws} Student-t draws")
        imp = importance_laplace(
            post, mode["p"], mode["cov"], np.random.default_rng(seeds[0]), importance, runner=runner
        )
        secs["importance"] = time.perf_counter() - t
        verdict, used = _importance_verdict(imp, importance.n_draws), "importance"
    if options.method == "mcmc" or (options.method == "auto" and not verdict["converged"]):
        t = time.perf_counter()
        budget = max(60.0, 60.0 * options.max_minutes - (time.perf_counter() - t0))
        steps = sampler.max_steps if options.max_steps is None else int(options.max_steps)
        say(f"MCMC: {sampler.n_ensembles} emcee ensembles until converged, {steps} steps or {budget / 60:.1f} min")
        cfg = dataclasses.replace(
            sampler,
            max_wall_s=budget,
            min_steps=min(sampler.min_steps, steps),
            max_steps=steps,
            progress=runner.bar("mcmc") is not None,
        )
        mc = _mcmc(post, mode, cfg, np.random.default_rng(seeds[3]), checkpoint, runner)
        secs["mcmc"] = time.perf_counter() - t
        diag = mc["diagnostics"]
        verdict = dict(
            {k: v for k, v in diag.items() if not isinstance(v, dict)},
            method="mcmc",
            text=diag["verdict"],
            per_parameter={k: diag[k] for k in ("rhat", "ess_bulk", "ess_tail")},
            importance_first=None if imp is None else {"k_hat": imp["k_hat"], "ess": imp["ess"]},
        )
        used = "mcmc"
    rng_r, rng_s = np.random.default_rng(seeds[1]), np.random.default_rng(seeds[2])
    n_draws = importance.n_draws
    if used == "importance":
        idx = resample(imp["weights"], n_draws, rng_r)
        draws, lp, ssr = imp["draws"][idx], imp["log_prob"][idx], imp["ssr"][idx]
    else:
        res = mc["result"]
        flat = res.chains[:, mc["burn"] :].reshape(-1, len(post.names))
        keep = np.unique(np.linspace(0, flat.shape[0] - 1, min(n_draws, flat.shape[0])).astype(int))
        draws = flat[keep]
        lp, ssr = post.evaluate(draws)  # the SSR of the kept draws, for the noise scales
    sigma = post.errors.sigma_draws(ssr, rng_s)
    secs["total"] = time.perf_counter() - t0
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
        seconds_per_evaluation=per_eval,
        n_windows=int(sum(c.W for c in problem.ctxs)),
        between_runs=between,
    )


def _track_posterior(problem, p0, use_prior: bool, say) -> tuple:
    """(:class:`TrackPosterior` of the fit's objective at ``p0`` with its error model and prior,
    seconds of one evaluation per parameter row)."""
    import time

    model, ctxs = problem.model, problem.ctxs
    ob = wf.WindowObjective(model, ctxs, problem.sd, p0, channels=problem.channels)
    nuisance = np.zeros(0)
    if model.n_nuisance:
        fixed = FitResult.fixed(model, p0, len(ctxs))
        nuisance = np.concatenate(wf.heldout_nuisance(model, fixed, ctxs, problem.sd))
    x0 = np.concatenate([np.asarray(p0, float), nuisance])
    post = TrackPosterior(ob, error_model(ob, x0), ParameterPrior.of_model(model, use_prior), nuisance)
    t = time.perf_counter()
    post.evaluate(np.repeat(np.asarray(p0, float)[None], 8, axis=0))
    per_eval = (time.perf_counter() - t) / 8
    say(f"one evaluation: {1e3 * per_eval:.1f} ms per parameter row (batch of 8)")
    return post, per_eval


def _importance_verdict(imp: dict, n_draws: int) -> dict:
    """The verdict of an importance stage: reliable when k-hat < :data:`KHAT_MAX` and the
    importance ESS reaches :data:`~bayesid.estimation.sampling.ESS_BULK_MIN`."""
    ok_k, ok_e = imp["k_hat"] < KHAT_MAX, imp["ess"] >= ESS_BULK_MIN
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
            f"{'>=' if ok_e else '<'} {ESS_BULK_MIN:.0f} of {n_draws} draws ({imp['finite']} with a finite posterior)."
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
