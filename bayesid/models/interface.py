"""The written model interface: what a simulation model of a vessel offers the estimation and
analysis layers.

Two implementations: the submarine's horizontal-plane or 6-DOF model with effects
(:class:`bayesid.models.submarine.EffectModel`) and the 3-DOF surface ship in MMG form
(:class:`bayesid.models.ship.model.ShipModel`). The fits (:mod:`bayesid.estimation.windows`), the long-run
identification and prediction (:mod:`bayesid.estimation.identification`), the gap diagnosis (:mod:`bayesid.analysis.gap`) and
the command line take a model and never ask which kind of vessel it is; what differs between
vessels is answered by the model (its defaults, its effect catalogue, its inverse dynamics).

Build one with :func:`bayesid.models.build_model`; a new vessel family implements this protocol
and registers its vehicle type in :data:`bayesid.models.FAMILIES`.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["SimulationModel", "ParameterLayout"]


@runtime_checkable
class SimulationModel(Protocol):
    """A vessel's simulation model plus a list of effects, simulated over a track's protocol
    windows (the contract; units SI, angles in radians unless a name says otherwise).

    Parameters and layout
    ---------------------
    ``vehicle`` : the vessel description it was built from (nominal coefficients).
    ``free`` : list of the coefficient names the fits change (SNAME or MMG names).
    ``effects`` : list of :class:`bayesid.models.effects.Effect`, in parameter order.
    ``param_names`` : ``free + ["effect.param", ...]``; the parameter vector is
    ``[theta_free (n_theta), q_1, ..., q_E]``; ``n_theta``, ``n_q`` (per effect), ``n_params``.
    ``theta0`` : (n_theta,) nominal values of the free coefficients.
    ``n_nuisance`` : per-track parameters (e.g. a wave phase), passed separately to
    :meth:`simulate`.   ``dt`` : model step (s).   ``mode`` : ``"horizontal"`` or ``"6dof"``.

    Class-level defaults (the vessel family's)
    ------------------------------------------
    ``DEFAULT_DT`` : model step (s) when the user gives none.
    ``DEFAULT_WEIGHTING`` : channel weighting of its fits (``"noise"`` or ``"residual"``,
    :func:`bayesid.estimation.windows.fit_weighted`).
    ``CATALOGUE`` : {name: Effect} candidate effects of the gap diagnosis.
    ``default_fit_window(scoring_window_s)`` : fit window (s) of the training fits when the
    protocol scores over ``scoring_window_s``.
    ``default_free(vehicle)``, ``check_free(vehicle, names, option)`` : the free list.
    ``get_effect(name)`` : a catalogue effect, ValueError naming an unknown one.
    """

    vehicle: object
    free: list
    effects: list
    param_names: list
    n_theta: int
    n_q: list
    n_nuisance: int
    theta0: np.ndarray
    dt: float
    mode: str

    @property
    def n_params(self) -> int:
        """Length of the parameter vector."""

    def start(self, theta=None) -> np.ndarray:
        """(n_params,) start of a fit: ``theta`` (default ``theta0``) and the effects' starts."""

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of the parameter vector (+-inf where unbounded)."""

    def scales(self) -> np.ndarray:
        """(n_params,) typical sizes (fit scaling, finite-difference steps)."""

    def split_params(self, P) -> tuple[np.ndarray, list]:
        """(B, n_params) -> (theta (B, n_theta), [q_e (B, n_q_e) per effect])."""

    def context(
        self, track, window_s=None, span_s: float = 1.0, s0=None, start: str = "measured", leadin_s: float = 0.0
    ):
        """A track prepared for simulation (:class:`bayesid.models.context.TrackContext`): step inputs,
        protocol windows (``window_s``; None = whole run), window-start states by the start rule
        ``start`` (lead-in ``leadin_s``), or the state ``s0`` (12,) at the first sample."""

    def simulate(
        self, ctx, P, nuisance=None, measured_start: bool = True, starts=None, samples: str = "scored"
    ) -> np.ndarray:
        """(B, n_samples, 12) predicted measurements (STATE_NAMES order, NaN in a diverged
        window) for (B, n_params) parameter vectors ``P``; ``nuisance`` (B, n_nuisance);
        ``starts`` (B, W, 6) start-state offsets of the fitted start rule; ``samples`` scored or
        lead."""

    def seed(self, tracks):
        """An equation-error start of the fit, (p (n_params,), summary dict), or None when the
        family has none."""

    def missing_forces(self, fitres, track):
        """Inverse dynamics: (motion dict, F (n, 3) missing X, Y, N in N and N m, inputs) of the
        fitted model on a track."""

    def signature_columns(self, motion, inputs, track, seeds=None) -> dict:
        """{effect name: [(n, 3) columns]}: the force-space shape each effect of the catalogue
        leaves in the missing forces (for the sparse-regression support); ``seeds`` from the
        diagnosis (e.g. a wave frequency)."""

    def where_samples(self, track, ctx, S) -> dict:
        """Extra per-sample region variables of the *where* analysis (may be empty)."""

    def regions(self) -> dict:
        """{region variable: bin edges} of the *where* analysis."""


class ParameterLayout:
    """The parameter vector both families share: ``[theta_free (n_theta), q_1, ..., q_E]`` with
    ``q_e`` the parameters of effect ``e`` (in the units of their names). A subclass sets
    ``theta0``, ``n_theta``, ``n_q``, ``effects`` and ``vehicle``."""

    @property
    def n_params(self) -> int:
        """Length of the parameter vector."""
        return self.n_theta + sum(self.n_q)

    def start(self, theta=None) -> np.ndarray:
        """(n_params,) start of a fit: ``theta`` (default ``theta0``) and each effect's
        :meth:`~bayesid.models.effects.Effect.start_values` for this vehicle."""
        th = self.theta0 if theta is None else np.asarray(theta, float)
        return np.concatenate([th] + [e.start_values(self.vehicle) for e in self.effects])

    def split_params(self, P):
        """(B, n_params) parameter vectors -> (theta (B, n_theta) free coefficients, [q_e (B,
        n_q_e) per effect, in the model's effect order])."""
        P = np.atleast_2d(np.asarray(P, float))
        th = P[:, : self.n_theta]
        qs, i = [], self.n_theta
        for n in self.n_q:
            qs.append(P[:, i : i + n])
            i += n
        return th, qs
