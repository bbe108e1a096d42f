"""Fits of a simulation model to tracks under the window protocol: multiple shooting.

The objective (:class:`WindowObjective`) is the simulation error over the protocol windows of
every track (:mod:`bayesid.protocol`), each window restarting from its measured state or from a
start state fitted with the parameters (:mod:`bayesid.estimation.shooting`), every scored channel divided
by its noise sd (heading difference wrapped):

    V(x) = sum_tracks sum_windows sum_samples sum_channels ((prediction - measurement) / sd)^2

The model is anything that implements :class:`bayesid.models.interface.SimulationModel`
(submarine :class:`~bayesid.models.submarine.EffectModel`, ship :class:`~bayesid.models.ship.ShipModel`). The
same objective serves the identification of long runs (:mod:`bayesid.estimation.identification`), every model of the
gap diagnosis (:mod:`bayesid.analysis.gap`) and the studies; :func:`fit_model` minimises it with the one
fit function (:func:`bayesid.estimation.fit.fit`) and returns its :class:`FitResult`. Also here:
the held-out nuisances, the two-step channel weighting (:func:`fit_weighted`), protocol scores of
a fitted model (:class:`Evaluation`: :func:`evaluate`, :func:`scores`, :func:`window_rms`), the pooled noise sds and the data check.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..models import context as ctxmod
from ..protocol import CHANNELS, Scores, estimate_noise, pooled_scores
from . import shooting
from .fit import FitResult, SolverOptions, fit
from .shooting import PENALTY

__all__ = [
    "WindowObjective",
    "GaussianPrior",
    "fit_model",
    "fit_weighted",
    "heldout_nuisance",
    "residual_sd",
    "scores",
    "window_rms",
    "Evaluation",
    "evaluate",
    "window_starts",
    "WindowProblem",
    "contexts",
    "START_Z",
    "warm_starts",
    "window_residuals",
    "channel_weights",
    "check_channels",
    "pooled_noise_sd",
    "check_enough_data",
    "MIN_SAMPLES_PER_PARAMETER",
    "PENALTY",
]


def channel_weights(ctx, sd, channels=None):
    """Weights of the channels of a track in the objective.

    Parameters
    ----------
    ctx : TrackContext
        The prepared track (its measured ``channels``).
    sd : dict
        ``{channel: sd}``, SI.
    channels : sequence of str, optional
        The scored channels; None: all the track measures.

    Returns
    -------
    dict
        ``{channel: 1/sd}``.

    Raises
    ------
    ValueError
        When the track measures none of ``channels``.
    """
    cs = [c for c in ctx.channels if channels is None or c in channels]
    if not cs:
        raise ValueError(
            f"track {ctx.name!r} measures none of the fitted channels {', '.join(channels)} "
            f"(it has {', '.join(ctx.channels)})"
        )
    return {c: 1.0 / sd[c] for c in cs}


def check_channels(channels):
    """Check a list of fit channels.

    Parameters
    ----------
    channels : sequence of str or None
        The channels.

    Returns
    -------
    tuple of str or None
        ``channels`` as a tuple (None stays None).

    Raises
    ------
    ValueError
        Naming a channel the protocol does not score (:data:`bayesid.protocol.CHANNELS`), or
        for an empty list.
    """
    if channels is None:
        return None
    channels = tuple(channels)
    bad = [c for c in channels if c not in CHANNELS]
    if bad or not channels:
        raise ValueError(
            f"unknown fit channel(s) {', '.join(bad) or '(none given)'}; choose from {', '.join(CHANNELS)}"
        )
    return channels


def window_residuals(model, ctxs, wts, P, nus, starts=None) -> tuple[np.ndarray, np.ndarray]:
    """Noise-scaled residuals over all tracks, and which rows diverged.

    Parameters
    ----------
    model : SimulationModel
        The model.
    ctxs : list of TrackContext
        The prepared tracks.
    wts : list of dict
        Per track ``{channel: 1 / sd}`` of the scored channels.
    P : ndarray, shape (B, n_params)
        Parameter rows.
    nus : list
        Per track the (B, n_nuisance) nuisances or None.
    starts : list or None
        Per track the (B, W, 6) start offsets of the fitted start rule (None: the measured rule).

    Returns
    -------
    R : ndarray, shape (B, n_res)
        The residuals; a sample of a diverged window holds :data:`PENALTY` (so an optimiser sees
        a large finite value).
    diverged : ndarray of bool, shape (B,)
        The rows with a diverged window (the one divergence flag).
    """
    out = []
    diverged = np.zeros(np.atleast_2d(P).shape[0], dtype=bool)
    for i, (ctx, w, nu) in enumerate(zip(ctxs, wts, nus)):
        S = model.simulate(ctx, P, nu, starts=None if starts is None else starts[i])
        for c, e in ctxmod.errors(ctx, S).items():
            if c not in w:
                continue
            r = e * w[c]
            bad = ~np.isfinite(r)
            diverged |= bad.any(axis=1)
            r[bad] = PENALTY
            out.append(r)
    return np.concatenate(out, axis=1), diverged


def _state_copy(state: dict) -> dict:
    """A copy of a :class:`WindowObjective`'s evaluation state whose per-track lists are its own."""
    return {k: list(v) if isinstance(v, list) else v for k, v in state.items()}


