"""A diagnosis as the report's section writers (:mod:`bayesid.report.diagnosis`) read it, built
from the few fields a test gives: every other field at the :class:`~bayesid.analysis.gap.Diagnosis`
dataclass's default (the thresholds at :class:`~bayesid.analysis.gap.verdict.Thresholds`'s, the
gap significant)."""

from __future__ import annotations

from dataclasses import MISSING, fields
from types import SimpleNamespace

from bayesid.analysis.gap import Diagnosis
from bayesid.analysis.gap.discovery import Discovery
from bayesid.analysis.gap.verdict import Thresholds
from bayesid.protocol import Scores


def diagnosis_view(**given) -> SimpleNamespace:
    """The fields ``given`` (``discovered``: the top-level list, as ``diagnosis.json`` names it)
    over the defaults; a field with no default and not given is absent (reading it fails)."""
    out = {"thresholds": Thresholds(), "significant_gap": True}
    for f in fields(Diagnosis):
        if f.default_factory is not MISSING:
            out[f.name] = f.default_factory()
        elif f.default is not MISSING:
            out[f.name] = f.default
    if "discovered" in given:
        given["discovered_terms"] = given.pop("discovered")
    return SimpleNamespace(**{**out, **given})


def scores(rms_position_m: float, **optional) -> Scores:
    """A stage's protocol scores with only the position RMS (m) a test sets, and its optional
    fields (``per_track_rms_position_m``, ``log_likelihood``)."""
    return Scores({}, float(rms_position_m), float("nan"), float("nan"), 0, **optional)


def discovery_view(**given) -> Discovery:
    """A structure discovery with the fields a test gives, every other one empty (no term found,
    nothing refitted, NaN errors)."""
    empty = dict(
        found=[],
        verdict="",
        discovered=[],
        inclusion={},
        residuals={},
        library_size=0,
        heldout_rms_before_m=float("nan"),
        heldout_rms_after_m=float("nan"),
        after_coefficients={},
        windows_before_m=[],
        windows_after_m=[],
        settings={},
        seconds=0.0,
    )
    return Discovery(**{**empty, **given})
