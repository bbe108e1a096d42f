"""Likelihood and priors over hydrodynamic coefficients: the posterior a track implies.

Gaussian measurement noise on the observed channels with per-channel standard deviations,

    log p(y | theta) = -1/2 sum_i sum_c ((y_ic - y_ic(theta)) / sigma_c)**2 + const,

evaluated for a batch of coefficient vectors in ONE batched simulation (emcee ``vectorize=True``).
Priors per coefficient: uniform within bounds (the paper's setting) or Gaussian (a towing-tank value
with a stated relative standard deviation: the Bayesian reading of the paper's Case 3, where
"known" values become uncertain nuisance parameters). A diverged simulation or a proposal outside
the prior support has log-probability ``-inf``, never NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data import terms
from ..data.track import STATE_NAMES, Track


@dataclass(frozen=True)
class CoefficientPrior:
    """Independent priors for the free coefficients (prime values).

    Parameters
    ----------
    names : tuple of str
        The P coefficient names.
    kind : tuple of str
        Per coefficient ``"uniform"`` or ``"normal"``.
    a, b : ndarray, shape (P,)
        Lower/upper bound (uniform) or mean/standard deviation (normal).

    Raises
    ------
    UnknownCoefficientError
        A name not in the term library.
    ValueError
        An unknown kind, non-finite parameters, bounds not increasing, a non-positive sd.
    """

    names: tuple
    kind: tuple
    a: np.ndarray
    b: np.ndarray

    def __post_init__(self):
        terms.check_names(self.names, "prior")
        for n, k, a, b in zip(self.names, self.kind, self.a, self.b):
            if k not in ("uniform", "normal"):
                raise ValueError(f"prior for {n}: kind must be 'uniform' or 'normal', not {k!r}")
            if not (np.isfinite(a) and np.isfinite(b)):
                raise ValueError(f"prior for {n}: parameters must be finite")
            if k == "uniform" and not a < b:
                raise ValueError(f"prior for {n}: lower bound {a} must be below upper bound {b}")
            if k == "normal" and not b > 0:
                raise ValueError(f"prior for {n}: standard deviation {b} must be positive")

    @classmethod
    def build(cls, uniform: dict | None = None, normal: dict | None = None) -> CoefficientPrior:
        """Priors from two dicts (order: uniform first).

        Parameters
        ----------
        uniform : dict, optional
            ``{name: (lo, hi)}``; bounds given in either order are sorted (negative
            coefficients).
        normal : dict, optional
            ``{name: (mean, sd)}``; the sd's sign is dropped.

        Returns
        -------
        CoefficientPrior
            The priors.

        Raises
        ------
        ValueError
            A coefficient with two priors, or any error of the constructor.
        """
        names, kind, a, b = [], [], [], []
        for n, (lo, hi) in (uniform or {}).items():
            names.append(n)
            kind.append("uniform")
            a.append(min(lo, hi))
            b.append(max(lo, hi))
        for n, (mu, sd) in (normal or {}).items():
            names.append(n)
            kind.append("normal")
            a.append(mu)
            b.append(abs(sd))
        if len(set(names)) != len(names):
            raise ValueError("a coefficient has two priors")
        return cls(tuple(names), tuple(kind), np.array(a, float), np.array(b, float))

    def logpdf(self, theta: np.ndarray) -> np.ndarray:
        """Log prior density.

        Parameters
        ----------
        theta : ndarray, shape (B, P)
            Prime coefficients.

        Returns
        -------
        ndarray, shape (B,)
            The log density; ``-inf`` outside a uniform support.
        """
        theta = np.atleast_2d(theta)
        uni = np.array([k == "uniform" for k in self.kind])
        out = np.zeros(theta.shape[0])
        if uni.any():
            lo, hi = self.a[uni], self.b[uni]
            inside = np.all((theta[:, uni] >= lo) & (theta[:, uni] <= hi), axis=1)
            out += np.where(inside, -np.sum(np.log(hi - lo)), -np.inf)
        if (~uni).any():
            mu, sd = self.a[~uni], self.b[~uni]
            z = (theta[:, ~uni] - mu) / sd
            out += -0.5 * np.sum(z**2, axis=1) - np.sum(np.log(sd * np.sqrt(2 * np.pi)))
        return out

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Draws from the prior.

        Parameters
        ----------
        n : int
            Number of draws.
        rng : numpy.random.Generator
            The random generator.

        Returns
        -------
        ndarray, shape (n, P)
            The draws.
        """
        out = np.empty((n, len(self.names)))
        for j, k in enumerate(self.kind):
            out[:, j] = rng.uniform(self.a[j], self.b[j], n) if k == "uniform" else rng.normal(self.a[j], self.b[j], n)
        return out


