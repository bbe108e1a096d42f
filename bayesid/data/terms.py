"""The one term library: every hydrodynamic coefficient as a named term.

A force term contributes ``0.5*rho*L**k * C' * (product of factors)`` to one degree of freedom
(X, Y, Z, K, M or N); an acceleration term (``Xudot``, ``Yvdot``, ...) contributes the same way
through an acceleration and is moved into the constant mass matrix. Everything that needs to know
about coefficients derives from this table: the simulator's force evaluation, the regressor matrix,
sensitivities, the X/Y/N grouping for plots and the towing-tank (static) versus rotary/added-mass
split of the paper's Case 2.

Conventions (Gertler & Hagen 1967; Feldman 1979; the prime system of ``shared/research/equations.md``):

* Names are SNAME: the force letter, then the motion variables of the product (``Yv`` multiplies
  u*v with the implicit u, ``Ydr`` multiplies u**2*delta_r, ``Yvabsv`` multiplies v*|v|,
  ``Nabsvr`` multiplies |v|*r, ``_eps`` terms also multiply the propulsion function eps(eta)).
* The prime form makes every force term quadratic in speed. A term of three velocity factors is
  divided by the speed through the water ``U = sqrt(u**2 + v**2 + w**2)`` (the feature ``1/U``):
  ``Nvvr`` multiplies v*v*r/U, ``Yvvv`` v**3/U, ``Nvabsvr`` v*|v|*r/U (Gertler & Hagen 1967;
  Feldman 1979; Fossen 2011, Handbook of Marine Craft Hydrodynamics, cubic cross-flow terms).
* The power of L is not typed in: it follows from the factors (prime rule). A force term has
  ``k = 2 + (number of rate factors p, q, r)``, a moment term one more (``1/U`` is no rate:
  ``Nvvr`` has k = 4, ``Yrrr`` k = 5); an acceleration term has
  ``k = 3`` for a linear and ``k = 4`` for an angular acceleration, a moment one more.
* Any product of the features below is a term, not only the names listed in :data:`LISTED`:
  ``Nvabsr`` (N from v|r|), ``Yrabsv`` (Y from r|v|), ``Yq`` (Y from u*q) are read from their
  names by :func:`parse` (the grammar is in its docstring) and added to the table the first time
  they are named (by a vehicle file, a free list, a prior, ...). A product the table already
  lists under another spelling (``Yabsvv`` for ``Yvabsv``) is refused with the listed name, so a
  listed force cannot enter twice under two names.
* ``db`` terms are per bow plane; a single ``delta_b`` input drives both planes together, so
  these terms carry a multiplicity of 2 (documented choice, equations.md "Pitfalls met").
* ``Cd0`` is the Healey & Lienard propulsion-minus-resistance coefficient,
  ``X = 0.5*rho*L**2 * Cd0 * (u_c|u_c| - u|u|)``, i.e. ``u**2 * X'prop(eta)`` with
  ``X'prop = Cd0*(eta|eta| - 1)`` for u > 0, extended to u <= 0 as drag opposing the motion.
"""

from __future__ import annotations

import difflib
import re
import threading
from dataclasses import dataclass

import numpy as np

DOFS = ("X", "Y", "Z", "K", "M", "N")
#: Body velocity names in state order (state vector indices 6..11).
VELOCITIES = ("u", "v", "w", "p", "q", "r")

# Feature vector evaluated once per right-hand-side call; a term is a product of features.
# The order is shared with the compiled kernel (bayesid.models.dynamics); change both together.
# "1/U" is 1/max(U, U_MIN_EPS) with U = sqrt(u^2 + v^2 + w^2), the speed through the water: the
# prime form of a term of three velocity factors (see parse()).
FEATURES = ("1", "u", "v", "w", "p", "q", "r", "dr", "ds", "db", "eps", "|v|", "|r|", "prop", "|w|", "|q|", "|p|")
FEATURES += ("1/U",)  # appended: the indices above are those of the kernels
F_INDEX = {name: i for i, name in enumerate(FEATURES)}
N_FEATURES = len(FEATURES)
MAX_FACTORS = 5
#: Most velocity factors of a force term; the third one brings the factor 1/U (see parse()).
MAX_VELOCITY_FACTORS = 3

