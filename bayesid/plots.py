"""Figures for reports (matplotlib, Agg backend). No algorithm lives here: every function takes
results already computed and writes one PNG."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import terms  # noqa: E402


def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def track_xy(tracks: dict, path, title: str = ""):
    """X-Y plot of tracks (name -> Track); north up, east right (x north, y east, NED)."""
    fig, ax = plt.subplots(figsize=(6, 6))
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
    return _save(fig, path)


def inputs_time(track, path, title: str = ""):
    """Rudder angle (deg) and propeller speed (rpm) against time."""
    fig, ax = plt.subplots(2, 1, figsize=(7, 4), sharex=True)
    ax[0].plot(track.t, np.degrees(track["delta_r"]))
    ax[0].set_ylabel("rudder, deg")
    ax[1].plot(track.t, track["n"])
    ax[1].set_ylabel("propeller, rpm")
    ax[1].set_xlabel("time, s")
    for a in ax:
        a.grid(alpha=0.3)
    ax[0].set_title(title)
    return _save(fig, path)


def position_error(t, errors: dict, path, title: str = ""):
    """Horizontal position error against time, one panel per entry (name -> (n,) m), like the
    paper's Fig. 2 (each panel its own scale)."""
    n = len(errors)
    fig, ax = plt.subplots(n, 1, figsize=(7, 2.2 * n), sharex=True, squeeze=False)
    for a, (name, e) in zip(ax[:, 0], errors.items()):
        a.plot(t, e * 1e3)
        a.set_ylabel("error, mm")
        a.set_title(f"{name}: max {np.nanmax(e) * 1e3:.3g} mm", fontsize=9)
        a.grid(alpha=0.3)
    ax[-1, 0].set_xlabel("time, s")
    if title:
        fig.suptitle(title)
    return _save(fig, path)


def coefficient_ratios(names, start, converged, known, path, title: str = "", lower=None, upper=None):
    """Estimated/true ratio per coefficient grouped X | Y | N, like the paper's Figs. 3-5.

    names : all coefficient names to show.   start, converged : name -> ratio for free ones.
    known : name -> ratio for known (fixed) ones, drawn as crosses.   lower, upper : bound ratios.
    """
    groups = [g for g in ("X", "Y", "N") if any(terms.term(n).group == g for n in names)]
    order = [n for g in groups for n in names if terms.term(n).group == g]
    xs = np.arange(len(order))
    fig, ax = plt.subplots(figsize=(max(7, 0.38 * len(order)), 4))
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
        ax.text(pos + k / 2 - 0.5, 1.0, f"{g} coefficients", ha="center", va="bottom",
                transform=ax.get_xaxis_transform(), fontsize=9)
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
    return _save(fig, path)


def convergence(histories: dict, path, title: str = ""):
    """Cost against iteration (log scale) for several fits (label -> list of costs)."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for label, costs in histories.items():
        c = np.asarray(costs, dtype=float)
        ax.semilogy(np.arange(c.size), np.where(c > 0, c, np.nan), label=label, lw=1.2)
    ax.set_xlabel("iteration")
    ax.set_ylabel("cost V(p)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(title)
    return _save(fig, path)


def singular_values(svals: dict, path, title: str = ""):
    """Normalised singular values of the residual Jacobian at the optimum, per case."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for label, s in svals.items():
        s = np.asarray(s, dtype=float)
        ax.semilogy(np.arange(1, s.size + 1), s / s[0], "o-", label=label, ms=4)
    ax.set_xlabel("index")
    ax.set_ylabel("singular value / largest")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(title)
    return _save(fig, path)


__all__ = ["track_xy", "inputs_time", "position_error", "coefficient_ratios", "convergence",
           "singular_values"]
