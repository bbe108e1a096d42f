"""Report layer: what the commands and the study scripts write; algorithm modules write no files
of their own.

* :mod:`~bayesid.report.study` -- the study contract: output folder, JSON files,
  ``manifest.json`` (command line, seed, git commit, package versions, wall time, quick or full).
* :mod:`~bayesid.report.markdown` -- markdown tables and the compact number format.
* :mod:`~bayesid.report.diagnosis` -- the report of a gap diagnosis (``bayesid diagnose``).
* :mod:`~bayesid.report.fit`, :mod:`~bayesid.report.predict`, :mod:`~bayesid.report.sample`,
  :mod:`~bayesid.report.convert` -- the reports of ``bayesid fit``, ``predict``, ``sample`` and
  ``convert``.
* :mod:`~bayesid.report.plots` -- the figures.

The names below are importable from ``bayesid.report`` itself.
"""

from __future__ import annotations

from .convert import write_convert_report
from .diagnosis import attribution_lines, write_diagnosis
from .fit import write_fit_report
from .markdown import fmt, md_table
from .predict import write_predict_report
from .sample import write_sample_report
from .study import PACKAGES, git_commit, prepare_out, write_json, write_manifest

__all__ = [
    "PACKAGES",
    "attribution_lines",
    "fmt",
    "git_commit",
    "md_table",
    "prepare_out",
    "write_convert_report",
    "write_diagnosis",
    "write_fit_report",
    "write_json",
    "write_manifest",
    "write_predict_report",
    "write_sample_report",
]
