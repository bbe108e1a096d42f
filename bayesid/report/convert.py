"""The summary of ``bayesid convert``: ``convert.json`` and ``convert.md`` beside the converted
Track CSVs."""

from __future__ import annotations

import json
from pathlib import Path


def write_convert_report(summary: dict, out) -> None:
    """Write ``convert.json`` and ``convert.md`` of ``bayesid convert``.

    Parameters
    ----------
    summary : dict
        What was converted: ``format``, ``runs`` (each with its ``output`` file, ``n_samples``,
        ``duration_s``, ``sample_rate_hz`` and ``notes``) and ``skipped`` (``source``, ``reason``).
    out : str or Path
        The folder of the converted files (it exists).
    """
    out = Path(out)
    runs, skipped = summary["runs"], summary["skipped"]
    (out / "convert.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    lines = [
        f"# bayesid convert --format {summary['format']}",
        "",
        f"{len(runs)} run(s) converted to Track CSVs (SI, rad, rpm; rudder + = to port).",
        "",
        "| output | samples | duration (s) | rate (Hz) | notes |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| {Path(r['output']).name} | {r['n_samples']} | {r['duration_s']:.1f} | "
        f"{r['sample_rate_hz']} | {'; '.join(r['notes']) or '-'} |"
        for r in runs
    ]
    if skipped:
        lines += ["", "Skipped:", *[f"- {s['source']}: {s['reason']}" for s in skipped]]
    (out / "convert.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
