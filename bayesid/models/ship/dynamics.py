"""The ship's equations (:mod:`bayesid.models.ship`) as compiled kernels that read the parameter
vector (:mod:`bayesid.models.ship.layout`) at every call: the hydrodynamic, propeller, rudder and
wind forces, the window driver :func:`simulate_windows` (the baseline and test oracle of the
generated kernel, :mod:`bayesid.models.ship.kernel`), the accelerations and forces at given
states and the generalised mass (inverse dynamics and the equation-error seed); and the true and
apparent wind of a track.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ...data.track import Track
from .hullterms import TERM_WIDTH
from .layout import GAUSS_W, GAUSS_X, NP, PARTICULARS


@nb.njit(cache=True)
def _forces(s, dlt, n, wn, we, cn, ce, p, gx, gw, F):
    """Hydrodynamic, propeller, rudder and wind forces (X, Y, N) at state s: F (3,)."""
    L, d, rho = p[0], p[2], p[5]
    D, AR, lam, eta, xR = p[8], p[9], p[10], p[11], p[12]
    rhoa, AT, AL = p[13], p[14], p[15]
    o = 16
    Xuu, Xvv, Xvr, Xrr = p[o + 3], p[o + 4], p[o + 5], p[o + 6]
    Yv, Yr, Nv, Nr, Ycf, Ncf = p[o + 7], p[o + 8], p[o + 9], p[o + 10], p[o + 11], p[o + 12]
    Yvvr, Yvrr, Nvvr, Nvrr = p[o + 13], p[o + 14], p[o + 15], p[o + 16]
    o = 20
    wP0, tP, k0, k1, k2, Ka, xP = p[o + 13], p[o + 14], p[o + 15], p[o + 16], p[o + 17], p[o + 18], p[o + 19]
    tR, aH, xH, eps, kap, lR, gR = p[o + 20], p[o + 21], p[o + 22], p[o + 23], p[o + 24], p[o + 25], p[o + 26]
    psi, u, v, r = s[2], s[3], s[4], s[5]
    U = math.sqrt(u * u + v * v)
    q = 0.5 * rho * L * d
    X = q * (Xuu * u * abs(u) + Xvv * v * v + Xvr * v * r * L + Xrr * r * r * L * L)
    Y = q * (Yv * U * v + Yr * u * r * L)
    N = q * L * (Nv * u * v + Nr * U * r * L)
    Ut = math.sqrt(u * u + v * v + p[NP - 1] * r * r * L * L)  # layout.FORM_SLOTS: coupling_rL
    if Ut > 1e-9:
        rl = r * L
        Y += q * (Yvvr * v * v * rl + Yvrr * v * rl * rl) / Ut
        N += q * L * (Nvvr * v * v * rl + Nvrr * v * rl * rl) / Ut
    i0 = 0.0
    i1 = 0.0
    h = 0.5 * L
    for k in range(gx.size):
        x = h * gx[k]
        w = v + x * r
        i0 += gw[k] * w * abs(w)
        i1 += gw[k] * x * w * abs(w)
    Y -= 0.5 * rho * d * Ycf * h * i0
    N -= 0.5 * rho * d * Ncf * h * i1
    # propeller
    vp = v + xP * L * r
    C1 = p[o + 36]
    if C1 > 0.0:  # the MMG 2015 wake in a turn (layout.WAKE_IN_TURN), C2m for beta_P < 0
        bP = math.atan2(-vp, abs(u) + 1e-12)
        C2 = p[o + 37] if bP > 0.0 else p[o + 38]
        uP = (1.0 - wP0) * (1.0 + (1.0 - math.exp(-C1 * abs(bP))) * (C2 - 1.0)) * u
    else:
        b2 = vp * vp / (u * u + vp * vp + 1e-12)
        wP = wP0 * math.exp(-4.0 * b2)
        uP = (1.0 - wP) * u
    KT = 0.0
    T = 0.0
    if n > 1e-6:
        J = min(max(uP / (n * D), -0.5), 1.2)
        KT = k0 + k1 * J + k2 * J * J
        T = rho * n * n * D**4 * KT
    elif n < -1e-6:
        T = -Ka * rho * n * n * D**4
    X += (1.0 - tP) * T
    # rudder
    if n > 1e-6:
        slip = math.sqrt(uP * uP + 8.0 * max(KT, 0.0) * n * n * D * D / math.pi)
        if uP >= 0.0:
            a = uP * (1.0 - kap) + kap * slip
            uR = eps * math.sqrt(eta * a * a + (1.0 - eta) * uP * uP)
        else:
            uR = eps * math.sqrt(eta) * kap * slip + (1.0 - math.sqrt(eta)) * uP
    elif uP >= 0.0:
        uR = eps * uP
    else:
        uR = uP
    # flow straightening: gR for beta_R >= 0 (lateral inflow at the rudder to port, v + lR L r <= 0),
    # gRm for beta_R < 0 (layout.FOLLOWS: equal unless the ship file gives gRm)
    wR = v + lR * L * r
    vR = -(gR if wR <= 0.0 else p[o + 35]) * wR
    UR = math.sqrt(uR * uR + vR * vR)
    fa = 6.13 * lam / (lam + 2.25)
    dm = p[o + 34] - dlt
    FN = 0.5 * rho * AR * fa * UR * (uR * math.sin(dm) - vR * math.cos(dm))
    X -= (1.0 - tR) * FN * math.sin(dm)
    Y -= (1.0 + aH) * FN * math.cos(dm)
    N -= (xR + aH * xH) * L * FN * math.cos(dm)
    # wind
    if AT > 0.0 or AL > 0.0:
        c, sn = math.cos(psi), math.sin(psi)
        wbx = c * wn + sn * we
        wby = -sn * wn + c * we
        ax = wbx - (u + c * cn + sn * ce)
        ay = wby - (v - sn * cn + c * ce)
        va2 = ax * ax + ay * ay
        if va2 > 0.0:
            g = math.atan2(-ay, -ax)
            qa = 0.5 * rhoa * va2
            X += qa * AT * (p[o + 27] * math.cos(g) + p[o + 28] * math.cos(3.0 * g))
            Y += qa * AL * (p[o + 29] * math.sin(g) + p[o + 30] * math.sin(3.0 * g))
            N += qa * AL * L * (p[o + 31] * math.sin(g) + p[o + 32] * math.sin(2.0 * g) + p[o + 33] * math.sin(3.0 * g))
    # extra hull terms (prime form, bayesid.models.ship.hullterms): TERM_WIDTH numbers each after NP
    rl = r * L
    for k in range((p.size - NP) // TERM_WIDTH):
        j = NP + TERM_WIDTH * k
        nv = int(p[j + 1] + p[j + 2] + p[j + 3] + p[j + 4])
        val = p[j + 7] * v ** int(p[j + 1]) * rl ** int(p[j + 2]) * abs(v) ** int(p[j + 3])
        val *= abs(rl) ** int(p[j + 4]) * dlt ** int(p[j + 5]) * abs(dlt) ** int(p[j + 6])
        if nv <= 2:
            val *= U ** (2 - nv)
        elif U > 1e-9:
            val /= U
            if nv == 4:  # a fourth-order surge term (hullterms.MAX_SURGE_ORDER)
                val /= U
        else:
            val = 0.0
        dof = int(p[j])
        if dof == 0:
            X += q * val
        elif dof == 1:
            Y += q * val
        else:
            N += q * L * val
    F[0] = X
    F[1] = Y
    F[2] = N


@nb.njit(cache=True)
def _rhs(s, dlt, n, wn, we, cn, ce, p, gx, gw, F, ds):
    L, d, m, xG, rho, kzz = p[0], p[2], p[3], p[4], p[5], p[6]
    o = 16
    q2 = 0.5 * rho * L * L * d
    mx, my, Jz = p[o] * q2, p[o + 1] * q2, p[o + 2] * q2 * L * L
    _forces(s, dlt, n, wn, we, cn, ce, p, gx, gw, F)
    psi, u, v, r = s[2], s[3], s[4], s[5]
    c, sn = math.cos(psi), math.sin(psi)
    ds[0] = u * c - v * sn + cn
    ds[1] = u * sn + v * c + ce
    ds[2] = r
    ds[3] = (F[0] + (m + my) * v * r + xG * m * r * r) / (m + mx)
    Iz = m * (kzz * L) ** 2 + xG * xG * m + Jz
    a11, a12, a22 = m + my, xG * m, Iz
    b1 = F[1] - (m + mx) * u * r
    b2 = F[2] - xG * m * u * r
    det = a11 * a22 - a12 * a12
    ds[4] = (a22 * b1 - a12 * b2) / det
    ds[5] = (a11 * b2 - a12 * b1) / det


@nb.njit(cache=True, parallel=True)
def simulate_windows(s0, starts, inputs, wind, cur, prm, dt, out, status):
    """RK4 of B parameter vectors over W windows, each restarting from its own state.

    Parameters
    ----------
    s0 : ndarray, shape (B, W, 6)
        State at each window start.
    starts : ndarray of int64, shape (W + 1,)
        Step index of each window start (last = n).
    inputs : ndarray, shape (B, n, 2)
        Rudder (rad, + to port) and propeller (rps), held over each step.
    wind : ndarray, shape (n, 2)
        True wind velocity towards (north/x, east/y), m/s, held over each step.
    cur : ndarray, shape (B, 2)
        Current, m/s, earth frame.
    prm : ndarray, shape (B, NP)
        Kernel parameter vectors (:mod:`bayesid.models.ship.layout`).
    dt : float
        Step, s.
    out : ndarray, shape (B, n + W, 6)
        Output: states at the window's step points (window w occupies rows
        ``starts[w] + w ... starts[w+1] + w``).
    status : ndarray of int64, shape (B, W)
        Output: 0 ok, 1 diverged (rest of window NaN).
    """
    B, W = s0.shape[0], s0.shape[1]
    gx, gw = GAUSS_X, GAUSS_W
    for job in nb.prange(B * W):
        b = job // W
        w = job % W
        s = s0[b, w].copy()
        k1 = np.empty(6)
        k2 = np.empty(6)
        k3 = np.empty(6)
        k4 = np.empty(6)
        tmp = np.empty(6)
        F = np.empty(3)
        p = prm[b]
        cn, ce = cur[b, 0], cur[b, 1]
        i0, i1 = starts[w], starts[w + 1]
        row = i0 + w
        out[b, row] = s
        status[b, w] = 0
        for k in range(i0, i1):
            dl, nn = inputs[b, k, 0], inputs[b, k, 1]
            wn, we = wind[k, 0], wind[k, 1]
            _rhs(s, dl, nn, wn, we, cn, ce, p, gx, gw, F, k1)
            for j in range(6):
                tmp[j] = s[j] + 0.5 * dt * k1[j]
            _rhs(tmp, dl, nn, wn, we, cn, ce, p, gx, gw, F, k2)
            for j in range(6):
                tmp[j] = s[j] + 0.5 * dt * k2[j]
            _rhs(tmp, dl, nn, wn, we, cn, ce, p, gx, gw, F, k3)
            for j in range(6):
                tmp[j] = s[j] + dt * k3[j]
            _rhs(tmp, dl, nn, wn, we, cn, ce, p, gx, gw, F, k4)
            bad = False
            for j in range(6):
                s[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
                if not math.isfinite(s[j]):
                    bad = True
            if bad or abs(s[3]) > 50.0 or abs(s[4]) > 50.0 or abs(s[5]) > 10.0:
                status[b, w] = 1
                for kk in range(k + 1, i1 + 1):
                    out[b, kk + w, :] = np.nan
                break
            out[b, k + 1 + w] = s


@nb.njit(cache=True)
def accelerations(states, inputs, wind, cur, prm, out):
    """Model accelerations (u', v', r') at given states.

    Parameters
    ----------
    states : ndarray, shape (N, 6)
        States (x, y, psi, u, v, r).
    inputs : ndarray, shape (N, 2)
        Rudder (rad) and propeller (rps).
    wind : ndarray, shape (N, 2)
        True wind velocity towards (north/x, east/y), m/s.
    cur : ndarray, shape (2,)
        Current, m/s, earth frame.
    prm : ndarray, shape (NP,)
        Kernel parameter vector.
    out : ndarray, shape (N, 3)
        Output: the accelerations, m/s^2 and rad/s^2.
    """
    F = np.empty(3)
    ds = np.empty(6)
    for i in range(states.shape[0]):
        _rhs(
            states[i], inputs[i, 0], inputs[i, 1], wind[i, 0], wind[i, 1], cur[0], cur[1], prm, GAUSS_X, GAUSS_W, F, ds
        )
        out[i, 0] = ds[3]
        out[i, 1] = ds[4]
        out[i, 2] = ds[5]


@nb.njit(cache=True)
def forces(states, inputs, wind, cur, prm, out):
    """External forces (X, Y, N) at given states.

    Parameters
    ----------
    states, inputs, wind, cur, prm : ndarray
        As in :func:`accelerations`.
    out : ndarray, shape (N, 3)
        Output: X, Y (N) and N (N m).
    """
    F = np.empty(3)
    for i in range(states.shape[0]):
        _forces(states[i], inputs[i, 0], inputs[i, 1], wind[i, 0], wind[i, 1], cur[0], cur[1], prm, GAUSS_X, GAUSS_W, F)
        out[i] = F


def mass_matrix(prm: np.ndarray) -> np.ndarray:
    """Generalised mass of the MMG equations (rigid body plus added mass).

    Parameters
    ----------
    prm : ndarray, shape (NP,)
        Kernel parameter vector.

    Returns
    -------
    ndarray, shape (3, 3)
        The mass matrix of (u', v', r'), kg and kg m^2.
    """
    L, d, m, xG, rho, kzz = prm[0], prm[2], prm[3], prm[4], prm[5], prm[6]
    o = len(PARTICULARS)
    q2 = 0.5 * rho * L * L * d
    mx, my, Jz = prm[o] * q2, prm[o + 1] * q2, prm[o + 2] * q2 * L * L
    Iz = m * (kzz * L) ** 2 + xG * xG * m + Jz
    return np.array([[m + mx, 0, 0], [0, m + my, xG * m], [0, xG * m, Iz]])


def wind_components(track: Track, t: np.ndarray) -> np.ndarray:
    """True-wind velocity of a track, interpolated at given times.

    Parameters
    ----------
    track : Track
        The track; its ``wind_speed`` and ``wind_dir`` (direction the wind comes FROM) are read.
    t : ndarray
        Times, s.

    Returns
    -------
    ndarray, shape (len(t), 2)
        Velocity towards (x/north, y/east), m/s; zeros when the track has no wind columns (or
        no finite value in them).
    """
    if "wind_speed" not in track or "wind_dir" not in track:
        return np.zeros((t.size, 2))
    sp = np.asarray(track["wind_speed"], float)
    di = np.asarray(track["wind_dir"], float)
    wn, we = -sp * np.cos(di), -sp * np.sin(di)
    ok = np.isfinite(wn) & np.isfinite(we)
    if not ok.any():
        return np.zeros((t.size, 2))
    return np.column_stack([np.interp(t, track.t[ok], wn[ok]), np.interp(t, track.t[ok], we[ok])])


def apparent_wind(track: Track, u, v, psi, t=None) -> tuple[np.ndarray, np.ndarray]:
    """Apparent wind of a ship moving through the track's true wind.

    Parameters
    ----------
    track : Track
        The track (its wind columns, :func:`wind_components`).
    u, v : array_like
        Body velocities, m/s, at the times ``t``.
    psi : array_like
        Heading, rad, at the times ``t``.
    t : ndarray, optional
        Times, s; default the track's.

    Returns
    -------
    speed : ndarray
        Apparent wind speed, m/s.
    angle : ndarray
        Angle off the bow the wind comes from, rad (+ from starboard).
    """
    t = track.t if t is None else t
    w = wind_components(track, t)
    c, s = np.cos(psi), np.sin(psi)
    ax = c * w[:, 0] + s * w[:, 1] - u
    ay = -s * w[:, 0] + c * w[:, 1] - v
    return np.hypot(ax, ay), np.arctan2(-ay, -ax)


#: The head-wind longitudinal force coefficient C_X used when the vessel file gives no ``[wind]``
#: ``Cx1``: merchant ships measure about 0.5 to 1 (Isherwood 1973, Trans. RINA 115:327-338).
TYPICAL_WIND_CX = 0.7


def wind_to_resistance(ship, track: Track) -> float | None:
    """How large the logged wind's surge force is against the hull's resistance: the RMS over the
    run of the head-wind force ``0.5 rho_air V_A^2 A_front |C_X|`` over the straight-running
    resistance at the approach speed ``0.5 rho L d |X'uu| U0^2`` (MMG prime form, Yasukawa &
    Yoshimura 2015, J. Mar. Sci. Technol. 20:37, eq. 6; the wind force as in the kernel's wind
    block). ``V_A`` is the apparent wind (:func:`apparent_wind`; the true wind where the track
    logs no u, v); ``U0`` the 90th percentile of the logged speed through the run.

    A ratio of 0.25 moves a steady speed set by that resistance by about 12 % (the force goes
    with U^2): a speed in the turn off by more than that is the wind's before it is the surge
    equation's.

    Parameters
    ----------
    ship : Ship
        The vessel (particulars, ``Xuu`` and the ``[wind]`` start ``Cx1``; :data:`TYPICAL_WIND_CX`
        where it gives none).
    track : Track
        The run; its ``wind_speed`` and ``wind_dir`` columns.

    Returns
    -------
    float or None
        The ratio; None when the track logs no wind, the ship has no frontal windage area or
        resistance, or the run has no speed.
    """
    t = np.asarray(track.t, float)
    w = wind_components(track, t)
    area = float(ship.particulars.get("A_front", 0.0))
    xuu = abs(float(ship.coefficients.get("Xuu", 0.0)))
    if not np.any(w) or area <= 0.0 or xuu <= 0.0:
        return None
    if all(k in track for k in ("u", "v", "psi")):
        u, v = np.asarray(track["u"], float), np.asarray(track["v"], float)
        va, _ = apparent_wind(track, u, v, np.asarray(track["psi"], float))
        speed = np.hypot(u, v)
    else:
        va = np.hypot(w[:, 0], w[:, 1])
        speed = np.hypot(np.gradient(np.asarray(track["x"], float), t), np.gradient(np.asarray(track["y"], float), t))
    ok = np.isfinite(va) & np.isfinite(speed)
    if not ok.any():
        return None
    u0 = float(np.percentile(speed[ok], 90))
    if u0 <= 0.0:
        return None
    cx = abs(float(ship.wind_start.get("Cx1") or 0.0)) or TYPICAL_WIND_CX
    rho_air = float(ship.particulars.get("rho_air", 1.225))
    wind = 0.5 * rho_air * area * cx * np.sqrt(np.mean(va[ok] ** 4))
    hull = 0.5 * float(ship.particulars["rho"]) * ship.L * float(ship.particulars["d"]) * xuu * u0**2
    return float(wind / hull)


__all__ = [
    "simulate_windows",
    "accelerations",
    "forces",
    "mass_matrix",
    "wind_components",
    "apparent_wind",
    "wind_to_resistance",
    "TYPICAL_WIND_CX",
]
