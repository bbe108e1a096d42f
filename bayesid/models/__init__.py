"""Simulation models of vessels behind one interface (:mod:`bayesid.models.interface`).

:func:`build_model` and :func:`model_class` are the one place that asks which kind of vessel a
vehicle description is; everything above the model layer (fits, prediction, the gap diagnosis,
the command line) works with the model it returns.
"""

from __future__ import annotations

import math

from .._numba import drop_stale_caches
from ..data.vehicle import Vehicle, load_vehicle
from .context import INPUT_RECONSTRUCTIONS
from .interface import SimulationModel
from .ship import Ship, ShipModel, is_ship_file, load_ship
from .submarine import EffectModel

# numba reads a cache at a function's first call, not at its decoration: dropping stale caches
# after the imports is in time (see bayesid._numba)
drop_stale_caches()

__all__ = ["FAMILIES", "SimulationModel", "build_model", "default_dt", "load_any_vehicle", "model_class"]

#: vehicle description type -> model class (a new vessel family registers here)
FAMILIES = {Vehicle: EffectModel, Ship: ShipModel}


def model_class(vehicle):
    """The model class of a vehicle description (:data:`FAMILIES`).

    Parameters
    ----------
    vehicle : Vehicle or Ship
        The vessel description.

    Returns
    -------
    type
        The model class registered for the description's type.

    Raises
    ------
    TypeError
        For a type no family registers.
    """
    for kind, cls in FAMILIES.items():
        if isinstance(vehicle, kind):
            return cls
    raise TypeError(
        f"no simulation model for a {type(vehicle).__name__}; known: {', '.join(k.__name__ for k in FAMILIES)}"
    )


def default_dt(vehicle) -> float:
    """The model step of a vehicle when the user gives none: its family's ``default_dt(vehicle)``
    where the family has one (a submarine's shortens with the vehicle's time unit ``L / U``:
    :meth:`bayesid.models.submarine.EffectModel.default_dt`), else its ``DEFAULT_DT``.

    Parameters
    ----------
    vehicle : Vehicle or Ship
        The vehicle.

    Returns
    -------
    float
        The step, s.

    Raises
    ------
    TypeError
        For a vehicle description of no registered family.
    """
    cls = model_class(vehicle)
    return cls.default_dt(vehicle) if hasattr(cls, "default_dt") else cls.DEFAULT_DT


def build_model(
    vehicle,
    free=None,
    effects=(),
    dt: float | None = None,
    mode: str = "horizontal",
    kernel: str = "generated",
    inputs: str = "hold",
    rudder_rate_deg_s: float | None = None,
):
    """The simulation model of a vehicle with ``effects``: for a ship the MMG 3-DOF
    :class:`~bayesid.models.ship.model.ShipModel`, for a submarine
    :class:`~bayesid.models.submarine.EffectModel` in ``mode``.

    Parameters
    ----------
    vehicle : Vehicle or Ship
        The vessel description.
    free : list of str, optional
        The coefficients the fits change; default for a ship the file's ``[fit] free``, for a
        submarine none.
    effects : sequence of Effect or str, default ()
        The effects added to the model (catalogue names or :class:`~bayesid.models.effects.Effect`).
    dt : float, optional
        Model step, s; default :func:`default_dt` (0.2 s ship; 0.5 s submarine, shorter for a
        small or fast one).
    mode : {"horizontal", "6dof"}, default "horizontal"
        Degrees of freedom of a submarine model (a ship is always 3-DOF).
    kernel : {"generated", "interpreted"}, default "generated"
        The compiled kernel kind (the interpreted one takes any set of terms without compiling).
    inputs : {"hold", "linear", "rate"}, default "hold"
        How the logged inputs are reconstructed between samples
        (:data:`bayesid.models.context.INPUT_RECONSTRUCTIONS`); the model's ``inputs``
        attribute, read by its track contexts.
    rudder_rate_deg_s : float, optional
        The control surfaces' gear rate of ``inputs="rate"``, deg/s
        (:func:`bayesid.models.context.rate_limited_knots`); default the vehicle file's (a ship's
        ``[service] rudder_rate_deg_s``). The model's ``rudder_rate_deg_s`` attribute.

    Returns
    -------
    SimulationModel
        The model.

    Raises
    ------
    KeyError
        For an unknown coefficient (:class:`~bayesid.data.terms.UnknownCoefficientError`).
    ValueError
        For an unknown effect or input reconstruction; ``inputs="rate"`` without a rate (none
        given and none in the vehicle file) or with one that is not positive.
    TypeError
        For a vehicle description of no registered family.
    """
    if inputs not in INPUT_RECONSTRUCTIONS:
        raise ValueError(f"inputs must be one of {', '.join(INPUT_RECONSTRUCTIONS)}, not {inputs!r}")
    cls = model_class(vehicle)
    model = cls.for_vehicle(
        vehicle, free, effects, dt=default_dt(vehicle) if dt is None else dt, mode=mode, kernel=kernel
    )
    model.inputs = inputs
    if inputs == "rate":
        rate = rudder_rate_deg_s if rudder_rate_deg_s is not None else getattr(cls, "gear_rate_deg_s", _none)(vehicle)
        if rate is None:
            raise ValueError(
                "inputs 'rate' needs the steering gear's rate: give it (--rudder-rate DEG_S) or write it in the "
                "ship file ([service] rudder_rate_deg_s)"
            )
        if not (math.isfinite(rate) and rate > 0):
            raise ValueError(f"--rudder-rate must be a positive number of deg/s, not {rate!r}")
        model.rudder_rate_deg_s = float(rate)
    return model


def _none(vehicle) -> None:
    """No gear rate (a family whose files give none)."""
    return None


def load_any_vehicle(path_or_id):
    """A ship (``kind = "ship3dof"``) or a submarine vehicle file, by path or packaged id.

    Parameters
    ----------
    path_or_id : str or Path
        A path to a TOML file, or the id of a packaged vehicle.

    Returns
    -------
    Ship or Vehicle
        The ship (:func:`~bayesid.models.ship.load_ship`) or the submarine
        (:func:`~bayesid.data.vehicle.load_vehicle`).
    """
    return load_ship(path_or_id) if is_ship_file(path_or_id) else load_vehicle(path_or_id)
