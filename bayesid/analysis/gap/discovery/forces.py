"""Where the force is missing: the inverse-dynamics force residuals of the training tracks
(:func:`force_residuals`: the forces the measured motion implies minus the fitted model's, with
the null that noise alone gives, measured on the model's own run through the inputs,
:func:`twin_track`) and their summary per degree of freedom against the best candidates
(:func:`force_summary`, for the report)."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

from ....data.track import STATE_NAMES, Track
from ....estimation.windows import pooled_noise_sd
from ....models.library import term_library
from .options import DOFS, DiscoveryOptions

__all__ = ["twin_track", "force_residuals", "force_summary"]


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
        The candidate terms (:func:`~.library.candidate_terms`).
    options : DiscoveryOptions, optional
        ``trim_s`` (default :class:`~.options.DiscoveryOptions`).
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


def force_summary(rows: list, sel, names: list, options: DiscoveryOptions) -> dict:
    """The missing force per degree of freedom against the best candidates (for the report).

    Parameters
    ----------
    rows : list of dict
        :func:`force_residuals`.
    sel : Selection
        :func:`~.selection.select_terms`.
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
        j = DOFS.index(g)
        y = F[:, j]
        top = sorted((n for n in names if n[0] == g), key=lambda n: -sel.inclusion.get(n, 0.0))[:5]
        rows_top = []
        for n in top:
            c = C[:, names.index(n)]
            cc = float(c @ c)
            r2 = float((c @ y) ** 2 / (cc * (y @ y))) if cc > 0 and y @ y > 0 else 0.0
            rows_top.append({"term": n, "inclusion_probability": sel.inclusion.get(n, 0.0), "force_r2": r2})
        out[g] = {
            "rms": float(np.sqrt(np.mean(y**2))),
            "noise_rms": None if null is None else float(np.sqrt(np.mean(null[:, j] ** 2))),
            "top": rows_top,
        }
    return out
