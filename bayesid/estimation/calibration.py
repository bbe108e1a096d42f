"""Predictive bands that hold their stated coverage: split-conformal calibration of a fitted model's
predictions on its own training runs, leave one run out.

A Laplace (or MCMC) posterior carries parameter uncertainty only. On real runs the model's
structural error dominates: at 20 Hz, samples inside one structural miss are not independent
evidence, and a 5-95 % band of posterior draws holds 1 of 8 measured overshoots on the KVLCC2
held-out zigzags. The remedy here is to measure the error the model actually makes on runs it
did not see, on the training runs themselves:

1. for each training run k, refit the model on the other runs (from the full fit's optimum, the
   same channel weights and prior) and take its Laplace posterior;
2. predict run k under the window protocol: per window the largest horizontal position error (m)
   and heading error (deg); and its manoeuvre indices (advance, transfer, tactical diameter,
   overshoots) with the spread (sd) of ``n_draws`` posterior draws;
3. nonconformity scores: window maxima as they are (metres, degrees); index errors normalised
   by the scale the error is expected to have, ``|measured - predicted| / sqrt(sd^2 + (kappa *
   predicted)^2)``: ``sd`` the fold's posterior spread of the index (parameter uncertainty) and
   ``kappa`` the calibration's typical relative error of that index (the median of
   ``|measured - predicted| / |predicted|`` over its scored rows, or over every row for an index
   with too few: the model's structural error, which grows with the size of the index). One
   score serves indices of different size and kind, and the band widens where the posterior is
   uncertain (an extrapolated manoeuvre) as well as where the index is large (locally weighted
   conformal: Lei et al. 2018, Sec. 5.2);
4. a band at level ``a`` is the split-conformal quantile of the scores (Vovk, Gammerman & Shafer
   2005; Lei et al. 2018, JASA 113:1094, Sec. 2): the ``ceil((n + 1) a)``-th smallest of ``n``
   scores, which holds at least ``a`` of the time for a new run exchangeable with the
   calibration runs. With too few scores for a level the band is unbounded (reported, not
   hidden).

A window band is the joint claim "the measured track stays within ``r`` of the prediction over
the window, and the heading within ``h``" (one score per window:
:meth:`Calibration.joint_window_scores`); an
index band is ``predicted +- q * sqrt(sd^2 + (kappa * predicted)^2)`` with ``sd`` the posterior
draws' spread of that index on the predicted run. Index kinds with fewer than
:data:`MIN_SCORES_PER_KEY` scores borrow the pooled scores of every index. An index kind with
no score at all (a turning circle predicted by a zigzag-trained model) is an extrapolation: its
band is given but flagged and kept out of the calibrated coverage (:data:`EXTRAPOLATION_NOTE`).

The index score needs ``kappa``: ``|measured - predicted| / sd`` alone fails on real runs, as an
overshoot's posterior spread can be a hundredth of its structural error, so the pooled scores
reach 360 and a zigzag-trained model's turning-circle band runs from -450 m to 490 m (Esso
Osaka).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from ..tasks import Runner, Task, TaskError
from . import windows as wf
from .indices import index_keys, manoeuvre_kind
from .laplace import fit_covariance
from .options import CalibrationOptions
from .prediction import FittedModel, predict, turning_band

__all__ = [
    "LEVELS",
    "MAX_FOLDS",
    "MIN_SCORES_PER_KEY",
    "MIN_ROWS_PER_KAPPA",
    "MIN_WINDOW_FRACTION",
    "INDEX_SCORE",
    "EXTRAPOLATION_NOTE",
    "full_window",
    "conformal_quantile",
    "Fold",
    "fold_scores",
    "leave_one_run_out",
    "Calibration",
    "uncalibrated_bands",
    "excitation",
    "yaw_rate_prime",
    "EXCITATION_MEASURES",
    "structural_scale",
    "coverage_table",
]

#: Nominal levels of the bands and of the reliability figure.
LEVELS = (0.5, 0.8, 0.9, 0.95)
#: An index kind with fewer calibration scores uses the pooled scores of all indices.
MIN_SCORES_PER_KEY = 9
#: An index with fewer calibration rows takes the median relative error of every index as its scale.
MIN_ROWS_PER_KAPPA = 3
#: Refits of a calibration: with more training runs, runs are left out in groups.
MAX_FOLDS = CalibrationOptions.max_folds
#: A window shorter than this fraction of the protocol window (a run's last, cut-off window) is
#: neither a calibration score nor a claim: its error has had no time to grow.
MIN_WINDOW_FRACTION = 0.5
#: Why a band of a manoeuvre the calibration never saw is not counted as calibrated.
EXTRAPOLATION_NOTE = (
    "no training run was of this manoeuvre kind, so no left-out error of it was ever measured: its bands "
    "borrow the scores of the other indices and are not calibrated (on synthetic tracks a zigzag-trained "
    "model's 90 % bands held under half of the turning circles' tactical diameters and windows); train on "
    "at least one run of each manoeuvre you predict"
)
#: The index nonconformity score, in words (written with every calibration).
INDEX_SCORE = "|measured - predicted| / sqrt(sd^2 + (kappa * predicted)^2)"


def full_window(w: dict, window_s: float) -> bool:
    """Whether a protocol window is long enough to score.

    Parameters
    ----------
    w : dict
        A window of a :class:`~bayesid.estimation.prediction.Prediction` (its ``duration_s``).
    window_s : float
        The protocol window, s.

    Returns
    -------
    bool
        True when the window lasts at least :data:`MIN_WINDOW_FRACTION` of ``window_s`` (or
        has no duration).
    """
    return w.get("duration_s") is None or w["duration_s"] >= MIN_WINDOW_FRACTION * window_s


def conformal_quantile(scores, level: float) -> float:
    """Split-conformal quantile: the ``ceil((n + 1) level)``-th smallest finite score, ``inf``
    when there are too few scores for the level (n < ``level / (1 - level)``).

    Parameters
    ----------
    scores : iterable of float
        The n nonconformity scores (None and non-finite ones are dropped).
    level : float
        In (0, 1).

    Returns
    -------
    float
        The quantile, ``inf`` with too few scores.

    Raises
    ------
    ValueError
        For a level outside (0, 1).
    """
    if not 0 < level < 1:
        raise ValueError(f"conformal level must be in (0, 1), not {level}")
    s = np.sort(np.asarray([v for v in scores if v is not None and np.isfinite(v)], float))
    k = math.ceil((s.size + 1) * level)
    return float(s[k - 1]) if 1 <= k <= s.size else float("inf")


@dataclass(frozen=True)
class Fold:
    """One fold of :func:`leave_one_run_out`, a task of :func:`fold_scores`.

    Parameters
    ----------
    refit : WindowProblem
        The full fit's problem and settings, refitted without the left-out runs.
    ks : list of int
        Indices of the left-out runs in ``refit.ctxs``.
    p : ndarray, shape (n_params,)
        The full fit's optimum (the refit's start).
    nuisance : list or None
        Its per-track nuisances.
    tracks : list of Track
        The left-out runs, in the order of ``ks``.
    window_s : float
        The protocol window of the scores (s).
    start : str
        The start rule of the predictions.
    leadin_s : float or None
        The lead-in of the fitted start rule.
    n_draws : int
        Posterior draws for the index spreads.
    seed : int
        Seed of those draws.
    """

    refit: wf.WindowProblem
    ks: list
    p: object
    nuisance: list | None
    tracks: list
    window_s: float
    start: str
    leadin_s: float | None
    n_draws: int
    seed: int


def fold_scores(fold: Fold) -> dict:
    """One fold of :func:`leave_one_run_out` (a task): refit without the runs ``fold.ks``, predict them.

    Parameters
    ----------
    fold : Fold
        The fold (:func:`bayesid.estimation.windows.fit_model` and
        :func:`bayesid.estimation.laplace.fit_covariance` as the full fit).

    Returns
    -------
    dict
        JSON-able: ``runs``, ``windows`` [{``run``, ``max_position_m``, ``max_heading_deg``}]
        (windows shorter than :data:`MIN_WINDOW_FRACTION` of ``window_s`` left out), ``indices``
        [{``run``, ``index``, ``measured``, ``predicted``, ``sd``, ``abs_error``}] (scored once
        every fold is in: :meth:`Calibration.normalised_index_scores`), ``p`` (the fold's optimum).
    """
    rf = fold.refit
    keep = [i for i in range(len(rf.ctxs)) if i not in set(fold.ks)]
    nu = None if fold.nuisance is None else [fold.nuisance[i] for i in keep]
    f = wf.fit_model(dataclasses.replace(rf, ctxs=[rf.ctxs[i] for i in keep]), np.asarray(fold.p, float), nu)
    cov, _ = fit_covariance(f, [rf.ctxs[i] for i in keep], rf.prior, rf.data_scale)
    rng = np.random.default_rng(fold.seed)
    wins, idx = [], []
    for track in fold.tracks:
        pr = predict(rf.model, f.p, [track], fold.window_s, start=fold.start, leadin_s=fold.leadin_s)
        wins += [
            {"run": track.name, "max_position_m": w["max_position_m"], "max_heading_deg": w["max_heading_deg"]}
            for w in pr.windows
            if full_window(w, fold.window_s)
        ]
        tb = turning_band(
            FittedModel(rf.model, f.p, cov), track, fold.n_draws, rng, start=pr.start_rule, leadin_s=pr.leadin_s
        )
        for key in index_keys(tb["measured"]):
            # NaN (an index the run or the prediction does not reach) is stored as None: a journaled
            # result goes through JSON, where a NaN would come back as the string "nan"
            m, q, sd = (_number(d.get(key)) for d in (tb["measured"], tb["predicted"], tb["sd"]))
            idx.append(
                {
                    "run": track.name,
                    "index": key,
                    "measured": m,
                    "predicted": q,
                    "sd": sd,
                    "abs_error": abs(m - q) if m is not None and q is not None else None,
                }
            )
    return {"runs": [t.name for t in fold.tracks], "windows": wins, "indices": idx, "p": f.p.tolist()}


def leave_one_run_out(
    refit: wf.WindowProblem,
    fit,
    train,
    options: CalibrationOptions = CalibrationOptions(),
    *,
    start: str = "measured",
    leadin_s: float | None = None,
    runner: Runner = Runner(),
) -> Calibration:
    """Leave-one-run-out calibration of a fitted model (module docstring).

    Parameters
    ----------
    refit : WindowProblem
        The full fit's problem and settings, which every fold refits.
    fit : FitResult
        The full fit (``p``, ``nuisance``: the refits' start).
    train : list of Track
        Its training tracks (at least 3), in the order of ``refit.ctxs``.
    options : CalibrationOptions, default CalibrationOptions()
        The protocol window of the scores, the posterior draws and their seed, the most folds.
    start : str, default "measured"
        The (resolved) start rule of the predictions.
    leadin_s : float, optional
        Its lead-in.
    runner : Runner, default Runner()
        Runs the folds as tasks (:class:`bayesid.tasks.Runner`).

    Returns
    -------
    Calibration
        Every field set: ``folds`` (:func:`fold_scores` each, or ``{"runs", "error"}``),
        ``window_scores`` {``max_position_m``, ``max_heading_deg``: lists}, ``excitation``
        ({run: :func:`excitation`}), ``index_score`` (:data:`INDEX_SCORE`),
        ``structural_scale`` (``kappa``, :func:`structural_scale`), ``index_scores`` {key: list
        of normalised scores, :meth:`Calibration.normalised_index_scores`}.

    Raises
    ------
    ValueError
        With fewer than 3 training runs.
    """
    if len(train) < 3:
        raise ValueError(f"leave-one-run-out calibration needs at least 3 training runs, not {len(train)}")
    model = refit.model
    nuisance = None if fit.nuisance is None or not model.n_nuisance else [np.asarray(v).tolist() for v in fit.nuisance]
    G = min(len(train), int(options.max_folds))
    groups = [[i for i in range(len(train)) if i % G == g] for g in range(G)]
    tasks = [
        Task(
            f"fold_{g}_of_{G}",
            {"runs": [train[i].name for i in ks], "fold": g},
            (
                Fold(
                    refit=refit,
                    ks=ks,
                    p=fit.p,
                    nuisance=nuisance,
                    tracks=[train[i] for i in ks],
                    window_s=options.window_s,
                    start=start,
                    leadin_s=leadin_s,
                    n_draws=options.draws,
                    seed=options.seed + g,
                ),
            ),
        )
        for g, ks in enumerate(groups)
    ]
    outs = runner.run(fold_scores, tasks, label="calibration")
    folds = [
        {"runs": t.params["runs"], "error": str(o)} if isinstance(o, TaskError) else o for t, o in zip(tasks, outs)
    ]
    good = [f for f in folds if "error" not in f]
    wins = [w for f in good for w in f["windows"]]
    kappa, scores = _index_scores(folds)
    return Calibration(
        method="split conformal, leave one training run out (refit on the others)"
        + (f", runs grouped into {G} folds" if G < len(train) else ""),
        window_s=options.window_s,
        start_rule=start,
        n_runs=len(train),
        n_folds=G,
        n_draws=options.draws,
        folds=folds,
        window_scores={
            "max_position_m": [w["max_position_m"] for w in wins],
            "max_heading_deg": [w["max_heading_deg"] for w in wins if w["max_heading_deg"] is not None],
        },
        excitation={t.name: excitation(t, getattr(model.vehicle, "L", None)) for t in train},
        index_score=INDEX_SCORE,
        structural_scale=kappa,
        index_scores=scores,
        kinds={t.name: manoeuvre_kind(t) for t in train},
    )


def _number(v) -> float | None:
    """``v`` as a finite float, or None (missing, NaN, or a non-finite value stored as text)."""
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def _fold_rows(folds, kind: str, finite: tuple) -> list:
    """The rows ``kind`` (``"windows"`` or ``"indices"``) of the successful ``folds`` whose
    ``finite`` entries are all present and finite numbers (a model file written by a journaled
    fit may hold a non-finite value as the string ``"nan"``)."""
    return [
        r
        for f in folds or []
        if "error" not in f
        for r in f.get(kind, [])
        if all(_number(r.get(k)) is not None for k in finite)
    ]


def _index_rows(folds) -> list:
    """The scored index rows of ``folds`` (:meth:`Calibration.index_rows`)."""
    return _fold_rows(folds, "indices", ("measured", "predicted"))


def _index_scores(folds) -> tuple[dict, dict]:
    """Structural scales and normalised index scores of ``folds``
    (:meth:`Calibration.normalised_index_scores`)."""
    rows = _index_rows(folds)
    kappa = structural_scale(rows)
    out: dict = {}
    for r in rows:
        sc = _scale(r["predicted"], r.get("sd"), kappa.get(r["index"], kappa["all"]))
        if sc is not None:
            out.setdefault(r["index"], []).append(abs(r["measured"] - r["predicted"]) / sc)
    return kappa, {k: out[k] for k in sorted(out)}


def excitation(track, length_m: float | None = None) -> dict:
    """How hard a run drives the vessel.

    Parameters
    ----------
    track : Track
        The run.
    length_m : float, optional
        The vessel's length L, m, for the nondimensional yaw rate.

    Returns
    -------
    dict
        ``rudder_deg``, the 95th percentile of ``|delta_r|`` (deg); ``yaw_rate_deg_s``, that
        of ``|r|`` (deg/s; from the heading's time derivative when ``r`` is not logged); and,
        with ``length_m``, ``yaw_rate_prime``, that of the nondimensional yaw rate
        ``r' = |r| L / U`` (:func:`yaw_rate_prime`: L over the radius of the path, the measure of
        how tight a turn the hull forces describe, whatever the speed). None for a channel the
        track lacks.
    """
    out = {"rudder_deg": None, "yaw_rate_deg_s": None}
    if "delta_r" in track:
        d = np.abs(np.asarray(track["delta_r"], float))
        d = d[np.isfinite(d)]
        out["rudder_deg"] = float(np.degrees(np.percentile(d, 95))) if d.size else None
    if "r" in track:
        r = np.asarray(track["r"], float)
    elif "psi" in track and len(track.t) > 2:
        r = np.gradient(np.unwrap(np.asarray(track["psi"], float)), np.asarray(track.t, float))
    else:
        r = np.array([])
    r = np.abs(r[np.isfinite(r)])
    out["yaw_rate_deg_s"] = float(np.degrees(np.percentile(r, 95))) if r.size else None
    if length_m is not None:
        if all(c in track for c in ("x", "y", "psi")):
            rp = yaw_rate_prime(track.t, track["x"], track["y"], track["psi"], length_m)
            out["yaw_rate_prime"] = float(np.percentile(rp, 95)) if rp.size else None
        else:
            out["yaw_rate_prime"] = None
    return out


def yaw_rate_prime(t, x, y, psi, length_m: float, span_s: float = 5.0) -> np.ndarray:
    """The nondimensional yaw rate ``r' = |r| L / U`` along a track, from its positions and
    heading: ``L |psi(t + s/2) - psi(t - s/2)| / |p(t + s/2) - p(t - s/2)|`` over spans of
    ``span_s`` (the heading change per metre of path times L: ``L / R`` on a circle of radius R,
    without differentiating noisy positions twice). Spans shorter than 0.1 m of path are left
    out.

    Parameters
    ----------
    t, x, y, psi : ndarray, shape (n,)
        Times (s), north and east positions (m) and heading (rad).
    length_m : float
        The vessel's length, m.
    span_s : float, default 5.0
        The span of each difference, s (a 2 cm position noise moves ``r'`` of a 0.3 m/s turn by
        about 2 % over 5 s; the chord of a 16 m circle at 1.2 m/s is 0.6 % short of its arc).

    Returns
    -------
    ndarray, shape (m,)
        ``r'`` at the spans' middles (finite values only).
    """
    t, x, y = (np.asarray(a, float) for a in (t, x, y))
    h = np.unwrap(np.asarray(psi, float))
    ok = np.isfinite(t) & np.isfinite(x) & np.isfinite(y) & np.isfinite(h)
    t, x, y, h = t[ok], x[ok], y[ok], h[ok]
    if t.size < 3:
        return np.array([])
    lo = np.searchsorted(t, t - 0.5 * span_s)
    hi = np.minimum(np.searchsorted(t, t + 0.5 * span_s, side="right") - 1, t.size - 1)
    keep = (hi > lo) & (t - t[lo] >= 0.4 * span_s) & (t[hi] - t >= 0.4 * span_s)
    lo, hi = lo[keep], hi[keep]
    chord = np.hypot(x[hi] - x[lo], y[hi] - y[lo])
    turn = np.abs(h[hi] - h[lo])
    good = chord > 0.1
    return length_m * turn[good] / chord[good]


#: The measures of :func:`excitation`: (key, label, unit).
EXCITATION_MEASURES = (
    ("rudder_deg", "rudder", "deg"),
    ("yaw_rate_deg_s", "yaw rate", "deg/s"),
    ("yaw_rate_prime", "nondimensional yaw rate r' = r L / U", ""),
)


def structural_scale(rows) -> dict:
    """``kappa`` per index: the median relative error ``|measured - predicted| / |predicted|`` of
    the scored rows (:meth:`Calibration.index_rows`) of that index, the model's typical structural
    error as a fraction of it; ``"all"``: the median over every row, used for an index with fewer
    than :data:`MIN_ROWS_PER_KAPPA` rows (0.0 without rows: the scores are then the parameter
    spread alone). Per index, because a model's relative errors differ by kind: on synthetic turns
    and zigzags 4 % for tactical diameters, 10-30 % for overshoots; one pooled kappa makes the 90 %
    bands of the tactical diameters hold every time and those of the overshoots too seldom.

    Parameters
    ----------
    rows : iterable of dict
        Scored rows (:meth:`Calibration.index_rows`).

    Returns
    -------
    dict
        ``{index or "all": kappa}``.
    """
    rel: dict = {}
    for r in rows:
        if r["predicted"] != 0:
            rel.setdefault(r["index"], []).append(abs(r["measured"] - r["predicted"]) / abs(r["predicted"]))
    every = [v for x in rel.values() for v in x]
    out = {"all": float(np.median(every)) if every else 0.0}
    out.update({k: float(np.median(v)) for k, v in rel.items() if len(v) >= MIN_ROWS_PER_KAPPA})
    return out


def _scale(predicted, sd, kappa) -> float | None:
    """``sqrt(sd^2 + (kappa * predicted)^2)`` (``sd`` None or non-finite counts as 0); None when
    it is not positive and finite."""
    sd, predicted = _number(sd), _number(predicted)
    s = sd if sd is not None and sd > 0 else 0.0
    v = math.hypot(s, kappa * abs(predicted)) if predicted is not None else float("nan")
    return v if np.isfinite(v) and v > 0 else None


def coverage_table(hits: dict, rows=None) -> dict:
    """Coverage of claims per level.

    Parameters
    ----------
    hits : dict
        ``{level: [bool, ...]}``, whether each claim held.
    rows : list of dict, optional
        The claims (each with ``band`` {level: {"q"}}).

    Returns
    -------
    dict
        ``{str(level): {"n", "inside", "coverage"}}``; with ``rows`` also ``unbounded``: how
        many of them had no finite band at that level (too few calibration scores), which hold
        trivially.
    """
    out = {
        str(a): {"n": len(v), "inside": int(sum(v)), "coverage": float(np.mean(v)) if v else None}
        for a, v in hits.items()
    }
    if rows is not None:
        for a, c in out.items():
            c["unbounded"] = sum(not np.isfinite(r["band"][a]["q"]) for r in rows)
    return out


def _parameter_rows(indices: dict, levels) -> tuple[dict, list]:
    """The start of :meth:`Calibration.bands` and :func:`uncalibrated_bands`: ``calibrated``
    (False), ``levels`` and ``parameter_only`` of the output, and one row per measured index."""
    out = {"calibrated": False, "levels": list(levels)}
    par_hits = []
    rows_i = []
    for name, tb in indices.items():
        for key in index_keys(tb["measured"]):
            m, q, sd = tb["measured"].get(key), tb["predicted"].get(key), (tb.get("sd") or {}).get(key)
            if m is None or not np.isfinite(m):
                continue
            pb = (tb.get("band_5_95") or {}).get(key)
            row = {
                "track": name,
                "index": key,
                "measured": m,
                "predicted": q,
                "sd": sd,
                "parameter_band_5_95": pb,
                "parameter_inside": bool(pb[0] <= m <= pb[1]) if pb else None,
                "band": {},
                "inside": {},
            }
            if pb:
                par_hits.append(row["parameter_inside"])
            rows_i.append(row)
    out["parameter_only"] = {
        "nominal": 0.9,
        "n": len(par_hits),
        "inside": int(sum(par_hits)),
        "coverage": float(np.mean(par_hits)) if par_hits else None,
    }
    return out, rows_i


def uncalibrated_bands(indices: dict, levels=LEVELS) -> dict:
    """What :meth:`Calibration.bands` gives for a model without a calibration: the posterior
    draws' own index bands only.

    Parameters
    ----------
    indices : dict
        ``{track: turning_band result}`` (:func:`bayesid.estimation.prediction.turning_band`:
        ``measured``, ``predicted``, ``sd``, ``band_5_95``).
    levels : sequence of float, default LEVELS
        Nominal levels the bands would have.

    Returns
    -------
    dict
        ``calibrated`` (False), ``levels``, ``parameter_only`` (as :meth:`Calibration.bands`),
        ``reason``, ``indices`` (the measured indices, without bands) and ``windows`` (empty).
    """
    out, rows_i = _parameter_rows(indices, levels)
    out.update(
        reason="the model has no calibration (bayesid fit on 3 or more runs computes one)",
        indices=rows_i,
        windows=[],
    )
    return out


@dataclass(frozen=True)
class Calibration:
    """A fitted model's leave-one-run-out calibration (:func:`leave_one_run_out`), the section
    ``calibration`` of ``model.json``, and the predictive bands it gives.

    Every field is as the model file stores it (:meth:`to_dict`); a field a file written by an
    older version lacks is None (and left out of :meth:`to_dict`). The bands are recomputed from
    the folds' rows, so a file written with an older score gets the current one. A calibration is
    not modified once made (its scores are computed once, on first use).

    Parameters
    ----------
    method : str, optional
        The method, in words.
    window_s : float, optional
        The protocol window of the window scores (s).
    start_rule : str, optional
        The start rule of the left-out predictions.
    n_runs : int, optional
        Training runs.
    n_folds : int, optional
        Folds (refits).
    n_draws : int, optional
        Posterior draws of each fold for the index spreads.
    folds : list of dict, optional
        :func:`fold_scores` of each fold, or ``{"runs", "error"}`` for a fold that failed.
    window_scores : dict, optional
        ``{max_position_m, max_heading_deg: list of float}``: the left-out windows' maxima.
    excitation : dict, optional
        ``{run: excitation}`` (:func:`excitation`) of the training runs.
    index_score : str, optional
        The index nonconformity score in words (:data:`INDEX_SCORE`).
    structural_scale : dict, optional
        ``{index or "all": kappa}`` at the time of writing (:func:`structural_scale`).
    index_scores : dict, optional
        ``{index: normalised scores}`` at the time of writing.
    kinds : dict, optional
        ``{run: manoeuvre kind}`` of the training runs
        (:func:`~bayesid.estimation.indices.manoeuvre_kind`, read from the rudder).
    """

    method: str | None = None
    window_s: float | None = None
    start_rule: str | None = None
    n_runs: int | None = None
    n_folds: int | None = None
    n_draws: int | None = None
    folds: list | None = None
    window_scores: dict | None = None
    excitation: dict | None = None
    index_score: str | None = None
    structural_scale: dict | None = None
    index_scores: dict | None = None
    kinds: dict | None = None

    @classmethod
    def from_dict(cls, d: dict) -> Calibration:
        """The calibration a model file stores.

        Parameters
        ----------
        d : dict
            ``model.json``'s ``calibration`` (:meth:`to_dict`, or a file written by an older
            version, which lacks some keys). Keys that are not fields are ignored.

        Returns
        -------
        Calibration
            With None for the fields ``d`` lacks.
        """
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})

    def to_dict(self) -> dict:
        """The JSON object of the calibration (``model.json``'s ``calibration``).

        Returns
        -------
        dict
            The fields in their order, those that are None left out.
        """
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if getattr(self, f.name) is not None}

    def extrapolation_folds(self) -> list:
        """The folds whose left-out runs include a manoeuvre kind none of the fold's training runs
        has: their scores measure the error of predicting a new kind of manoeuvre, wider than a
        prediction within the training kinds (with one run of each kind, every fold is one).

        Returns
        -------
        list of dict
            ``[{"runs", "kinds"}]``: the fold's left-out runs and the kinds the others lack; empty
            without ``kinds`` (a file written by an older version) or folds.
        """
        if not self.kinds or not self.folds:
            return []
        out = []
        for f in self.folds:
            left = [r for r in f["runs"] if r in self.kinds]
            others = {k for r, k in self.kinds.items() if r not in f["runs"]}
            new = sorted({self.kinds[r] for r in left} - others)
            if new:
                out.append({"runs": list(f["runs"]), "kinds": new})
        return out

    def fold_optima(self) -> list:
        """The optima of the refits (their ``p``).

        Returns
        -------
        list of list of float
            ``p`` of each successful fold, in fold order.
        """
        return [f["p"] for f in self.folds or [] if "p" in f]

    def window_rows(self) -> list:
        """Every window the calibration scored.

        Returns
        -------
        list of dict
            ``{run, max_position_m, max_heading_deg}`` of its successful folds (heading None
            where the run has no heading).
        """
        return _fold_rows(self.folds, "windows", ("max_position_m",))

    @functools.cached_property
    def _joint_window_scores(self) -> tuple[dict, list]:
        rows = self.window_rows()
        pos = np.array([w["max_position_m"] for w in rows], float)
        hd = np.array([w["max_heading_deg"] for w in rows if w.get("max_heading_deg") is not None], float)
        sp = float(np.median(pos)) if pos.size and np.median(pos) > 0 else 1.0
        sh = (float(np.median(hd)) if np.median(hd) > 0 else 1.0) if hd.size else None
        joint = [
            max(
                w["max_position_m"] / sp,
                w["max_heading_deg"] / sh if sh and w.get("max_heading_deg") is not None else 0.0,
            )
            for w in rows
        ]
        return {"max_position_m": sp, "max_heading_deg": sh}, joint

    def joint_window_scores(self) -> tuple[dict, list]:
        """Scales and joint scores of the calibration's windows.

        A window's claim is joint: the track within ``r`` *and* the heading within ``h``.
        Marginal quantiles of the two errors would hold jointly less often than either (at 50 %,
        6 of 26 claims on the Esso validation split). So each error is divided by its median over
        the calibration windows and the score is the larger of the two ratios (the max-normalised
        score of multi-output conformal prediction); a band at level ``a`` is
        ``r = q_a * scale_position``, ``h = q_a * scale_heading``, which holds jointly at ``a``.

        Returns
        -------
        scales : dict
            ``{max_position_m, max_heading_deg: scale}``: the medians (1.0 where a median is not
            positive, None for the heading when no window has one).
        joint : list of float
            The joint score of each window.
        """
        return self._joint_window_scores

    def window_band(self, level: float) -> dict:
        """The joint window band at a level (:meth:`joint_window_scores`).

        Parameters
        ----------
        level : float
            Nominal coverage in (0, 1).

        Returns
        -------
        dict
            ``max_position_m`` (m), ``max_heading_deg`` (deg; None without headings), ``q`` (the
            conformal factor), ``n_scores``; inf radii with too few windows for the level.
        """
        scales, joint = self._joint_window_scores
        q = conformal_quantile(joint, level)
        sh = scales["max_heading_deg"]
        return {
            "max_position_m": q * scales["max_position_m"],
            "max_heading_deg": q * sh if sh is not None else None,
            "q": q,
            "n_scores": len(joint),
        }

    def index_rows(self) -> list:
        """Every index the calibration scored.

        Returns
        -------
        list of dict
            The rows ``{run, index, measured, predicted, sd}`` of its successful folds
            (:func:`fold_scores`), with finite measured and predicted values.
        """
        return _index_rows(self.folds)

    @functools.cached_property
    def _normalised_index_scores(self) -> tuple[dict, dict]:
        return _index_scores(self.folds)

    def normalised_index_scores(self) -> tuple[dict, dict]:
        """Structural scales and normalised index scores, recomputed from the folds' rows (module
        docstring, step 3), so a model file written with an older score gets the current one.
        Rows whose scale is zero (no spread and a zero prediction) are left out.

        Returns
        -------
        kappa : dict
            ``{index or "all": relative scale}`` (:func:`structural_scale`).
        scores : dict
            ``{index: normalised scores}``, indices sorted.
        """
        return self._normalised_index_scores

    def index_band(self, key: str, predicted: float, sd: float | None, level: float) -> dict:
        """Band ``predicted +- q * sqrt(sd^2 + (kappa * predicted)^2)`` of one index at ``level``.

        Parameters
        ----------
        key : str
            The index (``tactical_diameter_m``, ...).
        predicted : float
            The model's value of the index.
        sd : float or None
            The posterior draws' spread of it (None: 0).
        level : float
            Nominal coverage in (0, 1).

        Returns
        -------
        dict
            ``lo``, ``hi`` (None when the prediction is not finite), ``q`` (the conformal
            factor), ``scale`` (the square root above), ``kappa`` (the index's own, or the median
            over every index when it had fewer than :data:`MIN_ROWS_PER_KAPPA` rows),
            ``n_scores`` and ``pooled`` (True when the key had fewer than
            :data:`MIN_SCORES_PER_KEY` scores and the pooled scores of every index were used).
        """
        kappas, by_key = self._normalised_index_scores
        kappa = kappas.get(key, kappas["all"])
        own = by_key.get(key, [])
        pooled = len(own) < MIN_SCORES_PER_KEY
        pool = [s for v in by_key.values() for s in v] if pooled else own
        q = conformal_quantile(pool, level)
        sc = _scale(predicted, sd, kappa)
        ok = sc is not None
        half = q * sc if ok else float("nan")
        return {
            "lo": predicted - half if ok else None,
            "hi": predicted + half if ok else None,
            "q": q,
            "scale": sc,
            "kappa": kappa,
            "n_scores": len(pool),
            "pooled": pooled,
        }

    def excitation_range(self) -> dict:
        """Range of the calibration runs' :func:`excitation`.

        Returns
        -------
        dict
            ``{measure: (smallest, largest)}`` for each measure some run has; empty for a
            calibration written before it recorded excitation.
        """
        out = {}
        for key, _, _ in EXCITATION_MEASURES:
            vals = [v[key] for v in (self.excitation or {}).values() if v.get(key) is not None]
            if vals:
                out[key] = (min(vals), max(vals))
        return out

    def outside_excitation(self, exc: dict) -> list:
        """Reasons a run's :func:`excitation` lies outside the calibration runs' range (below 0.8
        x their smallest or above 1.25 x their largest value of a measure), e.g. ``"rudder 5 deg
        below the training runs' 10-35 deg"``; empty when inside or when the calibration did not
        record its runs' excitation (written before it did). A calibrated band assumes a new run
        exchangeable with the calibration runs; a run driven outside their range is not (on the
        HSVA zigzags, a model trained on the six ``Z_xx_05`` runs, 10-35 deg rudder and yaw rates
        of 2.3-3.7 deg/s, misses the 90 % window band on ``Z_05_01``, 5 deg rudder, and
        ``Z_10_01``, 1.3 deg/s). Reported beside the bands, not removed from their coverage.

        Parameters
        ----------
        exc : dict
            The run's :func:`excitation`.

        Returns
        -------
        list of str
            The reasons, one per measure outside the range.
        """
        rng = self.excitation_range()
        out = []
        for key, label, unit in EXCITATION_MEASURES:
            x = exc.get(key)
            if key not in rng or x is None:
                continue
            lo, hi = rng[key]
            if x < 0.8 * lo or x > 1.25 * hi:
                out.append(
                    f"{label} {x:.3g}{' ' + unit if unit else ''} {'below' if x < lo else 'above'} the training "
                    f"runs' {lo:.3g}-{hi:.3g}{' ' + unit if unit else ''}"
                )
        return out

    def bands(
        self, window_s: float | None, windows: list, indices: dict, levels=LEVELS, excitations: dict | None = None
    ) -> dict:
        """Bands of a prediction at each level, with the measured value and whether it is inside
        (:func:`uncalibrated_bands` for a model without a calibration).

        Parameters
        ----------
        window_s : float or None
            The prediction's protocol window (s); window bands need the calibration's.
        windows : list of dict
            ``windows`` of a :class:`~bayesid.estimation.prediction.Prediction` (with ``max_position_m``,
            ``max_heading_deg``).
        indices : dict
            ``{track: turning_band result}`` (:func:`bayesid.estimation.prediction.turning_band`:
            ``measured``, ``predicted``, ``sd``, ``band_5_95``).
        levels : sequence of float, default LEVELS
            Nominal levels of the bands.
        excitations : dict, optional
            ``{track: excitation}`` (:func:`excitation`) of the predicted runs: runs driven
            outside the calibration runs' range are listed (``outside_range`` {track: reasons})
            and the coverage of the other runs' claims is given apart (``coverage_in_range``).

        Returns
        -------
        dict
            ``calibrated`` (True), ``levels``; ``windows`` (the full ones, :func:`full_window`)
            and ``indices`` (each row with ``band``, ``inside`` per level and ``extrapolated``);
            ``window_reason`` when the windows differ from the calibration's; ``coverage``
            {``windows``, ``indices``, ``all``: :func:`coverage_table`} of the calibrated claims;
            ``extrapolated`` {``runs``, ``kinds``, ``index_kinds``, ``note``, ``coverage``}: the
            index kinds the calibration never scored (an index row of such a kind, and every
            window of a run all of whose indices are such) have bands from the pooled scores but
            are not calibrated claims, and their coverage is kept apart; ``parameter_only`` (the
            posterior draws' own 5-95 % index bands: inside or not, and their coverage, the
            comparison the calibration is for).
        """
        out, rows_i = _parameter_rows(indices, levels)
        out["calibrated"] = True
        own = {k for k, v in self._normalised_index_scores[1].items() if v}
        for row in rows_i:
            row["extrapolated"] = row["index"] not in own
        # a run whose every measured index is of a kind the calibration never scored is a manoeuvre
        # the training runs did not contain (a turning circle from zigzags): its windows too
        ext_runs = sorted(
            {r["track"] for r in rows_i} - {r["track"] for r in rows_i if not r["extrapolated"]},
        )
        hits = {g: {a: [] for a in levels} for g in ("windows", "indices", "x_windows", "x_indices")}
        rows_w = []
        same_window = (
            window_s is not None and self.window_s is not None and abs(float(window_s) - float(self.window_s)) < 1e-9
        )
        if same_window:
            wb = {a: self.window_band(a) for a in levels}
            for w in windows:
                if not full_window(w, float(window_s)):
                    continue  # a run's cut-off last window: no claim
                row = dict(w, band={}, inside={}, extrapolated=w.get("track") in ext_runs)
                for a in levels:
                    b = wb[a]
                    ok = w["max_position_m"] <= b["max_position_m"] and (
                        w.get("max_heading_deg") is None
                        or b["max_heading_deg"] is None
                        or w["max_heading_deg"] <= b["max_heading_deg"]
                    )
                    row["band"][str(a)], row["inside"][str(a)] = b, bool(ok)
                    hits["x_windows" if row["extrapolated"] else "windows"][a].append(bool(ok))
                rows_w.append(row)
        else:
            out["window_reason"] = (
                f"windows of {window_s} s: the calibration is for {self.window_s} s "
                "windows; predict with that --score-window for calibrated window bands"
            )
        for row in rows_i:
            for a in levels:
                b = self.index_band(row["index"], row["predicted"], row["sd"], a)
                ok = b["lo"] is not None and b["lo"] <= row["measured"] <= b["hi"]
                row["band"][str(a)], row["inside"][str(a)] = b, bool(ok)
                hits["x_indices" if row["extrapolated"] else "indices"][a].append(bool(ok))
        outside = {k: v for k, v in ((t, self.outside_excitation(e)) for t, e in (excitations or {}).items()) if v}
        inr = {
            g: coverage_table(
                {
                    a: [r["inside"][str(a)] for r in rows if not r["extrapolated"] and r["track"] not in outside]
                    for a in levels
                }
            )
            for g, rows in (("windows", rows_w), ("indices", rows_i))
        }
        out.update(
            outside_range=outside,
            coverage_in_range=inr,
            windows=rows_w,
            indices=rows_i,
            window_s=self.window_s,
            coverage={
                "windows": coverage_table(hits["windows"], [r for r in rows_w if not r["extrapolated"]]),
                "indices": coverage_table(hits["indices"], [r for r in rows_i if not r["extrapolated"]]),
                "all": coverage_table(
                    {a: hits["windows"][a] + hits["indices"][a] for a in levels},
                    [r for r in rows_w + rows_i if not r["extrapolated"]],
                ),
            },
            extrapolated={
                "runs": ext_runs,
                "kinds": sorted({str(indices[r]["measured"].get("kind")) for r in ext_runs}),
                "index_kinds": sorted({r["index"] for r in rows_i if r["extrapolated"]}),
                "note": EXTRAPOLATION_NOTE,
                "coverage": {
                    "windows": coverage_table(hits["x_windows"]),
                    "indices": coverage_table(hits["x_indices"]),
                },
            },
        )
        return out
