"""Window start states fitted with the model: the fitted start rule of the window protocol.

Under the fitted rule (:data:`bayesid.protocol.START_RULES`) the state at the start of each
window segment is not read off the measurements: a first guess
(:func:`bayesid.protocol.state_guess`) is corrected by offsets in x, y, psi, u, v, r
(:data:`bayesid.models.context.START_INDEX`) that minimise the noise-weighted squared error of the
model's prediction over the samples that belong to the start (``ctx.lead``):

* on a held-out track, the lead-in before the window (the window is scored only after it):
  a moving-horizon estimate of the window's start state made with the model being scored
  (Rao, Rawlings & Mayne 2003, IEEE TAC 48(2), with the horizon ending at the window start);
* on a training track, the window itself (multiple shooting proper: Bock & Plitt 1984, IFAC
  World Congress; the start states are nuisance parameters of the fit, eliminated by variable
  projection in :class:`bayesid.estimation.windows.WindowObjective`, Golub & Pereyra 2003, Inverse Problems 19(2), with
  Kaufman's 1975 Jacobian).

Windows are independent given the parameters, so the start states of all windows are fitted at
once: one simulation per start component perturbs that component in every window, and each
window solves its own 6 x 6 Levenberg-Marquardt step (Nocedal & Wright 2006, Sec. 10.3). A
window left far above the noise is fitted once more from a second guess, the velocity along the
heading (:func:`zero_sideslip`): a first guess with the wrong sway velocity can start the
iterations in the basin of a start that turns the wrong way.
Why it matters: from 5 Hz positions with 0.2 m noise, a 1 s slope misjudges the start velocity by
about 0.1 m/s (6 m after 60 s); a 10 s lead-in through the model pins it to about 0.01 m/s.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from ..models.context import START_INDEX, errors

#: Finite-difference steps of the start offsets x, y (m), psi (rad), u, v (m/s), r (rad/s).
START_STEP = np.array([1e-3, 1e-3, 1e-5, 1e-4, 1e-4, 1e-5])
#: Residual (in weighted units) of a sample of a diverged window.
PENALTY = 1e3
#: Levenberg-Marquardt iterations of :func:`fit_starts` (each: 7 batched simulations of the start
#: samples), and the relative cost decrease below which it stops.
LM_ITERATIONS = 12
LM_TOLERANCE = 1e-7
#: A window whose start fit ends with a sum of squared weighted residuals above this many per
#: residual (an RMS of 3 noise sds) is fitted again from the zero-sideslip guess
#: (:func:`zero_sideslip`); the second fit replaces the first where its cost is below
#: ``RETRY_GAIN`` times the first's. From 5 Hz positions the first guess's sway velocity (a
#: quadratic's slope at the end of a 2 s span) can be 0.8 m/s off; a model with a strong v^2 r
#: moment then turns the wrong way at once and the iterations never leave that basin.
RETRY_COST = 9.0
RETRY_GAIN = 0.5
#: The retries of a window still above ``RETRY_COST``, in order: the zero-sideslip guess of the
#: fitted offsets (their speed kept), then of the measured guess (its speed kept). The first alone
#: keeps a speed the first fit drove backwards: on 5 Hz REMUS 100 logs with 0.5 m of position
#: noise, a perfect model's fitted starts then missed by more than 2 m in 19 % of 5 s windows
#: (u fitted near -1.1 m/s against a true +1.1); with the second, 9 % (31 % and 8 % of 15 s
#: windows; ``reports/benchmark_start_fits.txt``).
RETRY_GUESSES = ("fitted", "measured")
#: A lead-in window still above :data:`CONTINUATION_COST` after those retries is fitted once more by
#: continuation in the horizon: on the first of these fractions of its lead-in, then on each longer
#: one from the offsets of the shorter (the full lead-in last), from each of four guesses (the
#: offsets found, the measured guess, :func:`kinematic_guess` and :func:`mean_velocity_guess`).
#: Over a 10 s lead-in a start rate a few tenths of a degree per second off turns the heading of a
#: vehicle with weak yaw stability by several noise sds, and the first Gauss-Newton steps from there
#: can jump to a start that runs backwards; over its first 2.5 s the fit is nearly linear, and each
#: longer horizon starts in the shorter one's basin (the reasoning of multiple shooting, Bock & Plitt
#: 1984, applied to the horizon). On noisy copies of the newcomer's 5 Hz REMUS 100 runs a perfect
#: model's windows above 2 m went from 8.8 % to 0.5 % (5 s windows) and from 21 % to none (60 s);
#: ``reports/benchmark_start_fits.txt``. Only windows with a lead-in are continued (the held-out
#: windows, and the training windows of a fit with a lead-in, as the gap diagnosis's): a training
#: window that is its own lead (multiple shooting proper) is fitted with the coefficients, which
#: move it out of a wrong basin themselves. In a fit, a window the model cannot follow pays the
#: continuation at every parameter step (the newcomer's diagnoses ran in 48 and 51 s against 119
#: and 171 s before, the fits converging in fewer steps).
CONTINUATION_FRACTIONS = (0.25, 0.5, 0.75, 1.0)
#: The mean squared weighted residual per lead-in sample above which a lead-in window is continued:
#: twice a perfect model's (a window can sit below :data:`RETRY_COST` and still have its speed
#: 0.6 m/s off, which 60 s of prediction turn into 10 m).
CONTINUATION_COST = 2.0


def _weights(ctx, weights):
    """{channel: 1/sd} of the start fit: ``weights`` (the fit's) or the track's own noise sds."""
    if weights is not None:
        return {c: w for c, w in weights.items() if c in ctx.channels}
    return {c: 1.0 / ctx.lead["sd"][c] for c in ctx.channels}


def lead_residuals(model, ctx, P, nu, starts, weights, prepared=None) -> np.ndarray:
    """Weighted residuals over the start samples ``ctx.lead``.

    Parameters
    ----------
    model : SimulationModel
        The model.
    ctx : TrackContext
        A context with the fitted start rule.
    P : array_like, shape (B, n_params)
        Parameter vectors.
    nu : array_like, shape (B, n_nuisance), or None
        Nuisances of the track.
    starts : ndarray, shape (B, W, 6)
        Start offsets (:data:`START_INDEX` components).
    weights : dict
        ``{channel: 1/sd}`` of the channels used.
    prepared : Prepared, optional
        ``model.prepare(ctx, P, nu)`` (:func:`_prepare`), shared by the simulations of one fit.

    Returns
    -------
    ndarray, shape (B, n_rows)
        The residuals, channels in the order of ``ctx.channels`` restricted to ``weights``;
        PENALTY where a window diverged.
    """
    if prepared is None:
        S = model.simulate(ctx, P, nu, starts=starts, samples="lead")
    else:
        S = model.simulate(ctx, P, nu, starts=starts, samples="lead", prepared=prepared)
    out = []
    for c, e in errors(ctx, S, samples="lead").items():
        if c in weights:
            r = e * weights[c]
            r[~np.isfinite(r)] = PENALTY
            out.append(r)
    return np.concatenate(out, axis=1) if out else np.zeros((S.shape[0], 0))


def _prepare(model, ctx, P, nu):
    """``model.prepare(ctx, P, nu)``, or None for a model without it (an optional method of the
    :class:`~bayesid.models.interface.SimulationModel` contract)."""
    prepare = getattr(model, "prepare", None)
    return None if prepare is None else prepare(ctx, P, nu)


def _row_windows(ctx, weights) -> np.ndarray:
    """(n_rows,) window of each row of :func:`lead_residuals`."""
    return np.concatenate([ctx.lead["win"] for c in ctx.channels if c in weights] or [np.zeros(0, np.int64)])


def fit_starts(
    model,
    ctx,
    P,
    nu=None,
    weights=None,
    starts0=None,
    return_jacobian: bool = False,
):
    """Least-squares start-state offsets of every window of ``ctx`` for parameter rows ``P``.

    Batched Levenberg-Marquardt from ``starts0``; a window whose fit ends with a mean squared
    weighted residual above :data:`RETRY_COST` is fitted again from the zero-sideslip guesses
    (:func:`zero_sideslip`) of :data:`RETRY_GUESSES` in turn, while it stays above, and a fit
    replaces the one before where it at least halves the window's cost (:data:`RETRY_GAIN`). A
    window with a lead-in still above :data:`CONTINUATION_COST` is then fitted by
    continuation in the horizon (:data:`CONTINUATION_FRACTIONS`), kept on the same rule. The
    other windows keep the first fit's offsets.

    Parameters
    ----------
    model : EffectModel or ShipModel
        The model.
    ctx : TrackContext
        A context with the fitted start rule.
    P : array_like, shape (B, n_params)
        Parameter vectors (held fixed).
    nu : array_like, shape (B, n_nuisance), optional
        Nuisances of the track.
    weights : dict, optional
        ``{channel: 1/sd}`` (default: the track's own noise sds, ``ctx.lead["sd"]``).
    starts0 : array_like, shape (B, W, 6), optional
        First offsets (default zeros: the guess of ``ctx.s_meas``).
    return_jacobian : bool, default False
        Also return the Jacobian of :func:`lead_residuals` at the last linearisation and the
        window of each row (for variable projection).

    Returns
    -------
    offsets : ndarray, shape (B, W, 6)
        Offsets in x (m), y (m), psi (rad), u, v (m/s), r (rad/s) (:data:`START_INDEX`).
    J : ndarray, shape (6, B, n_rows)
        Only with ``return_jacobian``: the Jacobian of the residuals by the offsets.
    row_windows : ndarray, shape (n_rows,)
        Only with ``return_jacobian``: the window of each residual row.

    Raises
    ------
    ValueError
        When ``ctx`` has no start samples (the measured rule).
    """
    if ctx.lead is None:
        raise ValueError(f"track {ctx.name!r}: the start rule is {ctx.start!r}, not 'fitted'")
    P = np.atleast_2d(np.asarray(P, float))
    B, W = P.shape[0], ctx.W
    w = _weights(ctx, weights)
    rwin = _row_windows(ctx, w)
    G = sparse.csr_matrix((np.ones(rwin.size), (rwin, np.arange(rwin.size))), shape=(W, rwin.size))
    D = np.zeros((B, W, 6)) if starts0 is None else np.array(starts0, float)
    # the rows' coefficients, inputs and forces prepared once for every simulation of the fit
    nu7 = None if nu is None else np.repeat(np.atleast_2d(nu), 7, axis=0)
    P7 = np.repeat(P, 7, axis=0)
    prep = (_prepare(model, ctx, P, nu), _prepare(model, ctx, P7, nu7))
    lm = (model, ctx, P, nu, w, G, prep)
    D, cost, J = _levenberg_marquardt(lm, D)
    # a window whose fit ended far above the noise: again from the zero-sideslip guesses, kept when much better
    rows = np.maximum(np.asarray(G.sum(axis=1)).ravel(), 1.0)
    for guess in RETRY_GUESSES:
        stuck = cost / rows > RETRY_COST
        if not stuck.any():
            break
        first = zero_sideslip(ctx, D if guess == "fitted" else np.zeros_like(D))
        D2, cost2, J2 = _levenberg_marquardt(lm, np.where(stuck[..., None], first, D))
        better = stuck & (cost2 < RETRY_GAIN * cost)
        D = np.where(better[..., None], D2, D)
        cost = np.where(better, cost2, cost)
        for b, wi in zip(*np.nonzero(better)):
            J[:, b, rwin == wi] = J2[:, b, rwin == wi]
    if ctx.lead_steps > 0 and CONTINUATION_FRACTIONS:
        stuck = cost / rows > CONTINUATION_COST
        if stuck.any():
            D, cost, J = _continued(lm, ctx, D, cost, J, stuck, rwin)
    if return_jacobian:
        return D, J, rwin
    return D


def _continued(lm: tuple, ctx, D, cost, J, stuck, rwin) -> tuple:
    """The stuck windows of :func:`fit_starts` fitted by continuation in the horizon
    (:data:`CONTINUATION_FRACTIONS`) from each of four guesses; a window takes the best where it
    at least halves its cost (:data:`RETRY_GAIN`). Returns ``(D, cost, J)`` as
    :func:`_levenberg_marquardt`."""
    w = lm[4]
    t_rel = np.concatenate([ctx.lead["t_rel"] for c in ctx.channels if c in w])
    span = np.zeros(ctx.W)
    np.maximum.at(span, rwin, t_rel)
    guesses = [D, np.zeros_like(D)] + [
        np.broadcast_to(g, D.shape) for g in (kinematic_guess(ctx), mean_velocity_guess(ctx))
    ]
    for first in guesses:
        D2 = np.where(stuck[..., None], first, D)
        for frac in CONTINUATION_FRACTIONS:
            mask = None if frac >= 1.0 else (t_rel <= frac * span[rwin] + 1e-9).astype(float)
            D2, cost2, J2 = _levenberg_marquardt(lm, D2, mask)
        better = stuck & (cost2 < RETRY_GAIN * cost)
        D = np.where(better[..., None], D2, D)
        cost = np.where(better, cost2, cost)
        for b, wi in zip(*np.nonzero(better)):
            J[:, b, rwin == wi] = J2[:, b, rwin == wi]
    return D, cost, J


def kinematic_guess(ctx) -> np.ndarray:
    """Start offsets that set each window's first-guess u, v, r to :func:`kinematic_rates` at its
    segment start (the lead-in's first sample), where those are finite.

    Parameters
    ----------
    ctx : TrackContext
        A context with the fitted start rule.

    Returns
    -------
    ndarray, shape (W, 6)
        Offsets of :data:`START_INDEX` (x, y, psi zero).
    """
    out = np.zeros((ctx.W, 6))
    for wi, ta in enumerate(ctx.t_seg):
        k = kinematic_rates(ctx.track, float(ta), ctx.lead["sd"])
        for j, (name, col) in enumerate((("u", 6), ("v", 7), ("r", 11))):
            if np.isfinite(k[name]):
                out[wi, 3 + j] = k[name] - ctx.s_meas[wi, col]
    return out


def mean_velocity_guess(ctx) -> np.ndarray:
    """Start offsets that set each window's first-guess u, v, r to the lead-in's mean velocity and
    yaw rate: the slopes of straight lines fitted by least squares to its x, y and heading samples,
    the velocity turned into the body frame at the first guess's heading. Exact for a straight
    approach (a current included: the velocity over ground), where a local slope at the lead-in's
    first sample reads the noise of a few samples.

    Parameters
    ----------
    ctx : TrackContext
        A context with the fitted start rule and a lead-in.

    Returns
    -------
    ndarray, shape (W, 6)
        Offsets of :data:`START_INDEX` (x, y, psi zero; windows whose lead-in has fewer than 3
        samples of x, y and heading keep zeros).
    """
    out = np.zeros((ctx.W, 6))
    lead = ctx.lead
    if not all(c in lead["meas"] for c in ("x", "y", "psi")):
        return out
    for wi in range(ctx.W):
        sel = lead["win"] == wi
        t = lead["t_rel"][sel]
        cols = [np.asarray(lead["meas"][c], float)[sel] for c in ("x", "y", "psi")]
        ok = np.isfinite(t) & np.all([np.isfinite(c) for c in cols], axis=0)
        if ok.sum() < 3 or np.ptp(t[ok]) <= 0:
            continue
        cols[2] = np.unwrap(cols[2][ok])
        dx, dy, r = (np.polyfit(t[ok], c[ok] if i < 2 else c, 1)[0] for i, c in enumerate(cols))
        psi = ctx.s_meas[wi, 5]
        u, v = np.cos(psi) * dx + np.sin(psi) * dy, -np.sin(psi) * dx + np.cos(psi) * dy
        out[wi, 3:] = [u - ctx.s_meas[wi, 6], v - ctx.s_meas[wi, 7], r - ctx.s_meas[wi, 11]]
    return out


def zero_sideslip(ctx, D) -> np.ndarray:
    """Start offsets that turn each window's start velocity into one along its heading: the
    speed of ``ctx.s_meas`` plus ``D`` kept, the sway velocity zero (the second guess of
    :func:`fit_starts`).

    Parameters
    ----------
    ctx : TrackContext
        A context with the fitted start rule.
    D : ndarray, shape (B, W, 6)
        Start offsets (:data:`START_INDEX` components).

    Returns
    -------
    ndarray, shape (B, W, 6)
        ``D`` with the u and v offsets replaced.
    """
    u = ctx.s_meas[None, :, 6] + D[..., 3]
    v = ctx.s_meas[None, :, 7] + D[..., 4]
    out = np.array(D, float)
    out[..., 3] = np.hypot(u, v) * np.sign(np.where(u == 0.0, 1.0, u)) - ctx.s_meas[None, :, 6]
    out[..., 4] = -ctx.s_meas[None, :, 7]
    return out


def _levenberg_marquardt(lm: tuple, D: np.ndarray, mask=None) -> tuple:
    """The batched Levenberg-Marquardt iterations of :func:`fit_starts` from the offsets ``D``.

    Parameters
    ----------
    lm : tuple
        ``(model, ctx, P, nu, weights, G, prepared)``: G the sparse (W, n_rows) sum of the rows of
        each window; ``prepared`` the :func:`_prepare` of ``P`` and of its rows repeated 7 times.
    D : ndarray, shape (B, W, 6)
        First offsets.
    mask : ndarray, shape (n_rows,), optional
        Weights (0 or 1) of the residual rows: a shorter horizon of the continuation.

    Returns
    -------
    D : ndarray, shape (B, W, 6)
        The offsets.
    cost : ndarray, shape (B, W)
        Each window's sum of squared weighted residuals at ``D`` (the rows of ``mask``).
    J : ndarray, shape (6, B, n_rows)
        The Jacobian at the last linearisation.
    """
    model, ctx, P, nu, w, G, (prep, prep7) = lm
    B, W = D.shape[:2]
    P7 = np.repeat(P, 7, axis=0)
    nu7 = None if nu is None else np.repeat(np.atleast_2d(nu), 7, axis=0)

    def window_cost(r):
        return np.asarray((G @ (r * r).T).T)  # (B, W)

    def residuals(P_, nu_, D_, prep_):
        r_ = lead_residuals(model, ctx, P_, nu_, D_, w, prep_)
        return r_ if mask is None else r_ * mask

    r = residuals(P, nu, D, prep)
    cost = window_cost(r)
    lam = np.full((B, W), 1e-3)
    J = np.zeros((6, B, G.shape[1]))
    for _ in range(LM_ITERATIONS):
        # the 6 perturbed start vectors of every window in one batch: rows b*7 + j (j = 0: base)
        Dp = np.repeat(D, 7, axis=0).reshape(B, 7, W, 6)
        for j in range(6):
            Dp[:, j + 1, :, j] += START_STEP[j]
        R = residuals(P7, nu7, Dp.reshape(B * 7, W, 6), prep7).reshape(B, 7, -1)
        J = np.transpose((R[:, 1:] - R[:, :1]) / START_STEP[None, :, None], (1, 0, 2))  # (6, B, n)
        bad = ~np.isfinite(J) | (np.abs(R[:, 1:]).transpose(1, 0, 2) >= PENALTY)
        J[bad] = 0.0
        r = R[:, 0]
        A = np.empty((B, W, 6, 6))
        g = np.empty((B, W, 6))
        for b in range(B):
            Jb = J[:, b].T  # (n, 6)
            A[b] = np.asarray(G @ (Jb[:, :, None] * Jb[:, None, :]).reshape(-1, 36)).reshape(W, 6, 6)
            g[b] = np.asarray(G @ (Jb * r[b][:, None]))
        diag = np.einsum("bwii->bwi", A)
        improved = False
        for _attempt in range(3):
            M = A + (lam[..., None] * np.maximum(diag, 1e-12))[..., None] * np.eye(6)
            try:
                step = -np.linalg.solve(M, g[..., None])[..., 0]
            except np.linalg.LinAlgError:
                step = -np.einsum("bwij,bwj->bwi", np.linalg.pinv(M), g)
            step[~np.isfinite(step)] = 0.0
            Dt = D + step
            rt = residuals(P, nu, Dt, prep)
            ct = window_cost(rt)
            acc = ct < cost
            D = np.where(acc[..., None], Dt, D)
            gain = np.where(acc, (cost - ct) / np.maximum(cost, 1e-300), 0.0)
            cost = np.where(acc, ct, cost)
            lam = np.where(acc, lam / 3.0, lam * 4.0)
            if acc.any():
                improved = bool(np.max(gain) > LM_TOLERANCE)
                break
        if not improved:
            break
    return D, cost, J


def simulate(model, ctx, P, nu=None, weights=None, starts=None) -> np.ndarray:
    """``model.simulate`` at the scored samples under the context's start rule: with the fitted
    rule, the start offsets are fitted first (:func:`fit_starts`, or the given ``starts``).

    Parameters
    ----------
    model : SimulationModel
        The model.
    ctx : TrackContext
        The prepared track.
    P : array_like, shape (B, n_params)
        Parameter vectors.
    nu : array_like, shape (B, n_nuisance), optional
        Nuisances of the track.
    weights : dict, optional
        ``{channel: 1/sd}`` of the start fit (:func:`fit_starts`).
    starts : ndarray, shape (B, W, 6), optional
        Start offsets, instead of fitting them.

    Returns
    -------
    ndarray, shape (B, n_samples, 12)
        The predicted measurements.
    """
    if ctx.start != "fitted":
        return model.simulate(ctx, P, nu)
    if starts is None:
        starts = fit_starts(model, ctx, P, nu, weights)
    return model.simulate(ctx, P, nu, starts=starts)


def window_svd(Jd: np.ndarray) -> tuple:
    """The thin SVD of one window's start-state Jacobian, cut to its numerical rank (singular
    values above 1e-10 of the largest): the span :func:`project_out` removes and the
    pseudo-inverse the linearised start profile uses
    (:mod:`bayesid.estimation.track_posterior`).

    Parameters
    ----------
    Jd : ndarray, shape (n_w, 6)
        The window's rows of the Jacobian by the start offsets.

    Returns
    -------
    tuple
        ``(U, s, Vt)``: ndarray shapes (n_w, r), (r,), (r, 6), r the numerical rank.
    """
    U, s, Vt = np.linalg.svd(Jd, full_matrices=False)
    keep = s > 1e-10 * max(s[0], 1e-300) if s.size else np.zeros(0, bool)
    return U[:, keep], s[keep], Vt[keep]


def project_out(J: np.ndarray, Jd: np.ndarray, rwin: np.ndarray, W: int) -> np.ndarray:
    """Kaufman's variable-projection Jacobian: the columns of ``J`` with, window by window, their
    component in the span of that window's start-state Jacobian removed.

    Parameters
    ----------
    J : ndarray, shape (n, k)
        Jacobian by the parameters.
    Jd : ndarray, shape (n, 6)
        Jacobian by the start offsets.
    rwin : ndarray, shape (n,)
        Window of each row (rows of window w: ``rwin == w``).
    W : int
        Number of windows.

    Returns
    -------
    ndarray, shape (n, k)
        A new array.
    """
    out = np.array(J, float)
    for wi in range(W):
        rows = np.flatnonzero(rwin == wi)
        if rows.size == 0:
            continue
        Q, _, _ = window_svd(Jd[rows])
        out[rows] -= Q @ (Q.T @ out[rows])
    return out


#: Half-widths (s) of the two centred local-cubic fits that give the kinematic reference
#: (:func:`kinematic_rates`; each widened to at least 4 samples either side at slow logs).
KINEMATIC_HALF_SPANS_S = (2.0, 5.0)


def _local_slope(t, y, t_a: float, half: float, noise: float):
    """(value, slope, slope variance) at ``t_a`` of a centred cubic fitted to ``y`` over
    ``t_a +- half``; the variance with the larger of ``noise`` and the fit's residual sd."""
    sel = np.abs(t - t_a) <= half + 1e-9
    ok = sel & np.isfinite(y)
    if ok.sum() < 5:
        return float("nan"), float("nan"), float("nan")
    X = np.vander((t[ok] - t_a) / half, 4, increasing=True)
    c, *_ = np.linalg.lstsq(X, y[ok], rcond=None)
    s_fit = float(np.sqrt(np.sum((y[ok] - X @ c) ** 2) / max(ok.sum() - 4, 1)))
    var = max(float(noise), s_fit) ** 2 * float(np.linalg.pinv(X.T @ X)[1, 1]) / half**2
    return float(c[0]), float(c[1] / half), var


def kinematic_rates(track, t_a: float, sd: dict, half_spans_s=KINEMATIC_HALF_SPANS_S) -> dict:
    """Model-free u, v, r at ``t_a`` from the track's positions and heading, with their sd.

    A centred local cubic in time is fitted by least squares to x, y and the unwrapped heading
    over ``t_a +- half`` (Savitzky & Golay 1964, Anal. Chem. 36(8): the slope of a local
    polynomial); its slope at ``t_a`` is rotated into the body frame (horizontal kinematics,
    Fossen 2011, Ch. 2). The reference is the shorter span's; its sd combines that fit's noise
    (the larger of the channel's noise sd and the fit's residual sd) with the difference between
    the two spans, a measure of the bias a polynomial makes where the motion changes abruptly (a
    rudder reversal: measured on a 20 Hz zigzag, 0.7 deg/s between 2 s and 5 s spans).

    Parameters
    ----------
    track : Track
        The track (columns ``x``, ``y``, ``psi``; SI).
    t_a : float
        Time of the state, s.
    sd : dict
        Noise sd of ``x``/``y`` (m) and ``psi`` (rad).
    half_spans_s : tuple of float, default :data:`KINEMATIC_HALF_SPANS_S`
        The two half-widths, s (each widened to 4 samples either side of a slow log).

    Returns
    -------
    dict
        ``{"u", "v", "r"}`` (m/s, rad/s) and ``{"u_sd", "v_sd", "r_sd"}``; NaN where fewer
        than 5 finite samples lie in a span.
    """
    t = np.asarray(track.t, float)
    h = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    cols = {k: np.array(track[k], float) for k in ("x", "y", "psi")}  # copies: the track is not touched
    ok = np.isfinite(cols["psi"])
    cols["psi"][ok] = np.unwrap(cols["psi"][ok])
    est = []
    for half in half_spans_s:
        half = max(float(half), 4.0 * h)
        fx = _local_slope(t, cols["x"], t_a, half, sd["x"])
        fy = _local_slope(t, cols["y"], t_a, half, sd["y"])
        fp = _local_slope(t, cols["psi"], t_a, half, sd["psi"])
        cs, sn = np.cos(fp[0]), np.sin(fp[0])
        est.append(
            {
                "u": cs * fx[1] + sn * fy[1],
                "v": -sn * fx[1] + cs * fy[1],
                "r": fp[1],
                "var_uv": 0.5 * (fx[2] + fy[2]),
                "var_r": fp[2],
            }
        )
    a, b = est[0], est[-1]
    out = {k: float(a[k]) for k in ("u", "v", "r")}
    for k in ("u", "v", "r"):
        var = a["var_r"] if k == "r" else a["var_uv"]
        out[k + "_sd"] = float(np.sqrt(var + (a[k] - b[k]) ** 2))
    return out


def start_consistency(model, p, tracks, ctxs, sd: dict, label: str = "") -> list:
    """Fitted window starts set against the track's own kinematics, window by window.

    Under the fitted start rule a model that is far off can still follow a track for a while if
    its window starts are bent to compensate (a sway velocity the ship never had, a yaw rate
    ahead of the heading's own rate). Each window's start state is fitted with the model
    (:func:`fit_starts`, the fit's weights) and its u, v, r are compared with the model-free
    slope of the track at the same time (:func:`kinematic_rates`):
    ``z = (fitted - kinematic) / sqrt(sd_kinematic^2 + sd_fitted^2)``, the fitted start's sd from
    the Gauss-Newton covariance of its 6 components in that window.

    Parameters
    ----------
    model : SimulationModel
        The model.
    p : array_like, shape (n_params,)
        Its parameter vector.
    tracks : list of Track
        The tracks, parallel to ``ctxs``.
    ctxs : list of TrackContext
        Their contexts (fitted start rule; a context with another rule is skipped).
    sd : dict
        ``{channel: sd}`` (SI): the start fit's weights and the kinematic noise of x, y, psi.
    label : str, default ""
        Names the track set in the rows (e.g. ``"training"``).

    Returns
    -------
    list of dict
        Per window: ``set``, ``track``, ``t_s`` (start of the fitted segment), ``component``
        (the one of u, v, r with the largest |z|), ``fitted``, ``kinematic``, ``sd`` (SI)
        and ``z``.
    """
    P = np.atleast_2d(np.asarray(p, float))
    w = {c: 1.0 / s for c, s in sd.items()}
    rows = []
    names = ("u", "v", "r")
    for track, ctx in zip(tracks, ctxs):
        if ctx.start != "fitted" or ctx.lead is None:
            continue
        D, J, rwin = fit_starts(model, ctx, P, weights=w, return_jacobian=True)
        s0 = ctx.s_meas[:, START_INDEX] + D[0]
        for wi in range(ctx.W):
            Jw = J[:, 0, rwin == wi].T
            cov = np.linalg.pinv(Jw.T @ Jw) if Jw.size else np.full((6, 6), np.inf)
            ref = kinematic_rates(track, float(ctx.t_seg[wi]), sd)
            best = None
            for j, k in enumerate(names):
                s = float(np.sqrt(ref[k + "_sd"] ** 2 + max(cov[3 + j, 3 + j], 0.0)))
                z = (s0[wi, 3 + j] - ref[k]) / s if s > 0 else float("nan")
                if np.isfinite(z) and (best is None or abs(z) > abs(best["z"])):
                    best = {"component": k, "fitted": float(s0[wi, 3 + j]), "kinematic": float(ref[k]), "sd": s}
                    best["z"] = float(z)
            if best is not None:
                rows.append({"set": label, "track": ctx.name, "t_s": float(ctx.t_seg[wi]), **best})
    return rows


def kinematic_contexts(model, tracks, window_s, sd: dict) -> list:
    """Training contexts whose window starts are held at the tracks' own kinematics: u, v, r
    from :func:`kinematic_rates` (a centred fit: it uses samples after the start, which a
    training fit may, a held-out score may not), x, y, psi as the measured rule gives them.

    The alternative to fitted starts when a model far off would bend them
    (:func:`start_consistency`): held starts cannot absorb what the model lacks, so the
    coefficients must explain the motion.

    Parameters
    ----------
    model : SimulationModel
        The model.
    tracks : list of Track
        The training tracks.
    window_s : float or None
        The fit window, s.
    sd : dict
        Noise sd of ``x``/``y`` (m) and ``psi`` (rad).

    Returns
    -------
    list of TrackContext
        Contexts of the measured rule with their start states' u, v, r (``s_meas``) replaced
        where the kinematics give a finite value.
    """
    ctxs = [model.context(t, window_s, start="measured") for t in tracks]
    for c, t in zip(ctxs, tracks):
        for w in range(c.W):
            ref = kinematic_rates(t, float(c.t_start[w]), sd)
            for j, k in ((6, "u"), (7, "v"), (11, "r")):
                if np.isfinite(ref[k]):
                    c.s_meas[w, j] = ref[k]
    return ctxs


__all__ = [
    "START_INDEX",
    "START_STEP",
    "fit_starts",
    "kinematic_guess",
    "mean_velocity_guess",
    "kinematic_contexts",
    "kinematic_rates",
    "start_consistency",
    "simulate",
    "lead_residuals",
    "project_out",
    "window_svd",
]
