"""A refit whose prediction diverges on a held-out run the reference predicts is worse there, not
scored on its other windows only (issue 49: the held-out scores pool finite samples, so a
diverged window simply dropped out and a term that blows up on the designed run could be kept)."""

from __future__ import annotations

import numpy as np
from diagnosis_view import scores

from bayesid.analysis.gap import discovery as dv
from bayesid.analysis.gap.candidates import Stage
from bayesid.analysis.gap.discovery.confirmation import decide, diverged_run, worst_run
from bayesid.analysis.gap.verdict import Thresholds

RUNS = np.repeat(np.arange(4), [5, 5, 5, 3])
NAMES = ["z10", "z20", "t15", "designed"]


def _stage(windows, held_rms_m=float("nan")):
    """A refit with held-out window errors ``windows`` (its pooled held-out RMS ``held_rms_m``)."""
    return Stage(None, None, scores(float("nan")), scores(held_rms_m), None, np.asarray(windows, float))


def _windows(rng, level=0.3):
    return level * np.exp(0.1 * rng.standard_normal(RUNS.size))


def test_the_run_a_prediction_diverges_on_is_named():
    rng = np.random.default_rng(1)
    ref, st = _windows(rng), _windows(rng)
    assert diverged_run(ref, st, RUNS) is None
    st[16:] = np.nan  # the last two windows of the designed run
    assert diverged_run(ref, st, RUNS) == 3
    ref[16:] = np.nan  # both diverge there: no evidence either way
    assert diverged_run(ref, st, RUNS) is None
    assert diverged_run(ref, st[:5], RUNS) is None  # other shapes: nothing said


def test_a_refit_that_diverges_on_a_held_out_run_fails_the_kept_test():
    rng = np.random.default_rng(2)
    ref = _windows(rng, 0.9)
    st = _windows(rng, 0.3)  # a third of the reference's errors on every window ...
    st[15:] = np.nan  # ... but its prediction of the designed run diverges
    worst = worst_run(_stage(ref), _stage(st), (RUNS, NAMES), 0.1)
    assert worst == {"run": "designed", "error_ratio": None, "p_value": 0.0, "diverged": True}
    row = {
        "term": "Yvvdr",
        "heldout_rms_before_m": 0.9,
        "heldout_rms_after_m": 0.3,
        "heldout_shrinkage": 2 / 3,
        "excess_removed": 0.9,
        "window_p_value": 1e-5,
        "delta_bic": -500.0,
        "worst_run": worst,
    }
    out = decide(dict(row), True, Thresholds())
    assert not out["kept"] and "run designed diverges" in out["reason"], out
    # the same numbers without the divergence: kept
    assert decide({**row, "worst_run": None}, True, Thresholds())["kept"]


def test_a_competitor_that_diverges_is_separated_and_a_kept_term_that_diverges_is_not_preferred():
    rng = np.random.default_rng(3)
    kept = _windows(rng)
    other = kept * np.exp(0.02 * rng.standard_normal(RUNS.size))  # a tie on every window ...
    gone = other.copy()
    gone[15:] = np.nan  # ... but diverging on the designed run
    rows = [
        {"term": "Nvvr", "kept": True, "heldout_rms_after_m": 0.3},
        {"term": "Nvabsvabsr", "kept": True, "heldout_rms_after_m": 0.3},
    ]
    th = Thresholds()
    tie = dv.compare_structures(["Nvvr"], rows, {"Nvvr": _stage(kept), "Nvabsvabsr": _stage(other)}, th, RUNS, NAMES)
    assert [a["term"] for a in dv.alternatives(tie)["Nvvr"]] == ["Nvabsvabsr"]
    sep = dv.compare_structures(["Nvvr"], rows, {"Nvvr": _stage(kept), "Nvabsvabsr": _stage(gone)}, th, RUNS, NAMES)
    (entry,) = dv.separated(sep)["Nvvr"]
    assert (
        entry["term"] == "Nvabsvabsr" and entry["separating_run"] == "designed" and entry["separated_by"] == "heldout"
    )
    # the kept term diverging where the competitor does not: the runs favour the competitor
    fav = dv.compare_structures(["Nvvr"], rows, {"Nvvr": _stage(gone), "Nvabsvabsr": _stage(kept)}, th, RUNS, NAMES)
    (entry,) = dv.alternatives(fav)["Nvvr"]
    assert entry["favoured"] and entry["kept_worse_run"] == "designed"
    # and among kept terms, the one that diverges goes after the other
    stages = {"Nvvr": _stage(gone, float(np.nanmean(gone))), "Nvabsvabsr": _stage(kept, float(np.nanmean(kept)))}
    assert dv.dominance_order(["Nvvr", "Nvabsvabsr"], stages, th, (RUNS, NAMES)) == ["Nvabsvabsr", "Nvvr"]