class WindowObjective:
    """The multiple-shooting objective of a model on tracks (module docstring), in the variables
    ``x = [p (n_params), nuisance_1, ..., nuisance_T]`` (only the nuisances when the parameters
    are held: ``fit_nuisance_only``), with the protocol of :mod:`bayesid.estimation.fit`.

    Contexts with the fitted start rule have their window start states estimated with the
    parameters (6 per window, counted in the result's ``k``), eliminated by variable
    projection: every evaluation fits them for its parameters (so :meth:`residuals` keeps state:
    ``cache_residuals`` is False); the Jacobian holds them at that optimum and projects their
    directions out window by window (Kaufman 1975), or, where they come from a lead-in rather
    than the fitted samples themselves, re-fits them for every perturbed vector.

    The solver takes a Jacobian only at the points it accepts, and the objective keeps the start
    states of the last such point. Every evaluation is warm-started from them, not from the trial
    evaluated last: a rejected trial's start states, read as the next trial's first guess, made
    trust-region fits of a REMUS 100 at 5 s windows stop after one iteration at 29 x the cost
    they reach this way (issue 69). :meth:`accepted_residuals` gives back what the solver saw at
    its optimum, so a fit's reported cost and ``window_starts`` are those of that point.

    Parameters
    ----------
    model : SimulationModel
        A :class:`~bayesid.models.interface.SimulationModel`.
    ctxs : list of TrackContext
        Its track contexts (``model.context``).
    sd : dict
        ``{channel: noise sd}`` of the weights, SI.
    p0 : array_like, shape (n_params,), optional
        Start (default ``model.start()``).
    nuisance0 : list of array_like, optional
        Per track, the (n_nuisance,) start of the nuisances (default zeros).
    fit_nuisance_only : bool, default False
        Hold ``p0`` and fit only the per-track nuisances (held-out tracks).
    channels : sequence of str, optional
        The scored channels in the objective (None: all the tracks measure); the others still
        give the window start states.
    prior : GaussianPrior, optional
        Priors whose residuals follow the data's (a MAP fit); ignored with
        ``fit_nuisance_only`` or when it has no parameter.

    Raises
    ------
    ValueError
        For an unknown channel or a track that measures none of ``channels``.
    """

    cache_residuals = False
    sim_seconds = float("nan")

    def __init__(
        self,
        model,
        ctxs,
        sd: dict,
        p0=None,
        nuisance0=None,
        fit_nuisance_only: bool = False,
        channels=None,
        prior: GaussianPrior | None = None,
    ):
        self.model, self.ctxs = model, list(ctxs)
        self.prior = prior if prior is not None and not fit_nuisance_only and prior.idx.size else None
        self.p0 = model.start() if p0 is None else np.asarray(p0, float)
        nn = self.nn = model.n_nuisance
        T = self.T = len(self.ctxs)
        self.nu0 = [np.zeros(nn) for _ in range(T)] if nuisance0 is None else [np.asarray(v, float) for v in nuisance0]
        lo, hi = model.bounds()
        sc = model.scales()
        nlo = np.concatenate([np.full(e.n_nuisance, e.nuisance_lo) for e in model.effects] or [np.zeros(0)])
        nhi = np.concatenate([np.full(e.n_nuisance, e.nuisance_hi) for e in model.effects] or [np.zeros(0)])
        self.free_p = free_p = not fit_nuisance_only
        self.channels = check_channels(channels)
        self.wts = [channel_weights(c, sd, self.channels) for c in self.ctxs]
        x0 = np.concatenate(([self.p0] if free_p else []) + self.nu0) if (free_p or nn) else self.p0
        self.lo = np.concatenate(([lo] if free_p else []) + [nlo] * T)
        self.hi = np.concatenate(([hi] if free_p else []) + [nhi] * T)
        self.x_scale = np.concatenate(([sc] if free_p else []) + [np.ones(nn)] * T)
        fin = np.isfinite(self.lo) & np.isfinite(self.hi)
        span = np.where(fin, self.hi - self.lo, 0.0)
        self.x0 = np.where(
            fin, np.clip(x0, np.where(fin, self.lo, 0.0) + 1e-9 * span, np.where(fin, self.hi, 0.0) - 1e-9 * span), x0
        )
        pn = list(model.param_names) if free_p else []
        self.names = pn + [
            f"track{i}.{n}"
            for i in range(T)
            for e in model.effects
            for n in [f"{e.name}.nuisance{j}" for j in range(e.n_nuisance)]
        ]
        self.n_simulations = 0
        self.vp = any(c.start == "fitted" for c in self.ctxs)
        self.n_starts = sum(6 * c.W for c in self.ctxs if c.start == "fitted")
        self.lead_in = any(c.start == "fitted" and c.lead_steps > 0 for c in self.ctxs)
        self._last = {"x": None, "starts": [None] * T, "jd": [None] * T, "r": None}
        self._accepted = None  # a copy of ``_last`` at the last point whose Jacobian was taken

    def warm_start(self, starts) -> None:
        """Start the window start-state fits from given offsets instead of the measured guess.

        Parameters
        ----------
        starts : list
            Per track (W, 6) offsets, or None (cold for that track): a previous fit's
            ``window_starts`` on the same windows.

        Raises
        ------
        ValueError
            A track's offsets whose shape is not its context's (W, 6) (track named).
        """
        if len(starts) != self.T:
            raise ValueError(f"warm start for {len(starts)} tracks, the objective has {self.T}")
        self._accepted = None  # the given offsets, not an earlier fit's, start the next evaluation
        for i, (ctx, s) in enumerate(zip(self.ctxs, starts)):
            if s is None or ctx.start != "fitted":
                continue
            s = np.asarray(s, float)
            if s.shape != (ctx.W, 6):
                raise ValueError(
                    f"track {ctx.name!r}: warm-start offsets of shape {s.shape}, its windows need ({ctx.W}, 6)"
                )
            self._last["starts"][i] = s[None]

    def split_rows(self, X):
        """Split rows of the objective's variables into parameters and nuisances.

        Parameters
        ----------
        X : ndarray, shape (B, n)
            Variables.

        Returns
        -------
        P : ndarray, shape (B, n_params)
            Parameter rows (``p0`` repeated when only the nuisances are fitted).
        nuisances : list
            Per track the (B, n_nuisance) nuisances, or None without nuisances.
        """
        nn, T = self.nn, self.T
        P = X[:, : self.model.n_params] if self.free_p else np.repeat(self.p0[None], X.shape[0], 0)
        off = self.model.n_params if self.free_p else 0
        return P, [X[:, off + i * nn : off + (i + 1) * nn] if nn else None for i in range(T)]

    def _fit_starts(self, P, nus, want_jac=False):
        out = []
        for i, ctx in enumerate(self.ctxs):
            if ctx.start != "fitted":
                out.append(None)
                continue
            s0 = (self._last if self._accepted is None else self._accepted)["starts"][i]
            s0 = None if s0 is None else np.repeat(s0[:1], P.shape[0], axis=0)
            res = shooting.fit_starts(self.model, ctx, P, nus[i], self.wts[i], starts0=s0, return_jacobian=want_jac)
            if want_jac:
                d, J, rwin = res
                self._last["jd"][i] = (J[:, 0].T, rwin)
                out.append(d)
            else:
                out.append(res)
        return out

    def residuals_batch(self, X, starts=None):
        """Residuals of rows of variables. Fitted start states are fitted for each row unless
        ``starts`` holds them.

        Parameters
        ----------
        X : array_like, shape (B, n)
            Variables.
        starts : list, optional
            Per track the (B, W, 6) start offsets, or None for a track with the measured rule.

        Returns
        -------
        R : ndarray, shape (B, n_res)
            The residuals (a diverged window's samples hold :data:`PENALTY`), the prior's last.
        diverged : ndarray of bool, shape (B,)
            The rows with a diverged window.
        """
        X = np.atleast_2d(X)
        self.n_simulations += X.shape[0]
        P, nus = self.split_rows(X)
        if self.vp and starts is None:
            starts = self._fit_starts(P, nus)
        R, diverged = window_residuals(self.model, self.ctxs, self.wts, P, nus, starts)
        return self._with_prior(R, P), diverged

    def _with_prior(self, R, P):
        """The data residuals followed by the prior's (:class:`GaussianPrior`), when there is one."""
        return R if self.prior is None else np.hstack([R, self.prior.residuals(P)])

    def residuals(self, x):
        """Residuals at one vector of variables (fitted start states warm-started and remembered
        for the Jacobian).

        Parameters
        ----------
        x : ndarray, shape (n,)
            Variables.

        Returns
        -------
        r : ndarray, shape (n_res,)
            The residuals.
        diverged : bool
            False: divergence is penalised, not flagged.
        """
        if not self.vp:
            return self.residuals_batch(x)[0][0], False
        P, nus = self.split_rows(x[None])
        st = self._fit_starts(P, nus, want_jac=True)
        r = self._with_prior(window_residuals(self.model, self.ctxs, self.wts, P, nus, st)[0], P)[0]
        self._last.update(x=x.copy(), starts=st, r=r)
        return r, False

    def accepted_residuals(self, x):
        """The residuals of the last accepted point (the last whose Jacobian was taken) as the
        solver saw them, with its start states made current again, when ``x`` is that point;
        else None. A caller that changed the contexts since (a retiming) evaluates anew with
        :meth:`residuals`.

        Parameters
        ----------
        x : ndarray, shape (n,)
            Variables.

        Returns
        -------
        ndarray, shape (n_res,), or None
            The residuals the solver saw at ``x``, or None when ``x`` is not the accepted point.
        """
        acc = self._accepted
        if acc is None or not np.array_equal(acc["x"], x):
            return None
        self._last = _state_copy(acc)
        return acc["r"].copy()

    def jacobian(self, x, r0=None):
        """Residuals and forward-difference Jacobian from one batched simulation of n + 1 vectors
        (steps ``1e-6 x_scale``, backwards at an upper bound).

        Parameters
        ----------
        x : ndarray, shape (n,)
            Variables.
        r0 : ndarray, optional
            Not used (the base row is simulated with the perturbed ones).

        Returns
        -------
        r : ndarray, shape (n_res,)
            The residuals at ``x``.
        J : ndarray, shape (n_res, n)
            The Jacobian (fitted start states projected out, or re-fitted under a lead-in).
        """
        xsc, xhi = self.x_scale, self.hi
        h = 1e-6 * np.maximum(xsc, 1e-8)
        sign = np.where(x + h > xhi, -1.0, 1.0)
        X = np.repeat(x[None], x.size + 1, axis=0)
        X[1:] += np.diag(sign * h)
        if not self.vp:
            R = self.residuals_batch(X)[0]
            return R[0], ((R[1:] - R[0]) / (sign * h)[:, None]).T
        if self._last["x"] is None or not np.array_equal(self._last["x"], x):
            self.residuals(x)
        self._accepted = _state_copy(self._last)
        held = (
            None
            if self.lead_in
            else [None if d is None else np.repeat(d, X.shape[0], axis=0) for d in self._last["starts"]]
        )
        R = self.residuals_batch(X, held)[0]
        J = ((R[1:] - R[0]) / (sign * h)[:, None]).T
        if self.lead_in:
            return R[0], J
        r0 = 0
        for i, ctx in enumerate(self.ctxs):
            n_i = sum(ctx.meas[c].size for c in ctx.channels if c in self.wts[i])
            if ctx.start == "fitted":
                Jd, rwin = self._last["jd"][i]
                J[r0 : r0 + n_i] = shooting.project_out(J[r0 : r0 + n_i], Jd, rwin, ctx.W)
            r0 += n_i
        return R[0], J

    def result_fields(self, x) -> dict:
        """The fit result's fields at ``x``.

        Parameters
        ----------
        x : array_like, shape (n,)
            Variables.

        Returns
        -------
        dict
            ``model``, ``p``, per-track ``nuisance``, ``channels``, ``n_starts`` and ``k``
            (parameters, nuisances and window start states).
        """
        x = np.asarray(x, float)
        P, nus = self.split_rows(x[None])
        nuisance = [np.array(v[0]) if v is not None else np.zeros(0) for v in nus]
        starts = None
        if self.vp and x.size:  # the start states at x (the last evaluation's, or fitted now)
            if self._last["x"] is None or not np.array_equal(self._last["x"], x):
                self.residuals(x)
            starts = [None if s is None else np.array(s[0]) for s in self._last["starts"]]
        return {
            "model": self.model,
            "p": np.array(P[0]),
            "nuisance": nuisance,
            "channels": self.channels,
            "n_starts": self.n_starts,
            "k": self.model.n_params + sum(len(v) for v in nuisance) + self.n_starts,
            "window_starts": starts,
        }


