"""Identification on long, noisy runs: multiple shooting, seeded by equation error, with a
Laplace posterior, an optional prior from the vehicle file and predictive bands calibrated leave
one run out.

The objective (:class:`bayesid.estimation.windows.WindowObjective`) is the simulation error over
non-overlapping windows that restart from the measured state (causal estimate,
:func:`bayesid.protocol.state_at`) or from start states fitted with the model, so a long run that
an open-loop simulation would leave within a minute still gives a well-posed fit. Each channel is
weighted by its noise sd, estimated from the data (differences, Gasser et al. 1986;
:func:`bayesid.protocol.estimate_noise`), or by the residual RMS of a first fit; heading errors are
wrapped; tracks may have different sampling rates (the model steps at ``dt``, predictions are
interpolated to the samples); unmeasured velocities are not scored.

It works for both model families: a :class:`bayesid.models.ship.Ship` (the MMG 3-DOF model, seeded
by :func:`bayesid.models.ship.equation_error_seed`) and a submarine
:class:`bayesid.data.vehicle.Vehicle` (horizontal-plane model, started at the nominal
coefficients). The covariance is the Laplace approximation at the optimum with the AR(1)
inflation of the residuals (:mod:`bayesid.estimation.laplace`).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..data.validate import TrackWarning, check_track, in_api_terms
from ..models import build_model
from ..models.runs import PropulsionPointWarning, training_points
from ..protocol import resolve_start, start_settings
from ..tasks import Runner
from . import retiming as rt
from . import windows as wf
from .calibration import Calibration, leave_one_run_out
from .fit import FitResult
from .laplace import CovarianceWarning, ar1_inflation, covariance_sentence, fit_covariance
from .multistart import MultistartResult, multistart
from .options import CalibrationOptions, FitOptions
from .stepcheck import MAX_HALVINGS, StepCheck, StepWarning, step_check

__all__ = ["DEFAULT_WINDOW_S", "IdentifyResult", "identify"]

#: Protocol window (s) of a fit whose user gives none, for a family that scores over the
#: protocol window (submarines; ``default_fit_window`` of the submarine model).
DEFAULT_WINDOW_S = 30.0


@dataclass
class IdentifyResult:
    """What :func:`identify` found.

    Parameters
    ----------
    model : SimulationModel
        The simulation model (free coefficients, effects, step).
    fit : FitResult
        The final fit (with the prior when one was used).
    cov : ndarray, shape (n_params, n_params)
        The Laplace covariance of the parameters.
    posterior : dict
        The Laplace summary: ``residual_variance``, ``ar1_inflation``, ``condition_number``,
        ``weak_directions``.
    seed : dict
        The equation-error seed's summary (``used``, its R^2 and costs).
    noise_sd : dict
        ``{channel: noise sd}`` estimated from the tracks.
    fit_sd : dict
        ``{channel: sd}`` of the final weights.
    weighting : str
        The channel weighting used.
    channels : tuple of str or None
        The scored channels (None: every measured one).
    start_rule : str
        The window start rule, resolved on the tracks.
    train_scores : dict
        Pooled scores of the fit on its training tracks.
    window_s : float
        The multiple-shooting window (s).
    p0 : ndarray, shape (n_params,)
        The start of the fit (nominal or equation-error seed; when the chain of ``nested_start``
        was kept, the optimum of the model without the nesting effects with them at neutral).
    multistart : MultistartResult or None
        The multistart, when extra starts were asked for.
    prior : dict
        ``used``; with a prior per coefficient mean, sd, identified value, z-score with and
        without the prior, posterior sd, and the names the data ``moved`` beyond 1 prior sd and
        ``beyond_3sd``.
    calibration : Calibration or None
        The leave-one-run-out calibration (:func:`bayesid.estimation.calibration.leave_one_run_out`).
    step_check : StepCheck or None
        The step-halving check of the final fit (:mod:`bayesid.estimation.stepcheck`): how far
        halving the model step would move each free coefficient, in sd, and the steps tried.
    retimed_moves : dict or None
        With ``options.retime``: per training run, the start time (s) of each rudder movement
        within one log interval and its sd (:mod:`bayesid.estimation.retiming`).
    nested_start : dict or None
        With effects that have a ``neutral`` value (they contain the model without them): the
        chain that keeps the fit from ending above the model without them (``_keep_nested``):
        ``effects`` (their names), ``cost_without`` (that model's fit), ``cost_effect_start``
        (the fit from the effects' start values), ``cost_neutral_start`` (the fit from the
        first's optimum with the effects neutral), sums of squares at the same channel weights,
        and ``kept`` (``"neutral"`` or ``"effect start"``); None without such effects.
    training_points : dict or None
        Whether the training runs share one propulsion point (ships;
        :func:`bayesid.models.runs.training_points`): each steady approach's model speed against
        its measured one, and the runs ``apart`` from the others; None without two steady
        approaches.
    """

    model: object
    fit: FitResult
    cov: np.ndarray
    posterior: dict
    seed: dict
    noise_sd: dict
    fit_sd: dict
    weighting: str
    channels: tuple | None
    start_rule: str
    train_scores: dict
    window_s: float
    p0: np.ndarray
    multistart: MultistartResult | None
    prior: dict
    calibration: Calibration | None
    step_check: StepCheck | None = None
    retimed_moves: dict | None = None
    nested_start: dict | None = None
    training_points: dict | None = None


def identify(
    vehicle,
    train,
    options: FitOptions = FitOptions(),
    calibration: CalibrationOptions | None = CalibrationOptions(),
    *,
    runner: Runner = Runner(),
) -> IdentifyResult:
    """Identify the free coefficients (and effect parameters) on training tracks.

    With effects that have a catalogue ``neutral`` value (they contain the model without them),
    the fit from their start values is compared with the chain through the model without them
    (that model's fit, then the full model from its optimum with the effects neutral), and the
    lower kept (:attr:`IdentifyResult.nested_start`), so such a fit never ends above the model
    without the effects for want of a start.

    Parameters
    ----------
    vehicle : Ship or Vehicle
        The vessel description (:class:`~bayesid.models.ship.Ship` or
        :class:`~bayesid.data.vehicle.Vehicle`).
    train : list of Track
        The training tracks (``t, x, y, psi, delta_r, n``; ``u, v, r`` when measured; ``wind_*``
        for the wind effect).
    options : FitOptions, default FitOptions()
        What is fitted and how: free coefficients, effects, window, step, iterations, seed,
        weighting, scored channels, start rule, multistart, prior
        (:class:`~bayesid.estimation.options.FitOptions`). With the vehicle file's ``[prior]``, a
        MAP fit follows the fit without it, whose data residuals count as ``1 / inflation``
        independent samples each (the AR(1) inflation of the first fit's residuals, at most the
        samples per window), and the covariance is the Laplace covariance of that posterior.
    calibration : CalibrationOptions or None, default CalibrationOptions()
        With 3 or more training runs, calibrate the predictive bands leave one run out
        (:func:`bayesid.estimation.calibration.leave_one_run_out`); None: no calibration.
    runner : Runner, default Runner()
        Runs the multistart's starts and the calibration's folds, and receives progress
        messages (:class:`bayesid.tasks.Runner`).

    Returns
    -------
    IdentifyResult
        The model, final fit, covariance, weights, scores, the step check
        (:mod:`bayesid.estimation.stepcheck`; with ``options.refine_step`` the fit is at the
        step it accepted) and (with 3 or more runs) the calibration.

    Raises
    ------
    ValueError
        No training track; a track that fails :func:`bayesid.data.validate.check_track` (units,
        conventions; named); a track without the needed columns (named); an unknown channel or a
        track that measures none of the channels; too little data
        (:func:`bayesid.estimation.windows.check_enough_data`).
    KeyError
        An unknown coefficient name.

    Warns
    -----
    TrackWarning
        Each warning of :func:`bayesid.data.validate.check_track` on a training track (what
        ``bayesid fit`` prints about its files).
    StepWarning
        The model step too coarse for the data (:attr:`~bayesid.estimation.stepcheck.StepCheck.too_coarse`)
        at the step the fit ends at.
    CovarianceWarning
        The fit's Laplace covariance cut directions the tracks do not determine, so its sds
        understate the uncertainty (:func:`bayesid.estimation.laplace.covariance_sentence`).
    PropulsionPointWarning
        Training runs at different propulsion points (:func:`bayesid.models.runs.training_points`).

    Examples
    --------
    Six linear sway and yaw coefficients of NPS AUV II fitted on two zigzags (track files written
    by ``bayesid simulate``, as in the quickstart, or your own logs):

    >>> import bayesid
    >>> vehicle = bayesid.load_any_vehicle("nps_auv2")
    >>> train = [bayesid.read_csv(f) for f in ("z10.csv", "z20.csv")]
    >>> options = bayesid.FitOptions(free=("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"), dt=0.1)
    >>> res = bayesid.identify(vehicle, train, options)
    >>> res.model.param_names
    ['Yv', 'Yr', 'Nv', 'Nr', 'Ydr', 'Ndr']
    >>> for name, value, sd in zip(res.model.param_names, res.fit.p, res.cov.diagonal() ** 0.5):
    ...     print(f"{name:4s} {value:+.5f} +- {sd:.5f}")  # doctest: +SKIP
    """
    if not train:
        raise ValueError("identify needs at least one training track")
    for tr in train:  # what the commands print about their files, as Python warnings
        for w in check_track(tr, vehicle):
            warnings.warn(in_api_terms(w), TrackWarning, stacklevel=2)
    say = runner.say
    channels = wf.check_channels(options.channels)
    dt, p_start, tried, first = options.dt, None, [], None
    while True:
        st = _fit_at_step(vehicle, train, options, channels, dt, p_start, runner)
        first = first or st  # its start, seed and multistart describe the fit's way in
        check = step_check(st.f, st.cov, st.problem, st.rebuild)
        tried.append(st.model.dt)
        if not (options.refine_step and check.too_coarse and len(tried) <= MAX_HALVINGS):
            break
        say(f"{check.sentence()}: refitting at {st.model.dt / 2:g} s")
        dt, p_start = st.model.dt / 2, st.f.p
    check.steps_tried = tried
    if check.too_coarse:
        warnings.warn(in_api_terms(check.sentence()), StepWarning, stacklevel=2)
    if covariance_sentence(st.post):
        warnings.warn(covariance_sentence(st.post), CovarianceWarning, stacklevel=2)
    points = training_points(st.model, st.f.p, train)
    if points is not None and points["apart"]:
        warnings.warn(points["sentence"], PropulsionPointWarning, stacklevel=2)
    model, f, gp, prior_info = st.model, st.f, st.gp, st.prior_info
    calib = None
    if calibration is not None and len(train) >= 3:
        rule_p, lead_p = start_settings(options.start, train, calibration.window_s, model.dt, None)
        say(f"calibration: leave one of {len(train)} runs out on {runner.where()}")
        scale = (prior_info["residual_variance"], prior_info["ar1_inflation"]) if gp is not None else None
        refit = dataclasses.replace(st.problem, prior=gp, data_scale=scale)
        calib = leave_one_run_out(refit, f, train, calibration, start=rule_p, leadin_s=lead_p, runner=runner)
    return IdentifyResult(
        model=model,
        fit=f,
        cov=st.cov,
        posterior=st.post,
        seed=first.seed_info,
        noise_sd=st.sd,
        fit_sd=st.problem.sd,
        weighting=st.weighting,
        channels=channels,
        start_rule=st.rule,
        train_scores=wf.scores(model, f, st.problem.ctxs),
        window_s=st.window_s,
        p0=first.p0,
        multistart=first.ms,
        prior=prior_info,
        calibration=calib,
        step_check=check,
        retimed_moves=st.retimed,
        nested_start=first.nested,
        training_points=points,
    )


@dataclass
class _Stage:
    """One fit of :func:`identify` at one model step: the model, its problem (with the prior of a
    MAP fit), the fit, its Laplace covariance and summaries, and ``rebuild(dt) -> (model,
    ctxs)`` for the step check."""

    model: object
    problem: wf.WindowProblem
    f: FitResult
    cov: np.ndarray
    post: dict
    gp: object
    prior_info: dict
    seed_info: dict
    sd: dict
    weighting: str
    rule: str
    window_s: float
    p0: np.ndarray
    ms: MultistartResult | None
    rebuild: object
    retimed: dict | None = None
    nested: dict | None = None


def _fit_at_step(vehicle, train, options: FitOptions, channels, dt, p_start, runner: Runner) -> _Stage:
    """The fit of :func:`identify` at the model step ``dt`` (None: the family's), from
    ``p_start`` (None: the nominal coefficients or the equation-error seed, and the multistart
    when asked for; given, the optimum at a coarser step, refitted alone)."""
    say = runner.say

    def make(step):
        return build_model(
            vehicle,
            options.free,
            options.effects,
            step,
            inputs=options.inputs,
            rudder_rate_deg_s=options.rudder_rate_deg_s,
        )

    model = make(dt)
    window_s = options.window_s if options.window_s is not None else model.default_fit_window(DEFAULT_WINDOW_S)
    for e in model.effects:
        bare = [t.name for t in train if not all(c in t for c in e.needs_columns)]
        if bare:
            raise ValueError(
                f"the {e.name} effect needs columns {' and '.join(e.needs_columns)}; track(s) "
                f"{', '.join(bare)} have none (leave --effects {e.name} out, or add the measured "
                f"{e.name})"
            )
    rule = resolve_start(options.start, train)
    ctxs = [model.context(t, window_s, start=rule) for t in train]
    wf.check_enough_data(model, ctxs, window_s)
    sd = wf.pooled_noise_sd(train)
    p0, seed_info = model.start(), {"used": False}
    if p_start is not None:
        p0 = np.asarray(p_start, float)
    elif options.equation_error_seed:
        p0, seed_info = _equation_error_start(model, ctxs, train, sd, channels)
        if seed_info.get("tried"):
            say(f"equation-error seed: {'used' if seed_info.get('used') else 'not used'}")
        seed_info.pop("tried", None)
    say(f"multiple-shooting fit (model step {model.dt:g} s)")
    weighting = options.weighting or model.DEFAULT_WEIGHTING
    problem = wf.WindowProblem(model, ctxs, sd, channels=channels, max_nfev=options.max_nfev)
    f, sd_fit = wf.fit_weighted(problem, p0, weighting=weighting, bar=runner.bar("fit"))
    problem = dataclasses.replace(problem, sd=sd_fit)
    nested = None
    if p_start is None:  # a refined step refits from the coarser step's optimum alone

        def without():
            m = build_model(
                vehicle,
                options.free,
                [e.name for e in model.effects if e.neutral is None],
                model.dt,
                inputs=options.inputs,
                rudder_rate_deg_s=options.rudder_rate_deg_s,
            )
            return m, [m.context(t, window_s, start=rule) for t in train]

        f, p0, nested = _keep_nested(problem, f, p0, without, runner)
    ms = None
    if options.starts and p_start is None:  # a refined step refits from the multistart's best
        say(f"multistart: {options.starts} more start(s) on {runner.where()}")
        f, ms = _multistart(problem, f, p0, options, runner)
    retiming = None
    if options.retime:
        moves = rt.moves_of(ctxs)
        if any(m.size for m in moves):
            say(f"retiming {sum(m.size for m in moves)} rudder movement(s) within single log intervals")
            p_rt, retiming = rt.fit_retimed(problem, f.p, moves, options.max_nfev, bar=runner.bar("retime"))
            f = wf.fit_model(problem, p_rt)  # the coefficients at the retimed inputs, with their Jacobian
    gp = wf.GaussianPrior.of_model(model) if options.prior else None
    if gp is not None and gp.idx.size:
        say(f"MAP fit with the vehicle file's priors on {len(gp.names)} coefficient(s)")
        f, cov, post, gp, prior_info = _map_fit(problem, f, gp, runner)
        checked = dataclasses.replace(problem, prior=gp)
    else:
        cov, post = fit_covariance(f, ctxs)
        gp, prior_info, checked = None, {"used": False}, problem
    retimed = None
    if retiming is not None:
        cov, post, retimed = _timing_covariance(f, ctxs, retiming, gp, prior_info)

    def rebuild(step):
        m = make(step)
        cs = [m.context(t, window_s, start=rule) for t in train]
        if retiming is not None:
            for c, lone in zip(cs, retiming.per_track()):
                c.retime(lone)
        return m, cs

    return _Stage(
        model,
        checked,
        f,
        cov,
        post,
        gp,
        prior_info,
        seed_info,
        sd,
        weighting,
        rule,
        window_s,
        p0,
        ms,
        rebuild,
        retimed,
        nested,
    )


def neutral_start(model, p0):
    """The start ``p0`` with every effect that has a catalogue ``neutral`` value at it (at
    neutral, such an effect leaves the model without it).

    Parameters
    ----------
    model : SimulationModel
        The model (``[theta_free, q_1, ..., q_E]``, :class:`~bayesid.models.interface.ParameterLayout`).
    p0 : array_like, shape (n_params,)
        A parameter vector.

    Returns
    -------
    ndarray, shape (n_params,) or None
        ``p0`` with those effects neutral; None when no effect has a neutral value.
    """
    p, i, any_neutral = np.array(p0, float), model.n_theta, False
    for e, n in zip(model.effects, model.n_q):
        if e.neutral is not None:
            p[i : i + n], any_neutral = e.neutral, True
        i += n
    return p if any_neutral else None


def _kept_positions(model) -> np.ndarray:
    """Indices of ``p`` that are not parameters of an effect with a ``neutral`` value."""
    idx, i = list(range(model.n_theta)), model.n_theta
    for e, n in zip(model.effects, model.n_q):
        if e.neutral is None:
            idx += range(i, i + n)
        i += n
    return np.asarray(idx, int)


def _keep_nested(problem: wf.WindowProblem, f: FitResult, p0, without, runner: Runner) -> tuple:
    """(fit, its start, summary) of a fit with effects that contain the model without them.

    An effect with a catalogue ``neutral`` value nests the model without it, so its fit should
    never end above that model's; but a fit from the effect's own start can stop in a worse
    optimum (``coupling_speed`` from MMG's ``c_U = 1`` on a KVLCC2 flown with the file's form:
    SSR 11465 against 11048 without the effect, ``tests/test_identify_nested_start.py``). The
    chain the gap diagnosis refits with (:mod:`bayesid.analysis.gap.candidates`) removes that:
    the model without those effects is fitted from the same coefficients, and the full model
    again from its optimum with the effects neutral, from which a descent method cannot end
    higher. The lower of that fit and ``f`` is kept, at the channel weights of ``problem``.

    Parameters
    ----------
    problem : WindowProblem
        The full model's problem (its final channel weights, no prior).
    f : FitResult
        Its fit from ``p0``.
    p0 : ndarray, shape (n_params,)
        That fit's start.
    without : callable
        ``without() -> (model, ctxs)``: the model without the nesting effects and its contexts.
    runner : Runner
        Receives the progress messages.

    Returns
    -------
    tuple
        ``(fit, start, summary)``; the summary (:attr:`IdentifyResult.nested_start`) is None and
        ``f`` is returned when no effect has a neutral value.
    """
    model = problem.model
    pn = neutral_start(model, p0)
    if pn is None:
        return f, p0, None
    names = [e.name for e in model.effects if e.neutral is not None]
    runner.say(f"the fit again without {', '.join(names)}, then with them from neutral at its optimum")
    keep = _kept_positions(model)
    base_model, base_ctxs = without()
    fb = wf.fit_model(
        dataclasses.replace(problem, model=base_model, ctxs=base_ctxs), pn[keep], bar=runner.bar("fit without")
    )
    pn[keep] = fb.p
    fn = wf.fit_model(problem, pn, bar=runner.bar("fit from neutral"))
    info = {
        "effects": names,
        "cost_without": float(fb.cost),
        "cost_effect_start": float(f.cost),
        "cost_neutral_start": float(fn.cost),
        "kept": "neutral" if fn.cost < f.cost else "effect start",
    }
    return (fn, pn, info) if fn.cost < f.cost else (f, p0, info)


def _timing_covariance(f: FitResult, ctxs, retiming, gp, prior_info: dict) -> tuple:
    """(covariance, Laplace summary, movement times) of a retimed fit: the fit's Jacobian with
    the movements' directions projected out (:func:`bayesid.estimation.retiming.project_timing`),
    so that the coefficients' covariance counts the times' uncertainty; the times per track with
    their sds, s (:meth:`~bayesid.estimation.retiming.Retiming.times`)."""
    sd_factor = rt.project_timing(f, retiming.jac)
    if gp is not None:
        s2, infl = prior_info["residual_variance"], prior_info["ar1_inflation"]
        cov, post = fit_covariance(f, ctxs, gp, (s2, infl))
        for name, i in zip(gp.names, gp.idx):
            prior_info["coefficients"][name]["posterior_sd"] = float(math.sqrt(max(cov[i, i], 0.0)))
    else:
        cov, post = fit_covariance(f, ctxs)
        s2, infl = post["residual_variance"], post["ar1_inflation"]
    return cov, post, retiming.times(ctxs, sd_factor * math.sqrt(s2 * infl))


def _equation_error_start(model, ctxs, train, sd, channels) -> tuple:
    """(start, seed summary) of a fit: the model's equation-error estimate (``model.seed``) when
    it simulates the training windows better than the nominal coefficients, else the nominal
    ones. The summary's ``tried`` says whether the family has a seed (None: it has none)."""
    p0 = model.start()
    try:
        seeded = model.seed(train)  # None: the model family has no equation-error seed
    except Exception as exc:  # noqa: BLE001 - reported; the fit starts from nominal
        seeded = (None, {"error": f"{type(exc).__name__}: {exc}"})
    if seeded is None:
        return p0, {"used": False}
    ps, info = seeded
    if ps is None:
        return p0, dict(info, tried=True)
    c_nom, c_seed = wf.window_residuals(
        model,
        ctxs,
        [wf.channel_weights(c, sd, channels) for c in ctxs],
        np.vstack([p0, ps]),
        [None] * len(ctxs),
    )[0]
    info["cost_nominal"], info["cost_seed"] = float(c_nom @ c_nom), float(c_seed @ c_seed)
    if info["cost_seed"] < info["cost_nominal"]:
        return ps, dict(info, used=True, tried=True)
    return p0, dict(info, used=False, tried=True)


def _multistart(problem: wf.WindowProblem, f: FitResult, p0, options: FitOptions, runner: Runner) -> tuple:
    """(best fit, :class:`MultistartResult`) of ``options.starts`` more starts besides the
    default fit ``f`` (:func:`bayesid.estimation.multistart.multistart`)."""
    dflt = {
        "p": f.p.tolist(),
        "cost": float(f.cost),
        "success": bool(f.success),
        "nfev": int(f.n_simulations),
        "message": str(f.message),
    }
    ms = multistart(
        problem, p0, options.starts, np.random.default_rng(options.random_seed), default_fit=dflt, runner=runner
    )
    if ms.best != 0:  # the best optimum again in this process, for its Jacobian (few evaluations)
        f = wf.fit_model(problem, np.asarray(ms.fits[ms.best]["p"]))
    return f, ms


def _map_fit(problem: wf.WindowProblem, f: FitResult, gp, runner: Runner) -> tuple:
    """The MAP fit with the vehicle file's Gaussian prior ``gp`` from the fit ``f`` without it:
    (fit, covariance, Laplace summary, the weighted prior, prior summary). The prior weighs
    against the data as a likelihood whose samples count 1 / inflation each (serially correlated
    residuals), with the residual variance of the fit without it."""
    model, ctxs = problem.model, problem.ctxs
    s2 = f.cost / max(f.n_residuals - model.n_params, 1)
    infl = ar1_inflation(f, ctxs)
    gp = wf.GaussianPrior(gp.names, gp.idx, gp.mean, gp.sd, math.sqrt(s2 * infl))
    f0 = f
    f = wf.fit_model(dataclasses.replace(problem, prior=gp), f.p, f.nuisance, bar=runner.bar("fit with prior"))
    cov, post = fit_covariance(f, ctxs, gp, (s2, infl))
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
    return f, cov, post, gp, prior_info
