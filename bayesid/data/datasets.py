"""Loaders for third-party measured manoeuvring data -> :class:`~bayesid.data.track.Track`.

Three formats are read (:data:`FORMATS`); each loader returns a Track in the
package contract (``track.py``, README "Track files"): SI units, radians,
earth-fixed positions ``x, y`` with ``psi`` measured clockwise (seen from
above) from the ``x`` axis, body-frame ``u, v, r`` only where the file
measures them (positions are never differentiated here), rudder ``delta_r``
positive to port (a vessel moving ahead then turns to port, ``r < 0``), and
propeller speed ``n`` in rpm.

``"esso-osaka"``
    Esso Osaka 3 m model free-running tests, Osaka University (FRT-DS-ESSO;
    Wakita et al. 2022, doi:10.1007/s00773-021-00867-1; Miyauchi et al. 2022,
    doi:10.1007/s00773-022-00889-3).  CC BY-NC(-SA) 4.0: non-commercial; the
    files are read from outside the package and never copied into it.
    Described in ``shared/data/real/esso-osaka-frt/README.md``.
``"simman-hsva"``
    KVLCC2 7 m model zigzags, HSVA for SIMMAN 2008 (Stern & Agdrup (eds.),
    SIMMAN 2008 proceedings; files as redistributed by Alexandersson et al.
    2022, doi:10.1016/j.oceaneng.2022.112940).  Described in
    ``shared/data/real/kvlcc2-simman-hsva/README.md``.
``"simman-marin"``
    KVLCC2 free-running turning circles and zigzags, MARIN for SIMMAN 2008
    (same repository as the HSVA files); the files are at full scale and
    are Froude-scaled to the 7 m model (``scale``).  Described in
    ``shared/research/real-data-sources.md`` section 2.3.

Conventions that hold for every loader:

* ``t`` is the file's own time (s), not shifted: a run may start at t != 0.
  Rows whose fields are all empty are dropped; a row that repeats the
  previous time stamp exactly is dropped (first one kept); both are noted in
  ``track.meta["notes"]``.  A decreasing time is an error.
* ``psi`` is unwrapped (continuous, may leave (-pi, pi]); ``wind_dir`` is a
  direction in [0, 2*pi).
* Other cells that are empty stay missing (NaN).
* ``track.meta`` holds ``vessel``, ``format``, ``source_file``,
  ``sample_rate_hz`` (1 / median time step, 6 significant digits),
  ``conversions`` and ``notes`` (lists of str), ``reference`` (README and
  citation) and ``comments`` (a summary of all of these; written as ``#``
  lines by :func:`~bayesid.data.track.write_csv`).

Malformed files raise :class:`DatasetFormatError` naming the file, the row
(1-based line number in the file) and the column.
"""

from __future__ import annotations

import csv
import math
import os
import re
from pathlib import Path

import numpy as np

from .track import Track, TrackFormatError, clock
from .track import format_error as _track_fail

__all__ = [
    "FORMATS",
    "DatasetFormatError",
    "read_esso_osaka",
    "read_simman_hsva",
    "read_simman_marin",
    "read_run",
    "list_runs",
]

FORMATS = ("esso-osaka", "simman-hsva", "simman-marin")
"""Names of the supported third-party formats (``--format`` of ``bayesid convert``)."""

_TWO_PI = 2.0 * math.pi
# A data line that contains only these characters can go the fast float() path;
# anything else (letters of nan/inf, underscores, ...) is checked cell by cell.
_PLAIN = re.compile(r"[0-9eE+\-.,\s]*")
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_HEADER = re.compile(r"(?P<name>[^\[\]()]*?)\s*(?:\[(?P<u1>[^\[\]]*)\]|\((?P<u2>[^()]*)\))?")


class DatasetFormatError(TrackFormatError):
    """A third-party data file breaks its documented format.

    A :class:`~bayesid.data.track.TrackFormatError` (hence a ``ValueError``); the
    message names the file and, where applicable, the row (1-based line
    number in the file) and the column (the file's own column name, or
    ``col k (...)`` for files without a header); also available as the
    attributes ``path``, ``row`` and ``column``.

    Parameters
    ----------
    message : str
        The full message (file, row and column included).
    path : str, optional
        The file.
    row : int, optional
        1-based line number in the file.
    column : str, optional
        The column: the file's own column name, or ``col k (...)``.
    """


def _fail(path, message, row=None, column=None) -> DatasetFormatError:
    return _track_fail(path, message, row, column, error=DatasetFormatError)


def _collect_rows(path, numbered_cells, n_fields: int, expected: str):
    """Data rows from ``(line number, cells)`` pairs: empty rows dropped (their line numbers
    returned), a row with a field count other than ``n_fields`` an error naming its line.

    Parameters
    ----------
    path : str or Path
        The file, named in messages.
    numbered_cells : iterable of tuple
        ``(line number, cells)`` pairs.
    n_fields : int
        Fields of a data row.
    expected : str
        Completes the message of a row with another field count.

    Returns
    -------
    rows : list of list of str
        The data rows.
    row_of : list of int
        Their line numbers.
    dropped : list of int
        The line numbers of the empty rows.

    Raises
    ------
    DatasetFormatError
        At the first row with another field count.
    """
    rows, row_of, dropped = [], [], []
    for k, cells in numbered_cells:
        if not any(c.strip() for c in cells):
            dropped.append(k)
            continue
        if len(cells) != n_fields:
            raise _fail(path, f"has {len(cells)} fields, {expected} {n_fields}", row=k)
        rows.append(cells)
        row_of.append(k)
    return rows, row_of, dropped