@dataclass(frozen=True)
class GaussianPrior:
    """Independent Gaussian priors on some parameters of a model, as least-squares residuals
    ``weight * (p[idx] - mean) / sd`` appended to a fit's data residuals: the fit then minimises
    ``SSR + weight^2 * sum(z^2)``, the negative log posterior times ``2 * weight^2`` when the data
    residuals have variance ``weight^2`` (the residual variance times the serial-correlation
    inflation of the fit, :func:`bayesid.estimation.identification.identify`).

    Parameters
    ----------
    names : tuple of str
        The K parameter names.
    idx : ndarray of int, shape (K,)
        Their indices in the model's parameter vector.
    mean : ndarray, shape (K,)
        Prior means.
    sd : ndarray, shape (K,)
        Prior standard deviations.
    weight : float, default 1.0
        Residual sd of the data.
    """

    names: tuple
    idx: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    weight: float = 1.0

    @classmethod
    def of_model(cls, model, weight: float = 1.0) -> GaussianPrior:
        """The priors of the model's vehicle file (``vehicle.prior``, the ``[prior]`` section) on
        the model's free parameters (effect parameters have none).

        Parameters
        ----------
        model : SimulationModel
            The model.
        weight : float, default 1.0
            Residual sd of the data.

        Returns
        -------
        GaussianPrior
            The priors (none when the file has no ``[prior]`` section).
        """
        pri = getattr(model.vehicle, "prior", {}) or {}
        names = [n for n in model.param_names if n in pri]
        idx = np.array([model.param_names.index(n) for n in names], dtype=int)
        return cls(
            tuple(names),
            idx,
            np.array([pri[n][0] for n in names], float),
            np.array([pri[n][1] for n in names], float),
            float(weight),
        )

    def residuals(self, P) -> np.ndarray:
        """Prior residuals of parameter rows.

        Parameters
        ----------
        P : array_like, shape (B, n_params)
            Parameter rows.

        Returns
        -------
        ndarray, shape (B, K)
            ``weight * (p[idx] - mean) / sd``.
        """
        return self.weight * (np.atleast_2d(P)[:, self.idx] - self.mean) / self.sd

    def precision(self, n_params: int) -> np.ndarray:
        """Prior precision of the parameter vector.

        Parameters
        ----------
        n_params : int
            Length of the parameter vector.

        Returns
        -------
        ndarray, shape (n_params,)
            ``1 / sd^2`` (0 where a parameter has no Gaussian prior).
        """
        out = np.zeros(n_params)
        out[self.idx] = 1.0 / self.sd**2
        return out


