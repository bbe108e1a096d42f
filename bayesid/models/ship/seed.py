"""The equation-error seed of a ship fit: the coefficients that enter the forces linearly
(:data:`LINEAR`), regressed from the smoothed measured accelerations of the tracks.
"""

from __future__ import annotations

import numpy as np

from .dynamics import accelerations
from .layout import WIND

#: Coefficients that enter the forces linearly (the equation-error seed regresses these).
LINEAR = ("Xuu", "Xvv", "Xvr", "Xrr", "Yv", "Yr", "Nv", "Nr", "Ycf", "Ncf", "Yvvr", "Yvrr", "Nvvr", "Nvrr") + WIND


def equation_error_seed(model, tracks, names=None) -> tuple[np.ndarray, dict]:
    """Equation-error estimate of the coefficients that enter the forces linearly: regression
    of the smoothed measured accelerations on the model's accelerations (Savitzky-Golay
    smoothing and differentiation, :func:`bayesid.models.inverse.estimate_motion`; u, v from the track
    when measured, else from the positions).

    ``a_meas - a(theta0) = sum_i (theta_i - theta0_i) g_i`` with ``g_i = d a / d theta_i``
    (exact: the forces are linear in these coefficients and they do not enter the mass matrix);
    each equation is weighted by the inverse RMS of its left-hand side, and a small ridge
    (1e-6 of the normal matrix's trace) keeps unexcited directions at their start values.

    Parameters
    ----------
    model : ShipModel
        The model (its start, scales and bounds).
    tracks : sequence of Track
        The training tracks.
    names : sequence of str, optional
        The parameters regressed; default those of :data:`LINEAR` in the model.

    Returns
    -------
    p : ndarray, shape (n_params,)
        The model's start vector with the regressed entries replaced (clipped to the bounds).
    summary : dict
        ``names`` (the parameters regressed), ``n_samples``, ``r2`` per equation (X, Y, N).
    """
    p0 = model.start()
    lin = (
        [i for i, n in enumerate(model.param_names) if n.split(".")[-1] in LINEAR]
        if names is None
        else [model.param_names.index(n) for n in names]
    )
    rows, lhs = [], []
    for tr in tracks:
        motion, states, inp, wind, acc = model._motion(tr)
        keep = np.arange(0, states.shape[0], max(1, int(round(0.2 / np.median(np.diff(motion["t"]))))))
        st, ip, wd, ac = (np.ascontiguousarray(a[keep]) for a in (states, inp, wind, acc))
        P = np.repeat(p0[None], len(lin) + 1, axis=0)
        for j, i in enumerate(lin):
            P[j + 1, i] += model.scales()[i]
        prm, cur, _ = model.kernel_params(P)
        A = []
        for b in range(P.shape[0]):
            a = np.empty_like(ac)
            accelerations(st, ip, wd, np.ascontiguousarray(cur[b]), np.ascontiguousarray(prm[b]), a)
            A.append(a)
        G = np.stack([(A[j + 1] - A[0]) / model.scales()[i] for j, i in enumerate(lin)], axis=-1)  # (n, 3, k)
        rows.append(G)
        lhs.append(ac - A[0])
    G = np.concatenate(rows)
    y = np.concatenate(lhs)
    ok = np.all(np.isfinite(y), axis=1) & np.all(np.isfinite(G), axis=(1, 2))
    G, y = G[ok], y[ok]
    w = 1.0 / np.sqrt(np.mean(y**2, axis=0))
    Aw = (G * w[None, :, None]).reshape(-1, len(lin))
    yw = (y * w[None, :]).ravel()
    N = Aw.T @ Aw
    dx = np.linalg.solve(N + 1e-6 * np.trace(N) / max(len(lin), 1) * np.eye(len(lin)), Aw.T @ yw)
    p = p0.copy()
    p[lin] += dx
    lo, hi = model.bounds()
    p = np.clip(p, lo, hi)
    res = y - np.einsum("nek,k->ne", G, p[lin] - p0[lin])
    r2 = 1 - np.sum(res**2, axis=0) / np.sum((y - y.mean(axis=0)) ** 2, axis=0)
    return p, {
        "names": [model.param_names[i] for i in lin],
        "n_samples": int(y.shape[0]),
        "r2": {k: float(v) for k, v in zip("XYN", r2)},
    }


__all__ = ["equation_error_seed", "LINEAR"]
