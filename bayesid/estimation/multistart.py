"""Multistart identification: the same fit from many starts, run as independent tasks
(:mod:`bayesid.tasks`), to show whether the data single out one optimum.

On collinear data one local optimum is not an answer: the paper's finding (Furlong et al. 2003,
Sec. 5) is that widely different coefficient sets give almost identical manoeuvres. A multistart
fit makes that visible on the user's own tracks: the sorted final costs (a waterfall), how many
starts reach the best cost within a tolerance, and how far apart in coefficient space those
near-best optima are.

Starts (:func:`start_points`): the default start plus a Latin hypercube (scipy.stats.qmc) in the
box ``p0 +- spread * scale`` of each parameter (``scale`` the model's typical size,
:meth:`~bayesid.models.interface.SimulationModel.scales`), clipped to the parameter bounds.

Every start is fitted with the *same* channel weights (those of the default fit), so the costs
compare; a two-step (residual-weighted) fit sets the weights once, on the default start.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import qmc

from ..tasks import Runner, Task, TaskError
from .windows import WindowProblem, fit_model

__all__ = [
    "start_points",
    "fit_start",
    "MultistartResult",
    "summarise_starts",
    "run_starts",
    "multistart",
    "COST_TOLERANCE",
    "DISTINCT_TOLERANCE",
]

#: A start reached the best optimum when its cost is within this fraction of the best cost.
COST_TOLERANCE = 0.01
#: Two optima are distinct when a parameter differs by more than this fraction of its scale.
DISTINCT_TOLERANCE = 0.05


def start_points(p0, scales, lo, hi, n: int, rng, spread: float = 1.0) -> np.ndarray:
    """Latin-hypercube starts in ``p0 +- spread * |scales|`` clipped to ``[lo, hi]``.

    Parameters
    ----------
    p0 : array_like, shape (P,)
        Default start.
    scales : array_like, shape (P,)
        Typical sizes of the parameters.
    lo, hi : array_like, shape (P,)
        Bounds (+-inf allowed).
    n : int
        Number of starts (>= 0).
    rng : numpy.random.Generator
        Seeds the hypercube.
    spread : float, default 1.0
        Half-width of the box in units of ``scales``.

    Returns
    -------
    ndarray, shape (n, P)
        The starts.

    Raises
    ------
    ValueError
        For ``n < 0`` or a non-positive ``spread``.
    """
    p0, scales = np.asarray(p0, float), np.abs(np.asarray(scales, float))
    if n < 0 or not spread > 0:
        raise ValueError(f"start_points: n must be >= 0 and spread positive, got {n} and {spread}")
    if n == 0:
        return np.empty((0, p0.size))
    a = np.maximum(np.asarray(lo, float), p0 - spread * scales)
    b = np.minimum(np.asarray(hi, float), p0 + spread * scales)
    u = qmc.LatinHypercube(d=p0.size, seed=rng).random(n)
    return a + u * (b - a)


def fit_start(p0, problem: WindowProblem) -> dict:
    """One start of a multistart fit of a model (a task; runs in a worker): the multiple-shooting
    fit (:func:`bayesid.estimation.windows.fit_model`) of ``problem`` (fixed weights) from ``p0``.

    Parameters
    ----------
    p0 : array_like, shape (P,)
        The start.
    problem : WindowProblem
        The fit's problem and settings.

    Returns
    -------
    dict
        JSON-able: ``p`` (P,), ``cost`` (noise-scaled SSR, inf when the fit failed),
        ``success``, ``nfev``, ``message``.
    """
    try:
        f = fit_model(problem, np.asarray(p0, float))
    except Exception as exc:  # noqa: BLE001 - a start that diverges is a result, not an error
        return {
            "p": list(map(float, p0)),
            "cost": float("inf"),
            "success": False,
            "nfev": 0,
            "message": f"{type(exc).__name__}: {exc}",
        }
    return {
        "p": f.p.tolist(),
        "cost": float(f.cost) if np.isfinite(f.cost) else float("inf"),
        "success": bool(f.success),
        "nfev": int(f.n_simulations),
        "message": str(f.message),
    }


@dataclass
class MultistartResult:
    """The starts and their optima, best first.

    Parameters
    ----------
    names : list of str
        Parameter names.
    starts : ndarray, shape (n, P)
        Start vectors, the default first.
    kinds : list of str
        Per start, ``"default"`` or ``"lhs"``.
    fits : list of dict
        Per start, :func:`fit_start`'s dict.
    order : list of int
        Start indices sorted by final cost.
    best : int
        Index of the lowest cost.
    near_best : list of int
        Indices within :data:`COST_TOLERANCE` of the best cost.
    distinct : list of list of int
        Groups (lists of start indices) of near-best optima that lie within
        :data:`DISTINCT_TOLERANCE` scales of each other; the first holds the best.
    spread : dict
        ``{name: (max - min) of the near-best optima / scale}`` per parameter.
    max_distance : float
        Largest scaled distance (max over parameters of |difference| / scale) between two
        near-best optima.
    scales : ndarray, shape (P,), optional
        The parameter scales.
    """

    names: list
    starts: np.ndarray
    kinds: list
    fits: list
    order: list
    best: int
    near_best: list
    distinct: list
    spread: dict
    max_distance: float
    scales: np.ndarray = field(repr=False, default=None)

    def costs(self) -> np.ndarray:
        """Final costs sorted ascending (the waterfall).

        Returns
        -------
        ndarray, shape (n,)
            The costs.
        """
        return np.array([self.fits[i]["cost"] for i in self.order], float)

    def to_dict(self) -> dict:
        """JSON-able summary (model.json's ``multistart``).

        Returns
        -------
        dict
            Counts, tolerances, the best start and cost, the sorted costs, the near-best and
            distinct optima (with their coefficients) and one entry per start.
        """
        best_cost = self.fits[self.best]["cost"]
        return {
            "n_starts": len(self.fits),
            "cost_tolerance": COST_TOLERANCE,
            "distinct_tolerance_scales": DISTINCT_TOLERANCE,
            "best_start": self.best,
            "best_kind": self.kinds[self.best],
            "best_cost": best_cost,
            "sorted_costs": self.costs().tolist(),
            "n_near_best": len(self.near_best),
            "n_distinct_near_best": len(self.distinct),
            "max_scaled_distance_near_best": self.max_distance,
            "spread_near_best_scales": self.spread,
            "distinct_optima": [
                {
                    "starts": g,
                    "cost": self.fits[g[0]]["cost"],
                    "relative_cost": self.fits[g[0]]["cost"] / best_cost - 1 if best_cost else 0.0,
                    "coefficients": dict(zip(self.names, self.fits[g[0]]["p"])),
                }
                for g in self.distinct
            ],
            "starts": [
                {"kind": k, "cost": f["cost"], "success": f["success"], "nfev": f["nfev"]}
                for k, f in zip(self.kinds, self.fits)
            ],
        }


def summarise_starts(names, starts, kinds, fits, scales) -> MultistartResult:
    """Sort the optima, count the near-best and group them into distinct optima (greedy, in cost
    order: an optimum joins the first group whose best member is within
    :data:`DISTINCT_TOLERANCE` scales in every parameter).

    Parameters
    ----------
    names : sequence of str
        Parameter names.
    starts : array_like, shape (n, P)
        Start vectors.
    kinds : sequence of str
        Per start, ``"default"`` or ``"lhs"``.
    fits : sequence of dict
        Per start, :func:`fit_start`'s dict.
    scales : array_like, shape (P,)
        Parameter scales.

    Returns
    -------
    MultistartResult
        The summary.
    """
    scales = np.abs(np.asarray(scales, float))
    costs = np.array([f["cost"] for f in fits], float)
    order = [int(i) for i in np.argsort(np.where(np.isfinite(costs), costs, np.inf), kind="stable")]
    best = order[0]
    near = [i for i in order if np.isfinite(costs[i]) and costs[i] <= costs[best] * (1 + COST_TOLERANCE)]
    P = np.array([fits[i]["p"] for i in near], float)
    groups: list[list[int]] = []
    for i, p in zip(near, P):
        for g in groups:
            if np.max(np.abs(p - np.asarray(fits[g[0]]["p"])) / scales) <= DISTINCT_TOLERANCE:
                g.append(i)
                break
        else:
            groups.append([i])
    spread = dict(zip(names, ((P.max(0) - P.min(0)) / scales).tolist())) if len(near) else {}
    dist = float(max((np.max(np.abs(a - b) / scales) for a in P for b in P), default=0.0))
    return MultistartResult(
        list(names), np.asarray(starts, float), list(kinds), list(fits), order, best, near, groups, spread, dist, scales
    )


def run_starts(
    fit_fn,
    args: tuple,
    names,
    starts,
    kinds,
    scales,
    default_fit: dict | None = None,
    runner: Runner = Runner(),
) -> MultistartResult:
    """Fit from every start as a task and summarise (:func:`summarise_starts`).

    Parameters
    ----------
    fit_fn : callable
        Module-level ``fit_fn(p0, *args) -> {"p", "cost", "success", "nfev", "message"}``
        (:func:`fit_start` for a model).
    args : tuple
        The further arguments of ``fit_fn``.
    names : sequence of str
        Parameter names.
    starts : array_like, shape (n, P)
        The starts, the default first.
    kinds : sequence of str
        Per start, ``"default"`` or ``"lhs"``.
    scales : array_like, shape (P,)
        Parameter scales.
    default_fit : dict, optional
        The first start's result when already fitted (it is then not run again).
    runner : Runner, default Runner()
        :class:`bayesid.tasks.Runner` of the starts.

    Returns
    -------
    MultistartResult
        The summary; a failed task counts as a start with an infinite cost.
    """
    starts = np.asarray(starts, float)
    tasks = [
        Task(f"start{i:03d}", {"start": i, "kind": k, "p0": s.tolist()}, (s, *args))
        for i, (k, s) in enumerate(zip(kinds, starts))
    ]
    todo = tasks[1:] if default_fit is not None else tasks
    outs = runner.run(fit_fn, todo, label="starts")
    fits = ([default_fit] if default_fit is not None else []) + [
        {"p": t.params["p0"], "cost": float("inf"), "success": False, "nfev": 0, "message": str(o)}
        if isinstance(o, TaskError)
        else dict(o)
        for t, o in zip(todo, outs)
    ]
    for f in fits:  # a journaled inf comes back as the string "inf"
        f["cost"] = float(f["cost"])
    return summarise_starts(names, starts, kinds, fits, scales)


def multistart(
    problem: WindowProblem,
    p_default,
    n_starts: int,
    rng,
    *,
    default_fit: dict | None = None,
    spread: float = 1.0,
    runner: Runner = Runner(),
) -> MultistartResult:
    """Fit a model from the default start and ``n_starts`` Latin-hypercube starts, as tasks.

    Parameters
    ----------
    problem : WindowProblem
        :class:`~bayesid.estimation.windows.WindowProblem` (model, training contexts, fixed channel
        weights ``sd``, scored channels, iterations; its prior is not used).
    p_default : array_like, shape (P,)
        The default start.
    n_starts : int
        Extra starts (>= 1).
    rng : numpy.random.Generator
        Seeds the Latin hypercube.
    default_fit : dict, optional
        The default start's result when already fitted (a :func:`fit_start` dict), else it is
        fitted as one of the tasks.
    spread : float, default 1.0
        Half-width of the start box in scales (:func:`start_points`).
    runner : Runner, default Runner()
        :class:`bayesid.tasks.Runner` of the starts (its journal resumes a killed run).

    Returns
    -------
    MultistartResult
        The starts and their optima, best first.

    Raises
    ------
    ValueError
        For ``n_starts < 1``.
    """
    if n_starts < 1:
        raise ValueError(f"multistart needs at least one start besides the default, not {n_starts}")
    model = problem.model
    lo, hi = model.bounds()
    scales = model.scales()
    extra = start_points(p_default, scales, lo, hi, n_starts, rng, spread)
    starts = np.vstack([np.asarray(p_default, float)[None], extra])
    return run_starts(
        fit_start,
        (dataclasses.replace(problem, prior=None, data_scale=None),),
        model.param_names,
        starts,
        ["default"] + ["lhs"] * n_starts,
        scales,
        default_fit,
        runner,
    )
