"""Measured manoeuvring tracks and their CSV file format.

A *track file* is a CSV file with one row per sample and a header row, in SI
units with angles in radians:

* ``t`` (s), strictly increasing;
* states, any subset that was measured: ``x, y, z`` (earth-fixed NED position,
  m), ``phi, theta, psi`` (zyx Euler angles, rad), ``u, v, w`` (body-fixed
  velocities, m/s), ``p, q, r`` (body-fixed rates, rad/s);
* inputs: ``delta_r, delta_s, delta_b`` (rudder, stern and bow plane angles,
  rad) and ``n`` (propeller shaft speed, rpm);
* any other column is an exogenous signal kept by name; measured wind is
  ``wind_speed`` (true wind speed, m/s) and ``wind_dir`` (direction the true
  wind comes *from*, rad, earth frame, measured like ``psi``).

Missing values are empty fields (NaN in memory).  A header may carry a unit
annotation, ``psi [rad]`` or ``x (m)``; for the columns above it must be the
unit listed in :data:`UNITS`, for other columns any unit is kept in
``Track.units``.  Lines starting with ``#`` before the header are comments,
kept in ``Track.meta["comments"]``.  A comment ``# rudder positive: starboard``
declares a log in the other rudder sign convention (+ = to starboard, as in MMG
papers): ``delta_r`` is negated on reading into the package's (SNAME: + = to
port) and the comment rewritten to ``rudder positive: port (...)``, so that a
written copy is not negated twice.  A heading logged wrapped, as a compass logs
it ((-pi, pi] or [0, 2 pi)), is unwrapped on reading (:func:`unwrap_heading`;
the number of wraps in ``Track.meta["psi_wraps"]`` and a comment line), and a
jump of more than pi that is not a wrap is refused, naming ``psi`` and the time.
Floats are written with ``repr`` so that :func:`write_csv` followed by
:func:`read_csv` reproduces every value bit-for-bit (a continuous heading).
"""

from __future__ import annotations

import copy
import csv
import itertools
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "STATE_NAMES",
    "INPUT_NAMES",
    "UNITS",
    "TrackFormatError",
    "Track",
    "read_csv",
    "write_csv",
    "continuous_pieces",
    "unwrap_heading",
    "HeadingJumpError",
    "WRAP_LIMIT",
]

STATE_NAMES = ("x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r")
"""State column names; index order is the simulator state order."""

INPUT_NAMES = ("delta_r", "delta_s", "delta_b", "n")
"""Input column names, in the order of :meth:`Track.inputs`."""

UNITS: dict[str, str] = {
    "t": "s",
    "x": "m",
    "y": "m",
    "z": "m",
    "phi": "rad",
    "theta": "rad",
    "psi": "rad",
    "u": "m/s",
    "v": "m/s",
    "w": "m/s",
    "p": "rad/s",
    "q": "rad/s",
    "r": "rad/s",
    "delta_r": "rad",
    "delta_s": "rad",
    "delta_b": "rad",
    "n": "rpm",
    "wind_speed": "m/s",
    "wind_dir": "rad",
}
"""Contract unit of every named column; a header annotation must match it."""

_ROLE_NAMES = frozenset(STATE_NAMES) | frozenset(INPUT_NAMES)
# Plain decimal literal (ASCII digits only): no inf/nan, no "1_000", no hex.
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
# "name", "name [unit]" or "name (unit)".
_HEADER = re.compile(r"(?P<name>[^\[\]()]*?)\s*(?:\[(?P<u1>[^\[\]]*)\]|\((?P<u2>[^()]*)\))?")


class TrackFormatError(ValueError):
    """A track file breaks the format.

    The message names the file, and where applicable the row (1-based line
    number in the file) and the column; these are also available as the
    attributes ``path``, ``row`` and ``column`` (None when not applicable).

    Parameters
    ----------
    message : str
        The full message (file, row and column included, see :func:`format_error`).
    path : str, optional
        The file.
    row : int, optional
        1-based line number in the file.
    column : str, optional
        The column name.
    """

    def __init__(self, message, path=None, row=None, column=None):
        super().__init__(message)
        self.path, self.row, self.column = path, row, column


