"""Identification on long, noisy runs: multiple shooting, seeded by equation error, with a
Laplace posterior; prediction under the fixed window protocol; standard manoeuvre indices.

The objective (:class:`bayesid.estimation.windows.WindowObjective`) is the simulation error over non-overlapping windows
that restart from the measured state (causal estimate, :func:`bayesid.protocol.state_at`), so a
long run that an open-loop simulation would leave within a minute still gives a well-posed fit.
Each channel is weighted by its noise sd, estimated from the data (differences, Gasser et al.
1986; :func:`bayesid.protocol.estimate_noise`); heading errors are wrapped; tracks may have
different sampling rates (the model steps at ``dt``, predictions are interpolated to the
samples); unmeasured velocities are derived from the positions for the start states and are
simply not scored.

It works for both model families: a :class:`bayesid.models.ship.Ship` (the MMG 3-DOF model, seeded by
:func:`bayesid.models.ship.equation_error_seed`) and a submarine :class:`bayesid.data.vehicle.Vehicle`
(horizontal-plane :class:`bayesid.models.effects.EffectModel`, started at the nominal coefficients).

Posterior: the Laplace approximation at the optimum, ``cov = s^2 (J^T J)^-1 * n/n_eff`` with
``s^2 = SSR / (n - k)`` and ``n/n_eff = (1 + rho1) / (1 - rho1)`` from the lag-1
autocorrelation ``rho1`` of the residuals within windows (an AR(1) correction: simulation-error
residuals are strongly correlated, and ignoring that would make the bands far too narrow),
capped at the mean number of samples per window (each window then counts as one independent
residual per channel).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..data.track import Track
from ..models import build_model, load_any_vehicle
from ..models import context as ctxmod
from ..protocol import pooled_scores, resolve_start, start_settings
from . import shooting
from . import windows as wf
from .calibration import leave_one_run_out
from .fit import FitResult
from .laplace import gauss_newton_covariance
from .multistart import multistart

#: Protocol window (s) of a fit whose user gives none, for a family that scores over the
#: protocol window (submarines; :meth:`~bayesid.models.effects.EffectModel.default_fit_window`).
DEFAULT_WINDOW_S = 30.0


def _ar1_inflation(fitres: FitResult, ctxs) -> float:
    r = []
    for ctx in ctxs:
        S = shooting.simulate(fitres.model, ctx, fitres.p[None])
        for c, e in ctxmod.errors(ctx, S).items():
            if fitres.channels is not None and c not in fitres.channels:
                continue
            e = e[0]
            same = ctx.win[1:] == ctx.win[:-1]
            a, b = e[:-1][same], e[1:][same]
            ok = np.isfinite(a) & np.isfinite(b)
            if ok.sum() > 10 and np.std(a[ok]) > 0:
                r.append(np.corrcoef(a[ok], b[ok])[0, 1])
    rho = float(np.clip(np.median(r), 0.0, 0.999)) if r else 0.0
    # at most the samples per window: every window counts as one independent residual per channel
    per_window = max(1.0, np.mean([ctx.ts.size / ctx.W for ctx in ctxs]))
    return float(min((1 + rho) / (1 - rho), per_window))


def laplace_covariance(
    fitres: FitResult, ctxs, prior: wf.GaussianPrior | None = None, data_scale: tuple | None = None
) -> tuple[np.ndarray, dict]:
    """(n_params, n_params) Laplace covariance of the fitted parameters (module docstring).

    Without a prior: ``(J^T J)^+ * s2 * inflation`` with ``s2 = SSR / (n - k)`` and the AR(1)
    inflation of the residuals. With a ``prior`` (whose residuals end the fit's residual vector,
    weighted by ``sqrt(s2 * inflation)``; ``data_scale = (s2, inflation)`` of the fit without
    it): ``(J_d^T J_d / (s2 * inflation) + diag(1 / sd^2))^-1``, the Gaussian posterior of a
    likelihood whose samples count ``1 / inflation`` each."""
    n = fitres.model.n_params
    J = fitres.jac[:, :n]
    J = J.toarray() if hasattr(J, "toarray") else np.asarray(J)
    if prior is not None:
        J = J[: J.shape[0] - prior.idx.size]  # the data rows
        s2, infl = data_scale
        cov = psd_covariance(gauss_newton_covariance(J / math.sqrt(s2 * infl), prior_precision=prior.precision(n)))
    else:
        s2 = fitres.cost / max(fitres.n_residuals - J.shape[1], 1)
        infl = _ar1_inflation(fitres, ctxs)
        cov = psd_covariance(gauss_newton_covariance(J, residual_variance=s2, inflation=infl))
    sv = np.linalg.svd(J, compute_uv=False)
    return cov, {
        "residual_variance": s2,
        "ar1_inflation": infl,
        "condition_number": float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf"),
        "weak_directions": weak_directions(J, fitres.model.scales()),
    }


def psd_covariance(cov) -> np.ndarray:
    """The symmetric positive semi-definite form of a covariance: its symmetric part with the
    eigenvalues below zero (round-off of an ill-conditioned Gauss-Newton inverse) set to zero.
    What ``fit`` writes is what ``predict`` reads (:func:`load_model`)."""
    C = 0.5 * (np.asarray(cov, float) + np.asarray(cov, float).T)
    lam, V = np.linalg.eigh(C)
    C = (V * np.clip(lam, 0.0, None)) @ V.T
    return 0.5 * (C + C.T)


def weak_directions(J, scales, k: int = 3) -> list:
    """The ``k`` directions of parameter space the residuals constrain least: eigenvectors of
    ``(J D)^T (J D)`` with ``D = diag(scales)`` (parameters in units of their typical size), the
    smallest eigenvalue first. Each: ``{"eigenvalue", "vector"}`` (unit vector over the
    parameters, in scaled units), labelled by the report layer
    (:class:`bayesid.analysis.identifiability.Direction`)."""
    Js = np.asarray(J, float) * np.abs(np.asarray(scales, float))[None, :]
    lam, V = np.linalg.eigh(Js.T @ Js)
    return [{"eigenvalue": float(lam[i]), "vector": V[:, i].tolist()} for i in range(min(k, lam.size))]


def identify(
    vehicle,
    train,
    free=None,
    effects=(),
    window_s: float | None = None,
    dt: float | None = None,
    max_nfev: int = 60,
    seed: bool = True,
    progress=None,
    weighting: str | None = None,
    channels=None,
    start: str = "auto",
    starts: int = 0,
    rng=None,
    jobs: int = 1,
    scheduler: str | None = None,
    journal=None,
    prior: bool = True,
    calibrate: bool = True,
    calibration_window_s: float = 60.0,
    calibration_draws: int = 40,
    calibration_seed: int = 0,
) -> dict:
    """Identify the free coefficients (and effect parameters) on training tracks.

    Parameters
    ----------
    vehicle : :class:`~bayesid.models.ship.Ship` or :class:`~bayesid.data.vehicle.Vehicle`.
    train : list of Tracks (``t, x, y, psi, delta_r, n``; ``u, v, r`` when measured; ``wind_*``
        for the wind effect).   free : coefficient names (default: the ship file's ``[fit] free``).
    effects : effect names (ship: :data:`~bayesid.models.ship.SHIP_CATALOGUE`).
    window_s : multiple-shooting window (s); default the family's ``default_fit_window``
        (:data:`bayesid.models.ship.FIT_WINDOW_S` for a ship, :data:`DEFAULT_WINDOW_S` for a submarine).
    dt : model step (s; default the family's ``DEFAULT_DT``).
    seed : start from the model's equation-error estimate (``model.seed``; ships) when it
        simulates better than the nominal coefficients.
    weighting : ``"noise"`` or ``"residual"`` channel weights
        (:func:`bayesid.estimation.windows.fit_weighted`); default the family's
        (``"residual"`` for a ship, ``"noise"`` for a submarine).
    channels : the scored channels in the objective (default: every one the tracks measure;
        e.g. ``("x", "y", "psi")`` when the logged velocities are derived from the same
        positions and heading and add no independent information).
    start : window start-state rule (:data:`bayesid.protocol.START_RULES`; ``"auto"``: the start
        states of the windows are fitted with the coefficients when a track does not log u, v, r).
    starts : extra Latin-hypercube starts of a multistart fit (0: the default start alone;
        :func:`bayesid.estimation.multistart.multistart`, with the default fit's weights). The
        lowest cost is kept. ``rng`` (Generator) draws the starts; ``jobs``, ``scheduler`` and
        ``journal`` run them (:func:`bayesid.tasks.run_tasks`).
    prior : use the vehicle file's ``[prior]`` section (Gaussian priors, e.g. captive-test values
        with their error) when it has one: after the fit without it, a MAP fit
        (:class:`~bayesid.estimation.windows.GaussianPrior`) whose data residuals count as
        ``1 / inflation`` independent samples each (the AR(1) inflation of the first fit's
        residuals, at most the samples per window), and the Laplace covariance of that posterior.
    calibrate : with 3 or more training runs, calibrate the predictive bands leave one run out
        (:func:`bayesid.estimation.calibration.leave_one_run_out`: refits without each run,
        scored on it over ``calibration_window_s`` windows and its manoeuvre indices with
        ``calibration_draws`` posterior draws, seeded from ``calibration_seed``); the folds run as tasks.

    Returns
    -------
    dict: ``model`` (the simulation model), ``fit`` (:class:`~bayesid.estimation.fit.FitResult`), ``cov``,
    ``posterior`` (Laplace summary), ``seed`` (summary), ``noise_sd``, ``fit_sd`` (the sds of
    the final weights), ``train_scores``, ``multistart`` (a
    :class:`~bayesid.estimation.multistart.MultistartResult` or None), ``prior`` (whether the
    file's priors were used; per coefficient mean, sd, identified value, z-score with and without
    the prior, posterior sd; the names the data ``moved`` beyond 1 prior sd and ``beyond_3sd``),
    ``calibration`` (the leave-one-run-out scores, or None).

    Raises
    ------
    ValueError : no training track; a track without the needed columns (named); an unknown
        channel or a track that measures none of ``channels``; too little data
        (:func:`bayesid.estimation.windows.check_enough_data`).
    KeyError : an unknown coefficient name.
    """
    if not train:
        raise ValueError("identify needs at least one training track")
    say = progress or (lambda m: None)
    channels = wf.check_channels(channels)
    model = build_model(vehicle, free, effects, dt)
    if window_s is None:
        window_s = model.default_fit_window(DEFAULT_WINDOW_S)
    for e in model.effects:
        bare = [t.name for t in train if not all(c in t for c in e.needs_columns)]
        if bare:
            raise ValueError(
                f"the {e.name} effect needs columns {' and '.join(e.needs_columns)}; track(s) "
                f"{', '.join(bare)} have none (leave --effects {e.name} out, or add the measured "
                f"{e.name})"
            )
    rule = resolve_start(start, train)
    ctxs = [model.context(t, window_s, start=rule) for t in train]
    wf.check_enough_data(model, ctxs, window_s)
    sd = wf.pooled_noise_sd(train)
    p0 = model.start()
    seed_info = {"used": False}
    if seed:
        try:
            seeded = model.seed(train)  # None: the model family has no equation-error seed
        except Exception as exc:  # noqa: BLE001 - reported; the fit starts from nominal
            seeded = (None, {"error": f"{type(exc).__name__}: {exc}"})
        if seeded is not None:
            ps, info = seeded
            seed_info = info
            if ps is not None:
                c_nom, c_seed = wf.window_residuals(
                    model,
                    ctxs,
                    [wf.channel_weights(c, sd, channels) for c in ctxs],
                    np.vstack([p0, ps]),
                    [None] * len(ctxs),
                )
                info["cost_nominal"], info["cost_seed"] = float(c_nom @ c_nom), float(c_seed @ c_seed)
                if info["cost_seed"] < info["cost_nominal"]:
                    p0, seed_info = ps, dict(info, used=True)
                else:
                    seed_info = dict(info, used=False)
            say(f"equation-error seed: {'used' if seed_info.get('used') else 'not used'}")
    say("multiple-shooting fit")
    weighting = weighting or model.DEFAULT_WEIGHTING
    f, sd_fit = wf.fit_weighted(
        model,
        ctxs,
        sd,
        p0,
        max_nfev=max_nfev,
        weighting=weighting,
        channels=channels,
        progress="fit" if progress is not None else None,
    )
    ms = None
    if starts:
        say(f"multistart: {starts} more start(s) on {scheduler or f'{jobs} worker(s)'}")
        dflt = {
            "p": f.p.tolist(),
            "cost": float(f.cost),
            "success": bool(f.success),
            "nfev": int(f.n_simulations),
            "message": str(f.message),
        }
        ms = multistart(
            model,
            ctxs,
            sd_fit,
            p0,
            starts,
            np.random.default_rng(0) if rng is None else rng,
            max_nfev=max_nfev,
            channels=channels,
            default_fit=dflt,
            jobs=jobs,
            scheduler=scheduler,
            journal=journal,
            progress="starts" if progress is not None else None,
        )
        if ms.best != 0:  # the best optimum again in this process, for its Jacobian (few evaluations)
            f = wf.fit_model(
                model, ctxs, sd_fit, np.asarray(ms.fits[ms.best]["p"]), max_nfev=max_nfev, channels=channels
            )
    gp, prior_info = wf.GaussianPrior.of_model(model) if prior else None, {"used": False}
    if gp is not None and gp.idx.size:
        # the prior weighs against the data as a likelihood whose samples count 1 / inflation each
        # (serially correlated residuals), with the residual variance of the fit without it
        s2 = f.cost / max(f.n_residuals - model.n_params, 1)
        infl = _ar1_inflation(f, ctxs)
        gp = wf.GaussianPrior(gp.names, gp.idx, gp.mean, gp.sd, math.sqrt(s2 * infl))
        say(f"MAP fit with the vehicle file's priors on {len(gp.names)} coefficient(s)")
        f0 = f
        f = wf.fit_model(
            model,
            ctxs,
            sd_fit,
            f.p,
            f.nuisance,
            max_nfev=max_nfev,
            channels=channels,
            prior=gp,
            progress="fit with prior" if progress is not None else None,
        )
        cov, post = laplace_covariance(f, ctxs, gp, (s2, infl))
        z = (f.p[gp.idx] - gp.mean) / gp.sd
        z0 = (f0.p[gp.idx] - gp.mean) / gp.sd
        prior_info = {
            "used": True,
            "source": getattr(model.vehicle, "prior_source", ""),
            "data_weight_sd": gp.weight,
            "residual_variance": s2,
            "ar1_inflation": infl,
            "coefficients": {
                n: {
                    "mean": float(m),
                    "sd": float(d),
                    "identified": float(f.p[i]),
                    "z": float(zz),
                    "z_without_prior": float(zz0),
                    "posterior_sd": float(math.sqrt(max(cov[i, i], 0.0))),
                }
                for n, i, m, d, zz, zz0 in zip(gp.names, gp.idx, gp.mean, gp.sd, z, z0)
            },
            "moved": [n for n, zz in zip(gp.names, z) if abs(zz) > 1.0],
            "beyond_3sd": [n for n, zz in zip(gp.names, z) if abs(zz) > 3.0],
        }
    else:
        cov, post = laplace_covariance(f, ctxs)
        gp = None
    calib = None
    if calibrate and len(train) >= 3:
        rule_p, lead_p = start_settings(start, train, calibration_window_s, model.dt, None)
        say(f"calibration: leave one of {len(train)} runs out on {scheduler or f'{jobs} worker(s)'}")
        calib = leave_one_run_out(
            model,
            train,
            ctxs,
            f,
            sd_fit,
            calibration_window_s,
            start=rule_p,
            leadin_s=lead_p,
            channels=channels,
            max_nfev=max_nfev,
            prior=gp,
            data_scale=(prior_info["residual_variance"], prior_info["ar1_inflation"]) if gp is not None else None,
            n_draws=calibration_draws,
            seed=calibration_seed,
            jobs=jobs,
            scheduler=scheduler,
            journal=journal,
            progress="calibration" if progress is not None else None,
        )
    return {
        "model": model,
        "fit": f,
        "cov": cov,
        "posterior": post,
        "seed": seed_info,
        "noise_sd": sd,
        "fit_sd": sd_fit,
        "weighting": weighting,
        "channels": channels,
        "start_rule": rule,
        "train_scores": wf.scores(model, f, ctxs),
        "window_s": window_s,
        "p0": p0,
        "multistart": ms,
        "prior": prior_info,
        "calibration": calib,
    }


def model_document(res: dict, vehicle_ref: str, train_names, provenance: dict | None = None) -> dict:
    """The ``model.json`` document (format ``bayesid-model-1``) of an :func:`identify` result:
    vehicle reference, free coefficients, effects, step, fit window, parameters with their
    Laplace covariance and sds, weights, scores and ``provenance`` (package version, vehicle
    file hash and values, input hashes; stored as given). :func:`load_model` reads it back."""
    m, f = res["model"], res["fit"]
    sdv = np.sqrt(np.clip(np.diag(res["cov"]), 0, None))
    doc = {
        "format": "bayesid-model-1",
        "vehicle": vehicle_ref,
        "vehicle_id": m.vehicle.id,
        "free": list(m.free),
        "effects": [e.name for e in m.effects],
        "dt": m.dt,
        "fit_window_s": res["window_s"],
        "param_names": m.param_names,
        "p": f.p.tolist(),
        "cov": res["cov"].tolist(),
        "sd": sdv.tolist(),
        "start": res["p0"].tolist(),
        "posterior": res["posterior"],
        "seed": res["seed"],
        "noise_sd": res["noise_sd"],
        "weighting": res.get("weighting", "noise"),
        "fit_sd": res.get("fit_sd", res["noise_sd"]),
        "fit_channels": None if res.get("channels") is None else list(res["channels"]),
        "start_rule": res.get("start_rule", "measured"),
        "train_runs": list(train_names),
        "train_scores": res["train_scores"],
        "provenance": provenance or {},
        "fit": {
            "ssr": f.cost,
            "n_residuals": f.n_residuals,
            "nfev": f.n_simulations,
            "success": f.success,
            "message": f.message,
            "seconds": f.wall_s,
            "bic": f.bic,
        },
    }
    if res.get("multistart") is not None:
        doc["multistart"] = res["multistart"].to_dict()
    doc["prior"] = res.get("prior") or {"used": False}
    doc["calibration"] = res.get("calibration")
    return doc


def load_model(path):
    """(model, p, cov, doc) from a ``model.json`` (:func:`model_document`).

    Raises ValueError naming the file when it is not such a document."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ValueError(f"{path}: not a model file ({e})") from None
    if doc.get("format") != "bayesid-model-1":
        raise ValueError(f"{path}: not a bayesid model file (format {doc.get('format')!r})")
    missing = [k for k in ("vehicle", "free", "effects", "dt", "p", "cov") if k not in doc]
    if missing:
        raise ValueError(f"{path}: model file without {', '.join(repr(k) for k in missing)} (edited or truncated?)")
    ref = doc["vehicle"]
    if not isinstance(ref, str) or not isinstance(doc["free"], list) or not isinstance(doc["effects"], list):
        raise ValueError(f"{path}: 'vehicle' must be a string, 'free' and 'effects' lists")
    if not Path(ref).is_absolute() and (path.parent / ref).is_file():
        ref = str(path.parent / ref)
    vehicle = load_any_vehicle(ref)
    if not isinstance(doc["dt"], (int, float)) or not doc["dt"] > 0:
        raise ValueError(f"{path}: 'dt' must be a positive number of seconds, not {doc['dt']!r}")
    try:
        model = build_model(vehicle, doc["free"], doc["effects"], doc["dt"])
    except (KeyError, ValueError) as e:
        raise ValueError(
            f"{path}: its free coefficients or effects do not fit the vehicle {ref!r}: {e.args[0] if e.args else e}"
        ) from None
    n = len(model.param_names)
    try:
        p, cov = np.array(doc["p"], dtype=float), np.array(doc["cov"], dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{path}: 'p' and 'cov' must be numbers") from None
    if p.shape != (n,) or not np.all(np.isfinite(p)):
        raise ValueError(
            f"{path}: 'p' must be {n} finite numbers ({', '.join(model.param_names)}), got shape {p.shape}"
        )
    if cov.shape != (n, n) or not np.all(np.isfinite(cov)):
        raise ValueError(
            f"{path}: 'cov' must be a finite {n} x {n} matrix, got shape {cov.shape}"
            + ("" if cov.shape != (n, n) else " with non-finite entries")
        )
    # round-off of an ill-conditioned inverse (relative asymmetry ~1e-7, eigenvalues ~-1e-9 of
    # the largest) is not an edit; an asymmetry or a negative eigenvalue beyond 1e-6 is
    big = max(float(np.abs(cov).max()), 1e-300)
    lam = np.linalg.eigvalsh(0.5 * (cov + cov.T))
    if np.abs(cov - cov.T).max() > 1e-6 * big or lam.min() < -1e-6 * max(float(lam.max()), 1e-300):
        raise ValueError(
            f"{path}: 'cov' is not a symmetric positive semi-definite matrix (edited?): relative "
            f"asymmetry {np.abs(cov - cov.T).max() / big:.2g}, smallest/largest eigenvalue "
            f"{lam.min() / max(float(lam.max()), 1e-300):.2g}"
        )
    return model, p, psd_covariance(cov), doc


def predict(model, p, tracks, window_s: float | None, start: str = "auto", leadin_s: float | None = None) -> dict:
    """The protocol on tracks: per window and pooled RMS position / heading errors.

    ``start``: window start-state rule (:data:`bayesid.protocol.START_RULES`; ``"auto"`` decides
    on these tracks); ``leadin_s``: lead-in of the fitted rule (default
    :func:`bayesid.protocol.start_settings`). The result's ``start_rule`` and
    ``leadin_s`` say what was used.

    Returns dict ``pooled`` (:func:`~bayesid.protocol.pooled_scores`), ``per_track``
    {name: pooled scores}, ``windows`` (list of {track, t_start, duration_s (of its scored
    samples), rms_position_m, max_position_m, rms_heading_deg, max_heading_deg}) and ``_sim`` (per track (ctx, S) for plots)."""
    errs, per_track, windows, sims = [], {}, [], {}
    rule, lead = start_settings(start, tracks, window_s, model.dt, leadin_s)
    for tr in tracks:
        ctx = model.context(tr, window_s, start=rule, leadin_s=lead)
        S = shooting.simulate(model, ctx, np.asarray(p)[None])
        e = {k: v[0] for k, v in ctxmod.errors(ctx, S).items()}
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
    return {
        "pooled": pooled_scores(errs),
        "per_track": per_track,
        "windows": windows,
        "_sim": sims,
        "start_rule": rule,
        "leadin_s": lead,
    }


def posterior_samples(model, p, cov, n: int, rng) -> np.ndarray:
    """(n, n_params) draws from the Laplace posterior, kept inside the parameter bounds."""
    lo, hi = model.bounds()
    L = np.linalg.cholesky(cov + 1e-15 * np.eye(cov.shape[0]) * max(np.trace(cov), 1e-30))
    X = p[None] + rng.standard_normal((n, p.size)) @ L.T
    return np.clip(X, lo, hi)


# ---------------------------------------------------------------------------------------------
# Standard manoeuvre indices
# ---------------------------------------------------------------------------------------------
def _rudder_holds(t, delta, threshold: float, min_hold_s: float):
    """Runs of the rudder beyond ``threshold`` (rad) on one side, each (side, i_start, i_end, peak
    |delta|), with runs shorter than ``min_hold_s`` dropped (a blip of counter-rudder is not a
    reversal) and neighbouring runs on the same side merged."""
    side = np.where(delta > threshold, 1, np.where(delta < -threshold, -1, 0))
    edge = np.flatnonzero(np.diff(side) != 0) + 1
    starts = np.r_[0, edge]
    ends = np.r_[edge - 1, side.size - 1]
    runs = []
    for i, j in zip(starts, ends):
        if side[i] == 0 or not (t[j] - t[i] >= min_hold_s or (j == side.size - 1 and not runs)):
            continue
        peak = float(np.max(np.abs(delta[i : j + 1])))
        if runs and runs[-1][0] == side[i]:
            s0, a0, _, p0 = runs[-1]
            runs[-1] = (s0, a0, int(j), max(p0, peak))
        else:
            runs.append((int(side[i]), int(i), int(j), peak))
    return runs


def manoeuvre_indices(t, x, y, psi, delta) -> dict:
    """Standard indices of a turning circle or a zigzag from a track (ITTC 7.5-04-02-01, 2002,
    "Full scale manoeuvring trials procedure", Sec. 2.2: definitions of the turning circle and
    zigzag tests), after deciding which manoeuvre the run is.

    The rudder is read as holds: runs beyond 3 deg on one side lasting at least 2 s (shorter
    counter-rudder blips are not reversals). Execute: the first hold's start.

    * **turning**: one hold (the rudder never reversed) during which the heading changes by at
      least 90 deg: ``advance_m`` (distance along the approach heading at 90 deg of heading
      change), ``transfer_m`` (normal to it, at 90 deg) and ``tactical_diameter_m`` (normal
      distance at 180 deg; NaN when the heading does not get there before the rudder returns);
    * **zigzag**: at least two reversals between holds of similar size (each within a factor of
      two of the first), the heading oscillating about the approach heading (never 90 deg away):
      ``first_overshoot_deg`` and ``second_overshoot_deg`` (heading beyond the switching heading
      after the 1st and 2nd reversal);
    * otherwise ``"other"`` with the ``reason``, and no index.

    Arrays (n,): t (s), x, y (m), psi (rad, any wrap), delta (rad). Returns a dict with ``kind``
    (``"turning"``, ``"zigzag"``, ``"other"``), ``execute_t_s`` and the indices or ``reason``.
    """
    t, x, y, delta = (np.asarray(a, float) for a in (t, x, y, delta))
    psi = np.unwrap(np.asarray(psi, float))
    holds = _rudder_holds(t, delta, math.radians(3.0), 2.0)
    if not holds:
        return {"kind": "other", "reason": "the rudder is never held beyond 3 deg for 2 s"}
    i0 = holds[0][1]
    out = {"execute_t_s": float(t[i0])}
    h = psi - psi[i0]
    if len(holds) == 1:
        _, a, b, _ = holds[0]
        turned = float(np.degrees(np.max(np.abs(h[a : b + 1]))))
        if turned < 90.0:
            return dict(
                out,
                kind="other",
                reason=f"one rudder hold, but the heading changed only {turned:.0f} deg "
                "while it was held (a turning circle needs 90)",
            )
        out["kind"] = "turning"
        c, s = math.cos(psi[i0]), math.sin(psi[i0])
        along = c * (x - x[i0]) + s * (y - y[i0])
        normal = -s * (x - x[i0]) + c * (y - y[i0])
        for name, ang in (("90", math.pi / 2), ("180", math.pi)):
            k = np.flatnonzero(np.abs(h[a : b + 1]) >= ang)
            if k.size:
                j = a + k[0]
                if name == "90":
                    out["advance_m"] = float(along[j])
                    out["transfer_m"] = float(abs(normal[j]))
                else:
                    out["tactical_diameter_m"] = float(abs(normal[j]))
        for key in ("advance_m", "transfer_m", "tactical_diameter_m"):
            out.setdefault(key, float("nan"))
        return out
    first = holds[0][3]
    similar = all(0.5 * first <= p <= 2.0 * first for _, _, _, p in holds)
    span = float(np.degrees(np.max(np.abs(h[i0:]))))
    if len(holds) < 3 or not similar or span >= 90.0:
        why = (
            f"the rudder reversed {len(holds) - 1} time(s)"
            + (", between holds of different sizes" if not similar else "")
            + f", and the heading moved up to {span:.0f} deg from the approach heading"
        )
        return dict(
            out,
            kind="other",
            reason=why + " (a zigzag needs 2 reversals of one rudder angle with the "
            "heading within 90 deg; a turning circle one hold)",
        )
    out["kind"] = "zigzag"
    sw = [hd[1] for hd in holds[1:]]  # first sample of each hold after a reversal
    for name, k in (("first_overshoot_deg", 0), ("second_overshoot_deg", 1)):
        if k < len(sw):
            j = sw[k]
            end = sw[k + 1] if k + 1 < len(sw) else h.size
            going = np.sign(h[j] - h[max(j - 5, 0)]) or 1.0  # the heading keeps turning this way
            seg = h[j:end]
            ext = seg.max() - h[j] if going > 0 else h[j] - seg.min()
            out[name] = float(np.degrees(max(ext, 0.0)))
        else:
            out[name] = float("nan")
    return out


# ---------------------------------------------------------------------------------------------
# Reports of the fit and predict commands
# ---------------------------------------------------------------------------------------------
def windowed_xy(ctx, S):
    """(measured (n, 2), predicted (n + cuts, 2)) x, y with NaN between windows (for plots)."""
    xy = S[:, :2].copy()
    cut = np.flatnonzero(np.diff(ctx.win) != 0) + 1
    xy = np.insert(xy, cut, np.nan, axis=0)
    return np.column_stack([ctx.meas["x"], ctx.meas["y"]]), xy


def turning_band(
    model,
    p,
    cov,
    track,
    n_draws: int,
    rng,
    start: str = "measured",
    leadin_s: float = 0.0,
    keep_draws: bool = False,
    chunk: int | None = None,
) -> dict:
    """Whole-run open-loop prediction of a track from its first sample (``start`` rule, resolved:
    the measured state, or the state fitted to the first ``leadin_s`` seconds), with
    the manoeuvre indices of the measured run, the identified model, and a posterior predictive
    band (5-95 % of ``n_draws`` Laplace draws). The draws are simulated ``chunk`` at a time and
    reduced to their indices, so memory does not grow with ``n_draws`` x the track length;
    ``_S`` holds the identified model's prediction (1, n, 12), or every draw's with
    ``keep_draws``; the default ``chunk`` keeps each batch of predictions near 200 MB. ``sd``:
    {index: sd of the draws' values} (None with fewer than 3 finite draws)."""
    P = np.vstack([p[None], posterior_samples(model, p, cov, n_draws, rng)]) if n_draws else p[None]
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
    chunk = chunk or int(max(1, min(8, 2e8 // (8 * 12 * 3 * max(ctx.ts.size, 1)))))
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
    keys = [k for k in meas if k not in ("kind", "execute_t_s", "reason")]
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
    """({key: [5 %, 95 %] percentiles over the draws' finite values, or None with fewer than 3},
    {key: number of finite draws}) of a list of index dicts (one per posterior draw)."""
    band, n = {}, {}
    for k in keys:
        vals = np.array([d.get(k, np.nan) for d in draws], float)
        vals = vals[np.isfinite(vals)]
        band[k] = [float(np.percentile(vals, 5)), float(np.percentile(vals, 95))] if vals.size >= 3 else None
        n[k] = int(vals.size)
    return band, n


def predictive_sd(draws: list, keys) -> dict:
    """{key: standard deviation of the draws' finite values, or None with fewer than 3} of a list
    of index dicts (one per posterior draw)."""
    out = {}
    for k in keys:
        v = np.array([d.get(k, np.nan) for d in draws], float)
        v = v[np.isfinite(v)]
        out[k] = float(np.std(v, ddof=1)) if v.size >= 3 else None
    return out


def approach_condition(tracks, first_s: float = 5.0) -> tuple[float, float]:
    """(speed m/s, propeller rev/s) of the tracks' approach: medians over the first ``first_s``
    seconds of every track of the speed (from ``u, v`` when logged, else the positions'
    differences) and of ``n`` (rpm / 60). The condition a predicted turning circle starts from.
    Raises ValueError when no track has ``n``."""
    speeds, rps = [], []
    for tr in tracks:
        k = np.asarray(tr.t) <= tr.t[0] + first_s
        if "u" in tr and np.isfinite(tr["u"][k]).any():
            v = tr["v"][k] if "v" in tr else 0.0
            speeds.append(np.hypot(tr["u"][k], v))
        elif k.sum() >= 2:
            speeds.append(np.hypot(np.diff(tr["x"][k]), np.diff(tr["y"][k])) / np.diff(tr.t[k]))
        if "n" in tr:
            rps.append(np.asarray(tr["n"][k], float) / 60.0)
    if not rps:
        raise ValueError("approach_condition: no track logs the propeller speed n")
    sp = np.concatenate([np.atleast_1d(s) for s in speeds]) if speeds else np.array([np.nan])
    return float(np.nanmedian(sp)), float(np.nanmedian(np.concatenate(rps)))


def turning_circles(
    model, p, cov, n_draws: int, rng, speed_mps: float, rps: float, rudder_deg: float = 35.0, duration_s: float = 300.0
) -> dict:
    """Predicted turning circles to starboard and port: from a straight run at ``speed_mps``
    with the propeller at ``rps`` (rev/s), the rudder put over to ``rudder_deg`` at t = 1 s and
    held for ``duration_s``; advance, transfer and tactical diameter (m, :func:`manoeuvre_indices`,
    ITTC definitions) of the model at ``p``, with the 5-95 % band of ``n_draws`` Laplace
    posterior draws (``cov``; no band when ``n_draws`` is 0).

    Returns {side: {"predicted", "band_5_95", "sd" (of the draws), "n_finite_draws", "_S" (B, n, 12)
    predictions}}."""
    out = {}
    t = np.arange(0.0, duration_s + 1e-9, 0.1)
    for side, sgn in (("starboard", -1.0), ("port", 1.0)):  # package rudder: + = to port
        dr = np.where(t >= 1.0, sgn * math.radians(rudder_deg), 0.0)
        tr = Track(
            t,
            {
                "x": np.zeros_like(t),
                "y": np.zeros_like(t),
                "psi": np.zeros_like(t),
                "u": np.full_like(t, speed_mps),
                "v": np.zeros_like(t),
                "r": np.zeros_like(t),
                "delta_r": dr,
                "n": np.full_like(t, rps * 60),
            },
            name=f"turn{rudder_deg:g}_{side}",
        )
        s0 = np.zeros(12)
        s0[6] = speed_mps
        ctx = model.context(tr, None, s0=s0)
        P = np.vstack([p[None], posterior_samples(model, p, cov, n_draws, rng)]) if n_draws else p[None]
        S = model.simulate(ctx, P, measured_start=False)
        ind = [manoeuvre_indices(ctx.ts, s[:, 0], s[:, 1], s[:, 5], dr[ctx.idx]) for s in S]
        res = {"predicted": {k: ind[0][k] for k in ("advance_m", "transfer_m", "tactical_diameter_m")}}
        res["band_5_95"], res["n_finite_draws"] = predictive_band(ind[1:], list(res["predicted"]))
        res["sd"] = predictive_sd(ind[1:], list(res["predicted"]))
        res["_S"] = S
        out[side] = res
    return out
