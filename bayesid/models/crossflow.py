"""Cross-flow drag: the strip-sum integral and its polynomial (Gertler & Hagen) equivalent.

NPS AUV II models nonlinear sway/yaw (and heave/pitch) damping by a cross-flow drag integral
(Feldman 1979, as implemented in MSS ``npsauv.m``; equations.md "Crossflow drag as implemented").
The paper's model uses polynomial terms instead. :func:`fit_polynomial_equivalent` derives those
coefficients by least squares against the integral over the (v, r) samples that a set of
manoeuvres actually visits, so the two variants agree where the vehicle goes.
"""

from __future__ import annotations

import numpy as np

from ..data import terms
from .dynamics import features_array

#: Basis per force/moment: (term name, state index a, state index b) -> regressor a*|b| style.
HORIZONTAL_BASIS = {"Y": ("Yvabsv", "Yvabsr", "Yrabsr"), "N": ("Nvabsv", "Nabsvr", "Nrabsr")}
VERTICAL_BASIS = {"Z": ("Zwabsw", "Zwabsq", "Zqabsq"), "M": ("Mwabsw", "Mabswq", "Mqabsq")}


def crossflow_forces(states: np.ndarray, vehicle) -> np.ndarray:
    """Strip-sum cross-flow force and moment, (n, 6) in X, Y, Z, K, M, N order (X = K = 0), SI.

    ``Y = -(rho/2) sum_i w_i g_i (v + x_i r)/U_i``, ``N = -(rho/2) sum_i w_i g_i (v + x_i r) x_i/U_i``,
    ``Z = -(rho/2) sum_i w_i g_i (w - x_i q)/U_i``, ``M = +(rho/2) sum_i w_i g_i (w - x_i q) x_i/U_i``
    with ``g_i = Cdy h (v + x_i r)**2 + Cdz b (w - x_i q)**2`` and ``U_i = |(v + x_i r, w - x_i q)|``
    (equations.md "Crossflow drag as implemented").

    Parameters
    ----------
    states : ndarray, shape (n, 12)
        States in the simulator's state order (SI).
    vehicle : Vehicle
        The vehicle, with ``[crossflow]`` data.

    Returns
    -------
    ndarray, shape (n, 6)
        Force and moment, X, Y, Z, K, M, N (N, N m).

    Raises
    ------
    ValueError
        If the vehicle has no ``[crossflow]`` data.
    """
    cf = vehicle.crossflow
    if cf is None:
        raise ValueError(f"vehicle {vehicle.id} has no [crossflow] section")
    v, w, q, r = (states[:, i][:, None] for i in (7, 8, 10, 11))
    x = cf.stations[None, :]
    vl, wl = v + x * r, w - x * q
    U = np.hypot(vl, wl)
    g = cf.Cdy * cf.height_m * vl**2 + cf.Cdz * cf.breadth_m * wl**2
    k = np.divide(0.5 * vehicle.rho * g * cf.weights[None, :], U, out=np.zeros_like(U), where=U > 1e-12)
    out = np.zeros((states.shape[0], 6))
    out[:, 1] = -(k * vl).sum(axis=1)
    out[:, 5] = -(k * vl * x).sum(axis=1)
    out[:, 2] = -(k * wl).sum(axis=1)
    out[:, 4] = (k * wl * x).sum(axis=1)
    return out


