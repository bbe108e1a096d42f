"""The *verdict* of the gap diagnosis: is the gap significant, which effect is the cause, which
ones contribute, what remains (the rules are stated in :mod:`bayesid.analysis.gap`).

Noise floor: the error a model of the right form shows at the measured noise level under the
same protocol, its coefficients the fitted ones or draws from their uncertainty. Cause and
contributor tests: held-out error against the floor band, share of the excess removed, a
one-sided Wilcoxon signed-rank test of the paired per-window errors (Wilcoxon 1945, Biometrics
Bulletin 1(6)), and the training BIC difference (<= -10: very strong evidence, Kass & Raftery 1995,
JASA 90(430)).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
from scipy import stats

from ...data.track import STATE_NAMES, Track
from ...estimation.windows import evaluate, window_starts
from ...models.context import START_INDEX
from ...protocol import pooled_scores, wrap
from .records import CandidateRow, Contribution, NoiseFloor

__all__ = [
    "Thresholds",
    "DivergedSimulation",
    "noise_floor",
    "coefficient_draws",
    "FLOOR_DRAWS",
    "paired_window_test",
    "run_separation_test",
    "gap_summary",
    "assign_roles",
    "contribution",
    "verdict_of",
    "RunSeparation",
]


@dataclass(frozen=True)
class Thresholds:
    """The verdict's thresholds.

    Parameters
    ----------
    none_ratio : float, default 1.5
        Significant gap: held-out error above this multiple of the floor (the floor band).
    explain_fraction : float, default 0.5
        Share of the excess a cause removes.
    bic_threshold : float, default -10.0
        Largest training ΔBIC of an accepted effect.
    partial_p : float, default 0.01
        Level of the paired window test of a contributor.
    separation_margin : float, default 0.1
        Relative excess of one model's window errors over another's on a run below which the
        run does not count as separating them (:func:`run_separation_test`).
    """

    none_ratio: float = 1.5
    explain_fraction: float = 0.5
    bic_threshold: float = -10.0
    partial_p: float = 0.01
    separation_margin: float = 0.1

    def as_dict(self) -> dict:
        """The thresholds as a JSON-able dict.

        Returns
        -------
        dict
            ``{name: value}`` of the thresholds.
        """
        return {
            "none_ratio": self.none_ratio,
            "explain_fraction": self.explain_fraction,
            "bic_threshold": self.bic_threshold,
            "partial_p": self.partial_p,
            "separation_margin": self.separation_margin,
        }

    @classmethod
    def from_dict(cls, d: dict) -> Thresholds:
        """The thresholds read back from :meth:`as_dict` (a threshold the object lacks, written
        before it existed, keeps its default).

        Parameters
        ----------
        d : dict
            ``{name: value}``.

        Returns
        -------
        Thresholds

        Raises
        ------
        ValueError
            A name that is not a threshold (named).
        """
        unknown = sorted(set(d) - {f.name for f in fields(cls)})
        if unknown:
            raise ValueError(f"thresholds: unknown key(s) {unknown}; known: {[f.name for f in fields(cls)]}")
        return cls(**d)


class DivergedSimulation(ValueError):
    """A model's simulation of a whole track gave non-finite states (:func:`noise_floor`): the
    fixed-step integration diverged, a step too coarse for the vehicle or a fit far off."""


def noise_floor(model, fitres, ctxs, tracks, sd, rng, n_rep: int = 2, draws=None) -> NoiseFloor:
    """The protocol's error for a perfect model at the measured noise level: simulate the fitted
    model on each held-out track's inputs from its first measured state (as the start rule
    estimates it), add Gaussian noise to every channel, ``n_rep`` times, and re-run the
    protocol with the same model; with ``draws``, score each noisy copy with every row of
    ``draws`` instead (coefficients drawn from the fit's uncertainty,
    :func:`coefficient_draws`): the error of a model of the right form whose coefficients are
    known only as well as the training runs tell them.

    Parameters
    ----------
    model : SimulationModel
        The model.
    fitres : FitResult
        The fit simulated (its ``p``).
    ctxs : list of TrackContext
        The held-out tracks, prepared with the protocol's windows and start rule.
    tracks : list of Track
        The held-out tracks (their inputs and columns).
    sd : dict
        ``{channel: sd}`` of the added noise, SI.
    rng : numpy.random.Generator
        Draws the noise.
    n_rep : int, default 2
        Noisy copies per track.
    draws : ndarray, shape (n_draws, n_params), optional
        Parameter vectors each copy is scored with; None: ``fitres.p`` alone (the noise alone).

    Returns
    -------
    NoiseFloor
        Position RMS, heading RMS and RMS by channel of the pooled scores
        (:func:`bayesid.protocol.pooled_scores`) of the synthetic tracks; with ``draws``, also
        their number and the share of the draws' windows whose simulation diverged (left out
        of the RMS).

    Raises
    ------
    DivergedSimulation
        A whole-track simulation with non-finite states (naming the track, the time and the step).
    """
    errs, rows = [], fitres.p[None] if draws is None else np.asarray(draws, float)
    n_windows = n_lost = 0
    for ctx, tr in zip(ctxs, tracks):
        s_first = ctx.s_meas[0].copy()
        if ctx.start == "fitted":  # the first segment's start as the rule estimates it
            s_first[START_INDEX] += window_starts(model, fitres.p, ctx)[0]
        whole = model.context(tr, None, s0=s_first)
        S = model.simulate(whole, fitres.p[None], measured_start=False)[0]
        bad = ~np.isfinite(S).all(axis=1)
        if bad.any():
            raise DivergedSimulation(
                f"simulating held-out track {tr.name!r} whole from its first state, the model's states are not "
                f"finite from t = {whole.ts[np.argmax(bad)]:.1f} s at the model step of {model.dt:g} s: a step too "
                "coarse for the vehicle (give a smaller dt, --dt) or a fit far off"
            )
        for _ in range(n_rep):
            data = {k: np.asarray(tr[k], float).copy() for k in tr.data}
            for i, k in enumerate(STATE_NAMES):
                if k in tr:
                    vals = np.full(tr.n_samples, np.nan)
                    vals[whole.idx] = S[:, i] + rng.normal(0, sd.get(k, 0.0), whole.idx.size)
                    data[k] = wrap(vals) if k == "psi" else vals
            syn = Track(tr.t, data, name=tr.name)
            c2 = model.context(syn, ctx.window_s, start=ctx.start, leadin_s=ctx.leadin_s)
            for q in rows:
                e = evaluate(model, q, [c2]).errors[0]
                n_windows += c2.W
                n_lost += np.unique(c2.win[~np.isfinite(e["x"])]).size if "x" in e else 0
                errs.append(e)
    floor = NoiseFloor.of(pooled_scores(errs))
    if draws is None:
        return floor
    return replace(floor, coefficient_draws=len(rows), diverged_share=n_lost / max(n_windows, 1))


#: Coefficient draws of the noise floor with ``DiagnoseOptions(floor="coefficients")``
#: (:func:`coefficient_draws`), each scored on every noisy copy of every held-out track
FLOOR_DRAWS = 4
#: Seed of those draws: their own stream, so that the diagnosis's other random numbers are those of
#: the noise floor alone
FLOOR_DRAW_SEED = 20261129


def coefficient_draws(fitres, n: int = FLOOR_DRAWS, seed: int = FLOOR_DRAW_SEED) -> np.ndarray:
    """Parameter vectors drawn from the coefficient uncertainty a fit of the right model form has
    at the measured noise, for the noise floor (:func:`noise_floor`'s ``draws``).

    The covariance is the inverse Fisher information ``(J^T J)^+`` of the fit's residuals, each
    divided by its channel's noise sd (the Cramér-Rao bound; the Laplace covariance with residual
    variance 1, :func:`bayesid.estimation.laplace.gauss_newton_covariance`), over every fitted
    variable (window start offsets and nuisances too) and marginal over them: the block of the
    model's parameters. It is the residual variance the fit would have *if the model were right*,
    the floor's hypothesis: the fit's own residual variance would grow with the very gap the floor
    is to judge. Draws are antithetic pairs ``p +- L z`` (``L L^T`` the covariance, ``z``
    standard normal), so that their mean is the fit's; each is clipped into the model's bounds.

    Parameters
    ----------
    fitres : FitResult
        The fit (its ``p``, shape (n_params,), and Jacobian ``jac``, shape (n_res, n_params +
        n_other), of residuals divided by their noise sds).
    n : int, default FLOOR_DRAWS
        Number of draws (rounded up to even).
    seed : int, default FLOOR_DRAW_SEED
        Seed of the standard normal draws.

    Returns
    -------
    ndarray, shape (n, n_params)
        The draws.

    Raises
    ------
    ValueError
        A fit without a finite Jacobian (no covariance to draw from).
    """
    from ...estimation.laplace import gauss_newton_covariance

    if fitres.jac is None:
        raise ValueError("the fit has no Jacobian: no covariance to draw the floor's coefficients from")
    J = fitres.jac.toarray() if hasattr(fitres.jac, "toarray") else np.asarray(fitres.jac, float)
    if not np.isfinite(J).all():
        raise ValueError("the fit's Jacobian is not finite: no coefficient draws for the floor")
    k = fitres.p.size
    cov = gauss_newton_covariance(J)[:k, :k]
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    L = V * np.sqrt(np.clip(w, 0.0, None))
    z = np.random.default_rng(seed).standard_normal((-(-n // 2), k))
    dev = z @ L.T
    rows = fitres.p[None] + np.concatenate([dev, -dev])
    lo, hi = fitres.model.bounds()
    return np.clip(rows, lo, hi)


def paired_window_test(before: np.ndarray, after: np.ndarray) -> float:
    """One-sided p-value that the per-window errors ``after`` are smaller than ``before``
    (Wilcoxon signed-rank test on the paired windows).

    Parameters
    ----------
    before : ndarray, shape (n_windows,)
        Per-window errors of the reference model.
    after : ndarray, shape (n_windows,)
        Per-window errors of the candidate, the same windows.

    Returns
    -------
    float
        The p-value; 1.0 with fewer than 6 pairs (finite and different).
    """
    ok = np.isfinite(before) & np.isfinite(after) & (before != after)
    if ok.sum() < 6:
        return 1.0
    return float(stats.wilcoxon(before[ok], after[ok], alternative="greater").pvalue)


@dataclass(frozen=True)
class RunSeparation:
    """The run-by-run test of two models' window errors (:func:`run_separation_test`).

    Parameters
    ----------
    p_second_worse, p_first_worse : float
        Bonferroni-adjusted p-values that some run's second (first) model errors exceed the
        other's by more than the margin (1.0 when untestable).
    run_second_worse, run_first_worse : int or None
        The run of the smallest p, or None.
    ratio_by_run : dict
        ``{run: geometric-mean window error ratio second / first}``.
    df : int
        Degrees of freedom of the pooled within-run variance.
    """

    p_second_worse: float
    p_first_worse: float
    run_second_worse: int | None
    run_first_worse: int | None
    ratio_by_run: dict
    df: int


def run_separation_test(first: np.ndarray, second: np.ndarray, runs: np.ndarray, margin: float = 0.1) -> RunSeparation:
    """Whether some run tells two models apart: one-sided tests, run by run, that the second
    model's window errors exceed the first's by more than ``margin`` (and the converse).

    The pooled window test (:func:`paired_window_test`) asks whether one model is better over
    all held-out windows; two structures are told apart as soon as one run separates them (Box &
    Hill 1967, Technometrics 9:57: a run where the predictions differ), and a run of a few
    windows added to many on which two models agree does not move a pooled rank test. Here the
    log ratios ``d = log(second / first)`` of the paired windows are grouped by run; each run's
    mean is tested against ``log(1 + margin)`` with a t statistic whose variance is the
    within-run variance pooled over the runs (a one-way layout; windows restart from the
    measured state, so the windows of a run are taken as independent), one-sided, and the
    smallest p over the runs is multiplied by the number of runs (Bonferroni).

    Parameters
    ----------
    first, second : ndarray, shape (n_windows,)
        Per-window errors of the two models, the same windows (m).
    runs : ndarray of int, shape (n_windows,)
        The run of each window.
    margin : float, default 0.1
        The relative excess below which a run does not separate the models.

    Returns
    -------
    RunSeparation
        The two one-sided p-values, the runs they were found on, the error ratio of each run
        and the degrees of freedom.

    Raises
    ------
    ValueError
        Arrays of different lengths.
    """
    first, second, runs = np.asarray(first, float), np.asarray(second, float), np.asarray(runs)
    if not first.shape == second.shape == runs.shape:
        raise ValueError(f"window errors and runs differ in length: {first.shape}, {second.shape}, {runs.shape}")
    ok = np.isfinite(first) & np.isfinite(second) & (first > 0) & (second > 0)
    d, g = np.log(second[ok] / first[ok]), runs[ok]
    groups = [d[g == r] for r in np.unique(g)]
    labels = list(np.unique(g))
    df = int(sum(x.size - 1 for x in groups))
    ratios = {int(r): float(np.exp(x.mean())) for r, x in zip(labels, groups)}
    if df < 2:
        return RunSeparation(1.0, 1.0, None, None, ratios, df)
    sd = float(np.sqrt(sum(((x - x.mean()) ** 2).sum() for x in groups) / df))
    sd = max(sd, 1e-12)
    step = np.log1p(margin)
    found = []  # (p, run): the second model worse, then the first
    for sign in (1.0, -1.0):
        t = np.array([(sign * x.mean() - step) / (sd / np.sqrt(x.size)) for x in groups])
        p = stats.t.sf(t, df)
        i = int(np.argmin(p))
        found.append((float(min(1.0, p[i] * len(groups))), int(labels[i])))
    (p2, r2), (p1, r1) = found
    return RunSeparation(p2, p1, r2, r1, ratios, df)


def gap_summary(train: dict, held: dict) -> dict:
    """The JSON summary of a model's training and held-out scores.

    Parameters
    ----------
    train : dict
        Scores on the training tracks (:func:`~bayesid.estimation.windows.scores`).
    held : dict
        Scores on the held-out tracks.

    Returns
    -------
    dict
        ``train_rms_m``, ``heldout_rms_m``, ``heldout_max_m``, ``heading_rms_deg``,
        ``train_heading_rms_deg``, the log-likelihoods and ``heldout_rms_by_channel``.
    """
    return {
        "train_rms_m": train["rms_position_m"],
        "heldout_rms_m": held["rms_position_m"],
        "heldout_max_m": held["max_position_m"],
        "heading_rms_deg": held["rms_heading_deg"],
        "train_heading_rms_deg": train["rms_heading_deg"],
        "train_log_likelihood": train.get("log_likelihood"),
        "heldout_log_likelihood": held.get("log_likelihood"),
        "heldout_rms_by_channel": held["rms"],
    }


def is_cause(r: dict, significant: bool, band: float, th: Thresholds) -> bool:
    """Whether the effect closes the gap: held-out error inside the noise-floor band, at least
    ``explain_fraction`` of the excess removed, ΔBIC at most ``bic_threshold``.

    Parameters
    ----------
    r : dict
        A ranked candidate (``heldout_rms_m``, ``excess_removed``, ``delta_bic``).
    significant : bool
        Whether the gap is significant.
    band : float
        The floor band, m.
    th : Thresholds
        The thresholds.

    Returns
    -------
    bool
        True for a cause.
    """
    return bool(
        significant
        and r["heldout_rms_m"] <= band
        and r["excess_removed"] >= th.explain_fraction
        and r["delta_bic"] <= th.bic_threshold
    )


def is_contributor(r: dict, significant: bool, th: Thresholds) -> bool:
    """Whether the effect improves the held-out windows without closing the gap: paired window
    test p < ``partial_p`` (or at least ``explain_fraction`` of the excess removed, where too
    few windows make the test powerless), ΔBIC at most ``bic_threshold``, positive shrinkage.

    Parameters
    ----------
    r : dict
        A ranked candidate (``delta_bic``, ``heldout_shrinkage``, ``window_p_value``,
        ``excess_removed``).
    significant : bool
        Whether the gap is significant.
    th : Thresholds
        The thresholds.

    Returns
    -------
    bool
        True for a contributor.
    """
    return bool(
        significant
        and r["delta_bic"] <= th.bic_threshold
        and r["heldout_shrinkage"] > 0
        and (r["window_p_value"] < th.partial_p or r["excess_removed"] >= th.explain_fraction)
    )


def assign_roles(results: list, significant: bool, band: float, th: Thresholds) -> None:
    """Set every ranked candidate's ``role`` (``"cause"``, ``"contributor"`` or None) in place:
    each item of ``results`` is replaced by the record with its role.

    Parameters
    ----------
    results : list of CandidateRow
        The ranked candidates.
    significant : bool
        Whether the gap is significant.
    band : float
        The floor band, m.
    th : Thresholds
        The thresholds.
    """
    for i, r in enumerate(results):
        role = (
            None
            if getattr(r, "failed_fit", None)  # a failed fit is not evidence either way
            else "cause"
            if is_cause(r, significant, band, th)
            else "contributor"
            if is_contributor(r, significant, th)
            else None
        )
        results[i] = replace(r, role=role)


def contribution(r: CandidateRow, added: bool) -> Contribution:
    """The report's record of a contributor.

    Parameters
    ----------
    r : CandidateRow
        The ranked candidate.
    added : bool
        Whether it was added to the model.

    Returns
    -------
    Contribution
        Its effect, whether added, its share of the excess, held-out RMS, window test, ΔBIC and
        parameters.
    """
    return Contribution(
        r.effect, added, r.share_of_excess, r.heldout_rms_m, r.window_p_value, r.delta_bic, r.parameters
    )


def verdict_of(significant: bool, chosen: list, remainder_significant: bool) -> str:
    """The verdict string.

    Parameters
    ----------
    significant : bool
        Whether the gap is significant.
    chosen : list of str
        The effects added, in order.
    remainder_significant : bool
        Whether the remainder is still significant.

    Returns
    -------
    str
        ``"none"`` (no significant gap), else the effects added joined by ``+`` with
        ``+unexplained`` when the remainder is still significant, or ``"unexplained"``.
    """
    if not significant:
        return "none"
    return "+".join(chosen + (["unexplained"] if remainder_significant else [])) or "unexplained"