def _read_lines(path, encoding):
    path = Path(path)
    if path.is_dir():
        raise _fail(path, "is a folder, not a run file (use list_runs to expand folders)")
    try:
        with open(path, encoding=encoding, newline="") as f:
            return f.read().splitlines()
    except UnicodeDecodeError as exc:
        raise _fail(path, f"not {encoding} text ({exc})") from None


def _parse_rows(path, rows, names, row_of):
    """Parse data rows (lists of cell strings) into a float array.

    ``rows[i]`` is a list of ``len(names)`` cells from file line ``row_of[i]``.
    Empty cells -> NaN.

    Parameters
    ----------
    path : str or Path
        The file, named in messages.
    rows : list of list of str
        The data rows.
    names : list of str
        The column names, named in messages.
    row_of : list of int
        The line number of each row.

    Returns
    -------
    ndarray, shape (len(rows), len(names))
        The values.

    Raises
    ------
    DatasetFormatError
        On a non-numeric or overflowing cell.
    """
    out = np.empty((len(rows), len(names)))
    for i, cells in enumerate(rows):
        try:
            if not all(_PLAIN.fullmatch(c) for c in cells):
                raise ValueError
            out[i] = [float(c) if c.strip() else math.nan for c in cells]
        except ValueError:
            for c, name in zip(cells, names):
                text = c.strip()
                if text and not _NUMBER.fullmatch(text):
                    raise _fail(path, f"non-numeric value {text!r}", row=row_of[i], column=name) from None
            raise AssertionError("unreachable") from None  # pragma: no cover
    bad = np.argwhere(np.isinf(out))
    if bad.size:
        i, j = bad[0]
        raise _fail(path, f"value {rows[i][j].strip()!r} overflows float64", row=row_of[i], column=names[j])
    return out


def _clean_time(path, t, row_of, t_column, notes):
    """Indices of rows to keep: checks missing/decreasing times, drops repeats."""
    missing = np.flatnonzero(np.isnan(t))
    if missing.size:
        raise _fail(path, "missing time value", row=row_of[missing[0]], column=t_column)
    dt = np.diff(t)
    dec = np.flatnonzero(dt < 0)
    if dec.size:
        i = int(dec[0]) + 1
        raise _fail(
            path, f"time decreases ({t[i]!r} after {t[i - 1]!r} at row {row_of[i - 1]})", row=row_of[i], column=t_column
        )
    rep = np.flatnonzero(dt == 0) + 1
    keep = np.ones(t.shape, bool)
    if rep.size:
        keep[rep] = False
        notes.append(
            f"dropped {rep.size} row(s) repeating the previous time stamp "
            f"(first at line {row_of[rep[0]]}; the first of each repeat is kept)"
        )
    return keep


def _unwrap(angle):
    """np.unwrap over the finite samples (NaN gaps kept)."""
    out = angle.copy()
    ok = np.isfinite(angle)
    out[ok] = np.unwrap(angle[ok])
    return out


def _sample_rate(t):
    if t.size < 2:
        return None
    return float(f"{1.0 / float(np.median(np.diff(t))):.6g}")


def _empty_rows_note(dropped, notes):
    if dropped:
        span = (
            f"line {dropped[0]}"
            if len(dropped) == 1
            else f"lines {dropped[0]}-{dropped[-1]}"
            if dropped[-1] - dropped[0] == len(dropped) - 1
            else f"first at line {dropped[0]}"
        )
        notes.append(f"dropped {len(dropped)} empty row(s) ({span})")


def _whitespace_table(path, lines, head: int, fields, header_name: str):
    """Whitespace-separated numeric rows after ``head`` header lines -> (array (n, len(fields)),
    line numbers, notes). Empty rows dropped (noted); errors name file, row and column."""
    rows, row_of, dropped = _collect_rows(
        path, ((k, line.split()) for k, line in enumerate(lines[head:], start=head + 1)), len(fields), "expected"
    )
    if not rows:
        raise _fail(path, f"no data rows after the {header_name}", row=head + 1)
    a = _parse_rows(path, rows, fields, row_of)
    notes = []
    _empty_rows_note(dropped, notes)
    return a, row_of, notes


def _build(path, fmt, t, data, units, vessel, reference, conversions, notes, manoeuvre=None):
    name = Path(path).stem
    rate = _sample_rate(t)
    if t.size and t[0] != 0:
        notes.append(f"time as in the file: starts at t = {clock(t[0])} s")
    meta = {
        "vessel": vessel,
        "format": fmt,
        "source_file": os.fspath(path),
        "sample_rate_hz": rate,
        "conversions": list(conversions),
        "notes": list(notes),
        "reference": reference,
    }
    meta["comments"] = (
        [
            f"source: {os.fspath(path)} (format {fmt}, read by bayesid.data.datasets)",
            f"vessel: {vessel}",
            f"reference: {reference}",
            f"sample rate: {rate:g} Hz" if rate else "sample rate: n/a (one sample)",
        ]
        + [f"conversion: {c}" for c in conversions]
        + [f"note: {n}" for n in notes]
    )
    if manoeuvre is not None:  # the file's title line, where its format has one
        meta["manoeuvre"] = manoeuvre
        if manoeuvre:
            meta["comments"].insert(2, f"manoeuvre: {manoeuvre}")
    try:
        return Track(t, data, name=name, units=units, meta=meta)
    except ValueError as exc:  # should not happen after the checks above
        raise _fail(path, str(exc)) from None


