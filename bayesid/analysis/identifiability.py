"""Identifiability dossier: which coefficient combinations a track determines, and which it does not.

All quantities use *relative* coefficient changes, ``d theta_j / theta_j``, so that coefficients of
very different size are comparable: a sensitivity column is the change of the residual vector per
unit relative change (per 100 %) of one coefficient, and a direction such as
``0.71*Xvr - 0.70*Xrr`` means "raise Xvr by 0.71 % while lowering Xrr by 0.70 %".

Sources: Fisher information for output-error models (Ljung 1999, Sec. 9.2); sloppiness
(Gutenkunst et al. 2007, PLoS Comput. Biol. 3:e189); collinearity index and sensitivity measures
(Brun, Reichert & Kuensch 2001, Water Resour. Res. 37(4):1015-1030, Eqs. 4-7).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..data import terms


def relative_sensitivity(problem, theta) -> np.ndarray:
    """Sensitivity of the simulated channels to relative coefficient changes.

    ``S[:, j] = d y_sim / d ln(theta_j)`` from central differences in ONE batched simulation
    (2P + 1 tracks). Units: metres or radians per unit relative change.

    Parameters
    ----------
    problem : Problem
        The identification problem (:class:`~bayesid.estimation.objective.Problem`).
    theta : array_like, shape (P,)
        Prime coefficients (non-zero).

    Returns
    -------
    ndarray, shape (n_residuals, P)
        The sensitivities.
    """
    p = problem.scaled(theta)
    _, J = problem.jacobian(p, central=True)  # d r / d p, r = target - sim
    return -J * p[None, :]  # d sim / d ln theta = -(d r/d p) * p


def fisher_information(S: np.ndarray, sigma: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Fisher information of Gaussian output error, ``F = S^T diag(1/sigma^2) S``.

    Parameters
    ----------
    S : ndarray, shape (n, P)
        Sensitivities.
    sigma : ndarray, shape (n,)
        Standard deviations.
    mask : ndarray of bool, shape (n,), optional
        False for missing samples (excluded).

    Returns
    -------
    ndarray, shape (P, P)
        F.
    """
    w = 1.0 / sigma**2
    if mask is not None:
        w = np.where(mask, w, 0.0)
    return S.T @ (S * w[:, None])


@dataclass
class Direction:
    """One eigen-direction of the Fisher information (relative coordinates).

    Parameters
    ----------
    eigenvalue : float
        Its Fisher eigenvalue.
    vector : array_like, shape (P,)
        Unit length; its sign is fixed here so the largest component is positive.
    names : list of str
        The P coefficient names.
    """

    eigenvalue: float
    vector: np.ndarray  # (P,), unit length, sign fixed so the largest component is positive
    names: list

    def __post_init__(self):
        v = np.asarray(self.vector, dtype=float)
        self.vector = v * np.sign(v[np.argmax(np.abs(v))])

    @property
    def sd_relative(self) -> float:
        """Cramer-Rao standard deviation along the direction (relative units, 1 = 100 %)."""
        return float(1.0 / np.sqrt(self.eigenvalue)) if self.eigenvalue > 0 else float("inf")

    def weights(self, threshold: float = 0.1) -> dict:
        """The direction's large components.

        Parameters
        ----------
        threshold : float, default 0.1
            Smallest |weight| kept.

        Returns
        -------
        dict
            ``{name: weight}`` for components with |weight| >= threshold, largest first.
        """
        order = np.argsort(-np.abs(self.vector))
        return {self.names[i]: float(self.vector[i]) for i in order if abs(self.vector[i]) >= threshold}

    def label(self, threshold: float = 0.2, digits: int = 2) -> str:
        """The direction in words, e.g. ``"0.71*Xvr - 0.70*Xrr"``.

        Parameters
        ----------
        threshold : float, default 0.2
            Smallest |weight| written.
        digits : int, default 2
            Decimals of the weights.

        Returns
        -------
        str
            The label.
        """
        parts = []
        for n, w in self.weights(threshold).items():
            sign = "-" if w < 0 else ("+" if parts else "")
            parts.append(f"{sign} {abs(w):.{digits}f}*{n}".strip())
        return " ".join(parts)


def eigen_directions(F: np.ndarray, names) -> list[Direction]:
    """Eigen-decomposition of the Fisher information, sloppiest (smallest eigenvalue) first.

    Parameters
    ----------
    F : ndarray, shape (P, P)
        Fisher information (symmetrised here).
    names : sequence of str
        The P coefficient names.

    Returns
    -------
    list of Direction
        The P directions.
    """
    lam, V = np.linalg.eigh(0.5 * (F + F.T))
    out = []
    for k in range(lam.size):
        out.append(Direction(float(lam[k]), V[:, k], list(names)))
    return out


