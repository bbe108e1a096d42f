"""Compiled right-hand side of the 6-DOF standard submarine equations and the fixed-step RK4.

State ``s`` (12,): ``x, y, z, phi, theta, psi`` (earth-fixed NED, zyx Euler angles) and
``u, v, w, p, q, r`` (body-fixed) -- the paper's 12 first-order equations (Furlong et al. 2003,
Sec. 2.2, Eqs. 3-5). Inputs ``uin`` (4,): ``delta_r, delta_s, delta_b`` (rad) and ``n`` (rpm),
held constant over a step (zero-order hold).

``M nu_dot = tau_hydro + tau_hydrostatic + tau_crossflow - F_rb(nu)`` where ``M = M_RB - M_A``
is constant (:meth:`bayesid.data.vehicle.Vehicle.mass_matrix`) and is inverted once per coefficient
vector, outside the integration loop. The horizontal-plane mode (paper Sec. 4) is the same
equations restricted to (u, v, r): its ``Minv`` is the inverse of the (u, v, r) block of ``M``,
embedded in a 6x6 zero matrix, so w, p, q stay zero and z, phi, theta stay constant.

Everything here is pure functions over arrays; no allocation in the step functions.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..data.terms import F_INDEX, N_FEATURES

# Layout of the vehicle parameter vector ``vp`` passed to the kernels.
VP_M, VP_W, VP_B = 0, 1, 2
VP_XG, VP_YG, VP_ZG, VP_XB, VP_YB, VP_ZB = 3, 4, 5, 6, 7, 8
VP_IX, VP_IY, VP_IZ, VP_IXY, VP_IYZ, VP_IXZ = 9, 10, 11, 12, 13, 14
VP_RHO, VP_L, VP_UC, VP_CT = 15, 16, 17, 18
VP_CDYH, VP_CDZB, VP_XFLOW = 19, 20, 21
VP_VMAX, VP_WMAX, VP_THMAX = 22, 23, 24
N_VP = 25

# Divergence flags per track.
OK, NONFINITE, OUT_OF_BOUNDS = 0, 1, 2

RPM_TO_RAD_S = 2.0 * math.pi / 60.0
# |u| floor (m/s) in eta = u_c/u (eps(eta) is undefined at u = 0), and floor of the speed U in the
# feature 1/U (the prime form of a term of three velocity factors, bayesid.data.terms.parse).
U_MIN_EPS = 1e-3

assert F_INDEX["|p|"] == 16 and F_INDEX["1/U"] == 17 and N_FEATURES == 18  # kernel below hard-codes this order


def vehicle_params(vehicle, crossflow_integral: bool | None = None) -> np.ndarray:
    """Pack a :class:`~bayesid.data.vehicle.Vehicle` into the kernels' parameter vector.

    Divergence bounds: |u|,|v|,|w| > max(20 * nominal speed, 10) m/s, |p|,|q|,|r| > that speed /
    (L/4) rad/s, or |theta| > 85 deg (near the zyx Euler singularity) flag a track as diverged.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.
    crossflow_integral : bool, optional
        Switch the strip-sum cross-flow integral on; default when the vehicle's
        ``crossflow_model`` is ``"integral"``.

    Returns
    -------
    ndarray, shape (N_VP,)
        The parameter vector (indices ``VP_*`` of this module), SI.
    """
    vp = np.zeros(N_VP)
    vp[VP_M], vp[VP_W], vp[VP_B] = vehicle.mass, vehicle.weight, vehicle.buoyancy
    vp[VP_XG : VP_ZG + 1] = vehicle.rG
    vp[VP_XB : VP_ZB + 1] = vehicle.rB
    I = vehicle.inertia
    vp[VP_IX], vp[VP_IY], vp[VP_IZ] = I[0, 0], I[1, 1], I[2, 2]
    vp[VP_IXY], vp[VP_IYZ], vp[VP_IXZ] = -I[0, 1], -I[1, 2], -I[0, 2]
    vp[VP_RHO], vp[VP_L] = vehicle.rho, vehicle.L
    vp[VP_UC], vp[VP_CT] = vehicle.propulsion.uc_per_omega, vehicle.propulsion.CT_coeff
    if crossflow_integral is None:
        crossflow_integral = vehicle.crossflow_model == "integral"
    if crossflow_integral:
        cf = vehicle.crossflow
        vp[VP_CDYH], vp[VP_CDZB], vp[VP_XFLOW] = cf.Cdy * cf.height_m, cf.Cdz * cf.breadth_m, 1.0
    vmax = max(20.0 * vehicle.nominal_speed, 10.0)
    vp[VP_VMAX], vp[VP_WMAX], vp[VP_THMAX] = vmax, vmax / (vehicle.L / 4.0), math.radians(85.0)
    return vp


def crossflow_strips(vehicle) -> tuple[np.ndarray, np.ndarray]:
    """Strip stations and weights of the vehicle's cross-flow integral.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.

    Returns
    -------
    xs : ndarray, shape (n_strips,)
        Strip stations, m (one zero when the vehicle has no cross-flow data).
    ws : ndarray, shape (n_strips,)
        Strip weights (lengths), m (one zero when the vehicle has no cross-flow data).
    """
    if vehicle.crossflow is None:
        return np.zeros(1), np.zeros(1)
    return np.ascontiguousarray(vehicle.crossflow.stations), np.ascontiguousarray(vehicle.crossflow.weights)


@nb.njit(cache=True, inline="always")
def _eps(u, n_rad, eta, vp):
    """Propulsion function eps(eta) (Healey & Lienard 1993; equations.md "Propulsion")."""
    L = vp[VP_L]
    ct = vp[VP_CT] * L * L * eta * abs(eta) / 2.0
    ct1 = vp[VP_CT] * L * L / 2.0
    sn = 1.0 if n_rad >= 0.0 else -1.0
    su = 1.0 if u >= 0.0 else -1.0
    # |C_T| keeps the root real under strong reverse thrust; the sign ratio carries direction.
    return -1.0 + (sn / su) * (math.sqrt(abs(ct) + 1.0) - 1.0) / (math.sqrt(ct1 + 1.0) - 1.0)


@nb.njit(cache=True)
def features(s, uin, vp, f):
    """Fill ``f`` with the factors of the term library at a state and input.

    Parameters
    ----------
    s : ndarray, shape (12,)
        State (SI).
    uin : ndarray, shape (4,)
        Inputs ``delta_r, delta_s, delta_b`` (rad) and ``n`` (rpm).
    vp : ndarray, shape (N_VP,)
        Vehicle parameters (:func:`vehicle_params`).
    f : ndarray, shape (N_FEATURES,)
        Output: the features, in :data:`bayesid.data.terms.FEATURES` order (written in place);
        ``1/U`` is ``1 / max(U, U_MIN_EPS)`` with ``U = sqrt(u^2 + v^2 + w^2)`` (m/s).
    """
    u, v, w, p, q, r = s[6], s[7], s[8], s[9], s[10], s[11]
    n_rad = uin[3] * RPM_TO_RAD_S
    uc = vp[VP_UC] * n_rad
    ug = u if abs(u) > U_MIN_EPS else (U_MIN_EPS if u >= 0.0 else -U_MIN_EPS)
    f[0] = 1.0
    f[1] = u
    f[2] = v
    f[3] = w
    f[4] = p
    f[5] = q
    f[6] = r
    f[7] = uin[0]
    f[8] = uin[1]
    f[9] = uin[2]
    f[10] = _eps(ug, n_rad, uc / ug, vp)
    f[11] = abs(v)
    f[12] = abs(r)
    f[13] = uc * abs(uc) - u * abs(u)
    f[14] = abs(w)
    f[15] = abs(q)
    f[16] = abs(p)
    spd = math.sqrt(u * u + v * v + w * w)
    f[17] = 1.0 / (spd if spd > U_MIN_EPS else U_MIN_EPS)


@nb.njit(cache=True)
def generalized_force(s, uin, vp, tfac, tdof, tcoef, xs, ws, f, tau):
    """Right-hand side of ``M nu_dot = tau`` (6,): hydrodynamic terms, hydrostatics, cross-flow
    integral (if on) minus the rigid-body velocity terms. Writes ``tau`` in place.

    Parameters
    ----------
    s : ndarray, shape (12,)
        State (SI).
    uin : ndarray, shape (4,)
        Inputs ``delta_r, delta_s, delta_b`` (rad) and ``n`` (rpm).
    vp : ndarray, shape (N_VP,)
        Vehicle parameters (:func:`vehicle_params`).
    tfac : ndarray of int64, shape (P, 5)
        Feature indices of each term (:func:`bayesid.data.terms.factor_table`).
    tdof : ndarray of int64, shape (P,)
        Degree of freedom of each term.
    tcoef : ndarray, shape (P,)
        Dimensional term coefficients: prime coefficient * 0.5 rho L^k.
    xs : ndarray, shape (n_strips,)
        Cross-flow strip stations, m (:func:`crossflow_strips`).
    ws : ndarray, shape (n_strips,)
        Cross-flow strip weights, m.
    f : ndarray, shape (N_FEATURES,)
        Scratch array of the features.
    tau : ndarray, shape (6,)
        Output: the generalised force X, Y, Z, K, M, N (N, N m), written in place.
    """
    features(s, uin, vp, f)
    for i in range(6):
        tau[i] = 0.0
    # Hydrodynamic terms of the library (equations.md "Hydrodynamic terms").
    for j in range(tcoef.shape[0]):
        prod = tcoef[j]
        for k in range(tfac.shape[1]):
            idx = tfac[j, k]
            if idx == 0:  # padding ("1"): the term has no more factors
                break
            prod *= f[idx]
        tau[tdof[j]] += prod
    phi, th = s[3], s[4]
    u, v, w, p, q, r = s[6], s[7], s[8], s[9], s[10], s[11]
    sph, cph, sth, cth = math.sin(phi), math.cos(phi), math.sin(th), math.cos(th)
    W, B = vp[VP_W], vp[VP_B]
    xg, yg, zg = vp[VP_XG], vp[VP_YG], vp[VP_ZG]
    xb, yb, zb = vp[VP_XB], vp[VP_YB], vp[VP_ZB]
    # Hydrostatics (Fossen 1994 pp. 45-46; equations.md "Hydrostatics").
    tau[0] += -(W - B) * sth
    tau[1] += (W - B) * cth * sph
    tau[2] += (W - B) * cth * cph
    tau[3] += (yg * W - yb * B) * cth * cph - (zg * W - zb * B) * cth * sph
    tau[4] += -(xg * W - xb * B) * cth * cph - (zg * W - zb * B) * sth
    tau[5] += (xg * W - xb * B) * cth * sph + (yg * W - yb * B) * sth
    # Cross-flow drag strip sum (Feldman 1979 as in MSS; equations.md "Crossflow drag").
    if vp[VP_XFLOW] != 0.0:
        half_rho = 0.5 * vp[VP_RHO]
        for i in range(xs.shape[0]):
            x = xs[i]
            vl = v + x * r
            wl = w - x * q
            ucf = math.sqrt(vl * vl + wl * wl)
            if ucf > 1e-12:
                g = (vp[VP_CDYH] * vl * vl + vp[VP_CDZB] * wl * wl) * half_rho * ws[i] / ucf
                tau[1] -= g * vl
                tau[5] -= g * vl * x
                tau[2] -= g * wl
                tau[4] += g * wl * x
    # Rigid-body velocity terms moved to the right-hand side (paper Eq. 1; equations.md).
    m = vp[VP_M]
    Ix, Iy, Iz = vp[VP_IX], vp[VP_IY], vp[VP_IZ]
    Ixy, Iyz, Ixz = vp[VP_IXY], vp[VP_IYZ], vp[VP_IXZ]
    tau[0] -= m * (-v * r + w * q - xg * (q * q + r * r) + yg * p * q + zg * p * r)
    tau[1] -= m * (-w * p + u * r - yg * (r * r + p * p) + zg * q * r + xg * q * p)
    tau[2] -= m * (-u * q + v * p - zg * (p * p + q * q) + xg * r * p + yg * r * q)
    tau[3] -= (
        (Iz - Iy) * q * r
        - p * q * Ixz
        + (r * r - q * q) * Iyz
        + p * r * Ixy
        + m * (yg * (-u * q + v * p) - zg * (-w * p + u * r))
    )
    tau[4] -= (
        (Ix - Iz) * r * p
        - q * r * Ixy
        + (p * p - r * r) * Ixz
        + q * p * Iyz
        + m * (zg * (-v * r + w * q) - xg * (-u * q + v * p))
    )
    tau[5] -= (
        (Iy - Ix) * p * q
        - r * p * Iyz
        + (q * q - p * p) * Ixy
        + r * q * Ixz
        + m * (xg * (-w * p + u * r) - yg * (-v * r + w * q))
    )


@nb.njit(cache=True)
def rhs(s, uin, ext, vp, tfac, tdof, tcoef, Minv, xs, ws, f, tau, ds):
    """State derivative ``ds`` (12,) = d s / dt, in place (paper Eqs. 3-5).

    Parameters
    ----------
    s : ndarray, shape (12,)
        State (SI).
    uin : ndarray, shape (4,)
        Inputs ``delta_r, delta_s, delta_b`` (rad) and ``n`` (rpm).
    ext : ndarray, shape (6,)
        External generalised force (N, N m) added to the right-hand side of
        ``M nu_dot = tau``: zero for the vehicle alone, the exogenous forces of
        :mod:`bayesid.models.effects` (wave forcing, thrust deficit) otherwise.
    vp : ndarray, shape (N_VP,)
        Vehicle parameters (:func:`vehicle_params`).
    tfac, tdof, tcoef : ndarray
        The term encoding of :func:`generalized_force`.
    Minv : ndarray, shape (6, 6)
        Inverse mass matrix.
    xs, ws : ndarray, shape (n_strips,)
        Cross-flow strip stations and weights, m.
    f, tau : ndarray
        Scratch arrays, shapes (N_FEATURES,) and (6,).
    ds : ndarray, shape (12,)
        Output: the state derivative, written in place.
    """
    generalized_force(s, uin, vp, tfac, tdof, tcoef, xs, ws, f, tau)
    for i in range(6):
        tau[i] += ext[i]
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += Minv[i, j] * tau[j]
        ds[6 + i] = acc
    phi, th, psi = s[3], s[4], s[5]
    u, v, w, p, q, r = s[6], s[7], s[8], s[9], s[10], s[11]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    sps, cps = math.sin(psi), math.cos(psi)
    # zyx Euler kinematics (Fossen 1994, Eq. 2.18/2.28).
    ds[0] = cps * cth * u + (cps * sth * sph - sps * cph) * v + (cps * sth * cph + sps * sph) * w
    ds[1] = sps * cth * u + (sps * sth * sph + cps * cph) * v + (sps * sth * cph - cps * sph) * w
    ds[2] = -sth * u + cth * sph * v + cth * cph * w
    ds[3] = p + (sph * q + cph * r) * sth / cth
    ds[4] = cph * q - sph * r
    ds[5] = (sph * q + cph * r) / cth


@nb.njit(cache=True)
def rk4_step(s, uin, ext, dt, vp, tfac, tdof, tcoef, Minv, xs, ws, f, tau, k1, k2, k3, k4, tmp):
    """Advance ``s`` in place by one classical RK4 step; the input ``uin`` and the external
    force ``ext`` are held over the step.

    Parameters
    ----------
    s : ndarray, shape (12,)
        State (SI), advanced in place.
    uin : ndarray, shape (4,)
        Inputs ``delta_r, delta_s, delta_b`` (rad) and ``n`` (rpm).
    ext : ndarray, shape (6,)
        External generalised force, N and N m (:func:`rhs`).
    dt : float
        Step length, s.
    vp, tfac, tdof, tcoef, Minv, xs, ws : ndarray
        The vehicle, terms, inverse mass matrix and cross-flow strips of :func:`rhs`.
    f, tau, k1, k2, k3, k4, tmp : ndarray
        Scratch arrays: features (N_FEATURES,), generalised force (6,), the RK4 stages and
        an intermediate state (12,) each.
    """
    rhs(s, uin, ext, vp, tfac, tdof, tcoef, Minv, xs, ws, f, tau, k1)
    for i in range(12):
        tmp[i] = s[i] + 0.5 * dt * k1[i]
    rhs(tmp, uin, ext, vp, tfac, tdof, tcoef, Minv, xs, ws, f, tau, k2)
    for i in range(12):
        tmp[i] = s[i] + 0.5 * dt * k2[i]
    rhs(tmp, uin, ext, vp, tfac, tdof, tcoef, Minv, xs, ws, f, tau, k3)
    for i in range(12):
        tmp[i] = s[i] + dt * k3[i]
    rhs(tmp, uin, ext, vp, tfac, tdof, tcoef, Minv, xs, ws, f, tau, k4)
    for i in range(12):
        s[i] += dt * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) / 6.0


@nb.njit(cache=True)
def check_state(s, vp):
    """Divergence flag of a state: OK, NONFINITE or OUT_OF_BOUNDS.

    Parameters
    ----------
    s : ndarray, shape (12,)
        State (SI).
    vp : ndarray, shape (N_VP,)
        Vehicle parameters, with the divergence bounds (:func:`vehicle_params`).

    Returns
    -------
    int
        ``OK``, ``NONFINITE`` or ``OUT_OF_BOUNDS``.
    """
    for i in range(12):
        if not math.isfinite(s[i]):
            return NONFINITE
    vmax, wmax = vp[VP_VMAX], vp[VP_WMAX]
    for i in range(6, 9):
        if abs(s[i]) > vmax:
            return OUT_OF_BOUNDS
    for i in range(9, 12):
        if abs(s[i]) > wmax:
            return OUT_OF_BOUNDS
    if abs(s[4]) > vp[VP_THMAX]:
        return OUT_OF_BOUNDS
    return OK


@nb.njit(cache=True)
def _workspace():
    """Scratch arrays of one integration: features, generalised force, RK4 stages, and the
    external force (zeroed)."""
    return (
        np.empty(N_FEATURES),
        np.empty(6),
        np.empty(12),
        np.empty(12),
        np.empty(12),
        np.empty(12),
        np.empty(12),
        np.zeros(6),
    )


@nb.njit(cache=True, parallel=True)
def simulate_batch(s0, inputs, dt, sample_every, vp, tfac, tdof, tcoef, Minv, xs, ws, out, status, fail_step):
    """Integrate B tracks in parallel (one per coefficient vector).

    Parameters
    ----------
    s0 : ndarray, shape (B, 12)
        Initial states.
    inputs : ndarray, shape (n_steps, 4)
        Inputs per step, shared by all tracks.
    dt : float
        Step, s.
    sample_every : int
        Store every k-th state.
    vp : ndarray, shape (N_VP,)
        Vehicle parameters (:func:`vehicle_params`).
    tfac, tdof : ndarray of int64
        The term encoding of :func:`generalized_force`.
    tcoef : ndarray, shape (B, P)
        Dimensional term coefficients per track.
    Minv : ndarray, shape (B, 6, 6)
        Inverse mass matrices per track.
    xs, ws : ndarray, shape (n_strips,)
        Cross-flow strip stations and weights, m.
    out : ndarray, shape (B, n_steps // sample_every + 1, 12)
        Output: filled with the samples; NaN after a divergence.
    status : ndarray of int64, shape (B,)
        Output: OK / NONFINITE / OUT_OF_BOUNDS per track.
    fail_step : ndarray of int64, shape (B,)
        Output: first bad step per track, or -1.
    """
    B = s0.shape[0]
    n_steps = inputs.shape[0]
    for b in nb.prange(B):
        s = s0[b].copy()
        f, tau, k1, k2, k3, k4, tmp, ext = _workspace()
        out[b, 0] = s
        status[b] = OK
        fail_step[b] = -1
        for k in range(n_steps):
            rk4_step(s, inputs[k], ext, dt, vp, tfac, tdof, tcoef[b], Minv[b], xs, ws, f, tau, k1, k2, k3, k4, tmp)
            flag = check_state(s, vp)
            if flag != OK:
                status[b] = flag
                fail_step[b] = k
                for j in range((k + 1 + sample_every - 1) // sample_every, out.shape[1]):
                    for i in range(12):
                        out[b, j, i] = np.nan
                break
            if (k + 1) % sample_every == 0:
                out[b, (k + 1) // sample_every] = s


@nb.njit(cache=True, parallel=True)
def simulate_windows(s0, starts, inputs, exo, ecoef, dt, vp, tfac, tdof, tcoef, Minv, xs, ws, out, status):
    """Integrate B parameter vectors over W consecutive windows of one input record, each window
    restarting from its own state (the window protocol and multiple shooting; parallel over all
    B * W windows).

    Parameters
    ----------
    s0 : ndarray, shape (B, W, 12)
        State at each window start.
    starts : ndarray of int64, shape (W + 1,)
        Step index of each window start; ``starts[W]`` = n_steps.
    inputs : ndarray, shape (B, n_steps, 4)
        Inputs per parameter vector (held over a step).
    exo : ndarray, shape (B, n_steps, K)
        Exogenous signals.
    ecoef : ndarray, shape (B, K, 6)
        Their force coefficients: the external generalised force over step k is
        ``sum_j exo[b, k, j] * ecoef[b, j, :]`` (N, N m; held over the step).
    dt : float
        Step, s.
    vp : ndarray, shape (B, N_VP)
        Vehicle parameters per parameter vector.
    tfac, tdof : ndarray of int64
        The term encoding of :func:`generalized_force`.
    tcoef : ndarray, shape (B, P)
        Dimensional term coefficients.
    Minv : ndarray, shape (B, 6, 6)
        Inverse mass matrices.
    xs, ws : ndarray, shape (n_strips,)
        Cross-flow strip stations and weights, m.
    out : ndarray, shape (B, n_steps + W, 12)
        Output: window w occupies rows ``starts[w] + w .. starts[w + 1] + w`` (its start and
        end state both kept); NaN after a divergence.
    status : ndarray of int64, shape (B, W)
        Output: OK / NONFINITE / OUT_OF_BOUNDS per window.
    """
    B = s0.shape[0]
    W = starts.shape[0] - 1
    K = exo.shape[2]
    for job in nb.prange(B * W):
        b = job // W
        w = job % W
        s = s0[b, w].copy()
        f, tau, k1, k2, k3, k4, tmp, ext = _workspace()
        row = starts[w] + w
        out[b, row] = s
        status[b, w] = OK
        for k in range(starts[w], starts[w + 1]):
            for i in range(6):
                acc = 0.0
                for j in range(K):
                    acc += exo[b, k, j] * ecoef[b, j, i]
                ext[i] = acc
            rk4_step(
                s, inputs[b, k], ext, dt, vp[b], tfac, tdof, tcoef[b], Minv[b], xs, ws, f, tau, k1, k2, k3, k4, tmp
            )
            row += 1
            flag = check_state(s, vp[b])
            if flag != OK:
                status[b, w] = flag
                for j in range(row, starts[w + 1] + w + 1):
                    for i in range(12):
                        out[b, j, i] = np.nan
                break
            out[b, row] = s


@nb.njit(cache=True)
def simulate_triggered_zigzag(
    s0,
    n_steps,
    dt,
    rpm,
    i_input,
    i_state,
    delta,
    trigger,
    first_sign,
    response_sign,
    t_execute,
    rate_max,
    vp,
    tfac,
    tdof,
    tcoef,
    Minv,
    xs,
    ws,
    out,
    inputs,
):
    """Closed-loop zigzag on any (input, state) pair: input ``i_input`` is reversed when state
    ``i_state`` has changed from its value at execute by ``trigger`` in the direction the present
    command drives it (ITTC 7.5-04-02-01, Z-manoeuvre test). Heading zigzag: ``i_input = 0``
    (delta_r), ``i_state = 5`` (psi); vertical zigzag: ``i_input = 1`` (delta_s), ``i_state = 4``
    (theta). Same RK4 step as :func:`simulate_batch`.

    Parameters
    ----------
    s0 : ndarray, shape (12,)
        Initial state.
    n_steps : int
        Number of steps.
    dt : float
        Step, s.
    rpm : float
        Propeller speed, rpm, held.
    i_input : int
        Actuated input, 0..2.
    i_state : int
        Trigger state, 0..11.
    delta : float
        Command amplitude, rad.
    trigger : float
        Change of the trigger state that reverses the command (rad for an angle).
    first_sign : float
        +1/-1, sign of the first command.
    response_sign : float
        Sign of the change of state ``i_state`` that a positive input produces (sign of N'dr
        for the rudder and heading, of M'ds for the stern planes and pitch).
    t_execute : float
        Time of the first command, s; straight approach with all inputs zero before.
    rate_max : float
        Actuator rate limit, rad/s; <= 0 means instantaneous.
    vp, tfac, tdof, tcoef, Minv, xs, ws : ndarray
        The vehicle, terms, inverse mass matrix and cross-flow strips of :func:`rhs` (one
        parameter vector).
    out : ndarray, shape (n_steps + 1, 12)
        Output: the states.
    inputs : ndarray, shape (n_steps, 4)
        Output: the applied inputs.

    Returns
    -------
    int
        Divergence flag (OK when the run completed).
    """
    s = s0.copy()
    f, tau, k1, k2, k3, k4, tmp, ext = _workspace()
    uin = np.zeros(4)
    uin[3] = rpm
    out[0] = s
    cmd = 0.0
    x0 = s[i_state]
    started = False
    for k in range(n_steps):
        t = k * dt
        if not started and t >= t_execute - 1e-9:
            started = True
            x0 = s[i_state]
            cmd = first_sign * delta
        if started:
            dx = s[i_state] - x0
            # state change in the direction the present command drives the vehicle
            if cmd * response_sign > 0.0 and dx >= trigger:
                cmd = -cmd
            elif cmd * response_sign < 0.0 and dx <= -trigger:
                cmd = -cmd
        if rate_max > 0.0:
            step = rate_max * dt
            d = cmd - uin[i_input]
            uin[i_input] += min(max(d, -step), step)
        else:
            uin[i_input] = cmd
        for i in range(4):
            inputs[k, i] = uin[i]
        rk4_step(s, uin, ext, dt, vp, tfac, tdof, tcoef, Minv, xs, ws, f, tau, k1, k2, k3, k4, tmp)
        flag = check_state(s, vp)
        out[k + 1] = s
        if flag != OK:
            return flag
    return OK


@nb.njit(cache=True)
def simulate_zigzag(
    s0,
    n_steps,
    dt,
    rpm,
    delta,
    psi_trigger,
    first_sign,
    turn_sign,
    t_execute,
    rate_max,
    vp,
    tfac,
    tdof,
    tcoef,
    Minv,
    xs,
    ws,
    out,
    inputs,
):
    """Closed-loop heading zigzag: :func:`simulate_triggered_zigzag` with the rudder (input 0)
    triggered on the heading psi (state 5).

    Parameters
    ----------
    s0, n_steps, dt, rpm, delta : ndarray, int or float
        As in :func:`simulate_triggered_zigzag`.
    psi_trigger : float
        Heading change that reverses the rudder, rad.
    first_sign : float
        +1/-1, sign of the first rudder command.
    turn_sign : float
        Sign of N'dr (the ``response_sign``).
    t_execute, rate_max, vp, tfac, tdof, tcoef, Minv, xs, ws, out, inputs : float or ndarray
        As in :func:`simulate_triggered_zigzag`.

    Returns
    -------
    int
        Divergence flag (OK when the run completed).
    """
    return simulate_triggered_zigzag(
        s0,
        n_steps,
        dt,
        rpm,
        0,
        5,
        delta,
        psi_trigger,
        first_sign,
        turn_sign,
        t_execute,
        rate_max,
        vp,
        tfac,
        tdof,
        tcoef,
        Minv,
        xs,
        ws,
        out,
        inputs,
    )


@nb.njit(cache=True)
def simulate_pi_hold(
    s0,
    n_steps,
    dt,
    rpm,
    i_input,
    i_state,
    reference,
    kp,
    ki,
    plant_sign,
    u_max,
    rate_max,
    vp,
    tfac,
    tdof,
    tcoef,
    Minv,
    xs,
    ws,
    out,
    inputs,
):
    """Closed loop with a discrete PI controller on one state, driving one input (e.g. the rudder
    holding a yaw rate: Bech's reverse spiral). Same RK4 step as :func:`simulate_batch`.

    At the start of step k the controller reads ``y = s[i_state]`` and, with the error
    ``e = plant_sign * (reference[k] - y)``, commands ``c = kp*e + ki*I`` with ``I`` the running
    sum of ``e*dt`` (including step k), saturated at +-``u_max``. Anti-windup by conditional
    integration: while the command is saturated, ``I`` is only updated when the error drives the
    command back from the limit. The applied input follows ``c`` at most ``rate_max`` per second
    (<= 0: instantaneous) and is held over the step (zero-order hold). ``reference[k]`` NaN
    switches the controller off for that step: command 0, integrator reset. Other inputs: zero,
    propeller ``rpm``.

    Parameters
    ----------
    s0 : ndarray, shape (12,)
        Initial state.
    n_steps : int
        Number of steps.
    dt : float
        Step, s.
    rpm : float
        Propeller speed, rpm, held.
    i_input : int
        Driven input, 0..2.
    i_state : int
        Controlled state, 0..11.
    reference : ndarray, shape (n_steps,)
        Target of state ``i_state`` per step (its units), or NaN.
    kp : float
        Input per unit of error (e.g. rad rudder per rad/s of yaw rate = s).
    ki : float
        Input per unit of integrated error (e.g. rad rudder per rad of heading).
    plant_sign : float
        Sign of the steady change of the state that a positive input produces.
    u_max : float
        Saturation of the command, rad.
    rate_max : float
        Rate limit, rad/s.
    vp, tfac, tdof, tcoef, Minv, xs, ws : ndarray
        The vehicle, terms, inverse mass matrix and cross-flow strips of :func:`rhs` (one
        parameter vector).
    out : ndarray, shape (n_steps + 1, 12)
        Output: the states.
    inputs : ndarray, shape (n_steps, 4)
        Output: the applied inputs.

    Returns
    -------
    int
        Divergence flag (OK when the run completed).
    """
    s = s0.copy()
    f, tau, k1, k2, k3, k4, tmp, ext = _workspace()
    uin = np.zeros(4)
    uin[3] = rpm
    out[0] = s
    integ = 0.0
    for k in range(n_steps):
        ref = reference[k]
        if math.isnan(ref):
            cmd = 0.0
            integ = 0.0
        else:
            e = plant_sign * (ref - s[i_state])
            trial = integ + e * dt
            c = kp * e + ki * trial
            if c > u_max:
                cmd = u_max
                if e < 0.0:
                    integ = trial
            elif c < -u_max:
                cmd = -u_max
                if e > 0.0:
                    integ = trial
            else:
                cmd = c
                integ = trial
        if rate_max > 0.0:
            step = rate_max * dt
            d = cmd - uin[i_input]
            uin[i_input] += min(max(d, -step), step)
        else:
            uin[i_input] = cmd
        for i in range(4):
            inputs[k, i] = uin[i]
        rk4_step(s, uin, ext, dt, vp, tfac, tdof, tcoef, Minv, xs, ws, f, tau, k1, k2, k3, k4, tmp)
        flag = check_state(s, vp)
        out[k + 1] = s
        if flag != OK:
            return flag
    return OK


def features_array(states: np.ndarray, inputs: np.ndarray, vehicle) -> np.ndarray:
    """Term-library features for many samples (compiled path).

    Parameters
    ----------
    states : ndarray, shape (n, 12)
        States, in the state convention of this module.
    inputs : ndarray, shape (n, 4)
        Inputs, in the input convention of this module.
    vehicle : Vehicle
        The vehicle.

    Returns
    -------
    ndarray, shape (n, N_FEATURES)
        The features of each sample.
    """
    vp = vehicle_params(vehicle)
    out = np.empty((states.shape[0], N_FEATURES))
    for i in range(states.shape[0]):
        features(np.ascontiguousarray(states[i], dtype=float), np.ascontiguousarray(inputs[i], dtype=float), vp, out[i])
    return out


__all__ = [
    "vehicle_params",
    "crossflow_strips",
    "features",
    "generalized_force",
    "rhs",
    "rk4_step",
    "simulate_batch",
    "simulate_windows",
    "simulate_triggered_zigzag",
    "simulate_zigzag",
    "simulate_pi_hold",
    "features_array",
]
