"""*Candidates* of the gap diagnosis: each catalogue effect added to the model being extended,
fitted with all free coefficients from several starts, and scored on the held-out tracks.

Starts of a candidate fit (:func:`candidate_starts`): from the reference fit's coefficients and
from the nominal ones (the reference fit may have bent the coefficients to absorb the effect, a
local minimum for the candidate), each with the effect's own starts and seed
(:meth:`~bayesid.models.effects.Effect.fit_starts`, :meth:`~bayesid.models.effects.Effect.diagnosis_seed`). A
candidate whose effect has a ``neutral`` value nests the model it extends; when its fits end
worse than that model it is refitted once more from that model's optimum with the effect neutral
(:func:`nested_start`), so its ΔBIC is at most k ln n.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ...estimation.fit import FitResult
from ...estimation.windows import Evaluation, WindowProblem, contexts, evaluate, heldout_nuisance, warm_starts
from ...models import build_model
from .records import CandidateRow
from .verdict import paired_window_test

__all__ = [
    "Setup",
    "Stage",
    "BaseStage",
    "score_stage",
    "candidate_starts",
    "effect_offset",
    "nested_start",
    "extended_nuisance",
    "CandidateFit",
    "fit_candidate",
    "candidate_row",
    "failed_fit",
]


@dataclass
class Stage:
    """A model of the greedy rounds.

    Parameters
    ----------
    model : SimulationModel
        The model.
    fit : FitResult
        Its fit on the training tracks.
    train : dict
        Its training scores (:func:`~bayesid.estimation.windows.scores`).
    held : dict
        Its held-out scores.
    nuisance : list of ndarray or None
        Its held-out nuisances.
    windows : ndarray
        Its per-window held-out RMS position errors (:func:`~bayesid.estimation.windows.window_rms`).
    train_windows : ndarray, optional
        Its per-window RMS position errors on the training tracks' fit windows, m (None where not
        scored: the base models of the diagnosis).
    train_runs : ndarray of int, optional
        The training track of each of ``train_windows``.
    """

    model: object
    fit: FitResult
    train: dict
    held: dict
    nuisance: list | None
    windows: np.ndarray
    train_windows: np.ndarray | None = None
    train_runs: np.ndarray | None = None


@dataclass
class Setup:
    """What every model of one diagnosis shares: vehicle, free coefficients, tracks, windows.

    Parameters
    ----------
    vehicle : Vehicle or Ship
        The vehicle (nominal coefficients).
    free : list of str
        The free coefficients.
    train : list of Track
        The training tracks.
    heldout : list of Track
        The held-out tracks.
    dt : float
        The model step, s.
    mode : str
        The submarine equations (``"horizontal"``, ...).
    fit_window_s : float or None
        The training fits' window, s.
    window_s : float or None
        The held-out scoring window, s.
    rule : str
        The window start rule (:data:`bayesid.protocol.START_RULES`).
    leadin_s : float or None
        The lead-in of the fitted rule on the held-out tracks, s.
    effects : tuple, default ()
        Effects every model of the diagnosis has (the base model's), before the candidates.
    train_starts : {"fitted", "kinematic"}, default "fitted"
        Under the fitted rule, how the training fits get their window starts: fitted with the
        model, or held at the tracks' own kinematics
        (:func:`bayesid.estimation.windows.contexts`, with ``kinematic_sd``).
    kinematic_sd : dict, optional
        ``{channel: noise sd}`` (SI) of x, y, psi for the kinematic starts.
    inputs : {"hold", "linear", "rate"}, default "hold"
        How every model reconstructs the logged inputs between samples
        (:func:`bayesid.models.build_model`).
    rudder_rate_deg_s : float, optional
        The gear's rate of ``inputs="rate"``, deg/s (None: the vehicle file's).
    """

    vehicle: object
    free: list
    train: list
    heldout: list
    dt: float
    mode: str
    fit_window_s: float | None
    window_s: float | None
    rule: str
    leadin_s: float | None
    effects: tuple = ()
    train_starts: str = "fitted"
    kinematic_sd: dict | None = None
    inputs: str = "hold"
    rudder_rate_deg_s: float | None = None

    def build(self, effects):
        """The model with the setup's effects, then ``effects``, and its contexts.

        Parameters
        ----------
        effects : sequence of Effect or str
            The effects added to the setup's.

        Returns
        -------
        tuple
            ``(model, training contexts, held-out contexts)``.
        """
        m = build_model(
            self.vehicle,
            self.free,
            [*self.effects, *effects],
            dt=self.dt,
            mode=self.mode,
            inputs=self.inputs,
            rudder_rate_deg_s=self.rudder_rate_deg_s,
        )
        held_starts = self.train_starts == "kinematic"
        return (
            m,
            contexts(
                m, self.train, self.fit_window_s, self.rule, held_starts=held_starts, kinematic_sd=self.kinematic_sd
            ),
            contexts(m, self.heldout, self.window_s, self.rule, leadin_s=self.leadin_s),
        )


@dataclass
class BaseStage:
    """The base model of a diagnosis fitted on the training tracks, evaluated once on them and
    on the held-out ones, and checked.

    Parameters
    ----------
    setup : Setup
        The diagnosis's setup (its ``train_starts`` says how the training windows start).
    problem : WindowProblem
        The base model on the training contexts, weighted by the fit's channel sds (``sd_fit``).
    cho : list of TrackContext
        The held-out contexts.
    fit : FitResult
        The base fit.
    multistart : dict or None
        The summary of the extra starts (None without them).
    train : Evaluation
        The fit on the training contexts.
    held : Evaluation
        The fit on the held-out contexts.
    check : BaseCheck
        The base-fit check (:func:`~bayesid.analysis.gap.diagnose.base_fit_check`).
    """

    setup: Setup
    problem: WindowProblem
    cho: list
    fit: FitResult
    multistart: dict | None
    train: Evaluation
    held: Evaluation
    check: object

    @property
    def model(self):
        """The base model."""
        return self.problem.model

    @property
    def ctr(self) -> list:
        """The training contexts."""
        return self.problem.ctxs

    @property
    def sd_fit(self) -> dict:
        """``{channel: sd}``, the base fit's channel weights."""
        return self.problem.sd

    @cached_property
    def train_scores(self):
        """The training scores (:meth:`~bayesid.estimation.windows.Evaluation.scores` with ``sd_fit``)."""
        return self.train.scores(self.sd_fit)

    @cached_property
    def held_scores(self):
        """The held-out scores (:meth:`~bayesid.estimation.windows.Evaluation.scores` with ``sd_fit``)."""
        return self.held.scores(self.sd_fit)

    def stage(self) -> Stage:
        """The base model as the first stage of the greedy rounds.

        Returns
        -------
        Stage
            Its scores and held-out window errors (its training windows not scored).
        """
        return Stage(self.model, self.fit, self.train_scores, self.held_scores, None, self.held.window_rms())