# --------------------------------------------------------------------------- Esso Osaka

_ESSO_VESSEL = "Esso Osaka 3 m model (VLCC; Osaka University, Inukai pond, free running)"
_ESSO_REFERENCE = (
    "shared/data/real/esso-osaka-frt/README.md; GitHub NAOE-5thLab/FRT-DS-ESSO; "
    "Wakita et al. (2022) JMST 27:772, doi:10.1007/s00773-021-00867-1; "
    "Miyauchi et al. (2022) JMST 27:1065, doi:10.1007/s00773-022-00889-3; "
    "licence CC BY-NC(-SA) 4.0 (non-commercial)"
)
# file column base name -> (unit in the header, required)
_ESSO_COLUMNS = {
    "t": ("s", True),
    "x_position_mid": ("m", True),
    "u_velo": ("m/s", True),
    "y_position_mid": ("m", True),
    "vm_velo": ("m/s", True),
    "psi_hat": ("rad", True),
    "r_angvelo": ("rad/s", True),
    "n_prop": ("rps", True),
    "delta_rudder": ("rad", True),
    "wind_velo_relative_mid": ("m/s", False),
    "wind_dir_relative_mid": ("rad", False),
    "wind_velo_true": ("m/s", False),
    "wind_dir_true": ("rad", False),
}


def _esso_header(path, cells, row):
    """Header cells -> {base name: index}, checking units and required columns."""
    index = {}
    for j, cell in enumerate(cells):
        text = cell.strip()
        m = _HEADER.fullmatch(text)
        base = m["name"] if m else text
        unit = (m["u1"] if m["u1"] is not None else m["u2"]) if m else None
        if base in index:
            raise _fail(path, "duplicate column", row=row, column=text)
        if base in _ESSO_COLUMNS and unit is not None and unit.strip() != _ESSO_COLUMNS[base][0]:
            raise _fail(path, f"unit {unit.strip()!r}, expected {_ESSO_COLUMNS[base][0]!r}", row=row, column=text)
        index[base] = j
    for base, (unit, required) in _ESSO_COLUMNS.items():
        if required and base not in index:
            raise _fail(
                path, f"missing column (header has {[c.strip() for c in cells]})", row=row, column=f"{base} [{unit}]"
            )
    return index


def _true_wind_from_apparent(speed_a, dir_a, u, v, psi):
    """True wind (speed, from-direction in [0, 2pi)) from apparent wind and ship motion."""
    # apparent wind velocity (where it blows TO), earth frame
    ang = dir_a + psi
    wx, wy = -speed_a * np.cos(ang), -speed_a * np.sin(ang)
    # + ship velocity over ground (earth frame)
    wx = wx + u * np.cos(psi) - v * np.sin(psi)
    wy = wy + u * np.sin(psi) + v * np.cos(psi)
    return np.hypot(wx, wy), np.mod(np.arctan2(-wy, -wx), _TWO_PI)


