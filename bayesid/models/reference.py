"""Slow, obviously-correct reference implementation of the 6-DOF submarine equations.

Same model as the compiled kernel (:mod:`bayesid.models.dynamics`), written independently and in a
different form so that agreement between the two means something:

* features in vectorised numpy (:func:`reference_features`), hydrodynamic forces through the term
  library's regressor matrix (:func:`bayesid.data.terms.regressors`);
* hydrostatics as the weight and buoyancy vectors rotated into the body frame and their moments
  ``r_G x f_G + r_B x f_B`` (Fossen 1994, Sec. 2.5 / Eq. 2.162), not the expanded scalar list;
* the rigid-body Coriolis/centripetal force in Fossen's matrix form ``C_RB(nu) nu`` built from
  ``M_RB`` (Fossen 1994, Eq. 2.102; Fossen 2011, Thm. 3.2), not the hand-expanded terms of
  equations.md "Rigid body";
* kinematics as matrix products ``R(Theta) nu_1`` and ``T(Theta) nu_2`` with ``R`` composed from the
  three elementary rotations (Fossen 1994, Eq. 2.18 and 2.28);
* ``M nu_dot = tau`` solved with :func:`numpy.linalg.solve` at every call (no stored inverse);
* time integration by :func:`scipy.integrate.solve_ivp` (DOP853, tight tolerances), piecewise over
  the maximal intervals of constant input so the adaptive solver never steps across a
  zero-order-hold discontinuity.

It is meant for tests and for the benchmark ratio, not for production use: a 600 s track takes
seconds to tens of seconds. Readability wins over speed everywhere in this module.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from ..data import terms
from .crossflow import crossflow_forces
from .simulate import MODES, Manoeuvre, SimResult

#: |u| floor (m/s) inside eta = u_c/u (eps(eta) is undefined at u = 0), and floor of the speed
#: U in the feature 1/U; same value as the kernel.
U_FLOOR = 1e-3
#: Indices of surge, sway and yaw in nu (and of u, v, r in the mass matrix).
PLANE = [0, 1, 5]
#: State indices that the horizontal-plane model keeps at zero (phi, theta, w, p, q).
_HORIZONTAL_ZERO = {3: "phi", 4: "theta", 8: "w", 9: "p", 10: "q"}

# Status codes of SimResult (the same meaning as bayesid.models.dynamics.OK/NONFINITE/OUT_OF_BOUNDS).
_OK, _NONFINITE, _OUT_OF_BOUNDS = 0, 1, 2


# --------------------------------------------------------------------------------------------
# Small matrix helpers (Fossen 1994, Ch. 2)
# --------------------------------------------------------------------------------------------


def skew(a) -> np.ndarray:
    """Skew-symmetric matrix S(a) with ``S(a) b = a x b`` (Fossen 1994, Eq. 2.9).

    Parameters
    ----------
    a : array_like, shape (3,)
        The vector.

    Returns
    -------
    ndarray, shape (3, 3)
        S(a).
    """
    a1, a2, a3 = a
    return np.array([[0.0, -a3, a2], [a3, 0.0, -a1], [-a2, a1, 0.0]])


def rotation_matrix(phi: float, theta: float, psi: float) -> np.ndarray:
    """Body-to-earth rotation R(Theta) for zyx Euler angles:
    ``R = R_z(psi) R_y(theta) R_x(phi)`` (Fossen 1994, Eq. 2.18).

    Parameters
    ----------
    phi, theta, psi : float
        Roll, pitch and yaw angles, rad.

    Returns
    -------
    ndarray, shape (3, 3)
        R(Theta).
    """
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cf, -sf], [0.0, sf, cf]])
    Ry = np.array([[ct, 0.0, st], [0.0, 1.0, 0.0], [-st, 0.0, ct]])
    Rz = np.array([[cp, -sp, 0.0], [sp, cp, 0.0], [0.0, 0.0, 1.0]])
    return Rz @ Ry @ Rx


def euler_rate_matrix(phi: float, theta: float) -> np.ndarray:
    """T(Theta) with ``(phi, theta, psi)_dot = T (p, q, r)`` (Fossen 1994, Eq. 2.28).
    Singular at theta = +-90 deg.

    Parameters
    ----------
    phi, theta : float
        Roll and pitch angles, rad.

    Returns
    -------
    ndarray, shape (3, 3)
        T(Theta).
    """
    cf, sf = math.cos(phi), math.sin(phi)
    ct, tt = math.cos(theta), math.tan(theta)
    return np.array([[1.0, sf * tt, cf * tt], [0.0, cf, -sf], [0.0, sf / ct, cf / ct]])


def coriolis_rigid_body(M_RB: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Rigid-body Coriolis/centripetal matrix C_RB(nu), SI.

    ``C_RB = [[0, -S(M11 nu1 + M12 nu2)], [-S(M11 nu1 + M12 nu2), -S(M21 nu1 + M22 nu2)]]``
    (Fossen 1994, Eq. 2.102; Fossen 2011, Theorem 3.2). Skew-symmetric for symmetric M_RB.

    Parameters
    ----------
    M_RB : ndarray, shape (6, 6)
        The rigid-body mass matrix about the body origin.
    nu : ndarray, shape (6,)
        ``(u, v, w, p, q, r)``, m/s and rad/s.

    Returns
    -------
    ndarray, shape (6, 6)
        C_RB(nu).
    """
    nu1, nu2 = nu[:3], nu[3:]
    a = M_RB[:3, :3] @ nu1 + M_RB[:3, 3:] @ nu2
    b = M_RB[3:, :3] @ nu1 + M_RB[3:, 3:] @ nu2
    C = np.zeros((6, 6))
    C[:3, 3:] = -skew(a)
    C[3:, :3] = -skew(a)
    C[3:, 3:] = -skew(b)
    return C


