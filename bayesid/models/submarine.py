"""The submarine model: the base equations (:mod:`bayesid.models.dynamics`, the generated kernels of
:mod:`bayesid.models.codegen`) plus effects of the catalogue (:mod:`bayesid.models.effects`),
simulated over a track's protocol windows.

:class:`EffectModel` implements :class:`bayesid.models.interface.SimulationModel` for a
:class:`~bayesid.data.vehicle.Vehicle`; :data:`REGIONS` are the operating-region bins of its
*where* analysis.
"""

from __future__ import annotations

import math

import numpy as np

from ..data import terms
from ..data.track import Track
from ..protocol import wrap
from . import inverse
from .context import Prepared, TrackContext, prepared_for, sample_rows, start_states
from .effects import CATALOGUE, Effect, get, signature_dict
from .interface import ParameterLayout
from .library import MAX_ORDER, TermLibrary, motion_products
from .simulate import Manoeuvre, Simulator


class EffectModel(ParameterLayout):
    """The base model plus a list of effects, simulated over a track's protocol windows.

    The parameter vector of one model is ``[theta_free (P), q_1, ..., q_E]`` with ``q_e`` the
    effect parameters in the units of their names; per-track nuisance parameters
    (``n_nuisance``) are passed separately.

    Implements :class:`bayesid.models.interface.SimulationModel` (the submarine family).

    Parameters
    ----------
    vehicle : Vehicle
        The :class:`~bayesid.data.vehicle.Vehicle` (nominal coefficients, prime form).
    free : sequence of str, default ()
        Names of the coefficients the fit changes (SNAME; unknown names raise).
    effects : sequence of str or Effect, default ()
        Effect names (see :data:`~bayesid.models.effects.CATALOGUE`) or effects, applied in this
        order.
    mode : {"horizontal", "6dof"}, default "horizontal"
        Degrees of freedom (an effect with ``mode="6dof"`` forces 6-DOF).
    dt : float, default 0.5
        Integration step, s.
    kernel : {"generated", "interpreted"}, default "generated"
        The compiled kernel kind (:class:`bayesid.models.simulate.Simulator`,
        :mod:`bayesid.models.codegen`).

    Raises
    ------
    ValueError
        An effect listed twice, an unknown effect, the crossflow effect for a vehicle without
        ``[crossflow]`` data, or any error of :class:`~bayesid.models.simulate.Simulator`.
    UnknownCoefficientError
        A free name not in the term library.
    """

    DEFAULT_DT = 0.5
    #: The model step per time unit ``L / U`` of the vehicle: :data:`DEFAULT_DT` over that of the
    #: vehicle it was chosen for, NPS AUV II (5.3 m at 1.885 m/s, 2.81 s)
    DT_PER_TIME_UNIT = DEFAULT_DT / (5.3 / 1.885)
    DEFAULT_WEIGHTING = "noise"
    #: the horizontal-plane coefficients freed when the user names none
    DEFAULT_FREE = ("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr")

    @classmethod
    def for_vehicle(
        cls, vehicle, free=None, effects=(), dt: float = DEFAULT_DT, mode: str = "horizontal", kernel: str = "generated"
    ):
        """The model of :func:`bayesid.models.build_model`.

        Parameters
        ----------
        vehicle : Vehicle
            The vehicle.
        free : sequence of str, optional
            The free coefficients (None: none).
        effects : sequence of str or Effect, default ()
            The effects.
        dt : float, default DEFAULT_DT
            Integration step, s.
        mode : {"horizontal", "6dof"}, default "horizontal"
            Degrees of freedom.
        kernel : {"generated", "interpreted"}, default "generated"
            The compiled kernel kind.

        Returns
        -------
        EffectModel
            The model.
        """
        return cls(vehicle, free or (), effects, mode=mode, dt=dt, kernel=kernel)

    @staticmethod
    def effect_unsupported(effect, vehicle) -> str | None:
        """Why a vehicle cannot carry an effect, or None: the crossflow effect scales the vehicle
        file's cross-flow drag integral, which needs its ``[crossflow]`` section (a file without it,
        the docs' REMUS 100, made the default catalogue's diagnosis fail in round 1).

        Parameters
        ----------
        effect : Effect
            The effect.
        vehicle : Vehicle
            The vehicle.

        Returns
        -------
        str or None
            The reason, e.g. ``"the vehicle file has no [crossflow] section"``.
        """
        if effect.name == "crossflow" and getattr(vehicle, "crossflow", None) is None:
            return "the vehicle file has no [crossflow] section"
        return None

    @classmethod
    def default_dt(cls, vehicle) -> float:
        """The model step of a vehicle when the user gives none: :data:`DEFAULT_DT`, halved until it
        is at most :data:`DT_PER_TIME_UNIT` of the vehicle's time unit ``L / U`` (length over
        nominal speed). The fixed-step RK4 of the kernels diverges when the step is long against the
        vehicle's fastest sway-yaw time constant, which scales with ``L / U``: REMUS 100 (1.33 m at
        1.54 m/s) flown at the 0.5 s chosen for NPS AUV II gives non-finite states within a 90 s
        zigzag or turn, at 0.2 s and finer none (``tests/test_default_step.py``).

        Parameters
        ----------
        vehicle : Vehicle
            The vehicle (its ``L``, m, and ``nominal_speed``, m/s).

        Returns
        -------
        float
            The step, s: 0.5 for NPS AUV II and every vehicle as slow for its length, 0.125 for
            REMUS 100.
        """
        dt = cls.DEFAULT_DT
        L, U = float(getattr(vehicle, "L", 0.0) or 0.0), float(getattr(vehicle, "nominal_speed", 0.0) or 0.0)
        if L > 0.0 and U > 0.0:
            limit = cls.DT_PER_TIME_UNIT * L / U * (1.0 + 1e-9)
            while dt > limit and dt > 1e-3:
                dt /= 2.0
        return dt

    @staticmethod
    def default_fit_window(scoring_window_s):
        """A submarine's training fits use the scoring window.

        Parameters
        ----------
        scoring_window_s : float or None
            The protocol's scoring window, s (None: the whole run).

        Returns
        -------
        float or None
            ``scoring_window_s``.
        """
        return scoring_window_s

    @classmethod
    def default_free(cls, vehicle) -> list:
        """The coefficients freed when the user names none.

        Parameters
        ----------
        vehicle : Vehicle
            The vehicle (unused: the list is the family's).

        Returns
        -------
        list of str
            :attr:`DEFAULT_FREE`.
        """
        return list(cls.DEFAULT_FREE)

    @staticmethod
    def check_free(vehicle, names, option: str = "free") -> None:
        """Check a free list against the term library.

        Parameters
        ----------
        vehicle : Vehicle
            The vehicle (unused: every vehicle accepts the whole library).
        names : iterable of str
            The coefficient names.
        option : str, default "free"
            The option the names come from, named in the message.

        Raises
        ------
        UnknownCoefficientError
            A KeyError naming ``option`` and the unknown coefficient name.
        """
        terms.check_names(names, option)

    @staticmethod
    def get_effect(name):
        """A catalogue effect by name (:func:`~bayesid.models.effects.get`).

        Parameters
        ----------
        name : str or Effect
            A catalogue name; an :class:`~bayesid.models.effects.Effect` passes through.

        Returns
        -------
        Effect
            The effect.

        Raises
        ------
        ValueError
            Naming an unknown effect.
        """
        return name if isinstance(name, Effect) else get(name)

    def __init__(
        self, vehicle, free=(), effects=(), mode: str = "horizontal", dt: float = 0.5, kernel: str = "generated"
    ):
        self.vehicle, self.dt = vehicle, float(dt)
        self.effects = [self.get_effect(e) for e in effects]
        names = [e.name for e in self.effects]
        if len(set(names)) != len(names):
            raise ValueError(f"effect listed twice in {names}")
        for e in self.effects:
            why = self.effect_unsupported(e, vehicle)
            if why:
                raise ValueError(f"vehicle {vehicle.id}: {why}, which the {e.name} effect needs")
        self.mode = "6dof" if any(e.mode == "6dof" for e in self.effects) else mode
        dummy = Manoeuvre("protocol", self.dt, np.zeros((1, 4)), np.zeros(12))
        self.sim = Simulator(vehicle, dummy, free, self.mode, kernel=kernel)
        self.free = list(self.sim.free)
        self.force_index = {n: i for i, n in enumerate(self.sim.force_names)}
        self.theta0 = vehicle.coefficient_vector(self.free) if self.free else np.zeros(0)
        self.n_q = [len(e.params) for e in self.effects]
        self.n_theta = len(self.free)
        self.param_names = self.free + [f"{e.name}.{p}" for e in self.effects for p in e.params]
        self.n_nuisance = sum(e.n_nuisance for e in self.effects)
        self.K = max(1, sum(e.exo_columns for e in self.effects))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the parameter vector: coefficients unbounded, effects as catalogued.

        Returns
        -------
        lo, hi : ndarray, shape (n_params,)
            Lower and upper bounds (+-inf for the coefficients).
        """
        lo = [np.full(self.n_theta, -np.inf)] + [np.asarray(e.lo, float) for e in self.effects]
        hi = [np.full(self.n_theta, np.inf)] + [np.asarray(e.hi, float) for e in self.effects]
        return np.concatenate(lo), np.concatenate(hi)

    def scales(self) -> np.ndarray:
        """Typical sizes of the parameters: the nominal coefficients' magnitudes (at least 1e-3)
        and the effects' catalogued scales.

        Returns
        -------
        ndarray, shape (n_params,)
            The typical sizes.
        """
        th = np.maximum(np.abs(self.theta0), 1e-3)
        return np.concatenate([th] + [np.asarray(e.scale, float) for e in self.effects])

    def context(
        self, track: Track, window_s=None, span_s: float = 1.0, s0=None, start: str = "measured", leadin_s: float = 0.0
    ) -> TrackContext:
        """Prepare a track (inputs, windows, window-start states).

        Parameters
        ----------
        track : Track
            The track.
        window_s : float, optional
            Protocol window, s; None is one window over the whole run.
        span_s : float, default 1.0
            Span of the measured start-state estimate, s.
        s0 : array_like, shape (12,), optional
            Replaces the measured start state (world generation).
        start : {"measured", "fitted"}, default "measured"
            Otherwise the start rule gives it (:data:`bayesid.protocol.START_RULES`, resolved).
        leadin_s : float, default 0.0
            Lead-in of the fitted rule, s.

        Returns
        -------
        TrackContext
            The prepared track.
        """
        return TrackContext(self, track, window_s, span_s, s0=s0, start=start, leadin_s=leadin_s)

    def prepare(self, ctx: TrackContext, P, nuisance=None) -> Prepared:
        """The part of :meth:`simulate` that does not depend on the start states: coefficient
        rows, mass matrices and their inverses, the effects' changes, the step inputs and the
        exogenous forces of ``P`` on ``ctx``, for many simulations from other start states.

        Parameters
        ----------
        ctx : TrackContext
            The prepared track.
        P : array_like, shape (B, n_params) or (n_params,)
            Parameter vectors.
        nuisance : array_like, shape (B, n_nuisance), optional
            Per-track parameters of this track (default zeros).

        Returns
        -------
        Prepared
            Passed to :meth:`simulate` as ``prepared`` with the same ``ctx``, ``P`` and ``nuisance``.
        """
        th, qs = self.split_params(P)
        B = th.shape[0]
        nu = np.zeros((B, max(self.n_nuisance, 1))) if nuisance is None else np.atleast_2d(nuisance)
        sim = self.sim
        C = sim.coefficient_matrix(th if self.n_theta else None)
        if C.shape[0] != B:
            C = np.repeat(C, B, axis=0)
        tcoef = np.ascontiguousarray(C[:, sim.force_idx] * sim.tscale)
        M = sim.mass_matrices(C)
        vp = np.repeat(sim.vp[None], B, axis=0)
        for e, q in zip(self.effects, qs):
            e.modify(self, C, M, vp, tcoef, q)
        Minv = sim.inverse_mass_matrices(C, M)
        inputs = np.ascontiguousarray(ctx.inputs(self.effects, qs, B))
        exo = np.zeros((B, ctx.n_steps, self.K))
        ecoef = np.zeros((B, self.K, 6))
        j, jn = 0, 0
        for e, q in zip(self.effects, qs):
            res = e.exo(ctx, inputs, q, nu[:, jn : jn + e.n_nuisance])
            if res is not None:
                col, coef = res
                k = col.shape[2]
                exo[:, :, j : j + k] = col
                ecoef[:, j : j + k] = coef
                j += k
            jn += e.n_nuisance
        parts = {"qs": qs, "B": B, "vp": vp, "tcoef": tcoef, "Minv": Minv, "inputs": inputs, "exo": exo, "ecoef": ecoef}
        return Prepared(
            ctx, np.atleast_2d(np.asarray(P, float)), None if nuisance is None else np.atleast_2d(nuisance), parts
        )

    def simulate(
        self,
        ctx: TrackContext,
        P,
        nuisance=None,
        measured_start: bool = True,
        starts=None,
        samples: str = "scored",
        prepared: Prepared | None = None,
    ) -> np.ndarray:
        """Predicted measurements at the track's scored samples.

        Parameters
        ----------
        ctx : TrackContext
            The prepared track (:meth:`context`).
        P : array_like, shape (B, n_params) or (n_params,)
            Parameter vectors.
        nuisance : array_like, shape (B, n_nuisance), optional
            Per-track parameters of this track (default zeros).
        measured_start : bool, default True
            Map the window-start states through the effects' sensor models (False:
            ``ctx.s_meas`` are already model states, e.g. the true initial state).
        starts : array_like, shape (B, W, 6), optional
            Offsets added to the start state of every window (segment) in the measured frame,
            components :data:`~bayesid.models.context.START_INDEX` (x, y, psi, u, v, r); the
            fitted start rule (:mod:`bayesid.estimation.shooting`). Default none.
        samples : {"scored", "lead"}, default "scored"
            The window samples, or the samples that estimate the start states (``ctx.lead``).
        prepared : Prepared, optional
            :meth:`prepare` of this ``ctx``, ``P`` and ``nuisance`` (default: prepared here).

        Returns
        -------
        ndarray, shape (B, n_samples, 12)
            States as the sensors would report them (NaN in a diverged window).

        Raises
        ------
        ValueError
            ``prepared`` of another track, other rows or inputs.
        """
        pr = prepared_for(self, ctx, P, nuisance, prepared)
        qs, B, vp, tcoef, Minv = pr.parts["qs"], pr.parts["B"], pr.parts["vp"], pr.parts["tcoef"], pr.parts["Minv"]
        inputs, exo, ecoef, sim = pr.parts["inputs"], pr.parts["exo"], pr.parts["ecoef"], self.sim
        s0 = start_states(ctx, B, starts)
        if measured_start:
            for e, q in reversed(list(zip(self.effects, qs))):
                e.to_model(s0, q)
        if self.mode == "horizontal":
            s0[:, :, [2, 3, 4, 8, 9, 10]] = 0.0
        seg = ctx.layout(samples)  # the lead-in samples need only the lead-ins simulated
        out = np.empty((B, seg[-1] + ctx.W, 12))
        status = np.empty((B, ctx.W), dtype=np.int64)
        sim.kernel.simulate_windows(
            np.ascontiguousarray(s0),
            seg,
            ctx.gather(inputs, samples),
            ctx.gather(exo, samples),
            ecoef,
            self.dt,
            np.ascontiguousarray(vp),
            tcoef,
            Minv,
            sim.xs,
            sim.ws,
            out,
            status,
        )
        S, t_rel = sample_rows(ctx, out, samples, slice(3, 6))
        for e, q in zip(self.effects, qs):
            e.to_measured(S, t_rel, q)
        S[..., 5] = wrap(S[..., 5])
        return S

    # -- what the analysis layer asks of a model ----------------------------------------------
    def seed(self, tracks):
        """No equation-error seed: a submarine fit starts at the nominal coefficients.

        Parameters
        ----------
        tracks : list of Track
            The training tracks (unused).

        Returns
        -------
        None
            Always.
        """
        return None

    def missing_forces(self, fitres, track: Track):
        """Missing X, Y, N over time: rigid-body inverse dynamics of the smoothed measured motion
        minus the fitted model's hydrodynamic forces (Savitzky-Golay smoothed differentiation,
        :func:`bayesid.models.inverse.estimate_motion`).

        Parameters
        ----------
        fitres : FitResult
            A fit of this model (its coefficients are used when the model has free ones).
        track : Track
            The track.

        Returns
        -------
        motion : dict
            The smoothed motion (:func:`~bayesid.models.inverse.estimate_motion`).
        F : ndarray, shape (n, 3)
            Missing X, Y (N) and N (N m).
        inputs : ndarray, shape (n_samples, 4)
            The logged inputs (:func:`~bayesid.models.inverse.track_inputs`).
        """
        veh = self.vehicle.with_coefficients(fitres.coefficients()) if self.free else self.vehicle
        motion = inverse.estimate_motion(track)
        inputs = inverse.track_inputs(track)
        known = [
            t
            for t in inverse.horizontal_terms("X") + inverse.horizontal_terms("Y") + inverse.horizontal_terms("N")
            if veh.coefficients.get(t, 0.0) != 0.0
        ]
        known = sorted(set(known) | set(inverse.ADDED_MASS))
        F = inverse.force_targets(motion, veh, inputs, known=known)
        return motion, F, inputs

    def signature_columns(self, motion, inputs, track: Track, seeds=None, effects=None) -> dict:
        """Force-space signatures of the effects that leave one
        (:meth:`~bayesid.models.effects.Effect.force_signature`).

        Parameters
        ----------
        motion : dict
            The smoothed motion of :meth:`missing_forces`.
        inputs : ndarray, shape (n_samples, 4)
            The logged inputs at the track's samples.
        track : Track
            The track.
        seeds : dict, optional
            Seeds of the diagnosis (``"waves"``: the waves' frequency first).
        effects : iterable of Effect, optional
            The effects; default the catalogue.

        Returns
        -------
        dict
            ``{effect: [columns (n, 3) of X, Y, N]}``.
        """
        t = motion["t"]
        dr = np.interp(t, track.t, inputs[:, 0])
        rpm = np.interp(t, track.t, inputs[:, 3])
        veh = self.vehicle
        m = {
            "t": t,
            "u": motion["u"],
            "v": motion["v"],
            "r": motion["r"],
            "psi": np.interp(t, track.t, np.unwrap(track["psi"])),
            "rudder_rate": np.gradient(dr, t),
            "propeller_inflow": veh.propulsion.uc_per_omega * rpm * 2 * math.pi / 60,
            "q_dyn": 0.5 * veh.rho * veh.L**2,
            "omega": waves[0] if (waves := (seeds or {}).get("waves")) else None,
        }
        if "phi" in track and np.isfinite(track["phi"]).all():
            m["phi"] = np.interp(t, track.t, track["phi"])
        return signature_dict(self.CATALOGUE.values() if effects is None else effects, m)

    def where_samples(self, track: Track, ctx, S) -> dict:
        """No extra region variables for a submarine.

        Parameters
        ----------
        track : Track
            The track (unused).
        ctx : TrackContext
            The prepared track (unused).
        S : ndarray
            Predicted states (unused).

        Returns
        -------
        dict
            Empty.
        """
        return {}

    def regions(self) -> dict:
        """Operating-region bins of the *where* analysis.

        Returns
        -------
        dict
            :data:`REGIONS`, ``{region variable: bin edges}``.
        """
        return REGIONS

    def term_library(self) -> SubmarineTerms:
        """The submarine family's candidate terms for structure discovery.

        Returns
        -------
        SubmarineTerms
            The library bound to this model's vehicle.
        """
        return SubmarineTerms(self.vehicle)


class SubmarineTerms(TermLibrary):
    """The horizontal-plane products of the submarine term grammar (:func:`bayesid.data.terms.parse`,
    Gertler & Hagen 1967 prime form): every product of up to three motion factors from ``v r
    absv absr dr`` (``u`` implicit; three velocity factors carry ``1/U``, so the term stays of
    second order in speed), and the grammar's products of up to two velocity factors with up to
    three rudder factors; the constant force or moment twice, ``uu`` in
    prime form (u^2, e.g. a propeller's) and ``const`` the same at every speed
    (:data:`bayesid.data.terms.CONSTANT`). A product the table lists under another spelling
    (``Nuu`` is ``Nprop``) takes the listed name.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle (:class:`bayesid.data.vehicle.Vehicle`).
    """

    family = "submarine"

    @staticmethod
    def products() -> list[str]:
        """The name bodies of the grammar's horizontal-plane products.

        Returns
        -------
        list of str
            E.g. ``"vabsr"``, ``"vvdr"``, ``"uu"``.
        """
        vel = ["", "v", "r", "absv", "absr", "vv", "vr", "rr", "vabsv", "vabsr", "rabsv", "rabsr"]
        out = ["uu", terms.CONSTANT] + [a + "dr" * k for a in vel for k in range(4) if a + "dr" * k]
        # every product of up to three motion factors (issue 49), e.g. v^2 r: in prime form
        # 0.5 rho L^4 N'vvr v^2 r / U (:data:`bayesid.data.terms.MAX_VELOCITY_FACTORS`)
        return out + [b for b in motion_products(MAX_ORDER, rudder_abs=False) if b not in out]

    def candidates(self, model, max_order: int = MAX_ORDER, dofs=("Y", "N")) -> list[str]:
        """See :meth:`TermLibrary.candidates` (``max_order`` does not limit the submarine
        grammar's products).

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
        have = {k for k, v in self.vehicle.coefficients.items() if v != 0.0} | set(model.free)
        out, products = [], {self._product(n) for n in have} - {None}
        for g in dofs:
            for body in self.products():
                name = g + body
                try:
                    t = terms.parse(terms.listed_name(name) or name)  # Nuu is listed as Nprop
                except terms.UnknownCoefficientError:
                    continue
                key = self._product(t.name)  # one name per product (r|v| = |v|r)
                if t.name not in have and t.horizontal and key not in products:
                    out.append(t.name)
                    products.add(key)
        return out

    @staticmethod
    def _product(name: str):
        """``(dof, accel, sorted factors)`` of a coefficient of the grammar, None for another."""
        try:
            t = terms.parse(name)
        except terms.UnknownCoefficientError:
            return None
        return (t.dof, t.accel, tuple(sorted(t.factors)))

    def columns(self, names, motion: dict, inputs) -> np.ndarray:
        """See :meth:`TermLibrary.columns` (:func:`bayesid.models.inverse.library_columns`: the
        simulator's features, so the columns are the kernel's forces).

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
        for n in names:
            terms.term(n)  # adds a product to the table
        return inverse.library_columns(list(names), motion, inputs, self.vehicle)


#: Operating-region bins of a submarine's *where* analysis (NPS AUV II speeds and rates).
REGIONS = {
    "drift_angle_deg": [-90, -6, -2, 2, 6, 90],
    "yaw_rate_deg_s": [-30, -3, -1, 1, 3, 30],
    "rudder_deg": [-40, -15, -5, 5, 15, 40],
    "speed_mps": [0, 1.0, 1.5, 1.8, 10],
}
EffectModel.CATALOGUE = CATALOGUE


__all__ = ["EffectModel", "REGIONS", "SubmarineTerms"]