def format_error(path, message, row=None, column=None, error=None):
    """The error (``error`` class, default :class:`TrackFormatError`) naming file, row, column.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    message : str
        What is wrong; prefixed with ``"<path>: row <row>, column '<column>': "``.
    row : int, optional
        1-based line number in the file.
    column : str, optional
        The column name.
    error : type, optional
        Exception class, called as ``error(text, path=, row=, column=)``; default
        :class:`TrackFormatError`.

    Returns
    -------
    Exception
        The error, not raised.
    """
    where = str(path)
    if row is not None:
        where += f": row {row}"
    if column is not None:
        where += f", column '{column}'"
    return (error or TrackFormatError)(f"{where}: {message}", path=str(path), row=row, column=column)


@dataclass(eq=False, repr=False)
class Track:
    """One measured (or simulated) track: time base plus named columns.

    Arrays are copied to float64 on construction.

    Parameters
    ----------
    t : array_like, shape (n_samples,)
        Sample times, s; finite and strictly increasing.
    data : dict of str to array_like, each shape (n_samples,)
        Column name -> values in the contract units of :data:`UNITS`
        (NaN = missing, infinities are rejected).  Never contains ``"t"``.
        Column roles follow from the names: :data:`STATE_NAMES`,
        :data:`INPUT_NAMES`, anything else is exogenous.
    name : str
        Track name (the file stem when read from a file).
    units : dict of str to str
        Units of exogenous columns without a contract unit (e.g. from a
        header ``"rpm_aux [Hz]"``).
    meta : dict
        Free-form metadata; ``meta["comments"]`` (list of str) is written to
        and read from ``#`` lines in the file.

    Raises
    ------
    ValueError
        Naming the offending column: ``t`` not 1-D, not finite or not
        strictly increasing; a data column not 1-D, of the wrong length,
        containing infinities or named ``"t"``; a unit given for a column
        that is absent or has a contract unit.
    """

    t: np.ndarray
    data: dict[str, np.ndarray]
    name: str = ""
    units: dict[str, str] = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        label = f"track {self.name!r}"
        try:
            t = np.array(self.t, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{label}: column 't' is not numeric: {exc}") from None
        if t.ndim != 1:
            raise ValueError(f"{label}: column 't' must be 1-D, got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            i = int(np.flatnonzero(~np.isfinite(t))[0])
            raise ValueError(f"{label}: column 't' has non-finite value {t[i]} at index {i}")
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            i = int(bad[0]) + 1
            raise ValueError(f"{label}: column 't' is not strictly increasing at index {i} ({t[i - 1]!r} -> {t[i]!r})")
        data = {}
        for key, values in dict(self.data).items():
            if not isinstance(key, str) or not key:
                raise ValueError(f"{label}: column name must be a non-empty str, got {key!r}")
            if key == "t":
                raise ValueError(f"{label}: column 't' must be passed as `t`, not in `data`")
            try:
                col = np.array(values, dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"{label}: column '{key}' is not numeric: {exc}") from None
            if col.shape != t.shape:
                raise ValueError(f"{label}: column '{key}' has shape {col.shape}, expected {t.shape} like 't'")
            if np.any(np.isinf(col)):
                raise ValueError(f"{label}: column '{key}' contains infinite values (use NaN for missing)")
            data[key] = col
        units = dict(self.units)
        for key, unit in units.items():
            if key not in data:
                raise ValueError(f"{label}: unit given for column '{key}' which is not in the track")
            if key in UNITS:
                raise ValueError(
                    f"{label}: column '{key}' has the contract unit {UNITS[key]!r}; do not list it in `units`"
                )
            if not isinstance(unit, str) or not unit:
                raise ValueError(f"{label}: unit of column '{key}' must be a non-empty str")
        self.t, self.data, self.units = t, data, units

    def __repr__(self):
        span = f"t=[{self.t[0]:g}, {self.t[-1]:g}] s" if self.n_samples else "empty"
        return (
            f"Track(name={self.name!r}, n_samples={self.n_samples}, {span}, "
            f"states={self.state_columns}, inputs={self.input_columns}, "
            f"exogenous={self.exogenous_columns})"
        )

    @property
    def n_samples(self) -> int:
        """Number of samples (rows)."""
        return int(self.t.shape[0])

    @property
    def state_columns(self) -> list[str]:
        """Measured states present, in :data:`STATE_NAMES` order."""
        return [k for k in STATE_NAMES if k in self.data]

    @property
    def input_columns(self) -> list[str]:
        """Inputs present, in :data:`INPUT_NAMES` order."""
        return [k for k in INPUT_NAMES if k in self.data]

    @property
    def exogenous_columns(self) -> list[str]:
        """All other columns (wind, extra signals), in insertion order."""
        return [k for k in self.data if k not in _ROLE_NAMES]

    def __getitem__(self, name: str) -> np.ndarray:
        """Column ``name`` (or ``"t"``), shape (n_samples,); KeyError if absent."""
        if name == "t":
            return self.t
        try:
            return self.data[name]
        except KeyError:
            raise KeyError(f"track {self.name!r} has no column {name!r}; available: {['t', *self.data]}") from None

    def __contains__(self, name) -> bool:
        return name == "t" or name in self.data

    def states(self, names=None) -> np.ndarray:
        """Stacked state columns.

        Parameters
        ----------
        names : sequence of str, optional
            Columns to stack; default :attr:`state_columns`.

        Returns
        -------
        ndarray, shape (n_samples, len(names))
            The columns side by side (an empty (n_samples, 0) array when there are none).

        Raises
        ------
        KeyError
            If a requested column is absent.
        """
        names = self.state_columns if names is None else list(names)
        if not names:
            return np.empty((self.n_samples, 0))
        return np.column_stack([self[k] for k in names])

    def inputs(self, fill=None) -> np.ndarray:
        """Inputs in :data:`INPUT_NAMES` order (rad, rad, rad, rpm).

        Parameters
        ----------
        fill : float, optional
            Value for absent input columns (e.g. ``0.0``).  If None, an
            absent input raises.

        Returns
        -------
        ndarray, shape (n_samples, 4)
            The input columns, absent ones filled with ``fill``.

        Raises
        ------
        KeyError
            If ``fill`` is None and an input column is absent; names the
            track and the missing inputs.
        """
        missing = [k for k in INPUT_NAMES if k not in self.data]
        if missing and fill is None:
            raise KeyError(f"track {self.name!r} has no input column(s) {missing}; pass fill=<value> to fill them")
        out = np.empty((self.n_samples, len(INPUT_NAMES)))
        for j, k in enumerate(INPUT_NAMES):
            out[:, j] = self.data[k] if k in self.data else fill
        return out

    def with_columns(self, **cols) -> Track:
        """Copy with columns added or replaced (units of replaced columns kept).

        Parameters
        ----------
        **cols : array_like, each shape (n_samples,)
            Columns by name, in the contract units of :data:`UNITS`.

        Returns
        -------
        Track
            The new track (name, units and a deep copy of ``meta`` kept).

        Raises
        ------
        ValueError
            As in construction (wrong length, infinities, ``t`` given).
        """
        return Track(self.t, {**self.data, **cols}, name=self.name, units=self.units, meta=copy.deepcopy(self.meta))

    def slice_time(self, t0: float, t1: float) -> Track:
        """Copy with the samples where ``t0 <= t <= t1`` (s); may be empty.

        Parameters
        ----------
        t0 : float
            First time kept, s.
        t1 : float
            Last time kept, s.

        Returns
        -------
        Track
            The new track (name, units and a deep copy of ``meta`` kept).

        Raises
        ------
        ValueError
            If ``t0 > t1``.
        """
        if t0 > t1:
            raise ValueError(f"slice_time: t0={t0!r} > t1={t1!r}")
        keep = (self.t >= t0) & (self.t <= t1)
        return Track(
            self.t[keep],
            {k: v[keep] for k, v in self.data.items()},
            name=self.name,
            units=self.units,
            meta=copy.deepcopy(self.meta),
        )

    @classmethod
    def from_arrays(cls, t, states=None, inputs=None, name="", **exogenous) -> Track:
        """Build a track from arrays.

        Parameters
        ----------
        t : array_like, shape (n,)
            Times, s.
        states : dict of str to array_like, or array_like of shape (n, 12), optional
            A dict keyed by (a subset of) :data:`STATE_NAMES`, or all twelve
            states as columns in :data:`STATE_NAMES` order.
        inputs : dict of str to array_like, or array_like of shape (n, 4), optional
            A dict keyed by (a subset of) :data:`INPUT_NAMES`, or all four
            inputs as columns in :data:`INPUT_NAMES` order.
        name : str, default ""
            Track name.
        **exogenous : array_like, each shape (n,)
            Other columns, e.g. ``wind_speed=..., wind_dir=...``.

        Returns
        -------
        Track
            The new track.

        Raises
        ------
        ValueError
            Wrong array shape, a dict key that is not a state/input name, an
            exogenous keyword that is a state/input name, or any
            construction error.
        """
        data = {}
        for arg, names in (("states", STATE_NAMES), ("inputs", INPUT_NAMES)):
            given = states if arg == "states" else inputs
            if given is None:
                continue
            if isinstance(given, dict):
                unknown = [k for k in given if k not in names]
                if unknown:
                    raise ValueError(f"from_arrays: {arg} has unknown name(s) {unknown}; allowed: {list(names)}")
                data.update({k: given[k] for k in names if k in given})
            else:
                arr = np.asarray(given, dtype=np.float64)
                if arr.ndim != 2 or arr.shape[1] != len(names):
                    raise ValueError(f"from_arrays: {arg} array must have shape (n, {len(names)}), got {arr.shape}")
                data.update({k: arr[:, j] for j, k in enumerate(names)})
        clash = [k for k in exogenous if k in _ROLE_NAMES]
        if clash:
            raise ValueError(f"from_arrays: {clash} are state/input names; pass them via states=/inputs=")
        data.update(exogenous)
        return cls(t, data, name=name)


def _parse_header(path, cells, row):
    """Header cells -> (names, units of non-contract columns)."""
    names, units = [], {}
    for cell in cells:
        m = _HEADER.fullmatch(cell.strip())
        if m is None or not m["name"]:
            raise format_error(
                path,
                f"malformed column header {cell.strip()!r} (expected 'name', 'name [unit]' or 'name (unit)')",
                row=row,
            )
        name = m["name"]
        unit = m["u1"] if m["u1"] is not None else m["u2"]
        if name in names:
            raise format_error(path, "duplicate column name", row=row, column=name)
        if unit is not None:
            unit = unit.strip()
            if name in UNITS:
                if unit != UNITS[name]:
                    raise format_error(
                        path, f"unknown unit {unit!r}; this column must be in {UNITS[name]!r}", row=row, column=name
                    )
            elif not unit:
                raise format_error(path, "empty unit annotation", row=row, column=name)
            else:
                units[name] = unit
        names.append(name)
    if "t" not in names:
        sep = next((c for c in (";", "\t", "|") if len(names) == 1 and c in names[0]), None)
        hint = f": the header looks {sep!r}-separated; track files are comma-separated" if sep else ""
        raise format_error(path, f"no 't' column (columns: {names}){hint}", row=row, column="t")
    if not any(k in STATE_NAMES for k in names):
        raise format_error(
            path, f"no state column; need at least one of {list(STATE_NAMES)} (columns: {names})", row=row
        )
    return names, units


def _parse_value(path, text, row, column):
    text = text.strip()
    if not text:
        return math.nan
    if not _NUMBER.fullmatch(text):
        raise format_error(
            path, f"non-numeric value {text!r} (leave the field empty if missing)", row=row, column=column
        )
    value = float(text)
    if not math.isfinite(value):
        raise format_error(path, f"value {text!r} overflows float64", row=row, column=column)
    return value


_CHUNK_ROWS = 65536
"""Rows converted per block by :func:`read_csv` (bounds its memory to the arrays)."""


# Characters a plain decimal literal may contain (float() accepts more:
# "inf", "nan", "1_000", non-ASCII digits; each of those has another character).
_NOT_NUMERIC = re.compile(r"[^0-9eE+\-.\s]")


def _block_values(cells: tuple) -> np.ndarray | None:
    """Cells of one column -> float64 (NaN where empty), or None if any cell is invalid.

    Fast path of :func:`_parse_value` for a block; the caller re-reads a block
    that returns None row by row to name the first bad cell.
    """
    if _NOT_NUMERIC.search(" ".join(cells)):
        return None
    try:
        values = np.fromiter(map(float, cells), dtype=np.float64, count=len(cells))
    except ValueError:  # empty cells (or a malformed literal such as "1e" or "--1")
        try:
            values = np.fromiter(
                (float(c) if c and not c.isspace() else math.nan for c in cells), dtype=np.float64, count=len(cells)
            )
        except ValueError:
            return None
    return None if np.isinf(values).any() else values


def _check_rows(path, names, it, block, rows, last):
    """Row-by-row check of one block: raises the first error in file order.

    ``last`` is (t, row) of the sample before the block or None.  Used when the
    vectorised check of a block failed, so that the error names the same row
    and column as reading the file one row at a time.
    """
    for cells, row in zip(block, rows):
        if len(cells) != len(names):
            raise format_error(path, f"has {len(cells)} fields, header has {len(names)}", row=row)
        t = _parse_value(path, cells[it], row, "t")
        if math.isnan(t):
            raise format_error(path, "missing time value", row=row, column="t")
        if last is not None and t <= last[0]:
            what = "duplicate" if t == last[0] else "decreasing"
            raise format_error(
                path,
                f"time not strictly increasing ({what}: {t!r} after {last[0]!r} at row {last[1]})",
                row=row,
                column="t",
            )
        last = (t, row)
        for k, cell in zip(names, cells):
            if k != "t":
                _parse_value(path, cell, row, k)
    raise AssertionError("block failed the vectorised check but no row error found")


def _convert_block(path, names, it, block, rows, last):
    """One block of rows -> list of float64 columns (header order), checked."""
    n_fields = len(names)
    if all(len(cells) == n_fields for cells in block):
        columns = [_block_values(cells) for cells in zip(*block)]
        if all(c is not None for c in columns):
            t = columns[it]
            previous = np.array([-np.inf if last is None else last[0]])
            if not np.isnan(t).any() and (np.diff(t, prepend=previous) > 0).all():
                return columns
    _check_rows(path, names, it, block, rows, last)


def read_csv(path) -> Track:
    """Read and check a track file.

    The file is streamed and converted in blocks of :data:`_CHUNK_ROWS` rows,
    so memory stays close to that of the resulting arrays (a 1e6-row,
    17-column file: about 0.3 GB) and time is linear in the rows.

    Parameters
    ----------
    path : str or os.PathLike
        UTF-8 CSV file in the format described in this module.

    Returns
    -------
    Track
        ``name`` is the file stem; ``units`` holds annotations of
        non-contract columns; ``meta["comments"]`` the ``#`` lines before
        the header (text after ``#`` and one optional space).

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    TrackFormatError
        Naming the file, row (1-based line number) and column where
        applicable: empty file or no data rows; malformed or duplicate
        header; unit other than the contract unit; no ``t`` column; no state
        column; row with the wrong number of fields; missing ``t`` value;
        non-increasing (incl. repeated) time; non-numeric value (incl.
        ``inf``/``nan`` strings); a value that overflows float64.
    """
    with open(path, newline="", encoding="utf-8-sig") as f:
        try:
            return _read_stream(path, f)
        except UnicodeDecodeError as exc:
            raise format_error(path, f"not UTF-8 text ({exc})") from None


def _read_stream(path, f) -> Track:
    comments, n_before = [], 0
    header_line = None
    for line in f:
        stripped = line.strip()
        if stripped.startswith("#"):
            text = line.lstrip()[1:].rstrip("\r\n")
            comments.append(text[1:] if text.startswith(" ") else text)
        elif stripped:
            header_line = line
            break
        n_before += 1
    if header_line is None:
        raise format_error(path, "empty file (no header row)")

    reader = csv.reader(itertools.chain([header_line], f))
    names = it = None
    blocks: list[list[np.ndarray]] = []
    block, rows, last = [], [], None
    first_row = last_row = None  # line numbers of the first and the last data row

    def flush():
        nonlocal block, rows, last
        columns = _convert_block(path, names, it, block, rows, last)
        last = (float(columns[it][-1]), rows[-1])
        blocks.append(columns)  # noqa: F821 - ruff reads the later `del blocks` as unbinding it here
        block, rows = [], []

    try:
        for cells in reader:
            row = n_before + reader.line_num
            if len(cells) <= 1 and not "".join(cells).strip():
                continue  # blank line
            if names is None:
                names, units = _parse_header(path, cells, row)
                it = names.index("t")
                continue
            block.append(cells)
            rows.append(row)
            first_row = row if first_row is None else first_row
            last_row = row
            if len(block) == _CHUNK_ROWS:
                flush()
        if block:
            flush()
    except csv.Error as exc:
        raise format_error(path, f"CSV syntax error: {exc}", row=n_before + reader.line_num) from None

    if names is None:
        raise format_error(path, "empty file (no header row)")
    if not blocks:
        raise format_error(path, "no data rows after the header", row=n_before + 1)
    columns = [np.concatenate(parts) for parts in zip(*blocks)]
    del blocks
    data = {k: c for k, c in zip(names, columns) if k != "t"}
    comments = _rudder_convention(path, comments, data, n_before)
    meta = {"comments": comments, "file_rows": (first_row, last_row)}
    if "psi" in data:
        try:
            data["psi"], wraps = unwrap_heading(data["psi"], columns[it])
        except HeadingJumpError as exc:
            raise format_error(path, f"{exc} (at t = {clock(columns[it][exc.index])} s)", column="psi") from None
        if wraps:
            meta["psi_wraps"] = wraps
            comments.append(
                f"psi unwrapped on reading: {wraps} wrap(s) of 2 pi (a heading logged in (-pi, pi] or [0, 2 pi))"
            )
    return Track(columns[it], data, name=Path(path).stem, units=units, meta=meta)


#: A heading whose finite values all lie within this of 0 (rad) may be wrapped (a compass's
#: (-pi, pi] or [0, 2 pi)); beyond it the values are unwrapped already, or degrees (refused by
#: :func:`bayesid.data.validate.check_track`).
WRAP_LIMIT = 2.0 * math.pi + 0.1


#: A heading step of more than pi that leaves more than pi/2 as a wrap is a jump, not a wrap, when
#: faster than this (rad/s).
MAX_TURN_RATE = 1.0


class HeadingJumpError(ValueError):
    """A heading jump that is not a wrap of 2 pi (:func:`unwrap_heading`).

    Parameters
    ----------
    message : str
        What jumped, by how much, in what time.
    index : int
        The sample after the jump (the attribute ``index``).
    """

    def __init__(self, message: str, index: int):
        super().__init__(message)
        self.index = index


def unwrap_heading(psi, t=None) -> tuple[np.ndarray, int]:
    """A heading logged wrapped, as a compass, INS or AHRS logs it ((-pi, pi] or [0, 2 pi)),
    made continuous: each step between finite samples of more than pi is taken as a wrap and
    2 pi k added from it on (:func:`numpy.unwrap`), NaN kept. A heading whose values pass
    :data:`WRAP_LIMIT` is returned as it is (unwrapped already, or degrees).

    Parameters
    ----------
    psi : array_like, shape (n,)
        Heading, rad.
    t : array_like, shape (n,), optional
        Sample times, s (None: one sample per second).

    Returns
    -------
    psi : ndarray, shape (n,)
        The continuous heading, rad (the input itself when nothing was wrapped).
    wraps : int
        How many steps were wraps.

    Raises
    ------
    HeadingJumpError
        A step between finite samples of more than pi (a wrap, were it one) that leaves more than
        pi/2 once unwrapped, at more than :data:`MAX_TURN_RATE`: a jump of the heading (no vessel
        turns a quarter circle at 1 rad/s), which unwrapping would misread; ``index`` names the
        sample after it. A long gap of a turning vessel is not refused, nor is a step of less than
        pi (no wrap is read into it: the track is as it was).
    """
    psi = np.asarray(psi, float)
    ok = np.flatnonzero(np.isfinite(psi))
    if ok.size < 2 or np.max(np.abs(psi[ok])) > WRAP_LIMIT:
        return psi, 0
    step = np.diff(psi[ok])
    left = np.abs(step - 2.0 * math.pi * np.round(step / (2.0 * math.pi)))
    dt = np.diff(np.arange(psi.size, dtype=float)[ok] if t is None else np.asarray(t, float)[ok])
    wrap = np.abs(step) > math.pi
    bad = np.flatnonzero(wrap & (left > 0.5 * math.pi) & (left > MAX_TURN_RATE * dt))
    if bad.size:
        k = int(bad[0])
        raise HeadingJumpError(
            f"the heading jumps by {step[k]:.4g} rad in {dt[k]:.3g} s ({left[k]:.3g} rad even as a wrap of 2 pi): "
            "a jump, not a turn or a wrap of a compass heading (a glitch, or a gap of a turning vessel): "
            "unwrapping would misread it; fill or cut it",
            int(ok[k + 1]),
        )
    if not wrap.any():
        return psi, 0
    out = psi.copy()
    out[ok] = np.unwrap(psi[ok])
    return out, int(wrap.sum())


_RUDDER_LINE = re.compile(r"\s*rudder\s+positive\s*[:=]\s*(\S*)(.*)", re.IGNORECASE)


def _rudder_convention(path, comments: list, data: dict, n_comments: int) -> list:
    """Apply a ``# rudder positive: port|starboard`` comment (module docstring): with
    ``starboard``, negate ``data["delta_r"]`` in place and return the comments with that line
    rewritten; raise a format error naming the row for any other word."""
    out = list(comments)
    for i, c in enumerate(comments):
        m = _RUDDER_LINE.match(str(c))
        if not m:
            continue
        word = m.group(1).lower().strip(",;.")
        if word == "port":
            return out
        if word != "starboard":
            raise format_error(path, f"'# rudder positive:' must say port or starboard, not {m.group(1)!r}", row=i + 1)
        if "delta_r" in data:
            data["delta_r"] = 0.0 - data["delta_r"]
        out[i] = "rudder positive: port (delta_r negated on reading; the file's + was to starboard)"
        return out
    return out


def _format(value: float) -> str:
    return "" if math.isnan(value) else repr(value)


def write_csv(track: Track, path) -> None:
    """Write a track file that :func:`read_csv` reads back bit-for-bit.

    Column order: ``t``, states (:data:`STATE_NAMES` order), inputs
    (:data:`INPUT_NAMES` order), exogenous (insertion order).  Headers are
    plain names, except non-contract columns with a unit, written
    ``name [unit]``.  ``track.meta["comments"]`` is written as ``# `` lines
    before the header; other ``meta`` entries are not written.

    Parameters
    ----------
    track : Track
        The track to write (re-validated first).
    path : str or os.PathLike
        Overwritten if it exists.

    Raises
    ------
    ValueError
        If the track could not be read back: no samples, no state column,
        a column name that does not survive the header syntax (e.g. with
        brackets, commas are fine), or invalid contents (re-validated).
    """
    track = Track(track.t, track.data, name=track.name, units=track.units, meta=track.meta)
    if track.n_samples == 0:
        raise ValueError(f"track {track.name!r} has no samples; cannot write {path}")
    if not track.state_columns:
        raise ValueError(f"track {track.name!r} has no state column; cannot write {path}")
    names = ["t", *track.state_columns, *track.input_columns, *track.exogenous_columns]
    header = [f"{k} [{track.units[k]}]" if k in track.units else k for k in names]
    for k, cell in zip(names, header):
        m = _HEADER.fullmatch(cell)
        ok = m is not None and m["name"] == k and (m["u1"] or "").strip() == track.units.get(k, "")
        if not ok or k != k.strip():
            raise ValueError(
                f"track {track.name!r}: column {k!r} (unit {track.units.get(k)!r}) cannot be written as a header"
            )
    comments = [line for c in track.meta.get("comments", []) for line in re.split(r"\r\n|\r|\n", str(c))]
    columns = [track[k] for k in names]
    with open(os.fspath(path), "w", newline="", encoding="utf-8") as f:
        for c in comments:
            f.write(f"# {c}\n")
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(header)
        for a in range(0, track.n_samples, _CHUNK_ROWS):  # in blocks: memory stays near the arrays'
            table = np.column_stack([c[a : a + _CHUNK_ROWS] for c in columns]).tolist()
            writer.writerows([_format(v) for v in row] for row in table)


def clock(t: float) -> str:
    """A time of a track as a message prints it.

    To 0.01 s whatever its size, so that a time on an epoch clock (about 1.8e9 s) reads as
    ``1795789708.3``, not ``1.8e+09`` (``:g`` prints two gaps a minute apart alike); a short clock
    as ``:g`` prints it (``52.3``).

    Parameters
    ----------
    t : float
        The time, s.

    Returns
    -------
    str
        The time without its unit.
    """
    t = float(t)
    if not np.isfinite(t) or abs(t) < 1e5:
        return f"{t:g}"
    return f"{t:.2f}".rstrip("0").rstrip(".")


def continuous_pieces(track: Track, min_gap_s: float = 0.0) -> list[tuple[float, float]]:
    """The continuous pieces of a track: runs of samples with finite x, y and psi, split where
    consecutive such samples are more than ``max(5 x the median sample interval, min_gap_s)``
    apart (a logging gap, or a stretch of empty cells).

    A logged input (``delta_r``, ``delta_s``, ``delta_b``, ``n``) with no value for longer than
    that and five of its own median intervals removes the samples in between (a piece never runs
    on a guessed input; shorter holes are held, zero-order).

    Parameters
    ----------
    track : Track
        The track.
    min_gap_s : float, default 0.0
        Smallest gap that splits the track, s.

    Returns
    -------
    list of tuple
        ``(first, last)`` sample times of each piece, s.

    Raises
    ------
    ValueError
        Naming the track and column when x, y or psi is absent or entirely empty, or when no
        row has all three.
    """
    t = np.asarray(track.t, float)
    ok = np.ones(t.size, bool)
    for k in ("x", "y", "psi"):
        if k not in track:
            raise ValueError(f"track {track.name!r} has no column {k!r}; the protocol needs x, y, psi")
        fin = np.isfinite(np.asarray(track[k], float))
        if not fin.any():
            raise ValueError(f"track {track.name!r}: column {k!r} is empty (no value in any row)")
        ok &= fin
    gap = max(5.0 * float(np.median(np.diff(t))) if t.size > 1 else 0.0, min_gap_s)
    # a logged input (rudder, propeller) missing for longer than five of its own sample intervals
    # is a hole too: the model would fly on a guessed input there (shorter stretches are held)
    for k in ("delta_r", "delta_s", "delta_b", "n"):
        if k not in track:
            continue
        fin = np.flatnonzero(np.isfinite(np.asarray(track[k], float)))
        if fin.size < 2:
            continue
        tk = t[fin]
        hole = np.flatnonzero(np.diff(tk) > max(gap, 5.0 * float(np.median(np.diff(tk)))) + 1e-9)
        for h in hole:
            ok[fin[h] + 1 : fin[h + 1]] = False
    tt = t[ok]
    if tt.size == 0:
        raise ValueError(f"track {track.name!r}: no row has x, y and psi all measured")
    cut = np.flatnonzero(np.diff(tt) > gap + 1e-9)
    lo = np.r_[0, cut + 1]
    hi = np.r_[cut, tt.size - 1]
    return [(float(tt[a]), float(tt[b])) for a, b in zip(lo, hi)]
