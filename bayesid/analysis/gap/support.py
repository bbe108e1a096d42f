"""Independent *support* for a candidate effect: a sparse regression of the missing forces of
inverse dynamics on the effects' force signatures (each effect's
:meth:`~bayesid.models.effects.Effect.force_signature`, gathered by the model's ``signature_columns``).

Fasel, Kutz, Brunton & Brunton (2022), Ensemble-SINDy, Proc. R. Soc. A 478 (ensemble STLSQ with
bagging; :func:`bayesid.analysis.sindy.ensemble_stlsq`).
"""

from __future__ import annotations

import numpy as np

from ..sindy import ensemble_stlsq

__all__ = ["signature_regression"]


def signature_regression(F_list, cols_list, rng, n_models: int = 50, threshold: float = 0.1) -> dict:
    """Ensemble STLSQ of the missing forces on the effect signatures.

    Columns and target are RMS-normalised per equation; an effect's inclusion probability is the
    largest over its columns and equations.

    Parameters
    ----------
    F_list : list of ndarray
        Per track the (n, 3) missing X, Y, N (N, N m).
    cols_list : list of dict
        Per track ``{effect: [columns (n, 3)]}`` (the same effects and columns per track).
    rng : numpy.random.Generator
        Seeds the bootstrap.
    n_models : int, default 50
        Ensemble size.
    threshold : float, default 0.1
        STLSQ threshold on the RMS-normalised coefficients.

    Returns
    -------
    dict
        ``{effect: inclusion probability}``.
    """
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
        ry = np.sqrt(np.mean(y**2))
        rx = np.sqrt(np.mean(X**2, axis=0))
        live = rx > 1e-12 * max(rx.max(), 1e-300)
        if ry == 0 or not live.any():
            continue
        xi = ensemble_stlsq(X[:, live] / rx[live], y / ry, rng, threshold, 0.0, n_models)
        p = np.mean(xi != 0.0, axis=0)
        own = [o for o, keep in zip(owner, live) if keep]
        for o, pi in zip(own, p):
            prob[o] = max(prob[o], float(pi))
    return prob
