"""The candidate terms of structure discovery and the models they extend: the terms a model lacks
from its family's term library (:func:`candidate_terms`), the tied coefficients it may untie
(:func:`untied_candidates`), each candidate's value in the reference model
(:func:`reference_values`), a setup with terms added (:func:`with_terms`), the reference model
with every candidate added (:func:`augmented_model`) and the reference fit's parameters, window
starts and nuisances carried over to an extended model (:func:`extended_start`,
:func:`~bayesid.estimation.windows.warm_starts`, :func:`nuisance_start`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ....models import build_model
from ....models.library import MAX_ORDER, term_library
from ..candidates import Setup, Stage

__all__ = [
    "candidate_terms",
    "untied_candidates",
    "reference_values",
    "with_terms",
    "augmented_model",
    "extended_start",
    "nuisance_start",
]


def candidate_terms(model, max_order: int = MAX_ORDER, dofs=("Y", "N")) -> list[str]:
    """The candidate terms a model lacks, named as its vehicle file writes them: its family's
    term library (:func:`bayesid.models.library.term_library`).

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
        The names, grouped by force letter; the family's tied coefficients last
        (:func:`untied_candidates`).

    Raises
    ------
    NoTermLibraryError
        When the model's family offers no term library.
    """
    return term_library(model).candidates(model, max_order, dofs)


def untied_candidates(model, dofs=("Y", "N")) -> list[str]:
    """The family's physical candidates the model has a parameter for: its tied coefficients that
    are not free (:meth:`bayesid.models.library.TermLibrary.untied`; a ship's ``gRm``, gamma_R
    for beta_R < 0, following ``gR``; none for a submarine).

    Parameters
    ----------
    model : SimulationModel
        The reference model.
    dofs : sequence of str, default ("Y", "N")
        The force letters searched.

    Returns
    -------
    list of str
        The tied coefficients to untie.

    Raises
    ------
    NoTermLibraryError
        When the model's family offers no term library.
    """
    return term_library(model).untied(model, dofs)


def reference_values(ref: Stage, names: list) -> dict:
    """Each candidate's value in the reference model: 0 for a term it lacks; for a tied
    coefficient the value of the one it follows (the reference fit's, when that one is free).

    Parameters
    ----------
    ref : Stage
        The fitted reference model.
    names : list of str
        The candidates.

    Returns
    -------
    dict
        ``{name: prime value}``.
    """
    veh = ref.model.vehicle
    tied = term_library(ref.model).tied
    fitted = ref.fit.coefficients()
    return {n: float(fitted.get(tied[n], veh.coefficients.get(tied[n], 0.0))) if n in tied else 0.0 for n in names}


def with_terms(setup: Setup, values: dict) -> Setup:
    """A setup with terms added to its vehicle and to its free coefficients.

    Parameters
    ----------
    setup : Setup
        The setup (:class:`bayesid.analysis.gap.candidates.Setup`).
    values : dict
        ``{term: value}``, prime (names as a vehicle file writes them); terms already free keep
        their place in the free list.

    Returns
    -------
    Setup
        A copy whose vehicle has the terms at ``values`` and whose free list ends with the new
        ones, in ``values``' order.
    """
    return replace(
        setup,
        vehicle=setup.vehicle.with_coefficients(values),
        free=list(setup.free) + [k for k in values if k not in setup.free],
    )


def augmented_model(setup: Setup, effects, values: dict, window_s: float | None) -> tuple:
    """The reference model with every candidate added at its reference value (0 for a term) and
    free, on the interpreted kernel (one model for any number of terms, nothing to compile), and
    its training contexts over ``window_s`` windows.

    Parameters
    ----------
    setup : Setup
        The reference model's vehicle, free coefficients, training tracks and start rule.
    effects : sequence of Effect
        The reference model's effects.
    values : dict
        ``{candidate: reference value}`` (prime; :func:`reference_values`), added after the free
        coefficients in this order.
    window_s : float or None
        The windows of the contexts, s (None: the whole run).

    Returns
    -------
    model : SimulationModel
        The augmented model.
    contexts : list
        Its context of each training track.
    """
    veh = setup.vehicle.with_coefficients(values)
    m = build_model(
        veh,
        [*setup.free, *values],
        list(effects),
        dt=setup.dt,
        mode=setup.mode,
        kernel="interpreted",
        inputs=setup.inputs,
        rudder_rate_deg_s=setup.rudder_rate_deg_s,
    )
    return m, [m.context(t, window_s, start=setup.rule) for t in setup.train]


def extended_start(ref: Stage, model, values: list) -> np.ndarray:
    """The reference fit's parameters in ``model``'s order, matched by name (so the effects may
    come in another order than the reference model's), with the coefficients the reference
    lacks (the new terms, in ``model``'s order) at ``values``.

    Parameters
    ----------
    ref : Stage
        The fitted reference model.
    model : SimulationModel
        The model extended by the new terms.
    values : list of float
        The new terms' values (prime), in ``model``'s order.

    Returns
    -------
    ndarray, shape (model.n_params,)
        The start of ``model``'s fit.
    """
    known = dict(zip(ref.model.param_names, ref.fit.p))
    new = iter(np.asarray(values, float))
    return np.array([known[n] if n in known else next(new) for n in model.param_names], float)


def nuisance_start(ref: Stage, model) -> list | None:
    """The reference fit's per-track nuisances rearranged to ``model``'s effect order (matched by
    effect name), or None when ``model`` has none.

    Parameters
    ----------
    ref : Stage
        The fitted reference model.
    model : SimulationModel
        The model extended by new terms (the same effects, possibly in another order).

    Returns
    -------
    list of ndarray or None
        Per track, the nuisances in ``model``'s order; None when ``model`` has none.
    """
    if not model.n_nuisance:
        return None
    out = []
    for nu in ref.fit.nuisance:
        parts, off = {}, 0
        for e in ref.model.effects:
            parts[e.name] = np.asarray(nu[off : off + e.n_nuisance], float)
            off += e.n_nuisance
        out.append(np.concatenate([parts[e.name] for e in model.effects if e.n_nuisance]))
    return out