def read_esso_osaka(path) -> Track:
    """Read one Esso Osaka free-running run file (FRT-DS-ESSO CSV).

    Parameters
    ----------
    path : str or os.PathLike
        One run file, e.g. ``.../esso-osaka-frt/turning/turn_14-Oct-2020_14_08_51.csv``:
        UTF-8 CSV, one header row, 13 columns (t [s], x_position_mid [m],
        u_velo [m/s], y_position_mid [m], vm_velo [m/s], psi_hat [rad],
        r_angvelo [rad/s], n_prop [rps], delta_rudder [rad], and relative and
        true wind speed [m/s] and direction [rad]), 10 Hz.  Columns are
        matched by name; the four wind columns are optional.

    Returns
    -------
    Track
        ``n_samples`` rows (empty rows dropped), columns:

        * ``t`` (s, the file's time), ``x``, ``y`` (m, midship position in
          the pond's earth-fixed frame O0-x0y0: x0 is a pond axis, not true
          north; y0 to its right), ``psi`` (rad, ``psi_hat`` unwrapped),
          ``u``, ``v`` (m/s, body frame at midship, as measured), ``r``
          (rad/s, as measured);
        * ``delta_r`` = ``-delta_rudder`` (rad): the file's positive rudder
          turns the ship to starboard (r > 0), the package's to port;
        * ``n`` = 60 * ``n_prop`` (rpm; negative = astern);
        * ``wind_speed`` (m/s) and ``wind_dir`` (rad, direction the true wind
          comes from, clockwise from x0, in [0, 2*pi)): the file's
          ``wind_velo_true`` and ``wind_dir_true``, which already follow
          this convention (checked: they reproduce the file's apparent wind
          to < 0.005 m/s rms).  If only the apparent wind is given, the true
          wind is computed: with the apparent wind coming from angle
          ``g_A`` (clockwise from the bow) at speed ``U_A``, the apparent
          wind velocity over ground is ``-U_A (cos(g_A+psi), sin(g_A+psi))``,
          the true wind velocity is that plus the ship's velocity
          ``(u cos psi - v sin psi, u sin psi + v cos psi)``, and
          ``wind_dir = atan2(-w_y, -w_x) mod 2*pi``;
        * exogenous ``wind_speed_apparent`` [m/s] and ``wind_dir_apparent``
          [rad] (apparent wind at midship, from-direction clockwise from the
          bow), when present.

        ``meta`` as described in the module docstring.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    DatasetFormatError
        Naming file, row (line number) and column: no header; a required
        column missing or with another unit; duplicate column; a row with
        the wrong number of fields; a non-numeric or overflowing value; a
        missing or decreasing time.

    Notes
    -----
    Source and caveats: ``shared/data/real/esso-osaka-frt/README.md``.
    ``psi_hat`` is an estimate and drifts against the integral of ``r`` by
    up to ~30 deg on the longest runs; positions come from GNSS.
    """
    lines = _read_lines(path, "utf-8-sig")
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is None:
        raise _fail(path, "empty file (no header row)")
    header = next(csv.reader([lines[first]]))
    index = _esso_header(path, header, first + 1)
    names = [c.strip() for c in header]
    rows, row_of, dropped = _collect_rows(
        path, enumerate(csv.reader(lines[first + 1 :]), start=first + 2), len(names), "header has"
    )
    if not rows:
        raise _fail(path, "no data rows after the header", row=first + 2)
    a = _parse_rows(path, rows, names, row_of)
    notes, conversions = [], []
    _empty_rows_note(dropped, notes)
    keep = _clean_time(path, a[:, index["t"]], row_of, names[index["t"]], notes)
    a = a[keep]
    col = {base: a[:, j] for base, j in index.items()}

    psi = _unwrap(col["psi_hat"])
    data = {
        "x": col["x_position_mid"],
        "y": col["y_position_mid"],
        "psi": psi,
        "u": col["u_velo"],
        "v": col["vm_velo"],
        "r": col["r_angvelo"],
        "delta_r": 0.0 - col["delta_rudder"],
        "n": 60.0 * col["n_prop"],
    }
    conversions += [
        "x, y = x_position_mid, y_position_mid (midship, pond frame O0-x0y0; x0 is not north)",
        "u, v = u_velo, vm_velo (body frame at midship); r = r_angvelo",
        "psi = unwrap(psi_hat) (continuous)",
        "delta_r = -delta_rudder (file: +delta turns to starboard; package: + = to port)",
        "n [rpm] = 60 * n_prop [rps]",
    ]
    units = {}
    has_true = "wind_velo_true" in col and "wind_dir_true" in col
    has_app = "wind_velo_relative_mid" in col and "wind_dir_relative_mid" in col
    if has_true:
        data["wind_speed"] = col["wind_velo_true"]
        data["wind_dir"] = np.mod(col["wind_dir_true"], _TWO_PI)
        conversions.append(
            "wind_speed, wind_dir = wind_velo_true, wind_dir_true (from-direction, earth frame, clockwise from x0)"
        )
    elif has_app:
        data["wind_speed"], data["wind_dir"] = _true_wind_from_apparent(
            col["wind_velo_relative_mid"], col["wind_dir_relative_mid"], col["u_velo"], col["vm_velo"], col["psi_hat"]
        )
        conversions.append(
            "wind_speed, wind_dir computed from the apparent wind and the ship's "
            "velocity: w_true = -U_A (cos(g_A+psi), sin(g_A+psi)) + "
            "(u cos psi - v sin psi, u sin psi + v cos psi)"
        )
    else:
        notes.append("no wind columns in the file")
    if has_app:
        data["wind_speed_apparent"] = col["wind_velo_relative_mid"]
        data["wind_dir_apparent"] = col["wind_dir_relative_mid"]
        units.update(wind_speed_apparent="m/s", wind_dir_apparent="rad")
        conversions.append(
            "wind_speed_apparent, wind_dir_apparent = wind_velo_relative_mid, "
            "wind_dir_relative_mid (from-direction, clockwise from the bow)"
        )
    return _build(path, "esso-osaka", a[:, index["t"]], data, units, _ESSO_VESSEL, _ESSO_REFERENCE, conversions, notes)


# --------------------------------------------------------------------------- SIMMAN HSVA

_HSVA_VESSEL = "KVLCC2 7 m model (INSEAN 2487, scale 1:45.714; HSVA towing tank, CPMC, SIMMAN 2008)"
_HSVA_REFERENCE = (
    "shared/data/real/kvlcc2-simman-hsva/README.md; SIMMAN 2008 (Stern & Agdrup, "
    "eds.), HSVA free-running tests; files from GitHub "
    "martinlarsalbert/System-identification-of-Vessel-Manoeuvring-Models; "
    "Alexandersson et al. (2022) Ocean Eng. 266:112940"
)
_HSVA_HEADER_LINES = 4
_HSVA_FIELDS = (
    "col 0 (time, s)",
    "col 1 (x0, m)",
    "col 2 (y0, m)",
    "col 3 (psi, deg)",
    "col 4 (dx0/dt, m/s)",
    "col 5 (unverified)",
    "col 6 (r, deg/s)",
    "col 7 (unverified)",
    "col 8 (delta, deg)",
    "col 9 (n, rps)",
    "col 10 (thrust, N)",
    "col 11 (torque, N m)",
)
"""Column labels used in error messages; 0-based numbers as in the data set README."""


