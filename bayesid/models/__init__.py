"""Simulation models of vessels behind one interface (:mod:`bayesid.models.interface`).

:func:`build_model` and :func:`model_class` are the one place that asks which kind of vessel a
vehicle description is; everything above the model layer (fits, prediction, the gap diagnosis,
the command line) works with the model it returns.
"""

from __future__ import annotations

from ..data.vehicle import Vehicle, load_vehicle
from .interface import SimulationModel
from .ship import Ship, ShipModel, is_ship_file, load_ship
from .submarine import EffectModel

__all__ = ["FAMILIES", "SimulationModel", "build_model", "load_any_vehicle", "model_class"]

#: vehicle description type -> model class (a new vessel family registers here)
FAMILIES = {Vehicle: EffectModel, Ship: ShipModel}


def model_class(vehicle):
    """The model class of a vehicle description (:data:`FAMILIES`); TypeError for an unknown
    type."""
    for kind, cls in FAMILIES.items():
        if isinstance(vehicle, kind):
            return cls
    raise TypeError(
        f"no simulation model for a {type(vehicle).__name__}; known: {', '.join(k.__name__ for k in FAMILIES)}"
    )


def build_model(vehicle, free=None, effects=(), dt: float | None = None, mode: str = "horizontal"):
    """The simulation model of a vehicle with ``effects``: for a ship the MMG 3-DOF
    :class:`~bayesid.models.ship.model.ShipModel` (``free`` default: the file's ``[fit] free``), for a
    submarine :class:`~bayesid.models.submarine.EffectModel` in ``mode`` (``free`` default: none).
    ``dt`` default: the family's ``DEFAULT_DT`` (0.2 s ship, 0.5 s submarine).

    Raises KeyError for an unknown coefficient, ValueError for an unknown effect."""
    cls = model_class(vehicle)
    return cls.for_vehicle(vehicle, free, effects, dt=cls.DEFAULT_DT if dt is None else dt, mode=mode)


def load_any_vehicle(path_or_id):
    """A ship (``kind = "ship3dof"``) or a submarine vehicle file, by path or packaged id."""
    return load_ship(path_or_id) if is_ship_file(path_or_id) else load_vehicle(path_or_id)