@dataclass(frozen=True)
class WindowProblem:
    """One model on the protocol windows of a set of tracks: what a fit minimises, what a
    multistart fits from every start, what each fold of a calibration refits, and what every
    model of the gap diagnosis is scored on. Its two verbs are :meth:`fit` (the parameters that
    minimise the window objective) and :meth:`evaluate` (one simulation of a parameter vector over
    every window, :class:`Evaluation`). The contexts carry the windows and the start rule
    (:func:`contexts` builds them, :meth:`start_consistency` checks fitted starts).

    Parameters
    ----------
    model : SimulationModel
        The model.
    ctxs : list of TrackContext
        The contexts of the tracks (windows and start rule).
    sd : dict
        ``{channel: sd}``, the channel weights (SI).
    channels : tuple of str, optional
        The scored channels (None: every measured one).
    max_nfev : int, default 60
        Least-squares iterations of each fit.
    prior : GaussianPrior, optional
        :class:`GaussianPrior` of a MAP fit.
    data_scale : tuple, optional
        ``(residual variance, AR(1) inflation)`` of the fit without the prior
        for its covariance (:func:`bayesid.estimation.laplace.fit_covariance`).
    """

    model: object
    ctxs: list
    sd: dict
    channels: tuple | None = None
    max_nfev: int = 60
    prior: object = None
    data_scale: tuple | None = None

    def fit(self, p0=None, nuisance0=None, **options) -> FitResult:
        """:func:`fit_model` of this problem.

        Parameters
        ----------
        p0 : array_like, shape (n_params,), optional
            The start (default ``model.start()``).
        nuisance0 : list of array_like, optional
            Per track, the (n_nuisance,) start of the nuisances.
        **options
            ``fit_nuisance_only``, ``bar``, ``starts0`` of :func:`fit_model`.

        Returns
        -------
        FitResult
            As :func:`fit_model` (it raises the same errors).
        """
        return fit_model(self, p0, nuisance0, **options)

    def evaluate(self, p, nuisance=None) -> Evaluation:
        """:func:`evaluate` of a parameter vector on this problem's tracks.

        Parameters
        ----------
        p : array_like, shape (n_params,)
            The parameter vector.
        nuisance : list of ndarray, optional
            Per track, the (n_nuisance,) nuisances.

        Returns
        -------
        Evaluation
            The one simulation of ``p`` over every window.
        """
        return evaluate(self.model, p, self.ctxs, nuisance)

    def start_consistency(self, p, tracks, label: str = "") -> list:
        """Each fitted window start of ``p`` against the track's own kinematics
        (:func:`bayesid.estimation.shooting.start_consistency` on this problem's contexts, the
        problem's ``sd`` as the start fit's weights and the kinematic noise); a start more than
        :data:`START_Z` sd away is one the vessel did not have.

        Parameters
        ----------
        p : array_like, shape (n_params,)
            The parameter vector.
        tracks : list of Track
            The tracks, parallel to the contexts.
        label : str, default ""
            Names the track set in the rows.

        Returns
        -------
        list of dict
            Per window of a fitted-start context: ``set``, ``track``, ``t_s``, ``component``,
            ``fitted``, ``kinematic``, ``sd`` and ``z``.
        """
        return shooting.start_consistency(self.model, p, tracks, self.ctxs, self.sd, label)


