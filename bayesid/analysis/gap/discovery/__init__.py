"""Structure discovery: name the model terms behind an "unexplained" gap, refit with them and
check them on held-out runs.

The gap diagnosis (:mod:`bayesid.analysis.gap`) can only name effects of its catalogue. This package
asks the next question, "what term is the model missing?", in four steps:

1. **Where the force is missing.** On the training tracks, the forces the measured motion implies
   (smoothed motion and rigid-body inverse dynamics, :func:`bayesid.models.inverse.estimate_motion`)
   minus the fitted model's forces along the measured states (the model's ``missing_forces``), per
   degree of freedom X, Y, N, with their noise level (the scatter of successive differences).
2. **Candidate terms.** The terms the model lacks from its family's term library
   (:func:`bayesid.models.library.term_library`: the model answers, discovery never asks which
   kind of vessel it has), named as a vehicle file writes them: for a ship the extra hull terms of
   :mod:`bayesid.models.ship.hullterms` (products of ``v r |v| |r| dr |dr|`` up to third order and
   the constants ``X0 Y0 N0``, so port/starboard asymmetric forms such as ``N0``, ``Nabsdr``,
   ``Nvv`` are candidates) and its tied coefficients (``gRm``, gamma_R for beta_R < 0), untied at
   the value they follow; for a submarine the products of the term grammar
   (:class:`bayesid.models.submarine.SubmarineTerms`).
3. **Sparse selection with inclusion probabilities.** Per degree of freedom, the missing force is
   regressed on the candidates' force columns by sequentially thresholded least squares (pysindy
   ``STLSQ``; Brunton, Proctor & Kutz 2016) on RMS-normalised columns and target, so terms of
   different size compete by the share of the missing force they carry; an ensemble over a
   **block bootstrap** of the samples (blocks of :attr:`~.options.DiscoveryOptions.block_s` seconds: the
   residuals of a track are correlated in time, and resampling single samples would overstate the
   certainty) gives each term an inclusion probability (Fasel, Kutz, Brunton & Brunton 2022,
   Ensemble-SINDy, Proc. R. Soc. A 478:20210904). Candidates whose columns are nearly collinear
   (|cosine| >= :attr:`~.options.DiscoveryOptions.group_cos`) form a **group**: the group's inclusion
   probability is the share of models that select any member, and the group is tested as one
   candidate (its most probable member), never as a winner picked by chance.
4. **Confirmed by the output-error fit and held-out runs.** Each candidate is added to the model
   (start: the reference fit, its window start states included, plus the regression's step; the
   reference itself when that fit ends worse) and ALL free coefficients are re-identified by the
   same multiple-shooting fit ``bayesid fit`` uses, with the reference fit's channel weights; it is **kept** only if it passes the gap diagnosis's contributor test on
   the held-out windows (:func:`bayesid.analysis.gap.verdict.is_contributor`: training ΔBIC <= -10,
   held-out shrinkage > 0, and a one-sided Wilcoxon test of the paired per-window errors
   p < 0.01 or half the excess over the noise floor removed) and predicts no held-out run
   significantly worse than the reference model (the run test of
   :func:`bayesid.analysis.gap.verdict.run_separation_test`, same level: a term chosen on one
   kind of run that makes another kind worse does not carry). Terms that fit the training runs but
   not the held-out ones are reported as rejected with their numbers. The kept terms are then
   added together, best first (a term some held-out run shows worse than another kept term after
   it: :func:`~.confirmation.dominance_order`), each further one refitted on top of those added and kept only if
   it passes the same test against them while the held-out error is still above the floor band.

:func:`discover` runs the whole search from a reference model (the diagnosis's model after its
catalogue effects, or a base fit of its own) and returns a :class:`Discovery`.

The package is split by concept: :mod:`.options` (:class:`~.options.DiscoveryOptions`),
:mod:`.library` (the candidate terms and the models they extend; step 2), :mod:`.forces` (the
missing forces; step 1), :mod:`.selection` (the linearised problem and the ensemble; step 3, with
the block-bootstrap ensemble STLSQ of :func:`bayesid.analysis.sindy.block_ensemble_stlsq`),
:mod:`.confirmation` (the refits and the held-out tests; step 4) and this orchestration.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ....estimation.windows import warm_starts
from ....models.library import MAX_ORDER as MAX_ORDER
from ....models.library import NoTermLibraryError
from ....tasks import Runner, Task, TaskError, record_fields
from ..candidates import Setup, Stage
from ..records import Record, TermRow
from ..verdict import Thresholds
from ..verdict import is_contributor as is_contributor
from ..verdict import paired_window_test as paired_window_test
from ..verdict import run_separation_test as run_separation_test
from .confirmation import (
    Refits,
    TermFit,
    alternatives,
    combine,
    combined_competitors,
    compare_structures,
    decide,
    dominance_order,
    fit_term,
    heldout_rms_by_run,
    prune,
    refit_row,
    separated,
    training_separation,
    window_runs,
    worst_run,
)
from .forces import force_residuals, force_summary
from .forces import twin_track as twin_track
from .library import (
    augmented_model,
    candidate_terms,
    extended_start,
    nuisance_start,
    reference_values,
    untied_candidates,
    with_terms,
)
from .options import DOFS, DiscoveryOptions
from .selection import (
    Selection,
    alternative_pool,
    linearised_problem,
    mimicked_companions,
    mimicked_refits,
    mimics,
    project_out,
    refit_candidates,
    score_test,
    select_terms,
    tied_companions,
)

__all__ = [
    "DiscoveryOptions",
    "Discovery",
    "TermFit",
    "candidate_terms",
    "untied_candidates",
    "reference_values",
    "force_residuals",
    "select_terms",
    "score_test",
    "alternatives",
    "compare_structures",
    "separated",
    "training_separation",
    "window_runs",
    "dominance_order",
    "fit_term",
    "with_terms",
    "discover",
    "check_compare",
    "routed",
]

# the helpers' names before the package was split by concept (private in one module then)
_DOFS = DOFS
_augmented = augmented_model
_extended_start = extended_start
_warm_starts = warm_starts
_nuisance_start = nuisance_start
_project = project_out
_mimics = mimics
_candidates = refit_candidates
_alternative_pool = alternative_pool
_row = refit_row
_worst_run = worst_run
_decide = decide
_combine = combine
_by_run = heldout_rms_by_run

#: The fields of :class:`Discovery` that hold models, not in its JSON.
MODEL_FIELDS = ("after", "reference", "stages", "combined_stages")

#: At most this many competitors of a term added on top of others are refitted in its place
#: (:func:`~.confirmation.combined_competitors`): of the refitted terms, those kept alone first, then
#: those with the lowest single-term held-out RMS.
MAX_COMBINED_RIVALS = 6


@dataclass
class Discovery:
    """The result of :func:`discover` (JSON-able through :meth:`to_dict`, the ``discovery`` entry
    of ``diagnosis.json``).

    Parameters
    ----------
    found : list of str
        The kept terms, in the order added.
    verdict : str
        ``"discovered: N0+Nvvv"`` (with ``+unexplained`` when the held-out error is still above
        the floor band with them) or ``"no term of the library explains it"``.
    discovered : list of TermRow
        Every refitted candidate (:class:`~bayesid.analysis.gap.records.TermRow`, its fields
        documented there): the selection's numbers, the refit's, the kept test's decision. Read
        back from a file (:meth:`from_dict`), a row of an older shape stays the dict it was.
    inclusion : dict
        ``{term: inclusion probability}`` of every candidate with a non-zero one, best first.
    residuals : dict
        ``forces``: per degree of freedom the missing force's RMS (N or N m), the null's and the
        best candidates (:func:`~.forces.force_summary`); ``explained``: the share of the projected
        output residual's variance the ensemble's median model explains; ``projected_rms``: the
        share of the training residual's RMS no refit of the free parameters can remove;
        ``mimicked``: candidates the free parameters reproduce; ``mimicked_by``: each of them with
        the free parameter whose column is closest to its own (:func:`~.selection.select_terms`).
    library_size : int
        Number of candidate terms.
    heldout_rms_before_m : float
        The reference model's held-out RMS position error, m.
    heldout_rms_after_m : float
        With every kept term, m.
    after_coefficients : dict
        The coefficients of the model with every kept term (prime).
    windows_before_m : list of float
        The reference model's RMS position error of each held-out window, m.
    windows_after_m : list of float
        With every kept term, m.
    settings : dict
        The options and what the reference model was.
    seconds : float
        Wall time.
    alternatives : dict
        ``{kept term: [{"term", "heldout_rms_m", "window_p_value", "run_p_value", ...}, ...]}``:
        every competing refitted term the runs (held-out, or training where the held-out runs tie
        them) cannot separate from the kept term (:func:`~.confirmation.compare_structures`);
        empty lists where the runs separate the kept term from every other.
    separated : dict
        ``{kept term: [...]}``, the same entries for the competing terms the runs separate, with
        the run that separates each (``separating_run``, ``run_error_ratio``; where only the
        training runs do, ``train_separating_run``, ``train_error_ratio``) and ``separated_by``.
    dropped : list of str
        Terms of the combination dropped because the terms added after them made them redundant
        (:func:`~.confirmation.prune`), in the order dropped.
    after : Stage, optional
        The model with every kept term (None when nothing is kept); not in :meth:`to_dict`.
    reference : Stage, optional
        The model the terms were added to; not in :meth:`to_dict`.
    stages : dict, optional
        ``{term: Stage}`` of every refitted term's single-term model (the kept terms' and their
        alternatives' among them); not in :meth:`to_dict`.
    combined_stages : dict, optional
        ``{term added on top of others: {term: Stage}}``: its model and each competitor's refit in
        its place (:func:`~.confirmation.combined_competitors`); not in :meth:`to_dict`.
    """

    found: list
    verdict: str
    discovered: list[TermRow]
    inclusion: dict
    residuals: dict
    library_size: int
    heldout_rms_before_m: float
    heldout_rms_after_m: float
    after_coefficients: dict
    windows_before_m: list
    windows_after_m: list
    settings: dict
    seconds: float
    alternatives: dict = field(default_factory=dict)
    separated: dict = field(default_factory=dict)
    dropped: list = field(default_factory=list)
    after: Stage | None = field(repr=False, default=None)
    reference: Stage | None = field(repr=False, default=None)
    stages: dict = field(repr=False, default_factory=dict)
    combined_stages: dict = field(repr=False, default_factory=dict)

    def to_dict(self) -> dict:
        """The JSON-able fields.

        Returns
        -------
        dict
            ``{field: value}`` without the models (``after``, ``reference``, ``stages``,
            ``combined_stages``; ``discovered`` as the rows' JSON objects).
        """
        out = {k: v for k, v in self.__dict__.items() if k not in MODEL_FIELDS}
        out["discovered"] = [r.to_dict() if isinstance(r, Record) else dict(r) for r in self.discovered]
        return out

    @classmethod
    def from_dict(cls, d: dict) -> Discovery:
        """The result read back from its JSON (``diagnosis.json``'s ``discovery``, or
        :meth:`to_dict`), without the models (:data:`MODEL_FIELDS` empty); the
        rows of ``discovered`` as :class:`~bayesid.analysis.gap.records.TermRow`
        (:meth:`~bayesid.analysis.gap.records.Record.read`: a row of an older shape stays a dict).

        Parameters
        ----------
        d : dict
            The JSON object.

        Returns
        -------
        Discovery
            ``Discovery.from_dict(x).to_dict() == x``.

        Raises
        ------
        ValueError
            A key the result does not have, or a required one missing (named).
        """
        args = record_fields(cls, d, "discovery", skip=MODEL_FIELDS)
        return cls(**dict(args, discovered=[TermRow.read(r) for r in args["discovered"]]))

    def terms(self) -> list[dict]:
        """The top-level ``discovered`` list of ``diagnosis.json``: one item per refitted term.

        Returns
        -------
        list of dict
            ``term``, ``dof``, ``kept`` (True for the final model's terms, :attr:`found`),
            ``reason`` (why a term is not in the final model: it failed the kept test, or it
            passed alone but not on top of the terms added before it), ``coefficient`` and
            ``coefficient_sd`` (prime, its single-term refit), ``heldout_rms_m``,
            ``window_p_value`` (against the reference model), ``inclusion_probability``,
            ``refitted_as`` (``"selected"`` by the ensemble, ``"alternative"`` by the score
            test, ``"mimicked"``, ``"tied"`` (in a kept term's collinear group, at least half its score-test share) or
            ``"compared"``: asked for, ``DiscoveryOptions.compare``), ``alternatives`` (kept terms: :attr:`alternatives`; others: empty),
            ``separated`` (kept terms: :attr:`separated`; others: empty), ``separable`` (kept terms: no alternative survives; others: None) and
            ``heldout_rms_by_run_m`` (kept terms: ``{held-out run: position RMS, m}`` of the
            single-term refit, or of the model it was added to others in, :attr:`combined_stages`;
            others: empty). A term added on top of others also has ``heldout_rms_on_top_m``, that
            model's held-out position RMS: its alternatives' numbers are of models of that size.
        """
        out = []
        for row in self.discovered:
            t = row["term"]
            kept = t in self.found
            if kept:
                reason = "in the final model"
            elif t in self.dropped:
                reason = "passed the kept test alone and was added, then the later terms made it redundant: dropped"
            elif row.get("kept"):
                reason = "passed the kept test alone but not on top of " + "+".join(self.found)
            else:
                reason = row.get("reason", "")
            alts = list(self.alternatives.get(t, [])) if kept else []
            # a term added on top of others: its competitors were refitted in its place, so is it
            on_top = (self.combined_stages.get(t) or {}).get(t) if kept else None
            by_run = on_top if on_top is not None else self.stages.get(t) if kept else None
            out.append(
                {
                    "term": t,
                    "dof": row["dof"],
                    "kept": kept,
                    "reason": reason,
                    "coefficient": row.get("coefficient"),
                    "coefficient_sd": row.get("coefficient_sd"),
                    "heldout_rms_m": row.get("heldout_rms_after_m"),
                    "window_p_value": row.get("window_p_value"),
                    "inclusion_probability": row["inclusion_probability"],
                    "refitted_as": row.get("refitted_as", "selected"),
                    "alternatives": alts,
                    "separated": list(self.separated.get(t, [])) if kept else [],
                    "separable": (not alts) if kept else None,
                    "heldout_rms_by_run_m": heldout_rms_by_run(by_run) if by_run is not None else {},
                }
            )
            if on_top is not None:
                out[-1]["heldout_rms_on_top_m"] = on_top.held.rms_position_m
        return out


def _refit_terms(how: dict, refits: Refits, sel: Selection, significant: bool, runner: Runner) -> tuple[list, dict]:
    """Refit each term on top of the reference model (tasks of :func:`fit_term`) and decide its
    row by the kept test.

    Parameters
    ----------
    how : dict
        ``{term: refitted_as}``, in the order refitted.
    refits : Refits
        The reference model, its setup, how a term is fitted (:class:`TermFit`) and judged, and
        each term's value in the reference.
    sel : Selection
        The ensemble's selection (each term's regression value starts its refit).
    significant : bool
        Whether the reference model's gap is significant.
    runner : Runner
        Runs the fits; progress messages.

    Returns
    -------
    rows : list of TermRow
        One per term, decided.
    stages : dict
        ``{term: Stage}`` of every refit that converged.
    """
    ref, th = refits.ref, refits.thresholds
    names = list(how)
    tasks = [
        Task(
            n,
            {"term": n},
            (
                TermFit(
                    n,
                    sel.coefficient.get(n, 0.0),
                    ref,
                    refits.setup,
                    refits.effects,
                    refits.sd_fit,
                    refits.max_nfev,
                    refits.initial[n],
                ),
            ),
        )
        for n in names
    ]
    outs = Runner(runner.jobs, runner.scheduler).run(fit_term, tasks) if tasks else []
    rows, stages = [], {}
    for n, out in zip(names, outs):
        st = None if isinstance(out, TaskError) else out[0]
        msgs = [str(out)] if isinstance(out, TaskError) else out[1]
        for m in msgs:
            if isinstance(m, str):
                runner.say(f"discovery: {m}")
        sd = next((m[1] for m in msgs if isinstance(m, tuple)), None)
        row = refit_row(n, st, ref, sel, refits.floor_rms, sd, refits.runs, th.separation_margin)
        rows.append(decide(replace(row, refitted_as=how[n]), significant, th))
        if st is not None:
            stages[n] = st
    return rows, stages


def _named_alternatives(found: list, alts: dict) -> list[str]:
    """The kept terms as the verdict names them: ``Yvvdr (not separable from Nvvr, Yvdrdr on
    these runs)``; an alternative the held-out runs show better than the kept term (one that
    failed the kept test on its own, or was not added on top of the kept terms) is named apart:
    ``Nabsdr (the held-out runs favour N0)``."""
    out = []
    for k in found:
        favoured = [a["term"] for a in alts.get(k, []) if a.get("favoured")]
        others = [a["term"] for a in alts.get(k, []) if not a.get("favoured")]
        parts = [f"not separable from {', '.join(others)} on these runs"] if others else []
        parts += [f"the held-out runs favour {', '.join(favoured)}"] if favoured else []
        out.append(f"{k} ({'; '.join(parts)})" if parts else k)
    return out


def _verdict(found: list, heldout_rms: float, band: float, alts: dict | None = None) -> str:
    """``"discovered: A+B"`` (``+unexplained`` while the held-out error stays above the floor
    band: the terms explain part of the gap), or ``"no term of the library explains it"``; a
    kept term with alternatives the runs cannot separate from it is named with them
    (:func:`_named_alternatives`). With nothing kept, the terms a free coefficient may hide are
    named in the report (``residuals.mimicked_by``), not in the verdict: naming the likeliest one
    there named a stand-in in every control and non-force case of ``studies/structure_discovery.py``
    (with ``n_alternatives``, the likeliest of them are refitted, :func:`~.selection.mimicked_refits`,
    and kept like any candidate when they pass the kept test)."""
    if not found:
        return "no term of the library explains it"
    names = _named_alternatives(found, alts or {})
    return f"discovered: {'+'.join(names)}" + ("+unexplained" if heldout_rms > band else "")


#: The channels whose miss routes structure discovery into the surge equation: the speed through
#: the water is set by X alone (the position and heading channels by Y and N first).
SURGE_CHANNELS = ("u",)
#: Without a speed log: the speed over ground read from the positions
#: (:func:`bayesid.analysis.gap.where.speed_from_positions`) missed by at least this many times its
#: noise floor routes discovery into X too (models whose family sets ``SURGE_FROM_POSITIONS``). Set
#: between 1.57, the largest of the synthetic KVLCC2 cases without a surge miss, and 2.8, the smallest
#: with one (``studies/ship_surge.py`` without a velocity log, seeds 67 and 69).
SPEED_FROM_POSITIONS_RATIO = 2.0


def routed(options: DiscoveryOptions, where: dict | None, model) -> tuple[DiscoveryOptions, str | None]:
    """The degrees of freedom discovery searches, as *Where* points: when the channel the base
    model misses most (``where["dominant_channel"]``, the largest excess over its noise floor) is
    the speed ``u`` (:data:`SURGE_CHANNELS`), or, where u is not logged and the model's family
    sets ``SURGE_FROM_POSITIONS``, when the speed over ground read from the positions
    (``where["speed_from_positions"]``) misses by at least :data:`SPEED_FROM_POSITIONS_RATIO` times
    its floor, the surge equation X joins the searched degrees of
    freedom (first) where the model's term library offers X terms and ``options`` does not search
    it already: a model that loses speed wrongly in the turns is missing a surge force, which no
    term in Y or N supplies (the MMG surge: Yasukawa & Yoshimura 2015, J. Mar. Sci. Technol.
    20:37-52, Sec. 2.2). Y and N stay searched: a sway or yaw term that fits the same runs competes
    with the surge term, and the alternatives and the design tell them apart.

    Parameters
    ----------
    options : DiscoveryOptions
        The options asked for.
    where : dict or None
        The base model's *Where* summary (:func:`bayesid.analysis.gap.where.where`).
    model : SimulationModel
        The base model (its term library's X candidates).

    Returns
    -------
    options : DiscoveryOptions
        ``options``, or a copy with ``"X"`` added to ``dofs``.
    reason : str or None
        Why X was added (None when it was not).
    """
    where = where or {}
    channel = where.get("dominant_channel")
    sog = where.get("speed_from_positions") or {}
    by_speed = channel in SURGE_CHANNELS
    by_positions = (
        not by_speed
        and getattr(model, "SURGE_FROM_POSITIONS", False)
        and (sog.get("excess_ratio") or 0.0) >= SPEED_FROM_POSITIONS_RATIO
    )
    if not (by_speed or by_positions) or "X" in options.dofs:
        return options, None
    try:
        offered = candidate_terms(model, options.max_order, ("X",))
    except NoTermLibraryError:
        return options, None
    if not offered:
        return options, None
    if by_speed:
        ratio = ((where.get("channels") or {}).get(channel) or {}).get("excess_ratio")
        reason = (
            f"the base model misses the speed {channel} most"
            + (f" ({ratio:.3g} x its noise floor)" if ratio else "")
            + ": the surge equation X is searched too"
        )
    else:
        reason = (
            f"no speed log; the base model misses the speed over ground read from the positions by "
            f"{sog['excess_ratio']:.3g} x its noise floor (at least {SPEED_FROM_POSITIONS_RATIO:g}): the surge "
            "equation X is searched too"
        )
    return replace(options, dofs=("X", *options.dofs)), reason


def check_compare(model, options: DiscoveryOptions) -> None:
    """Check that every term of ``options.compare`` is a candidate term of ``model``.

    Parameters
    ----------
    model : SimulationModel
        The reference model (its vehicle's coefficients are not candidates).
    options : DiscoveryOptions
        ``compare``, ``max_order`` and ``dofs``.

    Raises
    ------
    ValueError
        Naming each term that is not among the candidates (:func:`candidate_terms`).
    """
    if not options.compare:
        return
    names = candidate_terms(model, options.max_order, options.dofs)
    bad = [n for n in options.compare if n not in names]
    if bad:
        raise ValueError(
            f"compare: {', '.join(bad)} {'is' if len(bad) == 1 else 'are'} not among the model's candidate terms "
            f"(degrees of freedom {', '.join(options.dofs)}, at most {options.max_order} factors; a coefficient "
            "the vehicle file already has is not a candidate)"
        )


def discover(
    setup: Setup,
    ref: Stage,
    effects=(),
    options: DiscoveryOptions = DiscoveryOptions(),
    context: dict | None = None,
    *,
    rng=None,
    runner: Runner = Runner(),
) -> Discovery:
    """Structure discovery on top of a fitted reference model (see the module docstring).

    Parameters
    ----------
    setup : Setup
        The reference model's vehicle, free coefficients, tracks, windows and start rule
        (:class:`bayesid.analysis.gap.candidates.Setup`).
    ref : Stage
        The reference model, fitted and scored (the diagnosis's model after its catalogue
        effects, or a base fit).
    effects : sequence of Effect, default ()
        The reference model's effects (kept, with their parameters refitted).
    options : DiscoveryOptions, default DiscoveryOptions()
        The library, the ensemble and the confirmation fits.
    context : dict, optional
        ``sd_fit`` (the reference fit's channel weights; required), ``floor_rms`` (the noise
        floor's held-out RMS, m; default 0), ``significant`` (whether the reference's gap is
        significant; default True) and ``thresholds`` (:class:`Thresholds`).
    rng : numpy.random.Generator, optional
        The bootstrap (default seed 0).
    runner : Runner, default Runner()
        Runs the confirmation fits as tasks; progress messages.

    Returns
    -------
    Discovery
        The kept terms, every refitted candidate with its numbers, the inclusion probabilities
        and the missing forces per degree of freedom.

    Raises
    ------
    ValueError
        No training track gives missing forces; ``context`` without ``sd_fit``.

    Examples
    --------
    Discovery usually runs inside :func:`bayesid.analysis.gap.diagnose.diagnose`
    (``DiagnoseOptions(discover=DiscoveryOptions())``, as ``bayesid discover`` runs it). Here it
    searches again, with other options (the yaw moment alone), on the base model of a diagnosis
    without candidates:

    >>> import bayesid
    >>> vehicle = bayesid.load_any_vehicle("nps_auv2")
    >>> train = [bayesid.read_csv(f) for f in ("z10.csv", "z20.csv")]
    >>> heldout = [bayesid.read_csv("t15.csv")]
    >>> free = ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"]
    >>> d = bayesid.diagnose(vehicle, free, train, heldout, bayesid.DiagnoseOptions(window_s=30.0, candidates=()))
    >>> context = {"sd_fit": d.fit_sd, "floor_rms": d.noise_floor["heldout_rms_m"], "significant": d.significant_gap}
    >>> options = bayesid.DiscoveryOptions(dofs=("N",))
    >>> found = bayesid.discover(d.setup, d.base, d.base.model.effects, options, context)
    >>> found.found, found.verdict  # doctest: +SKIP
    """
    t0 = time.perf_counter()
    ctx = dict(context or {})
    if "sd_fit" not in ctx:
        raise ValueError("discover needs context['sd_fit'], the reference fit's channel weights")
    th = ctx.get("thresholds", Thresholds())
    floor_rms, significant = float(ctx.get("floor_rms", 0.0)), bool(ctx.get("significant", True))
    rng = np.random.default_rng(0) if rng is None else rng
    check_compare(ref.model, options)
    names = candidate_terms(ref.model, options.max_order, options.dofs)
    runner.say(f"discovery: {len(names)} candidate terms")
    problem = linearised_problem(setup, ref, effects, names, ctx["sd_fit"])
    sel = select_terms(problem, names, options, rng)
    untied = untied_candidates(ref.model, options.dofs)
    terms = [n for n in names if n not in untied]  # those with force columns
    try:
        forces = force_summary(
            force_residuals(ref.model, ref.fit, setup.train, terms, options, rng), sel, terms, options
        )
    except ValueError as exc:  # no inverse dynamics: the output-space selection stands alone
        forces = {"error": str(exc)}
    cands = refit_candidates(sel, options)
    r2 = score_test(problem, names)
    pool = alternative_pool(r2, sel, cands, options)
    # the likeliest terms the selection set aside as mimicked: the output-error refit may still see them
    mimicked = (
        [n for n in mimicked_refits(sel, options.n_alternatives) if n not in (*cands, *pool)] if significant else []
    )
    # the terms asked for (an earlier round's kept terms and alternatives), whatever the selection says
    asked = [n for n in options.compare if n not in (*cands, *pool, *mimicked)]
    refit = [*cands, *pool, *mimicked, *asked]
    initial = reference_values(ref, refit)
    runner.say(f"discovery: refitting {', '.join(cands) or 'nothing'}")
    if pool:
        runner.say(f"discovery: and the alternatives {', '.join(pool)}")
    if mimicked:
        runner.say(f"discovery: and, set aside as mimicked, {', '.join(mimicked)}")
    if asked:
        runner.say(f"discovery: and, as asked (compare), {', '.join(asked)}")
    runs, run_names = window_runs(setup, ref.model)
    refits = Refits(
        ref, setup, tuple(effects), ctx["sd_fit"], options.max_nfev, floor_rms, th, (runs, run_names), initial
    )
    how = {
        n: "alternative" if n in pool else "mimicked" if n in mimicked else "compared" if n in asked else "selected"
        for n in refit
    }
    discovered, fitted = _refit_terms(how, refits, sel, significant, runner)
    # a kept term competes with the terms it stands for: those its mimic reproduces alike (set aside as
    # mimicked) or, for a term of the score test's pool, the members of its collinear group with at least half
    # its score-test share (the ensemble's own picks already stand for their groups, whose probable members
    # are refitted beside them)
    more = {}
    for r in (r for r in discovered if r.kept and options.n_alternatives > 0):
        if r.refitted_as == "mimicked":
            more.update(dict.fromkeys(mimicked_companions(sel, r.term, 2 * options.n_alternatives), "mimicked"))
        elif r.refitted_as == "alternative":
            more.update(dict.fromkeys(tied_companions(sel, r2, r.term), "tied"))
    more = {c: h for c, h in more.items() if c not in how}
    if more:
        for h, words in (("mimicked", "the terms mimicked alike"), ("tied", "the terms of its collinear group")):
            if h in more.values():
                runner.say(f"discovery: and {words}, {', '.join(c for c in more if more[c] == h)}")
        refits = replace(refits, initial={**refits.initial, **reference_values(ref, list(more))})
        rows, stages_more = _refit_terms(more, refits, sel, significant, runner)
        discovered, fitted = [*discovered, *rows], {**fitted, **stages_more}
    stages = {r.term: fitted[r.term] for r in discovered if r.kept}
    found, chain = [], [None]
    dropped = []
    if stages:
        found, chain = combine(list(stages), stages, refits)
    if len(found) > 1:
        # a term added early that the later ones make redundant goes (backward elimination)
        found, chain, dropped = prune(found, chain, stages, refits)
        if dropped:
            runner.say(f"discovery: {', '.join(dropped)} no longer needed on top of {'+'.join(found)}: dropped")
    after = chain[-1]
    train_names = [t.name for t in setup.train]
    compared = compare_structures(found, discovered, fitted, th, runs, run_names, train_names)
    combined = {}
    if len(found) > 1:
        # a term added on top of others competes with the terms that could take its place there
        # every refitted term may take that place: those kept alone first, then by their single-term held-out RMS
        rank = {r.term: (not r.kept, r.heldout_rms_after_m or np.inf) for r in discovered if r.term in fitted}
        rivals = sorted((n for n in rank if n not in found), key=rank.get)[:MAX_COMBINED_RIVALS]
        runner.say(f"discovery: refitting {', '.join(rivals) or 'nothing'} in the place of {', '.join(found[1:])}")
        compared, combined = combined_competitors(found, chain, compared, rivals, refits, train_names)
    alts = alternatives(compared)
    inclusion = dict(sorted(((k, v) for k, v in sel.inclusion.items() if v > 0), key=lambda kv: -kv[1]))
    return Discovery(
        found=found,
        verdict=_verdict(found, (after or ref).held.rms_position_m, th.none_ratio * floor_rms, alts),
        discovered=discovered,
        inclusion=inclusion,
        residuals={
            "forces": forces,
            "explained": sel.explained,
            "projected_rms": sel.projected_rms,
            "mimicked": sel.mimicked,
            "mimicked_by": sel.mimicked_by,
        },
        library_size=len(names),
        heldout_rms_before_m=ref.held.rms_position_m,
        heldout_rms_after_m=(after or ref).held.rms_position_m,
        after_coefficients=(after or ref).fit.coefficients(),
        windows_before_m=[float(x) for x in ref.windows],
        windows_after_m=[float(x) for x in (after or ref).windows],
        settings={
            **{k: getattr(options, k) for k in options.__dataclass_fields__},
            "dofs": list(options.dofs),
            "reference_effects": [getattr(e, "name", str(e)) for e in effects],
            "free": list(setup.free),
            "floor_rms_m": floor_rms,
            "significant": significant,
        },
        seconds=time.perf_counter() - t0,
        alternatives=alts,
        separated=separated(compared),
        dropped=dropped,
        after=after,
        reference=ref,
        stages=fitted,
        combined_stages=combined,
    )
