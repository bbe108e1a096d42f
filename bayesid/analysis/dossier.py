"""The identifiability dossier of a posterior: which coefficient combinations the data
determine (Fisher information, collinearity, structural nulls) and how the sampled posterior
compares with that along each direction. The posterior study (``studies/posterior.py``) composes
it; the algorithms live here."""

from __future__ import annotations

import numpy as np

from ..estimation.posterior import direction_draws
from . import identifiability

__all__ = ["dossier", "direction_convergence", "data_dossier", "DETERMINED", "AT_PRIOR"]

#: Posterior sd / prior sd below which a coefficient is determined by the data, and above which
#: it stays at its prior (between the two: partly determined).
DETERMINED = 0.5
AT_PRIOR = 0.9


#: Fisher eigenvalues below this x the largest are numerically zero (eigh precision ~1e-16).
ROUND_OFF = 1e-15


def _round_off(lam: np.ndarray, W: np.ndarray, names) -> tuple[int, dict]:
    """The number of Fisher eigenvalues (ascending ``lam``) at round-off level, below
    :data:`ROUND_OFF` x the largest, and the null space they span by its projector's diagonal
    (:func:`~bayesid.analysis.identifiability.subspace_participation`)."""
    k = int(np.sum(lam <= ROUND_OFF * lam[-1])) if lam.size else 0
    return k, identifiability.subspace_participation(W[:, :k], names)


def dossier(
    problem,
    theta_hat,
    prior_sd_abs,
    truth,
    vehicle,
    samples,
    noise: dict,
    determined: float = 0.5,
) -> dict:
    """The identifiability dossier of a posterior: Fisher information, its eigen-directions,
    collinearity indices, relative influence, structural (exact) null directions checked by
    simulation, and the posterior spread along each Fisher eigen-direction against its
    Cramer-Rao prediction (relative units, ``d theta / theta``).

    Sources: Fisher information and Cramer-Rao bound (Ljung 1999, Sec. 7.4); collinearity index
    (Brun, Reichert & Kuensch 2001, Water Resour. Res. 37(4)); principal angles (Bjorck & Golub
    1973, Math. Comp. 27).

    Parameters
    ----------
    problem : Problem
        :class:`~bayesid.estimation.objective.Problem` (its free names are the sampled set).
    theta_hat : array_like, shape (P,)
        Optimum, prime form.
    prior_sd_abs : array_like, shape (P,)
        Prior sd of each coefficient.
    truth : array_like, shape (P,)
        Reference coefficients of the structural-null check (2 % steps along each null).
    vehicle : Vehicle
        The vehicle (its term table gives the structural nulls).
    samples : ndarray, shape (n, P)
        Posterior draws, prime form (the structural nulls are checked with the problem's
        Simulator, ``problem.sim``).
    noise : dict
        ``{channel: sd}`` of the measurements (SI).
    determined : float, default 0.5
        A direction is determined when its Cramer-Rao sd is below this x the prior sd along it.
        Fisher eigenvalues below :data:`ROUND_OFF` x the largest count as zero.

    Returns
    -------
    dict
        ``F``, ``lam``, ``W`` (Fisher information, its eigenvalues and unit eigenvectors,
        sloppiest first) and ``sloppiest`` (a :class:`~bayesid.analysis.identifiability.Direction`)
        for further use, and JSON-able tables: ``directions``, ``fim_condition_number``,
        ``lam_ratio_min``, ``collinearity``, ``relative_influence``, ``structural_nulls``,
        ``structural_null_fim_angles_deg``, ``n_round_off_eigenvalues``,
        ``round_off_participation`` (how much each coefficient takes part in the round-off null
        space, the diagonal of its projector: basis-free, unlike the individual round-off
        directions, which any rotation replaces; each row of ``directions`` says whether it is
        ``round_off``), the angles between the
        extreme Fisher directions and posterior axes, and the posterior's widest and narrowest
        axes.
    """
    names = list(problem.names)
    S = identifiability.relative_sensitivity(problem, theta_hat)
    sig = problem.noise_vector(noise)
    F = identifiability.fisher_information(S, sig, problem.mask.reshape(-1))
    dirs = identifiability.eigen_directions(F, names)  # sloppiest first
    lam = np.array([d.eigenvalue for d in dirs])
    W = np.column_stack([d.vector for d in dirs])  # (P, P) unit columns
    # prior sd along each direction, in relative units (independent priors)
    psd_rel = np.asarray(prior_sd_abs, float) / np.abs(theta_hat)
    prior_along = np.sqrt((W**2).T @ psd_rel**2)
    post_along = direction_draws(samples, W, theta_hat).std(axis=0, ddof=1)
    cr = np.where(lam > 0, 1.0 / np.sqrt(np.clip(lam, 1e-300, None)), np.inf)
    k_round, participation = _round_off(lam, W, names)
    rows = []
    for k, d in enumerate(dirs):
        rows.append(
            dict(
                direction=d.label(),
                eigenvalue=float(lam[k]),
                cramer_rao_sd=float(cr[k]),
                posterior_sd=float(post_along[k]),
                prior_sd=float(prior_along[k]),
                determined=bool(cr[k] < determined * prior_along[k]),
                round_off=bool(k < k_round),
                weights=d.weights(0.1),
            )
        )
    # structural (exact) nulls of the sampled set, each checked by moving 2 % along it
    full, causes = identifiability.structural_null_space(names, vehicle)
    nulls = []
    if full.shape[1]:
        base = np.asarray(truth, float)
        st = problem.sim.run(np.vstack([base] + [base * (1 + 0.02 * full[:, k]) for k in range(full.shape[1])])).states
        null_angles = identifiability.principal_angles_deg(full, W[:, : max(k_round, full.shape[1])]).tolist()
        for k in range(full.shape[1]):
            dd = identifiability.Direction(0.0, full[:, k], names)
            pa = float(direction_draws(samples, full[:, k : k + 1], theta_hat).std(ddof=1))
            pr = float(np.sqrt((full[:, k] ** 2) @ psd_rel**2))
            nulls.append(
                dict(
                    direction=dd.label(threshold=0.15),
                    cause=causes[k] if k < len(causes) else "",
                    track_change_m=float(np.nanmax(np.abs(st[0, :, :2] - st[k + 1, :, :2]))),
                    posterior_sd=pa,
                    prior_sd=pr,
                )
            )
    else:
        null_angles = []
    # posterior principal axes vs Fisher directions (relative coordinates)
    C = np.cov(direction_draws(samples, np.eye(len(names)), theta_hat), rowvar=False)
    ev, EV = np.linalg.eigh(C)
    angle_sloppy = float(identifiability.principal_angles_deg(W[:, :1], EV[:, -1:])[0])
    angle_stiff = float(identifiability.principal_angles_deg(W[:, -1:], EV[:, :1])[0])
    infl = identifiability.relative_influence(S, sig)
    return dict(
        F=F,
        lam=lam,
        W=W,
        directions=rows,
        sloppiest=dirs[0],
        fim_condition_number=identifiability.condition_number(F),
        lam_ratio_min=float(lam[0] / lam[-1]),
        collinearity=identifiability.collinearity_table(S, names, sizes=(2, 3), top=5),
        relative_influence=dict(zip(names, infl.tolist())),
        structural_nulls=nulls,
        structural_null_fim_angles_deg=null_angles,
        n_round_off_eigenvalues=k_round,
        round_off_participation=participation,
        angle_sloppiest_vs_widest_posterior_axis_deg=angle_sloppy,
        angle_stiffest_vs_narrowest_posterior_axis_deg=angle_stiff,
        posterior_axis_widest=identifiability.Direction(float(ev[-1]), EV[:, -1], names).label(),
        posterior_axis_narrowest=identifiability.Direction(float(ev[0]), EV[:, 0], names).label(),
    )