def score_stage(model, fit: FitResult, ctx_train: list, ctx_held: list, sd_fit: dict) -> Stage:
    """A fitted model scored on the training and held-out contexts (held-out nuisances fitted with
    the parameters held).

    Parameters
    ----------
    model : SimulationModel
        The model.
    fit : FitResult
        Its fit on the training contexts.
    ctx_train : list of TrackContext
        The training contexts.
    ctx_held : list of TrackContext
        The held-out contexts.
    sd_fit : dict
        ``{channel: sd}``, the channel weights of the scores.

    Returns
    -------
    Stage
        The scored model, with its per-window errors on the held-out and the training tracks.
    """
    nu_h = heldout_nuisance(model, fit, ctx_held, sd_fit) if model.n_nuisance else None
    train = evaluate(model, fit.p, ctx_train)
    held = evaluate(model, fit.p, ctx_held, nu_h)
    return Stage(
        model,
        fit,
        train.scores(sd_fit),
        held.scores(sd_fit),
        nu_h,
        held.window_rms(),
        train.window_rms(),
        train.window_runs(),
    )


def effect_offset(model, effect) -> int:
    """Index of an effect's first parameter in the model's parameter vector.

    Parameters
    ----------
    model : SimulationModel
        The model (it contains the effect).
    effect : Effect
        The effect.

    Returns
    -------
    int
        The index.
    """
    k = [e.name for e in model.effects].index(effect.name)
    return model.n_theta + sum(model.n_q[:k])


