"""Figures for reports (matplotlib). No algorithm lives here: every figure function takes
results already computed, draws them onto the axes it is given (``ax=``, or ``axes=`` for a
figure of several panels, in the shape its docstring gives) or onto a new figure, and returns
those axes. Given a ``path`` (the argument after the data, as the reports and the study scripts
pass it), it writes the figure there as a PNG, closes it and returns the path instead.

The posterior figures (:func:`walker_traces`, :func:`rank_histograms`, :func:`pair_scatter`) are
ArviZ's (``az.plot_trace``, ``az.plot_rank``, ``az.plot_pair``) on the draws they are given.

The module never chooses a backend (no ``matplotlib.use``): the program that runs it does (where
it does not, matplotlib picks a non-interactive one when there is no display), and a notebook
keeps its own."""

from __future__ import annotations

import math
import textwrap
import warnings
from contextlib import contextmanager
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ..data import terms

__all__ = [
    "track_xy",
    "inputs_time",
    "position_error",
    "coefficient_ratios",
    "convergence",
    "singular_values",
    "walker_traces",
    "rank_histograms",
    "pair_scatter",
    "correlation_heatmap",
    "fim_spectra",
    "marginals_vs_truth",
    "inclusion_heatmap",
    "cross_prediction",
    "design_inputs",
    "predicted_vs_measured",
    "gap_ranking",
    "gap_channels",
    "gap_regions",
    "window_tracks",
    "window_scatter",
    "confusion_matrix",
    "turning_band",
    "multistart",
    "reliability",
    "prediction_band",
    "prior_posterior_marginals",
    "importance_weights",
    "training_fit",
    "MARK_GID",
    "mark_indices",
    "simulated_run",
    "plot_alternatives",
]


def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def _done(fig, axes, path):
    """What a figure function returns: ``axes`` when no ``path``; else ``fig`` written to ``path``
    (:func:`_save`: closed) and the path."""
    return axes if path is None else _save(fig, path)


def _axes(ax, figsize):
    """(figure, axes) to draw on: ``ax`` and its figure, or a new figure of ``figsize`` (in)."""
    if ax is None:
        return plt.subplots(figsize=figsize)
    return ax.figure, ax


def _panels(axes, shape, make, name):
    """(figure, ndarray of Axes of ``shape``) to draw on: ``axes`` (any array-like of as many
    Axes, of one figure), or the ones ``make()`` returns with their figure.

    Raises
    ------
    ValueError
        ``axes`` holds another number of Axes than ``shape`` asks.
    """
    if axes is None:
        fig, made = make()
        return fig, np.asarray(made, dtype=object).reshape(shape)
    given = np.asarray(axes, dtype=object)
    if given.size != math.prod(shape):
        raise ValueError(
            f"{name} draws on axes of shape {shape}: {math.prod(shape)} Axes, got {given.size} "
            f"(shape {given.shape}); pass axes=None for a new figure"
        )
    return given.flat[0].figure, given.reshape(shape)


