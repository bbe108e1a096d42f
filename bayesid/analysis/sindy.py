"""Model-free term check with ensemble SINDy: which horizontal force terms does a track excite?

Pipeline (horizontal plane: surge X, sway Y, yaw N; w = p = q = 0, no planes):

1. :func:`estimate_motion` -- body velocities u, v, r and their derivatives from the track
   (measured u, v, r smoothed, or x, y, psi differentiated and rotated into the body frame).
2. :func:`force_targets` -- the hydrodynamic generalised forces by inverse dynamics of the rigid
   body (Fossen 2011, Ch. 3: ``M_RB nu_dot + C_RB(nu) nu``, restricted to u, v, r), minus the
   known added mass: what the hydrodynamic force terms of every equation must add up to.
3. :func:`candidate_library` -- one column per horizontal term of :mod:`bayesid.data.terms` (the
   factor product times ``0.5*rho*L**k``, so a fitted coefficient is the *prime* value), plus
   extras that the model lacks (constants, cubic terms, symmetry-forbidden surge terms, rudder
   rate).
4. :func:`inclusion_probabilities` -- ensemble SINDy (Fasel et al. 2022): STLSQ (Brunton, Proctor
   & Kutz 2016) on bootstrap resamples of the samples, one regression per equation over that
   equation's candidates; the inclusion probability of a term is the fraction of bootstrap models
   in which its coefficient survives the threshold. The bootstrap over single samples is
   :func:`ensemble_stlsq`; :func:`block_ensemble_stlsq` resamples blocks of samples (structure
   discovery's, :mod:`bayesid.analysis.gap.discovery`); both fit the same STLSQ.
5. :func:`compare_with_model` -- included terms versus the vehicle's non-zero coefficients.

Sources: S. L. Brunton, J. L. Proctor, J. N. Kutz (2016), Discovering governing equations from
data by sparse identification of nonlinear dynamical systems, PNAS 113(15):3932-3937 (SINDy,
STLSQ); U. Fasel, J. N. Kutz, B. W. Brunton, S. L. Brunton (2022), Ensemble-SINDy, Proc. R. Soc. A
478:20210904 (bagging, inclusion probabilities); T. I. Fossen (2011), Handbook of Marine Craft
Hydrodynamics and Motion Control, Wiley, Ch. 3 (rigid-body kinetics, M_RB and C_RB); A. Savitzky &
M. J. E. Golay (1964), Anal. Chem. 36(8):1627-1639 (smoothing differentiator).
"""

from __future__ import annotations

import contextlib
import warnings
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ..data import terms
from ..data.track import Track
from ..models import dynamics
from ..models.inverse import (
    ADDED_MASS,
    EQUATIONS,
    estimate_motion,
    force_targets,
    held_inputs,
    horizontal_terms,
    inputs_array,
    known_values,
    library_columns,
    motion_arrays,
    motion_filter,
    track_inputs,
)

# Extras: terms the term library does not have, as (equation, factor function, power of L).
# The factor function takes a dict with u, v, r, dr, dr_dot (smoothed) and U0 (nominal speed) and
# returns the velocity product; the column is that product times 0.5*rho*L**k, so (like the
# library terms) a fitted coefficient is dimensionless. Cubic terms are divided by u to keep the
# dimension of a force (Abkowitz form, e.g. Y = 0.5 rho L^2 Y'vvv v^3/u); the constants use the
# nominal speed U0 (Y0' = Y0 / (0.5 rho L^2 U0^2)).
_EXTRA_DEFS = {
    # surge: a constant and the terms port/starboard symmetry forbids (odd in v, r, dr)
    "X0": ("X", lambda s: np.full_like(s["u"], s["U0"] ** 2), 2),
    "Xv": ("X", lambda s: s["u"] * s["v"], 2),
    "Xr": ("X", lambda s: s["u"] * s["r"], 3),
    "Xdr": ("X", lambda s: s["u"] ** 2 * s["dr"], 2),
}
for _g, _m in (("Y", 0), ("N", 1)):
    _EXTRA_DEFS.update(
        {
            f"{_g}0": (_g, lambda s: np.full_like(s["u"], s["U0"] ** 2), 2 + _m),
            f"{_g}vvv": (_g, lambda s: s["v"] ** 3 / s["ug"], 2 + _m),
            f"{_g}rrr": (_g, lambda s: s["r"] ** 3 / s["ug"], 5 + _m),
            f"{_g}vvr": (_g, lambda s: s["v"] ** 2 * s["r"] / s["ug"], 3 + _m),
            f"{_g}vrr": (_g, lambda s: s["v"] * s["r"] ** 2 / s["ug"], 4 + _m),
            f"{_g}drdrdr": (_g, lambda s: s["u"] ** 2 * s["dr"] ** 3, 2 + _m),
            f"{_g}drdot": (_g, lambda s: s["u"] * s["dr_dot"], 3 + _m),  # rudder rate, rad/s
        }
    )
