"""Sim-to-real gap diagnosis: where the model misses, which unmodelled effect causes it, and
how far the gap shrinks once that effect is in the model.

:func:`diagnose` receives only tracks, the vehicle (nominal coefficients) and the names of the
free coefficients. It

1. fits the base model on the training tracks (simulation error over protocol windows that
   restart from the measured state -- multiple shooting; :func:`fit`);
2. **where**: residuals per channel, per operating region (drift angle, yaw rate, rudder angle,
   speed), per manoeuvre phase, their spectrum, the missing forces X, Y, N from inverse
   dynamics, Ljung-Box whiteness and cross-correlation with the inputs and their rates
   (:func:`where`);
3. **which**: refits the model with each catalogue effect in turn (the effect's parameters and
   all free coefficients) and ranks the candidates by held-out RMS position error, with the
   BIC difference on the training tracks and a sparse regression (pysindy STLSQ ensemble) of
   the missing forces on effect signatures as independent support. A candidate whose effect has
   a catalogue ``neutral`` value contains the model it extends; if its fits end worse than that
   model, it is refitted from that model's optimum with the effect neutral (so ΔBIC <= k ln n);
4. **how far**: the protocol's scores before and after the top effect, on the training and the
   held-out tracks: RMS and maximum position error, heading RMS, and the Gaussian log-likelihood
   of all scored channels at the fits' channel sds (:func:`scores`).

Window start states follow the protocol's start rule (:data:`bayesid.protocol.START_RULES`):
restarted from the measured state when u, v, r are logged, else fitted with the model being
scored (:mod:`bayesid.shooting`: a 10 s lead-in before each held-out window; the window starts
of the training fits as nuisance parameters). One rule serves every model compared and the floor.

Verdict rules (stated in the report):

* the gap is *significant* when the held-out RMS position error exceeds ``none_ratio`` (1.5)
  times the **noise floor**: the error a perfect model would show at the measured noise level,
  estimated by simulating a model (the fitted base model and the nominal one; the smaller
  result counts) on the held-out inputs, adding noise of the sd estimated from the data
  (:func:`bayesid.protocol.estimate_noise`, without the lower bound that the fit weights use),
  and scoring that with the same model and start rule;
* an effect is *the cause* when, added with all coefficients re-identified, the held-out error
  falls into the floor band (at most ``none_ratio`` x the floor), it removes at least
  ``explain_fraction`` (0.5) of the excess over the floor, ``(rms_ref - rms_effect) /
  (rms_ref - floor)``, and its ΔBIC on the training tracks is at most ``-10`` (strong evidence,
  Kass & Raftery 1995);
* an effect is a *contributor* when it improves the held-out windows without closing the gap:
  one-sided Wilcoxon signed-rank test of the paired per-window RMS position errors,
  ``p < partial_p`` (0.01; or at least ``explain_fraction`` of the excess removed, where too
  few windows leave the test without power), ΔBIC at most -10 and positive shrinkage. Its
  *share* is the part of the base model's excess it removes;
* greedy rounds (``max_effects``, default 2): the best-ranked cause is added and ends the
  search; else the best-ranked contributor is added and the next round refits every other
  candidate on top of it;
* verdict: ``"none"`` when the gap is not significant (candidates are still fitted and ranked,
  for the report, but none is attributed: on a gap barely above the floor a flexible candidate
  removes half of a small excess by fitting noise); else the effects added joined by ``+``,
  with ``+unexplained`` appended when the remainder is still significant (above the band), or
  ``"unexplained"`` alone when nothing helps -- a contributor is named as one, never as the
  cause. ``gap_after`` is the model with every effect added; ``remainder`` is what is left
  (fraction of the base excess, significant or not); ``contributors`` lists every effect that
  passed the contributor test (added or not) with its share, p-value, ΔBIC and parameters.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal, stats

from . import effects as ef
from . import shooting
from .protocol import CHANNELS, estimate_noise, pooled_scores, start_settings, wrap
from .track import STATE_NAMES, Track

PENALTY = 1e3  # residual (in noise sds) of a sample in a diverged window


class Fit:
    """A fitted :class:`~bayesid.effects.EffectModel`: parameters, per-track nuisances, cost."""

    def __init__(self, model, p, nuisance, ssr, n_res, nfev, success, message, seconds, jac=None,
                 channels=None, n_starts=0):
        self.model, self.p, self.nuisance, self.jac = model, p, nuisance, jac
        #: window start states fitted with the parameters (fitted start rule; 6 per window)
        self.n_starts = int(n_starts)
        #: channels in the objective (None: every scored channel the tracks measure)
        self.channels = None if channels is None else tuple(channels)
        self.ssr, self.n_res, self.nfev = ssr, n_res, nfev
        self.success, self.message, self.seconds = success, message, seconds

    @property
    def k(self) -> int:
        """Number of fitted parameters (coefficients, effect parameters, nuisances, window
        start states)."""
        return self.model.n_params + sum(len(v) for v in self.nuisance) + self.n_starts

    @property
    def bic(self) -> float:
        """Schwarz criterion ``SSR + k ln n`` of the noise-scaled residuals (Gaussian
        likelihood with the estimated sds; the constant is dropped)."""
        return float(self.ssr + self.k * math.log(max(self.n_res, 1)))

    def effect_parameters(self) -> dict:
        th, qs = self.model.split_params(self.p[None])
        out = {}
        for e, q in zip(self.model.effects, qs):
            out[e.name] = {p: float(v) for p, v in zip(e.params, q[0])}
            if e.n_nuisance:
                out[e.name]["per_track_nuisance"] = [float(v[0]) for v in self.nuisance]
        return out

    def coefficients(self) -> dict:
        return {n: float(v) for n, v in zip(self.model.free, self.p[:self.model.n_theta])}


def channel_weights(ctx, sd, channels=None):
    """{channel: 1/sd} over the channels of ``ctx`` in the objective (all when ``channels`` is
    None). Raises ValueError when the track measures none of ``channels``."""
    cs = [c for c in ctx.channels if channels is None or c in channels]
    if not cs:
        raise ValueError(f"track {ctx.name!r} measures none of the fitted channels {', '.join(channels)} "
                         f"(it has {', '.join(ctx.channels)})")
    return {c: 1.0 / sd[c] for c in cs}


def check_channels(channels):
    """``channels`` as a tuple (None stays None); ValueError naming a channel the protocol does not
    score (:data:`bayesid.protocol.CHANNELS`)."""
    if channels is None:
        return None
    channels = tuple(channels)
    bad = [c for c in channels if c not in CHANNELS]
    if bad or not channels:
        raise ValueError(f"unknown fit channel(s) {', '.join(bad) or '(none given)'}; "
                         f"choose from {', '.join(CHANNELS)}")
    return channels


def window_residuals(model, ctxs, wts, P, nus, starts=None):
    """(B, n_res) noise-scaled residuals over all tracks; ``starts``: per track the (B, W, 6)
    start offsets of the fitted start rule (None: the measured rule)."""
    out = []
    for i, (ctx, w, nu) in enumerate(zip(ctxs, wts, nus)):
        S = model.simulate(ctx, P, nu, starts=None if starts is None else starts[i])
        for c, e in ef.errors(ctx, S).items():
            if c not in w:
                continue
            r = e * w[c]
            r[~np.isfinite(r)] = PENALTY
            out.append(r)
    return np.concatenate(out, axis=1)


def fit(model: ef.EffectModel, ctxs, sd: dict, p0=None, nuisance0=None, max_nfev: int = 60,
        fit_nuisance_only: bool = False, channels=None, progress: str | None = None) -> Fit:
    """Least-squares fit of the model's parameters (and per-track nuisances) to tracks.

    Objective: sum over tracks, protocol windows, samples and scored channels of
    ``(prediction - measurement)^2 / sd^2`` (heading difference wrapped), i.e. simulation error
    over windows that restart from the measured state (multiple shooting). Solver: scipy
    ``least_squares`` (trust-region reflective) with a forward-difference Jacobian computed in
    one batched simulation of all perturbed parameter vectors.

    Parameters
    ----------
    ctxs : track contexts of ``model`` (:meth:`EffectModel.context`).
    sd : {channel: noise sd} used as weights.
    p0 : start (default :meth:`EffectModel.start`).   nuisance0 : per track (n_nuisance,).
    fit_nuisance_only : keep ``p0`` fixed and fit only the nuisances (held-out tracks).
    channels : the scored channels in the objective (default: all the tracks measure); the
        others still give the window start states.
    progress : a label to show a progress bar (tqdm, on stderr) of the evaluations with it.

    Contexts with the fitted start rule (:mod:`bayesid.shooting`) have their window start states
    estimated with the parameters (6 per window, counted in :attr:`Fit.k`), eliminated by
    variable projection; with the measured rule the windows restart from the measured state.

    Raises ValueError for an unknown channel or a track that measures none of ``channels``.
    """
    tic = time.perf_counter()
    p0 = model.start() if p0 is None else np.asarray(p0, float)
    nn = model.n_nuisance
    T = len(ctxs)
    nu0 = [np.zeros(nn) for _ in range(T)] if nuisance0 is None else [np.asarray(v, float) for v in nuisance0]
    lo, hi = model.bounds()
    sc = model.scales()
    nlo = np.concatenate([np.full(e.n_nuisance, e.nuisance_lo) for e in model.effects] or [np.zeros(0)])
    nhi = np.concatenate([np.full(e.n_nuisance, e.nuisance_hi) for e in model.effects] or [np.zeros(0)])
    free_p = not fit_nuisance_only
    channels = check_channels(channels)
    wts = [channel_weights(c, sd, channels) for c in ctxs]

    x0 = np.concatenate(([p0] if free_p else []) + nu0) if (free_p or nn) else p0
    xlo = np.concatenate(([lo] if free_p else []) + [nlo] * T)
    xhi = np.concatenate(([hi] if free_p else []) + [nhi] * T)
    xsc = np.concatenate(([sc] if free_p else []) + [np.ones(nn)] * T)
    fin = np.isfinite(xlo) & np.isfinite(xhi)
    span = np.where(fin, xhi - xlo, 0.0)
    x0 = np.where(fin, np.clip(x0, np.where(fin, xlo, 0.0) + 1e-9 * span, np.where(fin, xhi, 0.0) - 1e-9 * span), x0)
    nfev = [0]
    # Fitted start rule: the window start states are eliminated by variable projection
    # (bayesid.shooting): every evaluation fits them for its parameters (warm-started at the
    # last optimum); the Jacobian holds them at that optimum and projects their directions out
    # window by window (Kaufman), or, where they come from a lead-in rather than the fitted
    # samples themselves, re-fits them for every perturbed vector.
    vp = any(c.start == "fitted" for c in ctxs)
    last = {"x": None, "starts": [None] * T, "jd": [None] * T}

    def split_rows(X):
        P = X[:, :model.n_params] if free_p else np.repeat(p0[None], X.shape[0], 0)
        off = model.n_params if free_p else 0
        return P, [X[:, off + i * nn:off + (i + 1) * nn] if nn else None for i in range(T)]

    def fit_all_starts(P, nus, want_jac=False):
        out = []
        for i, ctx in enumerate(ctxs):
            if ctx.start != "fitted":
                out.append(None)
                continue
            s0 = last["starts"][i]
            s0 = None if s0 is None else np.repeat(s0[:1], P.shape[0], axis=0)
            res = shooting.fit_starts(model, ctx, P, nus[i], wts[i], starts0=s0, return_jacobian=want_jac)
            if want_jac:
                d, J, rwin = res
                last["jd"][i] = (J[:, 0].T, rwin)
                out.append(d)
            else:
                out.append(res)
        return out

    def fun_batch(X, starts=None):
        X = np.atleast_2d(X)
        nfev[0] += X.shape[0]
        P, nus = split_rows(X)
        if vp and starts is None:
            starts = fit_all_starts(P, nus)
        return window_residuals(model, ctxs, wts, P, nus, starts)

    def fun(x):
        if not vp:
            return fun_batch(x)[0]
        P, nus = split_rows(x[None])
        st = fit_all_starts(P, nus, want_jac=True)
        last["x"], last["starts"] = x.copy(), st
        return window_residuals(model, ctxs, wts, P, nus, st)[0]

    def jac(x):
        h = 1e-6 * np.maximum(xsc, 1e-8)
        sign = np.where(x + h > xhi, -1.0, 1.0)
        X = np.repeat(x[None], x.size + 1, axis=0)
        X[1:] += np.diag(sign * h)
        if not vp:
            R = fun_batch(X)
            return ((R[1:] - R[0]) / (sign * h)[:, None]).T
        if last["x"] is None or not np.array_equal(last["x"], x):
            fun(x)
        lead_in = any(c.start == "fitted" and c.lead_steps > 0 for c in ctxs)
        held = None if lead_in else [None if d is None else np.repeat(d, X.shape[0], axis=0) for d in last["starts"]]
        R = fun_batch(X, held)
        J = ((R[1:] - R[0]) / (sign * h)[:, None]).T
        if lead_in:
            return J
        r0 = 0
        for i, ctx in enumerate(ctxs):
            n_i = sum(ctx.meas[c].size for c in ctx.channels if c in wts[i])
            if ctx.start == "fitted":
                Jd, rwin = last["jd"][i]
                J[r0:r0 + n_i] = shooting.project_out(J[r0:r0 + n_i], Jd, rwin, ctx.W)
            r0 += n_i
        return J

    if x0.size == 0:
        r = fun(x0)
        return Fit(model, p0, [np.zeros(0)] * T, float(r @ r), r.size, 1, True, "nothing to fit",
                   time.perf_counter() - tic, channels=channels)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=max_nfev, desc=progress, unit=" evaluations", leave=True)
        plain_fun = fun

        def fun(x):  # noqa: F811 - the same objective, counted on the bar
            bar.update(1)
            return plain_fun(x)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = optimize.least_squares(fun, x0, jac=jac, bounds=(xlo, xhi), x_scale=xsc, method="trf",
                                         max_nfev=max_nfev, xtol=1e-8, ftol=1e-8)
    finally:
        if bar is not None:
            bar.close()
    P, nus = split_rows(res.x[None])
    r = fun(res.x)
    n_starts = sum(6 * c.W for c in ctxs if c.start == "fitted")
    return Fit(model, np.array(P[0]), [np.array(v[0]) if v is not None else np.zeros(0) for v in nus], float(r @ r),
               r.size, nfev[0], bool(res.success), str(res.message), time.perf_counter() - tic, jac=res.jac,
               channels=channels, n_starts=n_starts)


def heldout_nuisance(model, fitres: Fit, ctxs, sd: dict, n_grid: int = 8, max_nfev: int = 30) -> list:
    """Per-track nuisances (e.g. a wave phase) of tracks the fit did not see, with the fitted
    parameters held: each track starts from the best of ``n_grid`` values spread over the
    nuisance bounds (a phase has a local minimum every period), then :func:`fit` refines them.
    Returns a list (one (n_nuisance,) array per track)."""
    nn = model.n_nuisance
    lo = np.concatenate([np.full(e.n_nuisance, e.nuisance_lo) for e in model.effects])
    hi = np.concatenate([np.full(e.n_nuisance, e.nuisance_hi) for e in model.effects])
    grid = lo[None] + (np.arange(n_grid)[:, None] + 0.5) / n_grid * (hi - lo)[None]
    P = np.repeat(fitres.p[None], n_grid, axis=0)
    starts = []
    for ctx in ctxs:
        w = channel_weights(ctx, sd)
        st = [shooting.fit_starts(model, ctx, P, grid, w)] if ctx.start == "fitted" else None
        r = window_residuals(model, [ctx], [w], P, [grid], st)
        starts.append(grid[int(np.argmin(np.sum(r * r, axis=1)))].copy())
    return fit(model, ctxs, sd, fitres.p, starts, max_nfev=max_nfev, fit_nuisance_only=True).nuisance


def residual_sd(model, fitres: Fit, ctxs, floor: dict) -> dict:
    """Per-channel RMS of a fit's simulation residuals over the protocol windows of ``ctxs``
    (heading wrapped; diverged samples ignored), each at least ``floor[channel]``.

    Returns {channel: sd} in the channel's SI unit. Raises KeyError when ``floor`` lacks a
    scored channel."""
    acc = {}
    for i, ctx in enumerate(ctxs):
        nu = fitres.nuisance[i][None] if fitres.nuisance and len(fitres.nuisance[i]) else None
        S = shooting.simulate(model, ctx, fitres.p[None], nu)
        for c, e in ef.errors(ctx, S).items():
            acc.setdefault(c, []).append(e[0][np.isfinite(e[0])])
    return {c: max(float(np.sqrt(np.mean(np.concatenate(v) ** 2))) if sum(x.size for x in v) else 0.0, floor[c])
            for c, v in acc.items()}


def fit_weighted(model, ctxs, sd: dict, p0=None, nuisance0=None, max_nfev: int = 60,
                 weighting: str = "noise", channels=None, progress: str | None = None) -> tuple[Fit, dict]:
    """:func:`fit` with the channel weights chosen by ``weighting``.

    ``"noise"``: weights ``1/sd`` from the measurement noise (right when the model structure is
    right, as in the synthetic benchmark). ``"residual"``: two-step feasible generalised least
    squares -- a first fit with the noise weights, then the weights ``1/s_c`` with ``s_c`` the
    RMS simulation residual of channel ``c`` (:func:`residual_sd`, at least the noise sd) and a
    second fit from the first one's optimum. On real data the structural error of the
    simulation over a window dwarfs the sensor noise (KVLCC2: 0.19 m and 1.5 deg against 1 cm and
    0.01 deg); noise weights would then let the best-measured channel (heading) decide the fit.
    The maximum-likelihood estimate with an unknown error variance per channel has these
    weights at its optimum (e.g. Ljung 1999, "System Identification", Sec. 7.3 and 15.2).

    ``channels`` restricts the objective to those scored channels (:func:`fit`); ``progress``
    labels a progress bar of each stage.

    Returns (fit, the sd dict of its weights). Raises ValueError on an unknown ``weighting``.
    """
    if weighting not in ("noise", "residual"):
        raise ValueError(f"weighting must be 'noise' or 'residual', not {weighting!r}")
    lab = (lambda k: None) if not progress else (lambda k: f"{progress} ({k})")
    f = fit(model, ctxs, sd, p0, nuisance0, max_nfev=max_nfev, channels=channels, progress=lab("noise weights"))
    if weighting == "noise":
        return f, dict(sd)
    sd2 = residual_sd(model, f, ctxs, sd)
    return fit(model, ctxs, sd2, f.p, f.nuisance if model.n_nuisance else None, max_nfev=max_nfev,
               channels=channels, progress=lab("residual weights")), sd2


def scores(model, fitres: Fit, ctxs, nuisance=None, sd: dict | None = None) -> dict:
    """Protocol scores of a fitted model on tracks (pooled over windows and tracks).

    With ``sd`` ({channel: sd}, SI) also ``log_likelihood`` (nats): the Gaussian log-density
    of every finite error of every scored channel, ``sum(-e^2 / (2 sd^2) - ln(sd sqrt(2 pi)))``,
    treating the samples as independent -- a relative measure (before vs after an effect, same
    sds and samples), not a calibrated one: simulation errors are correlated in time.
    Raises KeyError when ``sd`` lacks a scored channel."""
    errs, per_track = [], {}
    ll = 0.0
    for i, ctx in enumerate(ctxs):
        nu = None if nuisance is None else nuisance[i][None]
        S = shooting.simulate(model, ctx, fitres.p[None], nu)
        e = {k: v[0] for k, v in ef.errors(ctx, S).items()}
        errs.append(e)
        per_track[ctx.name] = pooled_scores([e])["rms_position_m"]
        if sd is not None:
            for c, v in e.items():
                v = v[np.isfinite(v)]
                ll += float(-0.5 * np.sum((v / sd[c]) ** 2) - v.size * math.log(sd[c] * math.sqrt(2 * math.pi)))
    out = pooled_scores(errs)
    out["per_track_rms_position_m"] = per_track
    if sd is not None:
        out["log_likelihood"] = ll
    return out


def window_rms(model, fitres: Fit, ctxs, nuisance=None) -> np.ndarray:
    """(n_windows,) RMS horizontal position error (m) of every protocol window of ``ctxs``
    (tracks in order, windows in time order; NaN for a window without a finite sample)."""
    out = []
    for i, ctx in enumerate(ctxs):
        nu = None if nuisance is None else nuisance[i][None]
        e = ef.errors(ctx, shooting.simulate(model, ctx, fitres.p[None], nu))
        pos2 = e["x"][0] ** 2 + e["y"][0] ** 2
        for w in range(ctx.W):
            v = pos2[(ctx.win == w) & np.isfinite(pos2)]
            out.append(float(np.sqrt(v.mean())) if v.size else np.nan)
    return np.array(out)


def paired_window_test(before: np.ndarray, after: np.ndarray) -> float:
    """One-sided p-value that the per-window errors ``after`` are smaller than ``before``
    (Wilcoxon signed-rank test on the paired windows; 1.0 with fewer than 6 pairs)."""
    ok = np.isfinite(before) & np.isfinite(after) & (before != after)
    if ok.sum() < 6:
        return 1.0
    return float(stats.wilcoxon(before[ok], after[ok], alternative="greater").pvalue)


def _gap_summary(train: dict, held: dict) -> dict:
    return {"train_rms_m": train["rms_position_m"], "heldout_rms_m": held["rms_position_m"],
            "heldout_max_m": held["max_position_m"], "heading_rms_deg": held["rms_heading_deg"],
            "train_heading_rms_deg": train["rms_heading_deg"],
            "train_log_likelihood": train.get("log_likelihood"), "heldout_log_likelihood": held.get("log_likelihood"),
            "heldout_rms_by_channel": held["rms"]}


# ---------------------------------------------------------------------------------------------
# Where
# ---------------------------------------------------------------------------------------------
def ljung_box(x, lags: int = 10) -> tuple[float, float]:
    """Ljung-Box Q statistic and p-value of a series (Ljung & Box 1978, Biometrika 65(2))."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)] - np.nanmean(x)
    n = x.size
    if n <= lags + 1 or not np.any(x):
        return float("nan"), float("nan")
    ac = np.array([np.sum(x[k:] * x[:n - k]) for k in range(lags + 1)]) / np.sum(x * x)
    q = n * (n + 2) * np.sum(ac[1:] ** 2 / (n - np.arange(1, lags + 1)))
    return float(q), float(stats.chi2.sf(q, lags))


