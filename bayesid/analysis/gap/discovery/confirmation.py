"""Confirmation of the selected terms by the output-error fit and the held-out runs: each term
refitted with every free coefficient (:class:`TermFit`, :func:`fit_term`), its record and the
kept test (:func:`refit_row`, :func:`worst_run`, :func:`decide`), the kept terms added together
best first (:func:`dominance_order`, :func:`combine`) and the competing structures the held-out
runs can or cannot separate from each kept term (:func:`compare_structures`,
:func:`alternatives`, :func:`separated`, :func:`window_runs`)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ....estimation.laplace import fit_covariance
from ....estimation.windows import WindowProblem, fit_model, warm_starts
from ....models.library import term_library
from ..candidates import Setup, Stage, score_stage
from ..records import TermRow
from ..verdict import RunSeparation, Thresholds, is_contributor, paired_window_test, run_separation_test
from .library import extended_start, nuisance_start, with_terms
from .selection import Selection

__all__ = [
    "TermFit",
    "fit_term",
    "refit_row",
    "worst_run",
    "diverged_run",
    "decide",
    "combine",
    "combined_competitors",
    "prune",
    "dominance_order",
    "compare_structures",
    "training_separation",
    "TrainingSeparation",
    "Refits",
    "alternatives",
    "separated",
    "window_runs",
    "heldout_rms_by_run",
]


@dataclass(frozen=True)
class TermFit:
    """One candidate term of a discovery: a task of :func:`fit_term`.

    Parameters
    ----------
    term : str
        The term's name.
    start : float
        Its regression coefficient (prime): the second start of the fit is the reference value
        plus this (the first is the reference value).
    ref : Stage
        The model it extends.
    setup : Setup
        The reference model's vehicle, free coefficients, tracks and windows.
    effects : tuple
        The reference model's effects.
    sd_fit : dict
        The reference fit's channel weights.
    max_nfev : int
        Least-squares iterations.
    initial : float, default 0.0
        The term's value in the reference model (:func:`~.library.reference_values`: 0 for a missing term,
        the followed value for a tied coefficient).
    """

    term: str
    start: float
    ref: Stage
    setup: Setup
    effects: tuple
    sd_fit: dict
    max_nfev: int
    initial: float = 0.0


def fit_term(task: TermFit) -> tuple[Stage | None, list]:
    """Add a term to the reference model and re-identify every free coefficient; score the fit.

    The fit starts at the reference plus the term's regression value (the linearised problem's
    step, :func:`~.selection.select_terms`). Only when that fit fails or ends above the reference's cost does
    a second one start at the reference itself (the term at its reference value, which reproduces
    the reference model), and the lower of the two is kept: one fit per term where the step is
    good, as the first round's candidates get one.

    A module-level function of a picklable argument (run as a task, :class:`bayesid.tasks.Runner`).

    Parameters
    ----------
    task : TermFit
        The term and the model it extends.

    Returns
    -------
    stage : Stage or None
        None when every fit failed.
    messages : list
        About failed starts (str), and ``("sd", value)``: the term's Laplace sd.
    """
    setup = with_terms(task.setup, {task.term: task.initial})
    model, ct, ch = setup.build([e for e in task.effects if e not in setup.effects])
    problem = WindowProblem(model, ct, task.sd_fit, max_nfev=task.max_nfev)
    nu0 = nuisance_start(task.ref, model)
    best, messages = None, []
    for c in dict.fromkeys((task.initial + float(task.start), task.initial)):
        if best is not None and best.cost <= task.ref.fit.cost * (1.0 + 1e-6):
            break  # the step's fit is at least as good as the reference: no second start
        try:
            f = fit_model(problem, extended_start(task.ref, model, [c]), nu0, starts0=warm_starts(task.ref.fit, ct))
        except Exception as exc:  # noqa: BLE001 - a failed start is reported
            messages.append(f"{task.term} (start {c:.3g}) failed: {exc}")
            continue
        if best is None or f.cost < best.cost:
            best = f
    if best is None:
        return None, messages
    try:  # the term's Laplace sd (AR(1)-inflated, as bayesid fit reports it)
        cov, _ = fit_covariance(best, ct)
        messages.append(("sd", float(np.sqrt(max(cov[model.n_theta - 1, model.n_theta - 1], 0.0)))))
    except Exception:  # noqa: BLE001 - no sd: the row says None
        pass
    return score_stage(model, best, ct, ch, task.sd_fit), messages


def refit_row(
    term: str,
    st: Stage | None,
    ref: Stage,
    sel: Selection | None,
    floor_rms: float,
    sd: float | None = None,
    runs: tuple | None = None,
    margin: float = 0.1,
) -> TermRow:
    """The ``discovered`` record of a refitted candidate.

    Parameters
    ----------
    term : str
        The term.
    st : Stage or None
        Its refit (None: every fit failed).
    ref : Stage
        The model it extends.
    sel : Selection or None
        The selection's numbers (:func:`~.selection.select_terms`); None for a term refitted on
        top of others.
    floor_rms : float
        The noise floor's held-out RMS, m.
    sd : float, optional
        The term's coefficient's Laplace sd.
    runs : tuple, optional
        ``(run of each held-out window, run names)`` of :func:`window_runs`, for the run test of
        :func:`worst_run`.
    margin : float, default 0.1
        The run test's relative margin.

    Returns
    -------
    TermRow
        The row of :attr:`bayesid.analysis.gap.discovery.Discovery.discovered` (without
        ``kept`` and ``reason`` unless every fit failed: :func:`decide` sets them).
    """
    sel = sel or Selection()
    row = TermRow(
        term=term,
        dof=term_library(ref.model).dof(term),
        inclusion_probability=sel.inclusion.get(term, 0.0),
        group_inclusion_probability=sel.group_probability.get(term, 0.0),
        group=sel.groups.get(term, []),
        regression_coefficient=sel.coefficient.get(term, 0.0),
        heldout_rms_before_m=ref.held.rms_position_m,
        train_rms_before_m=ref.train.rms_position_m,
    )
    if st is None:
        return replace(row, kept=False, reason="every fit failed")
    before, after = ref.held.rms_position_m, st.held.rms_position_m
    excess = before - floor_rms
    return replace(
        row,
        coefficient=st.fit.coefficients()[term],
        coefficient_sd=sd,
        heldout_rms_after_m=after,
        train_rms_after_m=st.train.rms_position_m,
        shrinkage=1 - after / before,  # also written as heldout_shrinkage (TermRow's alias)
        delta_bic=st.fit.bic - ref.fit.bic,
        # the refit starts at the reference (the term at 0): ending above it is a failed fit
        refit_failed=bool(st.fit.cost > ref.fit.cost * (1.0 + 1e-6)),
        window_p_value=paired_window_test(ref.windows, st.windows),
        heldout_windows_after_m=[float(x) for x in st.windows],
        excess_removed=(before - after) / excess if excess > 0 else 0.0,
        worst_run=worst_run(ref, st, runs, margin),
    )


def diverged_run(ref_windows, windows, runs) -> int | None:
    """The first held-out run on which a model's prediction diverged (a NaN window) where the
    model it is compared with predicts a finite error: the scores pool the finite samples only,
    so without this check a diverged run would simply not count against the model.

    Parameters
    ----------
    ref_windows, windows : array_like, shape (n_windows,)
        The two models' window RMS errors, m (NaN where a window's prediction diverged).
    runs : array_like of int, shape (n_windows,)
        The held-out run of each window.

    Returns
    -------
    int or None
        The run's index, None when ``windows`` has no NaN window that ``ref_windows`` has finite
        (or the shapes differ).
    """
    a, b, idx = np.asarray(ref_windows, float), np.asarray(windows, float), np.asarray(runs)
    if not a.shape == b.shape == idx.shape:
        return None
    bad = np.isfinite(a) & ~np.isfinite(b)
    return int(idx[bad][0]) if bad.any() else None


def worst_run(ref: Stage, st: Stage, runs: tuple | None, margin: float) -> dict | None:
    """The held-out run on which a refit predicts worst against its reference model: ``{"run",
    "error_ratio", "p_value"}`` of the run test (:func:`run_separation_test` with the reference
    first: the refit's window errors above the reference's by more than ``margin`` on one run,
    Bonferroni over the runs), None without the runs' layout. A term that passes the pooled
    window test while one run's windows are significantly worse does not carry to that run.

    Parameters
    ----------
    ref : Stage
        The reference model, scored per held-out window (``windows``).
    st : Stage
        The refit, scored on the same windows.
    runs : tuple or None
        ``(run of each held-out window, run names)`` (:func:`window_runs`).
    margin : float
        The run test's relative margin.

    Returns
    -------
    dict or None
        ``{"run", "error_ratio", "p_value"}``; None without ``runs``, when the windows do not
        match them, or when no run is worse. A run on which the refit's prediction diverges
        (:func:`diverged_run`) is the worst: ``{"run", "error_ratio": None, "p_value": 0.0,
        "diverged": True}``.
    """
    if runs is None:
        return None
    idx, names = runs
    a, b = np.asarray(ref.windows, float), np.asarray(st.windows, float)
    if not (a.shape == b.shape == np.shape(idx)):
        return None
    gone = diverged_run(a, b, idx)
    if gone is not None:
        return {"run": _run_name(names, gone), "error_ratio": None, "p_value": 0.0, "diverged": True}
    res = run_separation_test(a, b, np.asarray(idx), margin)
    i = res.run_second_worse
    if i is None:
        return None
    return {"run": _run_name(names, i), "error_ratio": res.ratio_by_run.get(i), "p_value": res.p_second_worse}


def _passes(row, significant: bool, th: Thresholds) -> bool:
    """The kept test: the contributor test (:func:`is_contributor`) and no held-out run
    predicted significantly worse than by the reference model (:func:`worst_run` at
    ``th.partial_p``)."""
    worst = row.get("worst_run") or {}
    harms = worst.get("p_value") is not None and worst["p_value"] < th.partial_p
    return is_contributor(row, significant, th) and not harms


def decide(row, significant: bool, th: Thresholds):
    """Set ``kept`` and ``reason`` of a refitted candidate by the kept test: the contributor test
    (:func:`~bayesid.analysis.gap.verdict.is_contributor`) and no held-out run predicted
    significantly worse than by the reference model (:func:`worst_run` at ``th.partial_p``). A row
    that has ``kept`` already is left as it is.

    Parameters
    ----------
    row : TermRow or dict
        :func:`refit_row` (a record), or a dict with its keys (updated in place).
    significant : bool
        Whether the reference model's gap is significant.
    th : Thresholds
        The test's thresholds.

    Returns
    -------
    TermRow or dict
        The record with ``kept`` and ``reason`` (a new one: records are frozen), or the dict
        updated.
    """
    if "kept" in row:
        return row
    kept, reason = _kept_and_reason(row, significant, th)
    if isinstance(row, TermRow):
        return replace(row, kept=kept, reason=reason)
    row["kept"], row["reason"] = kept, reason
    return row


def _kept_and_reason(row, significant: bool, th: Thresholds) -> tuple[bool, str]:
    """``(kept, reason)`` of the kept test on a refitted candidate (:func:`decide`)."""
    kept = _passes(row, significant, th)
    worst = row.get("worst_run") or {}
    if worst.get("diverged"):
        return False, f"its prediction of run {worst['run']} diverges where the model without it does not"
    if kept:
        return kept, "improves the held-out windows (contributor test)"
    if is_contributor(row, significant, th):
        return kept, (
            f"improves the held-out windows overall but predicts run {worst['run']} worse than the model "
            f"without it (window errors x{worst['error_ratio']:.2f}, run test p = {worst['p_value']:.2g}): "
            "it does not carry to that run"
        )
    if not significant:
        return kept, "the gap is not significant: nothing to explain"
    if row.get("refit_failed"):
        return kept, (
            "the refit ended above its reference on the training runs: a failed fit, not evidence against "
            "the term (with fitted window starts, see the base-fit check)"
        )
    if row["delta_bic"] > th.bic_threshold:
        return kept, f"training ΔBIC {row['delta_bic']:.1f} > {th.bic_threshold:g}"
    if row["heldout_shrinkage"] <= 0:
        return kept, "fits the training runs but not the held-out ones"
    return kept, f"held-out gain not significant (window test p = {row['window_p_value']:.3g})"


@dataclass(frozen=True)
class Refits:
    """What the refits of one discovery share: the reference model and its setup, how a term is
    fitted and how it is judged (:func:`combine`, :func:`prune`, :func:`combined_competitors`).

    Parameters
    ----------
    ref : Stage
        The reference model.
    setup : Setup
        Its setup.
    effects : tuple of Effect
        Its effects.
    sd_fit : dict
        The channel weights of the fits.
    max_nfev : int
        Iterations of each fit.
    floor_rms : float
        The noise floor's held-out RMS, m.
    thresholds : Thresholds
        The verdict's thresholds.
    runs : tuple or None
        ``(run of each held-out window, run names)`` (:func:`window_runs`).
    initial : dict
        Each term's value in the reference (:func:`~.library.reference_values`).
    """

    ref: Stage
    setup: Setup
    effects: tuple
    sd_fit: dict
    max_nfev: int
    floor_rms: float
    thresholds: Thresholds
    runs: tuple | None
    initial: dict


def _fit_on_top(values: dict, n: str, cur: Stage, refits: Refits):
    """Term ``n`` refitted on top of the terms ``values`` (``{term: value in cur}``) of the
    model ``cur``, every coefficient re-identified from ``cur``'s: the scored stage, or None when
    the fit fails."""
    setup, ref, sd_fit = refits.setup, refits.ref, refits.sd_fit
    trial = with_terms(setup, {**values, n: refits.initial[n]})
    model, ct, ch = trial.build([e for e in refits.effects if e not in setup.effects])
    p0 = extended_start(ref, model, [*values.values(), refits.initial[n]])
    n_ref = ref.model.n_theta
    p0[: n_ref + len(values)] = cur.fit.p[: n_ref + len(values)]
    try:
        f = fit_model(
            WindowProblem(model, ct, sd_fit, max_nfev=refits.max_nfev),
            p0,
            nuisance_start(cur, model),
            starts0=warm_starts(cur.fit, ct),
        )
    except Exception:  # noqa: BLE001 - the combination is skipped
        return None
    return score_stage(model, f, ct, ch, sd_fit)


def combine(kept: list, stages: dict, refits: Refits):
    """Add the kept terms together, best first (:func:`dominance_order`): each further term is refitted on top of those
    added (all coefficients re-identified) and stays only if it passes the kept test
    (:func:`decide`) against them while their held-out error is still above the floor band.

    Parameters
    ----------
    kept : list of str
        The terms that passed the kept test alone (at least one).
    stages : dict
        ``{term: Stage}`` of their single-term refits.
    refits : Refits
        The reference model, its setup, the fits and the judgement.

    Returns
    -------
    found : list of str
        The terms of the final model, in the order added.
    chain : list of Stage
        ``chain[i]`` is the model with ``found[: i + 1]`` (``chain[-1]`` the final model).
    """
    floor_rms, th, runs = refits.floor_rms, refits.thresholds, refits.runs
    order = dominance_order(kept, stages, th, runs)
    found, chain = [order[0]], [stages[order[0]]]
    for n in order[1:]:
        cur = chain[-1]
        if cur.held.rms_position_m <= th.none_ratio * floor_rms:
            break  # the gap is closed: a further term would fit noise
        values = {k: cur.fit.coefficients()[k] for k in found}
        st = _fit_on_top(values, n, cur, refits)
        if st is None:
            continue
        row = refit_row(n, st, cur, None, floor_rms, runs=runs, margin=th.separation_margin)
        if _passes(row, True, th):
            found.append(n)
            chain.append(st)
    return found, chain


def prune(found: list, chain: list, stages: dict, refits: Refits) -> tuple[list, list, list]:
    """Backward elimination after :func:`combine`: a term of the combination that no longer passes
    the kept test on top of all the others (the model without it, every coefficient refitted,
    against the model with it) is dropped, the weakest first (largest window p), until every
    remaining term passes.

    :func:`combine` adds terms best first while the held-out error stays above the floor band, so
    a surrogate chosen first can stay in the model after the term it stood for joined it (the
    forward half of stepwise selection; Efroymson 1960, "Multiple regression analysis", in
    Ralston & Wilf, Mathematical Methods for Digital Computers: a variable entered early is
    removed when later ones make it redundant).

    Parameters
    ----------
    found, chain : list
        :func:`combine`'s terms and models (``chain[i]`` with ``found[: i + 1]``).
    stages : dict
        ``{term: Stage}`` of the single-term refits (every term of ``found`` among them).
    refits : Refits
        The reference model, its setup, the fits and the judgement.

    Returns
    -------
    found : list of str
        The terms kept, in the order added.
    chain : list of Stage
        ``chain[i]`` the model with ``found[: i + 1]`` (refitted where the combination had no
        such model).
    dropped : list of str
        The terms dropped, in the order dropped.
    """
    floor_rms, th, runs = refits.floor_rms, refits.thresholds, refits.runs
    memo = {tuple(found[: i + 1]): st for i, st in enumerate(chain)} | {(t,): stages[t] for t in found}

    def model_of(terms: tuple):
        if terms not in memo:
            below = model_of(terms[:-1])
            values = None if below is None else {k: below.fit.coefficients()[k] for k in terms[:-1]}
            memo[terms] = None if below is None else _fit_on_top(values, terms[-1], below, refits)
        return memo[terms]

    dropped = []
    while len(found) > 1:
        full, weakest = model_of(tuple(found)), None
        for t in found:
            without = model_of(tuple(k for k in found if k != t))
            if full is None or without is None:
                continue
            row = refit_row(t, full, without, None, floor_rms, runs=runs, margin=th.separation_margin)
            if not _passes(row, True, th) and (weakest is None or row.window_p_value > weakest[1]):
                weakest = (t, row.window_p_value)
        if weakest is None:
            break
        found = [k for k in found if k != weakest[0]]
        dropped.append(weakest[0])
    return found, [model_of(tuple(found[: i + 1])) for i in range(len(found))], dropped


def combined_competitors(
    found: list, chain: list, compared: dict, competitors: list, refits: Refits, train_names=None
) -> tuple[dict, dict]:
    """The competitors of each term added on top of others (``found[i]``, ``i >= 1``), refitted in
    its place: on top of ``found[:i]``, the model it was judged against.

    A term added in a combination was chosen over the others for the second (third, ...) place,
    yet :func:`compare_structures` compares single-term refits, which lack the first term: a
    competitor that mimics the residual left by the first term would not be seen there. Each
    competitor ``a`` is refitted on top of ``found[:i]`` (:func:`_fit_on_top`), judged by the
    kept test against ``chain[i - 1]`` and compared with ``chain[i]`` by the tests of
    :func:`compare_structures` (Box & Hill 1967: models of equal size, the same data).

    Parameters
    ----------
    found, chain : list
        :func:`combine`'s terms and models.
    compared : dict
        :func:`compare_structures` of the single-term refits; the entries of ``found[i]``
        (``i >= 1``) are replaced.
    competitors : list of str
        Refitted terms that may compete for a place; the terms of ``found`` are skipped.
    refits : Refits
        The reference model, its setup, the fits and the judgement (as :func:`combine`).
    train_names : list of str, optional
        The training runs' names.

    Returns
    -------
    compared : dict
        ``compared`` with the entries of ``found[1:]`` from the refits in their place (each entry
        has ``on_top_of``: the terms it was refitted on top of).
    stages : dict
        ``{found[i]: {term: Stage}}``: ``found[i]``'s model (``chain[i]``) and each competitor's
        refit in its place, for the design.
    """
    floor_rms, th, runs = refits.floor_rms, refits.thresholds, refits.runs
    out, stages = dict(compared), {}
    for i in range(1, len(found)):
        k, below = found[i], chain[i - 1]
        values = {t: below.fit.coefficients()[t] for t in found[:i]}
        # it passed the kept test in the combination
        rows = [
            replace(refit_row(k, chain[i], below, None, floor_rms, runs=runs, margin=th.separation_margin), kept=True)
        ]
        fitted = {k: chain[i]}
        for a in dict.fromkeys(competitors):
            if a in found or a not in refits.initial:
                continue
            st = _fit_on_top(values, a, below, refits)
            if st is None:
                continue
            rows.append(
                decide(refit_row(a, st, below, None, floor_rms, runs=runs, margin=th.separation_margin), True, th)
            )
            fitted[a] = st
        cmp = compare_structures([k], rows, fitted, th, runs[0], runs[1], train_names)
        out[k] = [{**e, "on_top_of": list(found[:i])} for e in cmp[k]]
        stages[k] = fitted
    return out, stages


def dominance_order(kept: list, stages: dict, th: Thresholds, runs: tuple | None = None) -> list:
    """The kept terms, best first: a term the held-out runs show to be worse than another kept
    term comes after it, the rest by held-out position RMS.

    Term ``a`` *dominates* ``b`` when some held-out run predicts ``b`` significantly worse than
    ``a`` and none predicts ``a`` significantly worse than ``b`` (the run-by-run test of
    :func:`compare_structures`, :func:`~bayesid.analysis.gap.verdict.run_separation_test`, at
    ``th.partial_p`` with ``th.separation_margin``), or, where the held-out runs separate
    neither way, when the training runs show ``b`` to be worse (:func:`training_separation`).
    The pooled held-out RMS alone would put first a term that ties on many runs and loses
    clearly on one, such as a designed run added to separate it from the hidden term.

    Parameters
    ----------
    kept : list of str
        Terms that passed the kept test alone.
    stages : dict
        ``{term: Stage}``, each with ``held["rms_position_m"]`` and per-window ``windows``.
    th : Thresholds
        ``partial_p`` and ``separation_margin``.
    runs : tuple, optional
        ``(run of each held-out window, run names)`` (:func:`window_runs`); without it the
        order is by held-out RMS.

    Returns
    -------
    list of str
        The terms ordered by (number of kept terms that dominate it, held-out RMS).
    """
    beaten = dict.fromkeys(kept, 0)
    if runs is not None:
        idx = np.asarray(runs[0])
        for i, a in enumerate(kept):
            for b in kept[i + 1 :]:
                wa, wb = np.asarray(stages[a].windows, float), np.asarray(stages[b].windows, float)
                if not wa.shape == wb.shape == idx.shape:
                    continue
                res = run_separation_test(wa, wb, idx, th.separation_margin)
                b_worse, a_worse = res.p_second_worse < th.partial_p, res.p_first_worse < th.partial_p
                # a prediction that diverges on a run the other one predicts is the worse one there
                b_worse = b_worse or diverged_run(wa, wb, idx) is not None
                a_worse = a_worse or diverged_run(wb, wa, idx) is not None
                if not b_worse and not a_worse:  # the held-out runs tie them: do the training runs?
                    b_worse = training_separation(stages[a], stages[b], th).separated
                    a_worse = training_separation(stages[b], stages[a], th).separated
                if b_worse and not a_worse:
                    beaten[b] += 1
                elif a_worse and not b_worse:
                    beaten[a] += 1
    return sorted(kept, key=lambda n: (beaten[n], stages[n].held.rms_position_m))


def compare_structures(
    found: list, rows: list, stages: dict, th: Thresholds, runs=None, run_names=None, train_names=None
) -> dict:
    """Every refitted term that competes with a kept term, and whether the held-out runs separate
    the two.

    A refitted term ``a`` competes with a kept term ``k`` when it passes the kept test alone, or
    when its held-out RMS is no larger than ``k``'s (it predicts the held-out runs as well, though
    its gain over the reference model did not reach the kept test's level). The runs *separate*
    ``k`` from ``a`` when ``k``'s held-out windows are significantly better than ``a``'s, by
    either of two tests at the kept test's level ``th.partial_p``:

    - pooled over every held-out window: the one-sided paired window test
      (:func:`paired_window_test`, Wilcoxon signed rank), the test that keeps a term;
    - run by run (when ``runs`` is given): some run on which ``a``'s window errors exceed
      ``k``'s by more than ``th.separation_margin`` and none on which ``k``'s exceed ``a``'s
      (:func:`~bayesid.analysis.gap.verdict.run_separation_test`, Bonferroni over the runs): a
      single designed run of a few windows separates two structures that agree on every
      other run, which the pooled rank test cannot see;
    - on the training runs, when the held-out runs favour neither (no held-out run on which
      ``k`` is significantly worse, and ``a``'s held-out windows not significantly better
      pooled): the run test, pooled and run by run, on the two refits' training windows
      (:func:`training_separation`). Both refits have the same number of coefficients and were
      fitted to the same windows, so the one whose fitted model follows those windows
      significantly worse is the worse structure for them (two models of equal size compared on
      the data they were fitted to, Box & Hill 1967), and a designed run a user adds to the training
      runs separates there, where the held-out runs, of the old kinds, cannot. The window is
      the unit of both tests, not the sample: simulation errors are correlated within a window,
      which a comparison of the training log-likelihoods (ΔBIC) ignores.

    A prediction that diverges on a held-out run the other model predicts (:func:`diverged_run`)
    is the worse one on that run (p = 0): ``k`` diverging makes the runs favour ``a``; ``a``
    diverging separates it from ``k``.

    Otherwise ``a`` is an *alternative*: the output-error counterpart of a collinear group, two
    terms whose refitted models predict the held-out runs equally well, whatever their columns'
    cosine (Box & Hill 1967, "Discrimination among mechanistic models", Technometrics 9:57-71:
    models that fit the data equally are discriminated only by a run where their predictions
    differ).

    Parameters
    ----------
    found : list of str
        The kept terms of the final model.
    rows : list of dict
        Every refitted candidate (``term``, ``kept``, ``heldout_rms_after_m``, ``coefficient``).
    stages : dict
        ``{term: Stage}`` of the single-term refits (every refit that converged).
    th : Thresholds
        ``partial_p`` and ``separation_margin``.
    runs : ndarray of int, shape (n_windows,), optional
        The held-out run of each window of the stages' ``windows``; without it only the pooled
        test is used.
    run_names : list of str, optional
        The held-out runs' names, indexed by ``runs``.
    train_names : list of str, optional
        The training runs' names, indexed by the stages' ``train_runs``.

    Returns
    -------
    dict
        ``{kept term: [{"term", "passed_kept_test", "coefficient", "heldout_rms_m",
        "window_p_value", "run_p_value", "separating_run", "run_error_ratio", "kept_worse_run",
        "kept_worse_run_p_value", "separable", "heldout_rms_by_run_m"}, ...]}``, best first (lowest held-out RMS). ``window_p_value``:
        the pooled test's p; ``run_p_value``: the run test's (None without ``runs``);
        ``separating_run`` and ``run_error_ratio``: the run with the strongest evidence that
        ``a`` is worse and its geometric-mean error ratio ``a / k``; ``kept_worse_run`` and
        ``kept_worse_run_p_value``: the converse (a run on which ``k`` is significantly worse
        than ``a``, or None; its p); ``heldout_rms_by_run_m``
        ``{held-out run: position RMS, m}``; ``train_window_p_value``, ``train_run_p_value``,
        ``train_separating_run`` and ``train_error_ratio``: the training runs' tests
        (:func:`training_separation`; None without training windows); ``separated_by``: which
        data separate them (``"heldout"``, ``"training"`` or None); ``favoured``: the held-out
        runs show the competitor better than ``k`` (pooled, or on some run by the run test).
    """
    out = {}
    for k in found:
        out[k] = []
        if k not in stages:
            continue
        k_rms = next((r.get("heldout_rms_after_m") for r in rows if r["term"] == k), None) or np.inf
        kw = np.asarray(stages[k].windows)
        for r in rows:
            a = r["term"]
            if a == k or a in found or a not in stages:
                continue
            if not r.get("kept") and not (r.get("heldout_rms_after_m") or np.inf) <= k_rms:
                continue
            aw = np.asarray(stages[a].windows)
            p = paired_window_test(aw, kw)
            run = RunSeparation(None, 1.0, None, None, {}, 0)  # no runs: no run test
            if runs is not None and len(runs) == len(kw) == len(aw):
                run = run_separation_test(kw, aw, np.asarray(runs), th.separation_margin)
            # a prediction that diverges on a run the other one predicts is the worse one there
            a_gone = diverged_run(kw, aw, runs) if runs is not None else None
            k_gone = diverged_run(aw, kw, runs) if runs is not None else None
            if k_gone is not None:  # the kept term's prediction diverges where the competitor's does not
                run = replace(run, run_first_worse=k_gone, p_first_worse=0.0)
            elif a_gone is not None:
                run = replace(run, run_second_worse=a_gone, p_second_worse=0.0, p_first_worse=1.0)
            i = run.run_second_worse
            by_run = run.ratio_by_run
            by_heldout = k_gone is None and (
                p < th.partial_p
                or (
                    run.p_second_worse is not None
                    and run.p_second_worse < th.partial_p
                    and run.p_first_worse >= th.partial_p
                )
            )
            trn = training_separation(stages[k], stages[a], th, train_names)
            heldout_favours_a = a_gone is None and (
                run.p_first_worse < th.partial_p or paired_window_test(kw, aw) < th.partial_p
            )
            by_training = not by_heldout and not heldout_favours_a and trn.separated
            separated = by_heldout or by_training
            out[k].append(
                {
                    "term": a,
                    "passed_kept_test": bool(r.get("kept")),
                    "coefficient": r.get("coefficient"),
                    "heldout_rms_m": r["heldout_rms_after_m"],
                    "window_p_value": p,
                    "run_p_value": run.p_second_worse,
                    "separating_run": None if i is None else _run_name(run_names, i),
                    "run_error_ratio": by_run.get(i) if i is not None else None,
                    "kept_worse_run": None
                    if run.run_first_worse is None or run.p_first_worse >= th.partial_p
                    else _run_name(run_names, run.run_first_worse),
                    "kept_worse_run_p_value": run.p_first_worse if runs is not None else None,
                    "separable": bool(separated),
                    "heldout_rms_by_run_m": heldout_rms_by_run(stages[a]),
                    "train_window_p_value": trn.p_window,
                    "train_run_p_value": trn.p_run,
                    "train_separating_run": trn.run,
                    "train_error_ratio": trn.ratio,
                    "separated_by": "heldout" if by_heldout else "training" if by_training else None,
                    "favoured": bool(heldout_favours_a),
                }
            )
        out[k].sort(key=lambda d: d["heldout_rms_m"])
    return out


@dataclass(frozen=True)
class TrainingSeparation:
    """Whether the training runs show one refit worse than another (:func:`training_separation`).

    Parameters
    ----------
    separated : bool
        The training runs show ``other`` worse and neither test favours it.
    p_window, p_run : float or None
        The pooled and the run-by-run test's p that ``other`` is worse (None without training
        windows).
    run : str or int or None
        The training run of the run test's strongest evidence.
    ratio : float or None
        Its geometric-mean window error ratio ``other / kept``.
    """

    separated: bool = False
    p_window: float | None = None
    p_run: float | None = None
    run: str | int | None = None
    ratio: float | None = None


def training_separation(kept: Stage, other: Stage, th: Thresholds, names=None) -> TrainingSeparation:
    """Whether the training runs show ``other`` to be worse than ``kept``: its fitted model
    follows the training windows significantly worse.

    The refits' per-window training errors (``Stage.train_windows``) are compared as the
    held-out ones are run by run (:func:`~bayesid.analysis.gap.verdict.run_separation_test`:
    the mean log error ratio ``log(other / kept)`` tested against ``log(1 + th.separation_margin)``,
    one-sided, at ``th.partial_p``), once pooled over every training window and once run by
    run (Bonferroni over the runs); neither may favour ``other`` over ``kept``. Unlike the
    held-out pooled test (Wilcoxon signed rank, no margin), the pooled training test has the
    margin: the windows were fitted, and a structure of the same size that follows them a few
    per cent worse everywhere is not shown wrong by that.

    Parameters
    ----------
    kept, other : Stage
        Two single-term refits on the same training tracks and fit windows.
    th : Thresholds
        ``partial_p`` and ``separation_margin``.
    names : list of str, optional
        The training runs' names (else their indices).

    Returns
    -------
    TrainingSeparation
        Whether they are separated, the two tests' p-values, the run and its error ratio.
    """
    kw, aw = getattr(kept, "train_windows", None), getattr(other, "train_windows", None)
    runs = getattr(kept, "train_runs", None)
    if kw is None or aw is None or runs is None or not len(kw) == len(aw) == len(runs):
        return TrainingSeparation()
    kw, aw, runs = np.asarray(kw, float), np.asarray(aw, float), np.asarray(runs)
    pooled = run_separation_test(kw, aw, np.zeros(len(runs), int), th.separation_margin)
    run = run_separation_test(kw, aw, runs, th.separation_margin)
    i = run.run_second_worse
    worse = pooled.p_second_worse < th.partial_p or run.p_second_worse < th.partial_p
    better = pooled.p_first_worse < th.partial_p or run.p_first_worse < th.partial_p
    return TrainingSeparation(
        separated=bool(worse and not better),
        p_window=float(pooled.p_second_worse),
        p_run=float(run.p_second_worse),
        run=None if i is None else _run_name(names, i),
        ratio=run.ratio_by_run.get(i) if i is not None else None,
    )


def _run_name(names, i: int) -> str:
    """The name of held-out run ``i`` (its index when unnamed)."""
    return str(names[i]) if names is not None and 0 <= i < len(names) else str(i)


def alternatives(compared: dict) -> dict:
    """The structures the held-out runs cannot separate from each kept term.

    Parameters
    ----------
    compared : dict
        :func:`compare_structures`.

    Returns
    -------
    dict
        ``{kept term: [entry, ...]}``, the entries of ``compared`` with ``separable`` False,
        without that key; an empty list where the runs separate the kept term from every other.
    """
    return _split(compared, separable=False)


def separated(compared: dict) -> dict:
    """The competing structures the held-out runs separate from each kept term.

    Parameters
    ----------
    compared : dict
        :func:`compare_structures`.

    Returns
    -------
    dict
        ``{kept term: [entry, ...]}``, the entries of ``compared`` with ``separable`` True,
        without that key.
    """
    return _split(compared, separable=True)


def _split(compared: dict, separable: bool) -> dict:
    """The entries of :func:`compare_structures` whose ``separable`` is ``separable``, without it."""
    return {
        k: [{n: v for n, v in e.items() if n != "separable"} for e in es if e["separable"] is separable]
        for k, es in compared.items()
    }


def window_runs(setup: Setup, model) -> tuple[np.ndarray, list]:
    """The held-out run of each protocol window, in the order of a stage's ``windows``.

    Parameters
    ----------
    setup : Setup
        The held-out tracks, window and start rule.
    model : SimulationModel
        Any model of the setup (the windows do not depend on the parameters).

    Returns
    -------
    tuple
        ``(runs, names)``: ``runs`` ndarray of int, shape (n_windows,), the index of each
        window's track; ``names`` the held-out tracks' names.
    """
    ctxs = [model.context(t, setup.window_s, start=setup.rule, leadin_s=setup.leadin_s) for t in setup.heldout]
    return np.repeat(np.arange(len(ctxs)), [c.W for c in ctxs]), [c.name for c in ctxs]


def heldout_rms_by_run(stage) -> dict:
    """``{held-out run: position RMS, m}`` of a refit.

    Parameters
    ----------
    stage : Stage
        The refit (its ``held["per_track_rms_position_m"]``).

    Returns
    -------
    dict
        ``{held-out run: position RMS, m}``; empty when the stage has no held-out scores.
    """
    return dict((getattr(stage, "held", None) or {}).get("per_track_rms_position_m", {}))
