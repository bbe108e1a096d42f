"""Gauss-Newton (Laplace) covariance of fitted parameters: the one implementation that the
posterior study (known noise, weak prior) and the long-run fits (residual variance, AR(1)
inflation) both use, and the covariance of a multiple-shooting fit built on it.

The covariance of a fit on long, noisy runs (:func:`fit_covariance`) is
``cov = s^2 (J^T J)^-1 * n/n_eff`` with ``s^2 = SSR / (n - k)`` and ``n/n_eff = (1 + rho1) /
(1 - rho1)`` from the lag-1 autocorrelation ``rho1`` of the residuals within windows
(:func:`ar1_inflation`, an AR(1) correction: simulation-error residuals are strongly correlated,
and ignoring that would make the bands far too narrow), capped at the mean number of samples per
window (each window then counts as one independent residual per channel).

Bishop (2006), *Pattern Recognition and Machine Learning*, Sec. 4.4 (Laplace approximation);
for a least-squares objective the Hessian is approximated by ``J^T J`` (Gauss-Newton).
"""

from __future__ import annotations

import math

import numpy as np

from ..data.validate import BayesidWarning
from ..models.context import errors
from . import shooting
from .fit import FitResult

__all__ = [
    "ar1_inflation",
    "gauss_newton_covariance",
    "fit_covariance",
    "psd_covariance",
    "weak_directions",
    "covariance_sentence",
    "CovarianceWarning",
    "COVARIANCE_RCOND",
]

#: Eigenvalues of ``J^T J`` under this share of the largest are cut by the pseudo-inverse of a fit
#: without a prior (:func:`gauss_newton_covariance`): those directions get zero variance. A Jacobian
#: condition number above ``1 / sqrt(COVARIANCE_RCOND)`` (1e6) cuts at least one.
COVARIANCE_RCOND = 1e-12


class CovarianceWarning(BayesidWarning):
    """A fit whose Laplace covariance cut directions of the parameters the tracks do not determine
    (:func:`covariance_sentence`): its sds understate the uncertainty."""


def gauss_newton_covariance(
    J: np.ndarray,
    prior_precision: np.ndarray | None = None,
    residual_variance: float = 1.0,
    inflation: float = 1.0,
    rcond: float = COVARIANCE_RCOND,
) -> np.ndarray:
    """Laplace covariance ``(J^T J + diag(prior_precision))^-1 * residual_variance * inflation``.

    Parameters
    ----------
    J : ndarray, shape (n_res, P)
        Jacobian of the residuals, each residual divided by its noise sd when the noise is known
        (then ``residual_variance`` is 1), in the units of the parameters.
    prior_precision : ndarray, shape (P,), optional
        ``1 / prior_sd**2`` of a Gaussian prior (or a uniform prior's width^2/12 stand-in), or
        None for none. With a prior the (symmetrised) matrix is inverted; without one its
        pseudo-inverse is taken (``rcond``), so that directions the data do not determine get
        zero variance rather than an error: read them with the condition number.
    residual_variance : float, default 1.0
        Factor for an estimated noise variance (``SSR / (n - P)``).
    inflation : float, default 1.0
        Factor for correlated residuals (e.g. the AR(1) variance inflation of a fit whose
        residuals are serially correlated).
    rcond : float, default 1e-12
        Cut-off of the pseudo-inverse (no prior), relative to the largest singular value.

    Returns
    -------
    ndarray, shape (P, P)
        The covariance.

    Raises
    ------
    numpy.linalg.LinAlgError
        When a prior is given and the matrix is singular.
    """
    J = np.asarray(J, float)
    if prior_precision is None:
        return np.linalg.pinv(J.T @ J, rcond=rcond) * residual_variance * inflation
    H = J.T @ J + np.diag(np.asarray(prior_precision, float))
    cov = np.linalg.inv(0.5 * (H + H.T))
    return cov if residual_variance == 1.0 and inflation == 1.0 else cov * residual_variance * inflation


