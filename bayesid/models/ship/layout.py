"""The parameter vector of the ship's compiled kernels: particulars, then MMG coefficients, then
the model-form slots, in a fixed order, and the quadrature of the hull cross-flow integral. The interpreted kernels
(:mod:`bayesid.models.ship.dynamics`), the generated one (:mod:`bayesid.models.ship.kernel`), the
ship file (:mod:`bayesid.models.ship.fileformat`) and the model all read this layout.
"""

from __future__ import annotations

import numpy as np

#: Particulars in the kernel's parameter vector (order fixed; SI units, ratios as noted).
PARTICULARS = (
    "L",
    "B",
    "d",
    "mass_kg",
    "xG",
    "rho",
    "kzz",
    "Cb",
    "D_prop",
    "A_rudder",
    "lambda_rudder",
    "eta_prop_rudder",
    "x_rudder",
    "rho_air",
    "A_front",
    "A_lateral",
)
#: Coefficients (MMG prime form; see the module docstring), in the kernel's order.
COEFFICIENTS = (
    "mx",
    "my",
    "Jz",
    "Xuu",
    "Xvv",
    "Xvr",
    "Xrr",
    "Yv",
    "Yr",
    "Nv",
    "Nr",
    "Ycf",
    "Ncf",
    "Yvvr",
    "Yvrr",
    "Nvvr",
    "Nvrr",
    "wP",
    "tP",
    "k0",
    "k1",
    "k2",
    "Ka",
    "xP",
    "tR",
    "aH",
    "xH",
    "eps",
    "kappa",
    "lR",
    "gR",
    "Cx1",
    "Cx3",
    "Cy1",
    "Cy3",
    "Cn1",
    "Cn2",
    "Cn3",
    "dR0",
    "gRm",
    "C1",
    "C2",
    "C2m",
)
#: Coefficients that equal another one unless given (a ship file's ``[coefficients]``, a fit or
#: :meth:`~bayesid.models.ship.fileformat.Ship.with_coefficients`): ``gRm``, the rudder's
#: flow-straightening coefficient gamma_R for ``beta_R < 0``, is ``gR`` (``beta_R >= 0``), so a
#: ship file without it has one gamma_R for both sides (Yasukawa & Yoshimura 2015, eqs. 13-23 and
#: Tables 3-5, give two for KVLCC2). ``C2m``, the wake-in-turn coefficient C2 for ``beta_P < 0``, is
#: ``C2`` (``beta_P > 0``) in the same way. Appended last: the other coefficients keep their positions.
FOLLOWS = {"gRm": "gR", "C2m": "C2"}
#: The coefficients of the MMG 2015 wake in a turn (Yasukawa & Yoshimura 2015, eq. 16):
#: ``1 - w_P = (1 - wP) (1 + (1 - exp(-C1 |beta_P|)) (C2 - 1))``, ``C2m`` in place of ``C2`` for
#: ``beta_P < 0``. ``C1 = 0`` (a ship file without them) keeps the form ``w_P = wP exp(-4 beta_P^2)``.
WAKE_IN_TURN = ("C1", "C2", "C2m")
WIND = ("Cx1", "Cx3", "Cy1", "Cy3", "Cn1", "Cn2", "Cn3")
#: Model-form choices of a ship file's ``[form]`` section: ``{key: (default, the other choices)}``.
#: ``coupling_speed``: the speed the hull's coupling terms ``Yvvr``, ``Yvrr``, ``Nvvr``, ``Nvrr``
#: are divided by, ``"Ut"`` = ``sqrt(u^2 + v^2 + (rL)^2)`` (the package's form, bounded at every
#: speed) or ``"U"`` = ``sqrt(u^2 + v^2)`` (MMG 2015's ``v'^2 r' U^2``, Yasukawa & Yoshimura 2015,
#: the hull forces, eqs. 6-8 as the package cites them; in a 35 deg turn the package's form gives these terms 0.6-0.75 of MMG's,
#: ``benchmarks/shipmmg_turn.py``). A number in [0, 1] is the weight of ``(rL)^2`` between the
#: two (1 is ``"Ut"``, 0 is ``"U"``): the ``coupling_speed`` effect's fitted form, which
#: ``bayesid diagnose --write-vehicle`` writes. Not coefficients: no fit of the base model changes them.
FORMS = {"coupling_speed": ("Ut", "U")}
#: The kernel's numbers of the forms, after the coefficients: ``coupling_rL`` is the weight of
#: ``(rL)^2`` in the coupling speed (1 for ``"Ut"``, 0 for ``"U"``).
FORM_SLOTS = ("coupling_rL",)
NP = len(PARTICULARS) + len(COEFFICIENTS) + len(FORM_SLOTS)
#: Position of each particular in the parameter vector.
PARTICULAR_INDEX = {n: i for i, n in enumerate(PARTICULARS)}
#: Position of each coefficient in the parameter vector.
COEFFICIENT_INDEX = {n: len(PARTICULARS) + i for i, n in enumerate(COEFFICIENTS)}
#: Position of each form slot in the parameter vector.
FORM_INDEX = {n: len(PARTICULARS) + len(COEFFICIENTS) + i for i, n in enumerate(FORM_SLOTS)}


def form_slots(form: dict) -> list[float]:
    """The kernel's numbers of a ship's model-form choices (:data:`FORMS`, :data:`FORM_SLOTS`).

    Parameters
    ----------
    form : dict
        ``{key: choice}`` of :data:`FORMS` (a key left out has its default).

    Returns
    -------
    list of float
        One number per :data:`FORM_SLOTS` entry.
    """
    return [coupling_rl_weight(form.get("coupling_speed", FORMS["coupling_speed"][0]))]


def coupling_rl_weight(choice) -> float:
    """The weight of ``(rL)^2`` in the coupling speed of a ``[form] coupling_speed`` choice.

    Parameters
    ----------
    choice : str or float
        ``"Ut"`` (1), ``"U"`` (0) or the weight itself, in [0, 1].

    Returns
    -------
    float
        The weight.
    """
    if isinstance(choice, str):
        return 1.0 if choice == "Ut" else 0.0
    return float(choice)


#: Gauss-Legendre nodes (on [-1, 1]) and weights of the hull cross-flow integral, 16 points: the
#: stations are ``x = h * GAUSS_X`` with ``h`` the half length (see ``_forces``). Shared by the
#: interpreted kernels (:mod:`bayesid.models.ship.dynamics`) and the generated one
#: (:mod:`bayesid.models.ship.kernel`).
GAUSS_X, GAUSS_W = np.polynomial.legendre.leggauss(16)


__all__ = [
    "PARTICULARS",
    "COEFFICIENTS",
    "FOLLOWS",
    "WIND",
    "WAKE_IN_TURN",
    "FORMS",
    "FORM_SLOTS",
    "FORM_INDEX",
    "coupling_rl_weight",
    "form_slots",
    "NP",
    "PARTICULAR_INDEX",
    "COEFFICIENT_INDEX",
    "GAUSS_X",
    "GAUSS_W",
]
