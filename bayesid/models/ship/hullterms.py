"""Extra hull terms of a ship file: MMG polynomial terms in prime form, named as SNAME names.

The listed hull coefficients (:data:`~bayesid.models.ship.layout.COEFFICIENTS`: ``Xvv``, ``Yv``,
``Yvvr``, ``Nvrr``, ...) each have their slot in the kernels' parameter vector. Any other product
of the motion and rudder features up to third order is an **extra hull term**: a ship file may
give it in ``[coefficients]`` (``Yvvv = -0.15``, ``N0 = 0.0004``, ``Nabsdr = ...``), a fit may free
it, and structure discovery (:mod:`bayesid.analysis.discovery`) proposes such terms by these
names, so a discovered term can be pasted into a ship file.

Prime form (Yasukawa & Yoshimura 2015, J. Mar. Sci. Technol. 20:37-52, Sec. 2.2, eqs. 6-8:
``Y_H = 0.5 rho L d U^2 Y'_H(v', r')``)::

    X, Y = 0.5 rho L d U^2 C' f'_1 ... f'_k,     N = 0.5 rho L^2 d U^2 C' f'_1 ... f'_k

with ``U = sqrt(u^2 + v^2)`` and the prime features ``v' = v / U``, ``r' = r L / U``, ``|v'|``,
``|r'|``, the rudder angle ``dr`` (rad, + to port as the track logs it; MMG's delta is the
opposite sign) and ``|dr|``. Written in velocities, ``U^2 v'^a r'^b = U^(2-a-b) v^a (rL)^b``, so
the terms with at most two velocity factors are finite at every speed; a cubic one
(``Yvvv = Y'vvv``, MMG's ``v'^3 U^2 = v^3 / U``) is set to 0 below ``U = 1e-9`` m/s.

Name grammar: the force letter ``X``, ``Y`` or ``N``, then either ``0`` (a constant force or
moment in prime form, ``Y0``: ``0.5 rho L d U^2 Y0``) or one to three factors from ``v r absv absr
dr absdr`` (longest token first): ``Yvvv``, ``Nvrr``, ``Ndr``, ``Nabsdr`` (``|dr|``), ``Ndrabsdr``
(``dr |dr|``), ``Yabsvdr``; a surge term of velocity factors alone may have four
(``Xvvvv``, ``Xvvrr``: :data:`MAX_SURGE_ORDER`). A product that a listed coefficient already has (``Yrvv`` is
``Yvvr``) is refused with the listed name; the listed names keep their own forms (see
:mod:`bayesid.models.ship`).

In the kernels' parameter vector each extra term takes :data:`TERM_WIDTH` numbers after the
listed coefficients: its degree of freedom, the six factor exponents (order of
:data:`FACTORS`) and its coefficient (:func:`encode`).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

import numpy as np

from .layout import COEFFICIENTS, NP

#: The features an extra hull term multiplies, in the encoded exponent order.
FACTORS = ("v", "r", "|v|", "|r|", "dr", "|dr|")
#: Name tokens of the features, longest first.
_TOKENS = (("absdr", "|dr|"), ("absv", "|v|"), ("absr", "|r|"), ("dr", "dr"), ("v", "v"), ("r", "r"))
_VELOCITY = {"v", "r", "|v|", "|r|"}
_DOFS = ("X", "Y", "N")
#: Numbers per extra term in the kernels' parameter vector: dof, six exponents, coefficient.
TERM_WIDTH = 8
#: Highest order of an extra term (number of factors).
MAX_ORDER = 3
#: Highest order of a surge term of velocity factors alone: the MMG hull surge force is a
#: polynomial in ``v', r'`` to fourth order (``X'vvvv`` of Yasukawa & Yoshimura 2015, Sec. 2.2,
#: Table 4; ``X'vvrr``, ``X'rrrr``, ... the other products of that order), written
#: ``U^2 v'^a r'^b = v^a (rL)^b / U^2`` for ``a + b = 4`` and set to 0 below ``U = 1e-9`` m/s.
MAX_SURGE_ORDER = 4

# Products of the listed hull coefficients (their own slots and forms).
_LISTED_PRODUCTS = {
    ("X", ("v", "v")): "Xvv",
    ("X", ("r", "v")): "Xvr",
    ("X", ("r", "r")): "Xrr",
    ("Y", ("v",)): "Yv",
    ("Y", ("r",)): "Yr",
    ("N", ("v",)): "Nv",
    ("N", ("r",)): "Nr",
    ("Y", ("r", "v", "v")): "Yvvr",
    ("Y", ("r", "r", "v")): "Yvrr",
    ("N", ("r", "v", "v")): "Nvvr",
    ("N", ("r", "r", "v")): "Nvrr",
}


class HullTermError(KeyError):
    """A coefficient name that is neither a listed ship coefficient nor an extra hull term."""

    def __str__(self) -> str:  # KeyError quotes its argument
        return str(self.args[0])


@dataclass(frozen=True)
class HullTerm:
    """One extra hull term.

    Parameters
    ----------
    name : str
        Its name, e.g. ``"Nvvv"``.
    dof : int
        0 (X), 1 (Y) or 2 (N).
    factors : tuple of str
        The features it multiplies (:data:`FACTORS`), in name order; empty for a constant.
    """

    name: str
    dof: int
    factors: tuple[str, ...]

    @property
    def exponents(self) -> tuple[int, ...]:
        """Power of each feature of :data:`FACTORS`."""
        return tuple(self.factors.count(f) for f in FACTORS)

    @property
    def n_velocity(self) -> int:
        """Number of velocity factors (``v r |v| |r|``): the power of ``1/U`` of the prime form."""
        return sum(f in _VELOCITY for f in self.factors)

    @property
    def force(self) -> str:
        """``"X"``, ``"Y"`` or ``"N"``."""
        return _DOFS[self.dof]


def _unknown(name: str, reason: str) -> HullTermError:
    close = difflib.get_close_matches(str(name), COEFFICIENTS, n=3)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    return HullTermError(f"unknown ship coefficient {name!r}: {reason}{hint}")


def parse(name: str) -> HullTerm:
    """The extra hull term a name stands for (the grammar is in the module docstring).

    Parameters
    ----------
    name : str
        The name, e.g. ``"Yvvv"``, ``"N0"``, ``"Nabsdr"``.

    Returns
    -------
    HullTerm
        The term.

    Raises
    ------
    HullTermError
        A listed coefficient's name (it is not an extra term), a name the grammar cannot read, a
        product of more than :data:`MAX_ORDER` factors (:data:`MAX_SURGE_ORDER` for a surge term of
        velocity factors), or another spelling of a listed product;
        the message says which and suggests the closest listed names.
    """
    if not isinstance(name, str) or not name or name[0] not in _DOFS:
        raise _unknown(name, "an extra hull term starts with X, Y or N")
    if name in COEFFICIENTS:
        raise HullTermError(f"{name!r} is a listed ship coefficient, not an extra hull term")
    body = name[1:]
    if body == "0":
        return HullTerm(name, _DOFS.index(name[0]), ())
    factors, i = [], 0
    while i < len(body):
        for tok, feat in _TOKENS:
            if body.startswith(tok, i):
                break
        else:
            raise _unknown(name, f"cannot read {body[i:]!r} (after X, Y or N: 0, or factors v r absv absr dr absdr)")
        factors.append(feat)
        i += len(tok)
    if not factors:
        raise _unknown(name, "no factor after the force letter")
    most = MAX_SURGE_ORDER if name[0] == "X" and set(factors) <= _VELOCITY else MAX_ORDER
    if len(factors) > most:
        raise _unknown(
            name,
            f"{len(factors)} factors; an extra hull term has at most {MAX_ORDER} "
            f"(a surge term of v, r, absv, absr alone {MAX_SURGE_ORDER})",
        )
    listed = _LISTED_PRODUCTS.get((name[0], tuple(sorted(factors))))
    if listed is not None:
        raise HullTermError(f"ship coefficient {name!r} is the product listed as {listed!r}: use that name")
    return HullTerm(name, _DOFS.index(name[0]), tuple(factors))


def is_term(name: str) -> bool:
    """Whether a name reads as an extra hull term.

    Parameters
    ----------
    name : str
        The name.

    Returns
    -------
    bool
        True when :func:`parse` accepts it.
    """
    try:
        parse(name)
    except HullTermError:
        return False
    return True


def check_name(name: str) -> None:
    """Refuse a name that is neither a listed ship coefficient nor an extra hull term.

    Parameters
    ----------
    name : str
        The name.

    Raises
    ------
    HullTermError
        As :func:`parse`, for a name that is not listed.
    """
    if name not in COEFFICIENTS:
        parse(name)


def extra_terms(coefficients: dict) -> tuple[HullTerm, ...]:
    """The extra hull terms among a ship's coefficients, in the dict's order.

    Parameters
    ----------
    coefficients : dict
        ``{name: prime value}``.

    Returns
    -------
    tuple of HullTerm
        The terms of the names that are not listed coefficients.

    Raises
    ------
    HullTermError
        A name that is neither (see :func:`parse`).
    """
    return tuple(parse(k) for k in coefficients if k not in COEFFICIENTS)


def encode(terms, coefficients: dict) -> np.ndarray:
    """The parameter-vector tail of extra hull terms.

    Parameters
    ----------
    terms : sequence of HullTerm
        The terms.
    coefficients : dict
        ``{name: prime value}`` containing every term's name.

    Returns
    -------
    ndarray, shape (TERM_WIDTH * len(terms),)
        Per term: dof, the exponents of :data:`FACTORS`, the coefficient.
    """
    out = np.empty(TERM_WIDTH * len(terms))
    for k, t in enumerate(terms):
        out[TERM_WIDTH * k : TERM_WIDTH * (k + 1)] = [t.dof, *t.exponents, float(coefficients[t.name])]
    return out


def index(terms) -> dict:
    """Position of each extra term's coefficient in the kernels' parameter vector.

    Parameters
    ----------
    terms : sequence of HullTerm
        The terms, in encoded order.

    Returns
    -------
    dict
        ``{name: index}``.
    """
    return {t.name: NP + TERM_WIDTH * k + TERM_WIDTH - 1 for k, t in enumerate(terms)}


def signature(terms) -> tuple:
    """A hashable key of a term set's structure (the model's kernel cache key; the generated kernel
    reads the terms from the parameter rows, so every non-empty set shares one compile).

    Parameters
    ----------
    terms : sequence of HullTerm
        The terms.

    Returns
    -------
    tuple
        ``((dof, exponents), ...)``.
    """
    return tuple((t.dof, t.exponents) for t in terms)


def columns(terms, u, v, r, dr, L: float, rho: float, d: float) -> np.ndarray:
    """Forces of the terms at unit coefficient, at given states (the regression columns of
    structure discovery and the reference of the kernels' evaluation).

    Parameters
    ----------
    terms : sequence of HullTerm
        The terms.
    u, v : ndarray, shape (n,)
        Surge and sway velocity through the water, m/s.
    r : ndarray, shape (n,)
        Yaw rate, rad/s.
    dr : ndarray, shape (n,)
        Rudder angle, rad (+ to port).
    L : float
        Length, m.
    rho : float
        Water density, kg/m^3.
    d : float
        Draught, m.

    Returns
    -------
    ndarray, shape (n, len(terms))
        Each term's force (N, for X and Y) or moment (N m, for N) per unit prime coefficient.
    """
    u, v, r, dr = (np.asarray(a, float) for a in (u, v, r, dr))
    U = np.hypot(u, v)
    q = 0.5 * rho * L * d
    feats = {"v": v, "r": r * L, "|v|": np.abs(v), "|r|": np.abs(r) * L, "dr": dr, "|dr|": np.abs(dr)}
    out = np.empty((u.size, len(terms)))
    for k, t in enumerate(terms):
        col = np.ones(u.size)
        for f in t.factors:
            col = col * feats[f]
        nu = 2 - t.n_velocity
        with np.errstate(divide="ignore", invalid="ignore"):
            col = col * (U**nu if nu >= 0 else np.where(U > 1e-9, 1.0 / np.maximum(U, 1e-300) ** -nu, 0.0))
        out[:, k] = q * (L if t.dof == 2 else 1.0) * col
    return out


__all__ = [
    "FACTORS",
    "TERM_WIDTH",
    "MAX_ORDER",
    "MAX_SURGE_ORDER",
    "HullTerm",
    "HullTermError",
    "parse",
    "is_term",
    "check_name",
    "extra_terms",
    "encode",
    "index",
    "signature",
    "columns",
]