def _missing_forces(model, fitres, track: Track):
    """Missing X, Y, N (N, N m) over time: rigid-body inverse dynamics of the smoothed measured
    motion minus the fitted model's hydrodynamic forces (pysindy smoothed differentiation as in
    :func:`bayesid.sindy.estimate_motion`). Returns (motion dict, F (n, 3))."""
    from . import sindy

    if hasattr(model, "missing_forces"):  # a model with its own inverse dynamics (bayesid.ship)
        return model.missing_forces(fitres, track)
    veh = model.vehicle.with_coefficients(fitres.coefficients()) if model.free else model.vehicle
    motion = sindy.estimate_motion(track)
    inputs = sindy.track_inputs(track)
    known = [t for t in sindy.horizontal_terms("X") + sindy.horizontal_terms("Y") + sindy.horizontal_terms("N")
             if veh.coefficients.get(t, 0.0) != 0.0]
    known = sorted(set(known) | set(sindy.ADDED_MASS))
    F = sindy.force_targets(motion, veh, inputs, known=known)
    return motion, F, inputs


def signature_columns(motion, inputs, track: Track, vehicle, omega=None) -> dict:
    """Force-space signatures of the catalogue effects, {effect: (n, 3) columns for X, Y, N}:
    the shape of the force each effect leaves in the inverse-dynamics residual. Sensor bias has
    none (it acts on the measurements, not the forces)."""
    u, v, r = motion["u"], motion["v"], motion["r"]
    t = motion["t"]
    psi = np.interp(t, track.t, np.unwrap(track["psi"]))
    n = t.size
    dr = np.interp(t, track.t, inputs[:, 0])
    drdot = np.gradient(dr, t)
    rpm = np.interp(t, track.t, inputs[:, 3])
    uc = vehicle.propulsion.uc_per_omega * rpm * 2 * math.pi / 60
    q = 0.5 * vehicle.rho * vehicle.L ** 2
    cols = {
        "current": [np.column_stack([u * np.cos(psi), u * np.cos(psi), u * np.cos(psi)]),
                    np.column_stack([u * np.sin(psi), u * np.sin(psi), u * np.sin(psi)])],
        "actuator": [np.column_stack([u * u * drdot] * 3)],
        "thrust": [np.column_stack([q * uc * np.abs(uc), np.zeros(n), np.zeros(n)])],
        "crossflow": [np.column_stack([np.zeros(n), v * np.abs(v), v * np.abs(v)]),
                      np.column_stack([np.zeros(n), r * np.abs(r), r * np.abs(r)])],
    }
    if "phi" in track and np.isfinite(track["phi"]).all():
        phi = np.interp(t, track.t, track["phi"])
        cols["roll"] = [np.column_stack([phi * u * r, phi * u * u, phi * u * u])]
    if omega:
        cols["waves"] = [np.column_stack([np.sin(omega * (t - t[0]))] * 3),
                         np.column_stack([np.cos(omega * (t - t[0]))] * 3)]
    return cols