def subspace_participation(V: np.ndarray, names, threshold: float = 0.05) -> dict:
    """How much each coefficient takes part in a subspace: the diagonal of its orthogonal projector.

    Within a subspace whose eigenvalues are all at round-off level, the individual eigenvectors
    are not determined (any rotation of them is as good, and the last bits of a simulation pick
    one); the projector ``V V^T`` is. Its diagonal is 1 for a coefficient that lies wholly in the
    subspace, 0 for one orthogonal to it, and sums to the subspace's dimension.

    Parameters
    ----------
    V : ndarray, shape (P, K)
        Orthonormal columns spanning the subspace.
    names : sequence of str
        The P coefficient names.
    threshold : float, default 0.05
        Participations below this are left out.

    Returns
    -------
    dict
        ``{name: participation}``, largest first (empty when K is 0).
    """
    V = np.asarray(V, float)
    d = np.sum(V * V, axis=1) if V.size else np.zeros(len(names))
    order = np.argsort(-d, kind="stable")
    return {names[j]: float(d[j]) for j in order if d[j] >= threshold}


def condition_number(F: np.ndarray) -> float:
    """Ratio of the largest to the smallest eigenvalue of F.

    Parameters
    ----------
    F : ndarray, shape (P, P)
        A symmetric matrix (symmetrised here).

    Returns
    -------
    float
        The condition number (inf if singular).
    """
    lam = np.linalg.eigvalsh(0.5 * (F + F.T))
    return float(lam[-1] / lam[0]) if lam[0] > 0 else float("inf")


def collinearity_index(S: np.ndarray, subset) -> float:
    """Brun-Reichert-Kuensch collinearity index of a coefficient subset (Brun et al. 2001, Eq. 7).

    ``gamma_K = 1 / sqrt(min eig(S_K~^T S_K~))`` with the columns of S normalised to unit length.
    gamma = 1: orthogonal sensitivities; gamma -> inf: exactly linearly dependent. Brun et al. take
    gamma > 10-15 as practically non-identifiable.

    Parameters
    ----------
    S : ndarray, shape (n, P)
        Sensitivities.
    subset : iterable of int
        Column indices of the subset.

    Returns
    -------
    float
        gamma (inf for a zero column or a singular subset).
    """
    Sk = S[:, list(subset)]
    norms = np.linalg.norm(Sk, axis=0)
    if np.any(norms == 0):
        return float("inf")
    Sn = Sk / norms
    lam = np.linalg.eigvalsh(Sn.T @ Sn)[0]
    return float(1.0 / np.sqrt(lam)) if lam > 0 else float("inf")


def collinearity_table(S: np.ndarray, names, sizes=(2, 3), top: int = 10) -> list[dict]:
    """The most collinear subsets of each size.

    Parameters
    ----------
    S : ndarray, shape (n, P)
        Sensitivities.
    names : sequence of str
        The P coefficient names.
    sizes : sequence of int, default (2, 3)
        Subset sizes.
    top : int, default 10
        Subsets kept per size.

    Returns
    -------
    list of dict
        ``{subset, gamma}``, largest gamma first.
    """
    rows = []
    for k in sizes:
        for sub in itertools.combinations(range(S.shape[1]), k):
            rows.append(dict(subset=[names[i] for i in sub], gamma=collinearity_index(S, sub)))
    rows.sort(key=lambda r: -r["gamma"] if np.isfinite(r["gamma"]) else -np.inf)
    out, per = [], {k: 0 for k in sizes}
    for r in rows:
        k = len(r["subset"])
        if per[k] < top:
            out.append(r)
            per[k] += 1
    return out


def relative_influence(S: np.ndarray, sigma: np.ndarray | None = None) -> np.ndarray:
    """Brun's sensitivity measure ``delta_msqr_j = sqrt(mean_i (S_ij / sigma_i)^2)``: the RMS
    change of the (noise-scaled) track per unit relative change of coefficient j -- the paper's
    point (3), "some coefficients have a very small effect".

    Parameters
    ----------
    S : ndarray, shape (n, P)
        Sensitivities.
    sigma : ndarray, shape (n,), optional
        Noise sds (None: unscaled).

    Returns
    -------
    ndarray, shape (P,)
        The measure per coefficient.
    """
    Z = S if sigma is None else S / sigma[:, None]
    return np.sqrt(np.mean(Z**2, axis=0))


#: Rigid-body parts of each horizontal-plane equation row, keyed like terms: (factors, accel).
#: Mass-matrix entries (accel >= 0) and right-hand-side velocity products (accel = -1); a row
#: transformation moves them into the target row's free coefficients of the same key.
def _rigid_body_row(vehicle, row: str) -> dict:
    m, xg = vehicle.mass, vehicle.rG[0]
    if row == "X":  # (m - X'udot) u_dot = m (v r + xG r^2) + ...
        return {((), 0): m, (("v", "r"), -1): m, (("r", "r"), -1): m * xg}
    if row == "Y":  # (m - Y'vdot) v_dot + (m xG - Y'rdot) r_dot = -m u r + ...
        return {((), 1): m, ((), 5): m * xg, (("u", "r"), -1): -m}
    if row == "N":  # (m xG - N'vdot) v_dot + (Iz - N'rdot) r_dot = -m xG u r + ...
        return {((), 1): m * xg, ((), 5): vehicle.inertia[2, 2], (("u", "r"), -1): -m * xg}
    raise ValueError(f"row must be X, Y or N, not {row!r}")


