"""A candidate effect whose parameters the training runs do not determine is said to be (issue 69:
a current fitted at half the truth with sds of 5.6 m/s, and the verdict "none" read as "nothing is
missing")."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from diagnosis_view import diagnosis_view
from test_gap_userdata import FREE, user_world

from bayesid.analysis import gap
from bayesid.analysis.gap.candidates import UNDETERMINED_SCALES, parameter_sds, undetermined_parameters
from bayesid.analysis.gap.records import CandidateRow
from bayesid.data.vehicle import load_vehicle
from bayesid.models import effects as ef
from bayesid.report.diagnosis import _undetermined_lines


def _fit(east_size: float):
    """A fit of Yv and a current whose east component moves the residuals by ``east_size`` per m/s."""
    rng = np.random.default_rng(0)
    J = rng.normal(size=(400, 3)) * np.array([1.0, 1.0, east_size])
    return SimpleNamespace(jac=J, cost=400.0, names=["Yv", "current.current_north_mps", "current.current_east_mps"])


def test_a_parameter_the_residuals_hardly_move_is_undetermined_and_the_others_are_not():
    current = ef.get("current")
    sds = parameter_sds(_fit(1e-4), current)
    # Gauss-Newton: sd = sqrt(s2 / sum of the column's squares), s2 = 400 / 397
    assert abs(sds["current_north_mps"] - np.sqrt(400 / 397 / 400)) < 0.01
    assert sds["current_east_mps"] > UNDETERMINED_SCALES * current.scale[1]
    assert undetermined_parameters(current, sds) == ["current_east_mps"]
    assert undetermined_parameters(current, parameter_sds(_fit(1.0), current)) == []
    # a column the residuals do not move at all, or one the others reproduce: infinite, not the zero
    # sd a pseudo-inverse gives a null direction
    for col in (0.0, "copy"):
        fit = _fit(1.0)
        fit.jac[:, 2] = fit.jac[:, 1] if col == "copy" else 0.0
        sds = parameter_sds(fit, current)
        assert sds["current_east_mps"] == np.inf and undetermined_parameters(current, sds) == (
            ["current_north_mps", "current_east_mps"] if col == "copy" else ["current_east_mps"]
        ), (col, sds)
    assert parameter_sds(SimpleNamespace(jac=None, cost=1.0, names=[]), current) is None
    assert undetermined_parameters(current, None) == []


def test_the_report_says_the_runs_cannot_tell_and_the_record_keeps_the_sds():
    row = CandidateRow(
        effect="current",
        heldout_rms_m=1.0,
        train_rms_m=0.5,
        delta_bic=3.0,
        excess_removed=0.01,
        share_of_excess=0.01,
        heldout_shrinkage=0.01,
        parameters={"current_north_mps": 0.09, "current_east_mps": 0.1},
        heading_rms_deg=1.0,
        window_p_value=0.4,
        nfev=10,
        fit_seconds=1.0,
        parameter_sd={"current_north_mps": 5.6, "current_east_mps": 0.01},
        undetermined=["current_north_mps"],
    )
    assert CandidateRow.from_dict(row.to_dict()).to_dict() == row.to_dict()
    text = "\n".join(_undetermined_lines(diagnosis_view(ranking=[row.to_dict()])))
    assert "Not determined by the training runs: current (current_north_mps 0.09 +- 5.6)" in text
    assert "cannot tell" in text and "current_east_mps" not in text
    quiet = dict(row.to_dict(), undetermined=[])
    assert _undetermined_lines(diagnosis_view(ranking=[quiet])) == []


def test_a_current_the_runs_determine_is_not_flagged():
    # a control: a 0.19 m/s current on two 150 s runs with a velocity log is determined to a few mm/s
    veh = load_vehicle("nps_auv2")
    world = {"current": {"current_north_mps": 0.15, "current_east_mps": 0.12}}
    train, held = user_world(veh, world, 3, n_train=2, n_held=2, duration=150.0, velocity_log=True)
    options = gap.DiagnoseOptions(candidates=["current", "delay"], window_s=30.0, max_nfev=15, discover=None)
    d = gap.diagnose(veh, FREE, train, held, options, rng=np.random.default_rng(0))
    row = next(r for r in d.ranking if r.effect == "current")
    assert d.verdict == "current" and row.undetermined == []
    assert all(0 < sd < 0.01 for sd in row.parameter_sd.values()), row.parameter_sd
