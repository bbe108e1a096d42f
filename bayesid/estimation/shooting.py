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
window solves its own 6 x 6 Levenberg-Marquardt step (Nocedal & Wright 2006, Sec. 10.3).
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


def _weights(ctx, weights):
    """{channel: 1/sd} of the start fit: ``weights`` (the fit's) or the track's own noise sds."""
    if weights is not None:
        return {c: w for c, w in weights.items() if c in ctx.channels}
    return {c: 1.0 / ctx.lead["sd"][c] for c in ctx.channels}


def lead_residuals(model, ctx, P, nu, starts, weights) -> np.ndarray:
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

    Returns
    -------
    ndarray, shape (B, n_rows)
        The residuals, channels in the order of ``ctx.channels`` restricted to ``weights``;
        PENALTY where a window diverged.
    """
    S = model.simulate(ctx, P, nu, starts=starts, samples="lead")
    out = []
    for c, e in errors(ctx, S, samples="lead").items():
        if c in weights:
            r = e * weights[c]
            r[~np.isfinite(r)] = PENALTY
            out.append(r)
    return np.concatenate(out, axis=1) if out else np.zeros((S.shape[0], 0))


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
    P7 = np.repeat(P, 7, axis=0)
    nu7 = None if nu is None else np.repeat(np.atleast_2d(nu), 7, axis=0)

    def window_cost(r):
        return np.asarray((G @ (r * r).T).T)  # (B, W)

    r = lead_residuals(model, ctx, P, nu, D, w)
    cost = window_cost(r)
    lam = np.full((B, W), 1e-3)
    J = np.zeros((6, B, rwin.size))
    for _ in range(LM_ITERATIONS):
        # the 6 perturbed start vectors of every window in one batch: rows b*7 + j (j = 0: base)
        Dp = np.repeat(D, 7, axis=0).reshape(B, 7, W, 6)
        for j in range(6):
            Dp[:, j + 1, :, j] += START_STEP[j]
        R = lead_residuals(model, ctx, P7, nu7, Dp.reshape(B * 7, W, 6), w).reshape(B, 7, -1)
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
            rt = lead_residuals(model, ctx, P, nu, Dt, w)
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
    if return_jacobian:
        return D, J, rwin
    return D


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
        U, s, _ = np.linalg.svd(Jd[rows], full_matrices=False)
        keep = s > 1e-10 * max(s[0], 1e-300) if s.size else np.zeros(0, bool)
        Q = U[:, keep]
        out[rows] -= Q @ (Q.T @ out[rows])
    return out


__all__ = ["START_INDEX", "START_STEP", "fit_starts", "simulate", "lead_residuals", "project_out"]
