"""Markdown tables and the compact number format of every report."""

from __future__ import annotations

import math


def md_table(header, rows) -> str:
    """A markdown table.

    Parameters
    ----------
    header : list
        The column titles.
    rows : list of list
        The rows, values already formatted by the caller (written with ``str``).

    Returns
    -------
    str
        The table, one line per row, without a trailing newline.
    """
    lines = ["| " + " | ".join(str(h) for h in header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def fmt(x, digits: int = 3) -> str:
    """A number in the compact format of reports: ``1.23e-05``, ``0.123``, ``inf``.

    Parameters
    ----------
    x : float or None
        The number; None is written ``-``.
    digits : int
        Significant digits.

    Returns
    -------
    str
        ``x`` with ``digits`` significant digits, in exponent form outside [1e-3, 1e4).
    """
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    if x == 0:
        return "0"
    if 1e-3 <= abs(x) < 1e4:
        return f"{x:.{digits}g}"
    return f"{x:.{max(digits - 1, 1)}e}"