def signature_regression(F_list, cols_list, rng, n_models: int = 50, threshold: float = 0.1) -> dict:
    """Ensemble STLSQ (pysindy; Fasel et al. 2022) of the missing forces on the effect
    signatures. Columns and target are RMS-normalised per equation; an effect's inclusion
    probability is the largest over its columns and equations. Returns {effect: probability}."""
    import pysindy as ps
    from threadpoolctl import threadpool_limits

    from .sindy import legacy_seed

    effects = list(cols_list[0])
    prob = {e: 0.0 for e in effects}
    for eq in range(3):
        y = np.concatenate([F[:, eq] for F in F_list])
        X, owner = [], []
        for e in effects:
            for c in range(len(cols_list[0][e])):
                X.append(np.concatenate([cl[e][c][:, eq] for cl in cols_list]))
                owner.append(e)
        X = np.column_stack(X)
        ry = np.sqrt(np.mean(y ** 2))
        rx = np.sqrt(np.mean(X ** 2, axis=0))
        live = rx > 1e-12 * max(rx.max(), 1e-300)
        if ry == 0 or not live.any():
            continue
        Xn = X[:, live] / rx[live]
        stl = ps.STLSQ(threshold=threshold, alpha=0.0, normalize_columns=False, unbias=True, max_iter=20)
        ens = ps.EnsembleOptimizer(stl, bagging=True, n_models=n_models, replace=True)
        with legacy_seed(rng), threadpool_limits(1), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ens.fit(Xn, y / ry)
        xi = np.array(ens.coef_list)[:, 0, :]
        p = np.mean(xi != 0.0, axis=0)
        own = [o for o, l in zip(owner, live) if l]
        for o, pi in zip(own, p):
            prob[o] = max(prob[o], float(pi))
    return prob