_RATES = {"p", "q", "r", "|p|", "|r|", "|q|"}
_LINEAR = {"u", "v", "w", "|v|", "|w|"}
# Factors of the horizontal-plane model (w = p = q = 0, no stern or bow planes, no eps(eta)).
_PLANE_FACTORS = {"u", "v", "r", "dr", "|v|", "|r|", "prop", "1/U"}

TERM_KINDS = ("force", "added_mass")
CATEGORIES = ("static", "rotary", "added_mass")


@dataclass(frozen=True)
class Term:
    """One hydrodynamic coefficient.

    Parameters
    ----------
    name : str
        SNAME name, e.g. ``"Yvabsv"``.
    dof : int
        Index into ``DOFS`` of the force/moment it acts in.
    factors : tuple of str
        Feature names (:data:`FEATURES`) whose product the coefficient multiplies (force terms);
        empty for acceleration terms.
    accel : int, default -1
        Index into ``VELOCITIES`` of the acceleration (added-mass terms), else -1.
    multiplicity : int, default 1
        2 for per-bow-plane terms driven by one ``delta_b`` input, else 1.
    """

    name: str
    dof: int
    factors: tuple[str, ...]
    accel: int = -1
    multiplicity: int = 1

    @property
    def kind(self) -> str:
        """``"added_mass"`` (an acceleration term) or ``"force"`` (:data:`TERM_KINDS`)."""
        return "added_mass" if self.accel >= 0 else "force"

    @property
    def group(self) -> str:
        """Force/moment letter: ``"X"``, ``"Y"``, ... (the paper's Figs. 3-5 grouping)."""
        return DOFS[self.dof]

    @property
    def L_power(self) -> int:
        """Power k of L in the prime factor 0.5*rho*L**k (Gertler & Hagen prime rule)."""
        moment = 1 if self.dof >= 3 else 0
        if self.accel >= 0:
            return (3 if self.accel < 3 else 4) + moment
        if self.factors == ("prop",):
            return 2 + moment
        return 2 + sum(f in _RATES for f in self.factors) + moment

    @property
    def category(self) -> str:
        """``"static"`` (towing tank without a planar motion mechanism: u, v, w, control angles,
        propulsion), ``"rotary"`` (needs p, q, r: rotating arm/PMM) or ``"added_mass"``."""
        if self.accel >= 0:
            return "added_mass"
        return "rotary" if any(f in _RATES for f in self.factors) else "static"

    @property
    def horizontal(self) -> bool:
        """True if the term acts in the horizontal-plane model (surge, sway, yaw with
        w = p = q = 0 and no stern or bow plane deflection)."""
        if self.group not in ("X", "Y", "N"):
            return False
        if self.accel >= 0:
            return VELOCITIES[self.accel] in ("u", "v", "r")
        return all(f in _PLANE_FACTORS for f in self.factors)


def _T(name: str, factors: str, mult: int = 1, dof: str | None = None) -> Term:
    """Build a force term from its name and a space-separated factor list; the degree of
    freedom is the name's first letter unless given."""
    fs = tuple(factors.split())
    if "1" in fs:  # index 0 is the kernel's padding marker
        raise ValueError(f"term {name}: '1' is not a factor")
    for f in fs:
        if f not in F_INDEX:
            raise ValueError(f"term {name}: unknown factor {f!r}")
    if len(fs) > MAX_FACTORS:
        raise ValueError(f"term {name}: more than {MAX_FACTORS} factors")
    return Term(name, DOFS.index(dof or name[0]), fs, -1, mult)


def _A(name: str) -> Term:
    """Build an acceleration (added-mass) term, e.g. ``Yrdot`` (Y due to r-dot)."""
    return Term(name, DOFS.index(name[0]), (), VELOCITIES.index(name[1]), 1)