def read_simman_hsva(path) -> Track:
    """Read one KVLCC2 HSVA free-running zigzag file (SIMMAN 2008, ``HSVA_CPMC_KVLCC2_Z_*.dat``).

    Parameters
    ----------
    path : str or os.PathLike
        cp1252 text: 4 header lines (line 3 names the manoeuvre, e.g.
        ``Z20°/10° starting to starboard``), then 12 whitespace-separated
        numbers per line at 20 Hz, model scale.

    Returns
    -------
    Track
        Columns (file columns numbered from 0 as in the data set README):

        * ``t`` (s, col 0, time as in the file), ``x``, ``y`` (m, cols 1-2,
          earth-fixed tank frame, y to starboard), ``psi`` (rad, col 3 deg,
          unwrapped), ``r`` (rad/s, col 6 deg/s);
        * ``delta_r`` (rad, col 8 deg; sign unchanged: the file's positive
          rudder is to port and gives r < 0, as in the package);
        * ``n`` = 60 * col 9 (rpm; the file is in rps, constant 10.2295);
        * exogenous ``x_dot`` [m/s] (col 4: the earth-frame velocity dx0/dt;
          the data set README calls it u, but it equals the time derivative
          of x to < 1 mm/s rms while it differs from the body surge velocity
          by up to 6 %), ``thrust`` [N] (col 10), ``torque`` [N*m] (col 11),
          and the raw unverified cols 5 and 7 as ``hsva_col5`` and
          ``hsva_col7`` [unknown] (col 5 behaves like roll angle in deg,
          col 7 like a sway signal; neither is used as a state).

        No ``u`` or ``v``: the file gives only one earth-frame velocity
        component, so body velocities cannot be computed exactly (derive
        them from the track if needed).  ``meta`` as in the module
        docstring, plus ``meta["manoeuvre"]`` (header line 3).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    DatasetFormatError
        Naming file, row (line number) and column (``col k (...)``):
        fewer than 5 lines; a data row without 12 fields; a non-numeric or
        overflowing value; a decreasing time.

    Notes
    -----
    Column map and checks: ``shared/data/real/kvlcc2-simman-hsva/README.md``
    (col 4 re-identified here as dx0/dt).  The values are at model scale
    although the HSVA report says full scale.
    """
    lines = _read_lines(path, "cp1252")
    if len(lines) <= _HSVA_HEADER_LINES:
        raise _fail(
            path, f"too short: expected {_HSVA_HEADER_LINES} header lines and data rows, found {len(lines)} line(s)"
        )
    title = lines[2].strip() if len(lines) > 2 else ""
    if lines[0].strip().upper().startswith("MARIN"):
        raise _fail(
            path,
            "is a MARIN file (first line names MARIN), not HSVA: read it with format "
            "'simman-marin' (read_simman_marin)",
            row=1,
        )
    a, row_of, notes = _whitespace_table(path, lines, _HSVA_HEADER_LINES, _HSVA_FIELDS, "header")
    keep = _clean_time(path, a[:, 0], row_of, _HSVA_FIELDS[0], notes)
    a = a[keep]
    data = {
        "x": a[:, 1],
        "y": a[:, 2],
        "psi": _unwrap(np.radians(a[:, 3])),
        "r": np.radians(a[:, 6]),
        "delta_r": np.radians(a[:, 8]),
        "n": 60.0 * a[:, 9],
        "x_dot": a[:, 4],
        "thrust": a[:, 10],
        "torque": a[:, 11],
        "hsva_col5": a[:, 5],
        "hsva_col7": a[:, 7],
    }
    units = {"x_dot": "m/s", "thrust": "N", "torque": "N*m", "hsva_col5": "unknown", "hsva_col7": "unknown"}
    conversions = [
        "psi [rad] = unwrap(radians(col 3 [deg]))",
        "r [rad/s] = radians(col 6 [deg/s])",
        "delta_r [rad] = radians(col 8 [deg]) (sign unchanged: + = to port, gives r < 0)",
        "n [rpm] = 60 * col 9 [rps]",
        "x_dot = col 4 (earth-frame dx0/dt, m/s; not body u)",
        "hsva_col5, hsva_col7 = cols 5, 7 raw (meaning unverified)",
    ]
    notes.append("no u, v: only one earth-frame velocity component (dx0/dt) is in the file")
    return _build(
        path, "simman-hsva", a[:, 0], data, units, _HSVA_VESSEL, _HSVA_REFERENCE, conversions, notes, manoeuvre=title
    )


# --------------------------------------------------------------------------- SIMMAN MARIN

KVLCC2_SCALE = 320.0 / 7.0
"""Scale of the SIMMAN 2008 KVLCC2 models (full-scale Lpp 320 m over the 7.00 m models: 1:45.714)."""

_MARIN_VESSEL = (
    "KVLCC2 (SIMMAN 2008, MARIN free-running model tests; the files are at full scale, Lpp 320 m; the model 1:45.7)"
)
_MARIN_REFERENCE = (
    "shared/research/real-data-sources.md sec. 2.3; SIMMAN 2008 (Stern & Agdrup, eds.), "
    "MARIN free-running tests; files MARIN_FREE_KVLCC2_*_m.dat from GitHub "
    "martinlarsalbert/System-identification-of-Vessel-Manoeuvring-Models (data/01_raw/kvlcc2); "
    "Alexandersson et al. (2022) Ocean Eng. 266:112940"
)
_MARIN_FIELDS = (
    "col 0 (time, s)",
    "col 1 (x0, m)",
    "col 2 (y0, m)",
    "col 3 (phi, deg)",
    "col 4 (psi, deg)",
    "col 5 (dx0/dt, m/s)",
    "col 6 (dy0/dt, m/s)",
    "col 7 (p, deg/s)",
    "col 8 (r, deg/s)",
    "col 9 (delta, deg)",
    "col 10 (n, rpm)",
)
_MARIN_MAX_HEADER = 5


