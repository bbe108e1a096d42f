"""*Where* a fitted model misses: residuals by channel, operating region and manoeuvre phase,
and the missing forces of inverse dynamics (spectrum, whiteness, correlation with the inputs).

Ljung & Box (1978), Biometrika 65(2) for the whiteness test; Welch periodogram (scipy.signal).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal, stats

from ...estimation.windows import Evaluation, evaluate
from ...models.runs import APPROACH_TOLERANCE, approach_row
from ...protocol import pooled_scores
from .records import ApproachCheck, ThrustCheck

__all__ = ["where", "approach_check", "ljung_box", "window_xy", "speed_from_positions", "SPEED_SPAN_S"]

#: Span of the local quadratic (Savitzky-Golay) whose slope reads the speed over ground from the
#: positions, s (:func:`speed_from_positions`): a few seconds, short against a turn's change of speed
#: (the KVLCC2 model loses its speed over some 30 s), long against the samples (at least 5 are used).
SPEED_SPAN_S = 5.0


def ljung_box(x, lags: int = 10) -> tuple[float, float]:
    """Ljung-Box Q statistic and p-value of a series (Ljung & Box 1978, Biometrika 65(2)).

    Parameters
    ----------
    x : array_like
        The series (non-finite values dropped, mean removed).
    lags : int, default 10
        Lags of the statistic.

    Returns
    -------
    q : float
        The Q statistic (NaN for a series too short or all zero).
    p_value : float
        Its chi-squared p-value (NaN likewise).
    """
    x = np.asarray(x, float)
    x = x[np.isfinite(x)] - np.nanmean(x)
    n = x.size
    if n <= lags + 1 or not np.any(x):
        return float("nan"), float("nan")
    ac = np.array([np.sum(x[k:] * x[: n - k]) for k in range(lags + 1)]) / np.sum(x * x)
    q = n * (n + 2) * np.sum(ac[1:] ** 2 / (n - np.arange(1, lags + 1)))
    return float(q), float(stats.chi2.sf(q, lags))


def where(evaluation: Evaluation, fitres, tracks, sd, floor_by_channel=None) -> tuple[dict, tuple | None]:
    """Where the fitted base model misses on the tracks of an evaluation (usually the held-out
    ones): residuals per channel (with the excess over the noise floor ``floor_by_channel``),
    per operating region (``model.regions()``, plus ``model.where_samples``), per manoeuvre
    phase (straight, turning, rudder moving), and, from the missing forces X, Y, N of inverse
    dynamics (``model.missing_forces``), their RMS, spectrum peak (Welch), Ljung-Box whiteness,
    cross-correlation with the rudder and its rate, and (ships with a measured wind) the
    correlation with the apparent-wind signature.

    Parameters
    ----------
    evaluation : Evaluation
        The fitted base model simulated once on the tracks' protocol windows
        (:func:`bayesid.estimation.windows.evaluate`; its nuisances are *these* tracks', never the
        fit's own, which belong to its training tracks).
    fitres : FitResult
        The fitted base model (its ``p`` is the evaluation's; read by the inverse dynamics).
    tracks : list of Track
        The tracks, parallel to the evaluation's contexts.
    sd : dict
        ``{channel: noise sd}``, SI.
    floor_by_channel : dict, optional
        ``{channel: RMS of the noise floor}``, SI.

    Returns
    -------
    summary : dict
        JSON-able: ``channels``, ``dominant_channel``, ``regions``, ``dominant_region``,
        ``phases``, ``forces``, ``spectrum``, ``whiteness``, ``input_correlation`` (and
        ``wind_correlation`` for ships with a measured wind; ``speed_from_positions``,
        :func:`speed_from_positions`, when the tracks do not log the speed u; ``thrust``,
        :func:`_thrust_check`, when they log the propeller's thrust).
    forces : tuple or None
        ``(F list (n, 3) per track, [(motion, inputs, track)])``, or None when inverse dynamics
        failed -- the error is then in the summary under ``forces``.
    """
    model = evaluation.model
    errs, per_sample = _per_sample(evaluation, tracks)
    pooled = pooled_scores(errs)
    channels = {}
    for c, val in pooled.rms.items():
        fl = None if floor_by_channel is None else floor_by_channel.get(c)
        channels[c] = {"rms": val, "noise_sd": sd.get(c), "floor_rms": fl, "excess_ratio": (val / fl) if fl else None}
    channels["position"] = {"rms": pooled.rms_position_m}
    speed = {}
    if "u" not in pooled.rms:  # no speed log: the speed over ground read from the positions
        sd_xy = [sd[c] for c in ("x", "y") if c in sd]
        if sd_xy:
            speed = {"speed_from_positions": speed_from_positions(evaluation, math.sqrt(np.mean(np.square(sd_xy))))}
    ex = {c: d.get("excess_ratio") for c, d in channels.items() if d.get("excess_ratio")}
    common = set.intersection(*(set(p) for p in per_sample))
    cat = {k: np.concatenate([p[k] for p in per_sample]) for k in per_sample[0] if k in common}
    regions, dominant_region = _regions(model.regions(), cat)
    found, extra, forces = _force_diagnostics(model, fitres, tracks)
    # the keys in the order diagnosis.json has always had them
    summary = {"channels": channels, "regions": regions, "phases": _phases(cat), **found, **speed}
    summary.update(dominant_channel=max(ex, key=ex.get) if ex else None, dominant_region=dominant_region, **extra)
    return summary, forces


def speed_from_positions(evaluation: Evaluation, position_sd: float, span_s: float = SPEED_SPAN_S) -> dict | None:
    """How far the fitted model misses the speed over ground, read from the positions where the
    speed is not logged: in every protocol window the slope of a local quadratic
    (Savitzky-Golay, ``span_s`` wide, at least 5 samples; Savitzky & Golay 1964, Anal. Chem.
    36(8)) of the measured and of the simulated x, y, and the difference of their magnitudes.

    The floor is the error a perfect model would show: the position noise through the same slope
    filter, ``position_sd * ||c||`` with ``c`` the filter's derivative coefficients (the simulated
    positions carry no noise). The speed over ground is what the surge equation X sets (with the
    current): a model that loses too much or too little speed in the turns misses it, while a
    heading or sway miss moves the positions across the track and leaves it (on the synthetic
    KVLCC2 runs of ``studies/ship_surge.py`` without a velocity log, 2 Hz, 2 cm: hidden X'vvvv,
    X'vvrr, tP and tR 2.8-7.0 x the floor; nothing hidden, the propulsion point the base fit
    absorbs and a hidden N'rrr 1.35-1.57 x, seeds 67 and 69).

    Parameters
    ----------
    evaluation : Evaluation
        The fitted model on the tracks' protocol windows.
    position_sd : float
        The noise sd of the logged x and y, m.
    span_s : float, default :data:`SPEED_SPAN_S`
        The filter's span, s.

    Returns
    -------
    dict or None
        ``rms`` (m/s, the RMS of the simulated minus the measured speed over ground over every
        sample of every window the filter spans), ``floor_rms`` (m/s, the sample-weighted RMS of
        the windows' noise floors), ``excess_ratio`` (``rms / floor_rms``), ``span_s`` and
        ``n_windows``; None when no window has 5 finite samples.
    """
    err, floor2, n_win = [], [], 0
    for ctx, S0 in zip(evaluation.ctxs, evaluation.states):
        mx, my = np.asarray(ctx.meas["x"], float), np.asarray(ctx.meas["y"], float)
        for w in range(ctx.W):
            sel = (ctx.win == w) & np.isfinite(mx) & np.isfinite(my) & np.isfinite(S0[:, 0])
            t = ctx.ts[sel]
            if t.size < 5:
                continue
            dt = float(np.median(np.diff(t)))
            if not dt > 0:
                continue
            n = max(5, int(round(span_s / dt)) | 1)
            if t.size < n:
                continue
            xy = np.column_stack([mx[sel], my[sel], S0[sel, 0], S0[sel, 1]])
            d = signal.savgol_filter(xy, n, 2, deriv=1, delta=dt, axis=0)
            meas, sim = np.hypot(d[:, 0], d[:, 1]), np.hypot(d[:, 2], d[:, 3])
            err.append(sim - meas)
            gain2 = float(np.sum(signal.savgol_coeffs(n, 2, deriv=1, delta=dt) ** 2))
            floor2.append(np.full(t.size, position_sd**2 * gain2))
            n_win += 1
    if not err:
        return None
    rms = float(np.sqrt(np.mean(np.concatenate(err) ** 2)))
    floor = float(np.sqrt(np.mean(np.concatenate(floor2))))
    return {
        "rms": rms,
        "floor_rms": floor,
        "excess_ratio": rms / floor if floor > 0 else None,
        "span_s": float(span_s),
        "n_windows": n_win,
    }


def _per_sample(evaluation: Evaluation, tracks) -> tuple[list, list]:
    """(per track {channel: errors}, per track {feature: per-sample values}) of the fitted
    model's protocol windows: drift angle, yaw rate, rudder, speed, position error, its growth
    rate, heading error, rudder moving, turning, and the model family's own features."""
    errs, per_sample = list(evaluation.errors), []
    for ctx, e, S0, tr in zip(evaluation.ctxs, evaluation.errors, evaluation.states, tracks):
        u, v, r = (
            (np.asarray(tr[c], float)[ctx.idx] for c in ("u", "v", "r"))
            if all(c in tr for c in ("u", "v", "r"))
            else (S0[:, 6], S0[:, 7], S0[:, 11])
        )
        dr = np.asarray(tr["delta_r"], float)[ctx.idx]
        drate = np.gradient(dr, ctx.ts)
        pos = np.hypot(e["x"], e["y"])
        # growth rate of the position error: what goes wrong locally, not what accumulated
        growth = np.gradient(pos, ctx.ts)
        growth[np.r_[True, np.diff(ctx.win) != 0]] = np.nan
        row = dict(
            drift_angle_deg=np.degrees(np.arctan2(-v, u)),
            yaw_rate_deg_s=np.degrees(r),
            rudder_deg=np.degrees(dr),
            speed_mps=np.hypot(u, v),
            pos=pos,
            growth=growth,
            psi=np.degrees(e["psi"]),
            rudder_moving=np.abs(drate) > np.radians(0.5),
            turning=np.abs(r) > np.radians(1.0),
        )
        row.update(evaluation.model.where_samples(tr, ctx, S0[None]))
        per_sample.append(row)
    return errs, per_sample


def _regions(regions: dict, cat: dict) -> tuple[dict, dict]:
    """(per region the binned RMS errors and error growth, the dominant region: the bin of the
    fastest mean error growth relative to the whole record, among bins of 5 % of the samples)."""
    out, best = {}, (None, 0.0)
    for reg, edges in regions.items():
        if reg not in cat:
            continue
        rows = []
        for a, b in zip(edges[:-1], edges[1:]):
            sel = (cat[reg] >= a) & (cat[reg] < b)
            g = cat["growth"][sel]
            g = g[np.isfinite(g)]
            rows.append(
                {
                    "bin": [a, b],
                    "n": int(sel.sum()),
                    "rms_position_m": float(np.sqrt(np.mean(cat["pos"][sel] ** 2))) if sel.any() else None,
                    "mean_error_growth_mps": float(np.mean(np.abs(g))) if g.size else None,
                    "rms_heading_deg": float(np.sqrt(np.mean(cat["psi"][sel] ** 2))) if sel.any() else None,
                }
            )
        out[reg] = rows
        g_all = np.nanmean(np.abs(cat["growth"]))
        for row in rows:
            if row["mean_error_growth_mps"] and row["n"] >= 0.05 * cat["pos"].size:
                ratio = row["mean_error_growth_mps"] / g_all
                if ratio > best[1]:
                    best = (f"{reg} in [{row['bin'][0]}, {row['bin'][1]})", ratio)
    return out, {"region": best[0], "growth_ratio": best[1]}


def _phases(cat: dict) -> dict:
    """Per manoeuvre phase (straight, turning, rudder moving) its share of the time and the mean
    error growth in it."""
    phases = {
        "straight, rudder steady": (~cat["turning"]) & (~cat["rudder_moving"]),
        "turning, rudder steady": cat["turning"] & (~cat["rudder_moving"]),
        "rudder moving": cat["rudder_moving"],
    }
    out = {}
    for k, sel in phases.items():
        g = cat["growth"][sel]
        g = g[np.isfinite(g)]
        out[k] = {
            "fraction_of_time": float(sel.mean()),
            "mean_error_growth_mps": float(np.mean(np.abs(g))) if g.size else None,
        }
    return out


def _force_diagnostics(model, fitres, tracks) -> tuple[dict, dict, tuple | None]:
    """The missing forces' RMS, spectrum, whiteness and input correlation (first track with
    velocities), the propeller against a logged thrust and the wind correlation: ``(found, extra,
    (forces, motions) or None)``, ``found`` with ``spectrum``, ``forces``, ``whiteness`` and
    ``input_correlation`` (empty, or ``forces`` with the ``error``, when inverse dynamics fails),
    ``extra`` with ``thrust`` and ``wind_correlation`` where they apply."""
    spectrum, forces, whiteness, input_corr, extra = {}, {}, {}, {}, {}
    Fs, motions = [], []
    for tr in tracks:
        try:
            motion, F, inputs = model.missing_forces(fitres, tr)
        except Exception as exc:  # noqa: BLE001 - reported, not hidden
            forces = {"error": f"{type(exc).__name__}: {exc}"}
            break
        Fs.append(F)
        motions.append((motion, inputs, tr))
    if Fs:
        Fcat = np.vstack(Fs)
        forces = {k: float(np.sqrt(np.mean(Fcat[:, j] ** 2))) for j, k in enumerate("XYN")}
        motion, inputs, tr = motions[0]
        t = motion["t"]
        fs = 1.0 / np.median(np.diff(t))
        for j, k in ((1, "Y"), (2, "N")):
            f, pxx = signal.welch(Fs[0][:, j] - Fs[0][:, j].mean(), fs=fs, nperseg=min(len(t), int(256 * fs / 2)))
            sel = f > 0.02
            kk = np.argmax(pxx[sel])
            spectrum[k] = {
                "peak_period_s": float(1.0 / f[sel][kk]),
                "peak_frequency_hz": float(f[sel][kk]),
                "peak_to_median": float(pxx[sel][kk] / np.median(pxx[sel])),
            }
            dec = max(1, int(round(motion["window_s"] * fs)))
            qv, pv = ljung_box(Fs[0][::dec, j])
            whiteness[k] = {"ljung_box_q": qv, "p_value": pv, "decimation": dec}
            corr = {}
            dr = np.interp(t, tr.t, inputs[:, 0])
            for name, sig in (("delta_r", dr), ("delta_r_rate", np.gradient(dr, t))):
                a = sig - sig.mean()
                b = Fs[0][:, j] - Fs[0][:, j].mean()
                den = np.sqrt(np.sum(a * a) * np.sum(b * b))
                if den > 0:
                    cc = signal.correlate(b, a, mode="full") / den
                    lags = signal.correlation_lags(b.size, a.size) / fs
                    m = np.abs(lags) <= 10
                    kk = np.argmax(np.abs(cc[m]))
                    corr[name] = {"max_abs_corr": float(abs(cc[m][kk])), "lag_s": float(lags[m][kk])}
            input_corr[k] = corr
        thrust = _thrust_check(model, fitres, motions, Fs)
        if thrust is not None:
            extra.update(thrust=thrust.to_dict())
        sig = [model.signature_columns(mo, inp, tr) for (mo, inp, tr) in motions]
        if all("wind" in c for c in sig):  # dependence of the missing forces on the apparent wind
            wind = {}
            for j, k in enumerate("XYN"):
                a = np.concatenate([c["wind"][min(j, 2)][:, j] for c in sig])
                wind[k] = float(np.corrcoef(a, Fcat[:, j])[0, 1]) if a.std() > 0 else None
            extra.update(wind_correlation=wind)
    found = {"spectrum": spectrum, "forces": forces, "whiteness": whiteness, "input_correlation": input_corr}
    return found, extra, ((Fs, motions) if Fs else None)


def _thrust_check(model, fitres, motions: list, Fs: list) -> ThrustCheck | None:
    """The fitted model's propeller thrust against the logged one, on the tracks that log it
    (``model.logged_thrust``, ships only), and how much of the missing surge force the thrust
    error carries: the missing X with the logged thrust in place of the model's is
    ``X - (1 - tP) (T_logged - T_model)`` (Yasukawa & Yoshimura 2015, eq. 9).

    Returns
    -------
    ThrustCheck or None
        None when the model has no propeller check or no track logs a thrust.
    """
    check = getattr(model, "logged_thrust", None)
    if check is None:
        return None
    rows = []
    for (_, _, tr), F in zip(motions, Fs):
        d = check(fitres, tr)
        if d is not None:
            rows.append((d, F[:, 0]))
    if not rows:
        return None
    logged = np.concatenate([d.logged for d, _ in rows])
    modelled = np.concatenate([d.model for d, _ in rows])
    beta = np.concatenate([np.abs(d.beta_p) for d, _ in rows])
    X = np.concatenate([x for _, x in rows])
    X_logged = np.concatenate([x - (1.0 - d.t_p) * (d.logged - d.model) for d, x in rows])
    err = modelled - logged
    a, b = float(np.sqrt(np.mean(X**2))), float(np.sqrt(np.mean(X_logged**2)))
    return ThrustCheck(
        tracks=len(rows),
        logged_mean_n=float(np.mean(logged)),
        model_mean_n=float(np.mean(modelled)),
        bias_fraction=float(np.mean(modelled) / np.mean(logged) - 1.0) if np.mean(logged) else None,
        rms_n=float(np.sqrt(np.mean(err**2))),
        error_corr_abs_beta_p=float(np.corrcoef(-err, beta)[0, 1]) if err.std() > 0 and beta.std() > 0 else None,
        missing_x_rms_n=a,
        missing_x_rms_logged_thrust_n=b,
        propeller_share=1.0 - (b / a) ** 2 if a > 0 else None,
    )


def approach_check(model, p, train, held) -> ApproachCheck | None:
    """Each run's propulsion point against the fitted model's (:class:`ApproachCheck`): on each
    run's own approach (:func:`bayesid.models.runs.run_approach`), the speed the model at ``p``
    settles at with the rpm the run logs there (``model.steady_speed``), against the run's
    measured approach speed; a held-out run whose error is more than
    :data:`~bayesid.models.runs.APPROACH_TOLERANCE` from the training runs' median and
    outside their range is at another propulsion point, and gets the rpm that puts it at the
    training runs' point: where the model's steady speed misses the run's approach speed by the
    training runs' median miss (``model.self_propulsion_rpm`` at that speed; at the run's own
    speed when the model holds the training runs' point exactly).

    Parameters
    ----------
    model : SimulationModel
        The fitted model; one without ``steady_speed`` (no propeller model) gives None.
    p : array_like, shape (n_params,)
        Its parameters.
    train, held : list of Track
        The training and held-out runs.

    Returns
    -------
    ApproachCheck or None
        None when the model has no ``steady_speed`` or no held-out run has an approach to read.
    """
    if getattr(model, "steady_speed", None) is None:
        return None
    rows = []
    for role, tracks in (("training", train), ("held-out", held)):
        for tr in tracks:
            row = approach_row(model, p, tr, matched=role == "held-out")
            if row is not None:
                rows.append({"run": row.pop("run"), "role": role, **row})
    errs = {r: [x["speed_error"] for x in rows if x["role"] == r and x["steady"]] for r in ("training", "held-out")}
    if not errs["held-out"]:
        return None
    tr_err = float(np.median(errs["training"])) if errs["training"] else None
    for r in rows:
        if r["role"] == "held-out":
            r["off"] = bool(
                tr_err is not None
                and r["steady"]
                and abs(r["speed_error"] - tr_err) > APPROACH_TOLERANCE
                and not min(errs["training"]) <= r["speed_error"] <= max(errs["training"])
            )
        if r.get("off"):  # matched to the training runs' point: where the model misses them as it misses those
            try:
                r["matched_rpm"] = float(model.self_propulsion_rpm(p, r["speed_m_s"] * (1.0 + tr_err)))
            except ValueError:
                r["matched_rpm"] = None
    off = [r["speed_error"] for r in rows if r.get("off")]
    h_err = float(np.median(off if off else errs["held-out"]))
    other = bool(off)
    return ApproachCheck(runs=rows, training_error=tr_err, heldout_error=h_err, another_point=bool(other))


def window_xy(model, fitres, track, window_s, nu=None, start="measured", leadin_s=0.0):
    """Measured and predicted x, y of a track's protocol windows under a fitted model, NaN rows
    separating the windows (for plots).

    Parameters
    ----------
    model : SimulationModel
        The model.
    fitres : FitResult
        The fit (its ``p``).
    track : Track
        The track.
    window_s : float or None
        Protocol window, s.
    nu : ndarray, optional
        The track's nuisances.
    start : str, default "measured"
        The (resolved) start rule.
    leadin_s : float, default 0.0
        Lead-in of the fitted rule, s.

    Returns
    -------
    measured : ndarray, shape (n, 2)
        The measured x, y.
    predicted : ndarray, shape (n + W - 1, 2)
        The predicted x, y.
    """
    ctx = model.context(track, window_s, start=start, leadin_s=leadin_s)
    S = evaluate(model, fitres.p, [ctx], None if nu is None else [nu]).states[0]
    xy = S[:, :2].copy()
    cut = np.flatnonzero(np.diff(ctx.win) != 0) + 1
    xy = np.insert(xy, cut, np.nan, axis=0)
    meas = np.column_stack([ctx.meas["x"], ctx.meas["y"]])
    return meas, xy