def ar1_inflation(fitres: FitResult, ctxs) -> float:
    """Variance inflation ``(1 + rho1) / (1 - rho1)`` of serially correlated window residuals.

    ``rho1`` is the median lag-1 autocorrelation of the fit's residuals within windows over the
    scored channels of every track (clipped to [0, 0.999]); the result is capped at the mean
    number of samples per window, so that every window counts as at least one independent
    residual per channel.

    Parameters
    ----------
    fitres : FitResult
        The fit (its model, optimum ``p`` and scored ``channels``).
    ctxs : list of TrackContext
        The fit's training contexts.

    Returns
    -------
    float
        The inflation factor, at least 1.
    """
    r = []
    for ctx in ctxs:
        S = shooting.simulate(fitres.model, ctx, fitres.p[None])
        for c, e in errors(ctx, S).items():
            if fitres.channels is not None and c not in fitres.channels:
                continue
            e = e[0]
            same = ctx.win[1:] == ctx.win[:-1]
            a, b = e[:-1][same], e[1:][same]
            ok = np.isfinite(a) & np.isfinite(b)
            if ok.sum() > 10 and np.std(a[ok]) > 0:
                r.append(np.corrcoef(a[ok], b[ok])[0, 1])
    rho = float(np.clip(np.median(r), 0.0, 0.999)) if r else 0.0
    # at most the samples per window: every window counts as one independent residual per channel
    per_window = max(1.0, np.mean([ctx.ts.size / ctx.W for ctx in ctxs]))
    return float(min((1 + rho) / (1 - rho), per_window))


def fit_covariance(fitres: FitResult, ctxs, prior=None, data_scale: tuple | None = None) -> tuple[np.ndarray, dict]:
    """Laplace covariance of the fitted parameters (module docstring).

    Without a prior: ``(J^T J)^+ * s2 * inflation`` with ``s2 = SSR / (n - k)`` and the AR(1)
    inflation of the residuals. With a ``prior`` (whose residuals end the fit's residual vector,
    weighted by ``sqrt(s2 * inflation)``): ``(J_d^T J_d / (s2 * inflation) + diag(1 / sd^2))^-1``,
    the Gaussian posterior of a likelihood whose samples count ``1 / inflation`` each.

    Parameters
    ----------
    fitres : FitResult
        The fit (model, Jacobian ``jac``, cost, residual count).
    ctxs : list of TrackContext
        Its training contexts (for the AR(1) inflation).
    prior : GaussianPrior, optional
        The prior of a MAP fit (:class:`bayesid.estimation.windows.GaussianPrior`).
    data_scale : tuple, optional
        ``(s2, inflation)`` of the fit without the prior; needed with a prior.

    Returns
    -------
    cov : ndarray, shape (n_params, n_params)
        The covariance (:func:`psd_covariance`).
    info : dict
        ``residual_variance``, ``ar1_inflation``, ``condition_number`` (of the data Jacobian),
        ``directions_cut`` (the directions the pseudo-inverse gave zero variance, eigenvalues of
        ``J^T J`` under :data:`COVARIANCE_RCOND` of the largest; with a prior, whose matrix is
        inverted, those of a singular matrix, a free coefficient with neither data nor a prior,
        whose pseudo-inverse is taken then), ``sds_meaningful`` (none cut) and ``weak_directions``
        (:func:`weak_directions`).
    """
    n = fitres.model.n_params
    J = fitres.jac[:, :n]
    J = J.toarray() if hasattr(J, "toarray") else np.asarray(J)
    cut = None
    if prior is not None:
        J = J[: J.shape[0] - prior.idx.size]  # the data rows
        s2, infl = data_scale
        Jw = J / math.sqrt(s2 * infl)
        try:
            cov = psd_covariance(gauss_newton_covariance(Jw, prior_precision=prior.precision(n)))
            cut = 0
        except np.linalg.LinAlgError:  # a free coefficient neither the data nor a prior determine
            H = Jw.T @ Jw + np.diag(prior.precision(n))
            lam = np.linalg.eigvalsh(0.5 * (H + H.T))
            cut = int(np.sum(lam <= COVARIANCE_RCOND * max(lam.max(), 0.0)))
            cov = psd_covariance(np.linalg.pinv(H, rcond=COVARIANCE_RCOND, hermitian=True))
    else:
        s2 = fitres.cost / max(fitres.n_residuals - J.shape[1], 1)
        infl = ar1_inflation(fitres, ctxs)
        cov = psd_covariance(gauss_newton_covariance(J, residual_variance=s2, inflation=infl))
    sv = np.linalg.svd(J, compute_uv=False)
    if cut is None:
        cut = int(np.sum(sv**2 <= COVARIANCE_RCOND * sv[0] ** 2)) if sv.size else 0
    return cov, {
        "residual_variance": s2,
        "ar1_inflation": infl,
        "condition_number": float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf"),
        "directions_cut": cut,
        "sds_meaningful": cut == 0,
        "weak_directions": weak_directions(J, fitres.model.scales()),
    }


