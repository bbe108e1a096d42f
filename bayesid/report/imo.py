"""The IMO MSC.137(76) criteria table of a ship's runs in the ``predict`` and ``fit`` reports
(:mod:`bayesid.estimation.imo` computes it; this module finds the ship and the runs of a command's
document and writes the markdown)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..estimation.imo import imo_criteria
from ..models.ship import is_ship_file, load_ship
from .markdown import fmt, md_table

__all__ = ["fit_imo_lines", "imo_table_lines", "predict_imo_lines"]


def _ship(ref):
    """The ship of a vehicle reference, or None for a submarine (or no reference)."""
    return load_ship(ref) if ref and is_ship_file(ref) else None


def _limit(r: dict) -> str:
    if r["limit"] is None:
        return "-" if r["result"] == "not run" else "none without a scale"
    if r["unit"] == "m":
        return f"{fmt(r['limit_L'])} L = {fmt(r['limit'], 4)} m"
    lv = r.get("l_over_v_s")
    return f"{fmt(r['limit'])} deg" + (
        f" (L/V {fmt(lv)} s)" if lv is not None and r["criterion"].endswith("10_10") else ""
    )


def _value(r: dict | None) -> str:
    if r is None:
        return "-"
    if r["value"] is None:
        return r["result"]
    v = f"{fmt(r['value_L'])} L ({fmt(r['value'], 4)} m)" if r["unit"] == "m" else f"{fmt(r['value'])} deg"
    return f"{v} **{r['result']}**" if r["result"] in ("pass", "fail") else f"{v} ({r['result']})"


def imo_table_lines(columns: dict, *, length_m: float, scale: float | None, vessel: str) -> list:
    """The markdown section of the IMO criteria of some runs, side by side for several sources.

    Parameters
    ----------
    columns : dict
        ``{column title: {run: manoeuvre_indices result}}``, e.g. ``{"measured": ...,
        "predicted": ...}``; the first column decides each run's standard manoeuvre and test
        speed for every column (:func:`~bayesid.estimation.imo.imo_criteria` ``reference``).
    length_m : float
        The vessel file's L, m.
    scale : float or None
        The vessel file's model scale (None: not given; the table says so).
    vessel : str
        The vessel's id, named in the text.

    Returns
    -------
    list of str
        The section's lines (a heading, what scale it is at, the table).
    """
    titles = list(columns)
    ref = columns[titles[0]]
    tables = {c: imo_criteria(columns[c], length_m=length_m, scale=scale, reference=ref) for c in titles}
    index = {c: {(r["criterion"], r["run"]): r for r in rows} for c, rows in tables.items()}
    rows = [
        [
            f"{r['section']} {r['what']}",
            r["run"] or "-",
            r["manoeuvre"],
            _limit(r),
            *(_value(index[c].get((r["criterion"], r["run"]))) for c in titles),
        ]
        for r in tables[titles[0]]
    ]
    if scale is None:
        where = (
            f"{vessel} gives no `[particulars] scale`, so the values are at the file's scale (L = {fmt(length_m)} m). "
            "The distance criteria are ratios to L and the 20/20 limit is a fixed angle: they hold at any scale. "
            "The 10/10 overshoot limits depend on L/V at full scale and are not given (set `scale` in the "
            "vessel file, 1 for a full-scale ship)."
        )
    else:
        where = (
            f"At full scale: Froude scaling with {vessel}'s model scale 1:{fmt(scale, 5)} (L = {fmt(length_m * scale, 4)} m; "
            "distances x lambda, speeds and L/V x sqrt(lambda), angles unchanged). Viscous scale effects are not "
            "corrected."
        )
    return [
        "",
        "## IMO manoeuvring criteria (MSC.137(76) Sec. 5.3)",
        "",
        where
        + " Test speed V: each run's speed over ground at the first execute"
        + (f" ({titles[0]} run's for every column)" if len(titles) > 1 else "")
        + ". A criterion no run applies to is listed as not run; runs that are none of the standard "
        "manoeuvres (35 deg turn, 10/10 and 20/20 zigzag) are not listed.",
        "",
        md_table(["criterion", "run", "manoeuvre", "limit", *titles], rows),
        "",
    ]


def predict_imo_lines(doc: dict) -> list:
    """The IMO criteria section of a ``bayesid predict`` report: each track's measured and
    predicted indices side by side.

    Parameters
    ----------
    doc : dict
        The ``predict.json`` document (``model``: the model file, whose vehicle is read;
        ``indices``: ``{track: {"measured": ..., "predicted": ...}}``).

    Returns
    -------
    list of str
        The section's lines; empty for a submarine.
    """
    from ..estimation.modelfile import ModelDocument

    ship = _ship(ModelDocument.from_json(doc["model"]).vehicle_path())
    if ship is None:
        return []
    cols = {
        side: {n: d[side] for n, d in doc["indices"].items() if isinstance(d.get(side), dict)}
        for side in ("measured", "predicted")
    }
    return imo_table_lines(cols, length_m=ship.L, scale=ship.scale, vessel=ship.id)


def _track_indices(path) -> tuple | None:
    """(track name, manoeuvre indices) of a track file (None when it lacks a position, heading
    or rudder column); rows with a missing value among them left out."""
    from ..data.track import read_csv
    from ..estimation.indices import manoeuvre_indices

    tr = read_csv(path)
    cols = ("x", "y", "psi", "delta_r")
    if not all(c in tr for c in cols):
        return None
    a = np.column_stack([tr.t, *(np.asarray(tr[c], float) for c in cols)])
    a = a[np.all(np.isfinite(a), axis=1)]
    return (tr.name, manoeuvre_indices(*a.T)) if a.shape[0] > 2 else None


def fit_imo_lines(doc: dict) -> list:
    """The IMO criteria section of a ``bayesid fit`` report: the training runs as measured (read
    again from the files the fit recorded; ``bayesid predict`` sets the model's values beside
    them).

    Parameters
    ----------
    doc : dict
        The ``model.json`` document (``vehicle``; ``provenance.input_sha256``: the training
        files).

    Returns
    -------
    list of str
        The section's lines; empty for a submarine, or when no training file can be read any more.
    """
    ship = _ship(doc.get("vehicle"))
    if ship is None:
        return []
    runs = {}
    for f in (doc.get("provenance") or {}).get("input_sha256") or {}:
        got = _track_indices(f) if Path(f).is_file() else None
        if got is not None:
            runs[got[0]] = got[1]
    if not runs:
        return []
    return imo_table_lines({"measured (training run)": runs}, length_m=ship.L, scale=ship.scale, vessel=ship.id)
