"""Is the model step fine enough for the data? The step-halving check of every fit and
``bayesid fit --dt auto`` (issue 50: coefficient intervals that cover the truth at every log
rate)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bayesid.cli import main
from bayesid.data.track import INPUT_NAMES, STATE_NAMES, Track
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation.identification import identify
from bayesid.estimation.options import FitOptions
from bayesid.estimation.stepcheck import STEP_SHIFT_SD
from bayesid.models import build_model
from bayesid.models import manoeuvres as mv

FREE = ("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr")


def _logged_zigzags(hz: float = 10.0, seed: int = 0) -> list:
    """NPS AUV II 20/20 zigzags to both sides, the rudder reversing at 16 deg/s, integrated at
    0.02 s with the rudder moving linearly between its 0.02 s knots (a continuous truth for a
    0.5 s model step) and logged at ``hz`` with 5 cm and 0.3 deg noise, no u, v, r."""
    veh = load_vehicle("nps_auv2")
    rng = np.random.default_rng(seed)
    truth_model = build_model(veh, dt=0.02, inputs="linear")
    out = []
    for side in (1, -1):
        m = mv.zigzag(veh, 20, 20, dt=0.02, duration=100.0, first_sign=side, options=mv.ZigzagOptions(rate_deg_s=16))
        u = {k: np.append(m.inputs[:, j], m.inputs[-1, j]) for j, k in enumerate(INPUT_NAMES)}
        ctx = truth_model.context(Track(m.t, u), None, s0=m.initial_state)
        S = truth_model.simulate(ctx, truth_model.start()[None], measured_start=False)[0]
        k = int(round(1.0 / (hz * 0.02)))
        d = {c: S[::k, STATE_NAMES.index(c)] for c in ("x", "y", "psi")}
        d["x"] = d["x"] + rng.normal(0.0, 0.05, d["x"].size)
        d["y"] = d["y"] + rng.normal(0.0, 0.05, d["y"].size)
        d["psi"] = d["psi"] + rng.normal(0.0, math.radians(0.3), d["psi"].size)
        d.update({c: u[c][::k] for c in u})
        out.append(Track(m.t[::k], d, name=f"z20_{side}"))
    return out


def _d2(res) -> float:
    """The truth's (the file's coefficients) Mahalanobis distance from the estimate."""
    n = len(FREE)
    truth = load_vehicle("nps_auv2").coefficient_vector(list(FREE))
    d = res.fit.p[:n] - truth
    return float(d @ np.linalg.solve(res.cov[:n, :n], d))


def test_the_submarine_default_step_is_flagged_on_a_fine_log_and_auto_refines_it():
    train = _logged_zigzags()
    opts = FitOptions(free=FREE, prior=False, inputs="linear", max_nfev=40)
    coarse = identify(load_vehicle("nps_auv2"), train, opts, calibration=None)
    sc = coarse.step_check
    assert sc.dt == 0.5 and sc.dt_check == 0.25 and sc.steps_tried == [0.5]
    # halving the step moves the estimate by more than the tolerance: the 0.5 s step is coarse
    assert sc.too_coarse and math.sqrt(sc.d2) >= sc.max_shift_sd > STEP_SHIFT_SD
    assert "the step is coarse for these data" in sc.sentence()
    fine = identify(load_vehicle("nps_auv2"), train, FitOptions(**{**opts.to_dict(), "refine_step": True}), None)
    assert fine.model.dt < 0.5 and fine.step_check.steps_tried[0] == 0.5
    assert not fine.step_check.too_coarse
    # the shift was the step's bias: the refined estimate lies nearer the truth, inside the
    # joint 90 % ellipsoid, the coarse one outside (chi^2_6 quantile 10.64)
    assert _d2(fine) < 10.64 < _d2(coarse)


def test_a_fit_records_its_step_check_and_dt_auto_is_an_option(tmp_path, capsys):
    track = tmp_path / "zz.csv"
    sim = ["simulate", "--manoeuvre", "zigzag", "--angle", "20", "--duration", "60", "--mode", "horizontal"]
    assert main([*sim, "--sample", "0.2", "--out", str(track)]) == 0
    args = ["fit", "--vehicle", "nps_auv2", "--train", str(track), "--free", "Yv,Nr", "--max-nfev", "3"]
    assert main([*args, "--calibration", "none", "--dt", "auto", "--out", str(tmp_path / "fit")]) == 0
    doc = json.loads((tmp_path / "fit" / "model.json").read_text())
    sc = doc["fit"]["step_check"]
    assert sc["steps_tried"][0] == 0.5 and doc["dt"] == sc["steps_tried"][-1] == sc["dt"]
    assert set(sc["shift_sd"]) == {"Yv", "Nr"} and sc["tolerance_sd"] == STEP_SHIFT_SD
    assert "tep check:" in (tmp_path / "fit" / "report.md").read_text()
    capsys.readouterr()
    with pytest.raises(SystemExit) as e:
        main([*args, "--dt", "fast", "--out", str(tmp_path / "bad")])
    assert e.value.code == 2
    assert "--dt" in capsys.readouterr().err