# The table. Feldman/Healey form as implemented for NPS AUV II (equations.md, [V] terms), plus
# the Gertler-Hagen polynomial cross-flow terms that stand in for the cross-flow integral.
# New products are appended after these by term() (see parse()).
TERMS: tuple[Term, ...] = (
    # ---- X (surge) ----
    _T("Xpp", "p p"),
    _T("Xqq", "q q"),
    _T("Xrr", "r r"),
    _T("Xpr", "p r"),
    _A("Xudot"),
    _T("Xwq", "w q"),
    _T("Xvp", "v p"),
    _T("Xvr", "v r"),
    _T("Xqds", "u q ds"),
    _T("Xqdb", "u q db", 2),
    _T("Xrdr", "u r dr"),
    _T("Xvv", "v v"),
    _T("Xww", "w w"),
    _T("Xvdr", "u v dr"),
    _T("Xwds", "u w ds"),
    _T("Xwdb", "u w db", 2),
    _T("Xdsds", "u u ds ds"),
    _T("Xdbdb", "u u db db"),  # multiplicity 1: from the 2018 MSS file, where it is for the pair
    _T("Xdrdr", "u u dr dr"),
    _T("Xqds_eps", "u q ds eps"),
    _T("Xwds_eps", "u w ds eps"),
    _T("Xdsds_eps", "u u ds ds eps"),
    _T("Cd0", "prop", dof="X"),
    # ---- Y (sway) ----
    _A("Ypdot"),
    _A("Yrdot"),
    _T("Ypq", "p q"),
    _T("Yqr", "q r"),
    _A("Yvdot"),
    _T("Yp", "u p"),
    _T("Yr", "u r"),
    _T("Yvq", "v q"),
    _T("Ywp", "w p"),
    _T("Ywr", "w r"),
    _T("Yv", "u v"),
    _T("Yvw", "v w"),
    _T("Ydr", "u u dr"),
    _T("Yvabsv", "v |v|"),
    _T("Yvabsr", "v |r|"),
    _T("Yrabsr", "r |r|"),
    # ---- Z (heave) ----
    _A("Zqdot"),
    _T("Zpp", "p p"),
    _T("Zpr", "p r"),
    _T("Zrr", "r r"),
    _A("Zwdot"),
    _T("Zq", "u q"),
    _T("Zvp", "v p"),
    _T("Zvr", "v r"),
    _T("Zw", "u w"),
    _T("Zvv", "v v"),
    _T("Zds", "u u ds"),
    _T("Zdb", "u u db", 2),
    _T("Zq_eps", "u q eps"),
    _T("Zw_eps", "u w eps"),
    _T("Zds_eps", "u u ds eps"),
    _T("Zwabsw", "w |w|"),
    _T("Zwabsq", "w |q|"),
    _T("Zqabsq", "q |q|"),
    # ---- K (roll) ----
    _A("Kpdot"),
    _A("Krdot"),
    _T("Kpq", "p q"),
    _T("Kqr", "q r"),
    _A("Kvdot"),
    _T("Kp", "u p"),
    _T("Kr", "u r"),
    _T("Kvq", "v q"),
    _T("Kwp", "w p"),
    _T("Kwr", "w r"),
    _T("Kv", "u v"),
    _T("Kvw", "v w"),
    _T("Kdb", "u u db", 2),
    _T("Kp_eps", "u p eps"),
    _T("Kprop", "u u"),
    # ---- M (pitch) ----
    _A("Mqdot"),
    _T("Mpp", "p p"),
    _T("Mpr", "p r"),
    _T("Mrr", "r r"),
    _A("Mwdot"),
    _T("Mq", "u q"),
    _T("Mvp", "v p"),
    _T("Mvr", "v r"),
    _T("Mw", "u w"),
    _T("Mvv", "v v"),
    _T("Mds", "u u ds"),
    _T("Mdb", "u u db", 2),
    _T("Mq_eps", "u q eps"),
    _T("Mw_eps", "u w eps"),
    _T("Mds_eps", "u u ds eps"),
    _T("Mwabsw", "w |w|"),
    _T("Mabswq", "|w| q"),
    _T("Mqabsq", "q |q|"),
    # ---- N (yaw) ----
    _A("Npdot"),
    _A("Nrdot"),
    _T("Npq", "p q"),
    _T("Nqr", "q r"),
    _A("Nvdot"),
    _T("Np", "u p"),
    _T("Nr", "u r"),
    _T("Nvq", "v q"),
    _T("Nwp", "w p"),
    _T("Nwr", "w r"),
    _T("Nv", "u v"),
    _T("Nvw", "v w"),
    _T("Ndr", "u u dr"),
    _T("Nprop", "u u"),
    _T("Nvabsv", "v |v|"),
    _T("Nabsvr", "|v| r"),
    _T("Nrabsr", "r |r|"),
)

