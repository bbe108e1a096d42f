"""Report layer: what the commands and the study scripts write; algorithm modules write no files
of their own.

* :mod:`~bayesid.report.study` -- the study contract: output folder, JSON files,
  ``manifest.json`` (command line, seed, git commit, package versions, wall time, quick or full).
* :mod:`~bayesid.report.markdown` -- markdown tables and the compact number format.
* :mod:`~bayesid.report.diagnosis` -- the report of a gap diagnosis (``bayesid diagnose``).
* :mod:`~bayesid.report.fit`, :mod:`~bayesid.report.sample` -- the reports of ``bayesid fit``
  and ``bayesid sample``.
* :mod:`~bayesid.report.plots` -- the figures.

The names below are importable from ``bayesid.report`` itself.
"""

from __future__ import annotations

from .diagnosis import attribution_lines, write_diagnosis
from .fit import write_fit_report
from .markdown import fmt, md_table
from .sample import write_sample_report
from .study import PACKAGES, git_commit, prepare_out, write_json, write_manifest

__all__ = [
    "PACKAGES",
    "attribution_lines",
    "fmt",
    "git_commit",
    "md_table",
    "prepare_out",
    "write_diagnosis",
    "write_fit_report",
    "write_json",
    "write_manifest",
    "write_sample_report",
]