def direction_convergence(result, burn, W, theta_hat, determined) -> dict:
    """R-hat (walkers as chains) and bulk ESS (ArviZ) of the posterior draws projected on the
    determined and on the undetermined Fisher directions, reported separately.

    Parameters
    ----------
    result : SamplerResult
        The sampling run (:class:`~bayesid.estimation.sampling.SamplerResult`).
    burn : int
        The steps dropped.
    W : ndarray, shape (P, K)
        The Fisher directions (columns, relative units).
    theta_hat : ndarray, shape (P,)
        The reference of the relative units.
    determined : ndarray of bool, shape (K,)
        Which directions are determined.

    Returns
    -------
    dict
        ``determined`` and ``undetermined``: ``n``, ``rhat_max``, ``ess_bulk_min`` (None
        without such a direction).
    """
    import arviz as az

    E, N, Wk, P = result.chains.shape
    x = direction_draws(result.chains[:, burn:], W, theta_hat)  # (E, D, Wk, K)
    x = x.transpose(0, 2, 1, 3).reshape(E * Wk, -1, W.shape[1])  # (chains, draws, K)
    rh = np.array([float(az.rhat(x[:, :, k])) for k in range(x.shape[2])])
    ess = np.array([float(az.ess(x[:, :, k], method="bulk")) for k in range(x.shape[2])])
    out = {}
    for label, sel in (("determined", determined), ("undetermined", ~determined)):
        out[label] = dict(
            n=int(sel.sum()),
            rhat_max=float(rh[sel].max()) if sel.any() else None,
            ess_bulk_min=float(ess[sel].min()) if sel.any() else None,
        )
    return out


