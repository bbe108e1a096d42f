"""bayesid.estimation.laplace: the one Gauss-Newton (Laplace) covariance."""

import numpy as np
import pytest

from bayesid.estimation.laplace import gauss_newton_covariance


def test_linear_gaussian_posterior_covariance_with_a_prior():
    """For r = J p - y with unit noise and a Gaussian prior of precision L, the posterior
    covariance is (J'J + L)^-1 exactly; residual variance and inflation scale it."""
    rng = np.random.default_rng(0)
    J = rng.normal(size=(50, 3))
    L = np.array([1.0, 4.0, 0.25])
    exact = np.linalg.inv(J.T @ J + np.diag(L))
    np.testing.assert_allclose(gauss_newton_covariance(J, L), exact, rtol=1e-12)
    np.testing.assert_allclose(
        gauss_newton_covariance(J, L, residual_variance=2.0, inflation=1.5), 3.0 * exact, rtol=1e-12
    )


def test_without_a_prior_an_undetermined_direction_gets_zero_variance():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(40, 1))
    J = np.hstack([a, 2.0 * a, rng.normal(size=(40, 1))])  # p0 and p1 enter only as p0 + 2 p1
    cov = gauss_newton_covariance(J, residual_variance=0.5)
    null = np.array([2.0, -1.0, 0.0]) / np.sqrt(5.0)
    assert null @ cov @ null == pytest.approx(0.0, abs=1e-12)
    assert np.all(np.linalg.eigvalsh(cov) > -1e-12)
    with pytest.raises(np.linalg.LinAlgError):
        gauss_newton_covariance(J, np.zeros(3))