def _marin_time(path, stamps, row_of):
    """A uniform time base from 3-significant-digit stamps: ``t0 + k dt`` with ``dt`` the
    least-squares slope of stamp on row index.

    Parameters
    ----------
    path : str or Path
        The file, named in messages.
    stamps : ndarray, shape (n,)
        The time stamps, s.
    row_of : list of int
        The line number of each stamp.

    Returns
    -------
    t : ndarray, shape (n,)
        The uniform time base (the stamps as they are with fewer than 2).
    dt : float or None
        The step, s (None with fewer than 2 stamps).

    Raises
    ------
    DatasetFormatError
        Naming the first row whose stamp is missing, decreases, or lies off that grid by more
        than its rounding (half a unit of the third significant digit) plus one step; or when
        the time does not advance.
    """
    missing = np.flatnonzero(np.isnan(stamps))
    if missing.size:
        raise _fail(path, "missing time value", row=row_of[missing[0]], column=_MARIN_FIELDS[0])
    dec = np.flatnonzero(np.diff(stamps) < 0)
    if dec.size:
        i = int(dec[0]) + 1
        raise _fail(
            path, f"time decreases ({stamps[i]!r} after {stamps[i - 1]!r})", row=row_of[i], column=_MARIN_FIELDS[0]
        )
    k = np.arange(stamps.size, dtype=float)
    if stamps.size < 2:
        return stamps.copy(), None
    dt, t0 = np.polyfit(k, stamps, 1)
    if not dt > 0:
        raise _fail(path, "time does not advance", row=row_of[-1], column=_MARIN_FIELDS[0])
    t = t0 + dt * k
    tol = 0.0051 * np.abs(stamps) + 1.01 * dt
    off = np.flatnonzero(np.abs(stamps - t) > tol)
    if off.size:
        i = int(off[0])
        raise _fail(
            path,
            f"time stamp {stamps[i]:g} s is off the uniform grid ({t[i]:.4g} s at "
            f"step {dt:.5g} s): a gap or a time jump",
            row=row_of[i],
            column=_MARIN_FIELDS[0],
        )
    return t, dt


def _fuse_heading(psi, r, t, tau):
    """Causal complementary filter of a coarsely rounded heading with the integral of the yaw
    rate (see :func:`read_simman_marin`): psi, r (rad, rad/s), t (s), all (n,); tau (s)."""
    out = np.empty_like(psi)
    out[0] = psi[0]
    for k in range(1, psi.size):
        dt = t[k] - t[k - 1]
        q = out[k - 1] + 0.5 * dt * (r[k - 1] + r[k])
        out[k] = q + dt / (tau + dt) * (psi[k] - q)
    return out