class LogPosterior:
    """Vectorised log-posterior over the free coefficients of an identification problem.

    Call with theta (B, P) prime values; returns (B,). ``n_evaluations`` counts rows evaluated.

    Parameters
    ----------
    problem : Problem
        :class:`~bayesid.estimation.objective.Problem`; its free names must equal ``prior.names``.
    sigmas : dict
        ``{channel: noise standard deviation}`` (m or rad) for every channel of the problem.
    prior : CoefficientPrior
        The priors.

    Raises
    ------
    ValueError
        If the prior's names differ from the problem's free names or a sigma is not positive.
    KeyError
        Naming a channel without a sigma.
    """

    def __init__(self, problem, sigmas: dict, prior: CoefficientPrior):
        if list(prior.names) != list(problem.names):
            raise ValueError(f"prior names {list(prior.names)} differ from the free coefficients {problem.names}")
        missing = [c for c in problem.channels if c not in sigmas]
        if missing:
            raise KeyError(f"no noise standard deviation for channel(s) {missing}")
        sig = np.array([float(sigmas[c]) for c in problem.channels])
        if np.any(~(sig > 0)):
            raise ValueError(f"noise standard deviations must be positive: {dict(zip(problem.channels, sig))}")
        self.problem, self.prior = problem, prior
        self.w = np.tile(1.0 / sig, problem.y.shape[0])  # (n_residuals,)
        self.n_evaluations = 0

    def log_likelihood(self, theta) -> np.ndarray:
        """Gaussian log-likelihood up to a constant.

        Parameters
        ----------
        theta : array_like, shape (B, P)
            Prime coefficients.

        Returns
        -------
        ndarray, shape (B,)
            The log-likelihood; ``-inf`` for diverged tracks.
        """
        theta = np.atleast_2d(theta)
        R, div = self.problem.residuals_batch(self.problem.scaled(theta))
        ll = -0.5 * np.sum((R * self.w) ** 2, axis=1)
        ll[div | ~np.isfinite(ll)] = -np.inf
        return ll

    def __call__(self, theta) -> np.ndarray:
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        lp = self.prior.logpdf(theta)
        ok = np.isfinite(lp)
        out = np.full(theta.shape[0], -np.inf)
        if ok.any():  # only simulate proposals inside the prior support
            out[ok] = lp[ok] + self.log_likelihood(theta[ok])
        self.n_evaluations += theta.shape[0]
        return out