# --------------------------------------------------------------------------------------------
# Features of the term library
# --------------------------------------------------------------------------------------------


def propulsion_eps(u: np.ndarray, n_rpm: np.ndarray, vehicle) -> np.ndarray:
    """Propulsion function eps(eta), Healey & Lienard (1993) as in equations.md "Propulsion".

    ``eta = u_c/u`` with ``u_c = uc_per_omega * n * 2 pi / 60`` and ``u`` floored to
    ``|u| >= U_FLOOR`` (sign kept, u = 0 counts as positive);
    ``eps = -1 + sign(n)/sign(u) * (sqrt(|C_T| + 1) - 1)/(sqrt(C_T1 + 1) - 1)``,
    ``C_T = CT_coeff L^2 eta|eta|/2``, ``C_T1 = CT_coeff L^2/2``. The ``|C_T|`` keeps the root real
    under reverse thrust (the sign ratio carries the direction); n = 0 counts as positive.

    Parameters
    ----------
    u : array_like, shape (n,)
        Surge speed, m/s.
    n_rpm : array_like, shape (n,)
        Propeller speed, rpm.
    vehicle : Vehicle
        The vehicle (propulsion constants and L).

    Returns
    -------
    ndarray, shape (n,)
        eps(eta).
    """
    u = np.asarray(u, dtype=float)
    n_rad = np.asarray(n_rpm, dtype=float) * (2.0 * np.pi / 60.0)
    sign_u = np.where(u >= 0.0, 1.0, -1.0)
    sign_n = np.where(n_rad >= 0.0, 1.0, -1.0)
    u_guarded = np.where(np.abs(u) > U_FLOOR, u, sign_u * U_FLOOR)
    eta = vehicle.propulsion.uc_per_omega * n_rad / u_guarded
    k = vehicle.propulsion.CT_coeff * vehicle.L**2 / 2.0
    CT, CT1 = k * eta * np.abs(eta), k
    return -1.0 + (sign_n / sign_u) * (np.sqrt(np.abs(CT) + 1.0) - 1.0) / (np.sqrt(CT1 + 1.0) - 1.0)