def data_dossier(names, fisher, jac, scales, prior, draws, top: int = 5) -> dict:
    """The identifiability dossier of a user's tracks (``bayesid sample``): the Fisher spectrum,
    its named sloppy directions with the posterior and prior spread along them, collinearity
    indices, and per coefficient whether the data determine it, move it or leave it at its prior.

    Sources as :func:`dossier` (Ljung 1999 Sec. 7.4; Brun, Reichert & Kuensch 2001).

    Parameters
    ----------
    names : sequence of str
        The P parameter names.
    fisher : ndarray, shape (P, P)
        The data's information about the parameters (``J^T J`` of the posterior's weighted
        residuals, prior excluded).
    jac : ndarray, shape (n, P)
        That Jacobian (or any matrix with the same ``J^T J``, e.g. its QR factor R).
    scales : array_like, shape (P,)
        Typical size of each parameter: directions are in units of it (``d theta / scale``).
    prior : ParameterPrior
        The posterior's prior (:class:`~bayesid.estimation.track_posterior.ParameterPrior`): its
        ``marginal_mean()``, ``marginal_sd()`` (inf for a flat prior) and ``gaussian`` (P,) bool.
    draws : ndarray, shape (N, P)
        Unweighted posterior draws.
    top : int, default 5
        Sloppy directions listed (and twice as many correlations).

    Returns
    -------
    dict
        JSON-able: ``fisher_eigenvalues`` (scaled units, sloppiest first),
        ``fim_condition_number``, ``directions`` (each: label, eigenvalue, Cramer-Rao sd,
        posterior and prior sd along it, in scales, and ``round_off``: its eigenvalue below
        :data:`ROUND_OFF` x the largest, so that the direction is any vector of the round-off
        null space), ``sloppy`` (the ``top`` sloppiest), ``n_round_off_eigenvalues`` and
        ``round_off_participation`` (that space by its projector's diagonal,
        :func:`~bayesid.analysis.identifiability.subspace_participation`),
        ``collinearity`` (Brun et al. 2001 index of the most collinear pairs and triples),
        ``coefficients`` (per name: posterior mean, sd, prior mean and sd, ``sd_ratio``, ``z`` of
        the posterior mean against a Gaussian prior, ``status``: ``determined`` (ratio <
        :data:`DETERMINED`), ``partly``, ``at prior`` (ratio > :data:`AT_PRIOR`)), ``moved``
        (|z| > 1), ``moved_beyond_3sd``, ``correlations``.
    """
    names = list(names)
    prior_mean, prior_sd, gaussian = prior.marginal_mean(), prior.marginal_sd(), prior.gaussian
    D = np.abs(np.asarray(scales, float))
    Fs = np.asarray(fisher, float) * np.outer(D, D)
    dirs = identifiability.eigen_directions(Fs, names)
    W = np.column_stack([d.vector for d in dirs])
    draws = np.asarray(draws, float)
    psd = np.asarray(prior_sd, float)
    post_along = ((draws - draws.mean(axis=0)) / D) @ W
    post_along = post_along.std(axis=0, ddof=1)
    with np.errstate(invalid="ignore"):
        prior_along = np.sqrt((W**2).T @ (psd / D) ** 2)
    lam = np.array([d.eigenvalue for d in dirs])
    k_round, participation = _round_off(lam, W, names)
    rows = []
    for k, d in enumerate(dirs):
        rows.append(
            dict(
                direction=d.label(),
                eigenvalue=float(d.eigenvalue),
                cramer_rao_sd=d.sd_relative,
                posterior_sd=float(post_along[k]),
                prior_sd=float(prior_along[k]),
                round_off=bool(k < k_round),
                weights=d.weights(0.1),
            )
        )
    R = np.linalg.qr(np.asarray(jac, float) / D, mode="r")
    mean, sd = draws.mean(axis=0), draws.std(axis=0, ddof=1)
    coef, moved, beyond = {}, [], []
    for j, n in enumerate(names):
        ratio = float(sd[j] / psd[j]) if np.isfinite(psd[j]) and psd[j] > 0 else 0.0
        status = "determined" if ratio < DETERMINED else ("at prior" if ratio > AT_PRIOR else "partly")
        z = float((mean[j] - prior_mean[j]) / psd[j]) if gaussian[j] else None
        coef[n] = dict(
            mean=float(mean[j]),
            sd=float(sd[j]),
            prior_mean=None if not np.isfinite(prior_mean[j]) else float(prior_mean[j]),
            prior_sd=None if not np.isfinite(psd[j]) else float(psd[j]),
            prior="normal" if gaussian[j] else "uniform",
            sd_ratio=ratio,
            z=z,
            status=status,
        )
        if z is not None and abs(z) > 1.0:
            moved.append(n)
            if abs(z) > 3.0:
                beyond.append(n)
    with np.errstate(invalid="ignore", divide="ignore"):  # a constant column (a failed posterior): r undefined, NaN
        C = np.atleast_2d(np.corrcoef(draws, rowvar=False))  # one parameter: no pair
    iu = np.triu_indices(len(names), 1)
    order = np.argsort(-np.abs(np.nan_to_num(C[iu])))[: 2 * top]
    return dict(
        fisher_eigenvalues=[float(d.eigenvalue) for d in dirs],
        fim_condition_number=identifiability.condition_number(Fs),
        directions=rows,
        sloppy=rows[:top],
        n_round_off_eigenvalues=k_round,
        round_off_participation=participation,
        collinearity=identifiability.collinearity_table(R, names, sizes=(2, 3), top=top),
        coefficients=coef,
        moved=moved,
        moved_beyond_3sd=beyond,
        correlations=[dict(pair=[names[iu[0][i]], names[iu[1][i]]], r=float(C[iu][i])) for i in order],
    )
