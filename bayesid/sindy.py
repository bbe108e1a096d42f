"""Model-free term check with ensemble SINDy: which horizontal force terms does a track excite?

Pipeline (horizontal plane: surge X, sway Y, yaw N; w = p = q = 0, no planes):

1. :func:`estimate_motion` -- body velocities u, v, r and their derivatives from the track
   (measured u, v, r smoothed, or x, y, psi differentiated and rotated into the body frame).
2. :func:`force_targets` -- the hydrodynamic generalised forces by inverse dynamics of the rigid
   body (Fossen 2011, Ch. 3: ``M_RB nu_dot + C_RB(nu) nu``, restricted to u, v, r), minus the
   known added mass: what the hydrodynamic force terms of every equation must add up to.
3. :func:`candidate_library` -- one column per horizontal term of :mod:`bayesid.terms` (the
   factor product times ``0.5*rho*L**k``, so a fitted coefficient is the *prime* value), plus
   extras that the model lacks (constants, cubic terms, symmetry-forbidden surge terms, rudder
   rate).
4. :func:`inclusion_probabilities` -- ensemble SINDy (Fasel et al. 2022): STLSQ (Brunton, Proctor
   & Kutz 2016) on bootstrap resamples of the samples, one regression per equation over that
   equation's candidates; the inclusion probability of a term is the fraction of bootstrap models
   in which its coefficient survives the threshold.
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
import math
import warnings

import numpy as np
import pysindy as ps
from scipy.signal import savgol_filter
from threadpoolctl import threadpool_limits

from . import dynamics, terms
from .track import Track

EQUATIONS = ("X", "Y", "N")
#: The horizontal acceleration (added-mass) terms; the regression needs them known (see
#: :func:`force_targets`).
ADDED_MASS: tuple[str, ...] = tuple(terms.names_where(kind="added_mass", horizontal=True))
_PLANE = [0, 1, 5]  # u, v, r rows/columns of the 6x6 mass matrix

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
    _EXTRA_DEFS.update({
        f"{_g}0": (_g, lambda s: np.full_like(s["u"], s["U0"] ** 2), 2 + _m),
        f"{_g}vvv": (_g, lambda s: s["v"] ** 3 / s["ug"], 2 + _m),
        f"{_g}rrr": (_g, lambda s: s["r"] ** 3 / s["ug"], 5 + _m),
        f"{_g}vvr": (_g, lambda s: s["v"] ** 2 * s["r"] / s["ug"], 3 + _m),
        f"{_g}vrr": (_g, lambda s: s["v"] * s["r"] ** 2 / s["ug"], 4 + _m),
        f"{_g}drdrdr": (_g, lambda s: s["u"] ** 2 * s["dr"] ** 3, 2 + _m),
        f"{_g}drdot": (_g, lambda s: s["u"] * s["dr_dot"], 3 + _m),  # rudder rate, rad/s
    })
EXTRAS: tuple[str, ...] = tuple(_EXTRA_DEFS)
"""Names of the extra candidates (never in a vehicle model: their true value is 0)."""

def horizontal_terms(equation: str) -> list[str]:
    """Term-library names of one horizontal equation (``"X"``, ``"Y"`` or ``"N"``), table order."""
    if equation not in EQUATIONS:
        raise ValueError(f"equation must be one of {EQUATIONS}, got {equation!r}")
    return terms.names_where(group=equation, horizontal=True)


def equation_of(name: str) -> str:
    """Equation (``"X"``, ``"Y"``, ``"N"``) of a candidate name (library term or extra).

    Raises
    ------
    ValueError
        If ``name`` is neither a horizontal library term nor an extra.
    """
    if name in _EXTRA_DEFS:
        return _EXTRA_DEFS[name][0]
    if name in terms.INDEX and terms.term(name).horizontal:
        return terms.term(name).group
    raise ValueError(f"{name!r} is not a horizontal-plane candidate term "
                     f"(library terms: {[n for g in EQUATIONS for n in horizontal_terms(g)]}; "
                     f"extras: {list(EXTRAS)})")


# ---------------------------------------------------------------------------------------------
# 1. Motion
# ---------------------------------------------------------------------------------------------

def _column(track: Track, name: str, why: str) -> np.ndarray:
    if name not in track:
        raise ValueError(f"track {track.name!r} has no column {name!r} ({why}); "
                         f"columns: {['t', *track.data]}")
    col = track[name]
    bad = np.flatnonzero(~np.isfinite(col))
    if bad.size:
        raise ValueError(f"track {track.name!r}: column {name!r} is missing (NaN) at sample "
                         f"{bad[0]} (t = {track.t[bad[0]]:g} s); the smoothing differentiator "
                         "needs a gap-free, uniformly sampled record")
    return col


def _window_samples(window_s: float, dt: float, polyorder: int, n: int) -> int:
    w = int(round(window_s / dt))
    w += 1 - w % 2  # odd
    w = max(w, polyorder + 1 + polyorder % 2)  # the smallest odd length > polyorder
    if w > n:
        raise ValueError(f"smoothing window {window_s:g} s ({w} samples) is longer than the track "
                         f"({n} samples of {dt:g} s)")
    return w


def _sfd(window: int, polyorder: int) -> ps.SmoothedFiniteDifference:
    # A fresh smoother_kws dict each time: pysindy mutates its (shared) default dict.
    kws = {"window_length": window, "polyorder": polyorder}
    return ps.SmoothedFiniteDifference(smoother_kws=kws)


def _smooth_diff(x: np.ndarray, t: np.ndarray, window: int, polyorder: int):
    """Savitzky-Golay smoothing then second-order central differences (pysindy
    SmoothedFiniteDifference); returns (smoothed, derivative), both (n, k)."""
    d = _sfd(window, polyorder)
    xdot = np.asarray(d(np.asarray(x, dtype=float), t))
    return np.asarray(d.smoothed_x_), xdot


def _motion_filter(x: np.ndarray, motion: dict) -> np.ndarray:
    """The smoothing the motion went through (``passes`` Savitzky-Golay passes), along axis 0."""
    sm = motion.get("smoother")
    if sm is None:
        return np.asarray(x, dtype=float)
    y = np.asarray(x, dtype=float)
    for _ in range(int(sm["passes"])):
        y = savgol_filter(y, sm["window"], sm["polyorder"], axis=0)
    return y


def _held_inputs(inputs: np.ndarray, hold: str) -> list[np.ndarray]:
    """The input values in effect at the sample times, to be averaged over.

    ``"zoh"``: the input stored at sample k is held over [t_k, t_k+1) (the simulator's and
    :class:`~bayesid.simulate.SimResult`'s convention), so a central derivative at t_k sees half
    of the value held before and half of the value held after: a column ``f(state, input)`` is
    ``(f(state_k, in_k-1) + f(state_k, in_k)) / 2`` (averaging f, not the input, keeps nonlinear
    terms such as ``dr**2`` right across a rudder reversal). ``"sample"``: the stored value is
    the (continuous) signal at t_k; used as is.
    """
    if hold == "sample":
        return [inputs]
    prev = np.vstack([inputs[:1], inputs[:-1]])
    return [prev, inputs]


def estimate_motion(track: Track, window_s: float | None = None, polyorder: int = 3,
                    use_velocities: bool | None = None, input_hold: str = "zoh") -> dict:
    """Body-frame velocities and accelerations of a horizontal track.

    Two routes:

    * **measured velocities** (``u``, ``v``, ``r`` all in the track; the default when present):
      each is smoothed with a Savitzky-Golay filter and differentiated by central differences of
      the smoothed signal (pysindy ``SmoothedFiniteDifference``): one smoothing pass.
    * **positions** (otherwise, or ``use_velocities=False``): ``x``, ``y`` and the unwrapped
      ``psi`` are differentiated the same way, the earth-frame velocity is rotated into the body
      frame, ``u = cos(psi) x_dot + sin(psi) y_dot``, ``v = -sin(psi) x_dot + cos(psi) y_dot``,
      ``r = psi_dot`` (horizontal plane, phi = theta = 0; Fossen 2011, Ch. 2), and u, v, r are
      smoothed and differentiated once more for the accelerations: two smoothing passes.

    The returned ``smoother`` records the window and number of passes;
    :func:`candidate_library` passes every input-dependent column through the same smoothing, so
    that both sides of the regression have the same bandwidth (filtering a linear relation with
    one linear filter keeps it; a step of the rudder is smeared alike in r_dot and in the rudder
    moment). The rudder angle (if the track has ``delta_r``) is returned smoothed the same way,
    with its derivative (the rudder rate).

    Window choice (defaults measured on NPS AUV II at 10 Hz; see the report of issue 4):
    ``window_s = 1.0`` s for measured velocities -- short against the ~3 s yaw time constant;
    ``window_s = 8.0`` s from positions -- with 0.2 m / 0.2 deg noise the accelerations (a
    second smoothed derivative of the positions) are the noisiest quantity and set this choice:
    the error of the sway force target falls from ~2.6 kN (2 s) to ~0.6 kN (4 s) and ~0.13 kN
    (8 s) against a signal of 0.2-0.5 kN. The longer window costs little bias in the
    regression because the input columns are smoothed alike (the true model's residual on
    smoothed noise-free data stays at a few per cent).
    The window is rounded to an odd number of samples (at least polyorder + 2).

    Parameters
    ----------
    track : Track
        Needs ``t`` (s, uniform sampling) and ``psi`` (rad; always required: the check is defined
        for horizontal tracks with heading); ``x``, ``y`` (m) unless u, v, r are used; ``u``,
        ``v`` (m/s), ``r`` (rad/s) optional; ``delta_r`` (rad) optional.
    window_s : float, optional
        Savitzky-Golay window, s. Default 1.0 (measured velocities) or 8.0 (positions).
    polyorder : int
        Savitzky-Golay polynomial order (default 3).
    use_velocities : bool, optional
        Force a route; default: measured velocities if u, v and r are all present.
    input_hold : ``"zoh"`` (default) or ``"sample"``
        How the input columns are to be read: ``"zoh"`` -- the value stored at sample k is held
        over [t_k, t_k+1) (the simulator's convention), so the value in effect at t_k for a
        central derivative is the mean of samples k-1 and k; ``"sample"`` -- the value at t_k
        (a logged, continuous rudder angle). Ignoring a ZOH costs 8-12 % of the yaw-moment RMS
        on NPS AUV II manoeuvres (measured), so it matters for noise-free checks.

    Returns
    -------
    dict
        ``t`` (n,) s; ``u``, ``v`` (n,) m/s; ``r`` (n,) rad/s; ``u_dot``, ``v_dot`` (n,) m/s^2;
        ``r_dot`` (n,) rad/s^2; ``psi`` (n,) rad unwrapped; ``dr`` (n,) rad and ``dr_dot`` (n,)
        rad/s (smoothed rudder and its rate; absent without ``delta_r``); ``window_s`` (the
        window used, s); ``smoother`` (``{"window": samples, "polyorder", "passes"}``);
        ``input_hold``; ``source`` (``"velocities"`` or ``"positions"``).

    Raises
    ------
    ValueError
        Naming the column: ``psi`` absent; ``x``/``y`` absent on the positions route; u, v or r
        absent with ``use_velocities=True``; NaN in a needed column; non-uniform sampling; a
        window longer than the track; a bad ``input_hold``.
    """
    if input_hold not in ("zoh", "sample"):
        raise ValueError(f"input_hold must be 'zoh' or 'sample', got {input_hold!r}")
    psi = _column(track, "psi", "heading is required")
    t = track.t
    n = t.size
    if n < 5:
        raise ValueError(f"track {track.name!r} has {n} samples; need at least 5")
    dts = np.diff(t)
    dt = float(np.median(dts))
    if np.max(np.abs(dts - dt)) > 1e-6 * dt + 1e-9:
        i = int(np.argmax(np.abs(dts - dt)))
        raise ValueError(f"track {track.name!r}: column 't' is not uniformly sampled (step "
                         f"{dts[i]:g} s at index {i + 1}, median {dt:g} s); resample first")
    have_vel = all(c in track for c in ("u", "v", "r"))
    if use_velocities is None:
        use_velocities = have_vel
    if use_velocities:
        for c in ("u", "v", "r"):
            _column(track, c, "use_velocities=True needs measured u, v, r")
    if window_s is None:
        window_s = 1.0 if use_velocities else 8.0
    if not (isinstance(window_s, (int, float)) and window_s > 0 and math.isfinite(window_s)):
        raise ValueError(f"window_s must be a positive number of seconds, got {window_s!r}")
    polyorder = int(polyorder)
    if polyorder < 1:
        raise ValueError(f"polyorder must be >= 1, got {polyorder}")
    w = _window_samples(window_s, dt, polyorder, n)
    psi_u = np.unwrap(psi)
    if use_velocities:
        nu = np.column_stack([track["u"], track["v"], track["r"]])
        source, passes = "velocities", 1
    else:
        x = _column(track, "x", "positions route: x, y, psi are differentiated")
        y = _column(track, "y", "positions route: x, y, psi are differentiated")
        _, eta_dot = _smooth_diff(np.column_stack([x, y, psi_u]), t, w, polyorder)
        c, s = np.cos(psi_u), np.sin(psi_u)
        nu = np.column_stack([c * eta_dot[:, 0] + s * eta_dot[:, 1],
                              -s * eta_dot[:, 0] + c * eta_dot[:, 1], eta_dot[:, 2]])
        source, passes = "positions", 2
    nu_s, nu_dot = _smooth_diff(nu, t, w, polyorder)
    motion = dict(t=t.copy(), u=nu_s[:, 0], v=nu_s[:, 1], r=nu_s[:, 2], u_dot=nu_dot[:, 0],
                  v_dot=nu_dot[:, 1], r_dot=nu_dot[:, 2], psi=psi_u, window_s=w * dt,
                  smoother=dict(window=w, polyorder=polyorder, passes=passes),
                  input_hold=input_hold, source=source)
    if "delta_r" in track:
        held = _held_inputs(_column(track, "delta_r", "rudder")[:, None], input_hold)
        dr_s = _motion_filter(sum(held) / len(held), motion)
        motion["dr"] = dr_s[:, 0]
        motion["dr_dot"] = np.asarray(ps.FiniteDifference()(dr_s, t))[:, 0]
    return motion


# ---------------------------------------------------------------------------------------------
# 2. Force targets (inverse dynamics)
# ---------------------------------------------------------------------------------------------

def _motion_arrays(motion: dict, keys=("u", "v", "r", "u_dot", "v_dot", "r_dot")):
    out = []
    n = None
    for k in keys:
        if k not in motion:
            raise ValueError(f"motion has no {k!r} (use estimate_motion); keys: {sorted(motion)}")
        a = np.asarray(motion[k], dtype=float)
        if a.ndim != 1 or (n is not None and a.size != n):
            raise ValueError(f"motion[{k!r}] must be 1-D of the common length, got shape {a.shape}")
        n = a.size
        out.append(a)
    return out


def _known_values(known, vehicle) -> dict:
    """``known`` as {name: prime value}: a mapping is taken as is, a sequence of names takes the
    vehicle's values. Raises ValueError naming a name that is not a horizontal library term."""
    vals = dict(known) if isinstance(known, dict) else {k: None for k in known}
    for k in vals:
        if k in _EXTRA_DEFS or k not in terms.INDEX or not terms.term(k).horizontal:
            raise ValueError(f"known term {k!r} is not a horizontal term of the term library")
    return {k: float(vehicle.coefficients.get(k, 0.0) if v is None else v) for k, v in vals.items()}


def force_targets(motion: dict, vehicle, inputs=None, known=()) -> np.ndarray:
    """Hydrodynamic generalised forces X, Y, N by rigid-body inverse dynamics.

    ``tau_hydro = M_RB nu_dot + C_RB(nu) nu`` on the horizontal plane (Fossen 2011, Ch. 3,
    rigid-body kinetics with w = p = q = 0; the left-hand sides of the simulator's equations,
    :func:`bayesid.dynamics.generalized_force`):

        X = m (u_dot - v r - xG r^2 - yG r_dot)
        Y = m (v_dot + u r - yG r^2 + xG r_dot)
        N = Iz r_dot + m xG (v_dot + u r) - m yG (u_dot - v r)

    with ``M_RB`` the (u, v, r) block of ``vehicle.mass_matrix({})``. With ``known=()`` everything
    hydrodynamic is left in the target: added mass (``Xudot*u_dot`` ...), damping, rudder and
    propulsion (``Cd0``). Hydrostatics vanish on the horizontal plane.

    With ``known``, the contributions ``C' * column`` of those library terms are subtracted as
    well. A regression needs every acceleration term known (:data:`ADDED_MASS`: ``Xudot``,
    ``Yvdot``, ``Yrdot``, ``Nvdot``, ``Nrdot``; the default of :func:`inclusion_probabilities`):

    * without the diagonal ones the target is *itself* a combination of candidate columns
      (``m*u_dot`` is the ``Xudot`` column times m', ``-m*v*r`` the ``Xvr`` column times -m'),
      and a sparse regression returns that trivial two-term representation (measured on every
      manoeuvre: X'udot = +m', X'vr = -m', R^2 = 1);
    * with an off-diagonal one as a candidate (``Nvdot``: the v_dot column in the N equation),
      the *sway* equation of motion, ``(m - Y'vdot) v_dot = Y'v u v + Y'r u r + ...``, is a
      linear dependency among the N candidates, so any multiple of it can be added to the N
      model (measured: N'vdot = +m' on the spiral, wrong signs of N'v, N'r).

    With accelerations only in the target, the candidates are functions of (u, v, r, inputs)
    alone and no equation of motion relates them exactly: the explicit form SINDy needs
    (Brunton et al. 2016). Added masses come from elsewhere (strip theory, the vehicle file).

    Parameters
    ----------
    motion : dict from :func:`estimate_motion` (u, v, r, u_dot, v_dot, r_dot; (n,) each).
    vehicle : :class:`~bayesid.vehicle.Vehicle` (mass, inertia, rG; rho and L for ``known``).
    inputs : (n, 4) array, optional
        ``delta_r, delta_s, delta_b`` (rad), ``n`` (rpm); needed only for ``known`` force terms.
    known : sequence of str or dict
        Horizontal library terms taken as known: names (the vehicle's prime values) or
        ``{name: prime value}``.

    Returns
    -------
    ndarray (n, 3)
        X (N), Y (N), N (N m).

    Raises
    ------
    ValueError
        A missing motion key; a ``known`` name that is not a horizontal library term (named);
        ``inputs`` missing or malformed when a known force term needs them.
    """
    u, v, r, ud, vd, rd = _motion_arrays(motion)
    Mrb = vehicle.mass_matrix({})[np.ix_(_PLANE, _PLANE)]
    m = vehicle.mass
    xg, yg = float(vehicle.rG[0]), float(vehicle.rG[1])
    acc = np.column_stack([ud, vd, rd]) @ Mrb.T
    cor = np.column_stack([m * (-v * r - xg * r * r),
                           m * (u * r - yg * r * r),
                           m * (xg * u * r + yg * v * r)])
    F = acc + cor
    kv = _known_values(known, vehicle)
    if kv:
        names = list(kv)
        cols = _library_columns(names, motion, inputs, vehicle)
        for j, k in enumerate(names):
            F[:, EQUATIONS.index(terms.term(k).group)] -= kv[k] * cols[:, j]
    return F


# ---------------------------------------------------------------------------------------------
# 3. Candidate library
# ---------------------------------------------------------------------------------------------

def _inputs_array(inputs, n: int) -> np.ndarray:
    if inputs is None:
        raise ValueError("inputs (n, 4) are needed: delta_r (rad) and n (rpm) enter the rudder and "
                         "propulsion terms")
    a = np.asarray(inputs, dtype=float)
    if a.shape != (n, 4):
        raise ValueError(f"inputs must be (n, 4) = delta_r, delta_s, delta_b, n with n = {n}, "
                         f"got {a.shape}")
    for j, c in enumerate(("delta_r", "delta_s", "delta_b", "n")):
        bad = np.flatnonzero(~np.isfinite(a[:, j]))
        if bad.size:
            raise ValueError(f"inputs: {c} is not finite at sample {bad[0]}")
    return a


_INPUT_FACTORS = {"dr", "ds", "db", "prop", "eps"}


def _library_columns(names, motion: dict, inputs, vehicle) -> np.ndarray:
    """Columns (n, len(names)) of library terms (force and acceleration) at the motion.

    Force terms use the simulator's features at (u, v, r) and the inputs in effect at the sample
    times (see ``motion["input_hold"]``); a column with an input factor (rudder, propeller) is
    then passed through the motion's smoothing (``motion["smoother"]``)."""
    u, v, r, ud, vd, rd = _motion_arrays(motion)
    n = u.size
    out = np.empty((n, len(names)))
    force = [k for k in names if terms.term(k).kind == "force"]
    if force:
        held = _held_inputs(_inputs_array(inputs, n), motion.get("input_hold", "sample"))
        states = np.zeros((n, 12))
        states[:, 6], states[:, 7], states[:, 11] = u, v, r
        phi = 0.0
        for inp in held:
            inp = inp.copy()
            inp[:, 1:3] = 0.0  # horizontal plane: no plane terms
            feats = dynamics.features_array(states, inp, vehicle)
            phi = phi + terms.regressors(feats, force, vehicle.rho, vehicle.L) / len(held)
        dep = [j for j, k in enumerate(force) if _INPUT_FACTORS & set(terms.term(k).factors)]
        if dep:
            phi[:, dep] = _motion_filter(phi[:, dep], motion)
    accel = {"u": ud, "v": vd, "r": rd}
    jf = 0
    for j, k in enumerate(names):
        t = terms.term(k)
        if t.kind == "force":
            out[:, j] = phi[:, jf]
            jf += 1
        else:
            scale = 0.5 * vehicle.rho * vehicle.L ** t.L_power
            out[:, j] = scale * accel[terms.VELOCITIES[t.accel]]
    return out


def candidate_library(motion: dict, inputs, vehicle, extras: bool = True,
                      exclude=()) -> tuple[np.ndarray, list[str]]:
    """Candidate columns of the three horizontal equations.

    Column ``j`` is the factor product of term ``j`` times ``multiplicity*0.5*rho*L**k`` (the
    term library's prime scale, :func:`bayesid.terms.prime_scale`), so that ``X = sum_j Theta[:,
    j] * C'_j`` over the X candidates with ``C'_j`` the *prime* coefficient. Acceleration terms
    (``Xudot``, ``Yvdot``, ``Yrdot``, ``Nvdot``, ``Nrdot``) use the estimated accelerations;
    ``Cd0`` uses ``u_c|u_c| - u|u|`` with ``u_c`` from the propeller speed. Features are those of
    the simulator (:func:`bayesid.dynamics.features`) at the estimated u, v, r and at the inputs
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
    motion : dict from :func:`estimate_motion`.
    inputs : (n, 4) ``delta_r, delta_s, delta_b`` (rad), ``n`` (rpm); planes are ignored.
    vehicle : :class:`~bayesid.vehicle.Vehicle` (rho, L, nominal speed, propulsion).
    extras : add the extra candidates.
    exclude : names to leave out (e.g. terms passed as ``known`` to :func:`force_targets`).

    Returns
    -------
    Theta : ndarray (n, K), N (X, Y columns) or N m (N columns) per unit prime coefficient.
    names : list of K str, grouped X, Y, N; in each group the library terms (table order), then
        the extras. :func:`equation_of` gives a name's equation.

    Raises
    ------
    ValueError
        A missing motion key; ``inputs`` of the wrong shape or non-finite (channel named);
        a rudder rate needed (``extras=True``) but ``motion["dr_dot"]`` missing or NaN.
    """
    exclude = set(exclude)
    names_lib = [k for g in EQUATIONS for k in horizontal_terms(g) if k not in exclude]
    Theta_lib = _library_columns(names_lib, motion, inputs, vehicle)
    if not extras:
        return Theta_lib, names_lib
    u, v, r = _motion_arrays(motion, ("u", "v", "r"))
    held = _held_inputs(_inputs_array(inputs, u.size), motion.get("input_hold", "sample"))
    dr_dot = motion.get("dr_dot")
    if dr_dot is None or not np.all(np.isfinite(dr_dot)):
        raise ValueError("motion has no finite 'dr_dot' (rudder rate) for the drdot extras: "
                         "the track needs a delta_r column (estimate_motion smooths and "
                         "differentiates it), or pass extras=False")
    ug = np.where(np.abs(u) > dynamics.U_MIN_EPS, u, np.copysign(dynamics.U_MIN_EPS, u))
    ss = [dict(u=u, v=v, r=r, ug=ug, dr=inp[:, 0], dr_dot=np.asarray(dr_dot, dtype=float),
               U0=float(vehicle.nominal_speed)) for inp in held]
    names, cols = [], []
    for g in EQUATIONS:
        for k in names_lib:
            if terms.term(k).group == g:
                names.append(k)
                cols.append(Theta_lib[:, names_lib.index(k)])
        for k, (eq, fn, Lk) in _EXTRA_DEFS.items():
            if eq == g and k not in exclude:
                col = 0.5 * vehicle.rho * vehicle.L ** Lk * sum(fn(s) for s in ss) / len(ss)
                if k[1:] in ("dr", "drdrdr"):  # raw rudder: smooth like the motion
                    col = _motion_filter(col, motion)
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
    result depends on ``rng`` only and the caller's global state is untouched."""
    saved = np.random.get_state()
    np.random.seed(int(rng.integers(0, 2**32 - 1)))
    try:
        yield
    finally:
        np.random.set_state(saved)


def ensemble_stlsq(Xn: np.ndarray, yn: np.ndarray, rng: np.random.Generator, threshold: float,
                   alpha: float = 0.0, n_models: int = 100) -> np.ndarray:
    """Ensemble sequentially thresholded least squares: pysindy ``STLSQ`` (Brunton, Proctor &
    Kutz 2016, PNAS 113(15); ``unbias``, 20 iterations, ridge ``alpha``) inside pysindy's
    ``EnsembleOptimizer`` with bagging (Fasel, Kutz, Brunton & Brunton 2022, Proc. R. Soc. A
    478), on already normalised columns ``Xn`` (n, K) and target ``yn`` (n,); the bootstrap is
    seeded from ``rng`` (:func:`legacy_seed`), BLAS on one thread.

    Returns (n_models, K) coefficients; the inclusion probability of a column is the share of
    non-zero rows."""
    stl = ps.STLSQ(threshold=float(threshold), alpha=float(alpha), normalize_columns=False, unbias=True, max_iter=20)
    ens = ps.EnsembleOptimizer(stl, bagging=True, n_models=int(n_models), replace=True)
    with legacy_seed(rng), threadpool_limits(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # STLSQ "eliminated all coefficients", convergence
        ens.fit(Xn, yn)
    return np.array(ens.coef_list)[:, 0, :]


def track_inputs(track: Track) -> np.ndarray:
    """(n_samples, 4) inputs ``delta_r, delta_s, delta_b, n`` of a track (rad, rpm), absent
    columns 0. Raises ValueError naming the track when ``delta_r`` or ``n`` is missing."""
    for c, why in (("delta_r", "rudder terms"), ("n", "propulsion term Cd0 (rpm)")):
        _column(track, c, why)
    return track.inputs(fill=0.0)


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


def inclusion_probabilities(track: Track, vehicle, n_models: int = 100, threshold: float = 0.05,
                            rng: np.random.Generator | None = None, extras: bool = True,
                            window_s: float | None = None, polyorder: int = 3,
                            known=ADDED_MASS, ridge: float = 0.0,
                            trim_s: float | None = None) -> dict:
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
    AUV II selected better than any ridge tried; the support found is refitted without ridge)
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
    track : Track (see :func:`estimate_motion`); also needs ``delta_r`` (rad) and ``n`` (rpm).
    vehicle : :class:`~bayesid.vehicle.Vehicle` (mass properties, rho, L, propulsion; its
        coefficients are used only for the ``known`` terms).
    n_models : number of bootstrap models (>= 1).
    threshold : STLSQ threshold on the normalised coefficients (>= 0).
    rng : numpy.random.Generator -- all randomness (the bootstrap) comes from it. Required.
    extras : include the extra candidates (:data:`EXTRAS`).
    window_s, polyorder : smoothing (see :func:`estimate_motion`).
    known : names (vehicle values) or {name: prime value} of library terms subtracted from the
        target and removed from the candidates; must contain every term of :data:`ADDED_MASS`
        (default: exactly those, at the vehicle's values; see :func:`force_targets` for why).
    ridge : ridge weight per sample on the normalised problem (default 0).
    trim_s : seconds dropped at either end (default: half the smoothing window).

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
        A missing track column (named: psi, x, y, delta_r, n ...); ``n_models < 1``; negative
        ``threshold`` or ``ridge``; ``known`` without an added-mass term (named); see also
        :func:`estimate_motion`, :func:`force_targets`.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("inclusion_probabilities: rng must be a numpy.random.Generator "
                        "(all randomness comes from it)")
    if int(n_models) < 1:
        raise ValueError(f"n_models must be >= 1, got {n_models}")
    if not threshold >= 0:
        raise ValueError(f"threshold must be >= 0, got {threshold}")
    if not ridge >= 0:
        raise ValueError(f"ridge must be >= 0, got {ridge}")
    motion = estimate_motion(track, window_s=window_s, polyorder=polyorder)
    inputs = track_inputs(track)
    kv = _known_values(known, vehicle)
    missing = [k for k in ADDED_MASS if k not in kv]
    if missing:
        raise ValueError(f"known must include the added-mass terms {list(ADDED_MASS)} "
                         f"(missing {missing}): with accelerations among the candidates the "
                         "equations of motion are linear dependencies of the library and the "
                         "regression is degenerate (see force_targets)")
    F = force_targets(motion, vehicle, inputs, known=kv)
    Theta, names = candidate_library(motion, inputs, vehicle, extras=extras, exclude=list(kv))
    trim = motion["window_s"] / 2 if trim_s is None else float(trim_s)
    t = motion["t"]
    keep = (t >= t[0] + trim - 1e-9) & (t <= t[-1] - trim + 1e-9)
    if keep.sum() < 10:
        raise ValueError(f"track {track.name!r}: only {keep.sum()} samples left after trimming "
                         f"{trim:g} s at each end")
    Theta, F = Theta[keep], F[keep]
    n = Theta.shape[0]
    U0 = float(vehicle.nominal_speed)
    out = {"coefficients": {}, "r2": {}, "condition": {}, "vif": {}, "not_excited": {}}
    for e, g in enumerate(EQUATIONS):
        cand = [k for k in names if equation_of(k) == g]
        X = Theta[:, [names.index(k) for k in cand]]
        y = F[:, e]
        # "identically zero" is judged against the force scale 0.5 rho L^2 U0^2 (times L for N)
        fscale = 0.5 * vehicle.rho * vehicle.L ** (2 + (g == "N")) * U0 ** 2
        rms_y = float(np.sqrt(np.mean(y ** 2)))
        rms_x = np.sqrt(np.mean(X ** 2, axis=0))
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
        out["r2"][g] = float(1.0 - np.sum(resid ** 2) / ss) if ss > 0 else float("nan")
        out["condition"][g] = cond
        out["vif"][g] = {k: float(v) for k, v in zip(cand, vif)}
    out.update(threshold=float(threshold), n_models=int(n_models), n_samples=int(n),
               window_s=float(motion["window_s"]), source=motion["source"], known=kv,
               normalisation="columns and target divided by their RMS over the record; "
                             "threshold on |C' rms(column) / rms(target)|")
    return out


# ---------------------------------------------------------------------------------------------
# 5. Comparison with a model
# ---------------------------------------------------------------------------------------------

def compare_with_model(inclusion: dict, vehicle, level: float = 0.5) -> dict:
    """Included terms (inclusion probability >= ``level``) against a vehicle model's terms.

    Parameters
    ----------
    inclusion : dict from :func:`inclusion_probabilities` (needs ``"X"``, ``"Y"``, ``"N"``).
    vehicle : :class:`~bayesid.vehicle.Vehicle`; a term is "in the model" if its prime
        coefficient is non-zero (extras never are).
    level : inclusion-probability level in (0, 1].

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
            raise ValueError(f"inclusion has no equation {g!r} (expected the output of "
                             "inclusion_probabilities)")
        probs = inclusion[g]
        in_model = [k for k in probs
                    if k not in _EXTRA_DEFS and vehicle.coefficients.get(k, 0.0) != 0.0]
        included = [k for k, p in probs.items() if p >= level]
        out[g] = {
            "in_model": in_model,
            "included": included,
            "excited_and_in_model": [k for k in included if k in in_model],
            "in_model_not_seen": [k for k in in_model if k not in included],
            "spurious": [k for k in included if k not in in_model],
        }
    return out


__all__ = ["EQUATIONS", "ADDED_MASS", "EXTRAS", "horizontal_terms", "equation_of",
           "estimate_motion",
           "force_targets", "candidate_library", "inclusion_probabilities", "compare_with_model"]
