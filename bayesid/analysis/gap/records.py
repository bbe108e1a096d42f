"""The typed records of the gap diagnosis: the noise floor (:class:`NoiseFloor`), a ranked
candidate effect (:class:`CandidateRow`), what the rounds leave (:class:`Remainder`), the base-fit
check (:class:`BaseCheck`), a refitted term of structure discovery (:class:`TermRow`) and a run of
the design (:class:`DesignedRun`, with the run test's outlook, :class:`RunTestOutlook`).

Each is a :class:`bayesid.protocol.Record` (the package's one record base, which
:class:`bayesid.protocol.Scores` is too): a frozen dataclass that also reads as the JSON dict it
writes (``row["heldout_rms_m"]``, ``dict(row)``, ``row.get(...)``); :meth:`Record.to_dict` gives the
``diagnosis.json`` object key for key and in order, :meth:`Record.from_dict` reads it back.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import ClassVar

from ...models.runs import other_speed_note, with_rpm_scaled
from ...protocol import Record, Scores, read_float

__all__ = [
    "Record",
    "NoiseFloor",
    "CandidateRow",
    "Remainder",
    "Contribution",
    "ThrustCheck",
    "ApproachCheck",
    "FirstRoundSummary",
    "BaseCheck",
    "TermRow",
    "PairOutlook",
    "RunTestOutlook",
    "DesignedRun",
    "pair_label",
    "pair_of",
]


@dataclass(frozen=True, eq=False)
class NoiseFloor(Record):
    """The noise floor: the protocol's error of a model of the right form at the measured noise
    level, scored with the fitted coefficients (a perfect model) or with draws from their
    uncertainty (:func:`bayesid.analysis.gap.verdict.noise_floor`; ``Diagnosis.noise_floor``).

    Parameters
    ----------
    heldout_rms_m : float
        RMS position error on the synthetic held-out tracks, m.
    heading_rms_deg : float
        Heading RMS, deg.
    by_channel : dict
        ``{channel: RMS error}``, SI (``x``, ``y`` m, ``psi`` rad, ``u``, ``v`` m/s, ``r`` rad/s).
    coefficient_draws : int, optional
        With ``DiagnoseOptions(floor="coefficients")``: the number of coefficient vectors drawn
        from the base fit's inverse Fisher information at the noise
        (:func:`~bayesid.analysis.gap.verdict.coefficient_draws`) each noisy copy was scored
        with; None: the fitted coefficients alone (the noise alone).
    diverged_share : float, optional
        With ``coefficient_draws``: the share of the draws' windows whose simulation diverged
        (left out of the RMS).
    """

    heldout_rms_m: float
    heading_rms_deg: float
    by_channel: dict
    coefficient_draws: int | None = None
    diverged_share: float | None = None

    _WHAT: ClassVar[str] = "noise_floor"
    _OPTIONAL: ClassVar[tuple] = ("coefficient_draws", "diverged_share")

    @classmethod
    def of(cls, scores: Scores) -> NoiseFloor:
        """The floor of the protocol's scores of the synthetic tracks.

        Parameters
        ----------
        scores : Scores
            :func:`bayesid.protocol.pooled_scores` of the synthetic held-out tracks.

        Returns
        -------
        NoiseFloor
            Their position RMS, heading RMS and RMS by channel.
        """
        return cls(scores["rms_position_m"], scores["rms_heading_deg"], scores["rms"])


@dataclass(frozen=True, eq=False)
class CandidateRow(Record):
    """A candidate effect fitted on top of the model it extends, as the ranking and the rounds
    record it (:func:`bayesid.analysis.gap.candidates.candidate_row`; ``Diagnosis.ranking``,
    ``Diagnosis.rounds``).

    Parameters
    ----------
    effect : str
        The effect's name.
    heldout_rms_m : float
        Held-out RMS position error with the effect, m.
    train_rms_m : float
        Training RMS position error, m.
    delta_bic : float
        Training BIC difference against the model it extends (negative: the effect is favoured).
    excess_removed : float
        Share of the extended model's held-out excess over the noise floor the effect removes.
    share_of_excess : float
        Share of the base model's excess it removes.
    heldout_shrinkage : float
        1 - held-out RMS with the effect / without it.
    parameters : dict
        The effect's fitted parameters (unit in the name), and ``per_track_nuisance`` where the
        effect has per-track ones.
    heading_rms_deg : float
        Held-out heading RMS, deg.
    window_p_value : float
        One-sided paired window test (Wilcoxon) that the effect's held-out windows are better.
    nfev : int
        Simulations of the fit.
    fit_seconds : float
        Wall time of the fit, s.
    role : str or None
        ``"cause"``, ``"contributor"`` or None, by the verdict's rules
        (:func:`~bayesid.analysis.gap.verdict.assign_roles`; None until the round is judged).
    parameter_sd : dict or None
        Laplace sd of each fitted parameter of the effect (units in the name), marginal over the
        model's other parameters (:func:`~bayesid.analysis.gap.candidates.parameter_sds`); None
        where the fit has no Jacobian (left out of the JSON then).
    undetermined : list of str
        The parameters whose sd exceeds :data:`~bayesid.analysis.gap.candidates.UNDETERMINED_SCALES`
        times the effect's typical size (``Effect.scale``): the training runs do not determine
        them, and the candidate's fitted values and held-out test say nothing either way.
    failed_fit : str or None
        Why the fit failed, when the effect nests the model it extends (its ``neutral`` value
        reproduces it) and the fit still ended above that model's training cost: a failed fit, not
        evidence against the effect (:func:`~bayesid.analysis.gap.candidates.candidate_row`); None
        (left out of the JSON) otherwise.
    """

    effect: str
    heldout_rms_m: float
    train_rms_m: float
    delta_bic: float
    excess_removed: float
    share_of_excess: float
    heldout_shrinkage: float
    parameters: dict
    heading_rms_deg: float
    window_p_value: float
    nfev: int
    fit_seconds: float
    role: str | None = None
    parameter_sd: dict | None = None
    undetermined: list = field(default_factory=list)
    failed_fit: str | None = None

    _OPTIONAL: ClassVar[tuple] = ("parameter_sd", "failed_fit")
    _WHAT: ClassVar[str] = "candidate"


@dataclass(frozen=True, eq=False)
class Remainder(Record):
    """What the model after the rounds leaves of the gap (``Diagnosis.remainder``).

    Parameters
    ----------
    heldout_rms_m : float
        Held-out RMS position error after the rounds, m.
    fraction_of_excess : float
        Its excess over the noise floor as a share of the base model's (0 when the base model has
        none).
    significant : bool
        Whether the gap was significant and the held-out error is still above the floor band.
    """

    heldout_rms_m: float
    fraction_of_excess: float
    significant: bool

    _WHAT: ClassVar[str] = "remainder"


@dataclass(frozen=True, eq=False)
class Contribution(Record):
    """An effect that improves the held-out windows significantly without closing the gap, added
    or not (``Diagnosis.contributors``; :func:`bayesid.analysis.gap.verdict.contribution`).

    Parameters
    ----------
    effect : str
        The effect.
    added : bool
        Whether it was added to the model.
    share_of_excess : float
        The share of the base model's excess over the floor it removes.
    heldout_rms_m : float
        Held-out RMS position error with it, m.
    window_p_value : float
        The paired window test's p against the model it extends.
    delta_bic : float
        Its training ΔBIC.
    parameters : dict
        Its fitted parameters.
    """

    effect: str
    added: bool
    share_of_excess: float
    heldout_rms_m: float
    window_p_value: float
    delta_bic: float
    parameters: dict

    _WHAT: ClassVar[str] = "contributor"


@dataclass(frozen=True, eq=False)
class ThrustCheck(Record):
    """The fitted model's propeller thrust against a logged one (``Diagnosis.where["thrust"]``;
    :func:`bayesid.analysis.gap.where.where`).

    Parameters
    ----------
    tracks : int
        The tracks that log the thrust.
    logged_mean_n, model_mean_n : float
        The logged and the model's mean thrust, N.
    bias_fraction : float or None
        Model / logged mean - 1.
    rms_n : float
        RMS of model - logged thrust, N.
    error_corr_abs_beta_p : float or None
        Correlation of the thrust deficit (logged - model) with the propeller's drift angle's size.
    missing_x_rms_n : float
        The missing surge force's RMS (inverse dynamics), N.
    missing_x_rms_logged_thrust_n : float
        The same with the logged thrust in place of the model's, N.
    propeller_share : float or None
        1 - the squared ratio of the two: the share of the missing surge force's mean square the
        thrust error carries (negative: the fit absorbed the thrust error in other surge terms).
    """

    tracks: int
    logged_mean_n: float
    model_mean_n: float
    bias_fraction: float | None
    rms_n: float
    error_corr_abs_beta_p: float | None
    missing_x_rms_n: float
    missing_x_rms_logged_thrust_n: float
    propeller_share: float | None

    _WHAT: ClassVar[str] = "thrust check"


@dataclass(frozen=True, eq=False)
class ApproachCheck(Record):
    """Each run's propulsion point against the fitted model's (``Diagnosis.where["approach"]``;
    :func:`bayesid.analysis.gap.where.approach_check`): at the rpm a run logs on its approach, the
    speed the model settles at, against the approach speed the run measures. A run from another
    basin, model, propeller or rpm control is at another point; no coefficient fitted on the
    training runs carries that, and the model's speed drifts towards its own point on every
    straight leg of such a run.

    Parameters
    ----------
    runs : list of dict
        Per run: ``run``, ``role`` (``"training"``, ``"held-out"``), ``seconds``, ``speed_m_s``,
        ``rpm``, ``accel_m_s2``, ``rudder_moved`` (:func:`bayesid.models.runs.run_approach`),
        ``model_speed_m_s``, ``speed_error`` (model / measured - 1) and ``steady`` (the speed
        changes by at most :data:`~bayesid.models.runs.APPROACH_UNSTEADY` over the samples read). Held-out rows also
        ``matched_rpm`` (the rpm the model needs for the run's approach speed; for a run at another
        point, the rpm that puts it at the training runs' point, its ``speed_error`` theirs) and ``off`` (a
        steady approach more than :data:`~bayesid.models.runs.APPROACH_TOLERANCE` from the training runs' median
        ``speed_error`` and outside their range: another propulsion point).
    training_error : float or None
        The median ``speed_error`` of the steady training approaches.
    heldout_error : float or None
        The median ``speed_error`` of the held-out runs at another point, or of every steady
        held-out approach when none is.
    another_point : bool
        Some held-out run is at another point.
    heldout_rms_m, matched_heldout_rms_m : float, optional
        The base model's held-out RMS position error with the logged rpm, and with the rpm of
        each run at another point scaled to its ``matched_rpm`` (its propulsion point matched to
        its own approach, the first seconds the window protocol also starts from), m.
    floor_rms_m : float, optional
        The held-out noise floor, m.
    share_of_excess : float, optional
        ``(heldout - matched) / (heldout - floor)``: the share of the held-out excess the other
        propulsion point carries.
    rediagnosed : bool, optional
        True when the diagnosis was made again with those runs' rpm matched
        (``DiagnoseOptions.heldout_propeller="approach"``): every candidate was judged on them.
    """

    runs: list
    training_error: float | None
    heldout_error: float | None
    another_point: bool
    heldout_rms_m: float | None = None
    matched_heldout_rms_m: float | None = None
    floor_rms_m: float | None = None
    share_of_excess: float | None = None
    rediagnosed: bool | None = None

    _OPTIONAL: ClassVar[tuple] = (
        "heldout_rms_m",
        "matched_heldout_rms_m",
        "floor_rms_m",
        "share_of_excess",
        "rediagnosed",
    )
    _WHAT: ClassVar[str] = "approach check"

    @property
    def off_runs(self) -> list:
        """The held-out runs at another propulsion point."""
        return [r["run"] for r in self.runs if r["role"] == "held-out" and r.get("off")]

    def matched(self, tracks: list) -> list:
        """The held-out tracks with the rpm of each run at another point matched to its approach:
        the run's ``n`` scaled by ``matched_rpm / rpm`` (the others as they are).

        Parameters
        ----------
        tracks : list of Track
            The held-out tracks (the rows' ``run`` names).

        Returns
        -------
        list of Track
            Copies where a run is matched.
        """
        factor = {
            r["run"]: r["matched_rpm"] / r["rpm"]
            for r in self.runs
            if r["role"] == "held-out" and r.get("off") and r.get("matched_rpm")
        }
        return [tr if tr.name not in factor else with_rpm_scaled(tr, factor[tr.name]) for tr in tracks]

    def with_scores(self, heldout_rms_m: float, matched_heldout_rms_m: float, floor_rms_m: float) -> ApproachCheck:
        """The check with the held-out scores of the base model with the logged and the matched rpm.

        Parameters
        ----------
        heldout_rms_m, matched_heldout_rms_m, floor_rms_m : float
            As the fields, m.

        Returns
        -------
        ApproachCheck
            A copy with ``share_of_excess`` (None when the held-out error is within the floor).
        """
        excess = heldout_rms_m - floor_rms_m
        share = (heldout_rms_m - matched_heldout_rms_m) / excess if excess > 0 else None
        return replace(
            self,
            heldout_rms_m=float(heldout_rms_m),
            matched_heldout_rms_m=float(matched_heldout_rms_m),
            floor_rms_m=float(floor_rms_m),
            share_of_excess=None if share is None else float(share),
        )

    def sentence(self) -> str:
        """The check in words.

        Returns
        -------
        str
            Whether the held-out runs are at the training runs' propulsion point, naming those
            that are not and (when scored) the share of the excess their point carries; empty
            when no held-out approach could be read.
        """
        if self.heldout_error is None:
            return ""
        train = "" if self.training_error is None else f", against {self.training_error:+.1%} on the training runs"
        if not self.another_point:
            n_h = sum(1 for r in self.runs if r["role"] == "held-out" and r["steady"])
            return (
                f"At the rpm each run logs on its approach, the fitted model settles at a speed "
                f"{self.heldout_error:+.1%} off the measured approach speed of the held-out runs (median of {n_h})"
                f"{train}: the held-out runs are at the training runs' propulsion point."
            )
        off = self.off_runs
        names = ", ".join(off[:5]) + (f" and {len(off) - 5} more" if len(off) > 5 else "")
        speeds = other_speed_note(
            [r["speed_m_s"] for r in self.runs if r.get("off")],
            [r["speed_m_s"] for r in self.runs if r["role"] == "training" and r["steady"]],
        )
        text = (
            f"At the rpm they log on their approach, the fitted model settles at a speed {self.heldout_error:+.1%} off "
            f"the measured approach speed of held-out run(s) {names}{train}: **{'it is' if len(off) == 1 else 'they are'}"
            " at another propulsion point** (another basin, model, propeller or rpm control). No coefficient fitted "
            "on the training runs carries it: on every straight leg the model's speed drifts towards its own point, "
            "so u misses there whatever the hull's terms (the propulsion_point candidate shifts the wake for every "
            f"run alike){speeds}."
        )
        if self.matched_heldout_rms_m is not None:
            share = self.share_of_excess
            if share is None:
                reading = "."
            elif share >= 0:
                reading = f": {share:.0%} of the excess over the floor."
            else:
                reading = (
                    ": matching the rpm makes it worse, so the other point is not the rpm's scale alone (the "
                    "propeller's loading, and the rudder's inflow with it, differ too)."
                )
            text += (
                f" With the rpm of {'that run' if len(off) == 1 else 'those runs'} set to the training runs' point "
                f"for {'its' if len(off) == 1 else 'their'} own approach speed, the base model's held-out RMS goes from "
                f"{self.heldout_rms_m:.3g} m to {self.matched_heldout_rms_m:.3g} m (floor {self.floor_rms_m:.3g} m)"
                f"{reading}"
            )
        if self.rediagnosed:
            text += (
                f" Every candidate below was judged with {'that run' if len(off) == 1 else 'those runs'} at the "
                "matched rpm (--heldout-propeller approach): the verdict is about what the model misses once the "
                "propulsion point is set aside."
            )
        else:
            text += (
                " To judge the candidates with the held-out runs at their own point, diagnose again with "
                '--heldout-propeller approach (DiagnoseOptions(heldout_propeller="approach") in the Python API).'
            )
        return text


@dataclass(frozen=True, eq=False)
class FirstRoundSummary(Record):
    """Discovery beside round 1 against round 1's best effect (``Diagnosis.discovery_first``;
    :func:`bayesid.analysis.gap.diagnose.discovery_beside_round_one`).

    Parameters
    ----------
    found : list of str
        The terms discovery kept on the base model.
    verdict : str
        Its verdict.
    heldout_rms_m : float
        Held-out RMS position error with them, m.
    effect, effect_role : str
        Round 1's best effect and its role.
    effect_heldout_rms_m : float
        Held-out RMS position error with that effect, m.
    role : str or None
        The terms' role by the rounds' rules (None: nothing kept).
    window_p_value, share_of_effect_excess : float or None
        The paired window test of the terms' model against the effect's, and the share of the
        effect's excess over the floor the terms remove.
    took_round : bool
        Whether the terms took round 1.
    seconds : float
        Wall time.
    train_starts : str
        The base fit's training window starts the search ran on (``"fitted"``, ``"kinematic"``).
    other_starts : dict, optional
        The search on the other base fit's starts (its starts, terms and held-out RMS).
    discovered : list of dict, optional
        The kept terms' numbers when they did not take the round.
    """

    found: list
    verdict: str
    heldout_rms_m: float
    effect: str
    effect_role: str
    effect_heldout_rms_m: float
    role: str | None
    window_p_value: float | None
    share_of_effect_excess: float | None
    took_round: bool
    seconds: float
    train_starts: str
    other_starts: dict | None = None
    discovered: list | None = None

    _OPTIONAL: ClassVar[tuple] = ("other_starts", "discovered")
    _WHAT: ClassVar[str] = "discovery beside round 1"


@dataclass(frozen=True, eq=False)
class BaseCheck(Record):
    """Whether the base fit can be trusted (:func:`bayesid.analysis.gap.diagnose.base_fit_check`;
    ``Diagnosis.base_check``).

    Parameters
    ----------
    train_rms_at_window_m : float
        RMS position error on the training tracks under the held-out protocol (same window,
        same start rule), m.
    heldout_rms_m : float
        The base model's held-out RMS position error, m.
    ratio : float
        Held-out / training RMS under the same protocol (inf with a zero training error).
    threshold : float
        The ratio above which the fit is suspect
        (:data:`~bayesid.analysis.gap.diagnose.BASE_FIT_RATIO`).
    starts : dict or None
        The start check (:func:`~bayesid.analysis.gap.diagnose.start_check`: ``n_windows``,
        ``n_flagged``, ``fraction_flagged``, ``by_set``, ``worst``, ``suspect``, ``message``, ...);
        None under the measured start rule.
    suspect : bool
        Either test failed.
    message : str
        What the check found, and what to rule out first when suspect.
    train_starts : dict, optional
        Under ``--train-starts auto`` when the fitted starts were inconsistent:
        ``fitted_train_rms_at_window_m``, ``kinematic_train_rms_at_window_m`` (m) and ``used``
        (``"fitted"`` or ``"kinematic"``); left out of the JSON when None.
    multistart : dict or None
        The base fit's extra starts (``n_starts``, ``default_cost``, ``best_cost``,
        ``improved``, ``distinct_optima``); None without extra starts (written as null).
    """

    train_rms_at_window_m: float
    heldout_rms_m: float
    ratio: float
    threshold: float
    starts: dict | None
    suspect: bool
    message: str
    train_starts: dict | None = None
    multistart: dict | None = None

    _OPTIONAL: ClassVar[tuple] = ("train_starts",)
    _WHAT: ClassVar[str] = "base_check"


#: The fields of a :class:`TermRow` that only a refit gives, in order.
REFIT_FIELDS = (
    "coefficient",
    "coefficient_sd",
    "heldout_rms_after_m",
    "train_rms_after_m",
    "shrinkage",
    "delta_bic",
    "refit_failed",
    "window_p_value",
    "heldout_windows_after_m",
    "excess_removed",
    "worst_run",
)


@dataclass(frozen=True, eq=False)
class TermRow(Record):
    """A refitted candidate term of structure discovery, with the kept test's decision (an item of
    ``Discovery.discovered``; :func:`~bayesid.analysis.gap.discovery.confirmation.refit_row`,
    :func:`~bayesid.analysis.gap.discovery.confirmation.decide`).

    Parameters
    ----------
    term : str
        The term's name, as the vehicle file writes it (``Nabsdr``).
    dof : str
        Its force or moment (``X``, ``Y``, ``N``).
    inclusion_probability : float
        The ensemble's inclusion probability of the term (0 for a term refitted on top of
        others).
    group_inclusion_probability : float
        That of its collinear group.
    group : list of str
        Its collinear alternatives.
    regression_coefficient : float
        The linearised regression's coefficient (prime).
    heldout_rms_before_m : float
        Held-out RMS position error of the model it extends, m.
    train_rms_before_m : float
        Training RMS position error of that model, m.
    coefficient : float or None
        The refit's coefficient of the term (prime).
    coefficient_sd : float or None
        Its Laplace sd (AR(1)-inflated; None when the covariance failed).
    heldout_rms_after_m : float or None
        Held-out RMS position error of the refit, m.
    train_rms_after_m : float or None
        Its training RMS position error, m.
    shrinkage : float or None
        1 - held-out RMS after / before. Written twice: also as ``heldout_shrinkage`` (an alias,
        the key the contributor test reads, :func:`~bayesid.analysis.gap.verdict.is_contributor`;
        ``row["heldout_shrinkage"]`` and ``row.heldout_shrinkage`` give this value).
    delta_bic : float or None
        Training BIC difference against the model it extends.
    refit_failed : bool or None
        The refit ended above its reference's cost (a failed fit, not evidence against the term).
    window_p_value : float or None
        One-sided paired window test (Wilcoxon) that the refit's held-out windows are better.
    heldout_windows_after_m : list of float or None
        The refit's RMS position error of each held-out window, m.
    excess_removed : float or None
        Share of the reference's excess over the noise floor the term removes.
    worst_run : dict or None
        The held-out run the refit predicts worst against the reference (``run``,
        ``error_ratio``, ``p_value``; :func:`~bayesid.analysis.gap.discovery.confirmation.worst_run`),
        None when no run is worse.
    refitted_as : str or None
        ``"selected"`` by the ensemble, ``"alternative"`` by the score test, ``"mimicked"`` (set
        aside as mimicked by the selection and refitted all the same,
        :func:`~bayesid.analysis.gap.discovery.selection.mimicked_refits`), ``"tied"`` (a member of
        a kept term's collinear group explaining at least half its share in the score test,
        :func:`~bayesid.analysis.gap.discovery.selection.tied_companions`) or ``"compared"``
        (asked for, ``DiscoveryOptions.compare``: an earlier round's terms); None for a term
        refitted on top of others (left out of the JSON).
    kept : bool or None
        Whether it passed the kept test; None until decided (left out of the JSON).
    reason : str or None
        Why it was kept or not; None until decided (left out of the JSON).

    Notes
    -----
    When every fit of the term failed, the refit's fields (:data:`REFIT_FIELDS`, from
    ``coefficient`` to ``worst_run``) are None and left out of the JSON, and ``refitted_as`` is
    written after ``reason`` (the order those rows have always had).
    """

    term: str
    dof: str
    inclusion_probability: float
    group_inclusion_probability: float
    group: list
    regression_coefficient: float
    heldout_rms_before_m: float
    train_rms_before_m: float
    coefficient: float | None = None
    coefficient_sd: float | None = None
    heldout_rms_after_m: float | None = None
    train_rms_after_m: float | None = None
    shrinkage: float | None = None
    delta_bic: float | None = None
    refit_failed: bool | None = None
    window_p_value: float | None = None
    heldout_windows_after_m: list | None = None
    excess_removed: float | None = None
    worst_run: dict | None = None
    refitted_as: str | None = None
    kept: bool | None = None
    reason: str | None = None

    _OPTIONAL: ClassVar[tuple] = ("refitted_as", "kept", "reason")
    _ALIASES: ClassVar[dict] = {"heldout_shrinkage": "shrinkage"}
    _WHAT: ClassVar[str] = "discovered term"

    @property
    def refitted(self) -> bool:
        """Whether a fit of the term converged (the refit's fields are set)."""
        return self.heldout_rms_after_m is not None

    @property
    def heldout_shrinkage(self) -> float | None:
        """Alias of :attr:`shrinkage`."""
        return self.shrinkage

    def _keys(self) -> tuple:
        keys = super()._keys()
        if self.refitted:
            return keys
        keys = tuple(k for k in keys if k not in REFIT_FIELDS and k not in self._ALIASES)
        late = tuple(k for k in keys if k == "refitted_as")
        return tuple(k for k in keys if k != "refitted_as") + late


def pair_label(pair: tuple) -> str:
    """The JSON key of a pair of alternatives, ``"A vs B"``.

    Parameters
    ----------
    pair : tuple of str
        ``(a, b)``.

    Returns
    -------
    str
        ``"a vs b"``.
    """
    return f"{pair[0]} vs {pair[1]}"


def pair_of(label: str) -> tuple:
    """The pair of a JSON key :func:`pair_label` wrote.

    Parameters
    ----------
    label : str
        ``"A vs B"``.

    Returns
    -------
    tuple of str
        ``(A, B)``.

    Raises
    ------
    ValueError
        A key without `` vs `` (named).
    """
    a, sep, b = str(label).partition(" vs ")
    if not sep:
        raise ValueError(f"designed run: {label!r} is not a pair 'A vs B'")
    return a, b


def _pairs_json(pairs: dict, value=lambda v: v) -> dict:
    return {pair_label(k): value(v) for k, v in pairs.items()}


def _pairs_read(d: Mapping, value=lambda v: v) -> dict:
    return {pair_of(k): value(v) for k, v in d.items()}


@dataclass(frozen=True, eq=False)
class PairOutlook(Record):
    """The run test's outlook on one pair of a designed run (the kept term against an
    alternative; :func:`bayesid.analysis.gap.design.run_test_windows`).

    Parameters
    ----------
    expected_ratio : float or None
        The expected window error ratio if either model is right (None where not finite).
    windows_needed : float or None
        The protocol windows the run test needs to find it with its power (``inf``: never;
        None without the held-out runs' scatter).
    """

    expected_ratio: float | None
    windows_needed: float | None

    _WHAT: ClassVar[str] = "run-test outlook of a pair"


@dataclass(frozen=True, eq=False)
class RunTestOutlook(Record):
    """The run test's outlook on a designed run (:func:`bayesid.analysis.gap.design.design`).

    Parameters
    ----------
    windows : int
        The run's protocol windows.
    log_sd : float or None
        The held-out runs' within-run sd of log window-error ratios (None: too few windows).
    pairs : dict
        ``{(kept, alternative): PairOutlook}``; written with ``"A vs B"`` keys.
    sized_from_s : float or None
        The menu's duration when sizing lengthened the run, s; None when it did not.
    """

    windows: int
    log_sd: float | None
    pairs: dict
    sized_from_s: float | None = None

    _WHAT: ClassVar[str] = "run-test outlook"

    def __getitem__(self, key: str):  # the mapping reads as the JSON, pairs keyed "A vs B"
        return self.to_dict()[key]

    def to_dict(self) -> dict:
        """The outlook as its JSON object (pairs keyed ``"A vs B"``).

        Returns
        -------
        dict
            ``windows``, ``log_sd``, ``pairs``, ``sized_from_s``.
        """
        d = super().to_dict()
        d["pairs"] = _pairs_json(self.pairs, lambda v: v.to_dict())
        return d

    @classmethod
    def from_dict(cls, d: Mapping):
        """The outlook of a JSON object :meth:`to_dict` wrote.

        Parameters
        ----------
        d : Mapping
            The JSON object.

        Returns
        -------
        RunTestOutlook
            The outlook, its pairs keyed ``(a, b)``.

        Raises
        ------
        ValueError
            A key it lacks or does not have, or a pair key not ``"A vs B"`` (named).
        """
        d = dict(d)
        if "pairs" in d:
            d["pairs"] = _pairs_read(d["pairs"], PairOutlook.from_dict)
        return super().from_dict(d)


@dataclass(frozen=True, eq=False)
class DesignedRun(Record):
    """A run of the design's menu, scored (:func:`bayesid.analysis.gap.design.design`): how well it
    separates the alternatives, and what the run test could decide on it.

    Parameters
    ----------
    kind, rudder_deg, check_deg, side, rpm, duration_s, name : object
        The run (:class:`bayesid.models.runs.ManoeuvreRun`): kind, rudder angle (deg), check angle
        (deg, a zigzag's; None otherwise), side, rpm, duration (s) and its name.
    separation : float
        The smallest divergence (nats) over the pairs that rank the runs
        (:func:`~bayesid.analysis.gap.design.rank_by_separable_pairs`).
    worst_pair : tuple of str
        That pair.
    pairs : dict
        ``{(a, b): divergence}``, nats (NaN where not finite).
    max_position_difference_m : float
        The largest distance between two alternatives' predicted positions at one sample, m.
    run_test : RunTestOutlook
        The run test's outlook on this run.
    inputs : dict or None
        ``{"t" s, "delta_r" rad, "n" rpm}``: the input schedule (kept for the best runs).
    predicted : dict or None
        ``{label: {"t", "x", "y", "psi"}}``: the predictions, for the figure (the best run's).
    menu_inseparable : dict or None
        ``{(a, b): {"best_run", "separation"}}``: the pairs no run of the menu separates; set by
        the ranking.
    decidable_pairs : list of tuple or None
        The pairs the run test could decide on this run
        (:func:`~bayesid.analysis.gap.design.decidable_pairs`); set by the ranking.
    inputs_csv : str or None
        The file of the input schedule, relative to the diagnosis's folder, where the report
        wrote it (``diagnosis.json`` holds it in place of ``inputs``).

    Notes
    -----
    Every pair is written as ``"A vs B"`` (:func:`pair_label`) in the JSON.
    """

    kind: str
    rudder_deg: float
    check_deg: float | None
    side: str
    rpm: float
    duration_s: float
    name: str
    separation: float
    worst_pair: tuple
    pairs: dict
    max_position_difference_m: float
    run_test: RunTestOutlook
    inputs: dict | None = None
    predicted: dict | None = None
    menu_inseparable: dict | None = None
    decidable_pairs: list | None = None
    inputs_csv: str | None = None

    _OPTIONAL: ClassVar[tuple] = ("inputs", "predicted", "menu_inseparable", "decidable_pairs", "inputs_csv")
    _WHAT: ClassVar[str] = "designed run"

    def __getitem__(self, key: str):  # the mapping reads as the JSON, pairs keyed "A vs B"
        return self.to_dict()[key]

    def to_dict(self) -> dict:
        """The run as its JSON object, the pairs keyed ``"A vs B"``.

        Returns
        -------
        dict
            The fields in order, the None ones of ``_OPTIONAL`` left out.
        """
        d = super().to_dict()
        d["worst_pair"] = pair_label(self.worst_pair)
        d["pairs"] = _pairs_json(self.pairs)
        d["run_test"] = self.run_test.to_dict()
        if self.menu_inseparable is not None:
            d["menu_inseparable"] = _pairs_json(self.menu_inseparable, dict)
        if self.decidable_pairs is not None:
            d["decidable_pairs"] = [pair_label(p) for p in self.decidable_pairs]
        return d

    @classmethod
    def from_dict(cls, d: Mapping):
        """The run of a JSON object :meth:`to_dict` wrote (``diagnosis.json``'s ``design`` rows).

        Parameters
        ----------
        d : Mapping
            The JSON object.

        Returns
        -------
        DesignedRun
            The run, its pairs keyed ``(a, b)``.

        Raises
        ------
        ValueError
            A key it lacks or does not have, or a pair key not ``"A vs B"`` (named).
        """
        d = dict(d)
        if "worst_pair" in d:
            d["worst_pair"] = pair_of(d["worst_pair"])
        if "pairs" in d:
            d["pairs"] = _pairs_read(d["pairs"], read_float)
        if "run_test" in d:
            d["run_test"] = RunTestOutlook.from_dict(d["run_test"])
        if d.get("menu_inseparable") is not None:
            d["menu_inseparable"] = _pairs_read(d["menu_inseparable"], dict)
        if d.get("decidable_pairs") is not None:
            d["decidable_pairs"] = [pair_of(p) for p in d["decidable_pairs"]]
        return super().from_dict(d)
