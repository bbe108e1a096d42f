"""Likelihood and priors."""

import numpy as np
import pytest

from bayesid import cases
from bayesid.estimation.objective import Problem
from bayesid.estimation.posterior import CoefficientPrior, LogPosterior, add_noise
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator

SIG = dict(x=0.2, y=0.2, z=0.2, phi=np.radians(0.2), theta=np.radians(0.2), psi=np.radians(0.2))


@pytest.fixture(scope="module")
def post(nps):
    case = cases.make_case(2, nps, np.random.default_rng(0))
    m = mv.zigzag(nps, 20.0, duration=40.0)
    sim = Simulator(nps, m, free=case.free, mode="horizontal", sample_every=10)
    truth = np.array([case.true[n] for n in case.free])
    target = add_noise(sim.run(truth[None]).track(0), dict(x=0.2, y=0.2, psi=np.radians(0.2)), np.random.default_rng(1))
    pb = Problem(sim, target, truth)
    prior = CoefficientPrior.build(uniform={n: (case.lower[n], case.upper[n]) for n in case.free})
    return case, truth, LogPosterior(pb, SIG, prior)


def test_uniform_prior_support_and_density():
    pr = CoefficientPrior.build(uniform={"Yr": (0.02, 0.04)}, normal={"Nv": (-0.0074, 0.0001)})
    th = np.array([[0.03, -0.0074], [0.05, -0.0074]])
    lp = pr.logpdf(th)
    assert lp[0] == pytest.approx(-np.log(0.02) - np.log(0.0001 * np.sqrt(2 * np.pi)))
    assert lp[1] == -np.inf
    with pytest.raises(ValueError, match="Yr"):
        CoefficientPrior.build(uniform={"Yr": (0.03, 0.03)})
    with pytest.raises(KeyError, match="Yqx"):  # not a product of the features (Yq is u*q, a term)
        CoefficientPrior.build(uniform={"Yqx": (0.0, 1.0)})


def test_divergent_proposal_is_minus_inf_not_nan(nps, post):
    case, truth, lp = post
    wide = CoefficientPrior.build(uniform={n: (-100.0, 100.0) for n in case.free})
    lpw = LogPosterior(lp.problem, SIG, wide)
    bad = truth.copy()
    bad[case.free.index("Nr")] = 60.0  # wildly unstable yaw damping: the track diverges
    out = lpw(np.vstack([truth, bad]))
    assert np.isfinite(out[0]) and out[1] == -np.inf


def test_log_posterior_peaks_near_truth_and_rejects_outside_prior(post):
    case, truth, lp = post
    far = truth * 1.2
    outside = truth * 1.3  # beyond the +-25 % bounds
    out = lp(np.vstack([truth, far, outside]))
    assert out[0] > out[1] and out[2] == -np.inf
    assert lp.n_evaluations >= 3


def test_prior_names_must_match(post):
    case, truth, lp = post
    pr = CoefficientPrior.build(uniform={"Yr": (0.0, 1.0)})
    with pytest.raises(ValueError, match="differ"):
        LogPosterior(lp.problem, SIG, pr)


def test_laplace_start_fits_inside_the_prior():
    from bayesid.estimation.posterior import laplace_start

    pr = CoefficientPrior.build(uniform={"Yr": (0.0225, 0.0375), "Nr": (-0.02, -0.012)})
    theta_hat = np.array([0.0375, -0.016])  # optimum on Yr's upper bound
    cov = np.array([[1.0, 0.9e-4], [0.9e-4, 1e-8]])  # Yr sd 1.0 >> prior width; Nr sd 1e-4 < 2 % of it
    c, C = laplace_start(theta_hat, cov, pr)
    assert pr.a[0] < c[0] < pr.b[0] and c[1] == theta_hat[1]
    assert np.sqrt(C[0, 0]) <= 0.02 * (pr.b[0] - pr.a[0]) + 1e-15
    assert C[1, 1] == pytest.approx(1e-8)  # already narrow: unchanged
    corr = lambda M: M[0, 1] / np.sqrt(M[0, 0] * M[1, 1])
    assert corr(C) == pytest.approx(corr(cov))  # the Laplace shape is kept
    draws = np.random.default_rng(0).multivariate_normal(c, C, 2000)
    assert np.mean(np.isfinite(pr.logpdf(draws))) > 0.99