REGIONS = {
    "drift_angle_deg": [-90, -6, -2, 2, 6, 90],
    "yaw_rate_deg_s": [-30, -3, -1, 1, 3, 30],
    "rudder_deg": [-40, -15, -5, 5, 15, 40],
    "speed_mps": [0, 1.0, 1.5, 1.8, 10],
}


def where(model, fitres, ctxs, tracks, sd, floor_by_channel=None, nuisance=None) -> dict:
    """Where the fitted base model misses (see module docstring) on the tracks of ``ctxs``
    (usually the held-out ones). ``nuisance``: per-track nuisances of *these* tracks (None: the
    model has none; a fit's own nuisances belong to its training tracks and are never used
    here). Returns a JSON-able dict."""
    out = {"channels": {}, "regions": {}, "phases": {}, "spectrum": {}, "forces": {}, "whiteness": {},
           "input_correlation": {}}
    errs = []
    per_sample = []
    for i, ctx in enumerate(ctxs):
        nu = None if nuisance is None else nuisance[i][None]
        S = shooting.simulate(model, ctx, fitres.p[None], nu)
        e = {k: v[0] for k, v in ef.errors(ctx, S).items()}
        errs.append(e)
        tr = tracks[i]
        u, v, r = (np.asarray(tr[c], float)[ctx.idx] for c in ("u", "v", "r")) if all(
            c in tr for c in ("u", "v", "r")) else (S[0, :, 6], S[0, :, 7], S[0, :, 11])
        dr = np.asarray(tr["delta_r"], float)[ctx.idx]
        drate = np.gradient(dr, ctx.ts)
        pos = np.hypot(e["x"], e["y"])
        # growth rate of the position error: what goes wrong locally, not what accumulated
        growth = np.gradient(pos, ctx.ts)
        growth[np.r_[True, np.diff(ctx.win) != 0]] = np.nan
        row = dict(drift_angle_deg=np.degrees(np.arctan2(-v, u)), yaw_rate_deg_s=np.degrees(r),
                   rudder_deg=np.degrees(dr), speed_mps=np.hypot(u, v), pos=pos,
                   growth=growth, psi=np.degrees(e["psi"]), rudder_moving=np.abs(drate) > np.radians(0.5),
                   turning=np.abs(r) > np.radians(1.0))
        if hasattr(model, "where_samples"):
            row.update(model.where_samples(tr, ctx, S))
        per_sample.append(row)
    pooled = pooled_scores(errs)
    for c, val in pooled["rms"].items():
        fl = None if floor_by_channel is None else floor_by_channel.get(c)
        out["channels"][c] = {"rms": val, "noise_sd": sd.get(c), "floor_rms": fl,
                              "excess_ratio": (val / fl) if fl else None}
    out["channels"]["position"] = {"rms": pooled["rms_position_m"]}
    ex = {c: d["excess_ratio"] for c, d in out["channels"].items() if d.get("excess_ratio")}
    out["dominant_channel"] = max(ex, key=ex.get) if ex else None
    common = set.intersection(*(set(p) for p in per_sample))
    cat = {k: np.concatenate([p[k] for p in per_sample]) for k in per_sample[0] if k in common}
    best = (None, 0.0)
    regions = model.regions() if hasattr(model, "regions") else REGIONS
    for reg, edges in regions.items():
        if reg not in cat:
            continue
        rows = []
        for a, b in zip(edges[:-1], edges[1:]):
            sel = (cat[reg] >= a) & (cat[reg] < b)
            g = cat["growth"][sel]
            g = g[np.isfinite(g)]
            rows.append({"bin": [a, b], "n": int(sel.sum()),
                         "rms_position_m": float(np.sqrt(np.mean(cat["pos"][sel] ** 2))) if sel.any() else None,
                         "mean_error_growth_mps": float(np.mean(np.abs(g))) if g.size else None,
                         "rms_heading_deg": float(np.sqrt(np.mean(cat["psi"][sel] ** 2))) if sel.any() else None})
        out["regions"][reg] = rows
        g_all = np.nanmean(np.abs(cat["growth"]))
        for row in rows:
            if row["mean_error_growth_mps"] and row["n"] >= 0.05 * cat["pos"].size:
                ratio = row["mean_error_growth_mps"] / g_all
                if ratio > best[1]:
                    best = (f"{reg} in [{row['bin'][0]}, {row['bin'][1]})", ratio)
    out["dominant_region"] = {"region": best[0], "growth_ratio": best[1]}
    phases = {"straight, rudder steady": (~cat["turning"]) & (~cat["rudder_moving"]),
              "turning, rudder steady": cat["turning"] & (~cat["rudder_moving"]),
              "rudder moving": cat["rudder_moving"]}
    for k, sel in phases.items():
        g = cat["growth"][sel]
        g = g[np.isfinite(g)]
        out["phases"][k] = {"fraction_of_time": float(sel.mean()),
                            "mean_error_growth_mps": float(np.mean(np.abs(g))) if g.size else None}
    # missing forces, spectrum, whiteness, input correlation (first track with velocities)
    Fs, cols, motions = [], [], []
    for i, tr in enumerate(tracks):
        try:
            motion, F, inputs = _missing_forces(model, fitres, tr)
        except Exception as exc:  # noqa: BLE001 - reported, not hidden
            out["forces"]["error"] = f"{type(exc).__name__}: {exc}"
            break
        Fs.append(F)
        motions.append((motion, inputs, tr))
    if Fs:
        Fcat = np.vstack(Fs)
        out["forces"] = {k: float(np.sqrt(np.mean(Fcat[:, j] ** 2))) for j, k in enumerate("XYN")}
        motion, inputs, tr = motions[0]
        t = motion["t"]
        fs = 1.0 / np.median(np.diff(t))
        for j, k in ((1, "Y"), (2, "N")):
            f, pxx = signal.welch(Fs[0][:, j] - Fs[0][:, j].mean(), fs=fs, nperseg=min(len(t), int(256 * fs / 2)))
            sel = f > 0.02
            kk = np.argmax(pxx[sel])
            out["spectrum"][k] = {"peak_period_s": float(1.0 / f[sel][kk]), "peak_frequency_hz": float(f[sel][kk]),
                                  "peak_to_median": float(pxx[sel][kk] / np.median(pxx[sel]))}
            dec = max(1, int(round(motion["window_s"] * fs)))
            qv, pv = ljung_box(Fs[0][::dec, j])
            out["whiteness"][k] = {"ljung_box_q": qv, "p_value": pv, "decimation": dec}
            corr = {}
            dr = np.interp(t, tr.t, inputs[:, 0])
            for name, sig in (("delta_r", dr), ("delta_r_rate", np.gradient(dr, t))):
                a = (sig - sig.mean())
                b = Fs[0][:, j] - Fs[0][:, j].mean()
                den = np.sqrt(np.sum(a * a) * np.sum(b * b))
                if den > 0:
                    cc = signal.correlate(b, a, mode="full") / den
                    lags = signal.correlation_lags(b.size, a.size) / fs
                    m = np.abs(lags) <= 10
                    kk = np.argmax(np.abs(cc[m]))
                    corr[name] = {"max_abs_corr": float(abs(cc[m][kk])), "lag_s": float(lags[m][kk])}
            out["input_correlation"][k] = corr
        if hasattr(model, "signature_columns"):  # dependence of the missing forces on the apparent wind
            sig = [model.signature_columns(mo, inp, tr) for (mo, inp, tr) in motions]
            if all("wind" in c for c in sig):
                out["wind_correlation"] = {}
                for j, k in enumerate("XYN"):
                    a = np.concatenate([c["wind"][min(j, 2)][:, j] for c in sig])
                    b = Fcat[:, j]
                    out["wind_correlation"][k] = float(np.corrcoef(a, b)[0, 1]) if a.std() > 0 else None
        out["_force_arrays"] = (Fs, motions)
    return out