def fit_polynomial_equivalent(vehicle, manoeuvres, mode: str = "horizontal") -> dict:
    """Least-squares polynomial equivalent of the cross-flow integral over an envelope.

    The envelope is the set of (v, r) samples visited when the vehicle, with the integral
    variant, flies ``manoeuvres``. Y and N are fitted on those samples with the bases
    ``v|v|, v|r|, r|r|`` and ``v|v|, |v|r, r|r|`` (prime scaling from the term library). Z and M
    are fitted on the same samples mapped to the vertical plane (w = v, q = -r), which makes the
    local cross-flow velocity ``w - x q`` equal to ``v + x r``: no vertical manoeuvre is needed
    for a body whose strip sum is the same in both planes up to Cdz b / Cdy h.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle, with ``[crossflow]`` data.
    manoeuvres : sequence of Manoeuvre
        The manoeuvres that define the envelope (:func:`envelope_manoeuvres`).
    mode : {"horizontal", "6dof"}, default "horizontal"
        Degrees of freedom of the simulations.

    Returns
    -------
    dict
        ``coefficients`` (``{name: prime value}``), ``relative_rms_residual`` (per force:
        RMS(poly - integral) / RMS(integral)), ``envelope`` (``max_abs_v_mps``,
        ``max_abs_r_rad_s``, ``n_samples`` and the ``manoeuvres``' names).

    Raises
    ------
    RuntimeError
        If a manoeuvre diverges with the integral cross-flow.
    """
    from .simulate import simulate

    vi = vehicle.with_crossflow("integral")
    samples = []
    for m in manoeuvres:
        res = simulate(vi, m, mode=mode)
        if res.diverged[0]:
            raise RuntimeError(f"manoeuvre {m.name} diverged with the integral cross-flow")
        samples.append(res.states[0])
    S = np.vstack(samples)
    Sv = S.copy()
    Sv[:, 8], Sv[:, 10] = S[:, 7], -S[:, 11]  # mirrored into the vertical plane
    Sv[:, 7], Sv[:, 11] = 0.0, 0.0
    F_h = crossflow_forces(S, vi)
    F_v = crossflow_forces(Sv, vi)
    coeffs, resid = {}, {}
    for basis, Ssel, F in ((HORIZONTAL_BASIS, S, F_h), (VERTICAL_BASIS, Sv, F_v)):
        feats = features_array(Ssel, np.zeros((Ssel.shape[0], 4)), vi)
        for dof, names in basis.items():
            Phi = terms.regressors(feats, names, vi.rho, vi.L)
            y = F[:, terms.DOFS.index(dof)]
            sol, *_ = np.linalg.lstsq(Phi, y, rcond=None)
            coeffs.update({n: float(c) for n, c in zip(names, sol)})
            resid[dof] = float(np.sqrt(np.mean((Phi @ sol - y) ** 2)) / np.sqrt(np.mean(y**2)))
    env = dict(
        max_abs_v_mps=float(np.abs(S[:, 7]).max()),
        max_abs_r_rad_s=float(np.abs(S[:, 11]).max()),
        n_samples=int(S.shape[0]),
        manoeuvres=[m.name for m in manoeuvres],
    )
    return dict(coefficients=coeffs, relative_rms_residual=resid, envelope=env)


def envelope_manoeuvres(vehicle, dt: float = 0.1) -> list:
    """The manoeuvres whose envelope defines the packaged polynomial equivalent: the spiral,
    turning circles at +-10 and +-20 deg, zigzags 10/10 and 20/20 (both first-rudder signs).

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle, with ``[crossflow]`` data.
    dt : float, default 0.1
        Step of the manoeuvres, s.

    Returns
    -------
    list of Manoeuvre
        The manoeuvres, for the vehicle with the integral cross-flow.
    """
    from . import manoeuvres as mv

    vi = vehicle.with_crossflow("integral")
    out = [mv.spiral(vi, dt=dt)]
    out += [mv.turning_circle(vi, a, dt=dt) for a in (10.0, -10.0, 20.0, -20.0)]
    out += [mv.zigzag(vi, a, dt=dt, first_sign=s) for a in (10.0, 20.0) for s in (1, -1)]
    return out


if __name__ == "__main__":  # python -m bayesid.models.crossflow: print the TOML lines for the vehicle file
    from ..data.vehicle import load_vehicle

    veh = load_vehicle("nps_auv2")
    fit = fit_polynomial_equivalent(veh, envelope_manoeuvres(veh))
    print(f"# envelope: {fit['envelope']}")
    print(f"# relative RMS residual: {fit['relative_rms_residual']}")
    for k, val in fit["coefficients"].items():
        print(f"{k} = {val:.6e}")
