"""Gauss-Newton (Laplace) covariance of fitted parameters: the one implementation that the
posterior study (known noise, weak prior) and the long-run fits (residual variance, AR(1)
inflation) both use.

Bishop (2006), *Pattern Recognition and Machine Learning*, Sec. 4.4 (Laplace approximation);
for a least-squares objective the Hessian is approximated by ``J^T J`` (Gauss-Newton).
"""

from __future__ import annotations

import numpy as np

__all__ = ["gauss_newton_covariance"]


def gauss_newton_covariance(
    J: np.ndarray,
    prior_precision: np.ndarray | None = None,
    residual_variance: float = 1.0,
    inflation: float = 1.0,
    rcond: float = 1e-12,
) -> np.ndarray:
    """Laplace covariance ``(J^T J + diag(prior_precision))^-1 * residual_variance * inflation``.

    Parameters
    ----------
    J : (n_res, P) Jacobian of the residuals, each residual divided by its noise sd when the
        noise is known (then ``residual_variance`` is 1), in the units of the parameters.
    prior_precision : (P,) ``1 / prior_sd**2`` of a Gaussian prior (or a uniform prior's
        width^2/12 stand-in), or None for none. With a prior the (symmetrised) matrix is inverted;
        without one its pseudo-inverse is taken (``rcond``), so that directions the data do not
        determine get zero variance rather than an error: read them with the condition number.
    residual_variance : factor for an estimated noise variance (``SSR / (n - P)``).
    inflation : factor for correlated residuals (e.g. the AR(1) variance inflation of a fit
        whose residuals are serially correlated).

    Returns
    -------
    (P, P) covariance.

    Raises
    ------
    numpy.linalg.LinAlgError when a prior is given and the matrix is singular.
    """
    J = np.asarray(J, float)
    if prior_precision is None:
        return np.linalg.pinv(J.T @ J, rcond=rcond) * residual_variance * inflation
    H = J.T @ J + np.diag(np.asarray(prior_precision, float))
    cov = np.linalg.inv(0.5 * (H + H.T))
    return cov if residual_variance == 1.0 and inflation == 1.0 else cov * residual_variance * inflation