# ---------------------------------------------------------------------------------------------
# Diagnose
# ---------------------------------------------------------------------------------------------
def _noise_floor(model, fitres, ctxs, tracks, sd, rng, n_rep: int = 2) -> dict:
    """The protocol's error for a perfect model at the measured noise level: simulate the fitted
    model on each held-out track's inputs from its first measured state, add noise of sd ``sd``
    to every channel, re-run the protocol with the same model."""
    errs = []
    for ctx, tr in zip(ctxs, tracks):
        s_first = ctx.s_meas[0].copy()
        if ctx.start == "fitted":  # the first segment's start as the rule estimates it
            s_first[ef.START_INDEX] += shooting.fit_starts(model, ctx, fitres.p[None])[0, 0]
        whole = model.context(tr, None, s0=s_first)
        S = model.simulate(whole, fitres.p[None], measured_start=False)[0]
        for _ in range(n_rep):
            data = {k: np.asarray(tr[k], float).copy() for k in tr.data}
            for i, k in enumerate(STATE_NAMES):
                if k in tr:
                    vals = np.full(tr.n_samples, np.nan)
                    vals[whole.idx] = S[:, i] + rng.normal(0, sd.get(k, 0.0), whole.idx.size)
                    data[k] = wrap(vals) if k == "psi" else vals
            syn = Track(tr.t, data, name=tr.name)
            c2 = model.context(syn, ctx.window_s, start=ctx.start, leadin_s=ctx.leadin_s)
            S2 = shooting.simulate(model, c2, fitres.p[None])
            errs.append({k: v[0] for k, v in ef.errors(c2, S2).items()})
    return pooled_scores(errs)