class LogitTransform:
    """Bijection between the prior support and the real line, coordinate by coordinate: a
    coefficient with a uniform prior on [lo, hi] is ``theta = lo + (hi - lo) sigmoid(z)``; one
    with a Gaussian prior is unbounded and passes through (``theta = z``). The usual transform
    of a bounded parameter for sampling in an unconstrained space (Stan Reference Manual,
    "Constraint transforms: lower and upper bounded scalar").

    ``to_theta`` / ``to_z`` map (B, P) arrays; ``log_jacobian(z)`` (B,) is
    ``sum log |d theta / d z| = sum log(hi - lo) + log sigmoid(z) + log sigmoid(-z)`` over the
    bounded coordinates (computed with ``logaddexp``, finite for any finite z).

    Parameters
    ----------
    prior : CoefficientPrior
        The priors (their kinds and uniform bounds).
    """

    def __init__(self, prior: CoefficientPrior):
        self.bounded = np.array([k == "uniform" for k in prior.kind])
        self.lo = np.where(self.bounded, prior.a, 0.0)
        self.width = np.where(self.bounded, prior.b - prior.a, 1.0)

    def to_theta(self, z) -> np.ndarray:
        """Coefficients from unconstrained coordinates.

        Parameters
        ----------
        z : array_like, shape (B, P)
            Unconstrained coordinates.

        Returns
        -------
        ndarray, shape (B, P)
            Prime coefficients.
        """
        z = np.atleast_2d(np.asarray(z, dtype=float))
        s = 0.5 * (1.0 + np.tanh(0.5 * z))  # sigmoid without overflow
        return np.where(self.bounded, self.lo + self.width * s, z)

    def to_z(self, theta) -> np.ndarray:
        """Inverse of :meth:`to_theta`.

        Parameters
        ----------
        theta : array_like, shape (B, P)
            Prime coefficients.

        Returns
        -------
        ndarray, shape (B, P)
            Unconstrained coordinates.

        Raises
        ------
        ValueError
            When a bounded coordinate is not strictly inside its bounds (it would map to +-inf).
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        u = (theta - self.lo) / self.width
        if np.any(self.bounded & ~((u > 0) & (u < 1))):
            raise ValueError("a coefficient with a uniform prior is on or outside its bounds: no finite logit")
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.bounded, np.log(u) - np.log1p(-u), theta)

    def log_jacobian_terms(self, z) -> np.ndarray:
        """``log |d theta_j / d z_j|`` per coordinate (0 for the unbounded ones).

        Parameters
        ----------
        z : array_like, shape (B, P)
            Unconstrained coordinates.

        Returns
        -------
        ndarray, shape (B, P)
            The log-Jacobian terms.
        """
        z = np.atleast_2d(np.asarray(z, dtype=float))
        return np.where(self.bounded, np.log(self.width) - np.logaddexp(0.0, -z) - np.logaddexp(0.0, z), 0.0)

    def log_jacobian(self, z) -> np.ndarray:
        """``sum log |d theta / d z|`` over the coordinates.

        Parameters
        ----------
        z : array_like, shape (B, P)
            Unconstrained coordinates.

        Returns
        -------
        ndarray, shape (B,)
            The log-Jacobian.
        """
        return np.sum(self.log_jacobian_terms(z), axis=1)


class TransformedLogPosterior:
    """A log-posterior over coefficients seen in the unconstrained space of
    :class:`LogitTransform`: ``log p_z(z) = log p(theta(z)) + log |d theta / d z|``. A
    prior-dominated direction of a uniform box becomes a smooth (logistic) density instead of
    a hard wall that rejects every proposal outside it.

    Call with z (B, P); returns (B,). ``transform`` maps draws back (``to_theta``).

    Parameters
    ----------
    logpost : callable
        ``theta (B, P) -> (B,)`` log-density in coefficient space (e.g. :class:`LogPosterior`).
    prior : CoefficientPrior
        Its priors (the bounds).
    """

    def __init__(self, logpost, prior: CoefficientPrior):
        self.logpost, self.transform = logpost, LogitTransform(prior)

    def __call__(self, z) -> np.ndarray:
        z = np.atleast_2d(np.asarray(z, dtype=float))
        return self.logpost(self.transform.to_theta(z)) + self.transform.log_jacobian(z)


def add_noise(track: Track, sigmas: dict, rng: np.random.Generator) -> Track:
    """Copy of a track with independent Gaussian noise added to state channels.

    Parameters
    ----------
    track : Track
        The track.
    sigmas : dict
        ``{channel: sd}``, SI; only state channels are changed.
    rng : numpy.random.Generator
        The random generator.

    Returns
    -------
    Track
        The noisy copy.

    Raises
    ------
    KeyError
        Naming a channel that the track does not have.
    """
    for c in sigmas:
        if c not in track:
            raise KeyError(f"track {track.name!r} has no channel {c!r} to add noise to")
    noisy = {c: track[c] + rng.normal(0.0, float(s), track.n_samples) for c, s in sigmas.items() if c in STATE_NAMES}
    return track.with_columns(**noisy)


def laplace_start(
    theta_hat, cov, prior: CoefficientPrior, margin: float = 0.05, max_sd_fraction: float = 0.02
) -> tuple[np.ndarray, np.ndarray]:
    """Centre and covariance of a walkers' starting ball that respects the prior.

    The Laplace (Gauss-Newton) covariance of a sloppy problem can be far wider than a uniform
    prior (measured: marginal sd of 19x |truth| for Xrr in Case 2 with 0.2 m noise), and the
    optimum often sits on a bound, so a ball around it falls outside the support. This moves the
    centre ``margin`` of the prior width inside each uniform support and scales each coordinate of
    the covariance down, keeping its correlation structure, so that no marginal sd exceeds
    ``max_sd_fraction`` of the prior width (uniform) or of ten prior sds (normal).

    Parameters
    ----------
    theta_hat : array_like, shape (P,)
        The optimum, prime values.
    cov : array_like, shape (P, P)
        Its Laplace covariance.
    prior : CoefficientPrior
        The priors.
    margin : float, default 0.05
        Fraction of a uniform prior's width the centre keeps from each bound.
    max_sd_fraction : float, default 0.02
        Largest marginal sd, as a fraction of the prior width (uniform) or of ten prior sds
        (normal).

    Returns
    -------
    centre : ndarray, shape (P,)
        The centre of the ball.
    covariance : ndarray, shape (P, P)
        Its covariance.
    """
    theta_hat = np.asarray(theta_hat, dtype=float)
    cov = 0.5 * (np.asarray(cov, dtype=float) + np.asarray(cov, dtype=float).T)
    centre = theta_hat.copy()
    limit = np.empty(theta_hat.size)
    for j, k in enumerate(prior.kind):
        if k == "uniform":
            w = prior.b[j] - prior.a[j]
            centre[j] = np.clip(centre[j], prior.a[j] + margin * w, prior.b[j] - margin * w)
            limit[j] = max_sd_fraction * w
        else:
            limit[j] = max_sd_fraction * prior.b[j] * 10.0
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    D = np.minimum(1.0, limit / sd)
    return centre, cov * np.outer(D, D)


def prior_sd(prior: CoefficientPrior) -> np.ndarray:
    """Standard deviation of each marginal prior.

    Parameters
    ----------
    prior : CoefficientPrior
        The priors.

    Returns
    -------
    ndarray, shape (P,)
        width/sqrt(12) (uniform) or sd (normal).
    """
    uni = np.array([k == "uniform" for k in prior.kind])
    return np.where(uni, (prior.b - prior.a) / np.sqrt(12.0), prior.b)


def laplace_covariance(problem, theta_hat, sigmas: dict, prior: CoefficientPrior) -> np.ndarray:
    """Gauss-Newton (Laplace) posterior covariance at ``theta_hat``, prime units.

    ``cov = (J_w^T J_w + diag(1 / prior_sd**2))^-1`` with ``J_w`` the noise-weighted Jacobian of
    the simulated channels with respect to theta (central differences, one batched call). A
    uniform prior enters through its variance, width^2/12: a weak Gaussian stand-in that keeps the
    matrix invertible along directions the data do not determine (exact structural nulls
    included). Bishop 2006, Sec. 4.4 (Laplace approximation).

    Parameters
    ----------
    problem : Problem
        The identification problem (:class:`~bayesid.estimation.objective.Problem`).
    theta_hat : array_like, shape (P,)
        The optimum, prime values.
    sigmas : dict
        ``{channel: noise sd}``, SI.
    prior : CoefficientPrior
        The priors.

    Returns
    -------
    ndarray, shape (P, P)
        The covariance.

    Raises
    ------
    KeyError
        Naming a channel without a sigma (:meth:`bayesid.estimation.objective.Problem.noise_vector`).
    """
    from .laplace import gauss_newton_covariance

    p = problem.scaled(theta_hat)
    _, J = problem.jacobian(p, central=True)  # d r / d p
    Jw = (J / problem.reference[None, :]) / problem.noise_vector(sigmas)[:, None]  # d r / d theta
    Jw = np.where(problem.mask.reshape(-1)[:, None], Jw, 0.0)
    return gauss_newton_covariance(Jw, prior_precision=1.0 / prior_sd(prior) ** 2)


def marginal_table(
    samples: np.ndarray, names, prior: CoefficientPrior, truth: dict | None = None, level: float = 0.9
) -> list[dict]:
    """Per-coefficient posterior summary from pooled draws.

    Parameters
    ----------
    samples : ndarray, shape (N, P)
        Pooled draws, prime values.
    names : sequence of str
        The P coefficient names.
    prior : CoefficientPrior
        The priors.
    truth : dict, optional
        ``{name: true value}``.
    level : float, default 0.9
        Level of the central credible interval.

    Returns
    -------
    list of dict
        One row per coefficient: name, mean, sd, lower/upper of the central ``level`` credible
        interval (equal-tailed quantiles), ``sd_over_prior`` (posterior sd / prior sd: near 1 =
        the data add nothing), ``prior`` (its kind), and with ``truth``: truth, ``mean_ratio``
        (mean / truth) and ``covers`` (interval holds truth).
    """
    a = (1.0 - level) / 2.0
    lo, hi = np.quantile(samples, [a, 1.0 - a], axis=0)
    mean, sd = samples.mean(axis=0), samples.std(axis=0, ddof=1)
    psd = prior_sd(prior)
    rows = []
    for j, n in enumerate(names):
        r = dict(
            name=n,
            mean=float(mean[j]),
            sd=float(sd[j]),
            lower=float(lo[j]),
            upper=float(hi[j]),
            sd_over_prior=float(sd[j] / psd[j]),
            prior=prior.kind[j],
        )
        if truth is not None:
            t = float(truth[n])
            r.update(truth=t, mean_ratio=float(mean[j] / t), covers=bool(lo[j] <= t <= hi[j]))
        rows.append(r)
    return rows


def top_correlations(samples: np.ndarray, names, k: int = 10) -> dict:
    """The strongest posterior correlations.

    Parameters
    ----------
    samples : ndarray, shape (N, P)
        Draws.
    names : sequence of str
        The P names.
    k : int, default 10
        Number of pairs.

    Returns
    -------
    dict
        ``{"A–B": r}`` ordered by |r|.
    """
    C = np.corrcoef(samples, rowvar=False)
    iu = np.triu_indices(len(names), 1)
    order = np.argsort(-np.abs(C[iu]))[:k]
    return {f"{names[iu[0][i]]}–{names[iu[1][i]]}": float(C[iu][i]) for i in order}


def direction_draws(draws: np.ndarray, directions: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Project draws onto unit directions in relative coordinates.

    Parameters
    ----------
    draws : ndarray, shape (..., P)
        Prime values.
    directions : ndarray, shape (P, K)
        Unit vectors in ``theta / reference`` units.
    reference : ndarray, shape (P,)
        The reference values.

    Returns
    -------
    ndarray, shape (..., K)
        ``sum_j w_jk * theta_j / reference_j`` -- e.g. the position along
        ``0.71*Xvr - 0.70*Xrr`` in fractions of the reference values.
    """
    return (draws / reference) @ directions