@contextmanager
def _arviz():
    """ArviZ, imported at first use (it takes ~2 s), quiet about what the figures' users cannot act
    on: its import-time notice of a coming refactor, its use of a matplotlib call deprecated in
    3.11, more chains than draws (the walkers are the chains) and a trace of one draw (the
    burn-in's steps are drawn beside it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        warnings.filterwarnings("ignore", "Passing a dict or None as alias_mapping", DeprecationWarning)
        warnings.filterwarnings("ignore", "More chains", UserWarning)
        warnings.filterwarnings("ignore", "Attempting to set identical low and high xlims", UserWarning)
        import arviz as az

        yield az


def track_xy(tracks: dict, path=None, title: str = "", *, ax=None):
    """X-Y plot of tracks (name -> Track); north up, east right (x north, y east, NED).

    Parameters
    ----------
    tracks : dict of str to Track
        Name -> Track: its ``"x"`` and ``"y"`` (m) drawn as a line, its first sample as a dot; a
        legend when there are several.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The axes' title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    fig, ax = _axes(ax, (6, 6))
    for name, tr in tracks.items():
        ax.plot(tr["y"], tr["x"], label=name, lw=1.2)
        ax.plot(tr["y"][0], tr["x"][0], "k.", ms=6)
    ax.set_xlabel("y (east), m")
    ax.set_ylabel("x (north), m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    if len(tracks) > 1:
        ax.legend(fontsize=8)
    ax.set_title(title)
    return _done(fig, ax, path)


def inputs_time(track, path=None, title: str = "", *, axes=None):
    """Rudder angle (deg) and propeller speed (rpm) against time.

    Parameters
    ----------
    track : Track
        The track: its ``"delta_r"`` (rad, drawn in deg) and ``"n"`` (rpm) against its times ``t``
        (s), one panel each.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The top panel's title.
    axes : array_like of matplotlib.axes.Axes, shape (2,), optional
        The rudder and the propeller panels (default: a new figure of two panels sharing x).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (2,); with ``path``, ``path`` (the PNG written).
    """
    fig, ax = _panels(axes, (2,), lambda: plt.subplots(2, 1, figsize=(7, 4), sharex=True), "inputs_time")
    ax[0].plot(track.t, np.degrees(track["delta_r"]))
    ax[0].set_ylabel("rudder, deg")
    ax[1].plot(track.t, track["n"])
    ax[1].set_ylabel("propeller, rpm")
    ax[1].set_xlabel("time, s")
    for a in ax:
        a.grid(alpha=0.3)
    ax[0].set_title(title)
    return _done(fig, ax, path)


def position_error(t, errors: dict, path=None, title: str = "", *, axes=None):
    """Horizontal position error against time, one panel per entry, like the paper's Fig. 2 (each
    panel its own scale).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times, s.
    errors : dict of str to ndarray, shape (n,)
        Name -> horizontal position error, m (drawn in mm; each panel titled with the name and the
        largest error).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The figure's title (none when empty).
    axes : array_like of matplotlib.axes.Axes, shape (len(errors),), optional
        One panel per entry of ``errors`` (default: a new figure of panels sharing x).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (len(errors),); with ``path``, ``path`` (the PNG written).
    """
    n = len(errors)
    fig, ax = _panels(
        axes, (n,), lambda: plt.subplots(n, 1, figsize=(7, 2.2 * n), sharex=True, squeeze=False), "position_error"
    )
    for a, (name, e) in zip(ax, errors.items()):
        a.plot(t, e * 1e3)
        a.set_ylabel("error, mm")
        a.set_title(f"{name}: max {np.nanmax(e) * 1e3:.3g} mm", fontsize=9)
        a.grid(alpha=0.3)
    ax[-1].set_xlabel("time, s")
    if title:
        fig.suptitle(title)
    return _done(fig, ax, path)


def coefficient_ratios(names, start, converged, known, path=None, title: str = "", bounds=None, *, ax=None):
    """Estimated/true ratio per coefficient grouped X | Y | N, like the paper's Figs. 3-5.

    Parameters
    ----------
    names : sequence of str
        All coefficient names to show, in this order within their group.
    start : dict of str to float
        Name -> ratio at the start, for the free ones (open squares).
    converged : dict of str to float
        Name -> converged ratio, for the free ones (dots); holds every name of ``start``.
    known : dict of str to float
        Name -> ratio for known (fixed) ones, drawn as crosses.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The axes' title.
    bounds : tuple of two dicts of str to float, optional
        ``(lower, upper)``: name -> lower and upper bound ratio (``upper`` holds every name of
        ``lower``); the bounds of each name in them drawn as a grey bar.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    lower, upper = bounds if bounds is not None else (None, None)
    groups = [g for g in ("X", "Y", "N") if any(terms.term(n).group == g for n in names)]
    order = [n for g in groups for n in names if terms.term(n).group == g]
    xs = np.arange(len(order))
    fig, ax = _axes(ax, (max(7, 0.38 * len(order)), 4))
    for i, n in enumerate(order):
        if lower and n in lower:
            ax.plot([i, i], [lower[n], upper[n]], color="0.8", lw=3, zorder=0)
        if n in start:
            ax.plot(i, start[n], "s", mfc="none", mec="tab:blue", ms=7)
            ax.plot(i, converged[n], "o", color="tab:red", ms=5)
        elif n in known:
            ax.plot(i, known[n], "x", color="k", ms=7)
    ax.axhline(1.0, color="k", lw=0.8)
    pos = 0
    for g in groups:
        k = sum(terms.term(n).group == g for n in order)
        if pos:
            ax.axvline(pos - 0.5, color="0.5", ls="--", lw=0.8)
        ax.text(
            pos + k / 2 - 0.5,
            1.0,
            f"{g} coefficients",
            ha="center",
            va="bottom",
            transform=ax.get_xaxis_transform(),
            fontsize=9,
        )
        pos += k
    ax.set_xticks(xs, order, rotation=70, fontsize=8)
    ax.set_ylabel("estimated / true")
    ax.plot([], [], "s", mfc="none", mec="tab:blue", label="start")
    ax.plot([], [], "o", color="tab:red", label="converged")
    ax.plot([], [], "x", color="k", label="known (not identified)")
    if lower:
        ax.plot([], [], color="0.8", lw=3, label="bounds")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3, axis="y")
    ax.set_title(title, pad=16)
    return _done(fig, ax, path)


def convergence(histories: dict, path=None, title: str = "", *, ax=None):
    """Cost against iteration (log scale) for several fits.

    Parameters
    ----------
    histories : dict of str to list of float
        Label -> the fit's cost at each iteration (non-positive costs are not drawn).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The axes' title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    fig, ax = _axes(ax, (7, 4))
    for label, costs in histories.items():
        c = np.asarray(costs, dtype=float)
        ax.semilogy(np.arange(c.size), np.where(c > 0, c, np.nan), label=label, lw=1.2)
    ax.set_xlabel("iteration")
    ax.set_ylabel("cost V(p)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(title)
    return _done(fig, ax, path)


def singular_values(svals: dict, path=None, title: str = "", *, ax=None):
    """Normalised singular values of the residual Jacobian at the optimum, per case.

    Parameters
    ----------
    svals : dict of str to array_like
        Case label -> the singular values, largest first; drawn divided by the first (log scale)
        against their index, from 1.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The axes' title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    fig, ax = _axes(ax, (7, 4))
    for label, s in svals.items():
        s = np.asarray(s, dtype=float)
        ax.semilogy(np.arange(1, s.size + 1), s / s[0], "o-", label=label, ms=4)
    ax.set_xlabel("index")
    ax.set_ylabel("singular value / largest")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(title)
    return _done(fig, ax, path)


def walker_traces(
    chains: np.ndarray,
    names,
    show,
    path=None,
    burn: int = 0,
    truth: dict | None = None,
    title: str = "",
    *,
    axes=None,
):
    """Trace of every walker for the coefficients ``show`` (colour = ensemble) and the density of
    their draws after burn-in: ArviZ's ``plot_trace`` with each walker as one chain.

    The steps before ``burn`` are drawn in the trace too (shaded), not in the density.

    Parameters
    ----------
    chains : ndarray, shape (n_ensembles, n_steps, n_walkers, P)
        The walkers' positions, prime values (every ``max(1, n_steps // 1500)``-th step drawn).
    names : sequence of str
        The P coefficient names, in the order of the last axis of ``chains``.
    show : sequence of str
        The coefficients drawn, one row of panels each.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    burn : int, default 0
        Steps shaded as burn-in and left out of the density (0: none).
    truth : dict of str to float, optional
        Name -> true value, a dashed line.
    title : str, default ""
        The figure's title (none when empty).
    axes : array_like of matplotlib.axes.Axes, shape (len(show), 2), optional
        Per coefficient, the density (left) and the trace (right) panel, as ``az.plot_trace``
        takes them (default: a new figure, the traces three times as wide as the densities).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (len(show), 2); with ``path``, ``path`` (the PNG written).
    """
    E, N, W, _ = chains.shape
    k = len(show)
    fig, axes = _panels(
        axes,
        (k, 2),
        lambda: plt.subplots(k, 2, figsize=(10, 1.5 * k + 0.6), squeeze=False, gridspec_kw={"width_ratios": [1, 3]}),
        "walker_traces",
    )
    steps = np.arange(0, N, max(1, N // 1500))
    x = chains[:, steps][..., [list(names).index(n) for n in show]]  # (E, steps, W, k)
    kept = steps >= burn if np.any(steps >= burn) else np.ones(steps.size, bool)
    walkers = x[:, kept].transpose(0, 2, 1, 3).reshape(E * W, kept.sum(), k)  # chain e * W + w
    colors = plt.cm.tab10(np.arange(E) % 10)
    with _arviz() as az:
        idata = az.from_dict(posterior={n: walkers[..., i] for i, n in enumerate(show)}, coords={"draw": steps[kept]})
        az.plot_trace(
            idata,
            var_names=list(show),
            combined=True,
            chain_prop={"color": [*np.repeat(colors, W, axis=0), "k"]},  # the last: the combined density
            trace_kwargs={"linewidth": 0.3, "alpha": 0.25},
            axes=axes,
        )
    early = np.flatnonzero(~kept)
    if early.size:  # the burn-in's traces, joined to the first step kept
        early = np.append(early, early[-1] + 1) if early[-1] + 1 < steps.size else early
    for i, n in enumerate(show):
        a = axes[i, 1]
        for e in range(E if early.size else 0):
            a.plot(steps[early], x[e, early, :, i], color=colors[e], lw=0.3, alpha=0.25)
        if burn:
            a.axvspan(0, burn, color="0.85", zorder=0)
        if truth and n in truth:
            a.axhline(truth[n], color="k", lw=1.0, ls="--")
            axes[i, 0].axvline(truth[n], color="k", lw=1.0, ls="--")
        a.set_xlim(0, steps[-1])
    axes[-1, 0].set_xlabel("after burn-in, all walkers", fontsize=8)
    axes[-1, 1].set_xlabel("step (grey: burn-in; dashed: truth; colour: ensemble)")
    if title:
        fig.suptitle(title, fontsize=10)
    return _done(fig, axes, path)


def rank_histograms(draws: dict, path=None, title: str = "", *, axes=None):
    """Rank plots (Vehtari et al. 2021, Sec. 4.1) with each ensemble's pooled draws as one chain:
    ArviZ's ``plot_rank``.

    One panel per coefficient: the ranks of all its draws together, in 20 bins, as one row of
    bars per ensemble, each with a dashed line at the uniform expectation. Uniform bars in every
    row = the ensembles sample the same distribution.

    Parameters
    ----------
    draws : dict of str to ndarray, shape (n_ensembles, n_draws)
        Name -> the draws, one row per ensemble.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The figure's title (none when empty).
    axes : array_like of matplotlib.axes.Axes, shape (len(draws),), optional
        One panel per coefficient (default: a new figure of panels one above the other).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (len(draws),); with ``path``, ``path`` (the PNG written).
    """
    names = list(draws)
    k = len(names)
    E = np.shape(draws[names[0]])[0] if names else 1
    fig, axes = _panels(
        axes,
        (k,),
        lambda: plt.subplots(k, 1, figsize=(6, (0.8 + 0.25 * E) * k + 0.6), squeeze=False),
        "rank_histograms",
    )
    with _arviz() as az:
        idata = az.from_dict(posterior={n: np.asarray(draws[n]) for n in names})
        az.plot_rank(idata, var_names=names, bins=20, kind="bars", ax=axes)
    for a in axes:  # ArviZ's labels sized for its own figure
        a.set_title(a.get_title(), fontsize=9)
        a.set_xlabel("")
        a.set_ylabel("ensemble", fontsize=8)
        a.tick_params(labelsize=7)
    axes[-1].set_xlabel("rank of the draws (all ensembles; dashed: uniform expectation)", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    return _done(fig, axes, path)


def pair_scatter(
    samples: np.ndarray,
    names,
    pairs,
    path=None,
    truth: dict | None = None,
    bounds: dict | None = None,
    title: str = "",
    *,
    axes=None,
):
    """2-D posterior density for each (a, b) of ``pairs``, ArviZ's ``plot_pair``; truth as a star,
    prior box dashed.

    Each panel is a hexbin density of the draws (every ``max(1, N // 20000)``-th one), titled with
    the pair's correlation coefficient r.

    Parameters
    ----------
    samples : ndarray, shape (N, P)
        Posterior draws, prime values.
    names : sequence of str
        The P coefficient names, in the column order of ``samples``.
    pairs : sequence of (str, str)
        The pairs (a, b), one panel each: a along x, b along y.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    truth : dict of str to float, optional
        Name -> true value (a red star, where both names of a pair have one).
    bounds : dict of str to (float, float), optional
        Name -> (lo, hi) for uniform priors; the box is drawn where both names of a pair have
        bounds.
    title : str, default ""
        The figure's title (none when empty).
    axes : array_like of matplotlib.axes.Axes, shape (len(pairs),), optional
        One panel per pair (default: a new figure of a row of panels).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (len(pairs),); with ``path``, ``path`` (the PNG written).
    """
    k = len(pairs)
    fig, axes = _panels(axes, (k,), lambda: plt.subplots(1, k, figsize=(3.4 * k, 3.4), squeeze=False), "pair_scatter")
    idx = {n: i for i, n in enumerate(names)}
    sub = samples[:: max(1, samples.shape[0] // 20000)]
    shown = dict.fromkeys(n for pair in pairs for n in pair)
    star = {"marker": "*", "color": "tab:red", "markersize": 11, "markeredgecolor": "k"}
    with _arviz() as az:
        idata = az.from_dict(posterior={n: sub[None, :, idx[n]] for n in shown})  # one chain
        for a, (p, q) in zip(axes, pairs):
            az.plot_pair(
                idata,
                var_names=[p, q],
                kind="hexbin",
                gridsize=40,
                hexbin_kwargs={"cmap": "Blues"},
                reference_values={p: truth[p], q: truth[q]} if truth and p in truth and q in truth else None,
                reference_values_kwargs=star,
                ax=a,
            )
    for a, (p, q) in zip(axes, pairs):
        if bounds and p in bounds and q in bounds:
            (x0, x1), (y0, y1) = bounds[p], bounds[q]
            a.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], "k--", lw=0.7)
        with np.errstate(invalid="ignore", divide="ignore"):  # constant draws: r undefined (NaN)
            r = np.corrcoef(sub[:, idx[p]], sub[:, idx[q]])[0, 1]
        a.set_title(f"{p}–{q}: r = {r:+.3f}", fontsize=9)
        a.set_xlabel(p, fontsize=8)
        a.set_ylabel(q, fontsize=8)
        a.tick_params(labelsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    return _done(fig, axes, path)


def correlation_heatmap(C: np.ndarray, names, path=None, title: str = "", *, ax=None):
    """Posterior correlation matrix, -1 (blue) to +1 (red).

    Parameters
    ----------
    C : ndarray, shape (P, P)
        The correlation matrix.
    names : sequence of str
        The P coefficient names, labelling its rows and columns.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The axes' title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    P = len(names)
    fig, ax = _axes(ax, (0.32 * P + 2.5, 0.32 * P + 1.8))
    im = ax.imshow(C, cmap="RdBu_r", vmin=-1, vmax=1)
    ax.set_xticks(range(P), names, rotation=90, fontsize=7)
    ax.set_yticks(range(P), names, fontsize=7)
    fig.colorbar(im, ax=ax, shrink=0.8, label="correlation")
    ax.set_title(title, fontsize=10)
    return _done(fig, ax, path)


def fim_spectra(
    spectra: dict,
    path=None,
    prior_level: dict | None = None,
    title: str = "",
    ylabel: str = "Cramér–Rao sd along it (relative, 1 = 100 %)",
    *,
    ax=None,
):
    """Cramér–Rao relative sd ``1/sqrt(lambda)`` of each Fisher-information eigen-direction, per
    case, stiffest first (log scale).

    Non-positive eigenvalues (exact nulls, at round-off) have no finite sd and are not drawn --
    the report gives their count.

    Parameters
    ----------
    spectra : dict of str to array_like
        Case label -> the eigenvalues lambda of its Fisher information (any order).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    prior_level : dict of str to float, optional
        Label -> relative prior sd, drawn as a dashed line of the same colour as the label's
        spectrum.
    title : str, default ""
        The axes' title.
    ylabel : str, default "Cramér–Rao sd along it (relative, 1 = 100 %)"
        The y axis' label.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    fig, ax = _axes(ax, (7, 4.2))
    for i, (label, lam) in enumerate(spectra.items()):
        lam = np.sort(np.asarray(lam, dtype=float))[::-1]
        sd = np.where(lam > 0, 1.0 / np.sqrt(np.clip(lam, 1e-300, None)), np.nan)
        (line,) = ax.semilogy(np.arange(1, lam.size + 1), sd, "o-", ms=4, label=label)
        if prior_level and label in prior_level:
            ax.axhline(prior_level[label], color=line.get_color(), ls="--", lw=0.8)
    ax.set_xlabel("eigen-direction (stiffest first)")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=10)
    return _done(fig, ax, path)


def marginals_vs_truth(rows: list, path=None, title: str = "", *, ax=None):
    """Posterior mean and central interval as ratios to truth, per coefficient (grouped X | Y | N),
    with the prior's range (uniform: bounds; normal: +-2 sd) in grey.

    An interval is blue when it holds the truth, red when it misses it (the legend calls it the
    90 % interval).

    Parameters
    ----------
    rows : list of dict
        From :func:`bayesid.estimation.posterior.marginal_table` with truth (``name``, ``mean``,
        ``lower``, ``upper``, ``truth``, ``covers``), plus ``prior_lo``/``prior_hi``.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The axes' title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    order = sorted(rows, key=lambda r: "XYN".index(terms.term(r["name"]).group))
    fig, ax = _axes(ax, (max(7, 0.4 * len(order)), 4))
    for i, r in enumerate(order):
        t = r["truth"]
        lo, hi = sorted((r["prior_lo"] / t, r["prior_hi"] / t))
        ax.plot([i, i], [lo, hi], color="0.85", lw=6, zorder=0)
        a, b = sorted((r["lower"] / t, r["upper"] / t))
        ax.plot([i, i], [a, b], color="tab:blue" if r["covers"] else "tab:red", lw=2)
        ax.plot(i, r["mean"] / t, "o", color="k", ms=4)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xticks(range(len(order)), [r["name"] for r in order], rotation=70, fontsize=8)
    ax.set_ylabel("posterior / true")
    ax.plot([], [], color="0.85", lw=6, label="prior range")
    ax.plot([], [], color="tab:blue", lw=2, label="90 % interval holds truth")
    ax.plot([], [], color="tab:red", lw=2, label="90 % interval misses truth")
    ax.plot([], [], "ko", ms=4, label="posterior mean")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3, axis="y")
    ax.set_title(title, fontsize=10)
    return _done(fig, ax, path)


def inclusion_heatmap(inclusion: dict, path=None, vehicle=None, title: str = "", *, ax=None):
    """Terms x manoeuvres heatmap of SINDy inclusion probabilities (manoeuvre -> {term: p}).
    Terms the vehicle model has (non-zero coefficient) are marked with a * in the label.

    Parameters
    ----------
    inclusion : dict of str to dict of str to float
        Manoeuvre -> {term: inclusion probability}, a column each; the rows are all the terms, in
        the order they first appear (a term a manoeuvre lacks is blank). Empty: a small figure
        reading "no horizontal manoeuvre".
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    vehicle : Vehicle, optional
        The vehicle model whose non-zero ``coefficients`` mark the terms (none: no term marked).
    title : str, default ""
        The axes' title; with ``vehicle``, followed by a line "(* = term in the model)".
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    mans = list(inclusion)
    if not mans:
        fig, ax = _axes(ax, (4, 2))
        ax.text(0.5, 0.5, "no horizontal manoeuvre", ha="center", transform=ax.transAxes)
        return _done(fig, ax, path)
    names = list(dict.fromkeys(t for m in mans for t in inclusion[m]))
    A = np.array([[inclusion[m].get(t, np.nan) for m in mans] for t in names])
    fig, ax = _axes(ax, (0.7 * len(mans) + 3, 0.22 * len(names) + 1.5))
    im = ax.imshow(A, cmap="viridis", vmin=0, vmax=1, aspect="auto")
    labels = [t + (" *" if vehicle is not None and vehicle.coefficients.get(t, 0.0) != 0.0 else "") for t in names]
    ax.set_yticks(range(len(names)), labels, fontsize=6)
    ax.set_xticks(range(len(mans)), mans, rotation=60, fontsize=7, ha="right")
    fig.colorbar(im, ax=ax, shrink=0.6, label="inclusion probability")
    ax.set_title(title + ("\n(* = term in the model)" if vehicle is not None else ""), fontsize=9)
    return _done(fig, ax, path)


def cross_prediction(matrix: dict, path=None, title: str = "Identify on A (rows), predict B (columns)", *, ax=None):
    """Heatmap of RMS position errors (m), log colour scale, values printed.

    Parameters
    ----------
    matrix : dict of str to dict of str to float
        A -> {B: RMS position error, m, of the model identified on A predicting B}: the rows A
        and columns B (the keys of the first row, which every row has). Non-positive values are
        left blank.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default "Identify on A (rows), predict B (columns)"
        The axes' title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    rows = list(matrix)
    cols = list(next(iter(matrix.values())))
    A = np.array([[matrix[a][b] for b in cols] for a in rows], dtype=float)
    fig, ax = _axes(ax, (0.8 * len(cols) + 3, 0.45 * len(rows) + 1.8))
    from matplotlib.colors import LogNorm

    pos = A[np.isfinite(A) & (A > 0)]
    im = ax.imshow(
        np.where(A > 0, A, np.nan),
        cmap="magma_r",
        aspect="auto",
        norm=LogNorm(vmin=max(pos.min(), 1e-3), vmax=pos.max()) if pos.size else None,
    )
    for i in range(len(rows)):
        for j in range(len(cols)):
            ax.text(
                j,
                i,
                f"{A[i, j]:.2g}",
                ha="center",
                va="center",
                fontsize=6,
                color="w" if pos.size and A[i, j] > np.sqrt(pos.min() * pos.max()) else "k",
            )
    ax.set_xticks(range(len(cols)), cols, rotation=60, fontsize=7, ha="right")
    ax.set_yticks(range(len(rows)), rows, fontsize=7)
    fig.colorbar(im, ax=ax, shrink=0.8, label="RMS position error, m")
    ax.set_title(title, fontsize=9)
    return _done(fig, ax, path)


def design_inputs(
    manoeuvres: dict, path=None, title: str = "Rudder inputs: spiral and designed manoeuvres", *, axes=None
):
    """Rudder angle (deg) against time for each manoeuvre (label -> Manoeuvre).

    Parameters
    ----------
    manoeuvres : dict of str to Manoeuvre
        Label -> Manoeuvre, one panel each: its rudder input (the first column of ``inputs``, rad,
        drawn in deg) held over each step ``dt`` (s).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default "Rudder inputs: spiral and designed manoeuvres"
        The figure's title.
    axes : array_like of matplotlib.axes.Axes, shape (len(manoeuvres),), optional
        One panel per manoeuvre (default: a new figure of panels sharing x).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (len(manoeuvres),); with ``path``, ``path`` (the PNG written).
    """
    k = len(manoeuvres)
    fig, axes = _panels(
        axes, (k,), lambda: plt.subplots(k, 1, figsize=(8, 1.7 * k + 0.6), sharex=True, squeeze=False), "design_inputs"
    )
    for a, (label, m) in zip(axes, manoeuvres.items()):
        a.step(np.arange(m.n_steps) * m.dt, np.degrees(m.inputs[:, 0]), where="post", lw=0.8)
        a.set_ylabel("rudder, deg", fontsize=8)
        a.set_title(label, fontsize=8)
        a.grid(alpha=0.3)
    axes[-1].set_xlabel("time, s")
    fig.suptitle(title, fontsize=10)
    return _done(fig, axes, path)


def predicted_vs_measured(
    design: dict, path=None, title: str = "Designed / spiral: predicted vs measured sd ratio", *, ax=None
):
    """Bars of predicted and measured sd ratios per design criterion (criterion -> dict).

    Parameters
    ----------
    design : dict of str to dict
        Criterion -> its ``"predicted_sd_ratio"`` (Fisher) and ``"measured_sd_ratio"`` (repeated
        fits): the sd ratio designed / spiral, a pair of bars each, with a line at 1.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default "Designed / spiral: predicted vs measured sd ratio"
        The axes' title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    keys = list(design)
    x = np.arange(len(keys))
    fig, ax = _axes(ax, (5, 3.5))
    ax.bar(x - 0.18, [design[k]["predicted_sd_ratio"] for k in keys], 0.36, label="predicted (Fisher)")
    ax.bar(x + 0.18, [design[k]["measured_sd_ratio"] for k in keys], 0.36, label="measured (repeated fits)")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xticks(x, keys)
    ax.set_ylabel("sd ratio, designed / spiral")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    ax.set_title(title, fontsize=9)
    return _done(fig, ax, path)


def gap_ranking(
    ranking: list,
    before: float,
    floor: float,
    path=None,
    title: str = "Candidates: held-out RMS position error",
    band_ratio: float | None = None,
    *,
    ax=None,
):
    """Horizontal bars of each candidate's held-out RMS (m) with the base model, the noise floor
    and the noise-floor band.

    Parameters
    ----------
    ranking : list of dict
        The ranked candidates: ``effect`` and ``heldout_rms_m`` (m) each.
    before : float
        The base model's held-out RMS position error, m.
    floor : float
        The noise floor's (a perfect model at the estimated noise), m.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str
        The title.
    band_ratio : float, optional
        The floor band's upper edge as a multiple of the floor (``Thresholds.none_ratio``): the
        band from the floor to it is shaded, where a model's error counts as explained.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    names = [r["effect"] for r in ranking]
    vals = [r["heldout_rms_m"] for r in ranking]
    fig, ax = _axes(ax, (6.4, 0.4 * len(names) + 2.0))
    if band_ratio is not None and np.isfinite(floor):
        ax.axvspan(
            floor,
            band_ratio * floor,
            color="0.6",
            alpha=0.35,
            zorder=0,
            label=f"noise-floor band {floor:.2f}-{band_ratio * floor:.2f} m (gap explained inside)",
        )
    ax.barh(names[::-1], vals[::-1], height=0.6, color="tab:blue", alpha=0.85, zorder=1)
    ax.axvline(before, color="tab:red", ls="--", zorder=2, label=f"base model {before:.2f} m")
    ax.axvline(floor, color="k", ls=":", zorder=2, label=f"noise floor {floor:.2f} m")
    ax.set_xlabel("held-out RMS position error, m")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.3), ncol=2)
    ax.set_title(title)
    return _done(fig, ax, path)


def gap_channels(where: dict, path=None, title: str = "Where: residual RMS / noise-floor RMS per channel", *, ax=None):
    """Bar chart of each channel's excess ratio (base model, held-out tracks).

    Parameters
    ----------
    where : dict
        The diagnosis's *where* result (``channels``: per channel the excess ratio).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str
        The figure's title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    ch = {k: v["excess_ratio"] for k, v in where["channels"].items() if v.get("excess_ratio")}
    fig, ax = _axes(ax, (5, 3))
    ax.bar(list(ch), list(ch.values()), color="tab:orange")
    ax.axhline(1.0, color="k", ls=":")
    ax.set_ylabel("RMS / floor RMS")
    ax.set_title(title)
    return _done(fig, ax, path)


def gap_regions(where: dict, path=None, title: str = "Where: error growth by operating region", *, axes=None):
    """Mean position-error growth rate (m/s) per bin of each operating-region variable.

    Parameters
    ----------
    where : dict
        The diagnosis's *where* result (``regions``: per variable the bins and growth rates).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str
        The figure's title.
    axes : array_like of matplotlib.axes.Axes, shape (len(where["regions"]),), optional
        One panel per operating-region variable (default: a new figure of a row of panels).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (len(where["regions"]),); with ``path``, ``path`` (the PNG
        written).
    """
    regs = where["regions"]
    k = len(regs)
    fig, axes = _panels(axes, (k,), lambda: plt.subplots(1, k, figsize=(3.2 * k, 3)), "gap_regions")
    for ax, (name, rows) in zip(axes, regs.items()):
        labels = [f"{r['bin'][0]:g}..{r['bin'][1]:g}" for r in rows]
        vals = [r["mean_error_growth_mps"] or 0.0 for r in rows]
        ax.bar(range(len(rows)), vals, color="tab:green")
        ax.set_xticks(range(len(rows)))
        ax.set_xticklabels(labels, rotation=45, fontsize=7)
        ax.set_title(name, fontsize=9)
    axes[0].set_ylabel("mean |d error/dt|, m/s")
    fig.suptitle(title, fontsize=10)
    return _done(fig, axes, path)


def _plan_view(ax, title):
    """Finish a plan-view (x north up, y east right) track plot."""
    ax.set_xlabel("y (east), m")
    ax.set_ylabel("x (north), m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)


def window_tracks(
    measured,
    before,
    after,
    path=None,
    title: str = "",
    labels=("base model", "with top effect"),
    run=None,
    *,
    ax=None,
):
    """Measured track and the protocol's windowed predictions before and after the top effect:
    arrays (n, 2) of x, y (NaN separates windows); ``labels`` name the two predictions; ``run``
    (optional, a Track or a mapping with ``"t"``, ``"x"``, ``"y"``, ``"psi"``, ``"delta_r"``: the
    measured run) has its turning-circle indices marked (:func:`mark_indices`).

    Parameters
    ----------
    measured : ndarray, shape (n, 2)
        Measured x, y, m.
    before : ndarray, shape (n, 2)
        The windowed predictions of the base model (NaN separates windows), m.
    after : ndarray, shape (n, 2)
        The windowed predictions with the top effect, m.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str
        The figure's title.
    labels : tuple of str
        Names of the two predictions.
    run : Track or mapping, optional
        The measured run, whose turning-circle indices are marked.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    fig, ax = _axes(ax, (6, 6))
    ax.plot(measured[:, 1], measured[:, 0], "k.", ms=1.5, label="measured")
    ax.plot(before[:, 1], before[:, 0], "tab:red", lw=1.0, label=labels[0])
    if after is not None:
        ax.plot(after[:, 1], after[:, 0], "tab:blue", lw=1.0, label=labels[1])
    if run is not None:
        mark_indices(ax, None, run["t"], run, color="0.35", label="measured: ")
    _plan_view(ax, title)
    return _done(fig, ax, path)


def window_scatter(before, after, path=None, title: str = "", labels=("reference model", "with the terms"), *, ax=None):
    """Per held-out window, the RMS position error of two models (m), against the line of no
    change: the points below it are the windows the second model predicts better.

    Parameters
    ----------
    before : array_like, shape (W,)
        The first model's per-window RMS position errors, m.
    after : array_like, shape (W,)
        The second model's, m.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The title.
    labels : tuple of str, default ("reference model", "with the terms")
        The axes' model names.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    b, a = np.asarray(before, float), np.asarray(after, float)
    fig, ax = _axes(ax, (5, 5))
    top = float(np.nanmax(np.concatenate([b, a, [1e-3]])) * 1.05)
    ax.plot([0, top], [0, top], "k--", lw=0.8, label="no change")
    better = int(np.sum(a < b))
    ax.plot(b, a, "o", ms=4, color="tab:blue", label=f"{better} of {b.size} windows better")
    ax.set_xlim(0, top)
    ax.set_ylim(0, top)
    # a long model name (e.g. "with Ydrabsdr (best refitted, not kept)") wraps: on one line the
    # vertical label ran past the figure's height and its unit was cut off
    ax.set_xlabel(textwrap.fill(f"{labels[0]}: window RMS position error (m)", 60))
    ax.set_ylabel(textwrap.fill(f"{labels[1]}: window RMS position error (m)", 50))
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    return _done(fig, ax, path)


def confusion_matrix(confusion: dict, path=None, title: str = "True effect (rows) x verdict (columns)", *, ax=None):
    """Heat map of counts {true: {verdict: n}}.

    Parameters
    ----------
    confusion : dict
        ``{true effect: {verdict: count}}``.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str
        The figure's title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    rows = list(confusion)
    cols = sorted({v for d in confusion.values() for v in d}, key=lambda c: (c in ("none", "unexplained"), c))
    M = np.array([[confusion[r].get(c, 0) for c in cols] for r in rows])
    fig, ax = _axes(ax, (0.6 * len(cols) + 3, 0.45 * len(rows) + 2))
    ax.imshow(M, cmap="Blues")
    for i in range(len(rows)):
        for j in range(len(cols)):
            if M[i, j]:
                ax.text(j, i, str(M[i, j]), ha="center", va="center", fontsize=8)
    ax.set_xticks(range(len(cols)))
    ax.set_xticklabels(cols, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels(rows, fontsize=8)
    ax.set_title(title, fontsize=10)
    return _done(fig, ax, path)


def turning_band(sims: dict, path=None, title: str = "Predicted 35 deg turning circles (posterior draws)", *, ax=None):
    """Turning-circle tracks {label: (n_draws + 1, n, 12) states}: the identified model (first
    row, solid) and posterior draws (thin).

    Parameters
    ----------
    sims : dict
        ``{label: ndarray (n_draws + 1, n, 12)}``: states of the identified model (first row)
        and posterior draws.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str
        The figure's title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    fig, ax = _axes(ax, (6, 6))
    for i, (label, S) in enumerate(sims.items()):
        col = plt.cm.tab10(i % 10)
        for s in S[1:]:
            ax.plot(s[:, 1], s[:, 0], color=col, lw=0.4, alpha=0.3)
        ax.plot(S[0, :, 1], S[0, :, 0], color=col, lw=1.5, label=label)
    _plan_view(ax, title)
    return _done(fig, ax, path)


def multistart(summary: dict, circles, path=None, title: str = "Multistart fit", *, axes=None):
    """Left: the waterfall of a multistart fit, final costs sorted (relative to the best, log
    scale; the dashed line is the near-best tolerance). Right, when ``circles`` is given: the
    predicted turning circles [(label, x, y)] of the distinct near-best optima, plan view.

    Parameters
    ----------
    summary : dict
        The multistart summary (final costs, the near-best tolerance).
    circles : list of tuple or None
        ``[(label, x, y)]``: predicted turning circles of the distinct near-best optima, m.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str
        The figure's title.
    axes : array_like of matplotlib.axes.Axes, shape (2,) with ``circles``, else (1,), optional
        The waterfall and the turning circles' panels (default: a new figure of a row of panels).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (2,) with ``circles``, else (1,); with ``path``, ``path`` (the PNG
        written).
    """
    costs = np.asarray(summary["sorted_costs"], float)
    best = costs[0]
    rel = np.where(np.isfinite(costs), costs / best - 1 if best > 0 else costs - best, np.nan)
    k = 2 if circles else 1
    fig, axes = _panels(
        axes, (k,), lambda: plt.subplots(1, k, figsize=(11 if circles else 5.5, 4.8), squeeze=False), "multistart"
    )
    ax = axes[0]
    floor = max(1e-8, summary["cost_tolerance"] * 1e-3)
    ax.semilogy(np.arange(1, costs.size + 1), np.maximum(rel, floor), "o-", ms=4)
    ax.axhline(
        summary["cost_tolerance"], ls="--", c="k", lw=0.8, label=f"{100 * summary['cost_tolerance']:g} % of the best"
    )
    ax.set_xlabel("start, sorted by final cost")
    ax.set_ylabel("cost / best cost - 1")
    ax.set_title(
        f"{summary['n_near_best']} of {summary['n_starts']} starts within tolerance, "
        f"{summary['n_distinct_near_best']} distinct",
        fontsize=9,
    )
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    if circles:
        ax = axes[1]
        for label, x, y in circles:
            ax.plot(y, x, lw=1.2, label=label)
        ax.set_xlabel("y (east), m")
        ax.set_ylabel("x (north), m")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title("35 deg turning circles of the near-best optima", fontsize=9)
    fig.suptitle(title)
    return _done(fig, axes, path)


def reliability(
    coverage: dict,
    path=None,
    parameter_only: dict | None = None,
    title: str = "Predictive bands: nominal vs empirical coverage",
    *,
    ax=None,
):
    """Reliability diagram: for each group of claims (``coverage``: {group: {level: {"coverage",
    "n"}}}), the fraction of measured values inside the band against the band's nominal level;
    the diagonal is perfect calibration. ``parameter_only`` ({"nominal", "coverage", "n"}) adds
    the posterior draws' own band as one point for comparison.

    Parameters
    ----------
    coverage : dict
        ``{group: {level: {"coverage", "n"}}}``: held-out coverage of each group's bands.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    parameter_only : dict, optional
        ``{"nominal", "coverage", "n"}`` of the posterior draws' own band.
    title : str
        The figure's title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    fig, ax = _axes(ax, (5.5, 5))
    ax.plot([0, 1], [0, 1], "k--", lw=0.8, label="perfectly calibrated")
    for (group, cov), mk in zip(coverage.items(), "osd^"):
        lv = sorted(float(a) for a, v in cov.items() if v.get("coverage") is not None)
        if not lv:
            continue
        ys = [cov[str(a)]["coverage"] for a in lv]
        ax.plot(lv, ys, marker=mk, label=f"{group} (n = {cov[str(lv[0])]['n']})")
    if parameter_only and parameter_only.get("coverage") is not None:
        ax.plot(
            [parameter_only["nominal"]],
            [parameter_only["coverage"]],
            "rx",
            ms=10,
            mew=2,
            label=f"posterior draws alone, 5-95 % (n = {parameter_only['n']})",
        )
    ax.set_xlim(0.4, 1.0)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("nominal coverage")
    ax.set_ylabel("empirical coverage on these runs")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(title, fontsize=10)
    return _done(fig, ax, path)


def prediction_band(
    measured: dict, predicted: dict, band: dict, path=None, title: str = "", *, indices=None, axes=None
):
    """Time histories of a windowed prediction with its calibrated band: plan view (measured
    track, predicted windows, a circle of the band's position radius round each window's end:
    the band the track must stay within), heading (prediction +- the band's heading error,
    shaded) and rudder angle. A zigzag's or turn's ITTC indices are marked (:func:`mark_indices`):
    the measured run's in red, and a whole-run prediction's (one window) in purple.

    Parameters
    ----------
    measured : mapping
        The measured ``"x"``, ``"y"`` (m), ``"psi"`` and rudder angle ``"delta_r"`` (rad): arrays
        (n,) at the prediction's times, or with their own times ``"t"`` (s), arrays (m,): the
        whole run (a Track), lead-in included, so that an execute before the first window is on
        the figure.
    predicted : dict
        The prediction: ``"t"`` (s), ``"win"`` (the window index of each sample) and the
        predicted ``"x"``, ``"y"``, ``"psi"``, arrays (n,).
    band : dict
        The band: ``"max_position_m"`` and ``"max_heading_deg"`` (deg), an absent or non-finite
        value not drawn; ``"level"``, its nominal level in the legend (default 0.9).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str
        The plan view's title.
    indices : dict, optional
        The indices the report shows for the run, marked as they are: ``"measured"`` and
        ``"predicted"``, each a :func:`~bayesid.estimation.indices.manoeuvre_indices` result (a
        track's entry of ``predict.json``'s ``indices``, from
        :func:`~bayesid.estimation.prediction.turning_band`). Either absent: read from the whole
        measured run, and from the whole-run prediction (with the measured samples before its
        first one, which its start state is read from or fitted to).
    axes : array_like of matplotlib.axes.Axes, shape (3,), optional
        The plan view, the heading and the rudder angle panels (default: a new figure, the plan
        view left, the heading above the rudder angle right, sharing x).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (3,); with ``path``, ``path`` (the PNG written).
    """
    t, win = np.asarray(predicted["t"], float), np.asarray(predicted["win"])
    tm, hm = _measured_heading(t, measured)
    level = band.get("level", 0.9)
    radius_m, heading_deg = band.get("max_position_m"), band.get("max_heading_deg")
    rudder = np.asarray(measured["delta_r"], float)
    fig, axes = _panels(axes, (3,), lambda: _plan_heading_rudder((11, 6.5)), "prediction_band")
    ax, ax2, ax3 = axes
    ax.plot(measured["y"], measured["x"], "k.", ms=1.2, label="measured")
    cut = np.flatnonzero(np.diff(win) != 0) + 1
    ends = np.append(cut - 1, t.size - 1)
    for k, (a, b) in enumerate(zip(np.insert(cut, 0, 0), np.append(cut, t.size))):
        ax.plot(
            predicted["y"][a:b],
            predicted["x"][a:b],
            "tab:blue",
            lw=1.0,
            label="prediction (window protocol)" if k == 0 else None,
        )
    if radius_m is not None and np.isfinite(radius_m):
        for k, e in enumerate(ends):
            ax.add_patch(
                plt.Circle(
                    (predicted["y"][e], predicted["x"][e]),
                    radius_m,
                    fill=False,
                    color="tab:blue",
                    alpha=0.5,
                    lw=0.8,
                    label=f"{100 * level:g} % band radius {radius_m:.3g} m" if k == 0 else None,
                )
            )
    ax.set_xlabel("y (east), m")
    ax.set_ylabel("x (north), m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(title, fontsize=9)
    psi_m = _at(t, tm, hm) if tm is not t else hm
    psi_p = np.degrees(predicted["psi"])
    psi_p = psi_m + ((psi_p - psi_m + 180.0) % 360.0 - 180.0)  # the prediction on the measured branch
    ax2.plot(tm, hm, "k", lw=0.8, label="measured")
    for k, (a, b) in enumerate(zip(np.insert(cut, 0, 0), np.append(cut, t.size))):
        ax2.plot(t[a:b], psi_p[a:b], "tab:blue", lw=1.0, label="prediction" if k == 0 else None)
        if heading_deg is not None and np.isfinite(heading_deg):
            ax2.fill_between(
                t[a:b],
                psi_p[a:b] - heading_deg,
                psi_p[a:b] + heading_deg,
                color="tab:blue",
                alpha=0.2,
                label=f"{100 * level:g} % band" if k == 0 else None,
            )
    shown = indices or {}
    run = {"x": measured["x"], "y": measured["y"], "psi": np.radians(hm), "delta_r": rudder}
    mark_indices(ax, ax2, tm, run, indices=shown.get("measured"), label="measured: ")
    if cut.size == 0:  # one simulation of the whole run: its indices, from the same rudder
        # before its first sample the prediction is the measured run: its start state is read
        # from (or fitted to) those samples, and the execute may lie among them
        before = tm < t[0] - 1e-9 * max(1.0, abs(t[0]))
        run = {
            "x": np.r_[np.asarray(measured["x"], float)[before], predicted["x"]],
            "y": np.r_[np.asarray(measured["y"], float)[before], predicted["y"]],
            "psi": np.radians(np.r_[hm[before], psi_p]),
            "delta_r": np.r_[rudder[before], _at(t, tm, rudder) if tm is not t else rudder],
        }
        mark_indices(
            ax,
            ax2,
            np.r_[tm[before], t],
            run,
            indices=shown.get("predicted"),
            color="tab:purple",
            label="predicted: ",
            slot=1,
        )
    ax.legend(fontsize=7)
    ax2.set_ylabel("heading, deg")
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=7)
    ax3.plot(tm, np.degrees(rudder), "tab:green", lw=0.8)
    ax3.set_ylabel("rudder, deg")
    ax3.set_xlabel("t, s")
    ax3.grid(alpha=0.3)
    return _done(fig, axes, path)


def _plan_heading_rudder(figsize):
    """(figure, [plan view, heading, rudder angle]): a new figure of ``figsize`` (in), the plan
    view left, the heading above the rudder angle right, sharing x."""
    fig = plt.figure(figsize=figsize)
    ax = fig.add_subplot(1, 2, 1)
    ax2 = fig.add_subplot(2, 2, 2)
    return fig, [ax, ax2, fig.add_subplot(2, 2, 4, sharex=ax2)]


def _measured_heading(t, measured) -> tuple:
    """(times (s), heading (deg, :func:`_heading_deg`)) of a figure's measured run: its own
    ``"t"`` when it has one (the whole run), else ``t`` itself."""
    tm = np.asarray(measured["t"], float) if "t" in measured else t
    return tm, _heading_deg(measured["psi"])


def _at(t, tm, v) -> np.ndarray:
    """``v`` (at times ``tm``) at times ``t``, linear between its finite samples (exact at a
    sample: the figures' runs are subsets of one record)."""
    v = np.asarray(v, float)
    ok = np.isfinite(v)
    return np.interp(t, tm[ok], v[ok]) if ok.any() else np.full(np.shape(t), np.nan)


def prior_posterior_marginals(
    draws: np.ndarray, names, prior: dict, path=None, mark: dict | None = None, title: str = "", *, axes=None
):
    """One panel per parameter: histogram of the posterior draws (N, P) and the prior's density
    (a Gaussian's curve; a bounded uniform's level, drawn when it is not much wider than the
    posterior), ``mark`` {name: value} a vertical line (e.g. the fit's estimate).

    prior : {name: {"kind": "normal", "mean", "sd"} or {"kind": "uniform", "lower", "upper"}}.

    Parameters
    ----------
    draws : ndarray, shape (N, P)
        Posterior draws.
    names : sequence of str
        The P parameter names.
    prior : dict
        ``{name: {"kind": "normal", "mean", "sd"} or {"kind": "uniform", "lower", "upper"}}``.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    mark : dict, optional
        ``{name: value}`` drawn as a vertical line.
    title : str
        The figure's title.
    axes : array_like of matplotlib.axes.Axes, optional
        At least P axes, of any shape: one panel per parameter in row-major order, those left
        over turned off (default: a new figure of ``min(6, P)`` columns).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, of the shape given (default: (rows, ``min(6, P)``)); with ``path``,
        ``path`` (the PNG written).
    """
    P = len(names)
    nc = min(6, P)
    nr = -(-P // nc)
    if axes is None:
        fig, axes = plt.subplots(nr, nc, figsize=(2.2 * nc, 1.8 * nr + 0.6), squeeze=False)
    else:
        axes = np.asarray(axes, dtype=object)
        if axes.size < P:
            raise ValueError(f"prior_posterior_marginals draws {P} panels: got {axes.size} Axes")
        fig = axes.flat[0].figure
    for j, n in enumerate(names):
        a = axes.flat[j]
        x = draws[:, j]
        lo, hi = np.quantile(x, [0.001, 0.999])
        pr = prior.get(n, {})
        if pr.get("kind") == "normal":
            lo, hi = min(lo, pr["mean"] - 3 * pr["sd"]), max(hi, pr["mean"] + 3 * pr["sd"])
        span = hi - lo if hi > lo else max(abs(lo), 1e-12)
        a.hist(x, bins=40, range=(lo - 0.05 * span, hi + 0.05 * span), density=True, color="tab:blue", alpha=0.7)
        g = np.linspace(lo - 0.05 * span, hi + 0.05 * span, 200)
        if pr.get("kind") == "normal":
            a.plot(g, np.exp(-0.5 * ((g - pr["mean"]) / pr["sd"]) ** 2) / (pr["sd"] * np.sqrt(2 * np.pi)), "k--", lw=1)
        elif pr.get("kind") == "uniform" and np.isfinite(pr["upper"] - pr["lower"]):
            if pr["upper"] - pr["lower"] < 20 * span:
                a.axhline(1.0 / (pr["upper"] - pr["lower"]), color="k", ls="--", lw=1)
        if mark and n in mark:
            a.axvline(mark[n], color="tab:red", lw=1)
        a.set_title(n, fontsize=8)
        a.tick_params(labelsize=6)
        a.set_yticks([])
    for a in axes.flat[P:]:
        a.axis("off")
    fig.suptitle((title + "\n" if title else "") + "posterior (bars), prior (dashed), fit estimate (red)", fontsize=9)
    return _done(fig, axes, path)


def importance_weights(weights: np.ndarray, k_hat: float, ess: float, path=None, title: str = "", *, ax=None):
    """Sorted normalised importance weights (largest first, log scale) with the Pareto k-hat and
    the importance ESS: a few draws carrying most of the weight is what k-hat >= 0.7 flags.

    Parameters
    ----------
    weights : ndarray, shape (N,)
        Normalised importance weights.
    k_hat : float
        The Pareto k-hat of the weights.
    ess : float
        The importance-sampling effective sample size.
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str
        The figure's title.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    w = np.sort(np.asarray(weights, float))[::-1]
    fig, ax = _axes(ax, (6, 3.4))
    ax.semilogy(np.arange(1, w.size + 1), np.clip(w, 1e-300, None), lw=1)
    ax.axhline(1.0 / w.size, color="k", ls="--", lw=0.8, label="equal weights")
    ax.set_xlabel("draw (sorted by weight)")
    ax.set_ylabel("normalised weight")
    ax.set_title((title + ": " if title else "") + f"Pareto k-hat {k_hat:.2f}, ESS {ess:.0f} of {w.size}", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")
    return _done(fig, ax, path)


def training_fit(t, measured: dict, simulated: dict, win, path=None, title: str = "", *, indices=None, axes=None):
    """Measured against simulated motion of one training run under a fit's windows: plan view
    (measured track, each fit window's simulation) and heading against time, with the measured
    run's ITTC indices marked.

    Parameters
    ----------
    t : ndarray (n,)
        Sample times of the simulation, s.
    measured : mapping
        The measured ``"x"``, ``"y"`` (m) and ``"psi"`` (rad): arrays (n,) at ``t``, or with their
        own times ``"t"`` (s), arrays (m,): the whole run (a Track), lead-in included; with its
        rudder angle ``"delta_r"`` (rad) a zigzag's or turn's ITTC indices are marked
        (:func:`mark_indices`).
    simulated : dict
        The simulated ``"x"``, ``"y"`` (m) and ``"psi"`` (rad), arrays (n,), each window
        restarted as the fit scores it.
    win : ndarray (n,)
        The window index of each sample (a new line starts where it changes).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The figure's title.
    indices : dict, optional
        The measured run's :func:`~bayesid.estimation.indices.manoeuvre_indices` result as the
        report shows it (read from ``measured`` when not given).
    axes : array_like of matplotlib.axes.Axes, shape (2,), optional
        The plan view and the heading panels (default: a new figure of the two side by side).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (2,); with ``path``, ``path`` (the PNG written).
    """
    t, win = np.asarray(t, float), np.asarray(win)
    tm, hm = _measured_heading(t, measured)
    cut = np.flatnonzero(np.diff(win) != 0) + 1
    spans = list(zip(np.insert(cut, 0, 0), np.append(cut, t.size)))
    fig, axes = _panels(
        axes,
        (2,),
        lambda: plt.subplots(1, 2, figsize=(11, 4.8), gridspec_kw={"width_ratios": [1, 1.4]}),
        "training_fit",
    )
    ax, ax2 = axes
    ax.plot(measured["y"], measured["x"], "k.", ms=1.2, label="measured")
    for k, (a, b) in enumerate(spans):
        ax.plot(
            simulated["y"][a:b],
            simulated["x"][a:b],
            "tab:blue",
            lw=1.0,
            label="simulated (fit windows)" if not k else None,
        )
    ax.set_xlabel("y (east), m")
    ax.set_ylabel("x (north), m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    psi_m = _at(t, tm, hm) if tm is not t else hm
    psi_s = np.degrees(simulated["psi"])
    psi_s = psi_m + ((psi_s - psi_m + 180.0) % 360.0 - 180.0)  # the simulation on the measured branch
    ax2.plot(tm, hm, "k", lw=0.8, label="measured")
    for k, (a, b) in enumerate(spans):
        ax2.plot(t[a:b], psi_s[a:b], "tab:blue", lw=1.0, label="simulated (fit windows)" if not k else None)
    for a, _ in spans[1:]:
        ax2.axvline(t[a], color="0.7", lw=0.6, ls=":")
    if "delta_r" in measured:
        run = {"x": measured["x"], "y": measured["y"], "psi": np.radians(hm), "delta_r": measured["delta_r"]}
        mark_indices(ax, ax2, tm, run, indices=indices, label="measured: ")
        ax.legend(fontsize=7)
    ax2.set_xlabel("t, s")
    ax2.set_ylabel("heading, deg")
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    return _done(fig, axes, path)


#: The gid of each mark :func:`mark_indices` draws, prefixed to the index it shows.
MARK_GID = "ittc:"


def _heading_deg(psi) -> np.ndarray:
    """Heading (deg) as the figures draw it: the unwrapped heading in degrees (unwrapped across
    a gap of missing samples, which stay NaN)."""
    psi = np.asarray(psi, float)
    ok = np.isfinite(psi)
    out = np.full(psi.shape, np.nan)
    out[ok] = np.degrees(np.unwrap(psi[ok]))
    return out


def _mark_zigzag(ax, t, hdeg, ind: dict, style: tuple) -> None:
    """The executes, check headings, first and second overshoots and the initial turning time of
    a zigzag on a heading (deg) against time axis, where ``ind`` reads them: between samples (see
    :func:`mark_indices`)."""
    color, label, slot = style
    every = [float(v) for v in ind["executes_t_s"]]
    ex = every[:4]  # the 1st to 4th: those the indices are read from
    psi0 = float(np.interp(ex[0], t, hdeg))  # the original course: the heading at the 1st execute
    for k, te in enumerate(ex if not slot else []):  # a second run on the same rudder: the same executes
        ax.axvline(
            te, color=color, lw=0.7, ls=":", label=f"{label}executes" if not k else None, gid=f"{MARK_GID}execute"
        )
    checks = [float(v) for v in ind.get("check_heading_deg", [])][: len(ex) - 1]
    for k, check in enumerate(checks):
        end = every[k + 2] if k + 2 < len(every) else float(t[-1])
        ax.plot(
            [ex[k + 1], end],
            [psi0 + check] * 2,
            color=color,
            lw=0.8,
            ls="--",
            label=f"{label}check headings" if not k else None,
            gid=f"{MARK_GID}check_heading",
        )
    peaks = [float(v) for v in ind.get("overshoot_t_s", [])]
    for k, name in enumerate(("first", "second")):
        value = ind.get(f"{name}_overshoot_deg", float("nan"))
        if k >= min(len(peaks), len(checks)) or not (np.isfinite(value) and np.isfinite(peaks[k])):
            continue
        # the extreme lies beyond the check heading the way the heading turned to it from the
        # execute before, as manoeuvre_indices measures it
        going = np.sign(checks[k] - (checks[k - 1] if k else 0.0)) or 1.0
        tp, check = peaks[k], psi0 + checks[k]
        peak = check + going * value
        ax.plot(tp, peak, "v" if going < 0 else "^", color=color, ms=5, gid=f"{MARK_GID}{name}_overshoot_peak")
        ax.annotate(
            "",
            xy=(tp, peak),
            xytext=(tp, check),
            arrowprops={"arrowstyle": "<->", "color": color, "lw": 0.8},
            gid=f"{MARK_GID}{name}_overshoot",
        )
        ax.annotate(
            f"{name} overshoot\n{value:.1f} deg",
            xy=(tp, check + going * value / 2),
            xytext=(5, -22 * slot),
            textcoords="offset points",
            fontsize=7,
            color=color,
            va="center",
            gid=f"{MARK_GID}{name}_overshoot_text",
        )
    ttime = ind.get("initial_turning_time_s", float("nan"))
    if len(ex) > 1 and np.isfinite(ttime) and not slot:
        ax.annotate(
            "",
            xy=(ex[1], psi0),
            xytext=(ex[0], psi0),
            arrowprops={"arrowstyle": "<->", "color": color, "lw": 0.8},
            gid=f"{MARK_GID}initial_turning_time",
        )
        ax.annotate(
            f"initial turning time {ttime:.1f} s",
            xy=(ex[0], psi0),
            xytext=(0, -10 - 10 * slot),
            textcoords="offset points",
            fontsize=7,
            color=color,
            gid=f"{MARK_GID}initial_turning_time_text",
        )


def _mark_turn(ax, run: tuple, ind: dict, style: tuple) -> None:
    """The advance, transfer and tactical diameter of a turning circle on a plan view (y east
    across, x north up), as long as ``ind`` reads them (see :func:`mark_indices`)."""
    t, x, y, psi = run
    color, label, slot = style
    te = float(ind["execute_t_s"])
    x0, y0, p0 = (float(np.interp(te, t, v)) for v in (x, y, psi))  # at the execute, between samples
    c, s = np.cos(p0), np.sin(p0)
    h = psi - p0
    i0 = max(int(np.searchsorted(t, te)) - 1, 0)
    # the side of the turn: + across the original course (to starboard) for a heading increasing
    side = float(np.sign(h[i0 + int(np.argmax(np.abs(h[i0:])))])) or 1.0

    def on_course(along, across):  # (x, y) of the point along and across the original course
        return (x0 + along * c - across * s, y0 + along * s + across * c)

    marks, spans = [(x0, y0)], []
    if np.isfinite(ind.get("advance_m", float("nan"))):
        foot, point = on_course(ind["advance_m"], 0.0), on_course(ind["advance_m"], side * ind["transfer_m"])
        marks.append(point)
        ax.plot([y0, foot[1]], [x0, foot[0]], color=color, lw=0.6, ls="--", gid=f"{MARK_GID}original_course")
        spans += [("advance", (x0, y0), foot), ("transfer", foot, point)]
    after = np.flatnonzero(np.abs(h[i0:]) >= np.pi)
    if after.size and np.isfinite(ind.get("tactical_diameter_m", float("nan"))):
        # abeam the track where the heading change first reaches 180 deg (linear between samples)
        j = i0 + int(after[0])
        w = 0.0 if j == i0 else (np.pi - abs(h[j - 1])) / (abs(h[j]) - abs(h[j - 1]))
        along = c * (x[j - 1] + w * (x[j] - x[j - 1]) - x0) + s * (y[j - 1] + w * (y[j] - y[j - 1]) - y0)
        point = on_course(along, side * ind["tactical_diameter_m"])
        marks.append(point)
        spans.append(("tactical_diameter", on_course(along, 0.0), point))
    # the advance's value on the side of the course away from the turn (y is across the page)
    away = -np.sign(c * side) or -1.0
    for name, a, b in spans:
        # labels apart however small the circle is on its page: the advance and the transfer at
        # the advance's end (the transfer's foot on the original course), on the side away from
        # the turn, the advance below that point and the transfer above; the tactical diameter
        # beyond its far end, outside the circle
        if name == "tactical_diameter":
            left, at, up = b[1] < a[1], b, True
        else:
            left, at, up = away < 0, (b if name == "advance" else a), name == "transfer"
        ax.annotate(
            "",
            xy=(b[1], b[0]),
            xytext=(a[1], a[0]),
            arrowprops={"arrowstyle": "<->", "color": color, "lw": 0.8},
            gid=f"{MARK_GID}{name}",
        )
        ax.annotate(
            f"{name.replace('_', ' ')}\n{ind[name + '_m']:.1f} m",
            xy=(at[1], at[0]),
            # a second run's values a row lower: a run's advance and transfer stack about 40 pt
            xytext=(-4 if left else 4, (3 if up else -3) - 44 * slot),
            textcoords="offset points",
            fontsize=7,
            color=color,
            ha="right" if left else "left",
            va="bottom" if up else "top",
            gid=f"{MARK_GID}{name}_text",
        )
    mx, my = np.array(marks).T
    ax.plot(my, mx, "o", color=color, ms=3.5, label=f"{label}execute, 90 and 180 deg turned", gid=f"{MARK_GID}points")


def mark_indices(ax_plan, ax_heading, t, run, *, indices=None, color="tab:red", label="", slot=0):
    """Mark a run's ITTC manoeuvre indices on existing axes: a zigzag's on its heading history,
    a turning circle's on its plan view.

    The indices are those of :func:`bayesid.estimation.indices.manoeuvre_indices` (ITTC
    Recommended Procedure 7.5-04-02-01, Sec. 2.2.1-2.2.2; IMO MSC.137(76)), drawn as they are
    read, between samples: every time, angle and distance marked is the index's value, placed
    from the run's heading (zigzag) or position and heading (turn) at the first execute, linear
    between samples (``run`` must hold it):

    * **zigzag**, on ``ax_heading`` (heading in deg, the unwrapped ``run["psi"]``, against time):
      each execute (a dotted vertical line), the check heading after each later execute (a dashed
      horizontal line from it to the next execute, at the original course + ``check_heading_deg``),
      the first and second overshoot (a triangle at the heading's extreme, at ``overshoot_t_s``,
      and a double arrow from the check heading to it, labelled with the value in deg) and the
      initial turning time (a double arrow from the 1st to the 2nd execute at the original
      course, labelled in s);
    * **turning circle**, on ``ax_plan`` (y east across, x north up, as the package's plan views):
      the execute, the point the advance and transfer give (90 deg turned) and the tactical
      diameter's, abeam where the track has turned 180 deg (dots), the original course (dashed),
      the advance along it, the transfer and the tactical diameter normal to it (double arrows
      labelled with the value in m);
    * any other run: nothing.

    Every artist carries a gid :data:`MARK_GID` + the index it shows (``"ittc:first_overshoot"``,
    ``"ittc:advance"``, ...).

    Parameters
    ----------
    ax_plan : matplotlib.axes.Axes or None
        The plan view the run's ``y``, ``x`` are drawn on; None: no turning marks.
    ax_heading : matplotlib.axes.Axes or None
        The heading (deg, ``np.degrees(np.unwrap(psi))``) against time (s) axis; None: no
        zigzag marks. A heading offset by a constant (a heading change) marks the same indices
        when ``run["psi"]`` is offset by it too.
    t : array_like, shape (n,)
        Sample times, s.
    run : mapping
        ``"x"``, ``"y"`` (m), ``"psi"`` and ``"delta_r"`` (rad), arrays (n,): a Track or a dict.
    indices : dict, optional
        The run's :func:`~bayesid.estimation.indices.manoeuvre_indices` result, as a report shows
        it (computed from ``run`` when not given: pass the whole run, approach included).
    color : str, default "tab:red"
        The marks' colour.
    label : str, default ""
        Prefix of the marks' legend entries (e.g. ``"measured: "``).
    slot : int, default 0
        The text row: 0 for the first run marked on these axes, 1 for a second, so that the
        values of two runs do not overlap. A zigzag's executes and initial turning time are drawn
        for slot 0 only: a second run (a prediction from the same rudder record) has the same.

    Returns
    -------
    dict
        The indices marked (``kind`` ``"other"``: none drawn).

    Raises
    ------
    KeyError
        ``run`` lacks one of ``"x"``, ``"y"``, ``"psi"``, ``"delta_r"``.
    """
    from ..estimation.indices import manoeuvre_indices

    cols = np.vstack([np.asarray(t, float)] + [np.asarray(run[c], float) for c in ("x", "y", "psi", "delta_r")])
    t, x, y, psi, delta = cols[:, np.all(np.isfinite(cols), axis=0)]  # a measured run's gaps dropped
    if t.size < 3:
        return {"kind": "other", "reason": "fewer than 3 samples with x, y, psi and delta_r"}
    ind = manoeuvre_indices(t, x, y, psi, delta) if indices is None else indices
    style = (color, label, slot)
    if ind.get("kind") == "zigzag" and ax_heading is not None and ind.get("executes_t_s"):
        _mark_zigzag(ax_heading, t, _heading_deg(psi), ind, style)
    elif ind.get("kind") == "turning" and ax_plan is not None:
        _mark_turn(ax_plan, (t, x, y, np.unwrap(psi)), ind, style)
    return ind


def simulated_run(track, path=None, title: str = "", indices=None, *, axes=None):
    """A simulated (or measured) run: plan view, heading and rudder angle against time, with a
    zigzag's or turn's ITTC indices marked (:func:`mark_indices`).

    Parameters
    ----------
    track : Track
        The run: ``"x"``, ``"y"`` (m), ``"psi"`` and ``"delta_r"`` (rad) against its times ``t`` (s).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).
    title : str, default ""
        The figure's title.
    indices : dict, optional
        The run's :func:`~bayesid.estimation.indices.manoeuvre_indices` result (computed when not
        given).
    axes : array_like of matplotlib.axes.Axes, shape (3,), optional
        The plan view, the heading and the rudder angle panels (default: a new figure, the plan
        view left, the heading above the rudder angle right, sharing x).

    Returns
    -------
    ndarray of matplotlib.axes.Axes or Path
        The axes drawn on, shape (3,); with ``path``, ``path`` (the PNG written).
    """
    fig, axes = _panels(axes, (3,), lambda: _plan_heading_rudder((11, 5.5)), "simulated_run")
    ax, ax2, ax3 = axes
    ax.plot(track["y"], track["x"], "k", lw=1.0, label="track")
    ax.plot(track["y"][0], track["x"][0], "k.", ms=6)
    ax2.plot(track.t, _heading_deg(track["psi"]), "k", lw=1.0, label="heading")
    mark_indices(ax, ax2, track.t, track, indices=indices)
    ax.set_xlabel("y (east), m")
    ax.set_ylabel("x (north), m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax2.set_ylabel("heading, deg")
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=7)
    ax3.plot(track.t, np.degrees(track["delta_r"]), "tab:green", lw=0.8)
    ax3.set_ylabel("rudder, deg (+ port)")
    ax3.set_xlabel("t, s")
    ax3.grid(alpha=0.3)
    fig.suptitle(textwrap.fill(title, 130), fontsize=9)
    return _done(fig, axes, path)


def plot_alternatives(row, ax=None, *, path=None):
    """The alternatives' predicted tracks of one designed run (earth frame: x north, y east,
    plotted y against x), over the diagnosis's protocol windows started from the kept term's
    model.

    Parameters
    ----------
    row : DesignedRun
        A run of ``Diagnosis.design`` with ``predicted`` (``{label: {"t", "x", "y", "psi"}}``),
        ``name``, ``separation`` and ``worst_pair``.
    ax : matplotlib.axes.Axes, optional
        The axes drawn on (default: new axes on a new figure).
    path : str or Path, optional
        The PNG written, the figure then closed (default: none written, the axes returned).

    Returns
    -------
    matplotlib.axes.Axes or Path
        The axes drawn on; with ``path``, ``path`` (the PNG written).
    """
    fig, ax = _axes(ax, (6, 5))
    for i, (label, p) in enumerate(row.predicted.items()):
        ax.plot(
            p["y"],
            p["x"],
            ".",
            ms=2,
            label=(label if label.startswith("without") else f"with {label}") + (" (kept)" if i == 0 else ""),
        )
    ax.set_xlabel("y, east (m)")
    ax.set_ylabel("x, north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{row.name}: separation {row.separation:.3g} nats ({' vs '.join(row.worst_pair)})", fontsize=9)
    ax.legend(fontsize=8)
    return _done(fig, ax, path)