def candidate_starts(effect, model, base_theta, seeds: dict) -> list:
    """Start vectors of a candidate fit: from ``base_theta`` and from the nominal coefficients,
    each with the effect's own starts and its seed.

    Parameters
    ----------
    effect : Effect
        The candidate effect.
    model : SimulationModel
        The candidate model (it contains ``effect``).
    base_theta : ndarray
        The reference fit's free coefficients.
    seeds : dict
        ``{effect name: seed}`` (:meth:`~bayesid.models.effects.Effect.diagnosis_seed`).

    Returns
    -------
    list of tuple
        ``(p0, nuisance0 or None)`` per start.
    """
    out = []
    for th in (base_theta, None):
        p = model.start(th)
        # the effect need not be the model's first (greedy rounds)
        out += effect.fit_starts(p, effect_offset(model, effect), model, seeds.get(effect.name))
    return out


def extended_nuisance(model, ref_model, ref_fit):
    """The reference fit's per-track nuisances padded with zeros for the model's extra ones.

    Parameters
    ----------
    model : SimulationModel
        The extended model.
    ref_model : SimulationModel
        The model it extends.
    ref_fit : FitResult
        The reference fit.

    Returns
    -------
    list of ndarray or None
        Per track, the nuisances (None when ``model`` has none).
    """
    if not model.n_nuisance:
        return None
    return [
        np.concatenate([np.asarray(v, float), np.zeros(model.n_nuisance - ref_model.n_nuisance)])
        for v in ref_fit.nuisance
    ]


def nested_start(effect, model, ref_model, ref_fit):
    """The start of the extended model at the reference fit's optimum with the effect at its
    ``neutral`` value, where the model reproduces the reference model.

    Parameters
    ----------
    effect : Effect
        The effect appended last.
    model : SimulationModel
        ``ref_model`` plus ``effect``.
    ref_model : SimulationModel
        The model it extends.
    ref_fit : FitResult
        The reference fit.

    Returns
    -------
    tuple or None
        ``(p0, nuisance0)``; None when the effect does not nest the reference model.
    """
    if effect.neutral is None:
        return None
    return np.concatenate([ref_fit.p, np.asarray(effect.neutral, float)]), extended_nuisance(model, ref_model, ref_fit)


@dataclass(frozen=True)
class CandidateFit:
    """One candidate of a diagnosis round: a task of :func:`fit_candidate`.

    Parameters
    ----------
    effect : Effect
        The candidate effect.
    ref : Stage
        The model it extends (the base, or the base with the effects already chosen).
    model : SimulationModel
        ``ref.model`` plus ``effect``.
    ctx_train : list of TrackContext
        The training contexts of ``model``.
    ctx_held : list of TrackContext
        Its held-out contexts.
    sd_fit : dict
        ``{channel: sd}``, the base fit's channel weights (every candidate is fitted with them,
        so costs and BICs compare).
    seeds : dict
        ``{effect name: seed}`` of the candidates that have one.
    max_nfev : int
        Least-squares iterations of each fit.
    label : str, optional
        Progress-bar label of the fits (tqdm on stderr), None for no bar.
    """

    effect: object
    ref: Stage
    model: object
    ctx_train: list
    ctx_held: list
    sd_fit: dict
    seeds: dict
    max_nfev: int
    label: str | None = None


