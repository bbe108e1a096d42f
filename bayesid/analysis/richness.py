"""How much a manoeuvre tells about the coefficients: Fisher-information richness metrics and
manoeuvre design.

The paper's point (1) (Furlong et al. 2003, Sec. 4.2): the spiral was not "rich" enough. Here
richness is measured on the Fisher information ``F`` of the free coefficients in relative units
(:mod:`bayesid.analysis.identifiability`) for Gaussian output error with the given noise:

- D-criterion ``log det F`` (volume of the confidence ellipsoid, larger = richer);
- E-criterion ``lambda_min(F)`` (the worst-determined direction);
- condition number ``lambda_max / lambda_min``;
- the collinearity index of the whole free set (Brun et al. 2001, Eq. 7; the largest over all
  subsets, since the index can only grow when coefficients are added);
- per-coefficient Cramér–Rao relative standard deviation ``sqrt(diag(F^-1))``;
- the predicted standard deviation along a named direction ``w``:
  ``sqrt(w^T (F + P0)^-1 w)`` with ``P0`` the prior precision (0 for none).

Design criteria follow Goodwin & Payne (1977, *Dynamic System Identification*, Ch. 6) and
Pukelsheim (1993, *Optimal Design of Experiments*): D-optimal maximises ``log det``; the
direction criterion is c-optimality (Pukelsheim Sec. 2.10) on the chosen combination.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..models import manoeuvres as mv
from . import identifiability


def fisher_metrics(problem, theta, sigmas: dict) -> dict:
    """Richness metrics of one identification problem at ``theta``.

    Parameters
    ----------
    problem : Problem or JointProblem
        :class:`~bayesid.estimation.objective.Problem` or ``JointProblem`` (a combination of
        manoeuvres).
    theta : array_like, shape (P,)
        Prime coefficients (the truth in a synthetic study).
    sigmas : dict
        ``{channel: noise sd}`` (m, rad).

    Returns
    -------
    dict
        ``F`` (P, P), ``logdet_fim`` (``-inf`` when singular), ``min_eigenvalue``,
        ``condition_number``, ``max_collinearity_index``, ``cramer_rao_sd`` (name -> relative
        sd, ``inf`` when F is singular), ``S`` (n, P) relative sensitivities.

    Raises
    ------
    KeyError
        Naming a channel without a sigma.
    """
    S = identifiability.relative_sensitivity(problem, theta)
    sig = problem.noise_vector(sigmas)
    F = identifiability.fisher_information(S, sig, problem.mask.reshape(-1))
    F = 0.5 * (F + F.T)
    lam = np.linalg.eigvalsh(F)
    sign, logdet = np.linalg.slogdet(F)
    ok = sign > 0 and lam[0] > lam[-1] * 1e-15
    crsd = np.sqrt(np.diag(np.linalg.inv(F))) if ok else np.full(len(problem.names), np.inf)
    return dict(
        F=F,
        S=S,
        logdet_fim=float(logdet) if ok else -math.inf,
        min_eigenvalue=float(lam[0]),
        condition_number=identifiability.condition_number(F),
        max_collinearity_index=identifiability.collinearity_index(S, range(S.shape[1])),
        cramer_rao_sd=dict(zip(problem.names, crsd.tolist())),
    )


def direction_sd(F: np.ndarray, w: np.ndarray, prior_precision: np.ndarray | None = None) -> float:
    """Predicted posterior sd along a unit direction (relative units): ``sqrt(w^T (F + P0)^-1 w)``.

    Parameters
    ----------
    F : ndarray, shape (P, P)
        Fisher information.
    w : ndarray, shape (P,)
        The unit direction.
    prior_precision : ndarray, shape (P,) or (P, P), optional
        Prior precision ``P0`` (diagonal or full), relative units.

    Returns
    -------
    float
        The sd; ``inf`` when the matrix is singular along ``w``.
    """
    A = np.array(F, dtype=float)
    if prior_precision is not None:
        P0 = np.asarray(prior_precision, dtype=float)
        A = A + (np.diag(P0) if P0.ndim == 1 else P0)
    try:
        v = float(w @ np.linalg.solve(A, w))
    except np.linalg.LinAlgError:
        return math.inf
    return math.sqrt(v) if v > 0 else math.inf


@dataclass
class Design:
    """Outcome of :func:`design_multisine`.

    Parameters
    ----------
    manoeuvre : Manoeuvre
        The designed manoeuvre.
    criterion : str
        ``"D"`` or ``"direction"``.
    value : float
        Criterion at the design (log det, or predicted sd along ``w``).
    start_value : float
        Criterion at the equal-weight Schroeder multisine.
    weights : ndarray, shape (K,)
        Relative amplitudes of the frequencies.
    phases : ndarray, shape (K,)
        Their phases, rad.
    n_evaluations : int
        Problems evaluated by the search.
    """

    manoeuvre: object  # the designed Manoeuvre
    criterion: str
    value: float  # criterion at the design (log det, or predicted sd along w)
    start_value: float  # criterion at the equal-weight Schroeder multisine
    weights: np.ndarray
    phases: np.ndarray
    n_evaluations: int


@dataclass(frozen=True)
class RichnessOptions:
    """What :func:`design_multisine` searches and for which criterion.

    Parameters
    ----------
    criterion : {"D", "direction"}, default "D"
        ``"D"`` (maximise log det F) or ``"direction"`` (minimise the predicted sd along
        ``direction`` with ``prior_precision``).
    direction : ndarray, shape (P,), optional
        A unit vector in relative units (the direction criterion).
    prior_precision : ndarray, shape (P,), optional
        The prior's precision in relative units (the direction criterion).
    frequencies_hz : tuple of float, default (0.005, 0.01, 0.02, 0.035, 0.05, 0.08, 0.12, 0.2)
        The multisine's frequencies (Hz).
    amplitude_deg : float, default 20.0
        The rudder peak (deg): the multisine is scaled to it, never clipped.
    duration : float, default 600.0
        The manoeuvre's duration (s).
    dt : float, default 0.5
        Its input step (s).
    maxiter : int, default 20
        Differential-evolution generations.
    popsize : int, default 6
        Its population factor (cost: maxiter * popsize * 2K problems).

    Raises
    ------
    ValueError
        An unknown criterion, or ``direction`` missing for the direction criterion.
    """

    criterion: str = "D"
    direction: np.ndarray | None = None
    prior_precision: np.ndarray | None = None
    frequencies_hz: tuple = (0.005, 0.01, 0.02, 0.035, 0.05, 0.08, 0.12, 0.2)
    amplitude_deg: float = 20.0
    duration: float = 600.0
    dt: float = 0.5
    maxiter: int = 20
    popsize: int = 6

    def __post_init__(self):
        if self.criterion not in ("D", "direction"):
            raise ValueError(f"criterion must be 'D' or 'direction', not {self.criterion!r}")
        if self.criterion == "direction" and self.direction is None:
            raise ValueError("the direction criterion needs a direction (P,)")


def design_multisine(
    vehicle,
    make_problem,
    theta,
    sigmas: dict,
    options: RichnessOptions = RichnessOptions(),
    *,
    rng: np.random.Generator | None = None,
) -> Design:
    """Search multisine rudder inputs (relative amplitude and phase per frequency) for the best
    Fisher information within the rudder limit and a duration budget.

    The rudder peak is always ``options.amplitude_deg`` (the multisine is scaled, never clipped),
    so every candidate uses the same control authority; the propeller is held at the nominal
    speed. Search: :func:`scipy.optimize.differential_evolution` (seeded from ``rng``), started
    from the equal-weight Schroeder-phase multisine.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle the manoeuvres are built for.
    make_problem : callable
        ``make_problem(manoeuvre) -> Problem`` (same free coefficients, noise-free target).
    theta : array_like, shape (P,)
        Prime coefficients where F is evaluated (local design).
    sigmas : dict
        ``{channel: sd}`` of the measurements (SI).
    options : RichnessOptions, default RichnessOptions()
        Criterion, multisine space and search settings.
    rng : numpy.random.Generator, optional
        Seeds the search (default seed 0).

    Returns
    -------
    Design
        The best multisine found (the start when the search does not improve on it).
    """
    criterion, direction, prior_precision = options.criterion, options.direction, options.prior_precision
    amplitude_deg, duration, dt = options.amplitude_deg, options.duration, options.dt
    frequencies_hz, maxiter, popsize = options.frequencies_hz, options.maxiter, options.popsize
    rng = np.random.default_rng(0) if rng is None else rng
    f = np.asarray(frequencies_hz, dtype=float)
    K = f.size
    count = [0]

    def build(x):
        w, ph = x[:K], x[K:]
        return mv.multisine(
            vehicle,
            amplitude_deg=amplitude_deg,
            frequencies_hz=f,
            duration=duration,
            dt=dt,
            name="designed",
            options=mv.MultisineOptions(phases_rad=ph, weights=np.maximum(w, 1e-3)),
        )

    def score(x):
        count[0] += 1
        m = fisher_metrics(make_problem(build(x)), theta, sigmas)
        if criterion == "D":
            return -m["logdet_fim"] if np.isfinite(m["logdet_fim"]) else 1e12
        return direction_sd(m["F"], direction, prior_precision)

    x0 = np.concatenate([np.ones(K), mv.schroeder_phases(K) % (2 * math.pi)])
    start = score(x0)
    bounds = [(0.0, 1.0)] * K + [(0.0, 2 * math.pi)] * K
    res = optimize.differential_evolution(
        score,
        bounds,
        x0=x0,
        maxiter=maxiter,
        popsize=popsize,
        tol=1e-6,
        seed=int(rng.integers(2**31)),
        polish=False,
        init="sobol",
    )
    best = res.x if res.fun < start else x0
    sign = -1.0 if criterion == "D" else 1.0
    return Design(
        build(best),
        criterion,
        sign * float(min(res.fun, start)),
        sign * float(start),
        np.maximum(best[:K], 1e-3),
        best[K:],
        count[0],
    )


__all__ = ["fisher_metrics", "direction_sd", "Design", "RichnessOptions", "design_multisine"]
