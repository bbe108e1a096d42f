"""Likelihood and priors."""
import numpy as np
import pytest

from bayesid import cases, manoeuvres as mv
from bayesid.identify import Problem
from bayesid.posterior import CoefficientPrior, LogPosterior, add_noise
from bayesid.simulate import Simulator

SIG = dict(x=0.2, y=0.2, z=0.2, phi=np.radians(0.2), theta=np.radians(0.2), psi=np.radians(0.2))


@pytest.fixture(scope="module")
def post(nps):
    case = cases.make_case(2, nps, np.random.default_rng(0))
    m = mv.zigzag(nps, 20.0, duration=40.0)
    sim = Simulator(nps, m, free=case.free, mode="horizontal", sample_every=10)
    truth = np.array([case.true[n] for n in case.free])
    target = add_noise(sim.run(truth[None]).track(0), dict(x=0.2, y=0.2, psi=np.radians(0.2)),
                       np.random.default_rng(1))
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
    with pytest.raises(KeyError, match="Yq"):
        CoefficientPrior.build(uniform={"Yq": (0.0, 1.0)})


def test_divergent_proposal_is_minus_inf_not_nan(nps, post):
    case, truth, lp = post
    wide = CoefficientPrior.build(uniform={n: (-100.0, 100.0) for n in case.free})
    lpw = LogPosterior(lp.problem, SIG, wide)
    bad = truth.copy()
    bad[case.free.index("Nr")] = 60.0       # wildly unstable yaw damping: the track diverges
    out = lpw(np.vstack([truth, bad]))
    assert np.isfinite(out[0]) and out[1] == -np.inf


def test_log_posterior_peaks_near_truth_and_rejects_outside_prior(post):
    case, truth, lp = post
    far = truth * 1.2
    outside = truth * 1.3                   # beyond the +-25 % bounds
    out = lp(np.vstack([truth, far, outside]))
    assert out[0] > out[1] and out[2] == -np.inf
    assert lp.n_evaluations >= 3


def test_prior_names_must_match(post):
    case, truth, lp = post
    pr = CoefficientPrior.build(uniform={"Yr": (0.0, 1.0)})
    with pytest.raises(ValueError, match="differ"):
        LogPosterior(lp.problem, SIG, pr)