def read_simman_marin(path, scale: float = KVLCC2_SCALE, heading_tau_s: float | None = 20.0) -> Track:
    """Read one KVLCC2 MARIN free-running file (SIMMAN 2008, ``MARIN_FREE_KVLCC2_*_m.dat``),
    Froude-scaled to model scale.

    Parameters
    ----------
    path : str or os.PathLike
        Text: up to 5 title lines (e.g. ``Turning / Pull-out manoeuvring for KVLCC2 : 35 (deg)``),
        then 11 tab- or space-separated numbers per line (3 significant digits), at **full
        scale**: t (s), x0, y0 (m, earth-fixed, y to starboard), phi, psi (deg), dx0/dt,
        dy0/dt (m/s, earth-fixed), p, r (deg/s), delta (deg, + to port: gives r < 0), n (rpm).
    scale : float
        Froude scale ``lambda`` applied to reach the model (default :data:`KVLCC2_SCALE`, the
        1:45.714 of the 7 m SIMMAN models, so the track matches ``kvlcc2_7m``); 1 keeps full
        scale. Lengths / lambda, times and velocities / sqrt(lambda), rates and rpm *
        sqrt(lambda), angles unchanged (Froude similarity; ITTC 7.5-02-06-01).
    heading_tau_s : float or None
        Time constant (s, full scale) of the causal complementary filter that fuses the
        file's heading (3 significant digits: 1 deg steps past 100 deg) with the integral of its
        yaw rate (0.1-1 % resolution): ``psi_f[k] = q + a (psi[k] - q)`` with
        ``q = psi_f[k-1] + dt (r[k-1] + r[k]) / 2`` and ``a = dt / (tau + dt)``. The heading's
        rounding (up to 0.5 deg, a sawtooth during a turn) drops to about 0.05 deg; a rate
        rounding of ``e`` deg/s leaves an offset of at most ``e tau``. The filter uses no future
        sample, so a window's start state stays causal. None keeps the heading as in the file.

    Returns
    -------
    Track
        ``t`` (s; rebuilt on a uniform grid, see Notes), ``x``, ``y`` (m), ``phi``, ``psi`` (rad,
        psi unwrapped), ``u``, ``v`` (m/s, body frame: the earth-frame velocities rotated by
        psi; over ground, a tank has no current), ``p``, ``r`` (rad/s), ``delta_r`` (rad, sign
        unchanged), ``n`` (rpm); exogenous ``x_dot``, ``y_dot`` (m/s, as in the file, scaled).
        ``psi_file`` (rad, the file's heading unwrapped, when ``heading_tau_s`` fuses ``psi``).
        ``meta["scale"]`` holds ``scale``, ``meta["manoeuvre"]`` the title.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If ``scale`` is not a positive finite number, or ``heading_tau_s`` neither None nor a
        positive finite number.
    DatasetFormatError
        Naming file, row (line number) and column (``col k (...)``): no data rows; a row
        without 11 fields; a non-numeric or overflowing value; a time stamp that is missing,
        decreases or is off the uniform grid.

    Notes
    -----
    The stamps carry 3 significant digits, so after 100 s several rows share a stamp; the time
    base is ``t0 + k dt`` with ``dt`` fitted to all stamps (0.1352 s full scale, i.e. 50 Hz at
    model scale), checked against every stamp. Positions also carry 3 significant digits
    (about 10 m full scale, 0.2 m model scale, once |x| > 1000 m): kept as measured. So does the
    unwrapped heading in degrees (1 deg steps past 100 deg); rotating the earth-frame velocities
    by that heading would put up to ``U sin(0.5 deg)`` (0.01 m/s at model scale) into ``v``, so
    ``psi`` (and hence ``u``, ``v``) uses the fused heading unless ``heading_tau_s`` is None.
    Format: ``shared/research/real-data-sources.md`` section 2.3.
    """
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive number (Froude scale lambda), got {scale!r}")
    if heading_tau_s is not None and not (
        isinstance(heading_tau_s, (int, float)) and math.isfinite(heading_tau_s) and heading_tau_s > 0
    ):
        raise ValueError(f"heading_tau_s must be None or a positive number of seconds, got {heading_tau_s!r}")
    lines = _read_lines(path, "cp1252")
    head = 0
    while head < min(len(lines), _MARIN_MAX_HEADER):
        first = lines[head].split()
        if first and _NUMBER.fullmatch(first[0]):
            break
        head += 1
    title = next((ln.strip() for ln in lines[1:head] if ln.strip()), lines[0].strip() if head else "")
    a, row_of, notes = _whitespace_table(path, lines, head, _MARIN_FIELDS, "title lines")
    t_full, dt = _marin_time(path, a[:, 0], row_of)
    sq = math.sqrt(scale)
    psi_file = _unwrap(np.radians(a[:, 4]))
    psi = (
        psi_file
        if heading_tau_s is None
        else _fuse_heading(psi_file, np.radians(a[:, 8]), t_full, float(heading_tau_s))
    )
    xd, yd = a[:, 5] / sq, a[:, 6] / sq
    c, s = np.cos(psi), np.sin(psi)
    data = {
        "x": a[:, 1] / scale,
        "y": a[:, 2] / scale,
        "phi": np.radians(a[:, 3]),
        "psi": psi,
        "u": c * xd + s * yd,
        "v": -s * xd + c * yd,
        "p": np.radians(a[:, 7]) * sq,
        "r": np.radians(a[:, 8]) * sq,
        "delta_r": np.radians(a[:, 9]),
        "n": a[:, 10] * sq,
        "x_dot": xd,
        "y_dot": yd,
    }
    units = {"x_dot": "m/s", "y_dot": "m/s"}
    if heading_tau_s is not None:
        data["psi_file"], units["psi_file"] = psi_file, "rad"
    conversions = [
        f"Froude scale lambda = {scale:g}: x, y / lambda; t, velocities / sqrt(lambda); p, r, n * sqrt(lambda)",
        "t rebuilt as t0 + k dt (dt fitted to the 3-digit stamps" + (f": {dt:.6g} s full scale)" if dt else ")"),
        "phi, psi [rad] = radians(cols 3, 4 [deg]) (psi unwrapped)"
        + (
            ""
            if heading_tau_s is None
            else f"; psi fused with the integral of r (causal complementary filter, tau {heading_tau_s:g} s full "
            "scale; the file's heading kept as psi_file)"
        ),
        "u, v = earth-frame (col 5, col 6) rotated into the body frame by psi",
        "p, r [rad/s] = radians(cols 7, 8 [deg/s])",
        "delta_r [rad] = radians(col 9 [deg]) (sign unchanged: + = to port, gives r < 0)",
        "n [rpm] = col 10 [rpm]",
    ]
    notes.append(
        "positions, heading and stamps carry 3 significant digits (positions quantised to "
        f"{10.0 / scale:.3g} m once |x| > 1000 m full scale; heading to 1 deg past 100 deg)"
    )
    track = _build(
        path,
        "simman-marin",
        t_full / sq,
        data,
        units,
        _MARIN_VESSEL,
        _MARIN_REFERENCE,
        conversions,
        notes,
        manoeuvre=title,
    )
    track.meta["scale"] = float(scale)
    return track


# --------------------------------------------------------------------------- dispatch, listing

_READERS = {"esso-osaka": read_esso_osaka, "simman-hsva": read_simman_hsva, "simman-marin": read_simman_marin}


def _check_format(format):
    if format not in _READERS:
        raise ValueError(f"unknown format {format!r}; choose one of {list(FORMATS)}")


def read_run(path, format: str, **options) -> Track:
    """Read one run file of a third-party data set.

    Parameters
    ----------
    path : str or os.PathLike
        The run file.
    format : {"esso-osaka", "simman-hsva", "simman-marin"}
        See :data:`FORMATS`; dispatches to :func:`read_esso_osaka`,
        :func:`read_simman_hsva` or :func:`read_simman_marin`.
    **options
        Passed to the reader (``scale`` for ``"simman-marin"``).

    Returns
    -------
    Track
        In the package contract (SI, rad, rpm, ``delta_r`` + = to port).

    Raises
    ------
    ValueError
        Unknown ``format``.
    FileNotFoundError
        If ``path`` does not exist.
    DatasetFormatError
        As raised by the reader (names file, row, column).
    """
    _check_format(format)
    return _READERS[format](path, **options)


