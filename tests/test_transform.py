"""Sampling in an unconstrained space (issue 23, first part): the logit transform of the bounded
coefficients and its log-Jacobian."""

from __future__ import annotations

import emcee
import numpy as np
import pytest

from bayesid.estimation.posterior import CoefficientPrior, LogitTransform, TransformedLogPosterior

PRIOR = CoefficientPrior.build(uniform={"Yv": (-10.0, 10.0), "Nr": (-4.0, 6.0)}, normal={"Xudot": (0.3, 2.0)})


def gaussian_logpost(mu, cov, prior):
    """Gaussian log-likelihood times the prior (the linear-Gaussian problem), vectorised."""
    icov = np.linalg.inv(cov)

    def logpost(theta):
        d = np.atleast_2d(theta)[:, : len(mu)] - mu
        return -0.5 * np.einsum("bi,ij,bj->b", d, icov, d) + prior.logpdf(theta)

    return logpost


def test_transformed_density_is_the_coefficient_density_plus_the_log_jacobian():
    t = LogitTransform(PRIOR)
    rng = np.random.default_rng(0)
    z = rng.normal(0.0, 3.0, (50, 3))
    lp = gaussian_logpost(np.array([1.0, -2.0]), np.eye(2), PRIOR)
    np.testing.assert_allclose(TransformedLogPosterior(lp, PRIOR)(z), lp(t.to_theta(z)) + t.log_jacobian(z))
    # the log-Jacobian is the log of the diagonal derivative d theta / d z (central differences)
    h = 1e-6
    num = np.zeros(z.shape[0])
    for j in range(3):
        dz = np.zeros(3)
        dz[j] = h
        num += np.log(np.abs((t.to_theta(z + dz)[:, j] - t.to_theta(z - dz)[:, j]) / (2 * h)))
    np.testing.assert_allclose(t.log_jacobian(z), num, rtol=1e-6)


def test_draws_mapped_back_respect_the_bounds_and_the_map_inverts():
    t = LogitTransform(PRIOR)
    z = np.array([[-800.0, 800.0, 5.0], [40.0, -40.0, -3.0], [0.0, 0.0, 0.0]])
    th = t.to_theta(z)
    assert np.all(np.isfinite(t.log_jacobian(z)))
    assert np.all((th[:, 0] >= -10.0) & (th[:, 0] <= 10.0) & (th[:, 1] >= -4.0) & (th[:, 1] <= 6.0))
    assert th[2, 2] == 0.0 and th[0, 2] == 5.0  # the Gaussian coordinate is not transformed
    zz = np.random.default_rng(1).normal(0.0, 4.0, (20, 3))
    np.testing.assert_allclose(t.to_z(t.to_theta(zz)), zz, rtol=1e-9, atol=1e-9)
    with pytest.raises(ValueError, match="on or outside its bounds"):
        t.to_z([[10.0, 0.0, 0.0]])


def test_transformed_sampler_recovers_a_linear_gaussian_posterior():
    """Gaussian likelihood well inside the uniform box: the posterior is that Gaussian. The
    stretch move in z space, mapped back, recovers its mean and covariance."""
    mu = np.array([1.0, -2.0])
    cov = np.array([[1.0, 0.6], [0.6, 0.5]])
    prior = CoefficientPrior.build(uniform={"Yv": (-10.0, 10.0), "Nr": (-8.0, 6.0)})
    post = TransformedLogPosterior(gaussian_logpost(mu, cov, prior), prior)
    rng = np.random.default_rng(2)
    z0 = post.transform.to_z(mu + 0.1 * rng.normal(size=(32, 2)))
    sampler = emcee.EnsembleSampler(32, 2, post, vectorize=True)
    sampler.random_state = np.random.RandomState(3).get_state()  # emcee 3.1 has no seed argument
    sampler.run_mcmc(z0, 3000, progress=False)
    theta = post.transform.to_theta(sampler.get_chain(discard=500, flat=True))
    assert np.all((theta[:, 0] > -10) & (theta[:, 0] < 10) & (theta[:, 1] > -8) & (theta[:, 1] < 6))
    # Monte Carlo error: tau ~ 30 steps, 32 x 2500 draws -> about 2700 independent ones
    np.testing.assert_allclose(theta.mean(axis=0), mu, atol=0.08)
    np.testing.assert_allclose(np.cov(theta, rowvar=False), cov, rtol=0.12, atol=0.04)