# the former name of WindowProblem (bayesid.FitProblem warns and gives WindowProblem)
FitProblem = WindowProblem

#: |z| of a fitted window start against the track's own kinematics above which the start is
#: flagged (:meth:`WindowProblem.start_consistency`): at 5 sd a right model on Gaussian noise flags
#: about one start component in a million.
START_Z = 5.0


def contexts(
    model, tracks, window_s, start: str, *, leadin_s: float | None = 0.0, held_starts: bool = False, kinematic_sd=None
) -> list:
    """The contexts of a window problem: each track's windows and window starts under a start rule.

    Parameters
    ----------
    model : SimulationModel
        The model.
    tracks : list of Track
        The tracks.
    window_s : float or None
        The window, s (None: one window per track).
    start : str
        The start rule (:data:`bayesid.protocol.START_RULES`).
    leadin_s : float or None, default 0.0
        The lead-in of the fitted rule, s.
    held_starts : bool, default False
        Under the fitted rule, hold the window starts at the tracks' own kinematics
        (:func:`bayesid.estimation.shooting.kinematic_contexts`, a training fit's alternative to
        fitting them; the lead-in is then not used).
    kinematic_sd : dict, optional
        ``{channel: noise sd}`` (SI) of x, y, psi, for ``held_starts``.

    Returns
    -------
    list of TrackContext
        One per track.

    Raises
    ------
    ValueError
        ``held_starts`` without ``kinematic_sd``; a track the model cannot prepare (as
        ``model.context`` raises).
    """
    if start == "fitted" and held_starts:
        if kinematic_sd is None:
            raise ValueError("window starts held at the kinematics need kinematic_sd (the noise sds of x, y, psi)")
        return shooting.kinematic_contexts(model, tracks, window_s, kinematic_sd)
    return [model.context(t, window_s, start=start, leadin_s=leadin_s) for t in tracks]


def warm_starts(fit, ctxs) -> list | None:
    """A fit's window start offsets when they fit ``ctxs``'s windows (same tracks, same windows),
    else None: a model evaluated at another fit's parameters with cold start states can land in
    another optimum of the start-state problem (a base fit bent to follow its tracks: cost 8.6e7
    cold against 1.9e4 at the fit's own starts, sim_to_real's constant-yaw-moment case).

    Parameters
    ----------
    fit : FitResult
        The fit whose ``window_starts`` are carried over.
    ctxs : list
        The contexts of the new fit.

    Returns
    -------
    list or None
        Per track, None (measured starts) or the (W, 6) fitted start offsets; None when they do
        not fit ``ctxs``.
    """
    starts = getattr(fit, "window_starts", None)
    if starts is None or len(starts) != len(ctxs):
        return None
    for s, c in zip(starts, ctxs):
        if (s is None) != (c.start != "fitted") or (s is not None and np.shape(s) != (c.W, 6)):
            return None
    return starts


def fit_model(
    problem: WindowProblem,
    p0=None,
    nuisance0=None,
    *,
    fit_nuisance_only: bool = False,
    bar: str | None = None,
    starts0=None,
) -> FitResult:
    """Least-squares fit of a model's parameters (and per-track nuisances) to tracks: the
    :class:`WindowObjective` minimised by :func:`bayesid.estimation.fit.fit` (trust-region
    reflective, ``xtol = ftol = gtol = 1e-8``, variables scaled by ``model.scales()``, a
    forward-difference Jacobian computed in one batched simulation of all perturbed vectors).

    Parameters
    ----------
    problem : WindowProblem
        The model, its track contexts, the channel weights ``{channel: sd}``, the scored channels
        (None: all the tracks measure), the iterations and the :class:`GaussianPrior` whose
        residuals are appended to the data's (a MAP fit; None: none).
    p0 : array_like, shape (n_params,), optional
        The start (default ``model.start()``).
    nuisance0 : list of array_like, optional
        Per track, the (n_nuisance,) start of the nuisances.
    fit_nuisance_only : bool, default False
        Keep ``p0`` fixed and fit only the nuisances (held-out tracks).
    bar : str, optional
        A label to show a progress bar (tqdm, on stderr) of the evaluations with it.
    starts0 : list, optional
        Per track the (W, 6) window start offsets to warm-start from (a previous fit's
        ``window_starts`` on the same windows, :meth:`WindowObjective.warm_start`): a refit from
        another fit's optimum then starts at that fit's cost.

    Returns
    -------
    FitResult
        ``p``, ``nuisance``, ``cost`` the noise-scaled SSR, ``k``, ``bic``, ``n_simulations``,
        ``jac``, ``window_starts``.

    Raises
    ------
    ValueError
        An unknown channel or a track that measures none of the channels; ``starts0`` that do
        not fit the windows.
    """
    model, ctxs, sd, max_nfev = problem.model, problem.ctxs, problem.sd, problem.max_nfev
    ob = WindowObjective(model, ctxs, sd, p0, nuisance0, fit_nuisance_only, problem.channels, problem.prior)
    if starts0 is not None:
        ob.warm_start(starts0)
    if ob.x0.size == 0:
        r = ob.residuals(ob.x0)[0]
        res = FitResult(
            "none", [], ob.x0, float(r @ r), float(r @ r), True, "nothing to fit", n_simulations=1, n_residuals=r.size
        )
        for k, v in ob.result_fields(ob.x0).items():
            setattr(res, k, v)
        return res
    return fit(
        ob,
        ob.x0,
        (ob.lo, ob.hi),
        SolverOptions(max_nfev=max_nfev, ftol=1e-8, xtol=1e-8, gtol=1e-8, x_scale=ob.x_scale),
        bar=bar,
        quiet=True,
    )


