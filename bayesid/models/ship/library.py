"""The ship family's candidate term library for structure discovery: the extra hull terms of
:mod:`bayesid.models.ship.hullterms` and the ship file's tied coefficients
(:class:`bayesid.models.library.TermLibrary`).
"""

from __future__ import annotations

import numpy as np

from ..library import TermLibrary, motion_products
from . import hullterms


class ShipTerms(TermLibrary):
    """Every product of ``v r |v| |r| dr |dr|`` of one to three factors the ship lacks, and the
    constants ``X0 Y0 N0``, in MMG prime form (``0.5 rho L d U^2 C' f'_1 ... f'_k``, Yasukawa &
    Yoshimura 2015, Sec. 2.2, eqs. 6-8; :mod:`bayesid.models.ship.hullterms`), so port/starboard
    asymmetric forms (``N0``, ``Nabsdr``, ``Nvv``) are candidates; and the ship file's tied
    coefficients (``gRm``, gamma_R for beta_R < 0, which follows ``gR`` unless the file gives it).

    Parameters
    ----------
    vehicle : Ship
        The ship (:class:`bayesid.models.ship.fileformat.Ship`).
    """

    family = "ship"

    @property
    def tied(self) -> dict:
        """``{tied coefficient: the one it follows}`` (:attr:`Ship.tied`)."""
        return self.vehicle.tied

    def candidates(self, model, max_order: int = hullterms.MAX_ORDER, dofs=("Y", "N")) -> list[str]:
        """See :meth:`TermLibrary.candidates`; a listed coefficient's product (``Yrvv`` is
        ``Yvvr``) is not a candidate. In X, with ``max_order`` 3, the fourth-order products of
        :func:`surge_products` too (``Xvvvv``, ``Xvvrr``, ...: the MMG hull surge polynomial).

        Parameters
        ----------
        model : SimulationModel
            The reference model; its vehicle's coefficients are not candidates.
        max_order : int, default 3
            Highest number of motion factors.
        dofs : sequence of str, default ("Y", "N")
            The force letters searched.

        Returns
        -------
        list of str
            Candidate names, grouped by force letter, the untied coefficients last.
        """
        out = []
        for g in dofs:
            bodies = ["0", *motion_products(max_order)]
            if g == "X" and max_order >= hullterms.MAX_ORDER:
                bodies += surge_products()
            for body in bodies:
                name = g + body
                if name in self.vehicle.coefficients:
                    continue
                try:
                    hullterms.parse(name)
                except hullterms.HullTermError:
                    continue  # a listed product
                out.append(name)
        return out + self.untied(model, dofs)

    def untied(self, model, dofs=("Y", "N")) -> list[str]:
        """A ship file that gives one ``gR`` states a hypothesis, one flow-straightening
        coefficient gamma_R for both signs of the rudder's inflow angle (MMG eq. 23; Yasukawa &
        Yoshimura's Table 3 gives two for KVLCC2). Untying it, with the value it follows as its
        start, is a candidate like a missing term: a port/starboard asymmetry of the rudder
        force, acting in X, Y and N at once (it needs Y or N among ``dofs``). ``C2m`` (the wake in
        a turn's C2 for ``beta_P < 0``) is untied only where it acts: in a ship file with the MMG
        2015 wake in a turn (``C1 > 0``), and not beside the ``wake_in_turn`` effect, which sets it.

        Parameters
        ----------
        model : SimulationModel
            The reference model.
        dofs : sequence of str, default ("Y", "N")
            The force letters searched.

        Returns
        -------
        list of str
            The tied coefficients not free in ``model`` (empty when ``dofs`` has neither Y nor N).
        """
        if not {"Y", "N"} & set(dofs):
            return []
        wake = self.vehicle.coefficients.get("C1", 0.0) > 0.0 and not any(
            e.name == "wake_in_turn" for e in getattr(model, "effects", ())
        )
        return [k for k in self.tied if k not in model.free and (k != "C2m" or wake)]

    def columns(self, names, motion: dict, inputs) -> np.ndarray:
        """Force columns of terms at unit prime coefficient along a motion
        (:func:`hullterms.columns`, MMG prime form).

        Parameters
        ----------
        names : sequence of str
            Terms of :meth:`candidates` (not the untied coefficients).
        motion : dict
            Smoothed motion: ``u v r`` (n,), m/s and rad/s.
        inputs : array_like, shape (n, 4)
            The inputs at the motion's samples (``delta_r`` rad first).

        Returns
        -------
        ndarray, shape (n, len(names))
            N or N m per unit prime coefficient.
        """
        P = self.vehicle.particulars
        return hullterms.columns(
            [hullterms.parse(n) for n in names],
            motion["u"],
            motion["v"],
            motion["r"],
            np.asarray(inputs)[:, 0],
            P["L"],
            P["rho"],
            P["d"],
        )


def surge_products() -> list[str]:
    """The fourth-order products of the velocity factors ``v r |v| |r|`` that a port-starboard
    symmetric hull's surge force can have: even in the signed factors (``X(v, r) = X(-v, -r)``),
    e.g. ``vvvv``, ``vvvr``, ``vvrr``, ``vrrr``, ``rrrr``, ``vvabsrabsr``... The MMG hull surge
    polynomial (Yasukawa & Yoshimura 2015, J. Mar. Sci. Technol. 20:37-52, Sec. 2.2) has ``X'vvvv``
    of these; structure discovery offers the others beside it
    (:data:`~bayesid.models.ship.hullterms.MAX_SURGE_ORDER`).

    Returns
    -------
    list of str
        Name bodies (without the force letter) in :func:`~bayesid.models.library.motion_products`'
        spelling.
    """
    out = []
    for a_v in range(5):
        for c_v in (0, 1):
            for a_r in range(5):
                for c_r in (0, 1):
                    if a_v + c_v + a_r + c_r == hullterms.MAX_SURGE_ORDER and (a_v + a_r) % 2 == 0:
                        out.append("v" * a_v + "absv" * c_v + "r" * a_r + "absr" * c_r)
    return sorted(out, key=lambda p: (len(p), p))
