"""Prediction of tracks by a fitted model under the fixed window protocol, posterior draws of it,
and whole-run predictions reduced to manoeuvre indices with their posterior bands.

:func:`predict` restarts the model at every protocol window (:mod:`bayesid.protocol`) and scores
position and heading errors; :func:`turning_band` predicts a run open loop from its first sample
and reduces the model's and each posterior draw's prediction to the run's manoeuvre indices
(:mod:`bayesid.estimation.indices`); :func:`turning_circles` predicts standard turning circles from
an approach condition.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..data.track import Track
from ..models.context import errors
from ..models.runs import T_EXECUTE, Approach, ManoeuvreRun, free_run_states
from ..protocol import pooled_scores, start_settings
from . import shooting
from .indices import index_keys, manoeuvre_indices

#: The size a batch of whole-run predictions of posterior draws stays near (bytes).
BATCH_BYTES = 2e8

__all__ = [
    "BATCH_BYTES",
    "FittedModel",
    "Prediction",
    "predict",
    "predictive_band",
    "predictive_sd",
    "standard_run",
    "TURNING_INDICES",
    "training_turns",
    "turning_band",
    "turning_circles",
    "windowed_xy",
]


@dataclass(frozen=True)
class Prediction:
    """The window protocol's scores of a model on tracks (:func:`predict`).

    Parameters
    ----------
    pooled : dict
        The pooled RMS position / heading errors over every track
        (:func:`~bayesid.protocol.pooled_scores`).
    per_track : dict
        ``{track name: pooled scores}``.
    windows : list of dict
        One per scored window: ``track``, ``t_start``, ``duration_s`` (of its scored samples),
        ``rms_position_m``, ``max_position_m``, ``rms_heading_deg``, ``max_heading_deg``.
    simulated : dict
        ``{track name: (ctx, S)}``: the prepared track (:class:`~bayesid.models.context.TrackContext`)
        and the predicted states at its scored samples, ndarray (n, 12), for plots (not
        serialised; a caller may drop a track's entry once drawn).
    start_rule : str
        The window start rule used (resolved).
    leadin_s : float or None
        The lead-in used (s).
    """

    pooled: dict
    per_track: dict
    windows: list
    simulated: dict
    start_rule: str
    leadin_s: float | None

    def to_dict(self) -> dict:
        """The JSON-able scores (the simulations left out).

        Returns
        -------
        dict
            ``pooled``, ``per_track``, ``windows``, ``start_rule``, ``leadin_s``.
        """
        return {
            "pooled": self.pooled,
            "per_track": self.per_track,
            "windows": self.windows,
            "start_rule": self.start_rule,
            "leadin_s": self.leadin_s,
        }


def predict(model, p, tracks, window_s: float | None, start: str = "auto", leadin_s: float | None = None) -> Prediction:
    """The protocol on tracks: per window and pooled RMS position / heading errors.

    Parameters
    ----------
    model : SimulationModel
        The model.
    p : array_like, shape (n_params,)
        Its parameter vector.
    tracks : sequence of Track
        The tracks predicted.
    window_s : float or None
        Protocol window, s (None: one window per run).
    start : str, default "auto"
        Window start-state rule (:data:`bayesid.protocol.START_RULES`; ``"auto"`` decides on
        these tracks).
    leadin_s : float, optional
        Lead-in of the fitted rule, s (default :func:`bayesid.protocol.start_settings`).

    Returns
    -------
    Prediction
        The pooled, per-track and per-window scores, the simulations, and the start rule and
        lead-in used.

    Examples
    --------
    The model fitted on two zigzags (:func:`bayesid.estimation.identification.identify`) scored
    on a held-out turning circle over 30 s windows, as ``bayesid predict`` does:

    >>> import bayesid
    >>> vehicle = bayesid.load_any_vehicle("nps_auv2")
    >>> train = [bayesid.read_csv(f) for f in ("z10.csv", "z20.csv")]
    >>> res = bayesid.identify(vehicle, train, bayesid.FitOptions(free=("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"), dt=0.1))
    >>> pred = bayesid.predict(res.model, res.fit.p, [bayesid.read_csv("t15.csv")], window_s=30.0)
    >>> sorted(pred.pooled)
    ['max_position_m', 'n_samples', 'rms', 'rms_heading_deg', 'rms_position_m']
    >>> print(f"RMS position {pred.pooled['rms_position_m']:.3f} m over {len(pred.windows)} windows")  # doctest: +SKIP
    """
    errs, per_track, windows, sims = [], {}, [], {}
    rule, lead = start_settings(start, tracks, window_s, model.dt, leadin_s)
    for tr in tracks:
        ctx = model.context(tr, window_s, start=rule, leadin_s=lead)
        S = shooting.simulate(model, ctx, np.asarray(p)[None])
        e = {k: v[0] for k, v in errors(ctx, S).items()}
        errs.append(e)
        per_track[tr.name] = pooled_scores([e])
        pos = np.hypot(e["x"], e["y"])
        bounds = np.searchsorted(ctx.win, np.arange(ctx.W + 1))  # samples are in window order
        for w in range(ctx.W):
            sel = slice(bounds[w], bounds[w + 1])
            if bounds[w + 1] > bounds[w]:
                windows.append(
                    {
                        "track": tr.name,
                        "t_start": float(ctx.t_start[w]),
                        "duration_s": float(ctx.ts[bounds[w + 1] - 1] - ctx.t_start[w]),
                        "rms_position_m": float(np.sqrt(np.nanmean(pos[sel] ** 2))),
                        "max_position_m": float(np.nanmax(pos[sel])),
                        "rms_heading_deg": float(np.degrees(np.sqrt(np.nanmean(e["psi"][sel] ** 2))))
                        if "psi" in e
                        else None,
                        "max_heading_deg": float(np.degrees(np.nanmax(np.abs(e["psi"][sel])))) if "psi" in e else None,
                    }
                )
        sims[tr.name] = (ctx, S[0])
    return Prediction(
        pooled=pooled_scores(errs),
        per_track=per_track,
        windows=windows,
        simulated=sims,
        start_rule=rule,
        leadin_s=lead,
    )


@dataclass(frozen=True)
class FittedModel:
    """A fitted model at its estimate, with the Gaussian (Laplace or sampled) covariance of it.

    Parameters
    ----------
    model : SimulationModel
        The model (free coefficients, effects, step).
    p : array_like, shape (n_params,)
        The estimate (stored as a float array).
    cov : ndarray, shape (n_params, n_params), optional
        Its covariance (None: no posterior draws can be made).
    """

    model: object
    p: np.ndarray
    cov: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "p", np.asarray(self.p, float))

    def draws(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Draws from the Gaussian posterior, kept inside the parameter bounds.

        Parameters
        ----------
        n : int
            Number of draws.
        rng : numpy.random.Generator
            The random generator.

        Returns
        -------
        ndarray, shape (n, n_params)
            The draws.
        """
        lo, hi = self.model.bounds()
        cov = np.asarray(self.cov, float)
        L = np.linalg.cholesky(cov + 1e-15 * np.eye(cov.shape[0]) * max(np.trace(cov), 1e-30))
        X = self.p[None] + rng.standard_normal((n, self.p.size)) @ L.T
        return np.clip(X, lo, hi)

    def rows(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """The estimate, then posterior draws.

        Parameters
        ----------
        n : int
            Number of draws (none drawn when 0).
        rng : numpy.random.Generator
            The random generator.

        Returns
        -------
        ndarray, shape (1 + n, n_params)
            The rows.
        """
        return np.vstack([self.p[None], self.draws(n, rng)]) if n else self.p[None]


def windowed_xy(ctx, S):
    """Measured and predicted x, y of a protocol prediction, with NaN between windows (for plots).

    Parameters
    ----------
    ctx : TrackContext
        The prepared track.
    S : ndarray, shape (n, 12)
        The predicted states at its scored samples.

    Returns
    -------
    measured : ndarray, shape (n, 2)
        The measured x, y.
    predicted : ndarray, shape (n + cuts, 2)
        The predicted x, y, a NaN row at each window boundary.
    """
    xy = S[:, :2].copy()
    cut = np.flatnonzero(np.diff(ctx.win) != 0) + 1
    xy = np.insert(xy, cut, np.nan, axis=0)
    return np.column_stack([ctx.meas["x"], ctx.meas["y"]]), xy


def turning_band(
    fitted: FittedModel,
    track,
    n_draws: int,
    rng,
    *,
    start: str = "measured",
    leadin_s: float = 0.0,
    keep_draws: bool = False,
) -> dict:
    """Whole-run open-loop prediction of a track from its first sample, with the manoeuvre
    indices of the measured run, of the identified model and a posterior predictive band.

    The draws are simulated a few at a time (each batch of predictions near
    :data:`BATCH_BYTES`) and reduced to their indices, so memory does not grow with ``n_draws``
    x the track length.

    Parameters
    ----------
    fitted : FittedModel
        The model, its estimate and covariance.
    track : Track
        The run (``t, x, y, psi, delta_r`` and the model's inputs).
    n_draws : int
        Posterior draws of the band (0: none).
    rng : numpy.random.Generator
        Draws them.
    start : str, default "measured"
        The resolved start rule: ``"measured"`` (the measured first state) or ``"fitted"`` (the
        state fitted to the first ``leadin_s`` seconds, at least 2 s).
    leadin_s : float, default 0.0
        The lead-in of the fitted rule (s).
    keep_draws : bool, default False
        Keep every draw's prediction in ``_S`` (else the identified model's only).

    Returns
    -------
    dict
        ``measured`` and ``predicted`` indices (:func:`manoeuvre_indices`), ``band_5_95`` (5-95 %
        of the draws' values), ``sd`` ({index: sd of the draws' values}, None with fewer than 3
        finite draws), ``n_draws``, ``_S`` ((1, n, 12) or (1 + n_draws, n, 12) predictions) and
        ``_ctx``.
    """
    model = fitted.model
    P = fitted.rows(n_draws, rng)
    if start == "fitted":
        # the whole run from its first sample: the start state fitted to the first lead-in
        # seconds only (indices need the execute, which a lead-in before the window would cut)
        sel = track.t <= track.t[0] + max(leadin_s, 2.0) + 1e-9
        head = Track(track.t[sel], {k: np.asarray(v)[sel] for k, v in track.data.items()}, name=track.name)
        ctx = model.context(track, None, start="fitted", leadin_s=0.0)
        ctx_head = model.context(head, None, start="fitted", leadin_s=0.0)
    else:
        ctx = model.context(track, None)
    dr = np.asarray(track["delta_r"], float)[ctx.idx]
    meas = manoeuvre_indices(ctx.ts, ctx.meas["x"], ctx.meas["y"], ctx.meas["psi"], dr)
    pred, kept = [], []
    chunk = int(max(1, min(8, BATCH_BYTES // (8 * 12 * 3 * max(ctx.ts.size, 1)))))
    for i in range(0, P.shape[0], chunk):
        Pc = P[i : i + chunk]
        S = (
            model.simulate(ctx, Pc, starts=shooting.fit_starts(model, ctx_head, Pc))
            if start == "fitted"
            else model.simulate(ctx, Pc)
        )
        pred += [manoeuvre_indices(ctx.ts, s[:, 0], s[:, 1], s[:, 5], dr) for s in S]
        if keep_draws or i == 0:  # a copy: a view (even S[:0]) would keep the whole chunk alive
            kept.append(S if keep_draws else S[:1].copy())
        del S
    S = np.concatenate(kept, axis=0)
    # the indices of what the measured run is (none, with the reason, for anything else)
    keys = index_keys(meas)
    band, _ = predictive_band(pred[1:], keys)
    sd = predictive_sd(pred[1:], keys)  # the draws' spread: the scale of a calibrated band
    return {
        "measured": meas,
        "predicted": pred[0],
        "band_5_95": band,
        "sd": sd,
        "n_draws": int(n_draws),
        "_S": S,
        "_ctx": ctx,
    }


def predictive_band(draws: list, keys) -> tuple[dict, dict]:
    """Posterior predictive band of manoeuvre indices.

    Parameters
    ----------
    draws : list of dict
        Index dicts, one per posterior draw.
    keys : iterable of str
        The indices.

    Returns
    -------
    band : dict
        ``{key: [5 %, 95 %]}`` percentiles over the draws' finite values, or None with fewer
        than 3.
    n : dict
        ``{key: number of finite draws}``.
    """
    band, n = {}, {}
    for k in keys:
        vals = np.array([d.get(k, np.nan) for d in draws], float)
        vals = vals[np.isfinite(vals)]
        band[k] = [float(np.percentile(vals, 5)), float(np.percentile(vals, 95))] if vals.size >= 3 else None
        n[k] = int(vals.size)
    return band, n


def predictive_sd(draws: list, keys) -> dict:
    """Posterior spread of manoeuvre indices.

    Parameters
    ----------
    draws : list of dict
        Index dicts, one per posterior draw.
    keys : iterable of str
        The indices.

    Returns
    -------
    dict
        ``{key: standard deviation of the draws' finite values}``, or None with fewer than 3.
    """
    out = {}
    for k in keys:
        v = np.array([d.get(k, np.nan) for d in draws], float)
        v = v[np.isfinite(v)]
        out[k] = float(np.std(v, ddof=1)) if v.size >= 3 else None
    return out


def standard_run(model, P, run: ManoeuvreRun, approach: Approach) -> tuple:
    """The free run of a standard manoeuvre by each parameter vector and its ITTC indices: the one
    predictor of a turning circle or zigzag, read by :func:`turning_circles` (``bayesid fit --starts``, the studies)
    and by a diagnosis's standard predictions
    (:func:`bayesid.analysis.gap.design.standard_predictions`).

    The run starts straight ahead at the approach speed; the rudder is ordered at
    ``run.execute_s`` and moves at ``approach.rudder_rate``, the rate the logged runs' rudder moves
    at (:func:`bayesid.models.runs.approach_condition`; a rudder that steps turns the vessel
    sooner than its gear can: at KVLCC2's 15.8 deg/s a 35 deg order takes 2.2 s), a zigzag
    reversed on each row's own heading (:func:`bayesid.models.runs.free_run_states`). The samples
    are ``min(0.1 s, model.dt)`` apart over ``run.duration_s``, and the indices are read from the
    simulated track as from a measured one (:func:`~bayesid.estimation.indices.manoeuvre_indices`;
    ITTC Recommended Procedure 7.5-04-02-01 (2017), Sec. 2.2.1, 2.2.2).

    Parameters
    ----------
    model : SimulationModel
        The model.
    P : array_like, shape (B, n_params)
        Parameter vectors (e.g. an estimate and draws about it).
    run : ManoeuvreRun
        The manoeuvre (its length ``duration_s`` counted from the start of the approach).
    approach : Approach
        The approach condition (``u`` m/s, ``rpm``, ``rudder_rate`` rad/s).

    Returns
    -------
    ts : ndarray, shape (n_steps,)
        The model's step times, s.
    S : ndarray, shape (B, n_steps, 12)
        Each row's states (non-finite where its run diverged).
    indices : list of dict
        Each row's :func:`~bayesid.estimation.indices.manoeuvre_indices` (m, deg), read whether
        or not the row diverged: a caller decides what a diverged row's indices mean.
    """
    t = np.arange(0.0, run.duration_s, min(0.1, model.dt))
    ts, S, delta = free_run_states(model, P, run, approach, t)
    return ts, S, [manoeuvre_indices(ts, s[:, 0], s[:, 1], s[:, 5], d) for s, d in zip(S, delta)]


#: The indices of a predicted turning circle (:func:`turning_circles`, the standard predictions):
#: advance, transfer, tactical diameter and steady turning diameter (m), and the speed loss in the
#: steady turn (1 - u / U0 of the track's speed; :func:`~bayesid.estimation.indices.manoeuvre_indices`).
TURNING_INDICES = ("advance_m", "transfer_m", "tactical_diameter_m", "steady_turning_diameter_m", "speed_loss")


def turning_circles(
    fitted: FittedModel,
    n_draws: int,
    rng,
    approach: Approach,
    rudder_deg: float = 35.0,
    duration_s: float = 300.0,
) -> dict:
    """Predicted turning circles to starboard and port (:func:`standard_run`).

    From a straight approach (``approach``: the speed, rpm and rudder rate of the logged runs,
    :func:`bayesid.models.runs.approach_condition`), the rudder is ordered to ``rudder_deg`` at
    :data:`bayesid.models.runs.T_EXECUTE` s, moves there at the approach's rudder rate and is held
    for ``duration_s``; the indices of :data:`TURNING_INDICES` (ITTC definitions) of the model at
    its estimate, with the 5-95 % band of ``n_draws`` posterior draws.

    Parameters
    ----------
    fitted : FittedModel
        The model, its estimate and covariance (None is allowed with ``n_draws`` 0).
    n_draws : int
        Posterior draws of the band (0: no band).
    rng : numpy.random.Generator
        Draws them.
    approach : Approach
        The approach condition: ``u`` (m/s), ``rpm``, ``rudder_rate`` (rad/s).
    rudder_deg : float, default 35.0
        The rudder angle (deg).
    duration_s : float, default 300.0
        The time from the order on (s).

    Returns
    -------
    dict
        ``{side: {"predicted", "band_5_95", "sd" (of the draws), "n_finite_draws", "_S" (B, n, 12)
        predictions}}``; the indices in m, the speed loss a fraction.
    """
    out = {}
    for side in ("starboard", "port"):  # package rudder: + = to port
        run = ManoeuvreRun("turning_circle", rudder_deg, None, side, approach.rpm, T_EXECUTE + duration_s)
        _, S, ind = standard_run(fitted.model, fitted.rows(n_draws, rng), run, approach)
        res = {"predicted": {k: ind[0][k] for k in TURNING_INDICES}}
        res["band_5_95"], res["n_finite_draws"] = predictive_band(ind[1:], list(res["predicted"]))
        res["sd"] = predictive_sd(ind[1:], list(res["predicted"]))
        res["_S"] = S
        out[side] = res
    return out


#: A fitted model reproduces a training turning circle when its tactical and steady turning
#: diameters are within this fraction of the measured ones (issue 67's target).
TURN_TOLERANCE = 0.05
#: A predicted speed loss in the steady turn this far (a fraction of the approach speed) from the
#: measured one points at the speed in the turn rather than at the turning forces.
SPEED_LOSS_TOLERANCE = 0.05
#: A run whose logged wind pushes with at least this fraction of the hull's resistance at the
#: approach speed (:func:`bayesid.models.ship.dynamics.wind_to_resistance`: about 12 % of the
#: steady speed) suspects the wind first when the model has no wind effect.
WIND_SUSPECT_RATIO = 0.25


def training_turns(fitted: FittedModel, tracks, *, tolerance: float = TURN_TOLERANCE) -> list[dict]:
    """Whether a fitted model reproduces the turning circles it was trained on: each training run
    that reads as a turning circle (:func:`~bayesid.estimation.indices.manoeuvre_kind`) predicted
    whole from its measured first state with its logged inputs (:func:`turning_band`), its
    indices against the measured ones. A miss here is structural (the model form cannot hold the
    turn its coefficients were fitted to), not a prediction error.

    The component suspected: a speed loss in the steady turn off by more than
    :data:`SPEED_LOSS_TOLERANCE` of the approach speed points at the speed in the turn (the surge
    equation: hull resistance in the turn, the propeller's inflow and thrust deduction, the
    rudder's drag; MMG: Yasukawa & Yoshimura 2015, J. Mar. Sci. Technol. 20:37, eqs. 5-10), since
    the steady diameter is 2 U / r; a speed loss within it with a diameter off points at the
    sway force and yaw moment of the hull and rudder in the turn. Before either: a ship model
    without the wind effect on a run whose logged wind pushes with at least
    :data:`WIND_SUSPECT_RATIO` of the hull's resistance suspects the wind (on the Esso Osaka pond
    runs, 0.27-0.54 on the turns the index reader reads; fitted with the wind, the training turn's
    speed loss 0.38 against 0.44 measured, without it 0.22). A suspicion, not a diagnosis:
    ``bayesid diagnose`` tests named causes.

    Parameters
    ----------
    fitted : FittedModel
        The model and its estimate.
    tracks : list of Track
        The training runs (the others are skipped).
    tolerance : float, default :data:`TURN_TOLERANCE`
        The largest relative error of the tactical and steady turning diameters that counts as
        reproduced.

    Returns
    -------
    list of dict
        One per turning circle: ``run``, ``measured`` and ``predicted`` (``{index: value}`` of
        :data:`TURNING_INDICES`: m, the speed loss a fraction; None where not reached),
        ``rel_error`` (``{index: (predicted - measured) / measured}`` of the diameters, advance
        and transfer; None where either is missing), ``reproduced`` (bool, or None when neither
        diameter could be read from both), ``suspect`` (None when reproduced: ``"wind"``,
        ``"speed in the turn"`` or ``"turning forces"``), ``predicted_unread`` (why the model's
        run gave no index, e.g. it does not read as a turning circle; None when it did) and, for
        a ship model without the wind effect on a run that logs wind, ``wind_to_resistance``.
    """
    from .indices import manoeuvre_kind

    out = []
    for tr in tracks:
        if manoeuvre_kind(tr) != "turning_circle":
            continue
        tb = turning_band(fitted, tr, 0, None)
        meas = {k: _finite(tb["measured"].get(k)) for k in TURNING_INDICES}
        pred = {k: _finite(tb["predicted"].get(k)) for k in TURNING_INDICES}
        rel = {
            k: (pred[k] - meas[k]) / meas[k] if meas[k] and pred[k] is not None else None
            for k in TURNING_INDICES
            if k != "speed_loss"
        }
        judged = [abs(rel[k]) for k in ("tactical_diameter_m", "steady_turning_diameter_m") if rel[k] is not None]
        reproduced = None if not judged else max(judged) <= tolerance
        wind = _unmodelled_wind(fitted.model, tr)
        suspect = None
        if reproduced is False:
            m, q = meas["speed_loss"], pred["speed_loss"]
            off = m is not None and q is not None and abs(q - m) > SPEED_LOSS_TOLERANCE
            suspect = "speed in the turn" if off else "turning forces"
            if wind is not None and wind >= WIND_SUSPECT_RATIO:
                suspect = "wind"
        unread = None if any(v is not None for v in pred.values()) else tb["predicted"].get("reason", "not read")
        row = {
            "run": tr.name,
            "measured": meas,
            "predicted": pred,
            "rel_error": rel,
            "reproduced": reproduced,
            "suspect": suspect,
            "predicted_unread": unread,
        }
        if wind is not None:
            row["wind_to_resistance"] = wind
        out.append(row)
    return out


def _unmodelled_wind(model, track) -> float | None:
    """:func:`~bayesid.models.ship.dynamics.wind_to_resistance` of a ship model without the wind
    effect on a run that logs wind; None otherwise (a submarine, a model with the wind)."""
    from ..models.ship.dynamics import wind_to_resistance
    from ..models.ship.fileformat import Ship

    ship = getattr(model, "vehicle", None)
    if not isinstance(ship, Ship) or any(getattr(e, "name", e) == "wind" for e in getattr(model, "effects", ())):
        return None
    return wind_to_resistance(ship, track)


def _finite(v) -> float | None:
    """An index as a float, None when missing or not finite."""
    return float(v) if v is not None and math.isfinite(v) else None