EXTRAS: tuple[str, ...] = tuple(_EXTRA_DEFS)
"""Names of the extra candidates (never in a vehicle model: their true value is 0)."""


def equation_of(name: str) -> str:
    """Equation of a candidate name (library term or extra).

    Parameters
    ----------
    name : str
        The candidate.

    Returns
    -------
    str
        ``"X"``, ``"Y"`` or ``"N"``.

    Raises
    ------
    ValueError
        If ``name`` is neither a horizontal library term nor an extra.
    """
    if name in _EXTRA_DEFS:
        return _EXTRA_DEFS[name][0]
    if name in terms.INDEX and terms.term(name).horizontal:
        return terms.term(name).group
    raise ValueError(
        f"{name!r} is not a horizontal-plane candidate term "
        f"(library terms: {[n for g in EQUATIONS for n in horizontal_terms(g)]}; "
        f"extras: {list(EXTRAS)})"
    )


# ---------------------------------------------------------------------------------------------
# 3. Candidate library
# ---------------------------------------------------------------------------------------------


def candidate_library(motion: dict, inputs, vehicle, extras: bool = True, exclude=()) -> tuple[np.ndarray, list[str]]:
    """Candidate columns of the three horizontal equations.

    Column ``j`` is the factor product of term ``j`` times ``multiplicity*0.5*rho*L**k`` (the
    term library's prime scale, :func:`bayesid.data.terms.prime_scale`), so that ``X = sum_j Theta[:,
    j] * C'_j`` over the X candidates with ``C'_j`` the *prime* coefficient. Acceleration terms
    (``Xudot``, ``Yvdot``, ``Yrdot``, ``Nvdot``, ``Nrdot``) use the estimated accelerations;
    ``Cd0`` uses ``u_c|u_c| - u|u|`` with ``u_c`` from the propeller speed. Features are those of
    the simulator (:func:`bayesid.models.dynamics.features`) at the estimated u, v, r and at the inputs
    in effect at the sample times (``motion["input_hold"]``); every column with an input factor
    (rudder, propeller) is then smoothed like the motion (``motion["smoother"]``), so both sides
    of the regression have the same bandwidth.

    Extras (``extras=True``; see :data:`EXTRAS`), all absent from the vehicle model:
    ``X0``, ``Y0``, ``N0`` (constant, ``0.5 rho L^k U0^2`` with ``U0`` the nominal speed);
    ``Xv`` (u v), ``Xr`` (u r), ``Xdr`` (u^2 dr) -- forbidden by port/starboard symmetry;
    for Y and N: ``vvv`` (v^3/u), ``rrr`` (r^3/u), ``vvr`` (v^2 r/u), ``vrr`` (v r^2/u),
    ``drdrdr`` (u^2 dr^3) and ``drdot`` (u * rudder rate). Powers of L follow the prime rule
    (one per rate factor, one more for N).

    Parameters
    ----------
    motion : dict
        From :func:`estimate_motion`.
    inputs : array_like, shape (n, 4)
        ``delta_r, delta_s, delta_b`` (rad), ``n`` (rpm); planes are ignored.
    vehicle : Vehicle
        The :class:`~bayesid.data.vehicle.Vehicle` (rho, L, nominal speed, propulsion).
    extras : bool, default True
        Add the extra candidates.
    exclude : iterable of str, default ()
        Names to leave out (e.g. terms passed as ``known`` to :func:`force_targets`).

    Returns
    -------
    Theta : ndarray, shape (n, K)
        N (X, Y columns) or N m (N columns) per unit prime coefficient.
    names : list of str
        The K names, grouped X, Y, N; in each group the library terms (table order), then the
        extras. :func:`equation_of` gives a name's equation.

    Raises
    ------
    ValueError
        A missing motion key; ``inputs`` of the wrong shape or non-finite (channel named);
        a rudder rate needed (``extras=True``) but ``motion["dr_dot"]`` missing or NaN.
    """
    exclude = set(exclude)
    names_lib = [k for g in EQUATIONS for k in horizontal_terms(g) if k not in exclude]
    Theta_lib = library_columns(names_lib, motion, inputs, vehicle)
    if not extras:
        return Theta_lib, names_lib
    u, v, r = motion_arrays(motion, ("u", "v", "r"))
    held = held_inputs(inputs_array(inputs, u.size), motion.get("input_hold", "sample"))
    dr_dot = motion.get("dr_dot")
    if dr_dot is None or not np.all(np.isfinite(dr_dot)):
        raise ValueError(
            "motion has no finite 'dr_dot' (rudder rate) for the drdot extras: "
            "the track needs a delta_r column (estimate_motion smooths and "
            "differentiates it), or pass extras=False"
        )
    ug = np.where(np.abs(u) > dynamics.U_MIN_EPS, u, np.copysign(dynamics.U_MIN_EPS, u))
    ss = [
        dict(
            u=u, v=v, r=r, ug=ug, dr=inp[:, 0], dr_dot=np.asarray(dr_dot, dtype=float), U0=float(vehicle.nominal_speed)
        )
        for inp in held
    ]
    names, cols = [], []
    for g in EQUATIONS:
        for k in names_lib:
            if terms.term(k).group == g:
                names.append(k)
                cols.append(Theta_lib[:, names_lib.index(k)])
        for k, (eq, fn, Lk) in _EXTRA_DEFS.items():
            if eq == g and k not in exclude:
                col = 0.5 * vehicle.rho * vehicle.L**Lk * sum(fn(s) for s in ss) / len(ss)
                if k[1:] in ("dr", "drdrdr"):  # raw rudder: smooth like the motion
                    col = motion_filter(col, motion)
                names.append(k)
                cols.append(col)
    return np.column_stack(cols), names