#: The names written out in the table above, in table order. :data:`NAMES` is these followed by the
#: products added since (:func:`term`); both keep their order, so an index never changes.
LISTED: tuple[str, ...] = tuple(t.name for t in TERMS)
NAMES: tuple[str, ...] = LISTED
INDEX: dict[str, int] = {n: i for i, n in enumerate(NAMES)}

#: The polynomial terms that replace the cross-flow drag integral (Gertler & Hagen form).
CROSSFLOW_POLYNOMIAL = (
    "Yvabsv",
    "Yvabsr",
    "Yrabsr",
    "Nvabsv",
    "Nabsvr",
    "Nrabsr",
    "Zwabsw",
    "Zwabsq",
    "Zqabsq",
    "Mwabsw",
    "Mabswq",
    "Mqabsq",
)


class UnknownCoefficientError(KeyError):
    """A coefficient name that is not in the term library."""

    def __str__(self) -> str:  # KeyError quotes its argument; we want a readable message
        return str(self.args[0])


# Name grammar of parse(). Tokens of a product name after the force letter, longest first.
_TOKENS = (
    ("absu", "|u|"),
    ("absv", "|v|"),
    ("absw", "|w|"),
    ("absp", "|p|"),
    ("absq", "|q|"),
    ("absr", "|r|"),
    ("dr", "dr"),
    ("ds", "ds"),
    ("db", "db"),
    ("u", "u"),
    ("v", "v"),
    ("w", "w"),
    ("p", "p"),
    ("q", "q"),
    ("r", "r"),
)
_VELOCITY_FACTORS = {"u", "v", "w", "p", "q", "r", "|u|", "|v|", "|w|", "|p|", "|q|", "|r|"}
#: The name body of a constant force or moment, the same at every speed (``Nconst``; see :func:`parse`).
CONSTANT = "const"
_ACCEL_NAME = re.compile(r"([XYZKMN])([uvwpqr])dot")
_LOCK = threading.Lock()


def _product_key(t: Term) -> tuple:
    return t.dof, t.accel, tuple(sorted(t.factors))


def _unknown(name: str, reason: str) -> UnknownCoefficientError:
    close = difflib.get_close_matches(name, NAMES, n=3)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    return UnknownCoefficientError(f"unknown coefficient {name!r}: {reason}{hint}")