def row_transform_direction(names, vehicle, target: str, source: str) -> np.ndarray | None:
    """Coefficient direction generated by adding a small multiple of equation row ``source`` to
    row ``target`` of the horizontal-plane model ``M nu_dot = tau`` (``source == target``:
    scaling that row).

    Multiplying an equation system by an invertible matrix leaves its solution unchanged, so if the
    transformed row can be written with the same terms -- every term and rigid-body part of the
    source row has a same-factor twin among the *free* coefficients of the target row -- moving
    along this direction changes no track at all: an exact (structural) null direction of any
    output-error fit, whatever the manoeuvre. Returns None when the free set cannot represent the
    transformation.

    Derivative of the target coefficients with respect to the mixing factor, prime units:
    ``d C'_twin = C'_source_term * L**(k_source - k_twin)`` for hydrodynamic terms, and
    ``-/+ value / (0.5 rho L**k_twin)`` for mass-matrix / right-hand-side rigid-body parts.

    Parameters
    ----------
    names : sequence of str
        The P free coefficients.
    vehicle : Vehicle
        The vehicle (its coefficients, mass and inertia).
    target, source : {"X", "Y", "N"}
        The equation rows.

    Returns
    -------
    ndarray, shape (P,) or None
        The direction (relative units, unit length), or None.
    """
    names = list(names)
    theta = vehicle.coefficients
    d = dict.fromkeys(names, 0.0)
    twins = {(t.factors, t.accel): t for t in terms.TERMS if t.group == target and t.horizontal}
    half = 0.5 * vehicle.rho
    for t in terms.TERMS:
        if t.group != source or not t.horizontal or theta.get(t.name, 0.0) == 0.0:
            continue
        twin = twins.get((t.factors, t.accel))
        if twin is None or twin.name not in d:
            return None
        d[twin.name] += theta[t.name] * vehicle.L ** (t.L_power - twin.L_power)
    for key, val in _rigid_body_row(vehicle, source).items():
        if val == 0.0:
            continue
        twin = twins.get(key)
        if twin is None or twin.name not in d:
            return None
        sign = -1.0 if twin.kind == "added_mass" else 1.0  # M = M_RB - 0.5 rho L^k C'
        d[twin.name] += sign * val / (half * vehicle.L**twin.L_power)
    v = np.array([d[n] / theta[n] for n in names])
    nrm = np.linalg.norm(v)
    return v / nrm if nrm > 0 else None


def structural_null_space(names, vehicle) -> tuple[np.ndarray, list[str]]:
    """The exact null directions that row transformations of the horizontal-plane equations
    generate for this free set, and their causes in words.

    Raises nothing.

    Parameters
    ----------
    names : sequence of str
        The P free coefficients.
    vehicle : Vehicle
        The vehicle.

    Returns
    -------
    basis : ndarray, shape (P, k)
        Orthonormal basis of the null directions (a (P, 0) array when no transformation is
        representable).
    causes : list of str
        The cause of each representable transformation, in words.
    """
    vecs, causes = [], []
    for tgt in ("X", "Y", "N"):
        for src in ("X", "Y", "N"):
            v = row_transform_direction(names, vehicle, tgt, src)
            if v is not None:
                vecs.append(v)
                causes.append(
                    f"scale the {tgt} equation" if tgt == src else f"add the {src} equation to the {tgt} equation"
                )
    if not vecs:
        return np.zeros((len(names), 0)), []
    Q, R = np.linalg.qr(np.array(vecs).T)
    keep = np.abs(np.diag(R)) > 1e-8
    return Q[:, keep], causes


def principal_angles_deg(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Principal angles between the column spaces of A and B (orthonormalised here).

    Parameters
    ----------
    A : ndarray, shape (P, a)
        First set of columns.
    B : ndarray, shape (P, b)
        Second set of columns.

    Returns
    -------
    ndarray, shape (min(a, b),)
        The angles, deg (empty when either has no column).
    """
    if A.shape[1] == 0 or B.shape[1] == 0:
        return np.zeros(0)
    Qa, _ = np.linalg.qr(A)
    Qb, _ = np.linalg.qr(B)
    s = np.clip(np.linalg.svd(Qa.T @ Qb, compute_uv=False), -1.0, 1.0)
    return np.degrees(np.arccos(s))


__all__ = [
    "relative_sensitivity",
    "fisher_information",
    "Direction",
    "eigen_directions",
    "condition_number",
    "collinearity_index",
    "collinearity_table",
    "relative_influence",
    "row_transform_direction",
    "structural_null_space",
    "principal_angles_deg",
]