def heldout_nuisance(model, fitres: FitResult, ctxs, sd: dict, n_grid: int = 8, max_nfev: int = 30) -> list:
    """Per-track nuisances (e.g. a wave phase) of tracks the fit did not see, with the fitted
    parameters held: each track starts from the best of ``n_grid`` values spread over the
    nuisance bounds (a phase has a local minimum every period), then :func:`fit_model` refines them.

    Parameters
    ----------
    model : SimulationModel
        The model.
    fitres : FitResult
        The fit (its ``p`` is held).
    ctxs : list of TrackContext
        The held-out tracks.
    sd : dict
        ``{channel: sd}``, the channel weights.
    n_grid : int, default 8
        Starting values per nuisance range.
    max_nfev : int, default 30
        Least-squares iterations of the refinement.

    Returns
    -------
    list of ndarray
        One (n_nuisance,) array per track.
    """
    lo = np.concatenate([np.full(e.n_nuisance, e.nuisance_lo) for e in model.effects])
    hi = np.concatenate([np.full(e.n_nuisance, e.nuisance_hi) for e in model.effects])
    grid = lo[None] + (np.arange(n_grid)[:, None] + 0.5) / n_grid * (hi - lo)[None]
    P = np.repeat(fitres.p[None], n_grid, axis=0)
    starts = []
    for ctx in ctxs:
        w = channel_weights(ctx, sd)
        st = [shooting.fit_starts(model, ctx, P, grid, w)] if ctx.start == "fitted" else None
        r = window_residuals(model, [ctx], [w], P, [grid], st)[0]
        starts.append(grid[int(np.argmin(np.sum(r * r, axis=1)))].copy())
    return fit_model(
        WindowProblem(model, ctxs, sd, max_nfev=max_nfev), fitres.p, starts, fit_nuisance_only=True
    ).nuisance


def residual_sd(model, fitres: FitResult, ctxs, floor: dict) -> dict:
    """Per-channel RMS of a fit's simulation residuals over the protocol windows of ``ctxs``
    (heading wrapped; diverged samples ignored), each at least ``floor[channel]``.

    Parameters
    ----------
    model : SimulationModel
        The model.
    fitres : FitResult
        The fit (``p`` and ``nuisance``).
    ctxs : list of TrackContext
        The tracks.
    floor : dict
        ``{channel: smallest sd}``, SI.

    Returns
    -------
    dict
        ``{channel: sd}`` in the channel's SI unit.

    Raises
    ------
    KeyError
        When ``floor`` lacks a scored channel.
    """
    acc = {}
    for i, ctx in enumerate(ctxs):
        nu = fitres.nuisance[i][None] if fitres.nuisance and len(fitres.nuisance[i]) else None
        S = shooting.simulate(model, ctx, fitres.p[None], nu)
        for c, e in ctxmod.errors(ctx, S).items():
            acc.setdefault(c, []).append(e[0][np.isfinite(e[0])])
    return {
        c: max(float(np.sqrt(np.mean(np.concatenate(v) ** 2))) if sum(x.size for x in v) else 0.0, floor[c])
        for c, v in acc.items()
    }


def fit_weighted(
    problem: WindowProblem,
    p0=None,
    nuisance0=None,
    *,
    weighting: str = "noise",
    bar: str | None = None,
) -> tuple[FitResult, dict]:
    """:func:`fit_model` with the channel weights chosen by ``weighting``.

    ``"noise"``: weights ``1/sd`` from the measurement noise (right when the model structure is
    right, as in the synthetic benchmark). ``"residual"``: two-step feasible generalised least
    squares -- a first fit with the noise weights, then the weights ``1/s_c`` with ``s_c`` the
    RMS simulation residual of channel ``c`` (:func:`residual_sd`, at least the noise sd) and a
    second fit from the first one's optimum. On real data the structural error of the
    simulation over a window dwarfs the sensor noise (KVLCC2: 0.19 m and 1.5 deg against 1 cm and
    0.01 deg); noise weights would then let the best-measured channel (heading) decide the fit.
    The maximum-likelihood estimate with an unknown error variance per channel has these
    weights at its optimum (e.g. Ljung 1999, "System Identification", Sec. 7.3 and 15.2).

    Parameters
    ----------
    problem : WindowProblem
        As :func:`fit_model`, with the noise sds as its weights (``problem.sd``; its prior is not
        used).
    p0 : array_like, shape (n_params,), optional
        The start.
    nuisance0 : list of array_like, optional
        The nuisances' start per track.
    weighting : {"noise", "residual"}, default "noise"
        The channel weighting.
    bar : str, optional
        Labels a progress bar of each stage.

    Returns
    -------
    fit : FitResult
        The (last) fit.
    sd : dict
        ``{channel: sd}`` of its weights.

    Raises
    ------
    ValueError
        An unknown ``weighting``.
    """
    if weighting not in ("noise", "residual"):
        raise ValueError(f"weighting must be 'noise' or 'residual', not {weighting!r}")
    lab = (lambda k: None) if not bar else (lambda k: f"{bar} ({k})")
    first = dataclasses.replace(problem, prior=None, data_scale=None)
    f = fit_model(first, p0, nuisance0, bar=lab("noise weights"))
    if weighting == "noise":
        return f, dict(problem.sd)
    sd2 = residual_sd(problem.model, f, problem.ctxs, problem.sd)
    nuisance = f.nuisance if problem.model.n_nuisance else None
    return fit_model(dataclasses.replace(first, sd=sd2), f.p, nuisance, bar=lab("residual weights")), sd2