def _read(name: str) -> Term:
    """The term of a name by the grammar of :func:`parse` alone (no table look-up)."""
    if not isinstance(name, str) or not name or name[0] not in "XYZKMN":
        raise _unknown(str(name), "a name starts with the force letter X, Y, Z, K, M or N")
    if _ACCEL_NAME.fullmatch(name):
        return _A(name)
    body, eps = name[1:], False
    if body == CONSTANT:  # no factor, not even the implicit u's: a force the same at every speed
        return Term(name, DOFS.index(name[0]), (), -1, 1)
    if body.endswith("_eps"):
        body, eps = body[:-4], True
    factors, i = [], 0
    while i < len(body):
        for tok, feat in _TOKENS:
            if body.startswith(tok, i):
                break
        else:
            raise _unknown(
                name,
                f"cannot read {body[i:]!r} (factors are u v w p q r, absv absr absw absq absp, "
                "dr ds db, then optionally _eps)",
            )
        if feat not in F_INDEX:
            raise _unknown(name, f"{feat} is not a feature of the term library ({', '.join(FEATURES[1:])})")
        factors.append(feat)
        i += len(tok)
    if not factors:
        raise _unknown(name, "no factor after the force letter")
    n_vel = sum(f in _VELOCITY_FACTORS for f in factors)
    if n_vel > MAX_VELOCITY_FACTORS:
        raise _unknown(
            name,
            f"{n_vel} velocity factors; a prime-form term has at most {MAX_VELOCITY_FACTORS} "
            "(the third divided by the speed U; a fourth would need 1/U**2, which no feature gives)",
        )
    inv_speed = ["1/U"] * max(n_vel - 2, 0)  # prime form: quadratic in speed
    factors = ["u"] * max(2 - n_vel, 0) + factors + inv_speed + (["eps"] if eps else [])
    if len(factors) > MAX_FACTORS:
        counted = " (1/U of the third velocity factor counts as one)" if inv_speed else ""
        raise _unknown(name, f"{len(factors)} factors ({' '.join(factors)}); at most {MAX_FACTORS}{counted}")
    return Term(name, DOFS.index(name[0]), tuple(factors), -1, 2 if "db" in factors else 1)


def parse(name: str) -> Term:
    """The term an SNAME name stands for, read from the name (not added to the table).

    Grammar (Gertler & Hagen 1967; Feldman 1979), as the listed names are written:

    * an acceleration term is the force letter, one velocity and ``dot``: ``Yrdot`` (Y from
      r-dot), ``Xwdot``;
    * a force term is the force letter (``X Y Z K M N``), then the factors in order -- ``u v w p q
      r``, ``absv`` for ``|v|`` (likewise ``absr``, ``absw``, ``absq``, ``absp``), ``dr ds db`` for the
      rudder, stern-plane and bow-plane angles -- and optionally ``_eps`` for the propulsion
      function eps(eta);
    * the prime form makes every force term quadratic in the velocities (a rate counts as one
      velocity over L; the rudder, stern-plane and bow-plane angles are no velocities): the
      missing velocity factors are ``u``, put first. ``Yv`` is u*v, ``Ydr`` u*u*dr, ``Nvabsr``
      v*|r|, ``Xqds_eps`` u*q*ds*eps;
    * a term of three velocity factors is divided by the speed through the water
      ``U = sqrt(u**2 + v**2 + w**2)`` (the feature ``1/U``, put after the named factors and
      before ``eps``; Gertler & Hagen 1967, Feldman 1979, Fossen 2011 cubic cross-flow terms):
      ``Nvvr`` is v*v*r/U (``N = 0.5 rho L**4 N'vvr v**2 r / U``), ``Yrrr`` r*r*r/U, ``Nvabsvr``
      v*|v|*r/U, ``Yvvvdr`` v*v*v*dr/U. The guard ``U >= U_MIN_EPS`` (1e-3 m/s, as for eps(eta))
      keeps the feature finite at rest. Four or more velocity factors are refused (they would need
      1/U**2), and so is a third-order name whose factors with ``1/U`` exceed :data:`MAX_FACTORS`
      (``Nvvrdrdr``: v v r dr dr 1/U);
    * the power of L follows from the factors (:attr:`Term.L_power`); a term with ``db`` has
      multiplicity 2 (one coefficient per bow plane, one ``delta_b`` input), except the listed
      ``Xdbdb``;
    * ``Cd0``, ``Kprop`` and ``Nprop`` are listed names outside this grammar;
    * the force letter and ``const`` (``Nconst``, ``Yconst``) is a force or moment that is the same
      at every speed (a product of no factor, not even the implicit ``u``): dimensionally
      ``0.5 rho L**k * C'`` times (1 m/s)**2, with k as for any force term (2 for a force, 3 for
      a moment). Its value is the prime coefficient of the u^2 form (``Nprop``, ``Nuu``) that
      gives the same force at u = 1 m/s; the two differ where the speed changes.

    A listed name returns its listed term. Two spellings of a product that is not listed
    (``Nvabsr``, ``Nabsrv``) are two terms: give a vehicle one of them.

    Parameters
    ----------
    name : str
        SNAME name of the coefficient, e.g. ``"Nvabsr"``.

    Returns
    -------
    Term
        The listed term of a listed name, else the term read from the name.

    Raises
    ------
    UnknownCoefficientError
        The name is not a product of the features (:data:`FEATURES`; ``|u|`` is not a
        feature), has more than :data:`MAX_FACTORS` factors (``1/U`` included) or more than
        :data:`MAX_VELOCITY_FACTORS` velocity factors, or is another spelling of a listed product
        (``Yabsvv`` for ``Yvabsv``); the message says which, and suggests the closest names of the
        table.
    """
    i = INDEX.get(name)
    if i is not None and i < len(LISTED):
        return TERMS[i]
    t = _read(name)
    key = _product_key(t)
    for listed in TERMS[: len(LISTED)]:
        if _product_key(listed) == key:
            what = f"the {VELOCITIES[t.accel]}-dot term" if t.accel >= 0 else "the product " + "*".join(t.factors)
            raise UnknownCoefficientError(
                f"coefficient {name!r} is {what} in {t.group}, listed as {listed.name!r}: use that name"
            )
    return t


