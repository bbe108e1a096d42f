"""The report of ``bayesid predict`` (``report.md`` beside ``predict.json``): the window
protocol's scores, the manoeuvre indices, and the calibrated predictive bands with their coverage."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .imo import predict_imo_lines
from .markdown import fmt, grouped_warnings, md_table

#: Windows named as the worst in the per-window error distribution.
WORST_WINDOWS = 3


def window_distribution(windows: list, worst: int = WORST_WINDOWS) -> dict:
    """The distribution of the per-window errors of a protocol prediction, beside its pooled RMS.

    The pooled RMS weighs every sample alike, so a few windows with large errors can make it
    worse while most windows are better: the median and 90th percentile of the windows' RMS
    position errors, and the share of the pooled squared error the worst windows carry, show it.

    Parameters
    ----------
    windows : list of dict
        One per scored window, as :class:`bayesid.estimation.prediction.Prediction` gives them:
        ``track``, ``t_start`` (s), ``duration_s`` (s), ``rms_position_m`` and ``max_position_m``
        (m), ``rms_heading_deg`` (deg or None).
    worst : int, default :data:`WORST_WINDOWS`
        How many of the worst windows (largest RMS position error) are named.

    Returns
    -------
    dict
        ``n_windows``; ``rms_position_m`` and ``max_position_m``, each ``{"median", "p90",
        "max"}`` over the windows (m; None without windows); ``rms_heading_deg`` likewise (deg;
        None without heading); ``worst``: the ``worst`` windows, largest RMS position error
        first (``track``, ``t_start``, ``rms_position_m``, ``max_position_m``,
        ``rms_heading_deg``, ``share_of_pooled_squared_error``: the window's share of the pooled
        mean square position error, windows weighted by their scored duration);
        ``worst_share_of_pooled_squared_error``: theirs together.
    """

    def stats(key):
        v = np.array([w[key] for w in windows if w.get(key) is not None], float)
        v = v[np.isfinite(v)]
        if not v.size:
            return None
        return {"median": float(np.median(v)), "p90": float(np.quantile(v, 0.9)), "max": float(v.max())}

    # a window's weight in the pooled mean square: its scored samples, i.e. its duration
    dur = np.array([max(w["duration_s"], 0.0) for w in windows], float)
    ms = np.array([w["rms_position_m"] for w in windows], float) ** 2
    ok = np.isfinite(ms)
    total = float(np.sum(dur[ok] * ms[ok]))
    order = sorted((k for k in range(len(windows)) if ok[k]), key=lambda k: -windows[k]["rms_position_m"])[
        : max(int(worst), 0)
    ]
    named = [
        {
            "track": windows[k]["track"],
            "t_start": windows[k]["t_start"],
            "rms_position_m": windows[k]["rms_position_m"],
            "max_position_m": windows[k]["max_position_m"],
            "rms_heading_deg": windows[k].get("rms_heading_deg"),
            "share_of_pooled_squared_error": float(dur[k] * ms[k] / total) if total > 0 else None,
        }
        for k in order
    ]
    return {
        "n_windows": len(windows),
        "rms_position_m": stats("rms_position_m"),
        "max_position_m": stats("max_position_m"),
        "rms_heading_deg": stats("rms_heading_deg"),
        "worst": named,
        "worst_share_of_pooled_squared_error": (
            float(sum(w["share_of_pooled_squared_error"] for w in named)) if total > 0 and named else None
        ),
    }


def write_predict_report(doc: dict, out, tracks: list, command: str = "") -> None:
    """Write ``report.md`` of ``bayesid predict`` from its ``predict.json`` document.

    Parameters
    ----------
    doc : dict
        The ``predict.json`` document: window, start rule (and ``start``: how it was resolved),
        warnings, windowed and whole-run scores, the per-window distribution
        (``window_distribution``, :func:`window_distribution`), manoeuvre indices, bands.
    out : str or Path
        The folder written to (it exists; the figures are in ``figures/``).
    tracks : list of str
        The names of the predicted tracks, in the order of their figures.
    command : str
        The command line, quoted at the top of the report (none when empty).
    """
    whole = doc["whole_run"]
    rows = [
        [
            n,
            fmt(d["rms_position_m"]),
            fmt(d["max_position_m"]),
            fmt(d["rms_heading_deg"]),
            fmt(whole["per_track"][n]["rms_position_m"]),
        ]
        for n, d in doc["per_track"].items()
    ]
    lines = [
        "# Prediction under the window protocol",
        "",
        f"`{command}`" if command else "",
        "",
        _start_sentence(doc),
        "",
        md_table(["track", "RMS position (m)", "max (m)", "heading RMS (deg)", "whole-run RMS (m)"], rows),
        "",
        f"Pooled: {fmt(doc['pooled']['rms_position_m'])} m, heading {fmt(doc['pooled']['rms_heading_deg'])} deg; "
        f"whole run {fmt(whole['pooled']['rms_position_m'])} m.",
        "",
        *_distribution_lines(doc.get("window_distribution")),
    ]
    lines += [f"- **Warning**: {w}" for w in grouped_warnings(doc["warnings"])] + ([""] if doc["warnings"] else [])
    lines += _index_lines(doc["indices"])
    lines += predict_imo_lines(doc)  # ships: the IMO criteria, measured and predicted
    lines += ["", *_band_lines(doc["bands"], doc["n_draws"]), *[f"![{t}](figures/{t}.png)" for t in tracks], ""]
    (Path(out) / "report.md").write_text("\n".join(lines))


def _start_sentence(doc: dict) -> str:
    """How each window starts, with the rule as it was resolved and why (``doc["start"]``;
    a document without it gets the rule alone)."""
    note = doc.get("start") or {}
    if doc["start_rule"] == "measured":
        how = "the measured (causal) state"
    else:
        how = f"a state fitted with the model over the {fmt(doc['leadin_s'])} s before each window"
    return (
        f"Windows of {doc['window_s']} s restart from {how}; whole run = one open-loop simulation from the first "
        "state." + (f" Start rule **{doc['start_rule']}**: {note['reason']}." if note.get("reason") else "")
    )


def _distribution_lines(dist: dict | None) -> list:
    """The per-window error distribution beside the pooled scores, the worst windows named
    (none without ``window_distribution`` or windows)."""
    if not dist or not dist["n_windows"] or dist["rms_position_m"] is None:
        return []
    r, m, h = dist["rms_position_m"], dist["max_position_m"], dist.get("rms_heading_deg")
    rows = [
        ["RMS position (m)", fmt(r["median"]), fmt(r["p90"]), fmt(r["max"])],
        ["max position (m)", fmt(m["median"]), fmt(m["p90"]), fmt(m["max"])],
    ]
    if h is not None:
        rows.append(["RMS heading (deg)", fmt(h["median"]), fmt(h["p90"]), fmt(h["max"])])
    share = dist.get("worst_share_of_pooled_squared_error")
    worst = dist["worst"]
    return [
        f"### Per-window errors ({dist['n_windows']} windows)",
        "",
        md_table(["per window", "median", "90th percentile", "worst"], rows),
        "",
        "Worst windows: "
        + "; ".join(
            f"{w['track']} from t = {fmt(w['t_start'])} s (RMS {fmt(w['rms_position_m'])} m, max "
            f"{fmt(w['max_position_m'])} m)"
            for w in worst
        )
        + (
            f". These {len(worst)} of {dist['n_windows']} windows carry {fmt(100 * share)} % of the pooled squared "
            "position error (windows weighted by their scored duration)"
            if share is not None
            else ""
        )
        + (
            ": the pooled RMS weighs every sample alike, so a few bad windows dominate it and can make a model look "
            "worse while most of its windows are better; compare two models window by window, not by pooled RMS "
            "alone."
            if share is not None and share > 2.0 * len(worst) / dist["n_windows"]
            else "."
        ),
        "",
    ]


def _index_lines(indices: dict) -> list:
    """Each track's measured and predicted manoeuvre indices with the draws' 5-95 % band."""
    lines = []
    for n, d in indices.items():
        if d["measured"].get("kind") == "other":
            lines.append(f"- {n}: no turning or zigzag indices ({d['measured'].get('reason')})")
        if d["measured"].get("kind") in ("turning", "zigzag"):
            lines.append(
                f"- {n} ({d['measured']['kind']}): "
                + "; ".join(
                    f"{k} measured {fmt(d['measured'].get(k))}, predicted {fmt(d['predicted'].get(k))}"
                    + (f" [{fmt(d['band_5_95'][k][0])}, {fmt(d['band_5_95'][k][1])}]" if d["band_5_95"].get(k) else "")
                    for k in d["band_5_95"]
                )
            )
    return lines


def _band_lines(bands: dict, n_draws: int) -> list:
    """The section of the predictive bands and their coverage on the predicted runs (``bands``:
    those of ``predict.json``; ``n_draws``: the posterior draws behind the parameter-only bands)."""
    po = bands["parameter_only"]
    lines = [
        "## Predictive bands and their coverage on these runs",
        "",
        f"Posterior draws: {n_draws}. The draws' own 5-95 % index bands (parameter uncertainty only) hold "
        f"{po['inside']} of {po['n']} measured indices"
        + (f" ({fmt(100 * po['coverage'])} %)." if po["coverage"] is not None else "."),
        "",
    ]
    if not bands["calibrated"]:
        return lines + [f"No calibrated bands: {bands['reason']}.", ""]
    lines += _coverage_lines(bands)
    index_rows = _index_band_lines(bands)
    lines += index_rows
    window_rows = _window_band_lines(bands)
    if window_rows:
        lines += window_rows
    elif index_rows:
        lines += ["![reliability](figures/reliability.png)", ""]
    return lines


def _coverage_lines(bands: dict) -> list:
    """The coverage table of the calibrated bands, and the runs outside the training runs' range
    or extrapolated."""
    cov = bands["coverage"]
    lines = [
        "Calibrated bands (split conformal, leave one training run out: they include the structural error "
        "the model made on training runs it did not see). A window is inside when its largest position and "
        "heading errors are both within the band (one joint claim); an index when the measured value is, and "
        "is counted outside when the model predicts no value for it (e.g. its simulated zigzag never reaches "
        "the overshoot).",
        "",
        md_table(
            ["nominal", "windows inside", "indices inside", "all"],
            [
                [f"{100 * float(a):g} %"]
                + [
                    f"{c[a]['inside']}/{c[a]['n']} ({fmt(100 * c[a]['coverage'])} %)"
                    + (f", {c[a]['unbounded']} unbounded" if c[a].get("unbounded") else "")
                    if c[a]["n"]
                    else "-"
                    for c in (cov["windows"], cov["indices"], cov["all"])
                ]
                for a in cov["all"]
            ],
        ),
        "",
    ]
    if any(c.get("unbounded") for c in cov["all"].values()):
        lines += [
            "Unbounded: claims whose band at that level is infinite, because the calibration has too few scores "
            "for it (n scores support levels up to n / (n + 1)); they hold trivially and say nothing. Train on "
            "more runs for a finite band.",
            "",
        ]
    if bands.get("window_reason"):
        lines += [f"No window bands: {bands['window_reason']}.", ""]
    if bands.get("outside_range"):
        ir = bands["coverage_in_range"]
        held = "; ".join(f"{g} {c['0.9']['inside']}/{c['0.9']['n']}" for g, c in ir.items() if c["0.9"]["n"])
        lines += [
            "**Outside the training runs' range** (a calibrated band assumes a run like the calibration runs; these "
            "are driven harder or more gently, and their claims are counted above): "
            + "; ".join(f"{t}: {', '.join(v)}" for t, v in bands["outside_range"].items())
            + (f". The other runs' 90 % claims: {held}." if held else ". No other run has a claim to count."),
            "",
        ]
    ext = bands.get("extrapolated") or {}
    if ext.get("runs"):
        xc = ext["coverage"]
        lines += [
            f"**Extrapolated, not calibrated**: {', '.join(ext['runs'])} ({', '.join(ext['kinds'])}; indices "
            f"{', '.join(ext['index_kinds'])}): {ext['note']}. They are left out of the table above; their "
            "borrowed 90 % bands hold "
            + "; ".join(
                f"{g} {c['0.9']['inside']}/{c['0.9']['n']}"
                for g, c in (("windows", xc["windows"]), ("indices", xc["indices"]))
                if c["0.9"]["n"]
            )
            + " here.",
            "",
        ]
    return lines


def _index_band_lines(bands: dict) -> list:
    """The table of the indices' 90 % bands and how they are built (none without index bands)."""
    rows = [
        [
            r["track"],
            r["index"],
            fmt(r["measured"]),
            fmt(r["predicted"]),
            (
                f"[{fmt(r['band']['0.9']['lo'])}, {fmt(r['band']['0.9']['hi'])}]"
                if r["band"]["0.9"]["lo"] is not None
                else "no predicted value"
            )
            + (
                " (extrapolated)" if r.get("extrapolated") else " (pooled scores)" if r["band"]["0.9"]["pooled"] else ""
            ),
            "yes" if r["inside"]["0.9"] else "**no**",
            f"[{fmt(r['parameter_band_5_95'][0])}, {fmt(r['parameter_band_5_95'][1])}]"
            if r["parameter_band_5_95"]
            else "-",
        ]
        for r in bands["indices"]
    ]
    if not rows:
        return []
    return [
        "Indices, 90 % band:",
        "",
        md_table(["track", "index", "measured", "predicted", "90 % band", "inside", "draws' 5-95 %"], rows),
        "",
        "Band: predicted +- q x sqrt(sd^2 + (kappa x predicted)^2), sd the draws' spread of the index, kappa "
        "the training runs' median relative error of that index (model fit on the others): "
        + ", ".join(sorted({f"{r['index']} {fmt(r['band']['0.9']['kappa'])}" for r in bands["indices"]}))
        + "."
        + (
            " Pooled scores: the training runs gave fewer than 9 scores of this index, so its band uses the "
            "scores of every index (each normalised by its own index's kappa)."
            if any(r["band"]["0.9"]["pooled"] for r in bands["indices"])
            else ""
        ),
        "",
    ]


def _window_band_lines(bands: dict) -> list:
    """The table of the windows' 90 % bands and the reliability figure (none without window bands)."""
    wrows = [
        [
            w["track"],
            fmt(w["t_start"]),
            fmt(w["max_position_m"]),
            fmt(w["band"]["0.9"]["max_position_m"]),
            fmt(w["max_heading_deg"]),
            fmt(w["band"]["0.9"]["max_heading_deg"]),
            "yes" if w["inside"]["0.9"] else "**no**",
        ]
        for w in bands["windows"]
    ]
    if not wrows:
        return []
    return [
        "Windows, 90 % band:",
        "",
        md_table(
            [
                "track",
                "window start (s)",
                "max position error (m)",
                "band (m)",
                "max heading error (deg)",
                "band (deg)",
                "inside",
            ],
            wrows,
        ),
        "",
        "![reliability](figures/reliability.png)",
        "",
    ]
