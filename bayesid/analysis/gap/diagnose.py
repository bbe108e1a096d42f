"""The orchestration of the gap diagnosis: base fit, noise floor, *where*, greedy rounds of
candidates, verdict, support (the rules: :mod:`bayesid.analysis.gap`)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, fields, replace
from functools import cache, partial
from types import SimpleNamespace

import numpy as np

from ...estimation.fit import FitResult
from ...estimation.indices import manoeuvre_kind
from ...estimation.multistart import multistart
from ...estimation.options import check_rudder_rate_reading
from ...estimation.windows import (
    START_Z,
    WindowProblem,
    check_enough_data,
    contexts,
    evaluate,
    fit_weighted,
    pooled_noise_sd,
    scores,
)
from ...models import default_dt, model_class
from ...models.context import INPUT_RECONSTRUCTIONS
from ...protocol import start_settings
from ...tasks import Runner, Task, TaskError, record_fields
from .candidates import BaseStage, CandidateFit, Setup, Stage, candidate_row, fit_candidate
from .design import design, standard_predictions
from .discovery import Discovery, discover, routed, with_terms
from .records import (
    BaseCheck,
    CandidateRow,
    Contribution,
    DesignedRun,
    FirstRoundSummary,
    NoiseFloor,
    Record,
    Remainder,
)
from .support import signature_regression
from .verdict import (
    DivergedSimulation,
    Thresholds,
    assign_roles,
    coefficient_draws,
    contribution,
    gap_summary,
    is_cause,
    noise_floor,
    paired_window_test,
    verdict_of,
)
from .where import approach_check, where

__all__ = [
    "DiagnoseOptions",
    "Diagnosis",
    "FirstRound",
    "catalogue_candidates",
    "diagnose",
    "discovery_beside_round_one",
    "base_fit_check",
    "discovered_terms",
    "worse_on_other_kinds",
    "BASE_FIT_RATIO",
]


@dataclass
class Diagnosis:
    """The result of :func:`diagnose`. Every field but ``base`` and ``after`` is JSON-able
    (:meth:`to_dict`, the ``diagnosis.json`` document).

    Parameters
    ----------
    verdict : str
        ``"none"``, ``"unexplained"`` or the effects added joined by ``+`` (with
        ``+unexplained`` when a significant remainder is left).
    effects_added : list of str
        The effects added, in the order added.
    cause : str or None
        The effect that closes the gap, or None.
    contributors : list of Contribution
        Every effect that passed the contributor test (added or not), with its share, p-value,
        ΔBIC and parameters.
    remainder : Remainder
        What is left (RMS m, fraction, significant).
    ranking : list of CandidateRow
        Round 1's candidates, best first.
    rounds : list of list of CandidateRow
        Every round's candidates.
    gap_before : dict
        Scores of the base model.
    gap_after : dict
        Scores of the model after the rounds: every effect added (and discovery's terms when
        they took round 1, ``discovery_first``).
    heldout_shrinkage : float
        1 - after / before held-out RMS position error.
    noise_floor : NoiseFloor
        The perfect model's scores.
    gap_ratio : float
        Before / floor.
    significant_gap : bool
        Whether the gap is significant.
    where : dict
        The summary of :func:`~bayesid.analysis.gap.where.where`.
    sindy_support : dict
        ``{effect: inclusion probability}`` (or ``error``).
    noise_sd : dict
        ``{channel: sd}`` of the data (SI).
    fit_sd : dict
        ``{channel: sd}`` of the fits' weights (SI).
    base_fit : dict
        Coefficients (and effect parameters) of the base model.
    after_fit : dict
        Those of the model after the rounds (as ``gap_after``).
    train_tracks : list of str
        Names of the training tracks.
    heldout_tracks : list of str
        Names of the held-out tracks.
    settings : dict
        What was run.
    thresholds : Thresholds
        The verdict's thresholds (in the JSON as :meth:`~.verdict.Thresholds.as_dict`).
    seconds : float
        Wall time.
    round_seconds : list of float
        Wall time of each candidate round.
    discovery : Discovery or None
        Structure discovery (:class:`~bayesid.analysis.gap.discovery.Discovery`: every refitted
        term in ``discovered``; with its models when computed, without them when read back) on
        the model after the effects, or on the base model when its terms took round 1
        (``discovery_first``); None when it was not run (``{}`` in the JSON). The one copy:
        :attr:`discovered` is the same object.
    discovery_first : FirstRoundSummary or dict
        Discovery beside round 1 (:func:`discovery_beside_round_one`): whether discovery's terms
        on the base model beat round 1's best catalogue effect, with both held-out RMS and the
        paired window test; ``{}`` when round 1 had no effect to add or discovery was not run.
    gap_discovered : dict
        Scores of the model with the terms discovery kept after the rounds (as ``gap_before``;
        ``gap_after`` is the model without them); ``{}`` when discovery kept none there or its
        terms took round 1 (``gap_after`` then has them).
    base_check : BaseCheck
        Whether the base fit can be trusted (:func:`base_fit_check`), with ``multistart``: the
        extra starts' summary (``DiagnoseOptions.base_starts``), or None; ``{}`` in a diagnosis
        read from a JSON file that has no check.
    design : list of DesignedRun
        The runs that would separate the first kept term with alternatives from them, best first
        (:func:`bayesid.analysis.gap.design.design`,
        :class:`~bayesid.analysis.gap.records.DesignedRun`; the predicted tracks only in the first,
        the input schedules in the first three);
        empty when every kept term is separable or discovery was not run.
    predictions : list of dict
        The standard manoeuvres (35 deg turning circles both ways, zigzags 10/10 and 20/20) as the
        base model, the first kept term with alternatives and each alternative predict them, with
        the spread over parameter draws
        (:func:`bayesid.analysis.gap.design.standard_predictions`); empty with ``design``.
    manoeuvre_kinds : dict
        ``{"train": [...], "heldout": [...]}``: the standard manoeuvre each run resembles
        (:func:`bayesid.estimation.indices.manoeuvre_kind`); when the held-out kinds are all
        among the training kinds, every item of ``discovered`` has
        ``tested_only_within_training_manoeuvres: true``.
    base : Stage, optional
        The base model as a :class:`~bayesid.analysis.gap.candidates.Stage` (model, fit,
        scores, nuisances) for plots; not in :meth:`to_dict`.
    after : Stage, optional
        The model after the rounds (as ``gap_after``), likewise.
    setup : Setup, optional
        What every model of the diagnosis shares (vehicle, free coefficients, tracks, windows);
        not in :meth:`to_dict`.
    discovered_terms : list, optional
        The top-level ``discovered`` list (:func:`discovered_terms`), computed once by
        :func:`diagnose` or read back from the JSON (:meth:`from_dict`) and written as it is by
        :meth:`to_dict`, so a diagnosis computed and one read back take the same path: every
        refitted term (:meth:`~bayesid.analysis.gap.discovery.Discovery.terms`), the final model's
        with ``kept: true``, each kept one with the ``alternatives`` the runs cannot separate from
        it. Stored, not recomputed: ``worse_on_other_kinds`` needs the reference model's held-out
        scores, which the JSON does not keep.
    """

    verdict: str
    effects_added: list
    cause: str | None
    contributors: list
    remainder: Remainder
    ranking: list
    rounds: list
    gap_before: dict
    gap_after: dict
    heldout_shrinkage: float
    noise_floor: NoiseFloor
    gap_ratio: float
    significant_gap: bool
    where: dict
    sindy_support: dict
    noise_sd: dict
    fit_sd: dict
    base_fit: dict
    after_fit: dict
    train_tracks: list
    heldout_tracks: list
    settings: dict
    thresholds: Thresholds
    seconds: float
    round_seconds: list = field(default_factory=list)
    discovery: Discovery | None = None
    discovery_first: FirstRoundSummary | dict = field(default_factory=dict)
    gap_discovered: dict = field(default_factory=dict)
    base_check: BaseCheck | dict = field(default_factory=dict)
    design: list[DesignedRun] = field(default_factory=list)
    predictions: list = field(default_factory=list)
    manoeuvre_kinds: dict = field(default_factory=dict)
    base: Stage = field(repr=False, default=None)
    after: Stage = field(repr=False, default=None)
    setup: Setup = field(repr=False, default=None)
    discovered_terms: list | None = field(repr=False, default=None)

    _HIDDEN = ("base", "after", "setup", "discovered_terms")

    @property
    def discovered(self) -> Discovery | None:
        """Structure discovery's result: :attr:`discovery` (the name the CLI and the API have read
        it by)."""
        return self.discovery

    def to_dict(self) -> dict:
        """The JSON-able fields, in order (the models are left out).

        Returns
        -------
        dict
            ``{field: value}`` (the records as their JSON objects), and ``discovered``: the
            top-level list of discovered terms.
        """
        out = {f.name: _plain(getattr(self, f.name)) for f in fields(self) if f.name not in self._HIDDEN}
        out["discovery"] = self.discovery.to_dict() if self.discovery is not None else {}
        out["discovered"] = [dict(i) for i in self.discovered_terms or []]
        return out

    @classmethod
    def from_dict(cls, d: dict) -> Diagnosis:
        """The diagnosis read back from its JSON (``diagnosis.json``, or :meth:`to_dict`): every
        JSON field, without the models (``base``, ``after``, ``setup`` are None, and
        ``discovery`` has none); the top-level ``discovered`` list is kept as written and
        :meth:`to_dict` writes it again.

        Parameters
        ----------
        d : dict
            The JSON object.

        Returns
        -------
        Diagnosis
            The diagnosis; ``Diagnosis.from_dict(x).to_dict() == x``.

        Raises
        ------
        ValueError
            A key the diagnosis does not have, or a required one missing (named).
        """
        readers = {  # the records' fields, read back as records
            "remainder": Remainder.from_dict,
            "noise_floor": NoiseFloor.from_dict,
            "ranking": lambda rows: [CandidateRow.from_dict(r) for r in rows],
            "rounds": lambda rounds: [[CandidateRow.from_dict(r) for r in rnd] for rnd in rounds],
            "base_check": lambda c: BaseCheck.from_dict(c) if c else c,
            "contributors": lambda cs: [Contribution.from_dict(c) for c in cs],
            "discovery_first": lambda f: FirstRoundSummary.read(f) if f else f,
            "thresholds": Thresholds.from_dict,
            "design": lambda rows: [DesignedRun.from_dict(r) for r in rows],
            "discovery": lambda D: Discovery.from_dict(D) if D else None,
        }
        args = record_fields(cls, d, "diagnosis", skip=cls._HIDDEN, extra=("discovered",))
        args = {k: readers[k](v) if k in readers else v for k, v in args.items()}
        return cls(**args, discovered_terms=list(d.get("discovered") or []))


def discovered_terms(found, heldout_tracks: list, manoeuvre_kinds: dict, thresholds: Thresholds) -> list:
    """The top-level ``discovered`` list of a diagnosis (issue 40's contract): every refitted term
    of discovery (:meth:`~bayesid.analysis.gap.discovery.Discovery.terms`), the final model's with
    ``kept: true``, each with ``tested_only_within_training_manoeuvres`` (every held-out run is of
    a kind the training runs have: the held-out test says nothing of the other kinds) and, when
    kept, ``worse_on_other_kinds`` (:func:`worse_on_other_kinds`).

    Parameters
    ----------
    found : Discovery or None
        Structure discovery's result (None: no discovery ran).
    heldout_tracks : list of str
        The held-out runs' names.
    manoeuvre_kinds : dict
        ``{"train": [kind], "heldout": [kind]}`` (:func:`~bayesid.estimation.indices.manoeuvre_kind`).
    thresholds : Thresholds
        The diagnosis's thresholds (``separation_margin``).

    Returns
    -------
    list of dict
        The terms (empty without discovery).
    """
    if found is None:
        return []
    out = found.terms()
    within = set(manoeuvre_kinds.get("heldout", [])) <= set(manoeuvre_kinds.get("train", []))
    reference = getattr(getattr(found, "reference", None), "held", None) or {}
    for item in out:  # a held-out test of the same kinds says nothing of the others
        item["tested_only_within_training_manoeuvres"] = bool(manoeuvre_kinds) and within
        item["worse_on_other_kinds"] = (
            worse_on_other_kinds(item, reference, heldout_tracks, manoeuvre_kinds, thresholds) if item["kept"] else []
        )
    return out


def worse_on_other_kinds(
    item: dict, reference, heldout_tracks: list, manoeuvre_kinds: dict, thresholds: Thresholds | None = None
) -> list:
    """The held-out runs of a kind the training runs lack on which a kept term's single-term refit
    predicts worse than the reference model by more than the separation margin
    (``thresholds.separation_margin``, 10 %; a smaller excess is within what refits of equally
    good structures differ by): a term chosen on one kind of run that does not carry to another.

    Parameters
    ----------
    item : dict
        A term of :func:`discovered_terms` (``heldout_rms_by_run_m``).
    reference : Mapping
        The reference model's held-out scores (``per_track_rms_position_m``).
    heldout_tracks : list of str
        The held-out runs' names, parallel to ``manoeuvre_kinds["heldout"]``.
    manoeuvre_kinds : dict
        ``{"train": [kind], "heldout": [kind]}``.
    thresholds : Thresholds, optional
        Its ``separation_margin`` counts (default :class:`Thresholds`'s).

    Returns
    -------
    list of dict
        ``[{"run", "kind", "rms_m", "reference_rms_m"}]``.
    """
    base = (reference or {}).get("per_track_rms_position_m", {})
    mine = item.get("heldout_rms_by_run_m") or {}
    train = set(manoeuvre_kinds.get("train", []))
    margin = float((thresholds or Thresholds()).separation_margin)
    out = []
    for run, kind in zip(heldout_tracks, manoeuvre_kinds.get("heldout", [])):
        if kind in train or run not in mine or run not in base:
            continue
        if mine[run] > base[run] * (1.0 + margin):
            out.append({"run": run, "kind": kind, "rms_m": mine[run], "reference_rms_m": base[run]})
    return out


#: How the training fits of a diagnosis get their window starts (:class:`DiagnoseOptions`).
TRAIN_STARTS = ("fitted", "kinematic", "auto")
#: What the noise floor holds (:attr:`DiagnoseOptions.floor`).
FLOORS = ("noise", "coefficients")
#: The propeller speed the held-out runs are driven with (:attr:`DiagnoseOptions.heldout_propeller`).
HELDOUT_PROPELLERS = ("logged", "approach", "matched")


@dataclass(frozen=True)
class DiagnoseOptions:
    """What a gap diagnosis fits and compares (:func:`diagnose`).

    Parameters
    ----------
    candidates : tuple, optional
        Effects, as names of the model family's ``CATALOGUE`` or
        :class:`~bayesid.models.effects.Effect` objects; any sequence is stored as a tuple.
        None: the whole catalogue less the effects whose columns (``needs_columns``, e.g. the
        measured wind) not every track has (:func:`catalogue_candidates`).
    window_s : float or None, default 60.0
        The protocol window (s) of the held-out scores; None: the whole run.
    fit_window_s : float, optional
        The window of the multiple-shooting fits on the training tracks; None: the family's
        ``default_fit_window(window_s)`` (ship :data:`bayesid.models.ship.FIT_WINDOW_S`,
        submarine ``window_s``).
    dt : float, optional
        The model step (s); None: the vehicle's default (:func:`bayesid.models.default_dt`).
    mode : str, default "horizontal"
        The submarine equations (``"horizontal"``, ``"6dof"``, ...).
    max_nfev : int, default 60
        Least-squares iterations of each fit.
    max_effects : int, default 2
        Greedy rounds (after a contributor, try the others on top of it; a cause ends the search).
    weighting : str, optional
        Channel weights of the fits (:func:`~bayesid.estimation.windows.fit_weighted`); None: the
        family's. The base fit sets the weights; every candidate is fitted with the same weights,
        so their costs and BICs compare.
    start : str, default "auto"
        The window start-state rule (:data:`bayesid.protocol.START_RULES`), the same for every
        model compared, the training fits and the noise floor.
    leadin_s : float, optional
        The lead-in of the fitted rule on the held-out tracks (s); None:
        :func:`bayesid.protocol.start_settings`.
    base_starts : int, default 0
        Extra Latin-hypercube starts of the base fit (:func:`bayesid.estimation.multistart.multistart`,
        with the base fit's channel weights); the best optimum is the base model when it beats the
        default start's. 0: the default start alone.
    base_effects : tuple, default ()
        Effects of the base model (names or objects; e.g. those of a fitted model.json): every
        model compared has them, the candidates are tried on top.
    discover : DiscoveryOptions or None, default None
        Run structure discovery (:func:`bayesid.analysis.gap.discovery.discover`): beside round 1
        on the base model when round 1 has an effect to add (the model with its terms is one more
        candidate of the round; when it ranks first, the effects are tried on top of it:
        :func:`discovery_beside_round_one`), else on the model after the effects when its
        remainder is significant; None: not run.
    train_starts : {"fitted", "kinematic", "auto"}, default "fitted"
        Under the fitted start rule, the training fits' window starts: fitted with the model,
        held at the tracks' kinematics (:func:`bayesid.estimation.shooting.kinematic_contexts`),
        or ``"auto"``: fitted, unless the base-fit check finds them inconsistent with the
        kinematics, in which case the base model is refitted with held starts and the setup
        whose base fit predicts its own training tracks better under the held-out protocol is
        used for every fit of the diagnosis (``base_check["train_starts"]``).
    design : DiscriminationOptions or None, default None
        When given (and discovery names alternatives it cannot separate from a kept term), rank
        the standard runs that would separate them (:func:`bayesid.analysis.gap.design.design`).
    inputs : {"hold", "linear", "rate"}, default "hold"
        How every model of the diagnosis reconstructs the logged inputs between samples
        (:data:`bayesid.models.context.INPUT_RECONSTRUCTIONS`; :func:`bayesid.models.build_model`):
        ``"rate"`` moves the rudder at the gear's rate, for logs coarse for it (1-5 Hz).
    rudder_rate_deg_s : float, optional
        The gear's rate of ``inputs="rate"``, deg/s; None: the vehicle file's
        (``[service] rudder_rate_deg_s``).
    heldout_propeller : {"logged", "approach", "matched"}, default "logged"
        The propeller speed of the held-out runs. ``"approach"`` (a model with a propeller
        model: a ship's): when *Where*'s propulsion-point check finds held-out runs at another
        point than the training runs (:func:`~bayesid.analysis.gap.where.approach_check`: another
        basin, model, propeller or rpm control), the diagnosis is made again with each such run's
        logged rpm scaled to put it at the training runs' point (the fitted base model missing its
        approach speed as it misses theirs),
        so that every candidate is judged on the held-out runs without the point's difference
        (``where["approach"]`` keeps the check, with ``rediagnosed`` true). ``bayesid predict
        --propeller approach`` matches the same way to the model's own point (it has no training
        runs). ``"matched"``: the held-out runs given were
        matched so already (the second diagnosis of ``"approach"``): *Where* still reads their
        approach, but says nothing of it.
    floor : {"coefficients", "noise"}, default "coefficients"
        What the noise floor holds (:func:`~bayesid.analysis.gap.verdict.noise_floor`). ``"noise"``:
        the fitted model's error on its own simulations of the held-out runs at the measured
        noise (a perfect model's). ``"coefficients"``: the same simulations scored with
        coefficients drawn from the base fit's inverse Fisher information at the noise
        (:func:`~bayesid.analysis.gap.verdict.coefficient_draws`):
        the error of a model of the right form known only as well as the training runs tell it,
        so that a held-out run the training runs do not determine (a turn after zigzags) is not
        read as a missing effect. Every test against the floor (the gap's significance, a
        cause's band, the shares of the excess) uses it.

    Raises
    ------
    ValueError
        ``train_starts``, ``inputs``, ``heldout_propeller`` or ``floor`` not among the choices;
        ``rudder_rate_deg_s`` not positive, or given with another reading than ``"rate"``.
    """

    candidates: tuple | None = None
    window_s: float | None = 60.0
    fit_window_s: float | None = None
    dt: float | None = None
    mode: str = "horizontal"
    max_nfev: int = 60
    max_effects: int = 2
    weighting: str | None = None
    start: str = "auto"
    leadin_s: float | None = None
    base_starts: int = 0
    base_effects: tuple = ()
    discover: object = None
    train_starts: str = "fitted"
    design: object = None
    inputs: str = "hold"
    rudder_rate_deg_s: float | None = None
    heldout_propeller: str = "logged"
    floor: str = "coefficients"

    def __post_init__(self):
        if self.floor not in FLOORS:
            raise ValueError(f"floor must be one of {', '.join(FLOORS)}, not {self.floor!r}")
        if self.train_starts not in TRAIN_STARTS:
            raise ValueError(f"train_starts must be one of {', '.join(TRAIN_STARTS)}, not {self.train_starts!r}")
        if self.heldout_propeller not in HELDOUT_PROPELLERS:
            raise ValueError(
                f"heldout_propeller must be one of {', '.join(HELDOUT_PROPELLERS)}, not {self.heldout_propeller!r}"
            )
        if self.inputs not in INPUT_RECONSTRUCTIONS:
            raise ValueError(f"inputs must be one of {', '.join(INPUT_RECONSTRUCTIONS)}, not {self.inputs!r}")
        r = self.rudder_rate_deg_s
        if r is not None and not (math.isfinite(r) and r > 0):
            raise ValueError(f"rudder_rate_deg_s must be a positive number of deg/s, not {r!r}")
        check_rudder_rate_reading(self.inputs, r)
        if self.candidates is not None and not isinstance(self.candidates, tuple):
            object.__setattr__(self, "candidates", tuple(self.candidates))
        object.__setattr__(self, "base_effects", tuple(self.base_effects))


def catalogue_candidates(family, tracks: list, runner: Runner = Runner(), free=(), vehicle=None) -> list[str]:
    """The effects of a model family's catalogue that the tracks can inform: those whose
    columns (``needs_columns``, e.g. the measured wind) every track has, (a family with
    ``effect_clash``, the ship) that set no coefficient the base model fits, and (a family with
    ``effect_unsupported``, the submarine) that the vehicle file can carry (the crossflow effect
    needs its ``[crossflow]`` section). The candidates of :func:`diagnose` when
    ``DiagnoseOptions.candidates`` is None (and of ``bayesid diagnose`` without ``--candidates``).

    Parameters
    ----------
    family : type
        The model class (:func:`bayesid.models.model_class`), with its ``CATALOGUE``.
    tracks : list of Track
        Every track of the diagnosis (training and held-out).
    runner : Runner, default Runner()
        Receives one message per effect left out, naming it and the columns it needs or the free
        coefficients it sets.
    free : iterable of str, default ()
        The base model's free coefficients.
    vehicle : Vehicle or Ship, optional
        The vehicle (None: no effect is left out for it).

    Returns
    -------
    list of str
        The catalogue's names, in its order, less those left out.
    """
    names = []
    for name, effect in family.CATALOGUE.items():
        need = effect.needs_columns
        clash = family.effect_clash(effect, free) if hasattr(family, "effect_clash") else []
        why = None
        if vehicle is not None and hasattr(family, "effect_unsupported"):
            why = family.effect_unsupported(effect, vehicle)
        if why:
            runner.say(f"{why}: the {name} candidate is left out")
        elif clash:
            runner.say(
                f"the base model fits {', '.join(clash)}, which the {name} effect sets: the {name} candidate is "
                "left out (free its coefficient from the base fit to test it)"
            )
        elif all(c in t for t in tracks for c in need):
            names.append(name)
        else:
            runner.say(f"no {', '.join(need)} columns in every track: the {name} candidate is left out")
    return names


def diagnose(
    vehicle,
    free,
    train: list,
    heldout: list,
    options: DiagnoseOptions = DiagnoseOptions(),
    thresholds: Thresholds = Thresholds(),
    *,
    rng=None,
    runner: Runner = Runner(),
) -> Diagnosis:
    """Diagnose the sim-to-real gap of a base model (see :mod:`bayesid.analysis.gap`).

    Parameters
    ----------
    vehicle : Vehicle or Ship
        The nominal vehicle (its model family comes from :func:`bayesid.models.build_model`).
    free : list of str or None
        Coefficient names the fits change; None: the family's default (the ship file's ``[fit]
        free``, the submarine's ``Yv, Yr, Nv, Nr, Ydr, Ndr``), as ``bayesid diagnose`` without
        ``--free``.
    train : list of Track
        The training tracks.
    heldout : list of Track
        The held-out tracks (disjoint from ``train``).
    options : DiagnoseOptions, default DiagnoseOptions()
        Candidates, windows, step, iterations, greedy rounds, weighting and start rule.
    thresholds : Thresholds, default Thresholds()
        The verdict's thresholds (:class:`~bayesid.analysis.gap.verdict.Thresholds`).
    rng : numpy.random.Generator, optional
        Noise-floor simulation and the bootstrap of the signature regression (default seed 0).
    runner : Runner, default Runner()
        Where the candidates of a round are fitted and where progress messages go
        (:class:`bayesid.tasks.Runner`); with a progress reporter, every fit in this process
        shows a progress bar. The candidates are independent and each fit is deterministic, so
        the verdict, ranking and every number equal a serial run's (only the timings differ).

    Returns
    -------
    Diagnosis
        The verdict, the ranking of every round, the scores before and after and the evidence.

    design : DiscriminationOptions or None, default None
        When discovery keeps a term that the runs cannot separate from its alternatives, rank
        the standard manoeuvres by how well each would separate them
        (:func:`bayesid.analysis.gap.design.design`); None: not.

    Raises
    ------
    ValueError
        Empty or overlapping track sets; an unknown effect (named); too little data.
    KeyError
        An unknown coefficient (named).

    Examples
    --------
    The gap of NPS AUV II's model fitted on two zigzags, judged on a held-out turning circle
    (track files written by ``bayesid simulate``, as in the quickstart, or your own logs), with
    every effect of the catalogue as a candidate, two fits at a time, progress printed:

    >>> import bayesid
    >>> vehicle = bayesid.load_any_vehicle("nps_auv2")
    >>> train = [bayesid.read_csv(f) for f in ("z10.csv", "z20.csv")]
    >>> heldout = [bayesid.read_csv("t15.csv")]
    >>> free = ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"]
    >>> runner = bayesid.Runner(jobs=2, progress=print)
    >>> d = bayesid.diagnose(vehicle, free, train, heldout, bayesid.DiagnoseOptions(window_s=30.0), runner=runner)
    >>> d.verdict, [r["effect"] for r in d.ranking]  # doctest: +SKIP

    Structure discovery alone (the model terms the tracks say are missing), as ``bayesid
    discover`` runs it: no catalogue effect, discovery when the gap is significant:

    >>> options = bayesid.DiagnoseOptions(window_s=30.0, candidates=(), discover=bayesid.DiscoveryOptions())
    >>> d = bayesid.diagnose(vehicle, free, train, heldout, options)
    >>> [t["term"] for t in d.to_dict()["discovered"] if t["kept"]]  # doctest: +SKIP
    """
    t_start = time.perf_counter()
    opt, th = options, thresholds
    rng = np.random.default_rng(0) if rng is None else rng
    if opt.heldout_propeller == "approach" and getattr(model_class(vehicle), "steady_speed", None) is None:
        raise ValueError(
            "heldout_propeller='approach': the model has no propeller model to match the held-out runs' rpm to "
            "(only a ship's model has one)"
        )
    family, setup, cand_effects, sd = _diagnosis_setup(vehicle, free, train, heldout, opt, runner)
    free = setup.free
    names_t, names_h, dt = [t.name for t in train], [t.name for t in heldout], setup.dt
    say = runner.say
    weighting = opt.weighting or family.DEFAULT_WEIGHTING
    b, alt = _checked_base(setup, sd, weighting, opt, runner)
    base, cho, bfit, sd_fit, base_ms = b.model, b.cho, b.fit, b.sd_fit, b.multistart
    b_train, b_held, check = b.train_scores, b.held_scores, b.check
    setup = b.setup
    if check.suspect:
        say(check.message)
    # A base fit bent by the missing effect can be more sensitive to start-state errors than
    # the vehicle is; the floor is the smaller of the fitted and the nominal model's.
    nominal = FitResult.fixed(base, base.start(), len(train), "nominal")
    # the noise itself, not the weights' lower bound (a 1 mm carriage track is not 1 cm noise)
    sd_raw = pooled_noise_sd(train + heldout, floor=False)
    floors, diverged = [], None
    dev = None
    if opt.floor == "coefficients":  # the fit's coefficient uncertainty, around either model
        dev = coefficient_draws(bfit) - bfit.p[None]
    for f in (bfit, nominal):
        try:
            draws = None if dev is None else np.clip(f.p[None] + dev, *base.bounds())
            floors.append(noise_floor(base, f, cho, heldout, sd_raw, rng, draws=draws))
        except DivergedSimulation as exc:  # the other one may hold (a base fit bent far off)
            say(str(exc))
            diverged = exc
    if not floors:
        raise diverged
    floor = min(floors, key=lambda d: d.heldout_rms_m)
    w, forces = where(b.held, bfit, heldout, sd, floor_by_channel=floor.by_channel)
    approach = approach_check(base, bfit.p, train, heldout)
    if approach is not None:
        if approach.another_point and not base.n_nuisance and opt.heldout_propeller != "matched":
            # how much of the gap the other point carries
            ctx_m = contexts(base, approach.matched(heldout), setup.window_s, setup.rule, leadin_s=setup.leadin_s)
            matched = evaluate(base, bfit.p, ctx_m).scores(sd_fit)
            approach = approach.with_scores(b_held["rms_position_m"], matched["rms_position_m"], floor.heldout_rms_m)
        if opt.heldout_propeller == "approach" and approach.another_point and not base.n_nuisance:
            first = (b_held["rms_position_m"], floor.heldout_rms_m)
            return _rediagnosed(approach, first, vehicle, free, train, heldout, opt, thresholds, rng, runner, t_start)
        w["approach"] = approach.to_dict()
        if approach.another_point and opt.heldout_propeller != "matched":
            say(approach.sentence().replace("**", ""))
    if opt.discover is not None:  # Where's dominant channel decides where the search starts
        searched, why = routed(opt.discover, w, base)
        if why is not None:
            say(f"discovery: {why}")
            w["discovery_routed"] = why
            opt = replace(opt, discover=searched)
    seeds = _seeds(cand_effects, b, train)
    significant = bool(b_held["rms_position_m"] > th.none_ratio * floor.heldout_rms_m)
    base_stage = b.stage()
    disc_context = {"sd_fit": sd_fit, "floor_rms": floor.heldout_rms_m, "thresholds": th}
    beside, held = None, None
    if opt.discover is not None and setup.train_starts == "fitted" and (check.starts or {}).get("suspect"):
        # fitted training starts that contradict the kinematics absorb part of what the model lacks:
        # discovery on the base model also searches the base refitted with them held (computed once)
        held = cache(partial(_held_start_base, alt, setup, sd=sd, weighting=weighting, opt=opt, runner=runner))
    if opt.discover is not None and significant:
        # its own stream, spawned without drawing from rng: a diagnosis where round 1 adds
        # nothing gets the same numbers as before this stage existed
        beside = partial(
            discovery_beside_round_one,
            setup,
            base_stage,
            options=opt.discover,
            context=dict(disc_context, held_starts=held),
            rng=rng.spawn(1)[0],
            runner=runner,
        )
    search = _greedy_rounds(
        setup,
        cand_effects,
        base_stage,
        CandidateFits(sd_fit, seeds, opt.max_nfev),
        Judge(floor, significant, th),
        opt.max_effects,
        runner,
        beside=beside,
    )
    after = search.after
    chosen, roles, ranking = search.chosen, search.roles, search.ranking
    contributors, remainder = _outcome(search, floor, b_held, significant, th)
    remainder_sig = remainder.significant
    support = _signature_support(family, cand_effects, base, forces, seeds, rng)
    first = search.discovery_first
    verdict, found, gap_discovered = _discovery_after_rounds(
        search, significant, remainder_sig, setup, opt, disc_context, held, rng, runner
    )
    designed, predictions = _design(found, setup, opt.design, runner)
    kinds = {"train": [manoeuvre_kind(t) for t in train], "heldout": [manoeuvre_kind(t) for t in heldout]}
    return Diagnosis(
        verdict=verdict,
        effects_added=chosen,
        cause=next((e for e in chosen if roles[e].role == "cause"), None),
        contributors=contributors,
        remainder=remainder,
        ranking=ranking,
        rounds=search.rounds,
        gap_before=gap_summary(b_train, b_held),
        gap_after=gap_summary(after.train, after.held),
        heldout_shrinkage=1 - after.held.rms_position_m / b_held["rms_position_m"],
        noise_floor=floor,
        gap_ratio=b_held["rms_position_m"] / floor.heldout_rms_m,
        significant_gap=significant,
        where=w,
        sindy_support=support,
        noise_sd=sd,
        fit_sd=sd_fit,
        base_fit={
            "coefficients": bfit.coefficients(),
            "nominal": dict(zip(base.free, base.theta0.tolist())),
            **{k: getattr(bfit, k) for k in ("bic", "n_residuals", "success")},
            "nfev": bfit.n_simulations,
        },
        after_fit={"coefficients": after.fit.coefficients(), "effects": after.fit.effect_parameters()},
        train_tracks=names_t,
        heldout_tracks=names_h,
        settings=dict(_settings(opt, setup, cand_effects, weighting), free=list(free), dt=dt),
        thresholds=th,
        seconds=time.perf_counter() - t_start,
        round_seconds=search.seconds,
        discovery=found,
        discovery_first=first.summary if first is not None else {},
        gap_discovered=gap_discovered,
        base_check=replace(check, multistart=base_ms),
        design=designed,
        predictions=predictions,
        manoeuvre_kinds=kinds,
        base=base_stage,
        after=after,
        setup=setup,
        discovered_terms=discovered_terms(found, names_h, kinds, th),
    )


def _rediagnosed(approach, first, vehicle, free, train, heldout, opt, thresholds, rng, runner, t_start) -> Diagnosis:
    """``heldout_propeller="approach"`` with held-out runs at another propulsion point: the
    diagnosis made again on the held-out runs with their rpm matched to their approach
    (:meth:`~bayesid.analysis.gap.records.ApproachCheck.matched`), its ``where["approach"]`` the
    check that found them (``rediagnosed`` true; scored with ``first``, the base model's held-out
    RMS and floor with the logged rpm, against the matched diagnosis's base held-out RMS), its
    settings and time this call's."""
    off = approach.off_runs
    runner.say(
        f"held-out run(s) {', '.join(off)} at another propulsion point: diagnosed again with their rpm matched to "
        "their approach (heldout_propeller approach)"
    )
    again = diagnose(
        vehicle,
        free,
        train,
        approach.matched(heldout),
        replace(opt, heldout_propeller="matched"),
        thresholds,
        rng=rng,
        runner=runner,
    )
    scored = approach.with_scores(first[0], again.gap_before["heldout_rms_m"], first[1])
    where = dict(again.where, approach=replace(scored, rediagnosed=True).to_dict())
    settings = dict(again.settings, heldout_propeller="approach")
    return replace(again, where=where, settings=settings, seconds=time.perf_counter() - t_start)


def _diagnosis_setup(vehicle, free, train: list, heldout: list, opt: DiagnoseOptions, runner: Runner) -> tuple:
    """The tracks checked and what every model of the diagnosis shares: ``(family, Setup, the
    candidate effects, the pooled noise sd)``.

    Raises
    ------
    ValueError
        No training or held-out track, or tracks in both; an unknown effect (named).
    """
    if not train or not heldout:
        raise ValueError("diagnose needs at least one training and one held-out track")
    names_t, names_h = [t.name for t in train], [t.name for t in heldout]
    overlap = set(names_t) & set(names_h)
    if overlap or any(a is b for a in train for b in heldout):
        raise ValueError(f"training and held-out tracks overlap: {sorted(overlap)}")
    family = model_class(vehicle)
    dt = default_dt(vehicle) if opt.dt is None else opt.dt
    free = family.default_free(vehicle) if free is None else list(free)
    if opt.candidates is None:
        names = catalogue_candidates(family, train + heldout, runner, free, vehicle)
    else:
        names = opt.candidates
    cand_effects = [family.get_effect(c) for c in names]
    sd = pooled_noise_sd(train + heldout)
    fw = opt.fit_window_s if opt.fit_window_s is not None else family.default_fit_window(opt.window_s)
    rule, lead = start_settings(opt.start, train + heldout, opt.window_s, dt, opt.leadin_s)
    base_effects = tuple(family.get_effect(e) for e in opt.base_effects)
    cand_effects = [e for e in cand_effects if e.name not in {b.name for b in base_effects}]
    setup = Setup(
        vehicle, free, train, heldout, dt, opt.mode, fw, opt.window_s, rule, lead, base_effects,
        train_starts="kinematic" if opt.train_starts == "kinematic" else "fitted", kinematic_sd=sd,
        inputs=opt.inputs, rudder_rate_deg_s=opt.rudder_rate_deg_s,
    )  # fmt: skip
    return family, setup, cand_effects, sd


def _checked_base(setup: Setup, sd: dict, weighting: str, opt: DiagnoseOptions, runner: Runner) -> tuple:
    """The base model fitted and checked (:func:`_base_stage`), and under ``train_starts="auto"``
    refitted with window starts held at the kinematics when the check finds the fitted ones
    inconsistent with them: ``(the base stage used, the held-start one or None)``; the used
    one's ``check.train_starts`` says which and why."""
    b = _base_stage(setup, sd, weighting, opt, runner)
    alt = None
    if opt.train_starts == "auto" and (b.check.starts or {}).get("suspect"):
        runner.say("base fit: window starts inconsistent with the kinematics; refit with starts held at them")
        alt = _base_stage(replace(setup, train_starts="kinematic"), sd, weighting, opt, runner)
        use = alt.check.train_rms_at_window_m < b.check.train_rms_at_window_m
        summary = {
            "fitted_train_rms_at_window_m": b.check.train_rms_at_window_m,
            "kinematic_train_rms_at_window_m": alt.check.train_rms_at_window_m,
            "used": "kinematic" if use else "fitted",
        }
        if use:
            b = alt
        b.check = replace(b.check, train_starts=summary)
    return b, alt


def _discovery_after_rounds(
    search: Rounds,
    significant: bool,
    remainder_sig: bool,
    setup: Setup,
    opt: DiagnoseOptions,
    disc_context: dict,
    held,
    rng,
    runner,
) -> tuple:
    """The verdict after the greedy rounds and the discovery that goes with it: ``(verdict,
    Discovery or None, gap summary with the discovered terms)``. Discovery's terms came first
    when its model took round 1 (the effects on top of them); otherwise discovery runs on the
    model after the effects while its remainder is significant (on the base model: with held
    window starts too). ``held``: the held-start base (a callable) or None."""
    after, chosen, first = search.after, search.chosen, search.discovery_first
    found = first.discovery if first is not None and first.took_round else None
    if found is not None:  # discovery's terms came first, the effects on top of them
        verdict = found.verdict.replace("+unexplained", "")
        verdict += (
            (" -> " + verdict_of(True, chosen, remainder_sig)) if chosen else ("+unexplained" if remainder_sig else "")
        )
        return verdict, found, {}
    verdict = verdict_of(significant, chosen, remainder_sig)
    if opt.discover is None or not remainder_sig:
        return verdict, None, {}
    runner.say("structure discovery")
    found = discover(
        setup,
        after,
        list(after.model.effects),  # in the model's own order (its parameter vector's)
        opt.discover,
        dict(disc_context, significant=remainder_sig),
        rng=rng,
        runner=runner,
    )
    if held is not None and not chosen:  # on the base model: the one with held starts too
        found, _ = _better_with_held_starts(found, held, opt.discover, disc_context, rng, runner)
    gap = gap_summary(found.after.train, found.after.held) if found.after is not None else {}
    return verdict + " -> " + found.verdict, found, gap


#: The label of the model without the discovered terms in a design against it
WITHOUT_TERMS = "without the term"


def _design(found, setup: Setup, options, runner: Runner) -> tuple[list, list]:
    """The runs that separate the first kept term with alternatives from them
    (:func:`bayesid.analysis.gap.design.design`), and the standard manoeuvres as the base model,
    that term and its alternatives predict them
    (:func:`bayesid.analysis.gap.design.standard_predictions`), for ``Diagnosis.design`` and
    ``Diagnosis.predictions``. A kept term the runs separate from every other, whose held-out
    runs are all of the training runs' kinds (tested only within the training manoeuvres), is
    designed against the model without it (:data:`WITHOUT_TERMS`): the run of another kind
    that would test it. ``([], [])`` without discovery, design options or a kept term."""
    if found is None or options is None:
        return [], []
    within = {manoeuvre_kind(t) for t in setup.heldout} <= {manoeuvre_kind(t) for t in setup.train}
    for k in found.found:
        # a term added on top of others, and its competitors, as refitted in its place
        pool = getattr(found, "combined_stages", {}).get(k) or found.stages
        if k not in pool:
            continue
        alts = [a["term"] for a in found.alternatives.get(k, []) if a["term"] in pool]
        if alts:
            runner.say(f"design: the run that separates {k} from {', '.join(alts)}")
            stages = {n: pool[n] for n in (k, *alts)}
        elif within and found.reference is not None:
            runner.say(f"design: the run of another kind that would test {k} (against the model without it)")
            stages = {k: found.stages[k], WITHOUT_TERMS: found.reference}
        else:
            continue
        rows = design(stages, setup, options)
        # the predicted tracks for the top run's figure, the input schedules of the top three
        rows = [
            r if i == 0 else replace(r, predicted=None) if i < 3 else replace(r, predicted=None, inputs=None)
            for i, r in enumerate(rows)
        ]
        runner.say("design: the standard manoeuvres as the base model and each alternative predict them")
        models = {"base model": found.reference, **{n: st for n, st in stages.items() if n != WITHOUT_TERMS}}
        return rows, standard_predictions(models, setup, options)
    return [], []


def _base_stage(setup: Setup, sd: dict, weighting: str, opt: DiagnoseOptions, runner: Runner) -> BaseStage:
    """The base model of ``setup`` fitted (with its extra starts), evaluated on the training and
    held-out tracks and checked (ValueError: too little data)."""
    base, ctr, cho = setup.build(())
    fw = setup.fit_window_s
    check_enough_data(base, ctr, fw if fw is not None else max(c.ts[-1] - c.t_start[0] for c in ctr))
    runner.say("base fit" + (" (window starts held at the kinematics)" if setup.train_starts == "kinematic" else ""))
    bfit, sd_fit = fit_weighted(
        WindowProblem(base, ctr, sd, max_nfev=opt.max_nfev), weighting=weighting, bar=runner.bar("base fit")
    )
    problem = WindowProblem(base, ctr, sd_fit, max_nfev=opt.max_nfev)
    bfit, base_ms = _base_multistart(problem, bfit, opt, runner)
    b = BaseStage(setup, problem, cho, bfit, base_ms, problem.evaluate(bfit.p), evaluate(base, bfit.p, cho), None)
    b.check = base_fit_check(base, bfit, setup, sd_fit, b.held_scores)
    return b


def _better_with_held_starts(found, held, options, context: dict, rng, runner: Runner) -> tuple:
    """Discovery on the base model refitted with its training window starts held at the
    kinematics (``held() -> (setup, Stage, sd_fit)``) beside ``found`` (the search on the base fit
    with fitted starts): ``(discovery, (setup, Stage) or None)``, the search with kept terms and
    the lower held-out RMS, with ``train_starts`` and ``other_starts`` (the other search's terms
    and held-out RMS) recorded in its settings, and the held-start base when that one is used."""
    runner.say("structure discovery on the base model with window starts held at the kinematics")
    setup_k, base_k, sd_k = held()
    found_k = discover(
        setup_k,
        base_k,
        list(base_k.model.effects),
        options,
        dict(context, significant=True, sd_fit=sd_k),
        rng=rng.spawn(1)[0],
        runner=runner,
    )
    better = bool(found_k.found) and (not found.found or found_k.heldout_rms_after_m < found.heldout_rms_after_m)
    use, other = (found_k, found) if better else (found, found_k)
    use.settings["train_starts"] = "kinematic" if better else "fitted"
    use.settings["other_starts"] = {
        "train_starts": "fitted" if better else "kinematic",
        "found": list(other.found),
        "heldout_rms_m": other.heldout_rms_after_m,
    }
    return use, ((setup_k, base_k) if better else None)


def _held_start_base(done: BaseStage | None, setup: Setup, *, sd: dict, weighting: str, opt, runner: Runner) -> tuple:
    """The base model refitted with its training window starts held at the kinematics, for
    discovery beside round 1: ``(setup, Stage, sd_fit)``; ``done`` is that base stage when
    ``--train-starts auto`` already fitted it (and kept the fitted starts)."""
    k = done if done is not None else _base_stage(replace(setup, train_starts="kinematic"), sd, weighting, opt, runner)
    return k.setup, k.stage(), k.sd_fit


def _base_multistart(problem: WindowProblem, bfit: FitResult, opt: DiagnoseOptions, runner: Runner):
    """The base fit from ``opt.base_starts`` extra starts (seeded apart from the diagnosis' rng,
    so that a diagnosis without them is unchanged): ``(fit, summary)``, the summary None without
    starts."""
    if int(opt.base_starts) < 1:
        return bfit, None
    runner.say(f"base fit: {int(opt.base_starts)} extra start(s)")
    ms = multistart(problem, bfit.p, int(opt.base_starts), np.random.default_rng(20260), runner=runner)
    best = ms.fits[ms.best]
    improved = bool(best["cost"] < bfit.cost * (1.0 - 1e-6))
    summary = {
        "n_starts": int(opt.base_starts),
        "default_cost": float(bfit.cost),
        "best_cost": float(best["cost"]),
        "improved": improved,
        "distinct_optima": len(ms.distinct),
    }
    if improved:
        bfit = problem.fit(np.asarray(best["p"], float), None)
    return bfit, summary


def _outcome(
    search: Rounds, floor: NoiseFloor, b_held: dict, significant: bool, th: Thresholds
) -> tuple[list, Remainder]:
    """The contributors (every effect that improves the held-out windows significantly without
    closing the gap, added or not: round 1 alone, or as added in its round) and the remainder."""
    after, chosen, roles, ranking = search.after, search.chosen, search.roles, search.ranking
    floor_rms = floor.heldout_rms_m
    excess0 = b_held["rms_position_m"] - floor_rms
    contributors = [contribution(roles[e], added=True) for e in chosen if roles[e].role == "contributor"]
    contributors += [
        contribution(r, added=False) for r in ranking if r.role == "contributor" and r.effect not in chosen
    ]
    held = after.held.rms_position_m
    remainder = Remainder(
        heldout_rms_m=held,
        fraction_of_excess=(held - floor_rms) / excess0 if excess0 > 0 else 0.0,
        significant=bool(significant and held > th.none_ratio * floor_rms),
    )
    return contributors, remainder


def _settings(opt: DiagnoseOptions, setup: Setup, cand_effects, weighting: str) -> dict:
    """What a diagnosis ran, for ``Diagnosis.settings`` (key order as written before)."""
    return {
        "free": list(setup.free),
        "candidates": [e.name for e in cand_effects],
        "base_effects": [e.name for e in setup.effects],
        "window_s": opt.window_s,
        "fit_window_s": setup.fit_window_s,
        "dt": setup.dt,
        "mode": opt.mode,
        "start_rule": setup.rule,
        "leadin_s": setup.leadin_s,
        "max_nfev": opt.max_nfev,
        "max_effects": opt.max_effects,
        "weighting": weighting,
        **({"train_starts": opt.train_starts} if opt.train_starts != "fitted" else {}),
        # the logged inputs' reconstruction, when not the default (the JSON of a held reading unchanged)
        **({"inputs": opt.inputs} if opt.inputs != "hold" else {}),
        **({"rudder_rate_deg_s": opt.rudder_rate_deg_s} if opt.rudder_rate_deg_s is not None else {}),
        # the base fit's extra starts, when asked for (issue 69: what was passed is recorded)
        **({"base_starts": int(opt.base_starts)} if opt.base_starts else {}),
        **({"heldout_propeller": opt.heldout_propeller} if opt.heldout_propeller != "logged" else {}),
        "floor": opt.floor,
    }


#: Held-out over training RMS position error (same windows, same start rule) above which the base fit
#: is suspect: a model that generalises predicts held-out runs of the same kind about as well as
#: its training runs, and a structural miss alone rarely triples the ratio.
BASE_FIT_RATIO = 3.0


def base_fit_check(model, fit, setup: Setup, sd_fit: dict, held: dict) -> BaseCheck:
    """Whether the base fit can be trusted, by two tests a structural miss and a failed fit both
    fail (the message says which to rule out first):

    1. **Generalisation.** The held-out error against the error on its own training tracks
       scored by the held-out protocol (same window, same start rule): a held-out error far
       above the training error says the fit may have failed (a local optimum) or bent its
       coefficients to a miss the training runs let them absorb.
    2. **Window starts** (fitted start rule only). Every training and held-out window's fitted
       start u, v, r against the track's own kinematics
       (:func:`bayesid.estimation.shooting.start_consistency`): a start more than
       :data:`~bayesid.estimation.windows.START_Z` sd away is one the vessel did not have, which
       only a model far off needs; more than :data:`START_FRACTION` of the training or of the
       held-out windows so flagged makes the fit suspect (per set: one training run among many
       held-out ones is judged on its own windows).

    Parameters
    ----------
    model : SimulationModel
        The base model.
    fit : FitResult
        Its fit on the training tracks.
    setup : Setup
        The diagnosis' setup (training tracks, window, start rule).
    sd_fit : dict
        The channel weights of the scores (and of the start fits), SI.
    held : dict
        The base fit's held-out scores.

    Returns
    -------
    BaseCheck
        ``train_rms_at_window_m``, ``heldout_rms_m``, ``ratio``, ``threshold``
        (:data:`BASE_FIT_RATIO`), ``starts`` (:func:`start_check`, or None under the measured
        rule), ``suspect`` (bool: either test failed) and ``message``; ``multistart`` None
        (:func:`diagnose` sets it).
    """
    ctx = contexts(model, setup.train, setup.window_s, setup.rule, leadin_s=setup.leadin_s)
    train = scores(model, fit, ctx, sd=sd_fit).rms_position_m
    ratio = held["rms_position_m"] / train if train > 0 else float("inf")
    starts = start_check(model, fit, setup, sd_fit) if setup.rule == "fitted" else None
    bad_ratio = bool(ratio > BASE_FIT_RATIO)
    msgs = []
    if bad_ratio:
        msgs.append(
            f"its held-out RMS {held['rms_position_m']:.3g} m is {ratio:.1f} x its RMS on its own training tracks "
            f"under the same protocol ({train:.3g} m)"
        )
    if starts is not None and starts["suspect"]:
        msgs.append(starts["message"])
    if msgs:
        msg = (
            "base fit suspect: "
            + "; ".join(msgs)
            + ": either the fit failed (a local optimum) or the model misses structure its coefficients and "
            "window starts absorb; rule out the first (diagnose --starts N; DiagnoseOptions(base_starts=N) in the Python "
            "API) before reading the verdict"
        )
    else:
        msg = f"base fit: held-out / training RMS under the same protocol {ratio:.2f} (<= {BASE_FIT_RATIO:g})"
        if starts is not None:
            msg += f"; {starts['message']}"
    return BaseCheck(
        train_rms_at_window_m=train,
        heldout_rms_m=held["rms_position_m"],
        ratio=ratio,
        threshold=BASE_FIT_RATIO,
        starts=starts,
        suspect=bool(msgs),
        message=msg,
    )


#: Fraction of window starts flagged by the start check above which the base fit is suspect: a
#: right model flags about none (measured on the sim-to-real controls: largest |z| 3.3 of 24).
START_FRACTION = 0.1


def start_check(model, fit, setup: Setup, sd_fit: dict) -> dict:
    """The fitted window starts of the training and held-out tracks against the tracks' own
    kinematics (:func:`bayesid.estimation.shooting.start_consistency`), summarised.

    Parameters
    ----------
    model : SimulationModel
        The base model.
    fit : FitResult
        Its fit.
    setup : Setup
        The diagnosis' setup (fitted start rule).
    sd_fit : dict
        The fit's channel weights, SI.

    Returns
    -------
    dict
        ``n_windows``, ``n_flagged``, ``fraction_flagged`` (training and held-out together),
        ``z_threshold``, ``fraction_threshold``, ``by_set`` (``{"training": {n_windows, n_flagged,
        fraction_flagged}, "held-out": {...}}``), ``median_abs_z``, ``worst`` (the 5 rows of largest
        |z|, as the function gives them), ``suspect`` (more than ``fraction_threshold`` of the
        windows of either set flagged) and ``message``.
    """
    ctr = WindowProblem(model, contexts(model, setup.train, setup.fit_window_s, "fitted"), sd_fit)
    cho = WindowProblem(
        model, contexts(model, setup.heldout, setup.window_s, "fitted", leadin_s=setup.leadin_s), sd_fit
    )
    rows = ctr.start_consistency(fit.p, setup.train, "training")
    rows += cho.start_consistency(fit.p, setup.heldout, "held-out")
    return summarise_starts(rows)


def summarise_starts(rows: list[dict]) -> dict:
    """The start check's summary of per-window rows (:func:`start_check`'s return).

    Parameters
    ----------
    rows : list of dict
        :func:`bayesid.estimation.shooting.start_consistency` rows of the ``"training"`` and
        ``"held-out"`` sets (``set``, ``track``, ``t_s``, ``component``, ``fitted``,
        ``kinematic``, ``sd``, ``z``).

    Returns
    -------
    dict
        As :func:`start_check`.
    """
    z = np.array([abs(r["z"]) for r in rows])
    n_bad = int((z > START_Z).sum())
    frac = n_bad / z.size if z.size else 0.0
    # per set: many held-out windows must not dilute a training fit that needs impossible starts
    by_set = {}
    for name in ("training", "held-out"):
        zs = np.array([abs(r["z"]) for r in rows if r["set"] == name])
        bad = int((zs > START_Z).sum())
        by_set[name] = {
            "n_windows": int(zs.size),
            "n_flagged": bad,
            "fraction_flagged": bad / zs.size if zs.size else 0.0,
        }
    worst = sorted(rows, key=lambda r: -abs(r["z"]))[:5]
    units = {"u": "m/s", "v": "m/s", "r": "deg/s"}
    if worst:
        w = worst[0]
        f = np.degrees(1.0) if w["component"] == "r" else 1.0
        eg = (
            f"worst: {w['set']} track {w['track']} at {w['t_s']:.1f} s, fitted {w['component']} "
            f"{w['fitted'] * f:.3g} {units[w['component']]} against {w['kinematic'] * f:.3g} +- {w['sd'] * f:.2g} "
            "from its positions and heading"
        )
    else:
        eg = "no window to check"
    over = [k for k, b in by_set.items() if b["fraction_flagged"] > START_FRACTION]
    suspect = bool(over)
    msg = (
        " and ".join(f"{by_set[k]['n_flagged']} of {by_set[k]['n_windows']} {k}" for k in over)
        + f" fitted window starts contradict the track's own kinematics by more than {START_Z:g} sd "
        f"({eg}); the model follows these tracks only from start states the vessel did not have"
        if suspect
        else f"window starts: {n_bad} of {z.size} more than {START_Z:g} sd from the track's kinematics"
    )
    return {
        "n_windows": int(z.size),
        "n_flagged": n_bad,
        "fraction_flagged": frac,
        "z_threshold": START_Z,
        "fraction_threshold": START_FRACTION,
        "by_set": by_set,
        "median_abs_z": float(np.median(z)) if z.size else float("nan"),
        "worst": worst,
        "suspect": suspect,
        "message": msg,
    }


def _greedy_rounds(
    setup, cand_effects, base_stage, fits: CandidateFits, judge: Judge, max_effects, runner, beside=None
) -> Rounds:
    """The candidate rounds of :func:`diagnose`: each round fits every effect not yet chosen on
    top of the chosen ones (as tasks), ranks them on the held-out windows and adds the best cause
    (which ends the search) or the best contributor. With ``beside``, discovery's terms compete
    in round 1 (:func:`discovery_beside_round_one`): when they take it, the later rounds try the
    effects on top of them.

    Parameters
    ----------
    setup : Setup
        What every model of the diagnosis shares.
    cand_effects : list of Effect
        The candidates.
    base_stage : Stage
        The base model.
    fits : CandidateFits
        How each candidate is fitted (channel weights, seeds, iterations).
    judge : Judge
        The noise floor, whether the gap is significant, and the verdict's thresholds.
    max_effects : int
        Greedy rounds.
    runner : Runner
        Runs the candidates of a round as tasks.
    beside : callable, optional
        ``beside(results, stages) -> FirstRound or None``, called after round 1.

    Returns
    -------
    Rounds
        The ranking, every round, the effects chosen and their rows, the last stage, the rounds'
        wall times and discovery beside round 1.
    """
    sd_fit, seeds, max_nfev = fits.sd_fit, fits.seeds, fits.max_nfev
    floor, significant, th = judge.floor, judge.significant, judge.thresholds
    first = None
    say = runner.say
    band = th.none_ratio * floor.heldout_rms_m
    excess0 = base_stage.held.rms_position_m - floor.heldout_rms_m
    ranking, rounds, chosen, roles, seconds = [], [], [], {}, []
    current = base_stage
    parallel = runner.scheduler is not None or int(runner.jobs) > 1
    for rnd in range(max(1, int(max_effects))):
        t_round = time.perf_counter()
        ref = current
        results, stages = [], {}
        todo = [e for e in cand_effects if e.name not in chosen]
        say(f"round {rnd + 1}: {len(todo)} candidate(s)" + (f" on {runner.where()}" if parallel else ""))
        tasks = []
        for e in todo:
            m, ct, ch = setup.build([c for c in cand_effects if c.name in chosen] + [e])
            # one progress bar per fit in this process; workers' bars would interleave
            label = None if parallel else runner.bar(f"round {rnd + 1}: {e.name}")
            fit = CandidateFit(
                effect=e,
                ref=ref,
                model=m,
                ctx_train=ct,
                ctx_held=ch,
                sd_fit=sd_fit,
                seeds=seeds,
                max_nfev=max_nfev,
                label=label,
            )
            tasks.append(Task(e.name, {"round": rnd + 1, "effect": e.name}, (fit,)))

        def done(task, out, seconds, r=rnd):
            if isinstance(out, TaskError):
                say(f"round {r + 1}: {out}")
                return
            for msg in out[1]:
                say(msg)
            if out[0] is not None:
                say(f"round {r + 1}: {task.key} held-out RMS {out[0].held['rms_position_m']:.3f} m")

        # candidate fits are not journaled: a diagnosis is one run
        outs = Runner(runner.jobs, runner.scheduler).run(fit_candidate, tasks, on_done=done)
        for e, out in zip(todo, outs):
            if isinstance(out, TaskError) or out[0] is None:
                continue
            results.append(candidate_row(e, out[0], ref, floor.heldout_rms_m, excess0))
            stages[e.name] = out[0]
        results.sort(key=lambda d: (not np.isfinite(d.heldout_rms_m), d.heldout_rms_m))
        assign_roles(results, significant, band, th)
        rounds.append(results)
        seconds.append(time.perf_counter() - t_round)
        if rnd == 0:
            ranking = results
        top = _best_effect(results)
        if rnd == 0 and beside is not None:
            first = beside(results, stages)
            if first is not None and first.took_round:  # the effects are tried on top of its terms
                setup, current = first.setup, first.discovery.after
                if current.held.rms_position_m <= band:
                    break
                continue
        if top is None:
            break
        chosen.append(top.effect)
        roles[top.effect] = top
        current = stages[top.effect]
        if current.held.rms_position_m <= band:
            break
    return Rounds(ranking, rounds, chosen, roles, current, seconds, first)


@dataclass(frozen=True)
class CandidateFits:
    """How the rounds fit each candidate effect (:func:`_greedy_rounds`).

    Parameters
    ----------
    sd_fit : dict
        The channel weights of the fits, SI.
    seeds : dict
        ``{effect: start values}`` of the effects' parameters.
    max_nfev : int
        Iterations of each fit.
    """

    sd_fit: dict
    seeds: dict
    max_nfev: int


@dataclass(frozen=True)
class Judge:
    """What the rounds judge the candidates by (:func:`_greedy_rounds`).

    Parameters
    ----------
    floor : NoiseFloor
        The noise floor.
    significant : bool
        Whether the base model's gap is significant.
    thresholds : Thresholds
        The verdict's thresholds.
    """

    floor: NoiseFloor
    significant: bool
    thresholds: Thresholds


@dataclass(frozen=True)
class Rounds:
    """What the greedy rounds of candidate effects leave (:func:`_greedy_rounds`).

    Parameters
    ----------
    ranking : list of CandidateRow
        Round 1's candidates, best first.
    rounds : list of list of CandidateRow
        Every round's candidates.
    chosen : list of str
        The effects added, in the order added.
    roles : dict
        ``{effect added: its CandidateRow}``.
    after : Stage
        The last stage (the model after the rounds).
    seconds : list of float
        Wall time of each round.
    discovery_first : FirstRound or None
        Discovery beside round 1.
    """

    ranking: list
    rounds: list
    chosen: list
    roles: dict
    after: Stage
    seconds: list
    discovery_first: FirstRound | None


def _best_effect(results: list) -> CandidateRow | None:
    """The effect a round adds: the best-ranked cause (it closes the gap), else the best-ranked
    contributor (the next round looks for what explains the rest), else None."""
    return next((r for r in results if r.role == "cause"), None) or next(
        (r for r in results if r.role == "contributor"), None
    )


@dataclass
class FirstRound:
    """Discovery beside round 1 (:func:`discovery_beside_round_one`).

    Parameters
    ----------
    discovery : Discovery
        Structure discovery on the base model.
    took_round : bool
        Whether its terms took round 1 from the catalogue's best effect.
    setup : Setup or None
        The diagnosis' setup with the kept terms added (free, at their fitted values) when they
        took the round, else None.
    summary : FirstRoundSummary
        The comparison (``Diagnosis.discovery_first``).
    """

    discovery: Discovery
    took_round: bool
    setup: Setup | None
    summary: FirstRoundSummary


def discovery_beside_round_one(
    setup: Setup,
    base: Stage,
    results: list,
    stages: dict,
    *,
    options,
    context: dict,
    rng,
    runner: Runner,
) -> FirstRound | None:
    """Let structure discovery compete with the catalogue in round 1 of a diagnosis.

    An effect of the catalogue that partly mimics a missing term is added first by the greedy
    rounds, and the term is then hard to find on top of it (sim_to_real's constant yaw moment:
    waves absorbs part of it). So discovery also runs on the base model
    (:func:`bayesid.analysis.gap.discovery.discover`), and the model with its kept terms is one
    more candidate of round 1, with a role by the same rules
    (:func:`~bayesid.analysis.gap.verdict.is_cause`; its terms passed the contributor test when
    they were kept) and ranked by the round's own rule: the best-ranked cause, else the
    best-ranked contributor, by held-out RMS. When it ranks first, its terms take the round.
    When round 1 has no effect to add, nothing is run here: discovery after the rounds starts
    from the same base model.

    With ``context["held_starts"]`` (the diagnosis gives it when the start check finds the base fit's
    fitted training window starts inconsistent with the tracks' kinematics), discovery also runs
    on the base model refitted with those starts held at the kinematics: fitted starts absorb part
    of what the model lacks (a constant yaw moment turns a window's start yaw rate), so the
    missing force is hidden from the search. Of the two, the model with kept terms and the lower
    held-out RMS is the candidate; when it takes the round, the later rounds keep its starts.

    The summary also gives the paired window test of the terms' model against the effect's and
    the share of the effect's excess over the floor the terms remove; the decision does not use
    them (the rounds compare their candidates by held-out RMS too).

    Parameters
    ----------
    setup : Setup
        The diagnosis' setup.
    base : Stage
        The base model, fitted and scored.
    results : list of CandidateRow
        Round 1's ranked candidates (with their roles).
    stages : dict
        ``{effect name: Stage}`` of round 1's fitted candidates.
    options : DiscoveryOptions
        Discovery's options.
    context : dict
        ``sd_fit``, ``floor_rms`` and ``thresholds`` (:func:`~bayesid.analysis.gap.discovery.discover`),
        and optionally ``held_starts``: a callable ``() -> (Setup, Stage, sd_fit)``, the base model
        refitted with its training window starts held at the kinematics, its setup and its channel
        weights.
    rng : numpy.random.Generator
        The bootstrap.
    runner : Runner
        Runs the refits; progress messages.

    Returns
    -------
    FirstRound or None
        None when round 1 has no effect to add.
    """
    top = _best_effect(results)
    if top is None:
        return None
    tic = time.perf_counter()
    context = dict(context)
    held_starts = context.pop("held_starts", None)
    th = context.get("thresholds", Thresholds())
    runner.say(f"structure discovery beside round 1 (on the base model, against {top.effect})")
    found = discover(
        setup, base, list(base.model.effects), options, dict(context, significant=True), rng=rng, runner=runner
    )
    own = base  # the base fit the kept terms were found on (its BIC is theirs to beat)
    if held_starts is not None:
        found, held = _better_with_held_starts(found, held_starts, options, context, rng, runner)
        if held is not None:
            setup, own = held
    rival = stages[top.effect]
    p, share, role = None, None, None
    if found.found:
        floor_rms = float(context.get("floor_rms", 0.0))
        before, after = rival.held.rms_position_m, found.after.held.rms_position_m
        p = paired_window_test(rival.windows, found.after.windows)
        share = (before - after) / (before - floor_rms) if before > floor_rms else 0.0
        excess0 = base.held.rms_position_m - floor_rms
        row = {
            "heldout_rms_m": after,
            "excess_removed": (base.held.rms_position_m - after) / excess0 if excess0 > 0 else 0.0,
            "delta_bic": found.after.fit.bic - own.fit.bic,
        }
        role = "cause" if is_cause(row, True, th.none_ratio * floor_rms, th) else "contributor"
        # discovery's model ranked among round 1's rows as an effect named None
        rows = [*results, SimpleNamespace(effect=None, heldout_rms_m=after, role=role)]
        rows.sort(key=lambda d: (not np.isfinite(d.heldout_rms_m), d.heldout_rms_m))
    took = role is not None and _best_effect(rows).effect is None
    summary = FirstRoundSummary(
        found=list(found.found),
        verdict=found.verdict,
        heldout_rms_m=found.heldout_rms_after_m,
        effect=top.effect,
        effect_role=top.role,
        effect_heldout_rms_m=rival.held.rms_position_m,
        role=role,
        window_p_value=p,
        share_of_effect_excess=share,
        took_round=took,
        seconds=time.perf_counter() - tic,
        train_starts=found.settings.get("train_starts", "fitted"),
        # the search on the other base fit's starts
        other_starts=found.settings.get("other_starts"),
        # the kept terms' numbers; the discovery in the report is the one after the rounds
        discovered=None
        if took
        else [
            {k: r.get(k) for k in ("term", "heldout_rms_after_m", "shrinkage", "delta_bic", "kept")}
            for r in found.discovered
        ],
    )
    terms = {n: found.after_coefficients[n] for n in found.found}
    return FirstRound(found, took, with_terms(setup, terms) if took else None, summary)


def _signature_support(family, cand_effects, base, forces, seeds, rng) -> dict:
    """The model-free support of the candidates: the missing forces of the held-out tracks
    regressed on the candidates' force signatures (:func:`signature_regression`); ``{}`` without
    forces, ``{"error": ...}`` when the regression fails."""
    if not forces:
        return {}
    try:
        F_list, motions = forces
        order = list(family.CATALOGUE)  # catalogue effects first, in catalogue order
        ranked = sorted(cand_effects, key=lambda e: order.index(e.name) if e.name in order else len(order))
        cols = [base.signature_columns(mo, inp, tr, seeds, ranked) for (mo, inp, tr) in motions]
        return signature_regression(F_list, cols, rng)
    except Exception as exc:  # noqa: BLE001
        return {"error": f"{type(exc).__name__}: {exc}"}


def _seeds(effects, b: BaseStage, train) -> dict:
    """{effect name: seed} of the candidates that have one
    (:meth:`~bayesid.models.effects.Effect.diagnosis_seed`), from the base fit's errors on the training
    windows (its training :class:`~bayesid.estimation.windows.Evaluation`) and the training tracks'
    missing forces (None when inverse dynamics fails)."""
    base, bfit, ctxs, errors = b.model, b.fit, b.ctr, list(b.train.errors)
    try:  # wave frequency and per-track phases from the TRAINING tracks' missing forces
        tr_forces = [base.missing_forces(bfit, t) for t in train]
        forces = ([f[1] for f in tr_forces], [(f[0], f[2], t) for f, t in zip(tr_forces, train)])
    except Exception:  # noqa: BLE001 - no force seed: candidates start from their catalogue values
        forces = None
    evidence = {"ctxs": ctxs, "errors": errors, "forces": forces}
    seeds = {}
    for e in effects:
        try:
            s = e.diagnosis_seed(evidence)
        except Exception:  # noqa: BLE001 - a seed is a hint; without it the catalogue start serves
            s = None
        if s is not None:
            seeds[e.name] = s
    return seeds


def _plain(v):
    """``v`` as JSON: a record as its object, in lists too."""
    if isinstance(v, Record):
        return v.to_dict()
    if isinstance(v, Thresholds):
        return v.as_dict()
    if isinstance(v, list):
        return [_plain(x) for x in v]
    return v
