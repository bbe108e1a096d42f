"""The run that separates model structures the data cannot: rank standard manoeuvres by how far
apart the alternatives' predictions of them lie, against measurement noise and parameter
uncertainty.

Structure discovery (:mod:`bayesid.analysis.gap.discovery`) may keep a term whose alternatives
(other terms, other degrees of freedom) predict the held-out runs as well
(:func:`~bayesid.analysis.gap.discovery.confirmation.alternatives`). Which run would tell them apart? For each
manoeuvre of a menu (:func:`bayesid.models.runs.menu`: turning circles both sides at the largest and at half the
rudder, pull-outs, zigzags of other angles both sides, a spiral's rudder steps, a speed change,
a pseudo-random rudder sequence), all from the training runs' approach condition, within
their rudder rate and within the vehicle's rudder limit (:func:`within_limits`):

1. the input sequence is fixed by the kept term's model (a zigzag's rudder switches where that
   model's heading crosses the check angle; the other runs are open-loop schedules);
2. every alternative's model (each a single-term refit, :attr:`Discovery.stages`) predicts the
   run over the diagnosis's protocol windows, each window started from the kept model's state,
   as the held-out runs are scored;
3. its Gaussian predictive distribution per sample and channel (x, y, psi) has the variance of the
   error a prediction makes over a protocol window -- the measurement noise (the training runs'
   noise sd), or the largest held-out RMS of the alternatives when that is larger (their model
   error; one value for all, so that a difference of held-out error alone is no separation) --
   plus the spread of the predictions over parameter draws from the refit's Laplace covariance
   (:func:`bayesid.estimation.laplace.fit_covariance`);
4. two alternatives ``i, j`` are separated by the symmetric Kullback-Leibler (J) divergence of
   their predictive distributions, summed over samples one ``sample_s`` apart::

       J_ij = 1/2 sum_t,c [ (s_i^2 - s_j^2)^2 / (s_i^2 s_j^2) + (mu_i - mu_j)^2 (1/s_i^2 + 1/s_j^2) ]

   which is Box & Hill's criterion for discriminating between rival models with equal prior
   probabilities (Box & Hill 1967, "Discrimination among mechanistic models", Technometrics
   9:57-71, Sec. 3; the mean term alone is Hunter & Reiner's 1965 criterion). It is the expected
   log Bayes factor in favour of the right model of the two, in nats, if one of them is right:
   5 nats is a Bayes factor of about 150;
5. a run separates the set only as well as its worst pair: runs are ranked by the smallest
   pairwise divergence, and each row says which pair that is; a pair that no run of the menu
   separates (below ``DiscriminationOptions.min_separation`` on every run) is reported as not separable
   by the standard manoeuvres and the runs are ranked by the other pairs
   (:func:`rank_by_separable_pairs`);
6. the diagnosis decides with the run-by-run separation test
   (:func:`bayesid.analysis.gap.verdict.run_separation_test`), whose power grows with the
   run's windows: for the best runs, the expected window error ratio of the kept term and each
   alternative if either is right (:func:`expected_window_log_ratio`) and the scatter of window
   ratios within the held-out runs (:func:`window_log_sd`) give the windows the test needs
   (:func:`run_test_windows`), and such a run is lengthened to them (at most
   ``DiscriminationOptions.max_windows``) and scored again;
7. the runs are ranked first by the number of pairs of the kept term and an alternative that
   this test could decide on them within ``DiscriminationOptions.max_windows`` windows
   (:func:`decidable_pairs`), then by the divergence of 5. (:func:`rank_by_decidable_pairs`): a
   run with a large divergence but an expected window error ratio within the test's margin would
   not change the diagnosis's decision (the divergence sums small differences over many
   samples).

Samples of one track are correlated beyond the measurement noise (the models' own errors persist
over a window); the sum over samples ``sample_s`` apart, not every logged sample, keeps the
divergence from growing with the log rate. It ranks runs; it is not a coverage claim.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...data.track import STATE_NAMES, Track
from ...estimation.indices import manoeuvre_kind as manoeuvre_kind  # its home since the calibration reads it
from ...estimation.laplace import fit_covariance
from ...estimation.prediction import TURNING_INDICES, standard_run
from ...estimation.windows import pooled_noise_sd
from ...models.runs import (
    Approach,
    ManoeuvreRun,
    approach_condition,
    input_track,
    menu,
    run_inputs,
    simulate_run,
)
from .records import DesignedRun, PairOutlook, RunTestOutlook

__all__ = [
    "DiscriminationOptions",
    "predictive",
    "separation",
    "STANDARD_RUNS",
    "standard_predictions",
    "within_limits",
    "design",
    "rank_by_separable_pairs",
    "expected_window_log_ratio",
    "run_test_windows",
    "window_log_sd",
]

_CHANNELS = ("x", "y", "psi")
#: A designed run lasts at least this many protocol windows (when ``DiscriminationOptions.duration_s`` is
#: not given): the run-by-run separation test
#: (:func:`bayesid.analysis.gap.verdict.run_separation_test`) has no power on a run of one or two
#: windows.
RUN_WINDOWS = 3


@dataclass(frozen=True)
class DiscriminationOptions:
    """What :func:`design` simulates and how it scores.

    Parameters
    ----------
    max_rudder_deg : float, default 35.0
        The largest rudder angle of the menu (the standard turning circle's), deg; the
        vehicle's rudder limit where that is smaller (:func:`within_limits`).
    sample_s : float, default 1.0
        Spacing of the samples the divergence sums over, s.
    n_draws : int, default 8
        Parameter draws per alternative for its predictive spread (0: noise only).
    duration_s : float, optional
        Length of each run, s (default: the training runs' median length, at least 90 s and, in
        :func:`design`, at least :data:`RUN_WINDOWS` protocol windows).
    seed : int, default 0
        The draws and the pseudo-random rudder sequence.
    min_separation : float, default 20.0
        A pair of alternatives no run of the menu separates by more than this (nats) is *not
        separable by the standard manoeuvres*: it is reported (``menu_inseparable``) and does not
        rank the runs, which are ranked by the other pairs (the divergence sums correlated
        samples, so this is a ranking threshold, not a Bayes factor).
    max_windows : int, default 8
        The longest designed run the sizing for the run test proposes, in protocol windows
        (:func:`run_test_windows`; only when ``duration_s`` is not given).
    power : float, default 0.8
        The power the sizing asks of the run-by-run separation test.
    sized_rows : int, default 3
        How many of the best-ranked runs are sized.

    Raises
    ------
    ValueError
        An option out of range (named).
    """

    max_rudder_deg: float = 35.0
    sample_s: float = 1.0
    n_draws: int = 8
    duration_s: float | None = None
    seed: int = 0
    min_separation: float = 20.0
    max_windows: int = 8
    power: float = 0.8
    sized_rows: int = 3

    def __post_init__(self):
        if not 0 < self.max_rudder_deg <= 90:
            raise ValueError(f"max_rudder_deg must be in (0, 90], got {self.max_rudder_deg}")
        if not self.sample_s > 0:
            raise ValueError(f"sample_s must be > 0, got {self.sample_s}")
        if int(self.n_draws) < 0:
            raise ValueError(f"n_draws must be >= 0, got {self.n_draws}")
        if self.duration_s is not None and not self.duration_s > 0:
            raise ValueError(f"duration_s must be > 0, got {self.duration_s}")
        if not self.min_separation >= 0:
            raise ValueError(f"min_separation must be >= 0, got {self.min_separation}")
        if int(self.max_windows) < 1:
            raise ValueError(f"max_windows must be >= 1, got {self.max_windows}")
        if not 0 < self.power < 1:
            raise ValueError(f"power must be in (0, 1), got {self.power}")
        if int(self.sized_rows) < 0:
            raise ValueError(f"sized_rows must be >= 0, got {self.sized_rows}")


def within_limits(options: DiscriminationOptions, vehicle) -> DiscriminationOptions:
    """The options with ``max_rudder_deg`` no larger than the vehicle's rudder limit: a designed
    run the vessel cannot fly is no answer (NPS AUV II's file limits its rudder to 20 deg, below
    the menu's standard 35 deg turning circle).

    Parameters
    ----------
    options : DiscriminationOptions
        The design's options.
    vehicle : Vehicle or Ship or None
        The vehicle (:func:`bayesid.data.validate.rudder_limit_deg`: a submarine's
        ``limits.rudder_max``, a ship file's ``[limits] rudder_max_deg``; none: no limit).

    Returns
    -------
    DiscriminationOptions
        ``options`` itself when the vehicle has no smaller limit.
    """
    from ...data.validate import rudder_limit_deg

    limit = rudder_limit_deg(vehicle)
    if limit is None or limit >= options.max_rudder_deg:
        return options
    return replace(options, max_rudder_deg=float(limit))


def _draws(stage, ctxs, n_draws: int, rng) -> np.ndarray:
    """Parameter vectors of a fit: its estimate and ``n_draws`` draws from its Laplace
    covariance (the estimate alone when the covariance fails)."""
    p = np.asarray(stage.fit.p, float)
    if n_draws <= 0:
        return p[None]
    try:
        cov, _ = fit_covariance(stage.fit, ctxs)
    except Exception:  # noqa: BLE001 - no covariance: the estimate alone
        return p[None]
    k = stage.model.n_theta
    P = np.repeat(p[None], n_draws + 1, axis=0)
    C = 0.5 * (cov[:k, :k] + cov[:k, :k].T)
    P[1:, :k] = rng.multivariate_normal(p[:k], C, size=n_draws, method="eigh")
    return P


def predictive(stage, P: np.ndarray, reference: Track, window_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A model's Gaussian predictive distribution of a run over the protocol windows started
    from ``reference``'s states: per scored sample the mean and variance over the parameter
    vectors ``P`` of x, y (m) and psi (rad).

    Parameters
    ----------
    stage : Stage
        The model and its fit.
    P : ndarray, shape (B, n_params)
        Parameter vectors (the estimate first).
    reference : Track
        The run whose states start the windows.
    window_s : float or None
        The protocol window, s.

    Returns
    -------
    t : ndarray, shape (n,)
        Sample times, s.
    mean : ndarray, shape (n, 3)
        Predictive mean of ``x y psi`` (m, m, rad).
    var : ndarray, shape (n, 3)
        Predictive variance (parameter draws plus noise); NaN where a window diverged.
    """
    ctx = stage.model.context(reference, window_s)
    S = stage.model.simulate(ctx, P)
    cols = [STATE_NAMES.index(c) for c in _CHANNELS]
    Y = S[:, :, cols]
    psi0 = Y[0, :, 2]
    Y[:, :, 2] = psi0 + np.angle(np.exp(1j * (Y[:, :, 2] - psi0)))  # heading draws about the estimate's
    t = np.asarray(ctx.ts, float)
    return t, Y[0], Y.var(axis=0) if Y.shape[0] > 1 else np.zeros_like(Y[0])


def separation(a: tuple, b: tuple, noise_var: np.ndarray, sample_s: float) -> float:
    """The J divergence (nats) of two predictive distributions (module docstring, step 4),
    summed over samples ``sample_s`` apart.

    Parameters
    ----------
    a, b : tuple
        ``(t, mean, var)`` of :func:`predictive`, on the same samples.
    noise_var : ndarray, shape (3,)
        Measurement noise variance of x, y (m^2), psi (rad^2).
    sample_s : float
        Spacing of the samples summed, s.

    Returns
    -------
    float
        The divergence; NaN when no sample is finite in both.
    """
    t, ma, va = a
    _, mb, vb = b
    keep = np.zeros(t.size, bool)
    last = -np.inf
    for i, ti in enumerate(t):
        if ti - last >= sample_s - 1e-9:
            keep[i], last = True, ti
    sa, sb = noise_var + va[keep], noise_var + vb[keep]
    dm = ma[keep] - mb[keep]
    dm[:, 2] = np.angle(np.exp(1j * dm[:, 2]))
    terms = 0.5 * ((sa - sb) ** 2 / (sa * sb) + dm**2 * (1 / sa + 1 / sb))
    ok = np.isfinite(terms).all(axis=1)
    return float(terms[ok].sum()) if ok.any() else float("nan")


#: The standard manoeuvres :func:`standard_predictions` predicts: (kind, rudder deg or None for
#: the menu's largest, check deg, side), with the indices of :mod:`bayesid.estimation.indices`;
#: every rudder angle at most the vehicle's limit (:func:`within_limits`; a zigzag's check angle
#: its rudder angle).
STANDARD_RUNS = (
    ("turning_circle", None, None, "port"),
    ("turning_circle", None, None, "starboard"),
    ("zigzag", 10.0, 10.0, "port"),
    ("zigzag", 20.0, 20.0, "port"),
)
STANDARD_INDICES = {
    "turning_circle": TURNING_INDICES,
    "zigzag": ("first_overshoot_deg", "second_overshoot_deg"),
}


def _free_run_indices(stage, P, run: ManoeuvreRun, approach: Approach) -> list[dict]:
    """The indices of each parameter vector's free run
    (:func:`bayesid.estimation.prediction.standard_run`: a zigzag on its own switches, one batched
    simulation per pass), NaN where a run diverges."""
    keys = STANDARD_INDICES[run.kind]
    _, S, indices = standard_run(stage.model, P, run, approach)
    return [
        {k: float(got.get(k, float("nan"))) for k in keys}
        if np.isfinite(s).all()
        else dict.fromkeys(keys, float("nan"))
        for s, got in zip(S, indices)
    ]


def _spread(values: list) -> dict:
    """An index over the estimate (first) and the draws: ``value`` (the estimate's; NaN when its
    run diverged or never got there), ``low`` / ``high`` (5-95 % over the finite ones) and how many
    of ``n`` were finite."""
    v = np.asarray(values, float)
    ok = v[np.isfinite(v)]
    low, high = (float(np.percentile(ok, 5)), float(np.percentile(ok, 95))) if ok.size else (np.nan, np.nan)
    return {"value": float(v[0]), "low": low, "high": high, "n_finite": int(ok.size), "n": int(v.size)}


def standard_predictions(
    stages: dict, setup, options: DiscriminationOptions = DiscriminationOptions(), *, rng=None
) -> list[dict]:
    """Each model's free-running predictions of the standard manoeuvres (:data:`STANDARD_RUNS`:
    turning circles at the menu's largest rudder both ways, zigzags 10/10 and 20/20), from the
    training runs' approach condition, with the spread over parameter draws: where the
    alternatives part, beyond the runs they were chosen and tested on.

    The spread is the 5-95 % range of the index over the estimate and ``options.n_draws`` draws
    from each refit's Laplace covariance: parameter uncertainty only, not a calibrated band (no
    run of the kind may exist to check it on; ``in_training_kinds`` says whether one does).

    Parameters
    ----------
    stages : dict
        ``{label: Stage}``: e.g. the base model, the kept term's and its alternatives' refits.
    setup : Setup
        The diagnosis's tracks (the approach condition; the training runs' kinds).
    options : DiscriminationOptions, default DiscriminationOptions()
        ``max_rudder_deg``, ``duration_s``, ``n_draws``, ``seed``.
    rng : numpy.random.Generator, optional
        The parameter draws (default: ``options.seed``).

    Returns
    -------
    list of dict
        One per run: ``name``, ``kind``, ``rudder_deg``, ``check_deg``, ``side``,
        ``in_training_kinds`` (bool) and ``models``: ``{label: {index: {"value", "low",
        "high", "n_finite", "n"}}}`` (advance, transfer, tactical and steady turning diameter in
        m, the speed loss in the steady turn a fraction, :data:`~bayesid.estimation.prediction.TURNING_INDICES`;
        overshoots in deg; ``value`` NaN when the estimate's run diverged or never reached the index, the range
        over the ``n_finite`` of ``n`` runs that did).
    """
    rng = np.random.default_rng(options.seed) if rng is None else rng
    options = within_limits(options, setup.vehicle)
    approach = approach_condition(setup.train)
    kinds = {manoeuvre_kind(tr) for tr in setup.train}
    D = float(options.duration_s or max(150.0, approach.duration_s))
    draws = {}
    for k, st in stages.items():
        ctxs = [st.model.context(tr, setup.fit_window_s) for tr in setup.train]
        draws[k] = _draws(st, ctxs, options.n_draws, rng)
    out = []
    for kind, rudder, check, side in STANDARD_RUNS:
        a = float(options.max_rudder_deg) if rudder is None else min(rudder, float(options.max_rudder_deg))
        run = ManoeuvreRun(kind, a, None if check is None else a, side, approach.rpm, D)
        models = {}
        for k, st in stages.items():
            vals = _free_run_indices(st, draws[k], run, approach)
            models[k] = {i: _spread([v[i] for v in vals]) for i in STANDARD_INDICES[kind]}
        out.append(
            {
                "name": run.name,
                "kind": kind,
                "rudder_deg": a,
                "check_deg": check,
                "side": side,
                "in_training_kinds": kind in kinds,
                "models": models,
            }
        )
    return out


def design(
    stages: dict, setup, options: DiscriminationOptions = DiscriminationOptions(), *, rng=None, thresholds=None
) -> list[DesignedRun]:
    """Rank the menu's runs by how well they separate alternative model structures (module
    docstring: first by the pairs the run-by-run test could decide on them, then by the Box-Hill
    divergence), and size the best for that test (:func:`run_test_windows`).

    Parameters
    ----------
    stages : dict
        ``{label: Stage}``: the kept term's single-term model first, then its alternatives (at
        least two).
    setup : Setup
        The diagnosis's tracks and windows (:class:`bayesid.analysis.gap.candidates.Setup`); its
        training runs give the approach condition and the noise, its held-out runs the
        scatter of the window error ratios.
    options : DiscriminationOptions, default DiscriminationOptions()
        The menu's limits, the number of parameter draws, the sizing and the seed.
    rng : numpy.random.Generator, optional
        Parameter draws and the PRBS (default: ``options.seed``).
    thresholds : Thresholds, optional
        The run test's margin and level (``separation_margin``, ``partial_p``; default
        :class:`bayesid.analysis.gap.verdict.Thresholds`).

    Returns
    -------
    list of DesignedRun
        Best first (:class:`~bayesid.analysis.gap.records.DesignedRun`): the run, its
        ``separation`` (the smallest pairwise divergence, nats, over the pairs some run of the menu
        separates: :func:`rank_by_separable_pairs`) and ``worst_pair``, every pair's divergence
        (``pairs``, keyed ``(a, b)``), ``menu_inseparable`` (the pairs no run of the menu separates
        by more than ``options.min_separation``, the same on every row), the largest distance
        between two alternatives' predicted positions, the run test's outlook (``run_test``: the
        kept term against each alternative, the windows it needs, and the menu's duration when
        sizing lengthened the run), ``decidable_pairs`` (:func:`decidable_pairs`), the input
        schedule (``inputs``, :func:`bayesid.models.runs.run_inputs`) and the estimates'
        predictions over the windows (``predicted``, for the figure).

    Raises
    ------
    ValueError
        Fewer than two stages.
    """
    from .verdict import Thresholds

    if len(stages) < 2:
        raise ValueError(f"design needs at least two alternative models, got {len(stages)}")
    rng = np.random.default_rng(options.seed) if rng is None else rng
    th = Thresholds() if thresholds is None else thresholds
    options = within_limits(options, setup.vehicle)
    approach = approach_condition(setup.train)
    if options.duration_s is None and setup.window_s:  # enough windows for the run test to see it
        approach = replace(approach, duration_s=max(approach.duration_s, RUN_WINDOWS * float(setup.window_s)))
    sd = pooled_noise_sd(setup.train)
    noise_var = np.array([sd.get(c, 0.0) ** 2 for c in _CHANNELS]) + 1e-12
    # the error a prediction makes beyond the parameters' spread: the measurement noise, or the
    # largest held-out RMS of the alternatives when larger (their model error), one variance for
    # every alternative, so that a difference of held-out error alone is not a separation
    held = [[(st.held or {}).get("rms", {}).get(c, 0.0) for c in _CHANNELS] for st in stages.values()]
    noise_var = np.maximum(noise_var, np.nanmax(np.square(np.asarray(held, float)), axis=0))
    ctxs = {k: [st.model.context(tr, setup.fit_window_s) for tr in setup.train] for k, st in stages.items()}
    scoring = _Scoring(
        stages=stages,
        approach=approach,
        noise_var=noise_var,
        draws={k: _draws(st, ctxs[k], options.n_draws, rng) for k, st in stages.items()},
        window_s=setup.window_s,
        sample_s=options.sample_s,
        log_sd=window_log_sd(stages, setup),
        n_runs=len(setup.heldout) + 1,
        margin=th.separation_margin,
        level=th.partial_p,
        power=options.power,
    )
    out = [
        r
        for r in (_evaluate(run, scoring, rng) for run in menu(approach, options.max_rudder_deg, options.duration_s))
        if r is not None
    ]
    out = rank_by_decidable_pairs(rank_by_separable_pairs(out, options.min_separation), options.max_windows)
    if options.duration_s is None and setup.window_s and options.sized_rows:
        inseparable = set(out[0].menu_inseparable) if out else set()
        out[: options.sized_rows] = [
            _sized(r, scoring, rng, inseparable, options.max_windows) for r in out[: options.sized_rows]
        ]
        out = rank_by_decidable_pairs(out, options.max_windows)
    return out


@dataclass(frozen=True)
class _Scoring:
    """What scoring one run of the menu needs (:func:`_evaluate`)."""

    stages: dict
    approach: Approach
    noise_var: np.ndarray
    draws: dict
    window_s: float | None
    sample_s: float
    log_sd: float | None
    n_runs: int
    margin: float
    level: float
    power: float


def _evaluate(run: ManoeuvreRun, sc: _Scoring, rng) -> DesignedRun | None:
    """One menu run's row of :func:`design` (before ranking), None when the kept model diverges
    on it or no pair is finite."""
    labels = list(sc.stages)
    best = sc.stages[labels[0]]
    t, delta, n = run_inputs(best.model, best.fit.p, run, sc.approach, rng)
    ref = simulate_run(best.model, best.fit.p, input_track(t, delta, n, sc.approach), sc.approach)
    if ref is None:
        return None
    pred = {k: predictive(st, sc.draws[k], ref, sc.window_s) for k, st in sc.stages.items()}
    pairs = {}
    for i, a in enumerate(labels):
        for b in labels[i + 1 :]:
            pairs[(a, b)] = separation(pred[a], pred[b], sc.noise_var, sc.sample_s)
    finite = {k: v for k, v in pairs.items() if np.isfinite(v)}
    if not finite:
        return None
    worst = min(finite, key=finite.get)
    t_pred = next(iter(pred.values()))[0]
    each_s = np.r_[True, np.diff(np.floor(t_pred + 1e-9)) > 0]  # the figure's samples: one a second
    pos = np.stack([p[1][:, :2] for p in pred.values()])
    gap = np.sqrt(((pos[:, None] - pos[None]) ** 2).sum(axis=-1)).max(axis=(0, 1))
    win = best.model.context(ref, sc.window_s).win
    return DesignedRun(
        kind=run.kind,
        rudder_deg=run.rudder_deg,
        check_deg=run.check_deg,
        side=run.side,
        rpm=run.rpm,
        duration_s=run.duration_s,
        name=run.name,
        separation=finite[worst],
        worst_pair=worst,
        pairs=pairs,
        max_position_difference_m=float(np.nanmax(gap)),
        run_test=_run_test_outlook(pred, win, sc),
        inputs={"t": t.tolist(), "delta_r": delta.tolist(), "n": n.tolist()},
        predicted={
            k: {"t": p[0][each_s].tolist(), **{c: p[1][each_s, j].tolist() for j, c in enumerate(_CHANNELS)}}
            for k, p in pred.items()
        },
    )


def _run_test_outlook(pred: dict, win: np.ndarray, sc: _Scoring) -> RunTestOutlook:
    """The kept term (first label) against each alternative on one run: the expected window
    error ratio if either model were right and the windows the run test would need
    (:func:`expected_window_log_ratio`, :func:`run_test_windows`)."""
    labels = list(pred)
    pos_var = float(sc.noise_var[0] + sc.noise_var[1])
    out = {}
    for b in labels[1:]:
        m = expected_window_log_ratio(pred[labels[0]][1], pred[b][1], win, pos_var)
        need = (
            run_test_windows(m, sc.log_sd, sc.n_runs, margin=sc.margin, level=sc.level, power=sc.power)
            if sc.log_sd is not None and np.isfinite(m)
            else None
        )
        out[(labels[0], b)] = PairOutlook(float(np.exp(m)) if np.isfinite(m) else None, need)
    return RunTestOutlook(int(np.unique(win).size), sc.log_sd, out)


def _sized(row: DesignedRun, sc: _Scoring, rng, inseparable: set, max_windows: int) -> DesignedRun:
    """``row`` lengthened (up to ``max_windows`` protocol windows) until the run test would see
    the kept term apart from each alternative it can separate at all, re-simulated at each
    length (a pull-out's straight leg, say, adds windows that part the models less)."""
    first = row
    for _ in range(3):
        rt = row.run_test
        need = [
            v.windows_needed
            for k, v in rt.pairs.items()
            if k not in inseparable and v.windows_needed is not None and np.isfinite(v.windows_needed)
        ]
        target = min(int(max_windows), int(math.ceil(max(need)))) if need else 0
        if target <= rt.windows:
            break
        run = ManoeuvreRun(row.kind, row.rudder_deg, row.check_deg, row.side, row.rpm, target * float(sc.window_s))
        longer = _evaluate(run, sc, rng)
        if longer is None:
            break
        row = longer
    if row is first:
        return row
    keep = [k for k in row.pairs if k not in inseparable and np.isfinite(row.pairs[k])]
    worst = min(keep, key=row.pairs.get) if keep else row.worst_pair
    return replace(
        row,
        run_test=replace(row.run_test, sized_from_s=first.duration_s),
        menu_inseparable=first.menu_inseparable,
        worst_pair=worst,
        separation=float(row.pairs[worst]) if keep else row.separation,
    )


def expected_window_log_ratio(mean_a: np.ndarray, mean_b: np.ndarray, win: np.ndarray, pos_var: float) -> float:
    """The mean over a run's protocol windows of the expected log ratio of two models' window
    position errors, if one of them is right: ``1/2 log(1 + D_w / s^2)`` with ``D_w`` the mean
    squared distance between their predicted positions over window ``w`` and ``s^2`` the position
    error variance a right model makes (the design's noise variance of x plus y). The window
    error is the RMS of :func:`bayesid.estimation.windows.window_rms`: the wrong model's error
    squared is the right one's plus ``D_w``.

    Parameters
    ----------
    mean_a, mean_b : ndarray, shape (n, 3)
        Predicted ``x y psi`` of the two models at the run's scored samples (m, m, rad).
    win : ndarray of int, shape (n,)
        The protocol window of each sample.
    pos_var : float
        Position error variance of a right model, m^2 (positive).

    Returns
    -------
    float
        The mean expected log ratio; NaN when no window is finite.
    """
    d2 = ((np.asarray(mean_a)[:, :2] - np.asarray(mean_b)[:, :2]) ** 2).sum(axis=1)
    per = []
    for w in np.unique(win):
        v = d2[(win == w) & np.isfinite(d2)]
        if v.size:
            per.append(0.5 * math.log1p(float(v.mean()) / pos_var))
    return float(np.mean(per)) if per else float("nan")


def run_test_windows(
    log_ratio: float, log_sd: float, n_runs: int, *, margin: float = 0.1, level: float = 0.01, power: float = 0.8
) -> float:
    """Protocol windows one run needs for the run-by-run separation test
    (:func:`bayesid.analysis.gap.verdict.run_separation_test`) to find a model whose window
    errors are ``exp(log_ratio)`` times another's, with the given power: the one-sided test of the
    run's mean log ratio against ``log(1 + margin)`` at ``level / n_runs`` (Bonferroni), its
    variance ``log_sd^2 / n``, in the normal approximation::

        n = ((z_{1 - level / n_runs} + z_power) * log_sd / (log_ratio - log(1 + margin)))^2

    (the sample size of a one-sided one-sample test, e.g. Chow, Shao & Wang, "Sample Size
    Calculations in Clinical Research", 2nd ed., 2008, Sec. 3.1.1).

    Parameters
    ----------
    log_ratio : float
        The expected mean log ratio of the window errors on the run
        (:func:`expected_window_log_ratio`).
    log_sd : float
        The sd of the log ratios of the windows of one run about their run's mean (positive).
    n_runs : int
        The runs the test's Bonferroni factor counts (the held-out runs, the designed one
        included).
    margin : float, default 0.1
        The test's margin.
    level : float, default 0.01
        The test's level before the Bonferroni factor.
    power : float, default 0.8
        The probability of finding the difference.

    Returns
    -------
    float
        The windows needed (at least 2, the fewest the test uses); ``inf`` when the expected
        ratio does not exceed ``1 + margin``.

    Raises
    ------
    ValueError
        A non-positive ``log_sd`` or ``n_runs``, or ``level`` or ``power`` outside (0, 1).
    """
    from scipy import stats

    if not log_sd > 0 or int(n_runs) < 1:
        raise ValueError(f"log_sd and n_runs must be positive, got {log_sd}, {n_runs}")
    if not (0 < level < 1 and 0 < power < 1):
        raise ValueError(f"level and power must be in (0, 1), got {level}, {power}")
    step = log_ratio - math.log1p(margin)
    if not step > 0:
        return float("inf")
    z = stats.norm.ppf(1.0 - level / int(n_runs)) + stats.norm.ppf(power)
    return max(2.0, float((z * log_sd / step) ** 2))


def window_log_sd(stages: dict, setup) -> float | None:
    """The scatter of window error ratios within one run: the pooled within-run sd of
    ``log(e_alternative / e_kept)`` over the held-out windows of every alternative against the
    kept term (the first stage), each run's windows about that run's mean (the variance
    :func:`bayesid.analysis.gap.verdict.run_separation_test` uses).

    Parameters
    ----------
    stages : dict
        ``{label: Stage}``, the kept term first; each with its per-window held-out errors
        (``windows``).
    setup : Setup
        The held-out tracks, window and start rule (the run of each window).

    Returns
    -------
    float or None
        The sd; None with fewer than 2 degrees of freedom or windows that do not match the runs.
    """
    labels = list(stages)
    first = stages[labels[0]]
    ctxs = [first.model.context(t, setup.window_s, start=setup.rule, leadin_s=setup.leadin_s) for t in setup.heldout]
    runs = np.repeat(np.arange(len(ctxs)), [c.W for c in ctxs])
    e0 = np.asarray(first.windows, float)
    ss, df = 0.0, 0
    for k in labels[1:]:
        e1 = np.asarray(stages[k].windows, float)
        if e1.shape != e0.shape or e0.shape != runs.shape:
            return None
        ok = np.isfinite(e0) & np.isfinite(e1) & (e0 > 0) & (e1 > 0)
        d = np.log(e1[ok] / e0[ok])
        for r in np.unique(runs[ok]):
            x = d[runs[ok] == r]
            ss += float(((x - x.mean()) ** 2).sum())
            df += x.size - 1
    return float(math.sqrt(ss / df)) if df >= 2 and ss > 0 else None


def decidable_pairs(row: DesignedRun, max_windows: int) -> list:
    """The pairs of the kept term and an alternative (or the model without it) that the run-by-run
    test could decide on this run: some run of the menu separates them (not in
    ``row.menu_inseparable``) and the run test needs at most ``max_windows`` protocol windows
    to find their expected window error ratio with its power (:func:`run_test_windows`).

    A run whose divergence is large but whose expected window error ratio stays within the run
    test's margin would not change the diagnosis's decision: the divergence sums small
    differences over many samples, the decision reads window errors.

    Parameters
    ----------
    row : DesignedRun
        A designed run (its ``run_test`` pairs' ``windows_needed``; ``menu_inseparable``, if set).
    max_windows : int
        The most protocol windows a designed run may last (``DiscriminationOptions.max_windows``).

    Returns
    -------
    list of tuple
        The decidable pairs ``(kept, alternative)``, in the order of ``row.run_test.pairs``.
    """
    inseparable = set(row.menu_inseparable or {})
    out = []
    for pair, v in row.run_test.pairs.items():
        need = v.windows_needed
        if pair not in inseparable and need is not None and np.isfinite(need) and need <= max_windows:
            out.append(pair)
    return out


def rank_by_decidable_pairs(rows: list, max_windows: int) -> list:
    """Rank designed runs by the number of pairs the run test could decide on them
    (:func:`decidable_pairs`, set on each row as ``decidable_pairs``), then by their
    separation (nats, :func:`rank_by_separable_pairs`).

    The divergence ranks the runs by how far apart the alternatives' predictive distributions
    lie (Box & Hill 1967); the diagnosis decides between the alternatives by the run-by-run
    test of window errors against a margin. The design asks first for the run on which that
    decision can be made, and among equals for the largest divergence.

    Parameters
    ----------
    rows : list of DesignedRun
        Designed runs.
    max_windows : int
        As :func:`decidable_pairs`.

    Returns
    -------
    list of DesignedRun
        The rows with ``decidable_pairs`` set, best first.
    """
    rows = [replace(r, decidable_pairs=decidable_pairs(r, max_windows)) for r in rows]
    return sorted(rows, key=lambda r: (-len(r.decidable_pairs), -r.separation))


def rank_by_separable_pairs(rows: list, min_separation: float) -> list:
    """Rank designed runs by their worst pair among the pairs some run separates.

    A pair of alternatives whose divergence stays below ``min_separation`` on every run of the
    menu cannot be told apart by any of the standard manoeuvres (their terms make the same force
    history in all of them, e.g. ``v^2 r`` and ``v |v| |r|`` where ``v r < 0`` throughout); ranking
    the runs by it would rank them by noise. Such pairs are listed in every row's
    ``menu_inseparable`` and the runs are ranked by the smallest divergence of the other pairs
    (all pairs when none is separable).

    Parameters
    ----------
    rows : list of DesignedRun
        Designed runs (their ``pairs``: divergences, nats).
    min_separation : float
        The divergence (nats) a pair's best run must exceed to count as separable.

    Returns
    -------
    list of DesignedRun
        The rows, best first, each with ``separation``, ``worst_pair`` and ``menu_inseparable``
        (``{pair: {"best_run", "separation"}}``) set.
    """
    best: dict = {}
    for r in rows:
        for pair, v in r.pairs.items():
            if np.isfinite(v) and (pair not in best or v > best[pair][1]):
                best[pair] = (r.name, float(v))
    inseparable = {k: {"best_run": b[0], "separation": b[1]} for k, b in best.items() if b[1] < min_separation}
    ranked = [k for k in best if k not in inseparable] or list(best)
    out = []
    for r in rows:
        finite = {k: r.pairs[k] for k in ranked if np.isfinite(r.pairs.get(k, np.nan))}
        worst = min(finite, key=finite.get) if finite else r.worst_pair
        sep = float(finite[worst]) if finite else r.separation
        out.append(replace(r, separation=sep, worst_pair=worst, menu_inseparable=inseparable))
    return sorted(out, key=lambda r: -r.separation)
