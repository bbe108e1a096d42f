"""Structure discovery: name the model terms behind an "unexplained" gap, refit with them and
check them on held-out runs.

The gap diagnosis (:mod:`bayesid.analysis.gap`) can only name effects of its catalogue. This module
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
   **block bootstrap** of the samples (blocks of :attr:`DiscoveryOptions.block_s` seconds: the
   residuals of a track are correlated in time, and resampling single samples would overstate the
   certainty) gives each term an inclusion probability (Fasel, Kutz, Brunton & Brunton 2022,
   Ensemble-SINDy, Proc. R. Soc. A 478:20210904). Candidates whose columns are nearly collinear
   (|cosine| >= :attr:`DiscoveryOptions.group_cos`) form a **group**: the group's inclusion
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
   it: :func:`dominance_order`), each further one refitted on top of those added and kept only if
   it passes the same test against them while the held-out error is still above the floor band.

:func:`discover` runs the whole search from a reference model (the diagnosis's model after its
catalogue effects, or a base fit of its own) and returns a :class:`Discovery`.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
import pysindy as ps
from scipy.ndimage import uniform_filter1d
from threadpoolctl import threadpool_limits

from ...data.track import STATE_NAMES, Track
from ...estimation.laplace import fit_covariance
from ...estimation.windows import FitProblem, WindowObjective, fit_model, pooled_noise_sd
from ...models import build_model
from ...models.library import MAX_ORDER, term_library
from ...tasks import Runner, Task, TaskError
from .candidates import Setup, Stage, score_stage
from .verdict import Thresholds, is_contributor, paired_window_test, run_separation_test

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
    "window_runs",
    "dominance_order",
    "fit_term",
    "with_terms",
    "discover",
]

_DOFS = ("X", "Y", "N")


@dataclass(frozen=True)
class DiscoveryOptions:
    """What structure discovery searches and how it decides (:func:`discover`).

    Parameters
    ----------
    max_order : int, default 3
        Highest number of factors of a candidate term (ship; a submarine term has at most two
        velocity factors by its prime form).
    dofs : tuple of str, default ("Y", "N")
        The degrees of freedom searched (``"X"``, ``"Y"``, ``"N"``).
    n_models : int, default 100
        Bootstrap models of the ensemble.
    threshold : float, default 0.1
        STLSQ threshold on the normalised coefficients: a term must carry this share of the
        projected output residual's RMS to stay in a model.
    block_s : float, default 10.0
        Block length of the block bootstrap, s.
    min_probability : float, default 0.5
        Group inclusion probability from which a group is refitted (confirmation).
    max_candidates : int, default 6
        At most this many groups are refitted (the most probable).
    group_cos : float, default 0.95
        |cosine| of two candidates' force columns from which they form a collinear group.
    trim_s : float, default 2.0
        Seconds dropped at either end of each track (smoothing edges).
    lowpass_s : float, default 2.0
        Moving-average window applied alike to the missing forces and the columns, s.
    ridge : float, default 0.01
        Ridge weight per sample of the normalised regression (collinear columns).

    max_nfev : int, default 60
        Least-squares iterations of each confirmation fit.
    n_alternatives : int, default 0
        Further candidates refitted beside the selected ones: up to twice this many terms the
        ensemble selects (inclusion >= ``min_probability``) that a collinear group member stood
        for, and per searched degree of freedom this many best by the score test of the
        linearised problem (the share of the projected residual one column explains alone),
        whatever their group and inclusion probability: the structures the runs may not
        separate from the selected term (:func:`alternatives`). 0 (the default until the test
        suite's budget is re-measured with it): none; 2 is the setting measured.

    Raises
    ------
    ValueError
        An option out of range (named).
    """

    max_order: int = 3
    dofs: tuple = ("Y", "N")
    n_models: int = 100
    threshold: float = 0.1
    block_s: float = 10.0
    min_probability: float = 0.5
    max_candidates: int = 6
    group_cos: float = 0.95
    trim_s: float = 2.0
    lowpass_s: float = 2.0
    ridge: float = 0.01
    max_nfev: int = 60
    n_alternatives: int = 0

    def __post_init__(self):
        if not 1 <= int(self.max_order) <= MAX_ORDER:
            raise ValueError(f"max_order must be 1..{MAX_ORDER}, got {self.max_order}")
        bad = [d for d in self.dofs if d not in _DOFS]
        if bad or not self.dofs:
            raise ValueError(f"dofs must be a non-empty subset of {_DOFS}, got {self.dofs}")
        if int(self.n_models) < 2:
            raise ValueError(f"n_models must be >= 2, got {self.n_models}")
        if not 0 < self.min_probability <= 1:
            raise ValueError(f"min_probability must be in (0, 1], got {self.min_probability}")
        if not 0 < self.group_cos <= 1:
            raise ValueError(f"group_cos must be in (0, 1], got {self.group_cos}")
        if int(self.n_alternatives) < 0:
            raise ValueError(f"n_alternatives must be >= 0, got {self.n_alternatives}")
        if not self.threshold >= 0 or not self.block_s > 0 or not self.trim_s >= 0:
            raise ValueError("threshold and trim_s must be >= 0 and block_s > 0")
        object.__setattr__(self, "dofs", tuple(self.dofs))


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
        the floor band with them) or ``"no term of the library explains it"`` (naming the
        likeliest term hidden in a free coefficient, when one is: ``, unless N0 is hidden in dR0
        (refit with dR0 held to test it)``).
    discovered : list of dict
        Every refitted candidate: ``term``, ``dof``, ``inclusion_probability`` (the term's),
        ``group_inclusion_probability``, ``group`` (its collinear alternatives),
        ``regression_coefficient``, ``coefficient`` and ``coefficient_sd`` (prime: the
        regression's, the refit's and its Laplace sd),
        ``heldout_rms_before_m``, ``heldout_rms_after_m`` (and per window,
        ``heldout_windows_after_m``), ``train_rms_before_m``,
        ``train_rms_after_m``, ``shrinkage``, ``delta_bic``, ``window_p_value``,
        ``excess_removed``, ``worst_run`` (the held-out run the refit predicts worst against
        the reference: ``run``, ``error_ratio``, ``p_value``), ``kept`` and ``reason``.
    inclusion : dict
        ``{term: inclusion probability}`` of every candidate with a non-zero one, best first.
    residuals : dict
        ``forces``: per degree of freedom the missing force's RMS (N or N m), the null's and the
        best candidates (:func:`force_summary`); ``explained``: the share of the projected
        output residual's variance the ensemble's median model explains; ``projected_rms``: the
        share of the training residual's RMS no refit of the free parameters can remove;
        ``mimicked``: candidates the free parameters reproduce; ``mimicked_by``: each of them with
        the free parameter whose column is closest to its own (:func:`select_terms`).
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
        every competing refitted term the held-out runs cannot separate from the kept term
        (:func:`compare_structures`); empty lists where the runs separate the kept term from
        every other.
    separated : dict
        ``{kept term: [...]}``, the same entries for the competing terms the runs separate, with
        the run that separates each (``separating_run``, ``run_error_ratio``).
    after : Stage, optional
        The model with every kept term (None when nothing is kept); not in :meth:`to_dict`.
    reference : Stage, optional
        The model the terms were added to; not in :meth:`to_dict`.
    stages : dict, optional
        ``{term: Stage}`` of every refitted term's single-term model (the kept terms' and their
        alternatives' among them); not in :meth:`to_dict`.
    """

    found: list
    verdict: str
    discovered: list
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
    after: Stage | None = field(repr=False, default=None)
    reference: Stage | None = field(repr=False, default=None)
    stages: dict = field(repr=False, default_factory=dict)

    def to_dict(self) -> dict:
        """The JSON-able fields.

        Returns
        -------
        dict
            ``{field: value}`` without ``after``, ``reference`` and ``stages``.
        """
        return {k: v for k, v in self.__dict__.items() if k not in ("after", "reference", "stages")}

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
            ``refitted_as`` (``"selected"`` by the ensemble or ``"alternative"`` by the score
            test), ``alternatives`` (kept terms: :attr:`alternatives`; others: empty),
            ``separated`` (kept terms: :attr:`separated`; others: empty), ``separable`` (kept terms: no alternative survives; others: None) and
            ``heldout_rms_by_run_m`` (kept terms: ``{held-out run: position RMS, m}`` of the
            single-term refit; others: empty).
        """
        out = []
        for row in self.discovered:
            t = row["term"]
            kept = t in self.found
            if kept:
                reason = "in the final model"
            elif row.get("kept"):
                reason = "passed the kept test alone but not on top of " + "+".join(self.found)
            else:
                reason = row.get("reason", "")
            alts = list(self.alternatives.get(t, [])) if kept else []
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
                    "heldout_rms_by_run_m": _by_run(self.stages[t]) if kept and t in self.stages else {},
                }
            )
        return out


# -- 2. candidate terms ---------------------------------------------------------------------------


def candidate_terms(model, max_order: int = MAX_ORDER, dofs=("Y", "N")) -> list[str]:
    """The candidate terms a model lacks, named as its vehicle file writes them: its family's
    term library (:func:`bayesid.models.library.term_library`).

    Parameters
    ----------
    model : SimulationModel
        The reference model; its vehicle's coefficients (listed, non-zero or free) are not
        candidates.
    max_order : int, default 3
        Highest number of motion factors.
    dofs : sequence of str, default ("Y", "N")
        The force letters searched.

    Returns
    -------
    list of str
        The names, grouped by force letter; the family's tied coefficients last
        (:func:`untied_candidates`).

    Raises
    ------
    NoTermLibraryError
        When the model's family offers no term library.
    """
    return term_library(model).candidates(model, max_order, dofs)


def untied_candidates(model, dofs=("Y", "N")) -> list[str]:
    """The family's physical candidates the model has a parameter for: its tied coefficients that
    are not free (:meth:`bayesid.models.library.TermLibrary.untied`; a ship's ``gRm``, gamma_R
    for beta_R < 0, following ``gR``; none for a submarine).

    Parameters
    ----------
    model : SimulationModel
        The reference model.
    dofs : sequence of str, default ("Y", "N")
        The force letters searched.

    Returns
    -------
    list of str
        The tied coefficients to untie.

    Raises
    ------
    NoTermLibraryError
        When the model's family offers no term library.
    """
    return term_library(model).untied(model, dofs)


def reference_values(ref: Stage, names: list) -> dict:
    """Each candidate's value in the reference model: 0 for a term it lacks; for a tied
    coefficient the value of the one it follows (the reference fit's, when that one is free).

    Parameters
    ----------
    ref : Stage
        The fitted reference model.
    names : list of str
        The candidates.

    Returns
    -------
    dict
        ``{name: prime value}``.
    """
    veh = ref.model.vehicle
    tied = term_library(ref.model).tied
    fitted = ref.fit.coefficients()
    return {n: float(fitted.get(tied[n], veh.coefficients.get(tied[n], 0.0))) if n in tied else 0.0 for n in names}


# -- 1. force residuals ----------------------------------------------------------------------------


def twin_track(model, fit, track: Track, noise_sd: dict | None = None, rng=None) -> Track | None:
    """The fitted model's own run through a track's inputs: one window from the track's start
    state, the channels the track logs (states from the simulation, every other column as
    logged), optionally with white noise of the data's sd on the state channels.

    Parameters
    ----------
    model : SimulationModel
        The model.
    fit : FitResult
        Its fit.
    track : Track
        The logged track.
    noise_sd : dict, optional
        ``{channel: sd}`` (SI) of the noise added to the simulated channels; None: none.
    rng : numpy.random.Generator, optional
        Draws the noise.

    Returns
    -------
    Track or None
        The twin; None when the simulation diverges.
    """
    try:
        ctx = model.context(track, None)
        S = model.simulate(ctx, fit.p[None])[0]
    except Exception:  # noqa: BLE001 - no twin
        return None
    if not np.isfinite(S).all():
        return None
    data = {}
    for k in track.data:
        if k in STATE_NAMES:
            data[k] = S[:, STATE_NAMES.index(k)].copy()
            sd = (noise_sd or {}).get(k, 0.0)
            if sd > 0:
                data[k] += rng.normal(0.0, sd, data[k].size)
        else:
            data[k] = np.interp(ctx.ts, track.t, np.asarray(track[k], float))
    return Track(ctx.ts, data, name=f"{track.name} (model twin)")


def _forces_at(model, fit, track, t) -> np.ndarray | None:
    """The missing forces of a track interpolated at times ``t`` (None if inverse dynamics fails)."""
    try:
        m, F, _ = model.missing_forces(fit, track)
    except Exception:  # noqa: BLE001
        return None
    return np.column_stack([np.interp(t, m["t"], F[:, j], left=np.nan, right=np.nan) for j in range(3)])


def force_residuals(model, fit, tracks: list, names: list, options=None, rng=None) -> list[dict]:
    """The missing forces of each track, their null (what noise alone gives) and the candidates'
    columns at the same samples.

    The null is measured on the fitted model's own run through the track's inputs
    (:func:`twin_track`): the missing force of the twin with noise of the data's sd minus that of
    the noiseless twin is the noise as the processing (smoothing, differentiation) passes it. The
    noiseless twin's own missing force (the processing's bias on an exact model) is subtracted
    from the track's.

    Parameters
    ----------
    model : SimulationModel
        The reference model.
    fit : FitResult
        Its fit.
    tracks : list of Track
        The (training) tracks.
    names : list of str
        The candidate terms (:func:`candidate_terms`).
    options : DiscoveryOptions, optional
        ``trim_s`` (default :class:`DiscoveryOptions`).
    rng : numpy.random.Generator, optional
        The null's noise (default seed 0).

    Returns
    -------
    list of dict
        Per track: ``t`` (n,), ``F`` (n, 3) missing X, Y (N) and N (N m), ``null`` (n, 3) or
        None, and ``columns`` (n, K). Tracks whose inverse dynamics fail are left out.

    Raises
    ------
    ValueError
        When no track gives missing forces.
    """
    opt = options or DiscoveryOptions()
    rng = np.random.default_rng(0) if rng is None else rng
    sd = pooled_noise_sd(tracks, floor=False)
    out = []
    for tr in tracks:
        try:
            motion, F, inputs = model.missing_forces(fit, tr)
        except Exception:  # noqa: BLE001 - a track without usable motion adds no rows
            continue
        t = np.asarray(motion["t"], float)
        null = None
        twin = twin_track(model, fit, tr)
        F0 = None if twin is None else _forces_at(model, fit, twin, t)
        if F0 is not None:
            F = F - F0
            Fn = _forces_at(model, fit, twin_track(model, fit, tr, sd, rng), t)
            null = None if Fn is None else Fn - F0
        C = term_library(model).columns(names, motion, inputs)
        keep = (t >= t[0] + opt.trim_s) & (t <= t[-1] - opt.trim_s) & np.isfinite(F).all(1) & np.isfinite(C).all(1)
        if null is not None:
            keep &= np.isfinite(null).all(1)
        if keep.sum() > 10:
            out.append(
                {
                    "t": t[keep],
                    "F": F[keep],
                    "null": None if null is None else null[keep],
                    "columns": C[keep],
                }
            )
    if not out:
        raise ValueError("no training track gives missing forces (inverse dynamics failed on every track)")
    return out


# -- 3. sparse selection ---------------------------------------------------------------------------


def _blocks(rows: list, block_s: float) -> list[np.ndarray]:
    """Row indices of consecutive blocks of ``block_s`` seconds within each track."""
    blocks, o = [], 0
    for r in rows:
        t = r["t"]
        k = np.floor((t - t[0]) / block_s).astype(int)
        for b in np.unique(k):
            blocks.append(o + np.flatnonzero(k == b))
        o += t.size
    return blocks


def _lowpass(rows: list, seconds: float) -> list[dict]:
    """Every array of the rows through the same moving average (both sides of the regression
    keep one bandwidth)."""
    if seconds <= 0:
        return rows
    out = []
    for r in rows:
        k = max(1, int(round(seconds / float(np.median(np.diff(r["t"]))))))
        out.append(
            {
                key: (uniform_filter1d(v, k, axis=0, mode="nearest") if key != "t" and v is not None else v)
                for key, v in r.items()
            }
        )
    return out


def _project(S: np.ndarray | None, *arrays):
    """The arrays with their component in the span of the columns of ``S`` removed: what a refit
    of the free coefficients cannot absorb."""
    if S is None:
        return arrays
    sn = np.sqrt(np.mean(S**2, axis=0))
    live = sn > 0
    if not live.any():
        return arrays
    U, sv, _ = np.linalg.svd(S[:, live] / sn[live], full_matrices=False)
    Q = U[:, sv > 1e-8 * sv[0]]
    return tuple(None if a is None else a - Q @ (Q.T @ a) for a in arrays)


def _mimics(S: np.ndarray, free: list, C: np.ndarray, names: list, shift=None, rms: float = 0.0) -> dict:
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


def _ensemble(Xn, yn, blocks, threshold, options, rng) -> np.ndarray:
    """Block-bootstrap ensemble of ridge STLSQ fits (pysindy): (n_models, K) coefficients.

    STLSQ's ridge problem depends on the rows only through ``X'X`` and ``X'y``: each block's are
    summed once, a bootstrap replicate sums its blocks', and pysindy fits the K x K problem
    ``(R, R^-T X'y)`` with ``R'R = X'X`` (the same minimiser; tens of thousands of rows cost
    nothing more than one pass)."""
    G = np.stack([Xn[b].T @ Xn[b] for b in blocks])
    g = np.stack([Xn[b].T @ yn[b] for b in blocks])
    n = np.array([b.size for b in blocks], float)
    K = Xn.shape[1]
    stl = ps.STLSQ(threshold=threshold, alpha=0.0, normalize_columns=False, unbias=False, max_iter=20)
    xi = np.empty((options.n_models, K))
    with threadpool_limits(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "eliminated all coefficients"
        for m in range(options.n_models):
            pick = rng.integers(0, len(blocks), len(blocks))
            Gm, gm = G[pick].sum(axis=0), g[pick].sum(axis=0)
            R = np.linalg.cholesky(Gm + 1e-10 * np.trace(Gm) / K * np.eye(K)).T
            stl.alpha = options.ridge * n[pick].sum()
            stl.fit(R, np.linalg.solve(R.T, gm))
            xi[m] = stl.coef_[0]
    return xi


def _augmented(setup: Setup, effects, values: dict, window_s: float | None):
    """The reference model with every candidate added at its reference value (0 for a term) and
    free, on the interpreted kernel (one model for any number of terms, nothing to compile), and
    its training contexts over ``window_s`` windows."""
    veh = setup.vehicle.with_coefficients(values)
    m = build_model(veh, [*setup.free, *values], list(effects), dt=setup.dt, mode=setup.mode, kernel="interpreted")
    return m, [m.context(t, window_s, start=setup.rule) for t in setup.train]


def linearised_problem(setup: Setup, ref: Stage, effects, names: list, sd_fit: dict, window_s=None) -> dict:
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

    A tied coefficient among the candidates (:func:`untied_candidates`) is untied at the value it
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
    dict
        ``y`` (n,): minus the projected residuals; ``X`` (n, K): the projected candidate columns;
        ``size`` (K,): the columns' RMS before the projection; ``blocks``: row indices of each
        window (the block bootstrap's blocks); ``rms``: the residuals' RMS before the
        projection; ``mimics``: ``{candidate: {"parameter", "cosine", "shift",
        "shift_effect"}}``, the free parameter whose column is closest to the candidate's and how
        far the fit moved it (:func:`_mimics`).
    """
    if window_s is None:
        window_s = setup.fit_window_s if setup.rule == "measured" else setup.window_s
    values = reference_values(ref, names)
    model, ctxs = _augmented(setup, effects, values, window_s)
    n_ref, K = ref.model.n_theta, len(names)
    p0 = _extended_start(ref, model, list(values.values()))
    nu0 = _nuisance_start(ref, model)
    obj = WindowObjective(model, ctxs, sd_fit, p0=p0, nuisance0=nu0)
    starts = _warm_starts(ref.fit, ctxs)
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
    y, X = _project(J[:, other], -r, Jc)
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
    return {
        "y": y,
        "X": X,
        "size": size,
        "blocks": blocks,
        "rms": rms,
        "mimics": _mimics(J[:, other], [obj.names[j] for j in other], Jc, names, shift[other], rms),
    }


def select_terms(problem: dict, names: list, options: DiscoveryOptions, rng) -> dict:
    """Ensemble STLSQ of the projected output residuals on the candidates' projected columns
    (:func:`linearised_problem`), with a block bootstrap over the fit windows.

    Columns left with less than 10 % of their size by the projection are set aside as
    ``mimicked`` (a refit of the free coefficients produces them); the rest are normalised to unit
    RMS and the residual to unit RMS, so a coefficient is the share of the residual's RMS the
    term carries, and ``threshold`` the least share a kept term carries.

    Parameters
    ----------
    problem : dict
        :func:`linearised_problem`.
    names : list of str
        The candidates.
    options : DiscoveryOptions
        ``n_models``, ``threshold``, ``ridge``, ``group_cos``.
    rng : numpy.random.Generator
        Draws the bootstrap blocks.

    Returns
    -------
    dict
        ``inclusion`` ``{term: probability}``, ``group_probability`` ``{term: probability}``,
        ``groups`` ``{term: [collinear terms]}``, ``coefficient`` ``{term: median prime
        coefficient over the models that select it}``, ``share`` ``{term: median share of the
        residual RMS}``, ``mimicked`` (names), ``mimicked_by`` (``{mimicked term: {"parameter":
        its mimic, the free parameter whose column is closest to the term's, "cosine": |cosine|
        of the two, "shift": how far the fit moved the mimic from its start, "shift_effect": that
        move's change of the training residuals over their RMS, "span_cosine": the term's
        column's cosine with the span of all the free parameters'}}``, by ``shift_effect`` times
        ``cosine``, largest first; empty without ``problem["mimics"]``), ``explained`` (share of
        the projected residual's variance the median model explains) and ``projected_rms`` (the
        residual's RMS after the projection / before it).
    """
    X, y = problem["X"], problem["y"]
    rx = np.sqrt(np.mean(X**2, axis=0))
    live = rx > 0.1 * problem["size"]
    out = {"inclusion": {}, "group_probability": {}, "groups": {}, "coefficient": {}, "share": {}}
    out["mimicked"] = [n for n, ok, sz in zip(names, live, problem["size"]) if not ok and sz > 0]
    out["mimicked_by"] = _mimicked_by(out["mimicked"], problem, rx, names)
    ry = float(np.sqrt(np.mean(y**2)))
    out["projected_rms"] = ry / problem["rms"] if problem["rms"] > 0 else 0.0
    out["explained"] = 0.0
    idx = np.flatnonzero(live)
    if ry == 0 or idx.size == 0:
        return out
    Xn, yn = X[:, idx] / rx[idx], y / ry
    xi = _ensemble(Xn, yn, problem["blocks"], options.threshold, options, rng)
    sel = xi != 0.0
    groups = _groups(Xn, options.group_cos)
    med = np.median(xi, axis=0)
    out["explained"] = float(1 - np.mean((yn - Xn @ med) ** 2))
    for a, k in enumerate(idx):
        n = names[k]
        out["inclusion"][n] = float(sel[:, a].mean())
        out["group_probability"][n] = float(sel[:, groups[a]].any(axis=1).mean())
        out["groups"][n] = [names[idx[b]] for b in groups[a] if b != a]
        nz = xi[sel[:, a], a]
        out["coefficient"][n] = float(np.median(nz) * ry / rx[k]) if nz.size else 0.0
        out["share"][n] = float(np.median(np.abs(nz))) if nz.size else 0.0
    return out


def _mimicked_by(mimicked: list, problem: dict, rx: np.ndarray, names: list) -> dict:
    """The mimicked candidates with their mimics (``problem["mimics"]``) and ``span_cosine``
    (the term's column's cosine with the span of every free parameter's, from the share the
    projection leaves), most likely stand-ins first: by ``shift_effect`` times ``cosine`` (the
    refit's move of the mimic along the term's column), or by ``cosine`` without shifts."""
    mimics = problem.get("mimics") or {}
    out = {}
    for n in sorted((n for n in mimicked if n in mimics), key=lambda n: -_stand_in(mimics[n])):
        k = names.index(n)
        left = float(rx[k] / problem["size"][k])
        out[n] = {**mimics[n], "span_cosine": float(np.sqrt(max(0.0, 1.0 - left**2)))}
    return out


def _stand_in(m: dict) -> float:
    """How likely a mimicked term's mimic stands in for it: its move along the term's column."""
    return m["cosine"] * m.get("shift_effect", 1.0)


def force_summary(rows: list, sel: dict, names: list, options: DiscoveryOptions) -> dict:
    """The missing force per degree of freedom against the best candidates (for the report).

    Parameters
    ----------
    rows : list of dict
        :func:`force_residuals`.
    sel : dict
        :func:`select_terms`.
    names : list of str
        The candidates (columns of the rows).
    options : DiscoveryOptions
        ``dofs``, ``lowpass_s``.

    Returns
    -------
    dict
        Per degree of freedom: ``rms`` of the missing force (N or N m, low-passed),
        ``noise_rms`` (the null's, or None), and ``top``: the five most probable candidates of
        that degree of freedom with their inclusion probability and the share of the missing
        force's variance their column explains alone (``force_r2``).
    """
    rows = _lowpass(rows, options.lowpass_s)
    F = np.concatenate([r["F"] for r in rows])
    C = np.concatenate([r["columns"] for r in rows])
    nulls = [r["null"] for r in rows]
    null = np.concatenate(nulls) if all(n is not None for n in nulls) else None
    out = {}
    for g in options.dofs:
        j = _DOFS.index(g)
        y = F[:, j]
        top = sorted((n for n in names if n[0] == g), key=lambda n: -sel["inclusion"].get(n, 0.0))[:5]
        rows_top = []
        for n in top:
            c = C[:, names.index(n)]
            cc = float(c @ c)
            r2 = float((c @ y) ** 2 / (cc * (y @ y))) if cc > 0 and y @ y > 0 else 0.0
            rows_top.append({"term": n, "inclusion_probability": sel["inclusion"].get(n, 0.0), "force_r2": r2})
        out[g] = {
            "rms": float(np.sqrt(np.mean(y**2))),
            "noise_rms": None if null is None else float(np.sqrt(np.mean(null[:, j] ** 2))),
            "top": rows_top,
        }
    return out


# -- 4. confirmation ------------------------------------------------------------------------------


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
        The term's value in the reference model (:func:`reference_values`: 0 for a missing term,
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


def with_terms(setup: Setup, values: dict) -> Setup:
    """A setup with terms added to its vehicle and to its free coefficients.

    Parameters
    ----------
    setup : Setup
        The setup (:class:`bayesid.analysis.gap.candidates.Setup`).
    values : dict
        ``{term: value}``, prime (names as a vehicle file writes them); terms already free keep
        their place in the free list.

    Returns
    -------
    Setup
        A copy whose vehicle has the terms at ``values`` and whose free list ends with the new
        ones, in ``values``' order.
    """
    return replace(
        setup,
        vehicle=setup.vehicle.with_coefficients(values),
        free=list(setup.free) + [k for k in values if k not in setup.free],
    )


def _extended_start(ref: Stage, model, values: list) -> np.ndarray:
    """The reference fit's parameters in ``model``'s order, matched by name (so the effects may
    come in another order than the reference model's), with the coefficients the reference
    lacks (the new terms, in ``model``'s order) at ``values``."""
    known = dict(zip(ref.model.param_names, ref.fit.p))
    new = iter(np.asarray(values, float))
    return np.array([known[n] if n in known else next(new) for n in model.param_names], float)


def _warm_starts(fit, ctxs) -> list | None:
    """A fit's window start offsets when they fit ``ctxs``'s windows (same tracks, same windows),
    else None: a model evaluated at another fit's parameters with cold start states can land in
    another optimum of the start-state problem (a base fit bent to follow its tracks: cost 8.6e7
    cold against 1.9e4 at the fit's own starts, sim_to_real's constant-yaw-moment case)."""
    starts = getattr(fit, "window_starts", None)
    if starts is None or len(starts) != len(ctxs):
        return None
    for s, c in zip(starts, ctxs):
        if (s is None) != (c.start != "fitted") or (s is not None and np.shape(s) != (c.W, 6)):
            return None
    return starts


def _nuisance_start(ref: Stage, model):
    """The reference fit's per-track nuisances rearranged to ``model``'s effect order (matched by
    effect name), or None when ``model`` has none."""
    if not model.n_nuisance:
        return None
    out = []
    for nu in ref.fit.nuisance:
        parts, off = {}, 0
        for e in ref.model.effects:
            parts[e.name] = np.asarray(nu[off : off + e.n_nuisance], float)
            off += e.n_nuisance
        out.append(np.concatenate([parts[e.name] for e in model.effects if e.n_nuisance]))
    return out


def fit_term(task: TermFit) -> tuple[Stage | None, list]:
    """Add a term to the reference model and re-identify every free coefficient; score the fit.

    The fit starts at the reference plus the term's regression value (the linearised problem's
    step, :func:`select_terms`). Only when that fit fails or ends above the reference's cost does
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
    problem = FitProblem(model, ct, task.sd_fit, max_nfev=task.max_nfev)
    nu0 = _nuisance_start(task.ref, model)
    best, messages = None, []
    for c in dict.fromkeys((task.initial + float(task.start), task.initial)):
        if best is not None and best.cost <= task.ref.fit.cost * (1.0 + 1e-6):
            break  # the step's fit is at least as good as the reference: no second start
        try:
            f = fit_model(problem, _extended_start(task.ref, model, [c]), nu0, starts0=_warm_starts(task.ref.fit, ct))
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


def _row(
    term: str,
    st: Stage | None,
    ref: Stage,
    sel: dict | None,
    floor_rms: float,
    sd: float | None = None,
    runs: tuple | None = None,
    margin: float = 0.1,
) -> dict:
    """The ``discovered`` record of a refitted candidate (``sel``: the selection's numbers, None
    for a term refitted on top of others; ``sd``: its coefficient's Laplace sd; ``runs``:
    ``(run of each held-out window, run names)`` of :func:`window_runs`, for the run test of
    :func:`_worst_run` at the relative ``margin``)."""
    sel = sel or {"inclusion": {}, "group_probability": {}, "groups": {}, "coefficient": {}}
    row = {
        "term": term,
        "dof": term_library(ref.model).dof(term),
        "inclusion_probability": sel["inclusion"].get(term, 0.0),
        "group_inclusion_probability": sel["group_probability"].get(term, 0.0),
        "group": sel["groups"].get(term, []),
        "regression_coefficient": sel["coefficient"].get(term, 0.0),
        "heldout_rms_before_m": ref.held["rms_position_m"],
        "train_rms_before_m": ref.train["rms_position_m"],
    }
    if st is None:
        return {**row, "kept": False, "reason": "every fit failed"}
    before, after = ref.held["rms_position_m"], st.held["rms_position_m"]
    excess = before - floor_rms
    return {
        **row,
        "coefficient": st.fit.coefficients()[term],
        "coefficient_sd": sd,
        "heldout_rms_after_m": after,
        "train_rms_after_m": st.train["rms_position_m"],
        "shrinkage": 1 - after / before,
        "heldout_shrinkage": 1 - after / before,
        "delta_bic": st.fit.bic - ref.fit.bic,
        # the refit starts at the reference (the term at 0): ending above it is a failed fit
        "refit_failed": bool(st.fit.cost > ref.fit.cost * (1.0 + 1e-6)),
        "window_p_value": paired_window_test(ref.windows, st.windows),
        "heldout_windows_after_m": [float(x) for x in st.windows],
        "excess_removed": (before - after) / excess if excess > 0 else 0.0,
        "worst_run": _worst_run(ref, st, runs, margin),
    }


def _worst_run(ref: Stage, st: Stage, runs: tuple | None, margin: float) -> dict | None:
    """The held-out run on which a refit predicts worst against its reference model: ``{"run",
    "error_ratio", "p_value"}`` of the run test (:func:`run_separation_test` with the reference
    first: the refit's window errors above the reference's by more than ``margin`` on one run,
    Bonferroni over the runs), None without the runs' layout. A term that passes the pooled
    window test while one run's windows are significantly worse does not carry to that run."""
    if runs is None:
        return None
    idx, names = runs
    a, b = np.asarray(ref.windows, float), np.asarray(st.windows, float)
    if not (a.shape == b.shape == np.shape(idx)):
        return None
    res = run_separation_test(a, b, np.asarray(idx), margin)
    i = res["run_second_worse"]
    if i is None:
        return None
    return {"run": _run_name(names, i), "error_ratio": res["ratio_by_run"].get(i), "p_value": res["p_second_worse"]}


def _passes(row: dict, significant: bool, th: Thresholds) -> bool:
    """The kept test: the contributor test (:func:`is_contributor`) and no held-out run
    predicted significantly worse than by the reference model (:func:`_worst_run` at
    ``th.partial_p``)."""
    worst = row.get("worst_run") or {}
    harms = worst.get("p_value") is not None and worst["p_value"] < th.partial_p
    return is_contributor(row, significant, th) and not harms


def _decide(row: dict, significant: bool, th: Thresholds) -> None:
    """Set ``kept`` and ``reason`` of a refitted candidate by the contributor test."""
    if "kept" in row:
        return
    row["kept"] = _passes(row, significant, th)
    worst = row.get("worst_run") or {}
    if row["kept"]:
        row["reason"] = "improves the held-out windows (contributor test)"
    elif is_contributor(row, significant, th):
        row["reason"] = (
            f"improves the held-out windows overall but predicts run {worst['run']} worse than the model "
            f"without it (window errors x{worst['error_ratio']:.2f}, run test p = {worst['p_value']:.2g}): "
            "it does not carry to that run"
        )
    elif not significant:
        row["reason"] = "the gap is not significant: nothing to explain"
    elif row.get("refit_failed"):
        row["reason"] = (
            "the refit ended above its reference on the training runs: a failed fit, not evidence against "
            "the term (with fitted window starts, see the base-fit check)"
        )
    elif row["delta_bic"] > th.bic_threshold:
        row["reason"] = f"training ΔBIC {row['delta_bic']:.1f} > {th.bic_threshold:g}"
    elif row["heldout_shrinkage"] <= 0:
        row["reason"] = "fits the training runs but not the held-out ones"
    else:
        row["reason"] = f"held-out gain not significant (window test p = {row['window_p_value']:.3g})"


def _candidates(sel: dict, options: DiscoveryOptions) -> list[str]:
    """The groups refitted, most probable first (ties: the larger share of the missing force):
    each group above ``min_probability`` by the member that carries the most of the missing
    force in the ensemble (inclusion probability x share; the shorter name on ties)."""
    score = {n: sel["inclusion"][n] * sel["share"][n] for n in sel["inclusion"]}
    ranked = sorted(sel["group_probability"], key=lambda n: (-sel["group_probability"][n], -score[n]))
    chosen, covered = [], set()
    for n in ranked:
        if sel["group_probability"][n] < options.min_probability or len(chosen) >= options.max_candidates:
            break
        if n in covered:
            continue
        group = [n, *(m for m in sel["groups"][n] if m not in covered)]
        best = max(group, key=lambda m: (score.get(m, 0.0), -len(m)))
        chosen.append(best)
        covered |= {*group, *sel["groups"].get(best, [])}
    return chosen


def score_test(problem: dict, names: list) -> dict:
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
    X, y = problem["X"], problem["y"]
    yy = float(y @ y)
    xx = np.einsum("ij,ij->j", X, X)
    xy = X.T @ y
    ok = (xx > 0) & (yy > 0)
    r2 = np.where(ok, xy**2 / np.where(ok, xx * yy, 1.0), 0.0)
    return {n: float(v) for n, v in zip(names, r2)}


def _alternative_pool(r2: dict, sel: dict, chosen: list, options: DiscoveryOptions) -> list[str]:
    """Candidates refitted beside the selected ones (none when nothing is selected): first the
    terms the ensemble itself selects (inclusion probability >= ``min_probability``) that were
    not refitted because a collinear group member stood for them (at most ``2 n_alternatives``,
    most probable first: a hidden ``Nvvr`` with inclusion 0.99 was otherwise represented by
    ``Nabsvrabsr``); then per searched degree of freedom the ``n_alternatives`` best by the score
    test (:func:`score_test`) that explain at least half the share the best selected one does,
    whatever their group."""
    if not chosen or options.n_alternatives <= 0:
        return []
    mimicked = set(sel["mimicked"])
    probable = sorted(
        (n for n, p in sel["inclusion"].items() if p >= options.min_probability and n not in chosen),
        key=lambda n: (-sel["inclusion"][n], len(n), n),
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


def compare_structures(found: list, rows: list, stages: dict, th: Thresholds, runs=None, run_names=None) -> dict:
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
      other run, which the pooled rank test cannot see.

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
        ``{held-out run: position RMS, m}``.
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
            run = {
                "p_second_worse": None,
                "p_first_worse": 1.0,
                "run_second_worse": None,
                "run_first_worse": None,
                "ratio_by_run": {},
            }
            if runs is not None and len(runs) == len(kw) == len(aw):
                run = run_separation_test(kw, aw, np.asarray(runs), th.separation_margin)
            i = run["run_second_worse"]
            by_run = run["ratio_by_run"]
            separated = p < th.partial_p or (
                run["p_second_worse"] is not None
                and run["p_second_worse"] < th.partial_p
                and run["p_first_worse"] >= th.partial_p
            )
            out[k].append(
                {
                    "term": a,
                    "passed_kept_test": bool(r.get("kept")),
                    "coefficient": r.get("coefficient"),
                    "heldout_rms_m": r["heldout_rms_after_m"],
                    "window_p_value": p,
                    "run_p_value": run["p_second_worse"],
                    "separating_run": None if i is None else _run_name(run_names, i),
                    "run_error_ratio": by_run.get(i) if i is not None else None,
                    "kept_worse_run": None
                    if run["run_first_worse"] is None or run["p_first_worse"] >= th.partial_p
                    else _run_name(run_names, run["run_first_worse"]),
                    "kept_worse_run_p_value": run["p_first_worse"] if runs is not None else None,
                    "separable": bool(separated),
                    "heldout_rms_by_run_m": _by_run(stages[a]),
                }
            )
        out[k].sort(key=lambda d: d["heldout_rms_m"])
    return out


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


def _by_run(stage) -> dict:
    """``{held-out run: position RMS, m}`` of a refit."""
    return dict((getattr(stage, "held", None) or {}).get("per_track_rms_position_m", {}))


def _named_alternatives(found: list, alts: dict) -> list[str]:
    """The kept terms as the verdict names them: ``Yvvdr (not separable from Nvvr, Yvdrdr on
    these runs)``."""
    out = []
    for k in found:
        others = [a["term"] for a in alts.get(k, [])]
        out.append(f"{k} (not separable from {', '.join(others)} on these runs)" if others else k)
    return out


def dominance_order(kept: list, stages: dict, th: Thresholds, runs: tuple | None = None) -> list:
    """The kept terms, best first: a term the held-out runs show to be worse than another kept
    term comes after it, the rest by held-out position RMS.

    Term ``a`` *dominates* ``b`` when some held-out run predicts ``b`` significantly worse than
    ``a`` and none predicts ``a`` significantly worse than ``b`` (the run-by-run test of
    :func:`compare_structures`, :func:`~bayesid.analysis.gap.verdict.run_separation_test`, at
    ``th.partial_p`` with ``th.separation_margin``). The pooled held-out RMS alone would put
    first a term that ties on many runs and loses clearly on one, such as a designed run added
    to separate it from the hidden term.

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
                b_worse, a_worse = res["p_second_worse"] < th.partial_p, res["p_first_worse"] < th.partial_p
                if b_worse and not a_worse:
                    beaten[b] += 1
                elif a_worse and not b_worse:
                    beaten[a] += 1
    return sorted(kept, key=lambda n: (beaten[n], stages[n].held["rms_position_m"]))


def _combine(kept: list, stages: dict, ref: Stage, setup: Setup, fit_args: tuple, floor: tuple, initial: dict):
    """Add the kept terms together, best first (:func:`dominance_order`): each further term is refitted on top of those
    added (all coefficients re-identified) and stays only if it passes the kept test
    (:func:`_passes`) against them while their held-out error is still above the floor band.
    ``fit_args``: ``(effects, channel weights, iterations)``; ``floor``: ``(noise floor RMS,
    thresholds, runs)`` with ``runs`` as :func:`window_runs` returns it; ``initial``: each term's
    value in the reference (:func:`reference_values`)."""
    effects, sd_fit, max_nfev = fit_args
    floor_rms, th, runs = floor
    order = dominance_order(kept, stages, th, runs)
    found, cur, values = [order[0]], stages[order[0]], {order[0]: stages[order[0]].fit.coefficients()[order[0]]}
    for n in order[1:]:
        if cur.held["rms_position_m"] <= th.none_ratio * floor_rms:
            break  # the gap is closed: a further term would fit noise
        trial = with_terms(setup, {**values, n: initial[n]})
        model, ct, ch = trial.build([e for e in effects if e not in setup.effects])
        p0 = _extended_start(ref, model, [*values.values(), initial[n]])
        n_ref = ref.model.n_theta
        p0[: n_ref + len(values)] = cur.fit.p[: n_ref + len(values)]
        try:
            f = fit_model(
                FitProblem(model, ct, sd_fit, max_nfev=max_nfev),
                p0,
                _nuisance_start(cur, model),
                starts0=_warm_starts(cur.fit, ct),
            )
        except Exception:  # noqa: BLE001 - the combination is skipped
            continue
        st = score_stage(model, f, ct, ch, sd_fit)
        row = _row(n, st, cur, None, floor_rms, runs=runs, margin=th.separation_margin)
        if _passes(row, True, th):
            found.append(n)
            cur = st
            values = {k: f.coefficients()[k] for k in found}
    return found, cur


def _verdict(
    found: list, heldout_rms: float, band: float, alts: dict | None = None, mimicked: tuple = ({}, ())
) -> str:
    """``"discovered: A+B"`` (``+unexplained`` while the held-out error stays above the floor
    band: the terms explain part of the gap), or ``"no term of the library explains it"``; a
    kept term with alternatives the runs cannot separate from it is named with them
    (:func:`_named_alternatives`). With nothing kept, the likeliest mimicked term whose mimic is
    a free coefficient closely collinear with it (column cosine >= 0.9) that the fit moved along
    the term's column by at least the training residual's RMS (``mimicked``: ``(mimicked_by,
    free)``, :func:`select_terms`) is named with the test: ``no term of the library explains it, unless
    N0 is hidden in dR0 (refit with dR0 held to test it)``."""
    if not found:
        by, free = mimicked
        hidden = [
            (t, m["parameter"])
            for t, m in by.items()
            if m.get("parameter") in free and m["cosine"] >= 0.9 and (m.get("shift_effect") or 0.0) >= 1.0
        ]
        if hidden:
            t, p = hidden[0]
            return f"no term of the library explains it, unless {t} is hidden in {p} (refit with {p} held to test it)"
        return "no term of the library explains it"
    names = _named_alternatives(found, alts or {})
    return f"discovered: {'+'.join(names)}" + ("+unexplained" if heldout_rms > band else "")


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
    cands = _candidates(sel, options)
    pool = _alternative_pool(score_test(problem, names), sel, cands, options)
    refit = [*cands, *pool]
    initial = reference_values(ref, refit)
    runner.say(f"discovery: refitting {', '.join(cands) or 'nothing'}")
    if pool:
        runner.say(f"discovery: and the alternatives {', '.join(pool)}")
    tasks = [
        Task(
            n,
            {"term": n},
            (
                TermFit(
                    n,
                    sel["coefficient"].get(n, 0.0),
                    ref,
                    setup,
                    tuple(effects),
                    ctx["sd_fit"],
                    options.max_nfev,
                    initial[n],
                ),
            ),
        )
        for n in refit
    ]
    outs = Runner(runner.jobs, runner.scheduler).run(fit_term, tasks) if tasks else []
    runs, run_names = window_runs(setup, ref.model)
    discovered, stages, fitted = [], {}, {}
    for n, out in zip(refit, outs):
        st = None if isinstance(out, TaskError) else out[0]
        msgs = [str(out)] if isinstance(out, TaskError) else out[1]
        for m in msgs:
            if isinstance(m, str):
                runner.say(f"discovery: {m}")
        sd = next((m[1] for m in msgs if isinstance(m, tuple)), None)
        row = _row(n, st, ref, sel, floor_rms, sd, (runs, run_names), th.separation_margin)
        row["refitted_as"] = "alternative" if n in pool else "selected"
        _decide(row, significant, th)
        discovered.append(row)
        if st is not None:
            fitted[n] = st
        if row["kept"]:
            stages[n] = st
    found, after = ([], None)
    if stages:
        found, after = _combine(
            list(stages),
            stages,
            ref,
            setup,
            (tuple(effects), ctx["sd_fit"], options.max_nfev),
            (floor_rms, th, (runs, run_names)),
            initial,
        )
    compared = compare_structures(found, discovered, fitted, th, runs, run_names)
    alts = alternatives(compared)
    inclusion = dict(sorted(((k, v) for k, v in sel["inclusion"].items() if v > 0), key=lambda kv: -kv[1]))
    return Discovery(
        found=found,
        verdict=_verdict(
            found,
            (after or ref).held["rms_position_m"],
            th.none_ratio * floor_rms,
            alts,
            (sel["mimicked_by"], tuple(setup.free)),
        ),
        discovered=discovered,
        inclusion=inclusion,
        residuals={
            "forces": forces,
            "explained": sel["explained"],
            "projected_rms": sel["projected_rms"],
            "mimicked": sel["mimicked"],
            "mimicked_by": sel["mimicked_by"],
        },
        library_size=len(names),
        heldout_rms_before_m=ref.held["rms_position_m"],
        heldout_rms_after_m=(after or ref).held["rms_position_m"],
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
        after=after,
        reference=ref,
        stages=fitted,
    )