# ---------------------------------------------------------------------------------------------
# 4. Ensemble SINDy
# ---------------------------------------------------------------------------------------------


@contextlib.contextmanager
def legacy_seed(rng: np.random.Generator):
    """pysindy's EnsembleOptimizer draws its bootstrap indices from the legacy global
    ``np.random`` state; seed it from ``rng`` for the duration and restore it afterwards, so the
    result depends on ``rng`` only and the caller's global state is untouched.

    Parameters
    ----------
    rng : numpy.random.Generator
        Draws the legacy seed.
    """
    saved = np.random.get_state()
    np.random.seed(int(rng.integers(0, 2**32 - 1)))
    try:
        yield
    finally:
        np.random.set_state(saved)


def _stlsq(threshold: float, alpha: float = 0.0, unbias: bool = True):
    """pysindy ``STLSQ`` on already normalised columns, 20 iterations: the one sparse regression
    of both ensembles (pysindy and scikit-learn imported here, when a regression is first run:
    0.5 s of every command's start-up otherwise)."""
    import pysindy as ps

    return ps.STLSQ(threshold=threshold, alpha=alpha, normalize_columns=False, unbias=unbias, max_iter=20)


@contextlib.contextmanager
def _quiet_one_thread():
    """BLAS on one thread (the ensembles run inside parallel tasks) and STLSQ's warnings
    ("eliminated all coefficients", convergence) silenced."""
    with threadpool_limits(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


def ensemble_stlsq(
    Xn: np.ndarray, yn: np.ndarray, rng: np.random.Generator, threshold: float, alpha: float = 0.0, n_models: int = 100
) -> np.ndarray:
    """Ensemble sequentially thresholded least squares: pysindy ``STLSQ`` (Brunton, Proctor &
    Kutz 2016, PNAS 113(15); ``unbias``, 20 iterations, ridge ``alpha``) inside pysindy's
    ``EnsembleOptimizer`` with bagging (Fasel, Kutz, Brunton & Brunton 2022, Proc. R. Soc. A
    478), on already normalised columns ``Xn`` (n, K) and target ``yn`` (n,); the bootstrap is
    seeded from ``rng`` (:func:`legacy_seed`), BLAS on one thread.

    Bagging resamples single rows, as if they were independent; for rows correlated in time
    (windows of a track) see :func:`block_ensemble_stlsq`.

    Parameters
    ----------
    Xn : ndarray, shape (n, K)
        Normalised columns.
    yn : ndarray, shape (n,)
        Normalised target.
    rng : numpy.random.Generator
        Seeds the bootstrap.
    threshold : float
        STLSQ threshold.
    alpha : float, default 0.0
        Ridge weight.
    n_models : int, default 100
        Bootstrap models.

    Returns
    -------
    ndarray, shape (n_models, K)
        Coefficients; the inclusion probability of a column is the share of non-zero rows.
    """
    import pysindy as ps

    stl = _stlsq(float(threshold), float(alpha), unbias=True)
    ens = ps.EnsembleOptimizer(stl, bagging=True, n_models=int(n_models), replace=True)
    with legacy_seed(rng), _quiet_one_thread():
        ens.fit(Xn, yn)
    return np.array(ens.coef_list)[:, 0, :]


def block_ensemble_stlsq(
    Xn: np.ndarray,
    yn: np.ndarray,
    blocks: list,
    rng: np.random.Generator,
    threshold: float,
    ridge: float = 0.0,
    n_models: int = 100,
) -> np.ndarray:
    """Ensemble sequentially thresholded least squares over a **block bootstrap** of the rows:
    pysindy ``STLSQ`` (Brunton, Proctor & Kutz 2016, PNAS 113(15); no unbiasing, 20 iterations,
    ridge) fitted to ``n_models`` resamples, each drawing as many blocks as there are, with
    replacement (Ensemble-SINDy's bagging, Fasel, Kutz, Brunton & Brunton 2022, Proc. R. Soc. A
    478:20210904, with blocks instead of single rows: rows correlated in time, such as the
    samples of one window of a track, resampled one by one would overstate the certainty).

    STLSQ's ridge problem depends on the rows only through ``X'X`` and ``X'y``: each block's are
    summed once, a replicate sums its blocks', and STLSQ fits the K x K problem
    ``(R, R^-T X'y)`` with ``R'R = X'X`` (the same minimiser; tens of thousands of rows cost
    nothing more than one pass). BLAS runs on one thread.

    Parameters
    ----------
    Xn : ndarray, shape (n, K)
        Normalised columns.
    yn : ndarray, shape (n,)
        Normalised target.
    blocks : list of ndarray of int
        Row indices of each block (B blocks).
    rng : numpy.random.Generator
        Draws the blocks of each replicate: ``rng.integers(0, B, B)`` per model, in model order.
    threshold : float
        STLSQ threshold on the normalised coefficients.
    ridge : float, default 0.0
        Ridge weight per row: a replicate's STLSQ ridge ``alpha`` is ``ridge`` times its number of
        rows.
    n_models : int, default 100
        Bootstrap models.

    Returns
    -------
    ndarray, shape (n_models, K)
        Coefficients; the inclusion probability of a column is the share of non-zero rows.
    """
    G = np.stack([Xn[b].T @ Xn[b] for b in blocks])
    g = np.stack([Xn[b].T @ yn[b] for b in blocks])
    n = np.array([b.size for b in blocks], float)
    K = Xn.shape[1]
    stl = _stlsq(threshold, 0.0, unbias=False)
    xi = np.empty((n_models, K))
    with _quiet_one_thread():
        for m in range(n_models):
            pick = rng.integers(0, len(blocks), len(blocks))
            Gm, gm = G[pick].sum(axis=0), g[pick].sum(axis=0)
            R = np.linalg.cholesky(Gm + 1e-10 * np.trace(Gm) / K * np.eye(K)).T
            stl.alpha = ridge * n[pick].sum()
            stl.fit(R, np.linalg.solve(R.T, gm))
            xi[m] = stl.coef_[0]
    return xi


def _collinearity(Xn: np.ndarray) -> tuple[float, np.ndarray]:
    """Condition number of the normalised library and the (uncentred) variance inflation
    factor of each column, ``diag((Xn' Xn / n)^-1)`` (inf for an exactly dependent column)."""
    cond = float(np.linalg.cond(Xn))
    G = Xn.T @ Xn / Xn.shape[0]
    try:
        vif = np.diag(np.linalg.inv(G)).copy()
    except np.linalg.LinAlgError:
        vif = np.full(Xn.shape[1], np.inf)
    vif[~np.isfinite(vif) | (vif < 0)] = np.inf
    return cond, vif


@dataclass(frozen=True)
class SindyOptions:
    """The ensemble-SINDy term check's settings (:func:`inclusion_probabilities`).

    Parameters
    ----------
    n_models : int, default 100
        Bootstrap models (>= 1).
    threshold : float, default 0.05
        STLSQ threshold on the normalised coefficients (>= 0).
    extras : bool, default True
        Include the extra candidates (:data:`EXTRAS`).
    window_s : float, optional
        Smoothing window (s; :func:`estimate_motion`).
    polyorder : int, default 3
        Smoothing polynomial order (:func:`estimate_motion`).
    known : tuple or dict, default ADDED_MASS
        Names (vehicle values) or ``{name: prime value}`` of library terms subtracted from the
        target and removed from the candidates; must contain every term of :data:`ADDED_MASS`.
    ridge : float, default 0.0
        Ridge weight per sample on the normalised problem (>= 0).
    trim_s : float, optional
        Seconds dropped at either end (default: half the smoothing window).

    Raises
    ------
    ValueError
        ``n_models < 1``, a negative ``threshold`` or ``ridge``.
    """

    n_models: int = 100
    threshold: float = 0.05
    extras: bool = True
    window_s: float | None = None
    polyorder: int = 3
    known: object = ADDED_MASS
    ridge: float = 0.0
    trim_s: float | None = None

    def __post_init__(self):
        if int(self.n_models) < 1:
            raise ValueError(f"n_models must be >= 1, got {self.n_models}")
        if not self.threshold >= 0:
            raise ValueError(f"threshold must be >= 0, got {self.threshold}")
        if not self.ridge >= 0:
            raise ValueError(f"ridge must be >= 0, got {self.ridge}")


def inclusion_probabilities(
    track: Track,
    vehicle,
    options: SindyOptions = SindyOptions(),
    *,
    rng: np.random.Generator | None = None,
) -> dict:
    """Ensemble-SINDy inclusion probability of every horizontal candidate term.

    Per equation (X, Y, N) the candidates are that equation's library force terms and extras
    (:func:`candidate_library`, without the ``known`` terms), the target its column of
    :func:`force_targets` with the ``known`` terms (by default all added masses) subtracted.

    Normalisation and threshold: before the sparse regression every candidate column and the
    target are divided by their root-mean-square over the record (RMS rather than pysindy's L2
    norm, so the threshold does not depend on the number of samples). The normalised
    coefficient ``xi_j = C'_j * rms(Theta_j) / rms(F)`` is then the RMS of term j's
    contribution relative to the RMS of the whole force (for uncorrelated columns), and STLSQ
    drops terms with ``|xi_j| < threshold``: the default 0.05 keeps a term when it carries at
    least about 5 % of the force RMS. This is what "excited" means here. Caveat: when the force
    is a small difference of large terms (steady turns: N ~ 0 while rudder and damping moments
    are large) the individual xi are >> 1 and small errors in near-collinear columns clear the
    threshold easily; see ``condition`` and ``vif``.

    Regression: pysindy ``STLSQ`` (Brunton et al. 2016; ridge ``alpha = ridge * n`` on the
    normalised problem, default 0 = plain sequentially thresholded least squares, which on NPS
    AUV II selects better than any ridge tried; the support found is refitted without ridge)
    inside pysindy's ``EnsembleOptimizer`` with bagging (Fasel et al. 2022): ``n_models``
    bootstrap resamples of the samples, with replacement, each the size of the record. The
    inclusion probability of a term is the fraction of the models in which it survives;
    coefficients are the median over the models, zeros included ("bragging"), in prime form.
    The bootstrap indices come from ``rng`` (pysindy draws them from the legacy global
    ``np.random``, which is seeded from ``rng`` for the call and restored afterwards). Caveat:
    the samples are smoothed, hence autocorrelated over a window, and the bootstrap resamples
    them as if independent, so the probabilities come out sharper (nearer 0 or 1) than an
    honest block bootstrap would give.

    A column that is identically zero on the record (a term the manoeuvre cannot excite, e.g.
    ``Yr`` on a noise-free straight line) is left out of the regression, gets probability 0 and
    is listed in ``not_excited``; so is every candidate of an equation whose target is zero
    (nothing to explain). ``trim_s`` seconds (default half a window) are dropped at each end
    (Savitzky-Golay edge effects).

    Parameters
    ----------
    track : Track
        The track (see :func:`estimate_motion`); also needs ``delta_r`` (rad) and ``n`` (rpm).
    vehicle : Vehicle
        The :class:`~bayesid.data.vehicle.Vehicle` (mass properties, rho, L, propulsion; its
        coefficients are used only for the ``known`` terms).
    options : SindyOptions, default SindyOptions()
        Bootstrap models, threshold, extras, smoothing, known terms (by default exactly the
        added masses at the vehicle's values, see :func:`force_targets` for why), ridge, trim.
    rng : numpy.random.Generator
        All randomness (the bootstrap) comes from it. Required.

    Returns
    -------
    dict
        ``"X"``, ``"Y"``, ``"N"``: {term: inclusion probability in [0, 1]} (candidate order);
        ``"coefficients"``: {equation: {term: median prime coefficient}};
        ``"r2"``: {equation: R^2 of the median model on the record (NaN if the target is 0)};
        ``"condition"``: {equation: condition number of the normalised live columns};
        ``"vif"``: {equation: {term: variance inflation factor}} (large = indistinguishable
        from a combination of other candidates on this record);
        ``"not_excited"``: {equation: [terms with an all-zero column]};
        ``"known"``: {name: prime value subtracted}; ``"threshold"``, ``"n_models"``,
        ``"n_samples"``, ``"window_s"``, ``"source"`` (motion route), ``"normalisation"``.

    Raises
    ------
    TypeError
        ``rng`` is not a ``numpy.random.Generator``.
    ValueError
        A missing track column (named: psi, x, y, delta_r, n ...); ``known`` without an
        added-mass term (named); see also
        :func:`estimate_motion`, :func:`force_targets`.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("inclusion_probabilities: rng must be a numpy.random.Generator (all randomness comes from it)")
    n_models, threshold, extras, known = options.n_models, options.threshold, options.extras, options.known
    window_s, polyorder, ridge, trim_s = options.window_s, options.polyorder, options.ridge, options.trim_s
    motion = estimate_motion(track, window_s=window_s, polyorder=polyorder)
    inputs = track_inputs(track)
    kv = known_values(known, vehicle)
    missing = [k for k in ADDED_MASS if k not in kv]
    if missing:
        raise ValueError(
            f"known must include the added-mass terms {list(ADDED_MASS)} "
            f"(missing {missing}): with accelerations among the candidates the "
            "equations of motion are linear dependencies of the library and the "
            "regression is degenerate (see force_targets)"
        )
    F = force_targets(motion, vehicle, inputs, known=kv)
    Theta, names = candidate_library(motion, inputs, vehicle, extras=extras, exclude=list(kv))
    trim = motion["window_s"] / 2 if trim_s is None else float(trim_s)
    t = motion["t"]
    keep = (t >= t[0] + trim - 1e-9) & (t <= t[-1] - trim + 1e-9)
    if keep.sum() < 10:
        raise ValueError(f"track {track.name!r}: only {keep.sum()} samples left after trimming {trim:g} s at each end")
    Theta, F = Theta[keep], F[keep]
    n = Theta.shape[0]
    U0 = float(vehicle.nominal_speed)
    out = {"coefficients": {}, "r2": {}, "condition": {}, "vif": {}, "not_excited": {}}
    for e, g in enumerate(EQUATIONS):
        cand = [k for k in names if equation_of(k) == g]
        X = Theta[:, [names.index(k) for k in cand]]
        y = F[:, e]
        # "identically zero" is judged against the force scale 0.5 rho L^2 U0^2 (times L for N)
        fscale = 0.5 * vehicle.rho * vehicle.L ** (2 + (g == "N")) * U0**2
        rms_y = float(np.sqrt(np.mean(y**2)))
        rms_x = np.sqrt(np.mean(X**2, axis=0))
        live = rms_x > 1e-12 * fscale
        prob = np.zeros(len(cand))
        coef = np.zeros(len(cand))
        vif = np.full(len(cand), np.nan)
        out["not_excited"][g] = [k for k, ok in zip(cand, live) if not ok]
        if rms_y <= 1e-12 * fscale or not live.any():
            out["not_excited"][g] = list(cand)
            out[g] = {k: 0.0 for k in cand}
            out["coefficients"][g] = {k: 0.0 for k in cand}
            out["r2"][g] = out["condition"][g] = float("nan")
            out["vif"][g] = {k: float("nan") for k in cand}
            continue
        Xn = X[:, live] / rms_x[live]
        yn = y / rms_y
        xi = ensemble_stlsq(Xn, yn, rng, threshold, float(ridge) * n, n_models)  # (n_models, K_live)
        with threadpool_limits(1):
            cond, vif_live = _collinearity(Xn)
        prob[live] = np.mean(xi != 0.0, axis=0)
        coef[live] = np.median(xi, axis=0) * rms_y / rms_x[live]
        vif[live] = vif_live
        resid = y - X @ coef
        ss = float(np.sum((y - y.mean()) ** 2))
        out[g] = {k: float(p) for k, p in zip(cand, prob)}
        out["coefficients"][g] = {k: float(c) for k, c in zip(cand, coef)}
        out["r2"][g] = float(1.0 - np.sum(resid**2) / ss) if ss > 0 else float("nan")
        out["condition"][g] = cond
        out["vif"][g] = {k: float(v) for k, v in zip(cand, vif)}
    out.update(
        threshold=float(threshold),
        n_models=int(n_models),
        n_samples=int(n),
        window_s=float(motion["window_s"]),
        source=motion["source"],
        known=kv,
        normalisation="columns and target divided by their RMS over the record; "
        "threshold on |C' rms(column) / rms(target)|",
    )
    return out


# ---------------------------------------------------------------------------------------------
# 5. Comparison with a model
# ---------------------------------------------------------------------------------------------


def compare_with_model(inclusion: dict, vehicle, level: float = 0.5) -> dict:
    """Included terms (inclusion probability >= ``level``) against a vehicle model's terms.

    Parameters
    ----------
    inclusion : dict
        From :func:`inclusion_probabilities` (needs ``"X"``, ``"Y"``, ``"N"``).
    vehicle : Vehicle
        The :class:`~bayesid.data.vehicle.Vehicle`; a term is "in the model" if its prime
        coefficient is non-zero (extras never are).
    level : float, default 0.5
        Inclusion-probability level in (0, 1].

    Returns
    -------
    dict
        Per equation ``"X"``, ``"Y"``, ``"N"``: ``{"in_model": [...], "included": [...],
        "excited_and_in_model": [...], "in_model_not_seen": [...], "spurious": [...]}`` over that
        equation's candidates (candidate order).

    Raises
    ------
    ValueError
        ``level`` outside (0, 1]; ``inclusion`` without an equation (named).
    """
    if not 0.0 < level <= 1.0:
        raise ValueError(f"level must be in (0, 1], got {level}")
    out = {}
    for g in EQUATIONS:
        if g not in inclusion:
            raise ValueError(f"inclusion has no equation {g!r} (expected the output of inclusion_probabilities)")
        probs = inclusion[g]
        in_model = [k for k in probs if k not in _EXTRA_DEFS and vehicle.coefficients.get(k, 0.0) != 0.0]
        included = [k for k, p in probs.items() if p >= level]
        out[g] = {
            "in_model": in_model,
            "included": included,
            "excited_and_in_model": [k for k in included if k in in_model],
            "in_model_not_seen": [k for k in in_model if k not in included],
            "spurious": [k for k in included if k not in in_model],
        }
    return out


__all__ = [
    "SindyOptions",
    "EQUATIONS",
    "ADDED_MASS",
    "EXTRAS",
    "horizontal_terms",
    "equation_of",
    "estimate_motion",
    "force_targets",
    "candidate_library",
    "inclusion_probabilities",
    "ensemble_stlsq",
    "block_ensemble_stlsq",
    "compare_with_model",
]