def fit_candidate(task: CandidateFit) -> tuple[Stage | None, list]:
    """Fit a candidate's model on the training contexts from every start and score it.

    Every start of :func:`candidate_starts` is fitted (effects already chosen keep their fitted
    values), the best kept, the nested start tried when that is worse than the reference, and
    the best scored on the training and held-out contexts (held-out nuisances fitted with the
    parameters held). A module-level function of a picklable argument: the diagnosis runs the
    candidates of a round as tasks (:class:`bayesid.tasks.Runner`), in this process or in
    workers.

    Parameters
    ----------
    task : CandidateFit
        The candidate, the model it extends and the fit settings.

    Returns
    -------
    stage : Stage or None
        None when every fit failed.
    messages : list of str
        About failed starts.
    """
    effect, ref, model, sd_fit, label = task.effect, task.ref, task.model, task.sd_fit, task.label
    ctx_train, ctx_held = task.ctx_train, task.ctx_held
    problem = WindowProblem(model, ctx_train, sd_fit, max_nfev=task.max_nfev)
    messages = []
    best = None
    for p0, nu0 in candidate_starts(effect, model, ref.fit.p[: ref.model.n_theta], task.seeds):
        if ref.model.effects:  # effects already chosen keep their fitted values as the start
            p0 = p0.copy()
            p0[: ref.model.n_params] = ref.fit.p
            if nu0 is None and ref.model.n_nuisance:
                nu0 = extended_nuisance(model, ref.model, ref.fit)
        try:
            f = problem.fit(p0, nu0, bar=label)
        except Exception as exc:  # noqa: BLE001 - a failed candidate is reported
            messages.append(f"{effect.name} failed: {exc}")
            continue
        if best is None or f.cost < best.cost:
            best = f
    nested = nested_start(effect, model, ref.model, ref.fit)
    if nested is not None and (best is None or best.cost > ref.fit.cost):
        # a candidate that nests the model it extends cannot fit worse than it
        try:
            # from the reference fit's window starts too, where the candidate's cost equals the
            # reference's: a cold start of the start-state problem can land in another optimum
            f = problem.fit(*nested, starts0=warm_starts(ref.fit, ctx_train))
            if best is None or f.cost < best.cost:
                best = f
        except Exception as exc:  # noqa: BLE001
            messages.append(f"{effect.name} (nested start) failed: {exc}")
    if best is None:
        return None, messages
    return score_stage(model, best, ctx_train, ctx_held, sd_fit), messages


#: An effect parameter whose Laplace sd exceeds this many times the effect's typical size of it
#: (``Effect.scale``) is not determined by the training runs (issue 69: on two 5 Hz AUV runs without
#: a velocity log a current was fitted at half the truth with sds of 5.6 m/s, 56 times its 0.1 m/s)
UNDETERMINED_SCALES = 10.0
#: Singular values of the column-scaled Jacobian under this share of the largest are directions the
#: residuals do not move (:func:`parameter_sds`)
NULL_RCOND = 1e-10


def parameter_sds(fit: FitResult, effect) -> dict | None:
    """Laplace sds of an effect's fitted parameters, marginal over every other fitted variable.

    Gauss-Newton at the optimum, ``(J^T J)^-1 s2`` with ``s2 = SSR / (n - k)``, from the SVD of the
    Jacobian with its columns scaled to unit norm; without the AR(1) inflation of
    :func:`~bayesid.estimation.laplace.fit_covariance`: a lower bound of the sd, so that a
    parameter it calls undetermined is so at least by this much. A parameter with a share in a
    direction the residuals do not move (singular value under :data:`NULL_RCOND` of the largest:
    a zero column, or one the others reproduce) has an infinite sd, where a pseudo-inverse would
    give it none.

    Parameters
    ----------
    fit : FitResult
        The candidate's fit (its Jacobian ``jac``, shape (n_res, n_x), and ``names``).
    effect : Effect
        The candidate effect.

    Returns
    -------
    dict or None
        ``{parameter: sd}`` in the parameter's unit; None when the fit has no Jacobian.
    """
    if fit.jac is None:
        return None
    J = fit.jac.toarray() if hasattr(fit.jac, "toarray") else np.asarray(fit.jac, float)
    if not np.isfinite(J).all():
        return None
    s2 = fit.cost / max(J.shape[0] - J.shape[1], 1)
    # the SVD of the column-scaled Jacobian: a parameter with a share in a direction the residuals do
    # not move (a zero column, or one a combination of the others) has an infinite sd; a pseudo-inverse
    # would give it none
    norms = np.linalg.norm(J, axis=0)
    unit = np.where(norms > 0, norms, 1.0)
    _, sv, Vt = np.linalg.svd(J / unit, full_matrices=False)
    null = sv <= NULL_RCOND * (sv[0] if sv.size else 0.0)
    var = s2 * ((Vt[~null] / sv[~null, None]) ** 2).sum(axis=0) / unit**2
    unknown = (norms == 0) | (np.abs(Vt[null]) > 1e-6).any(axis=0)
    sd = np.where(unknown, np.inf, np.sqrt(var))
    index = {n: j for j, n in enumerate(fit.names)}
    keys = {p: f"{effect.name}.{p}" for p in effect.params}
    return {p: float(sd[index[k]]) for p, k in keys.items() if k in index}