def reference_features(states: np.ndarray, inputs: np.ndarray, vehicle) -> np.ndarray:
    """Term-library features in the order of ``terms.FEATURES``.

    ``prop = u_c|u_c| - u|u|`` (m^2/s^2) with ``u_c = uc_per_omega * n * 2 pi/60``;
    ``eps`` from :func:`propulsion_eps`; ``1/U`` (s/m) the inverse of the speed through the water
    ``U = |(u, v, w)|``, floored at ``U_FLOOR`` (the prime form of a term of three velocity
    factors, :func:`bayesid.data.terms.parse`).

    Parameters
    ----------
    states : array_like, shape (n, 12)
        ``x, y, z, phi, theta, psi, u, v, w, p, q, r`` (m, rad, m/s, rad/s).
    inputs : array_like, shape (n, 4)
        ``delta_r, delta_s, delta_b`` (rad), ``n`` (rpm).
    vehicle : Vehicle
        The :class:`~bayesid.data.vehicle.Vehicle` (propulsion constants and L).

    Returns
    -------
    ndarray, shape (n, N_FEATURES)
        The features.
    """
    states = np.atleast_2d(np.asarray(states, dtype=float))
    inputs = np.atleast_2d(np.asarray(inputs, dtype=float))
    u, v, w, p, q, r = (states[:, 6 + i] for i in range(6))
    dr, ds, db, n_rpm = (inputs[:, j] for j in range(4))
    uc = vehicle.propulsion.uc_per_omega * n_rpm * (2.0 * np.pi / 60.0)
    columns = {
        "1": np.ones_like(u),
        "u": u,
        "v": v,
        "w": w,
        "p": p,
        "q": q,
        "r": r,
        "dr": dr,
        "ds": ds,
        "db": db,
        "eps": propulsion_eps(u, n_rpm, vehicle),
        "|v|": np.abs(v),
        "|r|": np.abs(r),
        "prop": uc * np.abs(uc) - u * np.abs(u),
        "|w|": np.abs(w),
        "|q|": np.abs(q),
        "|p|": np.abs(p),
        "1/U": 1.0 / np.maximum(np.linalg.norm(states[:, 6:9], axis=1), U_FLOOR),
    }
    return np.column_stack([columns[name] for name in terms.FEATURES])


# --------------------------------------------------------------------------------------------
# The model: forces, accelerations, state derivative
# --------------------------------------------------------------------------------------------


