"""Motion and inverse dynamics of a logged track: what the measured motion says the forces were.

* :func:`estimate_motion` -- body velocities u, v, r and their derivatives from a track (measured
  u, v, r smoothed, or x, y, psi differentiated and rotated into the body frame), with a
  Savitzky-Golay smoothing differentiator (Savitzky & Golay 1964, Anal. Chem. 36(8); pysindy's
  SmoothedFiniteDifference).
* :func:`force_targets` -- the hydrodynamic generalised forces X, Y, N by rigid-body inverse
  dynamics (Fossen 2011, Handbook of Marine Craft Hydrodynamics and Motion Control, Ch. 3),
  minus the known terms.
* :func:`library_columns` -- the columns of term-library terms at the motion (the simulator's
  features).

The models' inverse dynamics (``missing_forces``, the ship's equation-error seed) and the
model-free term check (:mod:`bayesid.analysis.sindy`) use them.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import savgol_filter

from ..data import terms
from ..data.track import Track
from . import dynamics

__all__ = [
    "EQUATIONS",
    "ADDED_MASS",
    "horizontal_terms",
    "estimate_motion",
    "force_targets",
    "library_columns",
    "motion_arrays",
    "motion_filter",
    "inputs_array",
    "track_inputs",
    "require_column",
    "held_inputs",
    "known_values",
]

EQUATIONS = ("X", "Y", "N")
#: The horizontal acceleration (added-mass) terms; the regression needs them known (see
#: :func:`force_targets`).
ADDED_MASS: tuple[str, ...] = tuple(terms.names_where(kind="added_mass", horizontal=True))
_PLANE = [0, 1, 5]  # u, v, r rows/columns of the 6x6 mass matrix


def horizontal_terms(equation: str) -> list[str]:
    """Term-library names of one horizontal equation, in table order: the listed terms only, so
    a SINDy library does not grow with the products a process happened to read before
    (:func:`bayesid.data.terms.names_where`).

    Parameters
    ----------
    equation : {"X", "Y", "N"}
        The equation.

    Returns
    -------
    list of str
        The term names.

    Raises
    ------
    ValueError
        For another equation.
    """
    if equation not in EQUATIONS:
        raise ValueError(f"equation must be one of {EQUATIONS}, got {equation!r}")
    return terms.names_where(group=equation, horizontal=True, listed=True)


# ---------------------------------------------------------------------------------------------
# 1. Motion
# ---------------------------------------------------------------------------------------------


def require_column(track: Track, name: str, why: str) -> np.ndarray:
    """A column of a track that must be present and gap-free.

    Parameters
    ----------
    track : Track
        The track.
    name : str
        The column.
    why : str
        What needs it, named in the message.

    Returns
    -------
    ndarray, shape (n_samples,)
        The column.

    Raises
    ------
    ValueError
        Naming the track and column when it is absent or has a NaN (with its first sample).
    """
    if name not in track:
        raise ValueError(f"track {track.name!r} has no column {name!r} ({why}); columns: {['t', *track.data]}")
    col = track[name]
    bad = np.flatnonzero(~np.isfinite(col))
    if bad.size:
        raise ValueError(
            f"track {track.name!r}: column {name!r} is missing (NaN) at sample "
            f"{bad[0]} (t = {track.t[bad[0]]:g} s); the smoothing differentiator "
            "needs a gap-free, uniformly sampled record"
        )
    return col


def _window_samples(window_s: float, dt: float, polyorder: int, n: int) -> int:
    w = int(round(window_s / dt))
    w += 1 - w % 2  # odd
    w = max(w, polyorder + 1 + polyorder % 2)  # the smallest odd length > polyorder
    if w > n:
        raise ValueError(
            f"smoothing window {window_s:g} s ({w} samples) is longer than the track ({n} samples of {dt:g} s)"
        )
    return w


def _sfd(window: int, polyorder: int):
    """A pysindy ``SmoothedFiniteDifference`` (pysindy and scikit-learn imported here, when a
    derivative is first asked for: 0.7 s of every command's start-up otherwise)."""
    import pysindy as ps

    # A fresh smoother_kws dict each time: pysindy mutates its (shared) default dict.
    kws = {"window_length": window, "polyorder": polyorder}
    return ps.SmoothedFiniteDifference(smoother_kws=kws)


def _smooth_diff(x: np.ndarray, t: np.ndarray, window: int, polyorder: int):
    """Savitzky-Golay smoothing then second-order central differences (pysindy
    SmoothedFiniteDifference); returns (smoothed, derivative), both (n, k)."""
    d = _sfd(window, polyorder)
    xdot = np.asarray(d(np.asarray(x, dtype=float), t))
    return np.asarray(d.smoothed_x_), xdot


def motion_filter(x: np.ndarray, motion: dict) -> np.ndarray:
    """The smoothing the motion went through (``passes`` Savitzky-Golay passes), along axis 0.

    Parameters
    ----------
    x : array_like, shape (n, ...)
        Signals at the motion's samples.
    motion : dict
        The motion of :func:`estimate_motion` (its ``smoother`` is read; none: no smoothing).

    Returns
    -------
    ndarray
        The smoothed signals, of the shape of ``x``.
    """
    sm = motion.get("smoother")
    if sm is None:
        return np.asarray(x, dtype=float)
    y = np.asarray(x, dtype=float)
    for _ in range(int(sm["passes"])):
        y = savgol_filter(y, sm["window"], sm["polyorder"], axis=0)
    return y


def held_inputs(inputs: np.ndarray, hold: str) -> list[np.ndarray]:
    """The input values in effect at the sample times, to be averaged over.

    ``"zoh"``: the input stored at sample k is held over [t_k, t_k+1) (the simulator's and
    :class:`~bayesid.models.simulate.SimResult`'s convention), so a central derivative at t_k sees half
    of the value held before and half of the value held after: a column ``f(state, input)`` is
    ``(f(state_k, in_k-1) + f(state_k, in_k)) / 2`` (averaging f, not the input, keeps nonlinear
    terms such as ``dr**2`` right across a rudder reversal). ``"sample"``: the stored value is
    the (continuous) signal at t_k; used as is.

    Parameters
    ----------
    inputs : ndarray, shape (n, k)
        The inputs stored at the samples.
    hold : {"zoh", "sample"}
        How they are to be read.

    Returns
    -------
    list of ndarray
        ``[inputs]`` for ``"sample"``; ``[previous, inputs]`` (the value held before and after
        each sample time, the first sample repeated) for ``"zoh"``.
    """
    if hold == "sample":
        return [inputs]
    prev = np.vstack([inputs[:1], inputs[:-1]])
    return [prev, inputs]


def estimate_motion(
    track: Track,
    window_s: float | None = None,
    polyorder: int = 3,
    use_velocities: bool | None = None,
    input_hold: str = "zoh",
) -> dict:
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

    Window choice (defaults measured on NPS AUV II at 10 Hz):
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
    polyorder : int, default 3
        Savitzky-Golay polynomial order.
    use_velocities : bool, optional
        Force a route; default: measured velocities if u, v and r are all present.
    input_hold : {"zoh", "sample"}, default "zoh"
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
    psi = require_column(track, "psi", "heading is required")
    t = track.t
    n = t.size
    if n < 5:
        raise ValueError(f"track {track.name!r} has {n} samples; need at least 5")
    dts = np.diff(t)
    dt = float(np.median(dts))
    if np.max(np.abs(dts - dt)) > 1e-6 * dt + 1e-9:
        i = int(np.argmax(np.abs(dts - dt)))
        raise ValueError(
            f"track {track.name!r}: column 't' is not uniformly sampled (step "
            f"{dts[i]:g} s at index {i + 1}, median {dt:g} s); resample first"
        )
    have_vel = all(c in track for c in ("u", "v", "r"))
    if use_velocities is None:
        use_velocities = have_vel
    if use_velocities:
        for c in ("u", "v", "r"):
            require_column(track, c, "use_velocities=True needs measured u, v, r")
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
        x = require_column(track, "x", "positions route: x, y, psi are differentiated")
        y = require_column(track, "y", "positions route: x, y, psi are differentiated")
        _, eta_dot = _smooth_diff(np.column_stack([x, y, psi_u]), t, w, polyorder)
        c, s = np.cos(psi_u), np.sin(psi_u)
        nu = np.column_stack(
            [c * eta_dot[:, 0] + s * eta_dot[:, 1], -s * eta_dot[:, 0] + c * eta_dot[:, 1], eta_dot[:, 2]]
        )
        source, passes = "positions", 2
    nu_s, nu_dot = _smooth_diff(nu, t, w, polyorder)
    motion = dict(
        t=t.copy(),
        u=nu_s[:, 0],
        v=nu_s[:, 1],
        r=nu_s[:, 2],
        u_dot=nu_dot[:, 0],
        v_dot=nu_dot[:, 1],
        r_dot=nu_dot[:, 2],
        psi=psi_u,
        window_s=w * dt,
        smoother=dict(window=w, polyorder=polyorder, passes=passes),
        input_hold=input_hold,
        source=source,
    )
    if "delta_r" in track:
        held = held_inputs(require_column(track, "delta_r", "rudder")[:, None], input_hold)
        dr_s = motion_filter(sum(held) / len(held), motion)
        motion["dr"] = dr_s[:, 0]
        import pysindy as ps

        motion["dr_dot"] = np.asarray(ps.FiniteDifference()(dr_s, t))[:, 0]
    return motion


# ---------------------------------------------------------------------------------------------
# 2. Force targets (inverse dynamics)
# ---------------------------------------------------------------------------------------------


def motion_arrays(motion: dict, keys=("u", "v", "r", "u_dot", "v_dot", "r_dot")):
    """Arrays of a motion dict, checked.

    Parameters
    ----------
    motion : dict
        The motion of :func:`estimate_motion`.
    keys : sequence of str, default ("u", "v", "r", "u_dot", "v_dot", "r_dot")
        The entries wanted.

    Returns
    -------
    list of ndarray
        The entries as float arrays (n,), in ``keys`` order.

    Raises
    ------
    ValueError
        A missing key, or an entry that is not 1-D of the common length.
    """
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


def known_values(known, vehicle) -> dict:
    """Values of the terms taken as known.

    Parameters
    ----------
    known : sequence of str or dict
        Names (they take the vehicle's values) or ``{name: prime value}`` (taken as is).
    vehicle : Vehicle
        The vehicle.

    Returns
    -------
    dict
        ``{name: prime value}``.

    Raises
    ------
    ValueError
        Naming a name that is not a horizontal library term.
    """
    vals = dict(known) if isinstance(known, dict) else {k: None for k in known}
    for k in vals:
        if k not in terms.INDEX or not terms.term(k).horizontal:
            raise ValueError(f"known term {k!r} is not a horizontal term of the term library")
    return {k: float(vehicle.coefficients.get(k, 0.0) if v is None else v) for k, v in vals.items()}


def force_targets(motion: dict, vehicle, inputs=None, known=()) -> np.ndarray:
    """Hydrodynamic generalised forces X, Y, N by rigid-body inverse dynamics.

    ``tau_hydro = M_RB nu_dot + C_RB(nu) nu`` on the horizontal plane (Fossen 2011, Ch. 3,
    rigid-body kinetics with w = p = q = 0; the left-hand sides of the simulator's equations,
    :func:`bayesid.models.dynamics.generalized_force`):

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
    motion : dict
        From :func:`estimate_motion` (u, v, r, u_dot, v_dot, r_dot; (n,) each).
    vehicle : Vehicle
        The :class:`~bayesid.data.vehicle.Vehicle` (mass, inertia, rG; rho and L for ``known``).
    inputs : ndarray, shape (n, 4), optional
        ``delta_r, delta_s, delta_b`` (rad), ``n`` (rpm); needed only for ``known`` force terms.
    known : sequence of str or dict, default ()
        Horizontal library terms taken as known: names (the vehicle's prime values) or
        ``{name: prime value}``.

    Returns
    -------
    ndarray, shape (n, 3)
        X (N), Y (N), N (N m).

    Raises
    ------
    ValueError
        A missing motion key; a ``known`` name that is not a horizontal library term (named);
        ``inputs`` missing or malformed when a known force term needs them.
    """
    u, v, r, ud, vd, rd = motion_arrays(motion)
    Mrb = vehicle.mass_matrix({})[np.ix_(_PLANE, _PLANE)]
    m = vehicle.mass
    xg, yg = float(vehicle.rG[0]), float(vehicle.rG[1])
    acc = np.column_stack([ud, vd, rd]) @ Mrb.T
    cor = np.column_stack([m * (-v * r - xg * r * r), m * (u * r - yg * r * r), m * (xg * u * r + yg * v * r)])
    F = acc + cor
    kv = known_values(known, vehicle)
    if kv:
        names = list(kv)
        cols = library_columns(names, motion, inputs, vehicle)
        for j, k in enumerate(names):
            F[:, EQUATIONS.index(terms.term(k).group)] -= kv[k] * cols[:, j]
    return F


def inputs_array(inputs, n: int) -> np.ndarray:
    """Inputs checked for the library columns.

    Parameters
    ----------
    inputs : array_like, shape (n, 4)
        ``delta_r, delta_s, delta_b`` (rad), ``n`` (rpm).
    n : int
        The number of samples expected.

    Returns
    -------
    ndarray, shape (n, 4)
        The inputs as floats.

    Raises
    ------
    ValueError
        Inputs missing (None), of another shape, or not finite (naming the channel and sample).
    """
    if inputs is None:
        raise ValueError("inputs (n, 4) are needed: delta_r (rad) and n (rpm) enter the rudder and propulsion terms")
    a = np.asarray(inputs, dtype=float)
    if a.shape != (n, 4):
        raise ValueError(f"inputs must be (n, 4) = delta_r, delta_s, delta_b, n with n = {n}, got {a.shape}")
    for j, c in enumerate(("delta_r", "delta_s", "delta_b", "n")):
        bad = np.flatnonzero(~np.isfinite(a[:, j]))
        if bad.size:
            raise ValueError(f"inputs: {c} is not finite at sample {bad[0]}")
    return a


_INPUT_FACTORS = {"dr", "ds", "db", "prop", "eps"}


def library_columns(names, motion: dict, inputs, vehicle) -> np.ndarray:
    """Columns of library terms (force and acceleration) at the motion.

    Force terms use the simulator's features at (u, v, r) and the inputs in effect at the sample
    times (see ``motion["input_hold"]``); a column with an input factor (rudder, propeller) is
    then passed through the motion's smoothing (``motion["smoother"]``).

    Parameters
    ----------
    names : sequence of str
        Horizontal library terms.
    motion : dict
        From :func:`estimate_motion`.
    inputs : array_like, shape (n, 4)
        The inputs at the motion's samples; needed when ``names`` has force terms.
    vehicle : Vehicle
        The vehicle (rho, L and the propulsion of the features).

    Returns
    -------
    ndarray, shape (n, len(names))
        The columns, N or N m per unit prime coefficient.
    """
    u, v, r, ud, vd, rd = motion_arrays(motion)
    n = u.size
    out = np.empty((n, len(names)))
    force = [k for k in names if terms.term(k).kind == "force"]
    if force:
        held = held_inputs(inputs_array(inputs, n), motion.get("input_hold", "sample"))
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
            phi[:, dep] = motion_filter(phi[:, dep], motion)
    accel = {"u": ud, "v": vd, "r": rd}
    jf = 0
    for j, k in enumerate(names):
        t = terms.term(k)
        if t.kind == "force":
            out[:, j] = phi[:, jf]
            jf += 1
        else:
            scale = 0.5 * vehicle.rho * vehicle.L**t.L_power
            out[:, j] = scale * accel[terms.VELOCITIES[t.accel]]
    return out


def track_inputs(track: Track) -> np.ndarray:
    """Inputs ``delta_r, delta_s, delta_b, n`` of a track (rad, rpm), absent columns 0.

    Parameters
    ----------
    track : Track
        The track; it needs gap-free ``delta_r`` and ``n``.

    Returns
    -------
    ndarray, shape (n_samples, 4)
        The inputs.

    Raises
    ------
    ValueError
        Naming the track when ``delta_r`` or ``n`` is missing or has a NaN.
    """
    for c, why in (("delta_r", "rudder terms"), ("n", "propulsion term Cd0 (rpm)")):
        require_column(track, c, why)
    return track.inputs(fill=0.0)