def listed_name(name: str) -> str | None:
    """The listed name of the product a grammar name stands for (``Nuu`` -> ``Nprop``), or None
    when the product is not listed.

    Parameters
    ----------
    name : str
        A name of the grammar of :func:`parse`.

    Returns
    -------
    str or None
        The listed name.

    Raises
    ------
    UnknownCoefficientError
        When the grammar cannot read ``name``.
    """
    key = _product_key(_read(name))
    return next((t.name for t in TERMS[: len(LISTED)] if _product_key(t) == key), None)


def term(name: str) -> Term:
    """Look up a term by SNAME name; a product not in the table yet is read from its name
    (:func:`parse`) and added at the end of the table (:data:`TERMS`, :data:`NAMES`,
    :data:`INDEX`), where it stays for the rest of the process. Another process (a worker that
    receives a pickled vehicle) starts from the listed table: :func:`check_names` of the
    vehicle's coefficient names adds its products there.

    Parameters
    ----------
    name : str
        SNAME name of the coefficient.

    Returns
    -------
    Term
        The term of the table under ``name``.

    Raises
    ------
    UnknownCoefficientError
        if ``name`` is neither in the table nor a product of the features; the message says why
        and suggests close matches.
    """
    global TERMS, NAMES
    i = INDEX.get(name)
    if i is not None:
        return TERMS[i]
    t = parse(name)
    with _LOCK:
        if name not in INDEX:
            # TERMS and NAMES first: a reader that finds the index also finds the term
            TERMS = TERMS + (t,)
            NAMES = NAMES + (name,)
            INDEX[name] = len(TERMS) - 1
        return TERMS[INDEX[name]]


def check_names(names, where: str = "") -> None:
    """Raise :class:`UnknownCoefficientError` naming the first name that is neither in the table
    nor a product of the features; the products are added to the table (:func:`term`).

    Parameters
    ----------
    names : iterable of str
        Coefficient names to check.
    where : str, default ""
        Where the names come from (e.g. a file); appended to the message as ``" in <where>"``.

    Raises
    ------
    UnknownCoefficientError
        For the first name that is neither in the table nor a product of the features.
    """
    for n in names:
        if n not in INDEX:
            try:
                term(n)
            except UnknownCoefficientError as e:
                raise UnknownCoefficientError(f"{e}{' in ' + where if where else ''}") from None