@dataclass(frozen=True)
class Evaluation:
    """A parameter vector simulated once over every protocol window of a set of tracks: the
    predicted states, the errors by channel, and what is read from them (the protocol scores,
    each window's RMS position error, each run's). Every score of a fitted model on tracks is
    read from one of these, so nothing is simulated twice for two readings.

    Parameters
    ----------
    model : SimulationModel
        The model.
    p : ndarray, shape (n_params,)
        The parameter vector.
    ctxs : tuple of TrackContext
        The tracks' contexts.
    nuisance : tuple of ndarray or None
        Per track, the nuisances simulated with.
    starts : tuple
        Per track, the (W, 6) window start offsets fitted under the fitted rule
        (:func:`bayesid.estimation.shooting.fit_starts`), None under another rule.
    states : tuple of ndarray
        Per track, the (n_samples, 12) predicted measurements at the scored samples.
    errors : tuple of dict
        Per track, ``{channel: ndarray (n_samples,)}`` of prediction minus measurement
        (:func:`bayesid.models.context.errors`: heading wrapped, NaN where not finite).
    """

    model: object
    p: np.ndarray
    ctxs: tuple
    nuisance: tuple | None
    starts: tuple
    states: tuple
    errors: tuple

    def scores(self, sd: dict | None = None) -> Scores:
        """Protocol scores pooled over windows and tracks (:func:`scores`).

        Parameters
        ----------
        sd : dict, optional
            ``{channel: sd}``, SI, for the log-likelihood.

        Returns
        -------
        Scores
            :func:`bayesid.protocol.pooled_scores` with ``per_track_rms_position_m`` and, with
            ``sd``, ``log_likelihood``.
        """
        return _scores_of(self.ctxs, list(self.errors), sd)

    def window_rms(self) -> np.ndarray:
        """RMS horizontal position error of every window (:func:`window_rms`).

        Returns
        -------
        ndarray, shape (n_windows,)
            m; tracks in order, windows in time order, NaN for a window without a finite sample.
        """
        return _window_rms_of(self.ctxs, list(self.errors))

    def window_runs(self) -> np.ndarray:
        """The track of each window of :meth:`window_rms`.

        Returns
        -------
        ndarray of int, shape (n_windows,)
            The track's index in ``ctxs``.
        """
        return np.repeat(np.arange(len(self.ctxs)), [c.W for c in self.ctxs]).astype(int)


def evaluate(model, p, ctxs, nuisance=None) -> Evaluation:
    """Simulate a parameter vector once over every protocol window of tracks: under the fitted
    start rule each window's start offsets are fitted first with the parameters held
    (:func:`bayesid.estimation.shooting.fit_starts`, the track's own noise sds as weights), as
    :func:`bayesid.estimation.shooting.simulate` does.

    Parameters
    ----------
    model : SimulationModel
        The model.
    p : array_like, shape (n_params,)
        The parameter vector.
    ctxs : list of TrackContext
        The tracks' contexts.
    nuisance : list of ndarray, optional
        Per track, the (n_nuisance,) nuisances.

    Returns
    -------
    Evaluation
        The states, errors and start offsets of every track.
    """
    P = np.asarray(p, float)[None]
    starts, states, errors = [], [], []
    for i, ctx in enumerate(ctxs):
        nu = None if nuisance is None else nuisance[i][None]
        st = shooting.fit_starts(model, ctx, P, nu) if ctx.start == "fitted" else None
        S = model.simulate(ctx, P, nu) if st is None else model.simulate(ctx, P, nu, starts=st)
        starts.append(None if st is None else st[0])
        states.append(S[0])
        errors.append({k: v[0] for k, v in ctxmod.errors(ctx, S).items()})
    nus = None if nuisance is None else tuple(nuisance)
    return Evaluation(model, P[0], tuple(ctxs), nus, tuple(starts), tuple(states), tuple(errors))


def window_starts(model, p, ctx, nuisance=None) -> np.ndarray:
    """The start offsets of every window of a fitted-start context for a parameter vector
    (:func:`bayesid.estimation.shooting.fit_starts`, the track's own noise sds as weights): what
    :func:`evaluate` simulates from, without the simulation.

    Parameters
    ----------
    model : SimulationModel
        The model.
    p : array_like, shape (n_params,)
        The parameter vector.
    ctx : TrackContext
        A context of the fitted start rule.
    nuisance : ndarray, shape (n_nuisance,), optional
        The track's nuisances.

    Returns
    -------
    ndarray, shape (W, 6)
        Offsets of the :data:`bayesid.models.context.START_INDEX` components from ``ctx.s_meas``.

    Raises
    ------
    ValueError
        A context of another start rule.
    """
    if ctx.start != "fitted":
        raise ValueError(
            f"track {ctx.name!r}: window starts are fitted only under the fitted start rule, not {ctx.start!r}"
        )
    nu = None if nuisance is None else np.asarray(nuisance, float)[None]
    return shooting.fit_starts(model, ctx, np.asarray(p, float)[None], nu)[0]