def _is_run_file(path: Path, format: str) -> bool:
    """Cheap content sniff: does this file look like a run of ``format``?"""
    if format == "esso-osaka":
        if path.suffix.lower() != ".csv":
            return False
        try:
            with open(path, encoding="utf-8-sig", errors="replace") as f:
                for line in f:
                    if line.strip():
                        return "x_position_mid" in line
        except OSError:
            return False
        return False
    if path.suffix.lower() != ".dat":
        return False
    # both basins write .dat files: MARIN's first line names MARIN, HSVA's names HSVA
    return _is_marin(path) == (format == "simman-marin")


def _is_marin(path: Path) -> bool:
    try:
        with open(path, encoding="cp1252", errors="replace") as f:
            return f.readline().strip().upper().startswith("MARIN")
    except OSError:
        return False


def _data_text(path: Path, format: str) -> str:
    """The data rows of a run file (header and empty rows removed), for duplicate checks."""
    enc = "utf-8-sig" if format == "esso-osaka" else "cp1252"
    with open(path, encoding=enc, errors="replace", newline="") as f:
        lines = f.read().splitlines()
    if format == "esso-osaka":
        first = next((i for i, ln in enumerate(lines) if ln.strip()), len(lines))
        body = lines[first + 1 :]
        blank = ", \t"
    elif format == "simman-marin":
        first = next((i for i, ln in enumerate(lines) if ln.split() and _NUMBER.fullmatch(ln.split()[0])), len(lines))
        body = lines[first:]
        blank = " \t"
    else:
        body = lines[_HSVA_HEADER_LINES:]
        blank = " \t"
    return "".join(ln + "\n" for ln in body if ln.strip(blank))


def scan_runs(root, format):
    """The run files of a data set folder and the files left out, for :func:`list_runs` and the CLI.

    Parameters
    ----------
    root : str or os.PathLike
        A data set folder, or a single run file.
    format : {"esso-osaka", "simman-hsva", "simman-marin"}
        The data set's format (:func:`list_runs` says which files are runs of it).

    Returns
    -------
    kept : list of pathlib.Path
        The run files, sorted.
    skipped : list of tuple
        ``(path, reason)`` of each duplicate or trimmed copy left out.

    Raises
    ------
    ValueError
        Unknown ``format``.
    FileNotFoundError
        If ``root`` does not exist.
    """
    _check_format(format)
    root = Path(root)
    if not root.exists():
        raise FileNotFoundError(f"{root}: no such file or folder")
    if root.is_file():
        return [root], []
    skip_dirs = {"aux", "mmg_params"}
    candidates = sorted(
        p
        for p in root.rglob("*")
        if p.is_file()
        and not any(part.lower() in skip_dirs or part.startswith(".") for part in p.relative_to(root).parts[:-1])
        and _is_run_file(p, format)
    )
    # Duplicate / trimmed copies: within one folder, a file whose data rows
    # are one contiguous block of another file's data rows is dropped; the
    # longer file is kept (ties: the name that sorts first).
    texts = {p: _data_text(p, format) for p in candidates}
    kept, skipped = [], []
    by_dir: dict[Path, list[Path]] = {}
    for p in candidates:
        by_dir.setdefault(p.parent, []).append(p)
    for group in by_dir.values():
        order = sorted(group, key=lambda p: (-len(texts[p]), p.name))
        chosen: list[Path] = []
        for p in order:
            text = texts[p]
            first_row = text.split("\n", 1)[0]
            host = next((q for q in chosen if text and first_row in texts[q] and "\n" + text in "\n" + texts[q]), None)
            if host is None:
                chosen.append(p)
            else:
                what = "an exact copy" if text == texts[host] else "a trimmed copy"
                skipped.append(
                    (
                        p,
                        f"{what} of {host.name} (its data rows are a contiguous "
                        f"block of that file's rows); kept {host.name}",
                    )
                )
        kept.extend(chosen)
    return sorted(kept), skipped


def list_runs(root, format) -> list[Path]:
    """The run files of a data set folder, searched recursively.

    Parameters
    ----------
    root : str or os.PathLike
        A data set folder (e.g. ``shared/data/real/esso-osaka-frt``), or a
        single run file (returned as is).
    format : {"esso-osaka", "simman-hsva", "simman-marin"}
        ``"esso-osaka"``: ``*.csv`` files whose header row has
        ``x_position_mid`` (so ``mmg_params/*.csv`` and READMEs are
        skipped).  ``"simman-hsva"`` / ``"simman-marin"``: ``*.dat`` files
        whose first line does not / does name MARIN.  Folders named
        ``aux`` or ``mmg_params`` and hidden folders are not searched.

    Returns
    -------
    list of pathlib.Path
        Sorted.  Duplicate rule: within one folder, a file whose data rows
        (empty rows ignored) form one contiguous block of another file's data
        rows is a trimmed (or exact) copy of the same run and is left out;
        the longer file is kept, so no sample is lost (ties: the name that
        sorts first).  In the Esso set this drops
        ``turning/turn_cut_14-Sep-2020_15_58_08.csv`` (the first 2869 rows of
        ``turn_14-Sep-2020_15_58_08.csv``); ``turn_cut_14-Sep-2020_16_09_02.csv``
        has no full copy and is kept.

    Raises
    ------
    ValueError
        Unknown ``format``.
    FileNotFoundError
        If ``root`` does not exist.
    """
    return scan_runs(root, format)[0]