def pooled_noise_sd(tracks, floor: bool = True) -> dict:
    """{channel: noise sd} pooled over tracks: the median over the tracks of
    :func:`bayesid.protocol.estimate_noise` of each scored channel (SI units; floored at
    :data:`bayesid.protocol.NOISE_FLOOR` unless ``floor`` is False)."""
    sds = {}
    for tr in tracks:
        for k, v in estimate_noise(tr, [c for c in CHANNELS if c in tr], floor=floor).items():
            sds.setdefault(k, []).append(v)
    return {k: float(np.median(v)) for k, v in sds.items()}


def _wave_seed(F_list, motions, model, fitres) -> tuple[float, list]:
    """omega and per-track phases from the missing sway force's periodogram."""
    F = F_list[0][:, 1]
    t = motions[0][0]["t"]
    fs = 1.0 / np.median(np.diff(t))
    f, pxx = signal.periodogram(F - F.mean(), fs=fs)
    sel = (2 * np.pi * f >= 0.25) & (2 * np.pi * f <= 2.4)
    omega = float(2 * np.pi * f[sel][np.argmax(pxx[sel])])
    phases, amps = [], []
    for Fi, (mo, _, _) in zip(F_list, motions):
        tt = mo["t"] - mo["t"][0]
        A = np.column_stack([np.sin(omega * tt), np.cos(omega * tt)])
        sol = np.linalg.lstsq(A, Fi[:, [0, 1, 2]], rcond=None)[0]
        a, b = sol[:, 1]
        phases.append(math.atan2(b, a))
        amps.append(sol[0] * np.cos(phases[-1]) + sol[1] * np.sin(phases[-1]))
    amp = np.median(np.array(amps), axis=0)
    return omega, phases, amp


def _current_seed(model, fitres, ctxs) -> np.ndarray:
    """Earth-frame drift (m/s) that best explains the base model's position errors in the
    windows: measured - predicted ~ V_c t_rel (least squares through the window starts)."""
    num, den = np.zeros(2), 0.0
    for ctx in ctxs:
        e = ef.errors(ctx, shooting.simulate(model, ctx, fitres.p[None]))
        num -= np.array([np.nansum(e["x"][0] * ctx.t_rel), np.nansum(e["y"][0] * ctx.t_rel)])
        den += float(np.sum(ctx.t_rel ** 2))
    return num / den if den > 0 else np.zeros(2)


def _candidate_starts(name, model, base_theta, seeds):
    """Start vectors (list of (p0, nuisance0)) for a candidate fit: from the base fit's
    coefficients and from the nominal ones (the base fit may have bent the coefficients to
    absorb the effect, a local minimum for the candidate), plus effect-specific seeds."""
    out = []
    for th in (base_theta, None):
        out += _effect_starts(name, model, th, seeds)
    return out


def _effect_offset(model, name) -> int:
    """Index of effect ``name``'s first parameter in the model's parameter vector."""
    k = [e.name for e in model.effects].index(name)
    return model.n_theta + sum(model.n_q[:k])


def _effect_starts(name, model, base_theta, seeds):
    p = model.start(base_theta)
    i = _effect_offset(model, name)  # the effect need not be the model's first (greedy rounds)
    if name == "waves" and seeds.get("waves"):
        omega, phases, amp = seeds["waves"]
        p = p.copy()
        p[i:i + 4] = [omega, amp[0], amp[1], amp[2]]
        nn = model.n_nuisance  # the phase is the last nuisance (waves is the only effect with one)
        return [(p, [np.r_[np.zeros(nn - 1), ph] for ph in phases])]
    if name == "current" and "current" in seeds:
        p = p.copy()
        p[i:i + 2] = np.clip(seeds["current"], -1.4, 1.4)
        return [(p, None)]
    if name == "actuator":
        alt = p.copy()
        alt[i:i + 2] = [1.0, 5.0]
        return [(p, None), (alt, None)]
    if name == "delay":
        alt = p.copy()
        alt[i] = 1.5
        return [(p, None), (alt, None)]
    return [(p, None)]


def _nested_start(model, ref_model, ref_fit, name):
    """(p0, nuisance0) of ``model`` (= ``ref_model`` plus effect ``name`` appended last) at the
    reference fit's optimum with the new effect at its catalogue ``neutral`` value, where the
    model reproduces the reference model; None when the effect does not nest it."""
    e = next(e for e in model.effects if e.name == name)
    if e.neutral is None:
        return None
    return np.concatenate([ref_fit.p, np.asarray(e.neutral, float)]), _extended_nuisance(model, ref_model, ref_fit)


def _extended_nuisance(model, ref_model, ref_fit):
    """The reference fit's per-track nuisances padded with zeros for ``model``'s extra ones
    (None when ``model`` has none)."""
    if not model.n_nuisance:
        return None
    return [np.concatenate([np.asarray(v, float), np.zeros(model.n_nuisance - ref_model.n_nuisance)])
            for v in ref_fit.nuisance]


@dataclass
class _Stage:
    """A model of the greedy rounds: the model, its fit on the training tracks, its training and
    held-out scores (:func:`scores`) and its held-out nuisances."""

    model: object
    fit: Fit
    train: dict
    held: dict
    nuisance: list | None


def _is_cause(r, significant, band, explain_fraction, bic_threshold) -> bool:
    """The effect closes the gap: held-out error inside the noise-floor band, at least
    ``explain_fraction`` of the excess removed, ΔBIC at most ``bic_threshold``."""
    return bool(significant and r["heldout_rms_m"] <= band and r["excess_removed"] >= explain_fraction
                and r["delta_bic"] <= bic_threshold)


def _is_contributor(r, significant, explain_fraction, bic_threshold, partial_p) -> bool:
    """The effect improves the held-out windows without closing the gap: paired window test
    p < ``partial_p`` (or at least ``explain_fraction`` of the excess removed, where too few
    windows make the test powerless), ΔBIC at most ``bic_threshold``, positive shrinkage."""
    return bool(significant and r["delta_bic"] <= bic_threshold and r["heldout_shrinkage"] > 0
                and (r["window_p_value"] < partial_p or r["excess_removed"] >= explain_fraction))


def _contribution(r, added: bool) -> dict:
    return {"effect": r["effect"], "added": added, "share_of_excess": r["share_of_excess"],
            "heldout_rms_m": r["heldout_rms_m"], "window_p_value": r["window_p_value"],
            "delta_bic": r["delta_bic"], "parameters": r["parameters"]}


#: Least scored samples per estimated parameter a fit accepts (each sample has 3-6 channels).
MIN_SAMPLES_PER_PARAMETER = 10


def check_enough_data(model, ctxs, window_s: float) -> None:
    """Refuse (ValueError, naming the tracks) a fit whose training tracks are too short to say
    anything: fewer scored samples than :data:`MIN_SAMPLES_PER_PARAMETER` per parameter, or
    tracks that together last less than one fit window."""
    n = sum(int(c.ts.size) for c in ctxs)
    span = sum(float(c.ts[-1] - c.t_start[0]) if c.ts.size else 0.0 for c in ctxs)
    k = model.n_params
    names = ", ".join(f"track {c.name!r}" for c in ctxs)
    if n < MIN_SAMPLES_PER_PARAMETER * k:
        raise ValueError(f"training {names}: {n} scored samples for {k} parameters (need at least "
                         f"{MIN_SAMPLES_PER_PARAMETER * k}); give longer or more tracks, or fewer --free")
    if span < window_s:
        raise ValueError(f"training {names} last {span:.3g} s in all, less than one {window_s:g} s fit "
                         "window; give longer tracks or a shorter --window")