def scores(model, fitres: FitResult, ctxs, nuisance=None, sd: dict | None = None) -> Scores:
    """Protocol scores of a fitted model on tracks (pooled over windows and tracks):
    ``evaluate(model, fitres.p, ctxs, nuisance).scores(sd)``.

    With ``sd`` ({channel: sd}, SI) also ``log_likelihood`` (nats): the Gaussian log-density
    of every finite error of every scored channel, ``sum(-e^2 / (2 sd^2) - ln(sd sqrt(2 pi)))``,
    treating the samples as independent -- a relative measure (before vs after an effect, same
    sds and samples), not a calibrated one: simulation errors are correlated in time. Only the
    channels ``sd`` has enter it: a held-out track may log a channel (say ``r``) that the
    training tracks, whose fit gave ``sd``, did not; the log-likelihood stays over the fitted
    channels, the same before and after an effect.

    Parameters
    ----------
    model : SimulationModel
        The model.
    fitres : FitResult
        The fit (its ``p``).
    ctxs : list of TrackContext
        The tracks.
    nuisance : list of ndarray, optional
        Per track nuisances (:func:`heldout_nuisance`).
    sd : dict, optional
        ``{channel: sd}``, SI, for the log-likelihood.

    Returns
    -------
    Scores
        :func:`bayesid.protocol.pooled_scores` with ``per_track_rms_position_m`` (``{track
        name: m}``) and, with ``sd``, ``log_likelihood``.
    """
    return evaluate(model, fitres.p, ctxs, nuisance).scores(sd)


def _scores_of(ctxs, errs: list, sd: dict | None) -> Scores:
    """:func:`scores` of the tracks' errors (:attr:`Evaluation.errors`)."""
    per_track = {}
    ll = 0.0
    for ctx, e in zip(ctxs, errs):
        per_track[ctx.name] = pooled_scores([e])["rms_position_m"]
        if sd is not None:
            for c, v in e.items():
                if c not in sd:
                    continue
                v = v[np.isfinite(v)]
                ll += float(-0.5 * np.sum((v / sd[c]) ** 2) - v.size * math.log(sd[c] * math.sqrt(2 * math.pi)))
    return dataclasses.replace(
        pooled_scores(errs), per_track_rms_position_m=per_track, log_likelihood=ll if sd is not None else None
    )


def window_rms(model, fitres: FitResult, ctxs, nuisance=None) -> np.ndarray:
    """RMS horizontal position error of every protocol window of a set of tracks:
    ``evaluate(model, fitres.p, ctxs, nuisance).window_rms()``.

    Parameters
    ----------
    model : SimulationModel
        The model.
    fitres : FitResult
        The fit (its ``p``).
    ctxs : list of TrackContext
        The tracks.
    nuisance : list of ndarray, optional
        Per track nuisances.

    Returns
    -------
    ndarray, shape (n_windows,)
        RMS error, m (tracks in order, windows in time order; NaN for a window without a
        finite sample).
    """
    return evaluate(model, fitres.p, ctxs, nuisance).window_rms()


def _window_rms_of(ctxs, errs: list) -> np.ndarray:
    """:func:`window_rms` of the tracks' errors (:attr:`Evaluation.errors`)."""
    out = []
    for ctx, e in zip(ctxs, errs):
        pos2 = e["x"] ** 2 + e["y"] ** 2
        for w in range(ctx.W):
            v = pos2[(ctx.win == w) & np.isfinite(pos2)]
            out.append(float(np.sqrt(v.mean())) if v.size else np.nan)
    return np.array(out)


def pooled_noise_sd(tracks, floor: bool = True) -> dict:
    """Noise sds pooled over tracks: the median over the tracks of
    :func:`bayesid.protocol.estimate_noise` of each scored channel.

    Parameters
    ----------
    tracks : iterable of Track
        The tracks.
    floor : bool, default True
        Floor each track's sd at :data:`bayesid.protocol.NOISE_FLOOR`.

    Returns
    -------
    dict
        ``{channel: noise sd}``, SI units.
    """
    sds = {}
    for tr in tracks:
        for k, v in estimate_noise(tr, [c for c in CHANNELS if c in tr], floor=floor).items():
            sds.setdefault(k, []).append(v)
    return {k: float(np.median(v)) for k, v in sds.items()}


#: Least scored samples per estimated parameter a fit accepts (each sample has 3-6 channels).
MIN_SAMPLES_PER_PARAMETER = 10


def check_enough_data(model, ctxs, window_s: float) -> None:
    """Refuse a fit whose training tracks are too short to say anything.

    Parameters
    ----------
    model : SimulationModel
        The model (its number of parameters).
    ctxs : list of TrackContext
        The training tracks.
    window_s : float
        The fit window, s.

    Raises
    ------
    ValueError
        Naming the tracks: fewer scored samples than :data:`MIN_SAMPLES_PER_PARAMETER` per
        parameter, or tracks that together last less than one fit window.
    """
    n = sum(int(c.ts.size) for c in ctxs)
    span = sum(float(c.ts[-1] - c.t_start[0]) if c.ts.size else 0.0 for c in ctxs)
    k = model.n_params
    names = ", ".join(f"track {c.name!r}" for c in ctxs)
    if n < MIN_SAMPLES_PER_PARAMETER * k:
        raise ValueError(
            f"training {names}: {n} scored samples for {k} parameters (need at least "
            f"{MIN_SAMPLES_PER_PARAMETER * k}); give longer or more tracks, or fewer --free"
        )
    if span < window_s:
        raise ValueError(
            f"training {names} last {span:.3g} s in all, less than one {window_s:g} s fit "
            "window; give longer tracks or a shorter --fit-window"
        )
