"""Markdown tables and the compact number format of every report."""

from __future__ import annotations

import math
import re


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


def grouped_warnings(warnings: list) -> list:
    """Warnings as a reader sees them: one in full per kind (the same text but for the file before
    the first ``": "`` and the numbers), the other files of that kind named after it in one line.
    A check that fires on every file of a coarse log reads once, not once per file; the outputs'
    JSON keeps every warning.

    Parameters
    ----------
    warnings : list of str
        ``"<file>: <text>"`` each (:func:`bayesid.data.validate.check_track`).

    Returns
    -------
    list of str
        The first warning of each kind, each followed (when other files have it) by ``"the same
        for N more file(s), with their own numbers (in the outputs' warnings): a, b"``.
    """
    groups = {}
    for w in warnings:
        name, _, text = w.partition(": ")
        groups.setdefault(re.sub(r"\d+(\.\d+)?(e[-+]?\d+)?", "#", text), []).append((name, w))
    out = []
    for same in groups.values():
        out.append(same[0][1])
        if len(same) > 1:
            out.append(
                f"the same for {len(same) - 1} more file(s), with their own numbers (in the outputs' warnings): "
                + ", ".join(n for n, _ in same[1:])
            )
    return out


def warning_lines(warnings: list, title: str = "Input warnings") -> list:
    """A report's warnings section: a bold title and one bullet per :func:`grouped_warnings` line
    (nothing without warnings).

    Parameters
    ----------
    warnings : list of str
        The warnings.
    title : str, default "Input warnings"
        The section's title.

    Returns
    -------
    list of str
        Markdown lines, ending with a blank line; empty without warnings.
    """
    if not warnings:
        return []
    return [f"**{title}:**", "", *(f"- {w}" for w in grouped_warnings(warnings)), ""]
