"""Benchmark (issue 67): is the packaged KVLCC2 model's tight steady turn (steady turning diameter about 0.51
of the tactical diameter, u/U0 about 0.24, where the other basin's free-running turns measure 0.78) what the
MMG model (Yasukawa & Yoshimura 2015, J. Mar. Sci. Technol. 20:37-52) with the published KVLCC2 L7
coefficients itself predicts, or a difference between bayesid's ship kernel and the MMG equations?

An independent simulator answers it: the PyPI package ``shipmmg`` (0.0.11, MIT; ShipMMG/shipmmg, a 3-DOF MMG
model integrated with scipy's ``solve_ivp``) with its own KVLCC2 L7 parameter set (the ``ship_KVLCC2_L7_model``
fixture of its tests; the same set as ShipMMG.jl's ``get_KVLCC2_L7_params``: MMG 2015 Tables 1-5 except
x'_P = -0.690 and the wake ``w_P0 exp(-4 beta_P^2)`` in place of the MMG wake in a turn). Flown, both sides,
35 deg of rudder at 15.8 deg/s from t = 10 s, constant propeller, from 1.179 m/s (the HSVA approach):

(i) shipmmg with its KVLCC2 L7 set, at that set's self-propulsion point (its own surge force zero);
(ii) bayesid with the packaged ``kvlcc2_7m.toml``, at the file's self-propulsion point (its propeller is
     HSVA's 0.204 m, not MMG's 0.216 m, so its rpm differs);
(iii) bayesid with every particular and coefficient of the file replaced by shipmmg's value where they differ
      (the cubic hull terms as extra hull terms ``Yvvv``, ``Yrrr``, ``Nvvv``, ``Nrrr``, ``Xvvvv`` in place of the
      cross-flow integral; the table lists every difference), at the same rpm as (i);
(iv) (iii) with MMG 2015's own x'_P = -0.48 and wake in a turn (C1 2.0, C2 1.6 / 1.1; Tables 4-5).

The differences between the file and shipmmg's set are also tried by group (the cubic hull terms, X'vvvv, the
added masses, the propeller diameter, the other particulars, x'_P, the two gamma_R), each added alone to the
packaged file and each left alone at the file's value in (iii), every ship at its own self-propulsion point.

The turn indices of every run come from one function over its x, y, psi, u, v, r (advance and tactical
diameter from the execute position at 90 and 180 deg of heading change, linear between 0.05 s samples; the
steady turning diameter 2 U / |r| over the last 20 s and, as a check, a circle fitted to the track of the
last 360 deg; u/U0, r' = |r| L / U and the drift angle over the last 20 s). bayesid's own
``manoeuvre_indices`` (which reads the execute from the rudder ramp and the crossings from local
polynomials) gives the advance and tactical diameter of every track too, as a check of the definitions.

Then, to find what makes (i) and (iii) differ, the forces at one state (the steady starboard turn of (i):
u, v, r, rudder 35 deg, the same rps) are taken apart: shipmmg's X_H, X_P, X_R, Y_H, Y_R, N_H, N_R (its
``get_sub_values_from_simulation_result``; its Y_R there has ``1 - t_R`` where its simulation has
``1 + a_H``, so Y_R is formed from its F_N, and the accelerations of its own right-hand side are checked
against the components), bayesid's (the kernel's ``forces`` with the rudder area and the propeller zeroed in
turn), and each hull term of both. A reference MMG 2015 right-hand side written here (RK4, 0.05 s; it
reproduces both simulators) is flown with each of the kernel's hull and angle forms switched on alone, to
put a number on what each does to the turn.

    pip install --no-deps shipmmg==0.0.11   # its metadata pins Pillow<11 (its plotting); the model needs numpy, scipy
    python benchmarks/shipmmg_turn.py

Nothing is fitted. The last lines are machine-readable (``ratio_<model>_<side>``, ``u_over_U0_<model>_<side>``,
``first_differing_component`` in the order X_H Y_H N_H X_P X_R Y_R N_R, more than 1 % apart;
``largest_kernel_form_effect``: the kernel form that moves the reference's mean ratio most).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bayesid.estimation.indices import manoeuvre_indices  # noqa: E402
from bayesid.models.ship import load_ship  # noqa: E402
from bayesid.models.ship.dynamics import accelerations, forces  # noqa: E402
from bayesid.models.ship.layout import PARTICULAR_INDEX  # noqa: E402
from bayesid.models.ship.trials import T_EXECUTE, TrialOptions, propulsion_point, simulate_trial  # noqa: E402

try:
    from shipmmg import mmg_3dof as smmg
except ImportError:  # pragma: no cover - the benchmark needs the package
    smmg = None

#: The approach (HSVA, SIMMAN 2008; the packaged file's [service] speed), m/s; rudder, deg and deg/s.
U0, RUDDER_DEG, RUDDER_RATE = 1.179, 35.0, 15.8
#: Sample and RK4 step, s; run length after the execute, s; the steady window at the end, s.
DT, DURATION, TAIL = 0.05, 480.0, 20.0

#: shipmmg's KVLCC2 L7 set (ShipMMG/shipmmg tests/test_mmg_3dof.py, fixture ``ship_KVLCC2_L7_model``; its rho
#: 1.025 t/m^3 written here as 1025 kg/m^3, so forces are in N). Lengths m; x_P and l_R are prime (shipmmg
#: uses them so), x_R and x_H are given as primes here and passed to shipmmg times L (as the fixture does).
L7 = {
    "rho": 1025.0,
    "L_pp": 7.00,
    "B": 1.27,
    "d": 0.46,
    "nabla": 3.27,
    "x_G": 0.25,
    "D_p": 0.216,
    "H_R": 0.345,
    "A_R": 0.0539,
    "t_P": 0.220,
    "w_P0": 0.40,
    "m_x_dash": 0.022,
    "m_y_dash": 0.223,
    "J_z_dash": 0.011,
    "t_R": 0.387,
    "x_R_dash": -0.500,
    "a_H": 0.312,
    "x_H_dash": -0.464,
    "γ_R_minus": 0.395,
    "γ_R_plus": 0.640,
    "l_R": -0.710,
    "x_P": -0.690,
    "ϵ": 1.09,
    "κ": 0.50,
    "f_α": 2.747,
}
L7_HULL = {
    "k_0": 0.2931,
    "k_1": -0.2753,
    "k_2": -0.1385,
    "R_0_dash": 0.022,
    "X_vv_dash": -0.040,
    "X_vr_dash": 0.002,
    "X_rr_dash": 0.011,
    "X_vvvv_dash": 0.771,
    "Y_v_dash": -0.315,
    "Y_r_dash": 0.083,
    "Y_vvv_dash": -1.607,
    "Y_vvr_dash": 0.379,
    "Y_vrr_dash": -0.391,
    "Y_rrr_dash": 0.008,
    "N_v_dash": -0.137,
    "N_r_dash": -0.049,
    "N_vvv_dash": -0.030,
    "N_vvr_dash": -0.294,
    "N_vrr_dash": 0.055,
    "N_rrr_dash": -0.013,
}
#: MMG 2015's own values where shipmmg's set differs (Tables 4-5, KVLCC2 L7): x'_P and the wake in a turn.
MMG2015_WAKE = {"xP": -0.48, "C1": 2.0, "C2": 1.6, "C2m": 1.1}
#: Hull terms: bayesid name -> shipmmg name.
HULL_NAMES = {
    "Xvv": "X_vv_dash",
    "Xvr": "X_vr_dash",
    "Xrr": "X_rr_dash",
    "Xvvvv": "X_vvvv_dash",
    "Yv": "Y_v_dash",
    "Yr": "Y_r_dash",
    "Yvvv": "Y_vvv_dash",
    "Yvvr": "Y_vvr_dash",
    "Yvrr": "Y_vrr_dash",
    "Yrrr": "Y_rrr_dash",
    "Nv": "N_v_dash",
    "Nr": "N_r_dash",
    "Nvvv": "N_vvv_dash",
    "Nvvr": "N_vvr_dash",
    "Nvrr": "N_vrr_dash",
    "Nrrr": "N_rrr_dash",
}


def lambda_from_f_alpha(f: float) -> float:
    """The rudder aspect ratio whose Fujii slope 6.13 lambda / (lambda + 2.25) (Fujii's formula, as MMG 2015 uses it) is ``f``."""
    return 2.25 * f / (6.13 - f)


def shipmmg_values() -> tuple[dict, dict]:
    """shipmmg's KVLCC2 L7 set in bayesid's names: (particulars, coefficients)."""
    p = L7
    part = {
        "B": p["B"],
        "d": p["d"],
        "mass_kg": p["rho"] * p["nabla"],
        "xG": p["x_G"],
        "rho": p["rho"],
        "kzz": 0.25,  # I_zG = m (0.25 L)^2
        "D_prop": p["D_p"],
        "A_rudder": p["A_R"],
        "lambda_rudder": lambda_from_f_alpha(p["f_α"]),
        "eta_prop_rudder": p["D_p"] / p["H_R"],
        "x_rudder": p["x_R_dash"],
    }
    coef = {
        "mx": p["m_x_dash"],
        "my": p["m_y_dash"],
        "Jz": p["J_z_dash"],
        "Xuu": -L7_HULL["R_0_dash"],
        **{k: L7_HULL[v] for k, v in HULL_NAMES.items()},
        "Ycf": 0.0,  # shipmmg has the MMG cubic terms, no cross-flow integral
        "Ncf": 0.0,
        "wP": p["w_P0"],
        "tP": p["t_P"],
        "k0": L7_HULL["k_0"],
        "k1": L7_HULL["k_1"],
        "k2": L7_HULL["k_2"],
        "xP": p["x_P"],
        "tR": p["t_R"],
        "aH": p["a_H"],
        "xH": p["x_H_dash"],
        "eps": p["ϵ"],
        "kappa": p["κ"],
        "lR": p["l_R"],
        "gR": p["γ_R_plus"],  # bayesid's gR acts for beta_R >= 0, gRm for beta_R < 0
        "gRm": p["γ_R_minus"],
        "C1": 0.0,  # shipmmg's wake is w_P0 exp(-4 beta_P^2), the file's form
    }
    return part, coef


def shipmmg_params():
    """shipmmg's (basic, maneuvering) parameter objects of the KVLCC2 L7 set (SI)."""
    p = L7
    L, rho = p["L_pp"], p["rho"]
    m = rho * p["nabla"]
    q2 = 0.5 * rho * L**2 * p["d"]
    basic = smmg.Mmg3DofBasicParams(
        L_pp=L,
        B=p["B"],
        d=p["d"],
        x_G=p["x_G"],
        D_p=p["D_p"],
        m=m,
        I_zG=m * (0.25 * L) ** 2,
        A_R=p["A_R"],
        η=p["D_p"] / p["H_R"],
        m_x=p["m_x_dash"] * q2,
        m_y=p["m_y_dash"] * q2,
        J_z=p["J_z_dash"] * q2 * L**2,
        f_α=p["f_α"],
        ϵ=p["ϵ"],
        t_R=p["t_R"],
        x_R=p["x_R_dash"] * L,
        a_H=p["a_H"],
        x_H=p["x_H_dash"] * L,
        γ_R_minus=p["γ_R_minus"],
        γ_R_plus=p["γ_R_plus"],
        l_R=p["l_R"],
        κ=p["κ"],
        t_P=p["t_P"],
        w_P0=p["w_P0"],
        x_P=p["x_P"],
    )
    return basic, smmg.Mmg3DofManeuveringParams(**L7_HULL)


def shipmmg_components(u, v, r, delta, n, basic=None, hull=None) -> dict:
    """shipmmg's forces and intermediate values at one state (rudder delta in MMG's sign, + to starboard;
    n in rps). Its ``get_sub_values_from_simulation_result`` writes Y_R with ``1 - t_R``; its simulation
    uses ``-(1 + a_H) F_N cos(delta)``, formed here from its F_N."""
    b, h = shipmmg_params()
    b, h = basic or b, hull or h
    names = "X_H X_R X_P Y_H Y_R_sub N_H N_R U beta v' r' beta_P w_P J K_T beta_R gamma_R v_R u_R U_R alpha_R F_N"
    vals = smmg.get_sub_values_from_simulation_result(
        [u], [v], [r], [delta], [n], b, h, ρ=L7["rho"], return_all_vals=True
    )
    out = {k: float(np.asarray(x).ravel()[0]) for k, x in zip(names.split(), vals)}
    out["Y_R"] = -(1.0 + b.a_H) * out["F_N"] * math.cos(delta)
    return out


def shipmmg_rhs():
    """shipmmg's own right-hand side (the function ``simulate`` hands to ``solve_ivp``), taken by calling it
    with ``solve_ivp`` replaced for the call: f(t, [u, v, r, x, y, psi, delta, n]) -> derivatives."""
    basic, hull = shipmmg_params()
    got, real = {}, smmg.solve_ivp

    def grab(fun, *args, **kwargs):
        got["f"] = fun

    smmg.solve_ivp = grab
    try:
        smmg.simulate_mmg_3dof(basic, hull, [0.0, 1.0], [0.0, 0.0], [1.0, 1.0], ρ=L7["rho"])
    finally:
        smmg.solve_ivp = real
    return got["f"]


def rudder_ramp(t: np.ndarray, sign: float) -> np.ndarray:
    """The rudder (rad, MMG sign: + to starboard) of a turn: 0, then from T_EXECUTE at RUDDER_RATE to 35 deg."""
    return sign * np.clip((t - T_EXECUTE) * math.radians(RUDDER_RATE), 0.0, math.radians(RUDDER_DEG))


def fly_shipmmg(sign: float, nps: float) -> dict:
    """shipmmg's turn (sign +1 starboard, -1 port) at constant ``nps``: the track sampled every DT."""
    basic, hull = shipmmg_params()
    t = np.arange(0.0, T_EXECUTE + DURATION + DT / 2, DT)
    delta = rudder_ramp(t, sign)
    sol = smmg.simulate_mmg_3dof(
        basic, hull, t, delta, np.full(t.size, nps), u0=U0, ρ=L7["rho"], rtol=1e-9, atol=1e-10, max_step=0.1
    )
    if sol.status != 0:
        raise RuntimeError(f"shipmmg: {sol.message}")
    y = sol.sol(t)
    return {"t": t, "u": y[0], "v": y[1], "r": y[2], "x": y[3], "y": y[4], "psi": y[5], "delta_r": -delta}


def fly_bayesid(ship, sign: float, rpm: float) -> dict:
    """bayesid's turn (sign +1 starboard: the package's rudder -35 deg) at constant ``rpm``, RK4 at DT."""
    opts = TrialOptions(dt=DT, rudder_rate_deg_s=RUDDER_RATE, duration=DURATION)
    tr = simulate_trial(ship, "turn", -sign * RUDDER_DEG, speed=U0, rpm=rpm, options=opts).track
    out = {k: np.asarray(tr[k], float) for k in ("x", "y", "psi", "u", "v", "r", "delta_r")}
    out["t"] = np.asarray(tr.t, float)
    return out


# --- a reference MMG 2015 right-hand side, with the kernel's forms to switch on one at a time -----------------
#: The forms in which bayesid's kernel (bayesid/models/ship/dynamics.py ``_forces``) writes MMG terms
#: differently, and shipmmg's one departure from MMG 2015 (beta and U from v - x_G r; its v is at midship).
FORMS = {
    "R0_uu": "resistance -R'0 u|u| (MMG: -R'0 U^2)",
    "lin_u": "Y'r r' U u, N'v v' U u (MMG: U^2 r', U^2 v')",
    "coupling_Ut": "Y'vvr.. N'vrr over Ut = sqrt(u^2+v^2+(rL)^2) (MMG: over U)",
    "angles": "beta_P = atan(-(v + x_P L r)/u), v_R = -gamma_R (v + l_R L r) (MMG: beta - x'_P r', U gamma_R beta_R)",
    "xg_quirk": "shipmmg's U = sqrt(u^2 + (v - x_G r)^2), beta = asin(-(v - x_G r)/U)",
}


def ref_forces(u, v, r, delta, n, forms=(), wake=None, xP=None) -> dict:
    """MMG 2015 forces of the KVLCC2 L7 set at a state (SI; rudder + to starboard; n rps). ``forms``: names of
    FORMS to use instead of MMG's; ``wake``: (C1, C2 for beta_P > 0, C2 for beta_P < 0) for MMG 2015's wake in
    a turn in place of w_P0 exp(-4 beta_P^2); ``xP``: x'_P in place of the set's."""
    p, h = L7, L7_HULL
    L, d, rho = p["L_pp"], p["d"], p["rho"]
    xP = p["x_P"] if xP is None else xP
    vm = v - p["x_G"] * r if "xg_quirk" in forms else v
    U = math.hypot(u, vm)
    beta = math.atan2(-vm, u)
    vd, rd = v / U, r * L / U
    q = 0.5 * rho * L * d
    # hull: 0.5 rho L d U^2 times the prime polynomials (L once more for N)
    R0 = -h["R_0_dash"] * (u * abs(u) if "R0_uu" in forms else U * U)
    XH = q * R0 + q * U * U * (
        h["X_vv_dash"] * vd**2 + h["X_vr_dash"] * vd * rd + h["X_rr_dash"] * rd**2 + h["X_vvvv_dash"] * vd**4
    )
    lin = u if "lin_u" in forms else U
    cpl = U / math.sqrt(u * u + v * v + (r * L) ** 2) if "coupling_Ut" in forms else 1.0
    YH = q * (
        h["Y_v_dash"] * vd * U * U
        + h["Y_r_dash"] * rd * U * lin
        + U * U * (h["Y_vvv_dash"] * vd**3 + h["Y_rrr_dash"] * rd**3)
        + cpl * U * U * (h["Y_vvr_dash"] * vd**2 * rd + h["Y_vrr_dash"] * vd * rd**2)
    )
    NH = (
        q
        * L
        * (
            h["N_v_dash"] * vd * U * lin
            + h["N_r_dash"] * rd * U * U
            + U * U * (h["N_vvv_dash"] * vd**3 + h["N_rrr_dash"] * rd**3)
            + cpl * U * U * (h["N_vvr_dash"] * vd**2 * rd + h["N_vrr_dash"] * vd * rd**2)
        )
    )
    # propeller: (1 - t_P) rho n^2 D^4 K_T(J), J = (1 - w_P) u / (n D)
    if "angles" in forms:
        beta_P = math.atan2(-(v + xP * L * r), abs(u))
        s2 = math.sin(beta_P) ** 2
    else:
        beta_P = beta - xP * rd
        s2 = beta_P**2
    if wake is None:
        omw = 1.0 - p["w_P0"] * math.exp(-4.0 * s2)
    else:
        C1, C2p, C2m = wake
        omw = (1.0 - p["w_P0"]) * (1.0 + (1.0 - math.exp(-C1 * abs(beta_P))) * ((C2p if beta_P > 0 else C2m) - 1.0))
    D = p["D_p"]
    J = omw * u / (n * D)
    KT = h["k_0"] + h["k_1"] * J + h["k_2"] * J * J
    XP = (1.0 - p["t_P"]) * rho * n * n * D**4 * KT
    # rudder: F_N = 0.5 rho A_R f_alpha U_R^2 sin(delta - atan(v_R / u_R))
    eta, kap, eps = p["D_p"] / p["H_R"], p["κ"], p["ϵ"]
    uR = (
        eps
        * omw
        * u
        * math.sqrt(eta * (1.0 + kap * (math.sqrt(1.0 + 8.0 * KT / (math.pi * J * J)) - 1.0)) ** 2 + 1 - eta)
    )
    if "angles" in forms:
        wR = v + p["l_R"] * L * r
        vR = -(p["γ_R_plus"] if wR <= 0.0 else p["γ_R_minus"]) * wR
    else:
        beta_R = beta - p["l_R"] * rd
        vR = U * (p["γ_R_minus"] if beta_R < 0.0 else p["γ_R_plus"]) * beta_R
    FN = 0.5 * rho * p["A_R"] * p["f_α"] * (uR * uR + vR * vR) * math.sin(delta - math.atan2(vR, uR))
    XR = -(1.0 - p["t_R"]) * FN * math.sin(delta)
    YR = -(1.0 + p["a_H"]) * FN * math.cos(delta)
    NR = -(p["x_R_dash"] + p["a_H"] * p["x_H_dash"]) * L * FN * math.cos(delta)
    return {"X_H": XH, "X_P": XP, "X_R": XR, "Y_H": YH, "Y_R": YR, "N_H": NH, "N_R": NR, "F_N": FN}


def ref_accelerations(u, v, r, delta, n, **kw) -> tuple[float, float, float]:
    """(u', v', r') of MMG 2015's equations of motion at midship with ``ref_forces``."""
    p = L7
    L = p["L_pp"]
    m = p["rho"] * p["nabla"]
    q2 = 0.5 * p["rho"] * L**2 * p["d"]
    mx, my, Jz = p["m_x_dash"] * q2, p["m_y_dash"] * q2, p["J_z_dash"] * q2 * L**2
    xG = p["x_G"]
    Iz = m * (0.25 * L) ** 2 + xG * xG * m + Jz
    F = ref_forces(u, v, r, delta, n, **kw)
    X = F["X_H"] + F["X_P"] + F["X_R"]
    Y = F["Y_H"] + F["Y_R"]
    N = F["N_H"] + F["N_R"]
    du = (X + (m + my) * v * r + xG * m * r * r) / (m + mx)
    b1, b2 = Y - (m + mx) * u * r, N - xG * m * u * r
    det = (m + my) * Iz - (xG * m) ** 2
    return du, (Iz * b1 - xG * m * b2) / det, ((m + my) * b2 - xG * m * b1) / det


def fly_reference(sign: float, nps: float, **kw) -> dict:
    """The reference MMG model's turn, RK4 at DT with the rudder ramp at the stage times."""
    t = np.arange(0.0, T_EXECUTE + DURATION + DT / 2, DT)
    S = np.empty((t.size, 6))
    s = np.array([0.0, 0.0, 0.0, U0, 0.0, 0.0])  # x, y, psi, u, v, r

    def f(tt, s):
        delta = float(rudder_ramp(np.array([tt]), sign)[0])
        du, dv, dr = ref_accelerations(s[3], s[4], s[5], delta, nps, **kw)
        c, sn = math.cos(s[2]), math.sin(s[2])
        return np.array([s[3] * c - s[4] * sn, s[3] * sn + s[4] * c, s[5], du, dv, dr])

    for i, tt in enumerate(t):
        S[i] = s
        k1 = f(tt, s)
        k2 = f(tt + DT / 2, s + DT / 2 * k1)
        k3 = f(tt + DT / 2, s + DT / 2 * k2)
        k4 = f(tt + DT, s + DT * k3)
        s = s + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    out = dict(zip(("x", "y", "psi", "u", "v", "r"), S.T))
    out.update(t=t, delta_r=-rudder_ramp(t, sign))
    return out


# --- the turn's indices, one definition for every simulator --------------------------------------------------
def turn_indices(tr: dict) -> dict:
    """Advance, transfer and tactical diameter (from the execute position at T_EXECUTE, along and across its
    heading, at 90 and 180 deg of heading change, linear between samples), the steady turning diameter
    2 U / |r| over the last TAIL s and from a circle fitted to the last 360 deg of track, their ratio to the
    tactical diameter, u/U0, r' and the drift angle over the last TAIL s; and bayesid's manoeuvre_indices'
    advance and tactical diameter of the same track."""
    t, x, y, psi, u, v, r = (tr[k] for k in ("t", "x", "y", "psi", "u", "v", "r"))
    ie = int(np.searchsorted(t, T_EXECUTE))
    x0, y0, p0 = x[ie], y[ie], psi[ie]
    side = math.copysign(1.0, r[-1])
    if side != math.copysign(1.0, -tr["delta_r"][-1]):  # rudder to starboard (package sign < 0): r > 0
        raise RuntimeError("the turn goes against its rudder: a sign convention is wrong")
    h = side * (psi - p0)

    def at(angle):
        i = ie + int(np.flatnonzero(h[ie:] >= angle)[0])
        f = (angle - h[i - 1]) / (h[i] - h[i - 1])
        xa, ya = x[i - 1] + f * (x[i] - x[i - 1]), y[i - 1] + f * (y[i] - y[i - 1])
        dx, dy = xa - x0, ya - y0
        return dx * math.cos(p0) + dy * math.sin(p0), abs(-dx * math.sin(p0) + dy * math.cos(p0))

    advance, transfer = at(math.pi / 2)
    _, tactical = at(math.pi)
    tail = t >= t[-1] - TAIL
    U = np.hypot(u[tail], v[tail])
    steady = 2.0 * float(np.mean(U)) / float(np.mean(np.abs(r[tail])))
    last = h >= h[-1] - 2 * math.pi  # circle through the last full turn (Kasa's algebraic fit)
    A = np.column_stack([x[last], y[last], np.ones(last.sum())])
    cx, cy, c = np.linalg.lstsq(A, -(x[last] ** 2 + y[last] ** 2), rcond=None)[0]
    circle = 2.0 * math.sqrt(cx * cx / 4 + cy * cy / 4 - c)
    ind = manoeuvre_indices(t, x, y, psi, tr["delta_r"])
    return {
        "advance": advance,
        "transfer": transfer,
        "tactical": tactical,
        "steady": steady,
        "circle": circle,
        "ratio": steady / tactical,
        "u_U0": float(np.mean(u[tail])) / float(u[0]),
        "r_prime": float(np.mean(np.abs(r[tail]) * L7["L_pp"] / U)),
        "drift_deg": float(np.degrees(np.mean(np.abs(np.arctan2(-v[tail], u[tail]))))),
        "mi_advance": float(ind["advance_m"]),
        "mi_tactical": float(ind["tactical_diameter_m"]),
        "state": (float(u[-1]), float(v[-1]), float(r[-1])),
    }


def bayesid_ship_iii(base, keep: tuple = ()):
    """The packaged ship with every particular and coefficient replaced by shipmmg's KVLCC2 L7 value, except
    the names in ``keep`` (left at the file's value)."""
    part, coef = shipmmg_values()
    part = {k: v for k, v in part.items() if k not in keep}
    coef = {k: v for k, v in coef.items() if k not in keep}
    return with_values(base, part, coef)


def with_values(base, part: dict, coef: dict):
    """``base`` with particulars ``part`` and coefficients ``coef`` replaced."""
    return dataclasses.replace(base, particulars=dict(base.particulars, **part)).with_coefficients(coef)


#: Groups of the differences between the file and shipmmg's set (bayesid names).
GROUPS = {
    "cubic": ("Ycf Ncf -> Y'vvv Y'rrr N'vvv N'rrr", ("Ycf", "Ncf", "Yvvv", "Yrrr", "Nvvv", "Nrrr")),
    "Xvvvv": ("X'vvvv 0.771", ("Xvvvv",)),
    "added_mass": ("m'x m'y J'z 0.022 0.223 0.011", ("mx", "my", "Jz")),
    "D_prop": ("D_p 0.216 m (file: HSVA's 0.204 m)", ("D_prop",)),
    "particulars": (
        "B d mass xG rho A_R lambda eta",
        ("B", "d", "mass_kg", "xG", "rho", "A_rudder", "lambda_rudder", "eta_prop_rudder"),
    ),
    "xP": ("x'P -0.690", ("xP",)),
    "gR": ("gamma_R 0.640 / 0.395", ("gR", "gRm")),
}


def bayesid_components(ship, u, v, r, delta, n) -> dict:
    """bayesid's kernel forces at a state (rudder delta in MMG's sign; n rps), taken apart: hull = the rudder
    area and the propeller zeroed; propeller = rudder area zeroed minus hull; rudder = the rest."""
    state = np.array([[0.0, 0.0, 0.0, u, v, r]])

    def F(prm, nn):
        out = np.empty((1, 3))
        forces(state, np.array([[-delta, nn]]), np.zeros((1, 2)), np.zeros(2), prm, out)
        return out[0]

    prm = ship.params()
    bare = prm.copy()
    bare[PARTICULAR_INDEX["A_rudder"]] = 0.0
    H, HP, ALL = F(bare, 0.0), F(bare, n), F(prm, n)
    P, R = HP - H, ALL - HP
    return {"X_H": H[0], "Y_H": H[1], "N_H": H[2], "X_P": P[0], "X_R": R[0], "Y_R": R[1], "N_R": R[2]}


def hull_terms_table(ship, u, v, r) -> list[tuple]:
    """Each hull term's (X, Y or N) at the state in shipmmg (its own code, the set with that term alone),
    in MMG 2015 (reference, midship U) and in bayesid's kernel (the hull with and without the term)."""
    b0, h0 = shipmmg_params()
    zero = {k: 0.0 for k in L7_HULL if k not in ("k_0", "k_1", "k_2")}
    rows = []
    kernel_all = bayesid_components(ship, u, v, r, 0.0, 0.0)
    U = math.hypot(u, v)
    q = 0.5 * L7["rho"] * L7["L_pp"] * L7["d"]
    vd, rd = v / U, r * L7["L_pp"] / U
    powers = {"vv": (2, 0), "vr": (1, 1), "rr": (0, 2), "vvvv": (4, 0), "v": (1, 0), "r": (0, 1), "vvv": (3, 0)}
    powers.update({"vvr": (2, 1), "vrr": (1, 2), "rrr": (0, 3)})
    for name, sname in [("R0", "R_0_dash"), *HULL_NAMES.items()]:
        dof = {"R": "X", "X": "X", "Y": "Y", "N": "N"}[name[0]]
        key = f"{dof}_H"
        h1 = dataclasses.replace(h0, **{**zero, sname: L7_HULL[sname]})
        sm = shipmmg_components(u, v, r, 0.0, 1.0, b0, h1)[key]
        if name == "R0":
            mmg = -q * L7_HULL["R_0_dash"] * U * U
            kern = (
                kernel_all["X_H"] - bayesid_components(ship.with_coefficients({"Xuu": 0.0}), u, v, r, 0.0, 0.0)["X_H"]
            )
        else:
            a, b = powers[name[1:]]
            mmg = q * U * U * L7_HULL[sname] * vd**a * rd**b * (L7["L_pp"] if dof == "N" else 1.0)
            kern = kernel_all[key] - bayesid_components(ship.with_coefficients({name: 0.0}), u, v, r, 0.0, 0.0)[key]
        rows.append((name, key, sm, mmg, kern))
    return rows


def main() -> int:
    if smmg is None:
        print(
            "shipmmg is not installed: pip install --no-deps shipmmg==0.0.11 (numpy and scipy are all its model needs)"
        )
        return 0
    import shipmmg

    base = load_ship("kvlcc2_7m")
    ship3 = bayesid_ship_iii(base)
    ship4 = ship3.with_coefficients(MMG2015_WAKE)
    part, coef = shipmmg_values()
    last = []

    print(f"shipmmg {shipmmg.__version__} (KVLCC2 L7 set of its tests) against bayesid ({base.file_path})")
    print("\nparameters: packaged file vs shipmmg's KVLCC2 L7 set (bayesid names; * = differs, used in (iii))")
    print("name              packaged     shipmmg")
    for k, val in [*part.items(), *coef.items()]:
        old = base.particulars.get(k, base.coefficients.get(k, 0.0))
        star = "*" if not math.isclose(old, val, rel_tol=1e-9, abs_tol=1e-12) else " "
        print(f"{k:15s} {old:10.7g}  {val:10.7g} {star}")
    print(
        "(packaged mx, my, Jz: the file's empirical estimate; packaged Xvvvv, Yvvv, Yrrr, Nvvv, Nrrr: absent, the "
        "cross-flow integral Ycf, Ncf stands in; packaged gRm follows gR.)"
    )
    print("kernel forms that are not parameters: " + "; ".join(v for k, v in FORMS.items() if k != "xg_quirk") + ".")

    # the approach: shipmmg's own self-propulsion point at U0 (surge force zero going straight)
    def surge(n):
        c = shipmmg_components(U0, 0.0, 0.0, 0.0, n)
        return c["X_H"] + c["X_P"] + c["X_R"]

    nps = brentq(surge, 1.0, 60.0, xtol=1e-12)
    rpm3 = propulsion_point(ship3, U0)[1]
    rpm2 = propulsion_point(base, U0)[1]
    print(
        f"\napproach {U0} m/s; self-propulsion: shipmmg set {nps:.4f} rps ({60 * nps:.2f} rpm), bayesid (iii) "
        f"{rpm3:.2f} rpm, packaged file {rpm2:.2f} rpm (D_p 0.204 m). Rudder {RUDDER_DEG:g} deg at "
        f"{RUDDER_RATE} deg/s from t = {T_EXECUTE:g} s, {DURATION:g} s after; dt {DT} s."
    )

    runs = {}
    for sign, side in ((1.0, "stbd"), (-1.0, "port")):
        runs[("shipmmg", side)] = fly_shipmmg(sign, nps)
        runs[("packaged", side)] = fly_bayesid(base, sign, rpm2)
        runs[("iii", side)] = fly_bayesid(ship3, sign, 60.0 * nps)
        runs[("iv", side)] = fly_bayesid(ship4, sign, 60.0 * nps)
    labels = {
        "shipmmg": "(i) shipmmg, its KVLCC2 L7 set",
        "packaged": "(ii) bayesid, packaged file",
        "iii": "(iii) bayesid, shipmmg's values",
        "iv": "(iv) (iii) + x'P -0.48, MMG wake C1 C2",
    }
    head = (
        "model                                   side  advance transfer tactical  steady  circle  st/tac"
        "   u/U0     r'  drift | manoeuvre_indices adv  tac"
    )
    print("\n" + head)
    res = {}
    for key, label in labels.items():
        for side in ("stbd", "port"):
            ind = res[(key, side)] = turn_indices(runs[(key, side)])
            print(
                f"{label:39s} {side:4s} {ind['advance']:8.2f} {ind['transfer']:8.2f} {ind['tactical']:8.2f}"
                f" {ind['steady']:7.2f} {ind['circle']:7.2f} {ind['ratio']:7.3f} {ind['u_U0']:6.3f}"
                f" {ind['r_prime']:6.3f} {ind['drift_deg']:6.1f} | {ind['mi_advance']:21.2f} {ind['mi_tactical']:5.2f}"
            )
            last += [f"ratio_{key}_{side} {ind['ratio']:.3f}", f"u_over_U0_{key}_{side} {ind['u_U0']:.3f}"]

    # which of the parameter differences move the packaged file's turn: each group alone, and (iii) without it
    part, coef = shipmmg_values()
    print(
        "\nthe parameter differences by group (bayesid, each ship at its own self-propulsion point at U0): "
        "the packaged file with one group of shipmmg's values, and (iii) with one group left at the file's"
    )
    print(
        "group        values                                  side  file+group st/tac  u/U0 | (iii)-group st/tac  u/U0"
    )
    for key, (label, names) in GROUPS.items():
        added = with_values(
            base, {k: v for k, v in part.items() if k in names}, {k: v for k, v in coef.items() if k in names}
        )
        left = bayesid_ship_iii(base, keep=names)
        for sign, side in ((1.0, "stbd"), (-1.0, "port")):
            a = turn_indices(fly_bayesid(added, sign, propulsion_point(added, U0)[1]))
            b = turn_indices(fly_bayesid(left, sign, propulsion_point(left, U0)[1]))
            print(
                f"{key:12s} {label:39s} {side:4s} {a['ratio']:17.3f} {a['u_U0']:5.3f} |"
                f" {b['ratio']:18.3f} {b['u_U0']:5.3f}"
            )
            last += [f"ratio_file_plus_{key}_{side} {a['ratio']:.3f}", f"ratio_iii_minus_{key}_{side} {b['ratio']:.3f}"]

    # one state: the steady starboard turn of (i)
    u, v, r = res[("shipmmg", "stbd")]["state"]
    delta = math.radians(RUDDER_DEG)
    sm = shipmmg_components(u, v, r, delta, nps)
    rf = ref_forces(u, v, r, delta, nps)
    bz = bayesid_components(ship3, u, v, r, delta, nps)
    print(
        f"\nforces at one state, the end of (i)'s starboard turn: u {u:.4f} m/s, v {v:.4f} m/s, r {r:.5f} rad/s "
        f"(r' {r * L7['L_pp'] / math.hypot(u, v):.3f}, beta {math.degrees(math.atan2(-v, u)):.2f} deg), rudder "
        f"{RUDDER_DEG:g} deg to starboard, {nps:.4f} rps (N, N m)"
    )
    print(
        "component  MMG 2015 form                  shipmmg  MMG 2015 (ref.)  bayesid (iii)  bayesid/shipmmg  bayesid/MMG"
    )
    eqs = {
        "X_H": "q U^2 X'_H(v', r')",
        "Y_H": "q U^2 Y'_H(v', r')",
        "N_H": "q L U^2 N'_H(v', r')",
        "X_P": "(1 - t_P) rho n^2 D^4 K_T(J)",
        "X_R": "-(1 - t_R) F_N sin(delta)",
        "Y_R": "-(1 + a_H) F_N cos(delta)",
        "N_R": "-(x_R + a_H x_H) F_N cos(d)",
    }
    first = None
    for k in ("X_H", "Y_H", "N_H", "X_P", "X_R", "Y_R", "N_R"):
        rel = bz[k] / sm[k]
        if first is None and abs(rel - 1.0) > 0.01:
            first = k
        print(f"{k:9s}  {eqs[k]:28s} {sm[k]:10.3f} {rf[k]:16.3f} {bz[k]:14.3f} {rel:16.4f} {bz[k] / rf[k]:12.4f}")
    print(
        f"shipmmg there: U {sm['U']:.4f} (midship {math.hypot(u, v):.4f}), beta {sm['beta']:.4f} rad, beta_P "
        f"{sm['beta_P']:.4f}, w_P {sm['w_P']:.4f}, J {sm['J']:.4f}, K_T {sm['K_T']:.4f}, u_R {sm['u_R']:.4f}, "
        f"v_R {sm['v_R']:.4f}, alpha_R {sm['alpha_R']:.4f} rad, F_N {sm['F_N']:.3f} N (its sub-values' Y_R with "
        f"1 - t_R: {sm['Y_R_sub']:.3f})"
    )
    # the accelerations of each right-hand side at that state and at a transient one (90 deg into (i)'s turn)
    f = shipmmg_rhs()
    tr = runs[("shipmmg", "stbd")]
    i90 = int(np.flatnonzero(tr["psi"] >= math.pi / 2)[0])
    print("accelerations (u' m/s^2, v' m/s^2, r' rad/s^2) of each right-hand side:")
    for where, (su, sv, sr) in (
        ("steady (the state above)", (u, v, r)),
        (f"90 deg into (i)'s turn, t {tr['t'][i90]:.2f} s", (tr["u"][i90], tr["v"][i90], tr["r"][i90])),
    ):
        acc_b = np.empty((1, 3))
        accelerations(
            np.array([[0.0, 0.0, 0.0, su, sv, sr]]),
            np.array([[-delta, nps]]),
            np.zeros((1, 2)),
            np.zeros(2),
            ship3.params(),
            acc_b,
        )
        rows = (
            ("shipmmg's own right-hand side", f(0.0, [su, sv, sr, 0.0, 0.0, 0.0, delta, nps])[:3]),
            (
                "reference with shipmmg's U, beta (x_G r)",
                ref_accelerations(su, sv, sr, delta, nps, forms=("xg_quirk",)),
            ),
            ("reference, MMG 2015 (midship v)", ref_accelerations(su, sv, sr, delta, nps)),
            (
                "reference, MMG 2015 + the kernel's forms",
                ref_accelerations(su, sv, sr, delta, nps, forms=tuple(k for k in FORMS if k != "xg_quirk")),
            ),
            ("bayesid kernel (iii)", acc_b[0]),
        )
        print(f"  at {where}: u {su:.4f}, v {sv:.4f}, r {sr:.5f}")
        for label, a in rows:
            print(f"    {label:42s} {a[0]: .6f} {a[1]: .6f} {a[2]: .6f}")

    print("\nhull terms there (N, N m): shipmmg (that term alone), MMG 2015 (midship U), bayesid kernel (iii)")
    print("term    force     shipmmg    MMG 2015     bayesid   bayesid/MMG")
    for name, key, a, b, c in hull_terms_table(ship3, u, v, r):
        ratio = c / b if b else float("nan")
        print(f"{name:6s}  {key:5s} {a:11.3f} {b:11.3f} {c:11.3f} {ratio:12.3f}")

    print("\nthe reference MMG 2015 model flown with one form at a time (same approach, rps and rudder)")
    print("model                                                    side tactical  steady  st/tac   u/U0     r'")
    cases = [
        ("ref_shipmmg", "reference + shipmmg's U, beta (= (i))", {"forms": ("xg_quirk",)}),
        ("ref_mmg", "reference, MMG 2015 equations", {}),
        *((f"ref_{k}", f"MMG 2015 + kernel form {k}", {"forms": (k,)}) for k in FORMS if k != "xg_quirk"),
        (
            "ref_kernel",
            "MMG 2015 + all four kernel forms (= (iii))",
            {"forms": tuple(k for k in FORMS if k != "xg_quirk")},
        ),
        (
            "ref_mmg_wake",
            "MMG 2015, x'P -0.48 + wake in a turn C1 C2",
            {"wake": (MMG2015_WAKE["C1"], MMG2015_WAKE["C2"], MMG2015_WAKE["C2m"]), "xP": MMG2015_WAKE["xP"]},
        ),
    ]
    res_ref = {}
    for key, label, kw in cases:
        for sign, side in ((1.0, "stbd"), (-1.0, "port")):
            ind = turn_indices(fly_reference(sign, nps, **kw))
            res_ref[key] = res_ref.get(key, 0.0) + ind["ratio"] / 2  # mean of the two sides
            print(
                f"{label:56s} {side:4s} {ind['tactical']:8.2f} {ind['steady']:7.2f} {ind['ratio']:7.3f}"
                f" {ind['u_U0']:6.3f} {ind['r_prime']:6.3f}"
            )
            last.append(f"ratio_{key}_{side} {ind['ratio']:.3f}")
    last.append(f"first_differing_component {first}")
    effect = {k: abs(res_ref[f"ref_{k}"] - res_ref["ref_mmg"]) for k in FORMS if k != "xg_quirk"}
    last.append(f"largest_kernel_form_effect {max(effect, key=effect.get)}")
    print("\n".join(last))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
