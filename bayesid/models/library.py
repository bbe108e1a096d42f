"""The candidate terms a vessel family offers structure discovery: one small interface, like
PySINDy's feature libraries (``feature_library/base.py``: names and columns behind ``fit`` and
``transform``).

Structure discovery (:mod:`bayesid.analysis.gap.discovery`) asks a model for its
:class:`TermLibrary` (:func:`term_library`) and never which kind of vessel it has. A family's
library answers four questions:

* which terms the model lacks (:meth:`TermLibrary.candidates`), named as the family's vehicle
  file writes them, so a discovered term can be pasted into a vehicle file;
* their force columns along a motion (:meth:`TermLibrary.columns`): newtons or newton-metres per
  unit prime coefficient, in the family's prime form;
* which coefficients the vehicle file ties to another (:attr:`TermLibrary.tied`, e.g. a ship's
  gamma_R for beta_R < 0 following gamma_R), since untying one is a candidate like a term;
* the degree of freedom a candidate acts in (:meth:`TermLibrary.dof`).

A new vessel family implements a subclass and returns it from its model's ``term_library()``;
a model without one gets :class:`NoTermLibraryError` from discovery, never another family's
grammar.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DOFS", "MAX_ORDER", "NoTermLibraryError", "TermLibrary", "motion_products", "term_library"]

#: The degrees of freedom a horizontal-plane library searches.
DOFS = ("X", "Y", "N")
#: Highest number of motion factors of a candidate.
MAX_ORDER = 3


class NoTermLibraryError(TypeError):
    """The model's family offers no candidate term library (discovery cannot search it)."""


def motion_products(max_order: int, rudder_abs: bool = True) -> list[str]:
    """Every product of the motion factors ``v r dr`` and their ``|.|`` forms of one to
    ``max_order`` factors, one name per product (``|x| |x| = x x``), spelled in the factor order
    ``v absv r absr dr absdr``; the shorter first.

    Parameters
    ----------
    max_order : int
        Highest number of factors (1..:data:`MAX_ORDER`).
    rudder_abs : bool, default True
        Whether ``|dr|`` is a factor of the family's grammar.

    Returns
    -------
    list of str
        The name bodies (without the force letter), e.g. ``"vvr"``, ``"absdr"``.
    """
    parts = []
    for a_v in range(max_order + 1):
        for c_v in (0, 1):
            for a_r in range(max_order + 1):
                for c_r in (0, 1):
                    for a_d in range(max_order + 1):
                        for c_d in (0, 1) if rudder_abs else (0,):
                            n = a_v + c_v + a_r + c_r + a_d + c_d
                            if 1 <= n <= max_order:
                                parts.append(
                                    "v" * a_v + "absv" * c_v + "r" * a_r + "absr" * c_r + "dr" * a_d + "absdr" * c_d
                                )
    return sorted(parts, key=lambda p: (len(p), p))


class TermLibrary:
    """A vessel family's library of candidate model terms (the base: override every method).

    Parameters
    ----------
    vehicle : object
        The vessel description (the family's vehicle type).

    Attributes
    ----------
    family : str
        The family's name, for messages.
    """

    family = "vessel"

    def __init__(self, vehicle):
        self.vehicle = vehicle

    @property
    def tied(self) -> dict:
        """``{tied coefficient: the coefficient it follows}`` (empty when the family ties none)."""
        return {}

    def candidates(self, model, max_order: int = MAX_ORDER, dofs=("Y", "N")) -> list[str]:
        """The candidate terms ``model`` lacks, named as the family's vehicle file writes them,
        grouped by force letter; the untied coefficients (:meth:`untied`) last.

        Parameters
        ----------
        model : SimulationModel
            The reference model; its vehicle's coefficients (listed, non-zero or free) are not
            candidates.
        max_order : int, default 3
            Highest number of motion factors.
        dofs : sequence of str, default ("Y", "N")
            The force letters searched.

        Returns
        -------
        list of str
            Candidate names, grouped by force letter, the untied coefficients last.
        """
        raise NotImplementedError

    def untied(self, model, dofs=("Y", "N")) -> list[str]:
        """The tied coefficients that are not free in ``model`` (candidates to untie).

        Parameters
        ----------
        model : SimulationModel
            The reference model.
        dofs : sequence of str, default ("Y", "N")
            The force letters searched.

        Returns
        -------
        list of str
            The tied coefficients not free in ``model``.
        """
        return []

    def columns(self, names, motion: dict, inputs) -> np.ndarray:
        """Force columns of terms at unit prime coefficient along a motion.

        Parameters
        ----------
        names : sequence of str
            Terms of :meth:`candidates` (not the untied coefficients).
        motion : dict
            Smoothed motion (:func:`bayesid.models.inverse.estimate_motion`): ``u v r`` (n,).
        inputs : array_like, shape (n, 4)
            The inputs at the motion's samples (``delta_r`` rad first).

        Returns
        -------
        ndarray, shape (n, len(names))
            N or N m per unit prime coefficient.
        """
        raise NotImplementedError

    def dof(self, name: str) -> str:
        """The degrees of freedom a candidate acts in: its force letter, ``"XYN"`` for a tied
        coefficient (e.g. a rudder parameter acting in all three).

        Parameters
        ----------
        name : str
            A candidate.

        Returns
        -------
        str
            ``"X"``, ``"Y"``, ``"N"`` or ``"XYN"``.
        """
        return "XYN" if name in self.tied else name[0]


def term_library(model) -> TermLibrary:
    """The candidate term library of a model's family.

    Parameters
    ----------
    model : SimulationModel
        A model (:func:`bayesid.models.build_model`).

    Returns
    -------
    TermLibrary
        The family's library, bound to the model's vehicle.

    Raises
    ------
    NoTermLibraryError
        When the model's family offers none (a family registered without a ``term_library``).
    """
    make = getattr(model, "term_library", None)
    lib = make() if callable(make) else None
    if not isinstance(lib, TermLibrary):
        raise NoTermLibraryError(
            f"the {type(model).__name__} family offers no candidate term library: structure discovery "
            "cannot search it (implement bayesid.models.library.TermLibrary and return it from the "
            "model's term_library())"
        )
    return lib
