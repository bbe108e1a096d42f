"""Sparse selection of the candidate terms: the output-error problem linearised in the
candidates' coefficients with the free directions projected out (:func:`linearised_problem`), the
block-bootstrap ensemble STLSQ on it with inclusion probabilities and collinear groups
(:func:`select_terms`, :func:`bayesid.analysis.sindy.block_ensemble_stlsq`), the candidates a free
parameter mimics (:func:`mimics`), the score test (:func:`score_test`) and the terms refitted:
the most probable groups (:func:`refit_candidates`) and their alternatives
(:func:`alternative_pool`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ....estimation.windows import WindowObjective, warm_starts
from ....models.library import term_library
from ...sindy import block_ensemble_stlsq
from ..candidates import Setup, Stage
from .library import augmented_model, extended_start, nuisance_start, reference_values
from .options import DiscoveryOptions

__all__ = [
    "LinearisedProblem",
    "Selection",
    "linearised_problem",
    "project_out",
    "mimics",
    "select_terms",
    "score_test",
    "refit_candidates",
    "alternative_pool",
    "mimicked_refits",
    "mimicked_companions",
    "tied_companions",
    "TIED_SHARE",
    "MAX_TIED",
]


@dataclass(frozen=True)
class LinearisedProblem:
    """The output-error problem linearised in the candidates' coefficients (:func:`linearised_problem`).

    Parameters
    ----------
    y : ndarray, shape (n,)
        Minus the projected weighted residuals.
    X : ndarray, shape (n, K)
        The projected candidate columns.
    size : ndarray, shape (K,)
        The columns' RMS before the projection.
    blocks : list of ndarray
        Row indices of each window (the block bootstrap's blocks).
    rms : float
        The residuals' RMS before the projection.
    mimics : dict, default {}
        ``{candidate: {"parameter", "cosine", "shift", "shift_effect"}}`` (:func:`mimics`).
    """

    y: np.ndarray
    X: np.ndarray
    size: np.ndarray
    blocks: list
    rms: float
    mimics: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Selection:
    """The ensemble's selection of the candidate terms (:func:`select_terms`); every field
    defaults to empty (nothing selected).

    Parameters
    ----------
    inclusion : dict
        ``{term: inclusion probability}``.
    group_probability : dict
        ``{term: probability that the ensemble picks it or a term of its collinear group}``.
    groups : dict
        ``{term: [collinear terms]}``.
    coefficient : dict
        ``{term: median prime coefficient over the models that select it}``.
    share : dict
        ``{term: median share of the residual RMS}``.
    mimicked : list of str
        The terms a refit of the free coefficients reproduces.
    mimicked_by : dict
        ``{mimicked term: {"parameter", "cosine", "shift", "shift_effect", "span_cosine"}}``,
        likeliest stand-ins first.
    explained : float
        Share of the projected residual's variance the median model explains.
    projected_rms : float
        The residual's RMS after the projection / before it.
    """

    inclusion: dict = field(default_factory=dict)
    group_probability: dict = field(default_factory=dict)
    groups: dict = field(default_factory=dict)
    coefficient: dict = field(default_factory=dict)
    share: dict = field(default_factory=dict)
    mimicked: list = field(default_factory=list)
    mimicked_by: dict = field(default_factory=dict)
    explained: float = 0.0
    projected_rms: float = 0.0


def linearised_problem(
    setup: Setup, ref: Stage, effects, names: list, sd_fit: dict, window_s=None
) -> LinearisedProblem:
    """The output-error problem of the training tracks, linearised at the reference fit in the
    candidates' coefficients (all at 0).

    The windows: with measured start states, the fit's own (``setup.fit_window_s``): every
    restart from a measured state is another experiment, and over few long windows the free
    coefficients' sensitivities span nearly every candidate's (a synthetic KVLCC2 case with a
    hidden ``Nabsdr``: named with inclusion 0.97 over 15 s windows, set aside as mimicked over
    60 s ones). With fitted start states (no velocity log), the held-out protocol's scoring window
    (``setup.window_s``): over a short window the fitted start states absorb most of any term
    (the same case without the velocity log: nothing selected over 15 s windows, ``Nabsdr`` with
    inclusion 0.86 over 60 s ones).

    A tied coefficient among the candidates (:func:`~.library.untied_candidates`) is untied at the value it
    follows, and the column of the one it followed is the reference's (both sides).

    The weighted window residuals ``r`` and their Jacobian (:class:`bayesid.estimation.windows.
    WindowObjective`, fitted start states projected out) by the reference's free parameters
    (coefficients, effect parameters, nuisances) and by each candidate's coefficient. A refit
    with candidate ``c`` moves the residuals by ``J_c dc`` plus whatever the free parameters can
    absorb: so the free directions are projected out of ``r`` and of every ``J_c`` (Frisch-Waugh-
    Lovell), and what a candidate can still explain is the regression of the projected residual
    on its projected column -- the first Gauss-Newton step of adding it (Rao's score test).

    Parameters
    ----------
    setup : Setup
        The reference model's vehicle, free coefficients, tracks and windows.
    ref : Stage
        The fitted reference model.
    effects : sequence of Effect
        Its effects.
    names : list of str
        The candidates.
    sd_fit : dict
        The channel weights of the fit.
    window_s : float, optional
        The windows, s; default as above (the whole run when the chosen window is None).

    Returns
    -------
    LinearisedProblem
        The projected residuals and candidate columns, the columns' sizes, the windows' rows,
        the residuals' RMS and each candidate's mimic: the free parameter whose column is closest
        to the candidate's and how far the fit moved it (:func:`mimics`).
    """
    if window_s is None:
        window_s = setup.fit_window_s if setup.rule == "measured" else setup.window_s
    values = reference_values(ref, names)
    model, ctxs = augmented_model(setup, effects, values, window_s)
    n_ref, K = ref.model.n_theta, len(names)
    p0 = extended_start(ref, model, list(values.values()))
    nu0 = nuisance_start(ref, model)
    obj = WindowObjective(model, ctxs, sd_fit, p0=p0, nuisance0=nu0)
    starts = warm_starts(ref.fit, ctxs)
    if starts is not None:
        obj.warm_start(starts)
    r, J = obj.jacobian(np.asarray(obj.x0, float))
    # an untied coefficient takes its side from the one it followed: the reference's column of
    # that one is the sum of both (so the free directions projected out are the reference's own)
    tied = term_library(ref.model).tied
    for n in names:
        if n in tied and tied[n] in model.param_names:
            J[:, model.param_names.index(tied[n])] += J[:, model.param_names.index(n)]
    cand = np.arange(n_ref, n_ref + K)
    other = np.setdiff1d(np.arange(J.shape[1]), cand)
    Jc = J[:, cand]
    size = np.sqrt(np.mean(Jc**2, axis=0))
    y, X = project_out(J[:, other], -r, Jc)
    # how far the fit moved each parameter from its start (the vehicle file's coefficients, the
    # effects' starts, nuisances 0): a mimic moved far may stand in for a missing term
    start = np.concatenate([model.start(), np.zeros(J.shape[1] - model.n_params)])
    shift, rms = np.asarray(obj.x0, float) - start, float(np.sqrt(np.mean(r**2)))
    blocks, o = [], 0
    for ctx, w in zip(ctxs, obj.wts):
        n_c = sum(1 for c in ctx.channels if c in w)
        rows = np.arange(n_c * ctx.ts.size).reshape(n_c, ctx.ts.size)
        for wi in np.unique(ctx.win):
            blocks.append(o + rows[:, ctx.win == wi].ravel())
        o += rows.size
    return LinearisedProblem(
        y, X, size, blocks, rms, mimics(J[:, other], [obj.names[j] for j in other], Jc, names, shift[other], rms)
    )


def project_out(S: np.ndarray | None, *arrays) -> tuple:
    """The arrays with their component in the span of the columns of ``S`` removed: what a refit
    of the free coefficients cannot absorb (Frisch-Waugh-Lovell).

    Parameters
    ----------
    S : ndarray, shape (n, P), optional
        The free parameters' columns; zero columns are ignored, the others scaled to unit RMS
        (singular values below 1e-8 of the largest dropped).
    *arrays : ndarray, shape (n,) or (n, K), or None
        The arrays to project; None stays None.

    Returns
    -------
    tuple
        The projected arrays, in order; ``arrays`` unchanged when ``S`` is None or all zero.
    """
    if S is None:
        return arrays
    sn = np.sqrt(np.mean(S**2, axis=0))
    live = sn > 0
    if not live.any():
        return arrays
    U, sv, _ = np.linalg.svd(S[:, live] / sn[live], full_matrices=False)
    Q = U[:, sv > 1e-8 * sv[0]]
    return tuple(None if a is None else a - Q @ (Q.T @ a) for a in arrays)


def mimics(S: np.ndarray, free: list, C: np.ndarray, names: list, shift=None, rms: float = 0.0) -> dict:
    """Per candidate, its *mimic*: the free parameter whose column is closest to the candidate's,
    the one a refit moves most to reproduce the term alone (a constant yaw moment ``N0`` and the
    neutral rudder angle ``dR0``, whose column is nearly the rudder's constant yaw moment).

    Parameters
    ----------
    S : ndarray, shape (n, P)
        The free parameters' columns (sensitivities of the weighted residuals).
    free : list of str
        Their names (P,).
    C : ndarray, shape (n, K)
        The candidates' columns.
    names : list of str
        The candidates (K,).
    shift : ndarray, shape (P,), optional
        How far the fit moved each free parameter from its start (the vehicle file's value).
    rms : float, default 0
        The residuals' RMS at the fit (with ``shift``).

    Returns
    -------
    dict
        ``{candidate: {"parameter": its mimic, "cosine": |cosine| of the two columns}}``, with
        ``shift`` (the mimic's) and ``shift_effect`` (``|shift|`` times the RMS of the mimic's
        column over ``rms``: how much the refit's move of the mimic changes the training
        residuals, linearised, in their RMS) when ``shift`` is given and ``rms`` > 0; a candidate
        with a zero column, or no free parameter with a non-zero one, is left out.
    """
    sn, cn = np.linalg.norm(S, axis=0), np.linalg.norm(C, axis=0)
    live = np.flatnonzero(sn > 0)
    if live.size == 0:
        return {}
    cos = np.abs(C.T @ S[:, live]) / np.maximum(cn[:, None], 1e-300) / sn[live]
    out = {}
    for k, n in enumerate(names):
        if cn[k] == 0:
            continue
        b = int(np.argmax(cos[k]))
        j = live[b]
        out[n] = {"parameter": free[j], "cosine": float(min(cos[k, b], 1.0))}
        if shift is not None and rms > 0:
            out[n]["shift"] = float(shift[j])
            out[n]["shift_effect"] = float(abs(shift[j]) * sn[j] / np.sqrt(S.shape[0]) / rms)
    return out


def _groups(Xn: np.ndarray, cos: float) -> list[list[int]]:
    """Groups of nearly collinear columns of a normalised library: column j's group is every
    column whose |cosine| with j is at least ``cos``."""
    G = np.abs(Xn.T @ Xn) / Xn.shape[0]
    return [list(np.flatnonzero(G[j] >= cos)) for j in range(Xn.shape[1])]


def select_terms(problem: LinearisedProblem, names: list, options: DiscoveryOptions, rng) -> Selection:
    """Ensemble STLSQ of the projected output residuals on the candidates' projected columns
    (:func:`linearised_problem`), with a block bootstrap over the fit windows.

    Columns left with less than 10 % of their size by the projection are set aside as
    ``mimicked`` (a refit of the free coefficients produces them); the rest are normalised to unit
    RMS and the residual to unit RMS, so a coefficient is the share of the residual's RMS the
    term carries, and ``threshold`` the least share a kept term carries.

    Parameters
    ----------
    problem : LinearisedProblem
        :func:`linearised_problem`.
    names : list of str
        The candidates.
    options : DiscoveryOptions
        ``n_models``, ``threshold``, ``ridge``, ``group_cos``.
    rng : numpy.random.Generator
        Draws the bootstrap blocks.

    Returns
    -------
    Selection
        The inclusion and group probabilities, groups, coefficients and shares of the live
        candidates; the mimicked ones with their mimics (``mimicked_by``: the free parameter whose
        column is closest to the term's, the |cosine| of the two, how far the fit moved the mimic
        from its start, that move's change of the training residuals over their RMS and the
        term's column's cosine with the span of all the free parameters', by ``shift_effect``
        times ``cosine``, largest first; empty without ``problem.mimics``); the share of the
        projected residual's variance the median model explains and the residual's RMS after the
        projection / before it.
    """
    X, y = problem.X, problem.y
    rx = np.sqrt(np.mean(X**2, axis=0))
    live = rx > 0.1 * problem.size
    mimicked = [n for n, ok, sz in zip(names, live, problem.size) if not ok and sz > 0]
    ry = float(np.sqrt(np.mean(y**2)))
    quiet = Selection(
        mimicked=mimicked,
        mimicked_by=_mimicked_by(mimicked, problem, rx, names),
        projected_rms=ry / problem.rms if problem.rms > 0 else 0.0,
    )
    idx = np.flatnonzero(live)
    if ry == 0 or idx.size == 0:
        return quiet
    Xn, yn = X[:, idx] / rx[idx], y / ry
    xi = block_ensemble_stlsq(Xn, yn, problem.blocks, rng, options.threshold, options.ridge, options.n_models)
    sel = xi != 0.0
    groups = _groups(Xn, options.group_cos)
    med = np.median(xi, axis=0)
    out = Selection(
        mimicked=quiet.mimicked,
        mimicked_by=quiet.mimicked_by,
        explained=float(1 - np.mean((yn - Xn @ med) ** 2)),
        projected_rms=quiet.projected_rms,
    )
    for a, k in enumerate(idx):
        n = names[k]
        out.inclusion[n] = float(sel[:, a].mean())
        out.group_probability[n] = float(sel[:, groups[a]].any(axis=1).mean())
        out.groups[n] = [names[idx[b]] for b in groups[a] if b != a]
        nz = xi[sel[:, a], a]
        out.coefficient[n] = float(np.median(nz) * ry / rx[k]) if nz.size else 0.0
        out.share[n] = float(np.median(np.abs(nz))) if nz.size else 0.0
    return out


def _mimicked_by(mimicked: list, problem: LinearisedProblem, rx: np.ndarray, names: list) -> dict:
    """The mimicked candidates with their mimics (``problem.mimics``) and ``span_cosine``
    (the term's column's cosine with the span of every free parameter's, from the share the
    projection leaves), most likely stand-ins first: by ``shift_effect`` times ``cosine`` (the
    refit's move of the mimic along the term's column), or by ``cosine`` without shifts."""
    by_term = problem.mimics or {}
    out = {}
    for n in sorted((n for n in mimicked if n in by_term), key=lambda n: -_stand_in(by_term[n])):
        k = names.index(n)
        left = float(rx[k] / problem.size[k])
        out[n] = {**by_term[n], "span_cosine": float(np.sqrt(max(0.0, 1.0 - left**2)))}
    return out


def _stand_in(m: dict) -> float:
    """How likely a mimicked term's mimic stands in for it: its move along the term's column."""
    return m["cosine"] * m.get("shift_effect", 1.0)


def score_test(problem: LinearisedProblem, names: list) -> dict:
    """The share of the projected output residual each candidate's projected column explains
    alone (the squared cosine of the two: Rao's score statistic over the residual's sum of
    squares, the first Gauss-Newton step of adding that term alone).

    Parameters
    ----------
    problem : dict
        :func:`linearised_problem`.
    names : list of str
        The candidates (its columns).

    Returns
    -------
    dict
        ``{term: share in [0, 1]}``.
    """
    X, y = problem.X, problem.y
    yy = float(y @ y)
    xx = np.einsum("ij,ij->j", X, X)
    xy = X.T @ y
    ok = (xx > 0) & (yy > 0)
    r2 = np.where(ok, xy**2 / np.where(ok, xx * yy, 1.0), 0.0)
    return {n: float(v) for n, v in zip(names, r2)}


def refit_candidates(sel: Selection, options: DiscoveryOptions) -> list[str]:
    """The groups refitted, most probable first (ties: the larger share of the missing force):
    each group above ``min_probability`` by the member that carries the most of the missing
    force in the ensemble (inclusion probability x share; the shorter name on ties).

    Parameters
    ----------
    sel : Selection
        :func:`select_terms`.
    options : DiscoveryOptions
        ``min_probability`` and ``max_candidates``.

    Returns
    -------
    list of str
        One term per group refitted, at most ``max_candidates``.
    """
    score = {n: sel.inclusion[n] * sel.share[n] for n in sel.inclusion}
    ranked = sorted(sel.group_probability, key=lambda n: (-sel.group_probability[n], -score[n]))
    chosen, covered = [], set()
    for n in ranked:
        if sel.group_probability[n] < options.min_probability or len(chosen) >= options.max_candidates:
            break
        if n in covered:
            continue
        group = [n, *(m for m in sel.groups[n] if m not in covered)]
        best = max(group, key=lambda m: (score.get(m, 0.0), -len(m)))
        chosen.append(best)
        covered |= {*group, *sel.groups.get(best, [])}
    return chosen


def alternative_pool(r2: dict, sel: Selection, chosen: list, options: DiscoveryOptions) -> list[str]:
    """Candidates refitted beside the selected ones (none when nothing is selected): first the
    terms the ensemble itself selects (inclusion probability >= ``min_probability``) that were
    not refitted because a collinear group member stood for them (at most ``2 n_alternatives``,
    most probable first: a hidden ``Nvvr`` with inclusion 0.99 was otherwise represented by
    ``Nabsvrabsr``); then per searched degree of freedom the ``n_alternatives`` best by the score
    test (:func:`score_test`) that explain at least half the share the best selected one does,
    whatever their group.

    Parameters
    ----------
    r2 : dict
        :func:`score_test`.
    sel : Selection
        :func:`select_terms`.
    chosen : list of str
        The selected terms (:func:`refit_candidates`).
    options : DiscoveryOptions
        ``n_alternatives``, ``min_probability`` and ``dofs``.

    Returns
    -------
    list of str
        The alternatives to refit, none of them in ``chosen``.
    """
    if not chosen or options.n_alternatives <= 0:
        return []
    mimicked = set(sel.mimicked)
    probable = sorted(
        (n for n, p in sel.inclusion.items() if p >= options.min_probability and n not in chosen),
        key=lambda n: (-sel.inclusion[n], len(n), n),
    )
    out = probable[: 2 * options.n_alternatives]
    floor = 0.5 * max(r2.get(n, 0.0) for n in chosen)
    for g in options.dofs:
        ranked = sorted(
            (n for n in r2 if n[0] == g and n not in chosen and n not in mimicked and n not in out and r2[n] >= floor),
            key=lambda n: (-r2[n], len(n), n),
        )
        out += ranked[: options.n_alternatives]
    return out


def mimicked_refits(sel: Selection, n: int) -> list[str]:
    """The candidates set aside as mimicked that are refitted all the same: one per mimic (the
    term it likeliest stands in for), likeliest first.

    The set-aside is the linearised problem's (a term's column within the span of the free
    coefficients' columns): the output-error refit with every coefficient free can still tell
    them apart, as the rudder's other forces do for the neutral rudder angle. On KVLCC2 zigzags
    with a constant yaw moment ``N0`` hidden and no velocity log, ``N0`` is set aside as mimicked
    by ``dR0`` (column cosine 0.989) and nothing is kept; refitted beside ``dR0`` it lands at
    0.00297 (truth 0.003) and passes the kept test (held-out 0.866 -> 0.043 m).

    Parameters
    ----------
    sel : Selection
        :func:`select_terms` (``mimicked_by``, likeliest stand-ins first).
    n : int
        At most this many.

    Returns
    -------
    list of str
        The terms, one per mimic, likeliest first.
    """
    out: dict = {}  # one term per mimic: the same mimic twice tests one likeness twice
    for t, m in sel.mimicked_by.items():
        out.setdefault(m["parameter"], t)
    return list(out.values())[: max(int(n), 0)]


#: A kept term's collinear companions (:func:`tied_companions`) explain at least this fraction of the
#: share of the missing force the kept term explains in the linearised score test (the floor of the
#: score test's alternatives, :func:`alternative_pool`)
TIED_SHARE = 0.5
#: At most this many tied companions per kept term
MAX_TIED = 8


def tied_companions(sel: Selection, r2: dict, term: str, n: int = MAX_TIED) -> list[str]:
    """The members of ``term``'s collinear group (regression columns with cosine at least
    ``group_cos``, :func:`select_terms`) that the linearised score test (:func:`score_test`) does not
    set aside: each explains at least :data:`TIED_SHARE` of the share ``term`` explains. A term
    of the score test's pool (:func:`alternative_pool`: the best few per degree of freedom,
    whatever their group) kept after its refit has them as its competitors, and only their refits
    can say whether the runs separate them from it; without them it could be named alone, or beside
    the wrong companions, by the noise's choice of a representative. (A term the ensemble selects
    stands for its group by the selection's own choice, :func:`refit_candidates`, and the group's
    probable members are refitted beside it; refitting the tied members of those too, the
    synthetic cases of ``studies/closing_the_loop.py`` named a wrong term alone after the loop
    once.) On synthetic KVLCC2 runs with a hidden fourth-order hull surge term
    (``studies/ship_surge.py``) the eleven even fourth-order X products lie in one group and
    their shares differ by 6-25 %, in an order that changes with the noise: a hidden ``Xvvrr`` was
    kept as itself with one noise seed and as ``Xvvvv`` with another, alone (with the other
    companions at 0.9 of the share, ``Xvvrr``, at 0.86 of ``Xvvvv``'s, was still left out).

    Parameters
    ----------
    sel : Selection
        :func:`select_terms` (``groups``).
    r2 : dict
        :func:`score_test`: ``{term: share of the missing force explained}``.
    term : str
        A kept term.
    n : int, default MAX_TIED
        At most this many.

    Returns
    -------
    list of str
        The companions, largest share first, without ``term``; empty when its score is not
        positive or it has no group.
    """
    s = float(r2.get(term, 0.0))
    if s <= 0.0:
        return []
    tied = [m for m in sel.groups.get(term, []) if r2.get(m, 0.0) >= TIED_SHARE * s]
    return sorted(tied, key=lambda m: (-r2[m], len(m), m))[: max(int(n), 0)]


def mimicked_companions(sel: Selection, term: str, n: int) -> list[str]:
    """The other candidates set aside as mimicked by the same free parameter as ``term``,
    likeliest first: a kept term of :func:`mimicked_refits` has them as its competitors (their
    columns all lie near their mimic's), and only their refits can say whether the runs
    separate them from it. Without them such a term would be named alone by construction (a
    hidden ``Nvvr`` on the submarine without a velocity log: ``Nvabsr`` refitted in its place
    and kept alone).

    Parameters
    ----------
    sel : Selection
        :func:`select_terms` (``mimicked_by``).
    term : str
        A mimicked term.
    n : int
        At most this many.

    Returns
    -------
    list of str
        The companions, without ``term``; empty when ``term`` is not mimicked.
    """
    by = sel.mimicked_by
    if term not in by:
        return []
    p = by[term]["parameter"]
    return [t for t, m in by.items() if m["parameter"] == p and t != term][: max(int(n), 0)]
