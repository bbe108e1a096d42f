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

    The parameter vector is ``[theta_free (n_theta), q_1, ..., q_E]``: the free coefficients,
    then the parameters of each effect. A protocol is not instantiated: each family has its own
    constructor and ``for_vehicle`` class method (:func:`bayesid.models.build_model`).

    Attributes
    ----------
    vehicle : object
        The vessel description it was built from (nominal coefficients).
    free : list of str
        The coefficient names the fits change (SNAME or MMG names).
    effects : list of Effect
        The :class:`bayesid.models.effects.Effect` objects, in parameter order.
    param_names : list of str
        ``free + ["effect.param", ...]``, the names of the parameter vector.
    n_theta : int
        Number of free coefficients.
    n_q : list of int
        Number of parameters of each effect.
    n_params : int
        Length of the parameter vector.
    n_nuisance : int
        Number of per-track parameters (e.g. a wave phase), passed separately to
        :meth:`simulate`.
    theta0 : ndarray, shape (n_theta,)
        Nominal values of the free coefficients.
    dt : float
        Model step, s.
    mode : str
        ``"horizontal"`` or ``"6dof"``.
    inputs : str, optional
        How its track contexts reconstruct the logged inputs between samples, ``"hold"``,
        ``"linear"`` or ``"rate"`` (set by :func:`bayesid.models.build_model`; a model without it
        holds them).
    rudder_rate_deg_s : float, optional
        The control surfaces' gear rate (deg/s) of ``inputs`` ``"rate"``.
    DEFAULT_DT : float
        Class level, the vessel family's: model step (s) when the user gives none.
    DEFAULT_WEIGHTING : str
        Class level: channel weighting of its fits (``"noise"`` or ``"residual"``,
        :func:`bayesid.estimation.windows.fit_weighted`).
    CATALOGUE : dict
        Class level: ``{name: Effect}``, the candidate effects of the gap diagnosis.
    SURGE_FROM_POSITIONS : bool, optional
        Class level: where the speed u is not logged, a miss of the speed over ground read from the
        positions routes structure discovery into the surge equation X
        (:func:`bayesid.analysis.gap.discovery.routed`); absent: it does not.

    Methods
    -------
    default_fit_window(scoring_window_s)
        Class level: fit window (s) of the training fits when the protocol scores over
        ``scoring_window_s``.
    default_free(vehicle)
        Class level: the default free list of a vehicle.
    default_dt(vehicle)
        Optional, class level: the model step (s) of a vehicle when the user gives none
        (:func:`bayesid.models.default_dt`; absent: ``DEFAULT_DT``).
    effect_unsupported(effect, vehicle)
        Optional, class level: why the vehicle cannot carry a catalogue effect (a sentence), or
        None; the default catalogue leaves such an effect out
        (:func:`bayesid.analysis.gap.diagnose.catalogue_candidates`).
    gear_rate_deg_s(vehicle)
        Optional, class level: the steering gear's rate its vehicle file gives (deg/s), or None.
    check_free(vehicle, names, option)
        Class level: raise KeyError naming ``option`` and an unknown coefficient of ``names``.
    get_effect(name)
        Class level: a catalogue effect by name; ValueError naming an unknown one.
    prepare(ctx, P, nuisance=None)
        Optional: the part of :meth:`simulate` that does not depend on the start states, a
        :class:`bayesid.models.context.Prepared` that :meth:`simulate` then takes as
        ``prepared=`` (the start fits simulate the same rows from many start states,
        :func:`bayesid.estimation.shooting.fit_starts`); absent: every simulation prepares anew.
    term_library()
        Optional: the family's candidate model terms for structure discovery, a
        :class:`bayesid.models.library.TermLibrary` bound to the model's vehicle (the prime-form
        products discovery may add in X, Y and N, and how each is written into a vehicle file); a
        family without it is refused by discovery with
        :class:`~bayesid.models.library.NoTermLibraryError`, never searched in another family's
        terms.
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
        """Start of a fit: ``theta`` and the effects' starts.

        Parameters
        ----------
        theta : array_like, shape (n_theta,), optional
            Free coefficients; default ``theta0``.

        Returns
        -------
        ndarray, shape (n_params,)
            The parameter vector.
        """

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the parameter vector.

        Returns
        -------
        lo, hi : ndarray, shape (n_params,)
            Lower and upper bounds (+-inf where unbounded).
        """

    def scales(self) -> np.ndarray:
        """Typical sizes of the parameters (fit scaling, finite-difference steps).

        Returns
        -------
        ndarray, shape (n_params,)
            The typical sizes, in the parameters' units.
        """

    def split_params(self, P) -> tuple[np.ndarray, list]:
        """Split parameter vectors into the free coefficients and the effects' parameters.

        Parameters
        ----------
        P : array_like, shape (B, n_params)
            Parameter vectors.

        Returns
        -------
        theta : ndarray, shape (B, n_theta)
            The free coefficients.
        qs : list of ndarray
            ``q_e`` of shape (B, n_q_e) per effect.
        """

    def context(
        self, track, window_s=None, span_s: float = 1.0, s0=None, start: str = "measured", leadin_s: float = 0.0
    ):
        """A track prepared for simulation: step inputs, protocol windows, window-start states.

        Parameters
        ----------
        track : Track
            The track.
        window_s : float, optional
            Protocol window, s; None is one window over the whole run.
        span_s : float, default 1.0
            Span of the measured start-state estimate, s (:func:`bayesid.protocol.state_at`).
        s0 : array_like, shape (12,), optional
            The state at the first sample, replacing the estimated start state.
        start : {"measured", "fitted"}, default "measured"
            The (resolved) start rule of the window-start states.
        leadin_s : float, default 0.0
            Lead-in of the fitted start rule, s.

        Returns
        -------
        TrackContext
            The prepared track (:class:`bayesid.models.context.TrackContext`).
        """

    def simulate(
        self, ctx, P, nuisance=None, measured_start: bool = True, starts=None, samples: str = "scored"
    ) -> np.ndarray:
        """Predicted measurements of parameter vectors on a prepared track.

        Parameters
        ----------
        ctx : TrackContext
            The prepared track (:meth:`context`).
        P : array_like, shape (B, n_params)
            Parameter vectors.
        nuisance : array_like, shape (B, n_nuisance), optional
            Per-track parameters of this track (default zeros).
        measured_start : bool, default True
            The window-start states are measurements, mapped through the effects' sensor models
            (False: they are model states already).
        starts : array_like, shape (B, W, 6), optional
            Start-state offsets of the fitted start rule, one row per window.
        samples : {"scored", "lead"}, default "scored"
            The scored samples or the lead-in samples that estimate the start states.

        Returns
        -------
        ndarray, shape (B, n_samples, 12)
            Predicted measurements (STATE_NAMES order, NaN in a diverged window).
        """

    def seed(self, tracks):
        """An equation-error start of the fit.

        Parameters
        ----------
        tracks : list of Track
            The training tracks.

        Returns
        -------
        tuple or None
            ``(p, summary)``: the start ``p`` (n_params,) and a summary dict; None when the
            family has no seed.
        """

    def missing_forces(self, fitres, track):
        """Inverse dynamics of the fitted model on a track: the forces it misses.

        Parameters
        ----------
        fitres : FitResult
            A fit of this model.
        track : Track
            The track.

        Returns
        -------
        motion : dict
            The smoothed measured motion (``t``, ``u``, ``v``, ``r``, ...).
        F : ndarray, shape (n, 3)
            Missing X, Y (N) and N (N m) at the motion's samples.
        inputs : ndarray
            The logged inputs at the track's samples, one column per input.
        """

    def signature_columns(self, motion, inputs, track, seeds=None) -> dict:
        """The force-space shape each effect of the catalogue leaves in the missing forces (for
        the sparse-regression support).

        Parameters
        ----------
        motion : dict
            The smoothed motion of :meth:`missing_forces`.
        inputs : ndarray
            The logged inputs of :meth:`missing_forces`.
        track : Track
            The track.
        seeds : dict, optional
            Seeds of the diagnosis (e.g. a wave frequency).

        Returns
        -------
        dict
            ``{effect name: [columns (n, 3)]}``.
        """

    def where_samples(self, track, ctx, S) -> dict:
        """Extra per-sample region variables of the *where* analysis (may be empty).

        Parameters
        ----------
        track : Track
            The track.
        ctx : TrackContext
            The prepared track.
        S : ndarray, shape (B, n_samples, 12)
            Predicted states of :meth:`simulate`.

        Returns
        -------
        dict
            ``{region variable: values (n_samples,)}``.
        """

    def regions(self) -> dict:
        """Bins of the *where* analysis.

        Returns
        -------
        dict
            ``{region variable: bin edges}``.
        """


class ParameterLayout:
    """The parameter vector both families share: ``[theta_free (n_theta), q_1, ..., q_E]`` with
    ``q_e`` the parameters of effect ``e`` (in the units of their names).

    A mixin without a constructor: a subclass sets ``theta0``, ``n_theta``, ``n_q``, ``effects``
    and ``vehicle``.
    """

    @property
    def n_params(self) -> int:
        """Length of the parameter vector."""
        return self.n_theta + sum(self.n_q)

    def start(self, theta=None) -> np.ndarray:
        """Start of a fit: ``theta`` and each effect's
        :meth:`~bayesid.models.effects.Effect.start_values` for this vehicle.

        Parameters
        ----------
        theta : array_like, shape (n_theta,), optional
            Free coefficients; default ``theta0``.

        Returns
        -------
        ndarray, shape (n_params,)
            The parameter vector.
        """
        th = self.theta0 if theta is None else np.asarray(theta, float)
        return np.concatenate([th] + [e.start_values(self.vehicle) for e in self.effects])

    def split_params(self, P):
        """Split parameter vectors into the free coefficients and the effects' parameters.

        Parameters
        ----------
        P : array_like, shape (B, n_params) or (n_params,)
            Parameter vectors.

        Returns
        -------
        theta : ndarray, shape (B, n_theta)
            The free coefficients.
        qs : list of ndarray
            ``q_e`` of shape (B, n_q_e) per effect, in the model's effect order.
        """
        P = np.atleast_2d(np.asarray(P, float))
        th = P[:, : self.n_theta]
        qs, i = [], self.n_theta
        for n in self.n_q:
            qs.append(P[:, i : i + n])
            i += n
        return th, qs