def prime_scale(names, rho: float, L: float) -> np.ndarray:
    """Dimensional factor of each term: ``multiplicity * 0.5 * rho * L**k``.

    Parameters
    ----------
    names : sequence of str
        The P term names.
    rho : float
        Water density, kg/m^3.
    L : float
        Reference length, m.

    Returns
    -------
    ndarray, shape (P,)
        The dimensional factor of each term.
    """
    return np.array([TERMS[INDEX[n]].multiplicity * 0.5 * rho * L ** TERMS[INDEX[n]].L_power for n in names])


def factor_table(names) -> tuple[np.ndarray, np.ndarray]:
    """Compiled-kernel encoding of force terms.

    Parameters
    ----------
    names : sequence of str
        The P force-term names; a product not in the table yet is added (:func:`term`).

    Returns
    -------
    factors : ndarray of int64, shape (P, MAX_FACTORS)
        Feature indices padded at the end with 0, the index of ``"1"`` (never a real factor;
        the kernel stops at the first 0).
    dof : ndarray of int64, shape (P,)
        Index into ``DOFS`` of each term's force or moment.

    Raises
    ------
    ValueError
        If a name is an acceleration term (those belong in the mass matrix).
    """
    P = len(names)
    fac = np.zeros((P, MAX_FACTORS), dtype=np.int64)
    dof = np.zeros(P, dtype=np.int64)
    for j, n in enumerate(names):
        t = term(n)
        if t.kind != "force":
            raise ValueError(f"{n} is an acceleration term, not a force term")
        for i, f in enumerate(t.factors):
            fac[j, i] = F_INDEX[f]
        dof[j] = t.dof
    return fac, dof


def names_where(
    *,
    group: str | None = None,
    category: str | None = None,
    kind: str | None = None,
    horizontal: bool | None = None,
    listed: bool = False,
) -> list[str]:
    """Term names (table order) matching all given filters.

    Example: ``names_where(group="Y", category="rotary", horizontal=True)``.

    Parameters
    ----------
    group : str, optional
        Force/moment letter (:attr:`Term.group`: ``"X"``, ``"Y"``, ...).
    category : str, optional
        One of :data:`CATEGORIES` (:attr:`Term.category`).
    kind : str, optional
        One of :data:`TERM_KINDS` (:attr:`Term.kind`).
    horizontal : bool, optional
        Keep only the terms that do (True) or do not (False) act in the horizontal-plane model
        (:attr:`Term.horizontal`).
    listed : bool, default False
        Only the names written out in the table (:data:`LISTED`), not the products this process
        added since: a candidate library that must not depend on which vehicles were loaded
        before.

    Returns
    -------
    list of str
        The matching names, in table order. A filter left at None does not filter.
    """
    out = []
    for t in TERMS[: len(LISTED)] if listed else TERMS:
        if group is not None and t.group != group:
            continue
        if category is not None and t.category != category:
            continue
        if kind is not None and t.kind != kind:
            continue
        if horizontal is not None and t.horizontal != horizontal:
            continue
        out.append(t.name)
    return out


def regressors(features: np.ndarray, names, rho: float, L: float) -> np.ndarray:
    """Regressor columns of force terms: ``Phi[:, j] = scale_j * prod(features of term j)``.

    ``tau_dof = sum_j [dof_j == dof] * Phi[:, j] * C'_j`` (hydrodynamic part only).

    Parameters
    ----------
    features : ndarray, shape (n, N_FEATURES)
        Feature rows, from :func:`bayesid.models.dynamics.features`.
    names : sequence of str
        The P force-term names.
    rho : float
        Water density, kg/m^3.
    L : float
        Reference length, m.

    Returns
    -------
    ndarray, shape (n, P)
        The regressor columns, newtons or newton-metres per unit coefficient.
    """
    fac, _ = factor_table(names)
    scale = prime_scale(names, rho, L)
    return np.prod(features[:, fac], axis=2) * scale