def diagnose(vehicle, free, train: list, heldout: list, candidates=None, window_s: float | None = 60.0,
             dt: float = 0.5, mode: str = "horizontal", rng=None, max_nfev: int = 60,
             none_ratio: float = 1.5, explain_fraction: float = 0.5, bic_threshold: float = -10.0,
             max_effects: int = 2, progress=None, fit_window_s: float | None = None,
             weighting: str | None = None, partial_p: float = 0.01, start: str = "auto",
             leadin_s: float | None = None, progress_bars: bool = False) -> dict:
    """Diagnose the sim-to-real gap of a base model (see the module docstring).

    Parameters
    ----------
    vehicle : nominal vehicle.   free : coefficient names the fits change.
    train, heldout : lists of Tracks (disjoint; ValueError if a track object or name repeats).
    candidates : effect names (default: the whole :data:`~bayesid.effects.CATALOGUE`).
    window_s : protocol window (s) of the held-out scores, None = whole run.   dt : model step (s).
    fit_window_s : window of the multiple-shooting fits on the training tracks (default: for a
        ship :data:`bayesid.ship.FIT_WINDOW_S`, whatever the scoring window; for a submarine
        ``window_s``).
    vehicle : a submarine :class:`~bayesid.vehicle.Vehicle` (candidates from
        :data:`bayesid.effects.CATALOGUE`) or a :class:`bayesid.ship.Ship` (candidates from
        :data:`bayesid.ship.SHIP_CATALOGUE`).
    rng : numpy Generator (noise-floor simulation, bootstrap of the signature regression).
    max_effects : greedy rounds (default 2: after a contributor, try the others on top of it;
        a cause ends the search; module docstring).
    weighting : channel weights of the fits (:func:`fit_weighted`): ``"noise"`` or
        ``"residual"``; default ``"residual"`` for a ship (real data, where the structural error
        dominates) and ``"noise"`` for a submarine. The base fit sets the weights; every
        candidate is fitted with the same weights, so their costs and BICs compare.
    partial_p : level of the paired per-window test of a contributor (module docstring).
    start : window start-state rule (:data:`bayesid.protocol.START_RULES`; ``"auto"``: fitted when
        a track lacks a logged u, v or r). The same rule serves every model compared, the
        training fits (fitted: start states estimated with the parameters) and the noise floor.
    progress_bars : show a progress bar (tqdm) of the evaluations of every fit.
    leadin_s : lead-in of the fitted rule on the held-out tracks (s; default
        :func:`bayesid.protocol.start_settings`: 10 s or 25 samples of the slowest log, at most
        the window).

    Returns
    -------
    dict with ``verdict``, ``cause``, ``contributors``, ``remainder``, ``effects_added``,
    ``ranking``, ``gap_before``, ``gap_after``, ``where``, ``noise_floor``, ``base_fit``,
    ``thresholds`` ... (JSON-able).

    Raises
    ------
    ValueError : empty or overlapping track sets; unknown coefficient or effect (named).
    """
    t_start = time.perf_counter()
    rng = np.random.default_rng(0) if rng is None else rng
    if not train or not heldout:
        raise ValueError("diagnose needs at least one training and one held-out track")
    names_t, names_h = [t.name for t in train], [t.name for t in heldout]
    overlap = set(names_t) & set(names_h)
    if overlap or any(a is b for a in train for b in heldout):
        raise ValueError(f"training and held-out tracks overlap: {sorted(overlap)}")
    from . import ship as sh

    is_ship = isinstance(vehicle, sh.Ship)
    catalogue, getter = (sh.SHIP_CATALOGUE, sh.get_effect) if is_ship else (ef.CATALOGUE, ef.get)
    cands = list(catalogue) if candidates is None else list(candidates)
    for c in cands:
        getter(c)
    say = progress or (lambda msg: None)
    sd = pooled_noise_sd(train + heldout)

    fw = fit_window_s if fit_window_s is not None else (sh.FIT_WINDOW_S if is_ship else window_s)
    rule, lead = start_settings(start, train + heldout, window_s, dt, leadin_s)

    def build(effects):
        m = sh.ShipModel(vehicle, free, effects, dt=dt) if is_ship else ef.EffectModel(vehicle, free, effects,
                                                                                         mode=mode, dt=dt)
        return (m, [m.context(t, fw, start=rule) for t in train],
                [m.context(t, window_s, start=rule, leadin_s=lead) for t in heldout])

    weighting = weighting or ("residual" if is_ship else "noise")
    base, ctr, cho = build(())
    check_enough_data(base, ctr, fw if fw is not None else max(c.ts[-1] - c.t_start[0] for c in ctr))
    say("base fit")
    bar = (lambda label: label) if progress_bars else (lambda label: None)
    bfit, sd_fit = fit_weighted(base, ctr, sd, max_nfev=max_nfev, weighting=weighting, progress=bar("base fit"))
    b_train, b_held = scores(base, bfit, ctr, sd=sd_fit), scores(base, bfit, cho, sd=sd_fit)
    # A base fit bent by the missing effect can be more sensitive to start-state errors than
    # the vehicle is; the floor is the smaller of the fitted and the nominal model's.
    nominal = Fit(base, base.start(), [np.zeros(0)] * len(train), 0.0, 0, 0, True, "nominal", 0.0)
    # the noise itself, not the weights' lower bound (a 1 mm carriage track is not 1 cm noise)
    sd_raw = pooled_noise_sd(train + heldout, floor=False)
    floor = min((_noise_floor(base, f, cho, heldout, sd_raw, rng) for f in (bfit, nominal)),
                key=lambda d: d["rms_position_m"])
    w = where(base, bfit, cho, heldout, sd, floor_by_channel=floor["rms"])
    F_list, motions = w.pop("_force_arrays", (None, None))
    seeds = {"current": _current_seed(base, bfit, ctr)}
    try:  # wave frequency and per-track phases from the TRAINING tracks' missing forces
        tr_forces = [_missing_forces(base, bfit, t) for t in train]
        seeds["waves"] = _wave_seed([f[1] for f in tr_forces], [(f[0], f[2], t) for f, t in zip(tr_forces, train)],
                                    base, bfit)
    except Exception:  # noqa: BLE001 - no seed: the candidate starts from its catalogue values
        pass
    significant = b_held["rms_position_m"] > none_ratio * floor["rms_position_m"]
    band = none_ratio * floor["rms_position_m"]
    excess0 = b_held["rms_position_m"] - floor["rms_position_m"]
    ref_windows = window_rms(base, bfit, cho)  # per held-out window, of the model being extended
    ranking, rounds, chosen, roles = [], [], [], {}
    current = _Stage(base, bfit, b_train, b_held, None)
    for rnd in range(max(1, int(max_effects))):
        ref = current
        results, fits, win_of = [], {}, {}
        for name in cands:
            if name in chosen:
                continue
            say(f"round {rnd + 1}: {name}")
            m, ct, ch = build(chosen + [name])
            base_theta = ref.fit.p[:ref.model.n_theta]
            best = None
            for p0, nu0 in _candidate_starts(name, m, base_theta, seeds):
                # effects already chosen keep their fitted values as the start
                if chosen:
                    p0 = p0.copy()
                    p0[:ref.model.n_params] = ref.fit.p
                    if nu0 is None and ref.model.n_nuisance:
                        nu0 = _extended_nuisance(m, ref.model, ref.fit)
                try:
                    f = fit(m, ct, sd_fit, p0, nu0, max_nfev=max_nfev, progress=bar(f"round {rnd + 1}: {name}"))
                except Exception as exc:  # noqa: BLE001 - a failed candidate is reported
                    say(f"{name} failed: {exc}")
                    continue
                if best is None or f.ssr < best.ssr:
                    best = f
            nested = _nested_start(m, ref.model, ref.fit, name)
            if nested is not None and (best is None or best.ssr > ref.fit.ssr):
                # a candidate that nests the model it extends cannot fit worse than it: start
                # once more at that model's optimum with the new effect at its neutral value
                try:
                    f = fit(m, ct, sd_fit, *nested, max_nfev=max_nfev)
                    if best is None or f.ssr < best.ssr:
                        best = f
                except Exception as exc:  # noqa: BLE001
                    say(f"{name} (nested start) failed: {exc}")
            if best is None:
                continue
            nu_h = heldout_nuisance(m, best, ch, sd_fit) if m.n_nuisance else None
            s_tr, s_h = scores(m, best, ct, sd=sd_fit), scores(m, best, ch, nu_h, sd=sd_fit)
            win_of[name] = window_rms(m, best, ch, nu_h)
            p_win = paired_window_test(ref_windows, win_of[name])
            excess = ref.held["rms_position_m"] - floor["rms_position_m"]
            gain = ref.held["rms_position_m"] - s_h["rms_position_m"]
            results.append({"effect": name, "heldout_rms_m": s_h["rms_position_m"],
                            "train_rms_m": s_tr["rms_position_m"],
                            "delta_bic": best.bic - ref.fit.bic, "excess_removed": gain / excess if excess > 0 else 0.0,
                            "share_of_excess": gain / excess0 if excess0 > 0 else 0.0,
                            "heldout_shrinkage": 1 - s_h["rms_position_m"] / ref.held["rms_position_m"],
                            "parameters": best.effect_parameters()[name],
                            "heading_rms_deg": s_h["rms_heading_deg"], "window_p_value": p_win,
                            "nfev": best.nfev, "fit_seconds": best.seconds})
            fits[name] = _Stage(m, best, s_tr, s_h, nu_h)
        results.sort(key=lambda d: (not np.isfinite(d["heldout_rms_m"]), d["heldout_rms_m"]))
        for r in results:
            r["role"] = ("cause" if _is_cause(r, significant, band, explain_fraction, bic_threshold) else
                         "contributor" if _is_contributor(r, significant, explain_fraction, bic_threshold, partial_p)
                         else None)
        rounds.append(results)
        if rnd == 0:
            ranking = results
        # the best-ranked cause closes the gap; else the best-ranked contributor is added and the
        # next round looks for what explains the rest
        top = next((r for r in results if r["role"] == "cause"), None) or next(
            (r for r in results if r["role"] == "contributor"), None)
        if top is None:
            break
        chosen.append(top["effect"])
        roles[top["effect"]] = dict(top)
        current = fits[top["effect"]]
        ref_windows = win_of[top["effect"]]
        if current.held["rms_position_m"] <= band:
            break
    after = current
    remainder_sig = bool(significant and after.held["rms_position_m"] > band)
    if not significant:
        verdict = "none"
    else:
        verdict = "+".join(chosen + (["unexplained"] if remainder_sig else [])) or "unexplained"
    # every effect that improves the held-out windows significantly without closing the gap,
    # added or not (round 1 alone, or as added in its round)
    contributors = [_contribution(roles[e], added=True) for e in chosen if roles[e]["role"] == "contributor"]
    contributors += [_contribution(r, added=False) for r in ranking
                     if r["role"] == "contributor" and r["effect"] not in chosen]
    remainder = {"heldout_rms_m": after.held["rms_position_m"],
                 "fraction_of_excess": (after.held["rms_position_m"] - floor["rms_position_m"]) / excess0
                 if excess0 > 0 else 0.0, "significant": remainder_sig}
    # SINDy support on the missing forces
    support = {}
    if F_list:
        try:
            omega = seeds.get("waves", (None,))[0]
            cols = [base.signature_columns(mo, inp, tr) if is_ship else signature_columns(mo, inp, tr, vehicle, omega)
                    for (mo, inp, tr) in motions]
            cols = [{k: v for k, v in c.items() if k in cands} for c in cols]
            support = signature_regression(F_list, cols, rng)
        except Exception as exc:  # noqa: BLE001
            support = {"error": f"{type(exc).__name__}: {exc}"}
    res = {
        "verdict": verdict,
        "effects_added": chosen,
        "cause": next((e for e in chosen if roles[e]["role"] == "cause"), None),
        "contributors": contributors,
        "remainder": remainder,
        "ranking": ranking,
        "rounds": rounds,
        "gap_before": _gap_summary(b_train, b_held),
        "gap_after": _gap_summary(after.train, after.held),
        "heldout_shrinkage": 1 - after.held["rms_position_m"] / b_held["rms_position_m"],
        "noise_floor": {"heldout_rms_m": floor["rms_position_m"], "heading_rms_deg": floor["rms_heading_deg"],
                        "by_channel": floor["rms"]},
        "gap_ratio": b_held["rms_position_m"] / floor["rms_position_m"],
        "significant_gap": bool(significant),
        "where": w,
        "sindy_support": support,
        "noise_sd": sd,
        "fit_sd": sd_fit,
        "base_fit": {"coefficients": bfit.coefficients(), "nominal": dict(zip(base.free, base.theta0.tolist())),
                     "bic": bfit.bic, "n_residuals": bfit.n_res, "success": bfit.success, "nfev": bfit.nfev},
        "after_fit": {"coefficients": after.fit.coefficients(), "effects": after.fit.effect_parameters()},
        "train_tracks": names_t, "heldout_tracks": names_h,
        "settings": {"free": list(free), "candidates": cands, "window_s": window_s,
                     "fit_window_s": fw, "dt": dt, "mode": mode, "start_rule": rule, "leadin_s": lead,
                     "max_nfev": max_nfev, "max_effects": max_effects, "weighting": weighting},
        "thresholds": {"none_ratio": none_ratio, "explain_fraction": explain_fraction,
                       "bic_threshold": bic_threshold, "partial_p": partial_p},
        "seconds": time.perf_counter() - t_start,
    }
    res["_curves"] = {"base": (base, bfit, None), "after": (after.model, after.fit, after.nuisance)}
    return res


def window_xy(model, fitres, track, window_s, nu=None, start="measured", leadin_s=0.0):
    """(measured (n, 2), predicted (n + W - 1, 2)) x, y of a track's protocol windows under a
    fitted model (``nu``: its per-track nuisance), NaN rows separating the windows (for plots)."""
    ctx = model.context(track, window_s, start=start, leadin_s=leadin_s)
    S = shooting.simulate(model, ctx, fitres.p[None], None if nu is None else nu[None])[0]
    xy = S[:, :2].copy()
    cut = np.flatnonzero(np.diff(ctx.win) != 0) + 1
    xy = np.insert(xy, cut, np.nan, axis=0)
    meas = np.column_stack([ctx.meas["x"], ctx.meas["y"]])
    return meas, xy


__all__ = ["Fit", "fit", "scores", "where", "diagnose", "ljung_box", "signature_columns",
           "signature_regression", "window_xy"]