def covariance_sentence(info: dict) -> str | None:
    """What a fit's covariance summary says about its sds, when they cannot be trusted.

    Parameters
    ----------
    info : dict
        The summary of :func:`fit_covariance` (``directions_cut``, ``condition_number``).

    Returns
    -------
    str or None
        The sentence when the pseudo-inverse cut a direction (its sds understate the
        uncertainty); None otherwise, and for a summary written before the count existed.
    """
    cut = int(info.get("directions_cut") or 0)
    if not cut:
        return None
    return (
        f"the Laplace covariance is near-singular (Jacobian condition number {info['condition_number']:.3g}): "
        f"{cut} direction(s) of the parameters the tracks do not determine got zero variance, so every sd "
        "understates the uncertainty and no interval from it holds; free fewer coefficients, or add runs that "
        "excite them, or give priors"
    )


def psd_covariance(cov) -> np.ndarray:
    """The symmetric positive semi-definite form of a covariance: its symmetric part with the
    eigenvalues below zero (round-off of an ill-conditioned Gauss-Newton inverse) set to zero.
    What ``fit`` writes is what ``predict`` reads (:func:`bayesid.estimation.modelfile.load_model`).

    Parameters
    ----------
    cov : array_like, shape (P, P)
        A covariance.

    Returns
    -------
    ndarray, shape (P, P)
        Its symmetric positive semi-definite form.
    """
    C = np.atleast_2d(np.asarray(cov, float))  # np.cov of one parameter's draws is 0-d
    C = 0.5 * (C + C.T)
    lam, V = np.linalg.eigh(C)
    C = (V * np.clip(lam, 0.0, None)) @ V.T
    return 0.5 * (C + C.T)


def weak_directions(J, scales, k: int = 3) -> list:
    """The directions of parameter space the residuals constrain least: eigenvectors of
    ``(J D)^T (J D)`` with ``D = diag(scales)`` (parameters in units of their typical size), the
    smallest eigenvalue first.

    Parameters
    ----------
    J : array_like, shape (n_res, P)
        Jacobian of the residuals.
    scales : array_like, shape (P,)
        Typical sizes of the parameters.
    k : int, default 3
        Number of directions.

    Returns
    -------
    list of dict
        ``{"eigenvalue", "vector"}`` each (unit vector over the parameters, in scaled units),
        labelled by the report layer (:class:`bayesid.analysis.identifiability.Direction`).
    """
    Js = np.asarray(J, float) * np.abs(np.asarray(scales, float))[None, :]
    lam, V = np.linalg.eigh(Js.T @ Js)
    return [{"eigenvalue": float(lam[i]), "vector": V[:, i].tolist()} for i in range(min(k, lam.size))]