class ReferenceModel:
    """The equations of motion of one vehicle with one coefficient set, in plain numpy.

    Parameters
    ----------
    vehicle : Vehicle
        The :class:`~bayesid.data.vehicle.Vehicle`.
    coefficients : dict, optional
        ``{name: prime value}`` overriding some of the vehicle's coefficients.
    mode : {"6dof", "horizontal"}, default "6dof"
        Horizontal: only the terms that act in the horizontal plane (``Term.horizontal``, as the
        compiled simulator) and only the (u, v, r) rows of ``M nu_dot = tau``; w, p, q
        accelerations are zero. Overriding a coefficient that does not act in the horizontal
        plane therefore has no effect in that mode.

    Raises
    ------
    UnknownCoefficientError
        A name in ``coefficients`` not in the term library.
    ValueError
        A bad mode or a non-finite coefficient.
    """

    def __init__(self, vehicle, coefficients: dict | None = None, mode: str = "6dof"):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        coefficients = {} if coefficients is None else dict(coefficients)
        terms.check_names(coefficients, "reference coefficients")
        for name, value in coefficients.items():
            if not math.isfinite(float(value)):
                raise ValueError(f"coefficient {name} = {value} is not finite")
        self.vehicle, self.mode = vehicle, mode
        self.coefficients = {**vehicle.coefficients, **{k: float(v) for k, v in coefficients.items()}}
        self.force_names = [t.name for t in terms.TERMS if t.kind == "force" and (mode == "6dof" or t.horizontal)]
        self.force_dofs = np.array([terms.term(n).dof for n in self.force_names])
        self.force_values = np.array([self.coefficients.get(n, 0.0) for n in self.force_names])
        self.M_RB = vehicle.mass_matrix({})  # rigid body only (6, 6)
        self.M = vehicle.mass_matrix(self.coefficients)  # rigid body + added mass (6, 6)

    # -- right-hand side pieces, each (n, 6) in X, Y, Z, K, M, N order -------------------------

    def hydrodynamic_force(self, states: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """Force of the term library: ``Phi(states, inputs) @ C'`` per dof.

        Parameters
        ----------
        states : ndarray, shape (n, 12)
            States (SI).
        inputs : ndarray, shape (n, 4)
            Inputs (rad, rpm).

        Returns
        -------
        ndarray, shape (n, 6)
            X, Y, Z, K, M, N (N, N m).
        """
        veh = self.vehicle
        Phi = terms.regressors(reference_features(states, inputs, veh), self.force_names, veh.rho, veh.L)
        tau = np.zeros((Phi.shape[0], 6))
        for dof in range(6):
            sel = self.force_dofs == dof
            tau[:, dof] = Phi[:, sel] @ self.force_values[sel]
        return tau

    def hydrostatic_force(self, states: np.ndarray) -> np.ndarray:
        """Weight and buoyancy in body axes: ``f_G = R^T (0, 0, W)``, ``f_B = -R^T (0, 0, B)``,
        moments ``r_G x f_G + r_B x f_B`` (Fossen 1994, Eq. 2.162 with the sign of a
        right-hand-side force; equals equations.md "Hydrostatics").

        Parameters
        ----------
        states : ndarray, shape (n, 12)
            States (SI).

        Returns
        -------
        ndarray, shape (n, 6)
            X, Y, Z, K, M, N (N, N m).
        """
        veh = self.vehicle
        out = np.zeros((states.shape[0], 6))
        for i, s in enumerate(states):
            R = rotation_matrix(s[3], s[4], s[5])
            f_G = R.T @ np.array([0.0, 0.0, veh.weight])
            f_B = -R.T @ np.array([0.0, 0.0, veh.buoyancy])
            out[i, :3] = f_G + f_B
            out[i, 3:] = np.cross(veh.rG, f_G) + np.cross(veh.rB, f_B)
        return out

    def crossflow_force(self, states: np.ndarray) -> np.ndarray:
        """Strip-sum cross-flow drag when ``vehicle.crossflow_model == "integral"``, else 0
        (:func:`bayesid.models.crossflow.crossflow_forces`).

        Parameters
        ----------
        states : ndarray, shape (n, 12)
            States (SI).

        Returns
        -------
        ndarray, shape (n, 6)
            X, Y, Z, K, M, N (N, N m).
        """
        if self.vehicle.crossflow_model == "integral":
            return crossflow_forces(states, self.vehicle)
        return np.zeros((states.shape[0], 6))

    def coriolis_force(self, states: np.ndarray) -> np.ndarray:
        """Rigid-body Coriolis/centripetal force ``C_RB(nu) nu`` (left-hand side sign).

        Parameters
        ----------
        states : ndarray, shape (n, 12)
            States (SI).

        Returns
        -------
        ndarray, shape (n, 6)
            The force, N and N m.
        """
        return np.array([coriolis_rigid_body(self.M_RB, s[6:]) @ s[6:] for s in states])

    def generalized_force(self, states, inputs) -> np.ndarray:
        """``tau = tau_hydro + tau_hydrostatic + tau_crossflow - C_RB(nu) nu``: the right-hand
        side of ``M nu_dot = tau``. All six rows are returned in both modes (in the horizontal
        mode only horizontal-plane terms enter ``tau_hydro``).

        Parameters
        ----------
        states : array_like, shape (n, 12) or (12,)
            States (SI).
        inputs : array_like, shape (n, 4) or (4,)
            Inputs (rad, rpm).

        Returns
        -------
        ndarray, shape (n, 6)
            tau, SI.
        """
        states = np.atleast_2d(np.asarray(states, dtype=float))
        inputs = np.atleast_2d(np.asarray(inputs, dtype=float))
        return (
            self.hydrodynamic_force(states, inputs)
            + self.hydrostatic_force(states)
            + self.crossflow_force(states)
            - self.coriolis_force(states)
        )

    def acceleration(self, states, inputs) -> np.ndarray:
        """``nu_dot`` from ``M nu_dot = tau`` (6-DOF) or from its (u, v, r) block with
        ``w_dot = p_dot = q_dot = 0`` (horizontal). Singular M gives NaN.

        Parameters
        ----------
        states : array_like, shape (n, 12) or (12,)
            States (SI).
        inputs : array_like, shape (n, 4) or (4,)
            Inputs (rad, rpm).

        Returns
        -------
        ndarray, shape (n, 6)
            The accelerations, m/s^2 and rad/s^2.
        """
        tau = self.generalized_force(states, inputs)
        nu_dot = np.zeros_like(tau)
        for i, t in enumerate(tau):
            try:
                if self.mode == "horizontal":
                    nu_dot[i, PLANE] = np.linalg.solve(self.M[np.ix_(PLANE, PLANE)], t[PLANE])
                else:
                    nu_dot[i] = np.linalg.solve(self.M, t)
            except np.linalg.LinAlgError:
                nu_dot[i] = np.nan
        return nu_dot

    def rhs(self, states, inputs) -> np.ndarray:
        """State derivative: ``(x, y, z)_dot = R(Theta) (u, v, w)``,
        ``(phi, theta, psi)_dot = T(Theta) (p, q, r)`` (Fossen 1994, Eq. 2.18/2.28) and ``nu_dot``
        from :meth:`acceleration`.

        Parameters
        ----------
        states : array_like, shape (n, 12) or (12,)
            States (SI).
        inputs : array_like, shape (n, 4) or (4,)
            Inputs (rad, rpm).

        Returns
        -------
        ndarray, shape (n, 12)
            d states / dt.
        """
        states = np.atleast_2d(np.asarray(states, dtype=float))
        out = np.empty_like(states)
        for i, s in enumerate(states):
            out[i, 0:3] = rotation_matrix(s[3], s[4], s[5]) @ s[6:9]
            out[i, 3:6] = euler_rate_matrix(s[3], s[4]) @ s[9:12]
        out[:, 6:] = self.acceleration(states, inputs)
        return out


# --------------------------------------------------------------------------------------------
# Integration
# --------------------------------------------------------------------------------------------


def _bounds(vehicle) -> tuple[float, float, float]:
    """Physical bounds beyond which a track counts as diverged (the kernel's rule, see
    :func:`bayesid.models.dynamics.vehicle_params`): speed (m/s), rate (rad/s), |theta| (rad)."""
    vmax = max(20.0 * vehicle.nominal_speed, 10.0)
    return vmax, vmax / (vehicle.L / 4.0), math.radians(85.0)


def simulate_reference(
    vehicle,
    manoeuvre: Manoeuvre,
    mode: str = "6dof",
    coefficients: dict | None = None,
    sample_every: int = 1,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    method: str = "DOP853",
) -> SimResult:
    """Simulate one track with ``solve_ivp`` (DOP853): the anchor for the compiled simulator.

    The inputs are a zero-order hold on the manoeuvre grid (input k over [k dt, (k+1) dt)). The
    integration runs piecewise over maximal intervals of constant input and reports the state at
    the sample times ``k * sample_every * dt``.

    Parameters
    ----------
    vehicle : Vehicle
        The :class:`~bayesid.data.vehicle.Vehicle`.
    manoeuvre : Manoeuvre
        The :class:`~bayesid.models.simulate.Manoeuvre`.
    mode : {"6dof", "horizontal"}, default "6dof"
        See :class:`ReferenceModel`.
    coefficients : dict, optional
        ``{name: prime value}`` overriding some vehicle coefficients.
    sample_every : int, default 1
        Store every k-th grid point; must divide ``manoeuvre.n_steps``.
    rtol, atol : float, default 1e-10
        solve_ivp tolerances (state units: m, rad, m/s, rad/s).
    method : str, default "DOP853"
        solve_ivp method (``"DOP853"``, the anchor; ``"RK45"`` at rtol 1e-8 is the fair speed
        reference of ``benchmarks/simulate.py``).

    Returns
    -------
    SimResult
        B = 1: ``states`` (1, n_samples, 12). ``status`` is 0, or 1 if solve_ivp failed or the
        state went non-finite, or 2 if the state left the physical bounds (the kernel's:
        |u|,|v|,|w|, |p|,|q|,|r|, |theta| > 85 deg); ``fail_step`` is the grid step during which
        the bound was crossed (status 2) or the last grid step reached (status 1), else -1; the
        samples after it are NaN.

    Raises
    ------
    UnknownCoefficientError
        A name in ``coefficients`` not in the term library.
    ValueError
        Bad mode or ``sample_every``; horizontal mode with non-zero w, p, q, phi or theta in the
        initial state.
    """
    model = ReferenceModel(vehicle, coefficients, mode)
    s0 = np.asarray(manoeuvre.initial_state, dtype=float).copy()
    if mode == "horizontal":
        bad = [name for i, name in _HORIZONTAL_ZERO.items() if s0[i] != 0.0]
        if bad:
            raise ValueError(f"horizontal mode needs {', '.join(bad)} = 0 initially")
    se = int(sample_every)
    n_steps, dt = manoeuvre.n_steps, manoeuvre.dt
    if se < 1 or n_steps % se:
        raise ValueError(f"sample_every={sample_every} must divide n_steps={n_steps}")
    inputs = manoeuvre.inputs
    sample_steps = np.arange(0, n_steps + 1, se)  # grid index of each sample
    states = np.full((1, sample_steps.size, 12), np.nan)
    states[0, 0] = s0
    status, fail_step = _OK, -1

    # Segment boundaries: grid indices where the input row changes.
    changes = np.flatnonzero(np.any(inputs[1:] != inputs[:-1], axis=1)) + 1
    starts = np.concatenate([[0], changes])
    ends = np.concatenate([changes, [n_steps]])

    vmax, wmax, thmax = _bounds(vehicle)

    def out_of_bounds(t, s):  # > 0 inside the bounds; terminal event when it crosses zero
        return min(vmax - np.max(np.abs(s[6:9])), wmax - np.max(np.abs(s[9:12])), thmax - abs(s[4]))

    out_of_bounds.terminal = True
    out_of_bounds.direction = -1

    s = s0
    for a, b in zip(starts, ends):
        uin = inputs[a]

        def f(t, y, uin=uin):
            return model.rhs(y, uin)[0]

        in_segment = (sample_steps > a) & (sample_steps <= b)
        eval_steps = np.union1d(sample_steps[in_segment], [b])  # always end at the segment end
        sol = solve_ivp(
            f, (a * dt, b * dt), s, method=method, t_eval=eval_steps * dt, rtol=rtol, atol=atol, events=out_of_bounds
        )
        n_ok = sol.y.shape[1]
        finite = np.all(np.isfinite(sol.y), axis=0)
        if not finite.all():
            n_ok = int(np.argmin(finite))
        for k, y in zip(eval_steps[:n_ok], sol.y.T[:n_ok]):
            if k % se == 0:
                states[0, k // se] = y
        if sol.status == 1:  # left the physical bounds
            status = _OUT_OF_BOUNDS
            fail_step = int(math.ceil(sol.t_events[0][0] / dt - 1e-9)) - 1
        elif sol.status == -1 or n_ok < eval_steps.size:
            status = _NONFINITE
            last_good = eval_steps[n_ok - 1] if n_ok > 0 else a
            fail_step = int(last_good)
        if status != _OK:
            states[0, sample_steps > fail_step] = np.nan
            break
        s = sol.y[:, -1]

    inputs_sampled = np.vstack([inputs, inputs[-1:]])[::se]
    return SimResult(
        sample_steps * dt,
        states,
        inputs_sampled,
        np.array([status], dtype=np.int64),
        np.array([fail_step], dtype=np.int64),
        name=manoeuvre.name,
    )


__all__ = [
    "U_FLOOR",
    "skew",
    "rotation_matrix",
    "euler_rate_matrix",
    "coriolis_rigid_body",
    "propulsion_eps",
    "reference_features",
    "ReferenceModel",
    "simulate_reference",
]