def undetermined_parameters(effect, sds: dict | None) -> list[str]:
    """The parameters of an effect the training runs do not determine: Laplace sd (``sds``,
    :func:`parameter_sds`) above :data:`UNDETERMINED_SCALES` times the effect's typical size
    (``Effect.scale``).

    Parameters
    ----------
    effect : Effect
        The candidate effect.
    sds : dict or None
        ``{parameter: sd}``; None gives none.

    Returns
    -------
    list of str
        The parameters, in the effect's order.
    """
    if not sds:
        return []
    return [p for p, sc in zip(effect.params, effect.scale) if sds.get(p, 0.0) > UNDETERMINED_SCALES * abs(sc)]


#: A candidate that nests the model it extends failed its fit when its training cost ends above that
#: model's by more than this share (:func:`candidate_row`): the nested start reproduces the model.
FAILED_FIT_SHARE = 1e-6


def failed_fit(effect, st: Stage, ref: Stage) -> str | None:
    """Why a candidate's fit failed, or None: an effect with a ``neutral`` value nests the model it
    extends, so its best fit can only end at or under that model's training cost; one that ends
    above it by more than :data:`FAILED_FIT_SHARE` did not converge (issue 69: on 5 Hz AUV runs a
    delay's training ΔBIC read +6,142), and its ΔBIC and held-out scores are not evidence.

    Parameters
    ----------
    effect : Effect
        The candidate effect.
    st : Stage
        The fitted candidate.
    ref : Stage
        The model it extends.

    Returns
    -------
    str or None
        The sentence, or None when the fit is not known to have failed.
    """
    if effect.neutral is None or not st.fit.cost > ref.fit.cost * (1.0 + FAILED_FIT_SHARE):
        return None
    return (
        f"its fit ended at a training cost of {st.fit.cost:.6g}, above the {ref.fit.cost:.6g} of the model it extends, "
        "which it contains with the effect at its neutral value: the fit failed (a local optimum), and its ΔBIC and "
        "held-out scores are not evidence about the effect"
    )


def candidate_row(effect, st: Stage, ref: Stage, floor_rms: float, excess0: float) -> CandidateRow:
    """The ranking's record of a fitted candidate against the model it extends.

    Parameters
    ----------
    effect : Effect
        The candidate effect.
    st : Stage
        The fitted candidate.
    ref : Stage
        The model it extends.
    floor_rms : float
        The noise floor's RMS position error, m.
    excess0 : float
        The base model's excess over the floor, m.

    Returns
    -------
    CandidateRow
        Held-out and training RMS position error (m), training ΔBIC, share of the reference's
        excess over the floor it removes (``excess_removed``) and of the base model's
        (``share_of_excess``), held-out shrinkage, its parameters, heading RMS (deg), the paired
        window test's p-value, cost (``nfev``, ``fit_seconds``); ``role`` None (the round's
        verdict sets it, :func:`~bayesid.analysis.gap.verdict.assign_roles`); ``failed_fit``
        (:func:`failed_fit`).
    """
    excess = ref.held.rms_position_m - floor_rms
    gain = ref.held.rms_position_m - st.held.rms_position_m
    sds = parameter_sds(st.fit, effect)
    return CandidateRow(
        effect=effect.name,
        heldout_rms_m=st.held.rms_position_m,
        train_rms_m=st.train.rms_position_m,
        delta_bic=st.fit.bic - ref.fit.bic,
        excess_removed=gain / excess if excess > 0 else 0.0,
        share_of_excess=gain / excess0 if excess0 > 0 else 0.0,
        heldout_shrinkage=1 - st.held.rms_position_m / ref.held.rms_position_m,
        parameters=st.fit.effect_parameters()[effect.name],
        heading_rms_deg=st.held.rms_heading_deg,
        window_p_value=paired_window_test(ref.windows, st.windows),
        nfev=st.fit.n_simulations,
        fit_seconds=st.fit.wall_s,
        parameter_sd=sds,
        undetermined=undetermined_parameters(effect, sds),
        failed_fit=failed_fit(effect, st, ref),
    )
