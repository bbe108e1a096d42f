"""Calibrated predictive bands (issue 31): the conformal quantile; on synthetic tracks with a
structural error (a current the model lacks), nominal 90 % bands calibrated leave one run out
cover 80-97 % of held-out windows and indices, while the posterior draws' own bands (parameter
uncertainty alone) cover far less; predict writes the coverage table and the figures."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bayesid.cli import main
from bayesid.data.track import Track, write_csv
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation.calibration import calibrated_bands, conformal_quantile, index_band
from bayesid.models import effects as ef
from bayesid.models import manoeuvres as mv

NOISE = {"x": 0.1, "y": 0.1, "psi": math.radians(0.2), "u": 0.01, "v": 0.01, "r": math.radians(0.1)}


def test_conformal_quantile_is_the_finite_sample_order_statistic():
    s = np.arange(1.0, 10.0)  # 9 scores
    assert conformal_quantile(s, 0.9) == 9.0  # ceil(10 * 0.9) = 9th smallest
    assert conformal_quantile(s, 0.5) == 5.0  # ceil(10 * 0.5) = 5th
    assert conformal_quantile(s[:8], 0.9) == math.inf  # 8 scores cannot support 90 %
    assert conformal_quantile([1.0, float("nan"), None, 2.0], 0.5) == 2.0
    with pytest.raises(ValueError):
        conformal_quantile(s, 1.0)


def test_index_bands_pool_the_scores_of_a_kind_with_too_few():
    cal = {
        "index_scores": {"first_overshoot_deg": [1.0] * 3, "second_overshoot_deg": list(np.arange(1.0, 11.0))},
        "window_scores": {"max_position_m": [], "max_heading_deg": []},
        "window_s": 60.0,
    }
    b = index_band(cal, "first_overshoot_deg", 5.0, 0.5, 0.9)
    assert b["pooled"] and b["n_scores"] == 13 and b["q"] == conformal_quantile([1.0] * 3 + list(range(1, 11)), 0.9)
    b2 = index_band(cal, "second_overshoot_deg", 5.0, 0.5, 0.9)
    assert not b2["pooled"] and b2["lo"] == pytest.approx(5.0 - 10 * 0.5)
    # a prediction with another window length gets no window band, and says why
    out = calibrated_bands(cal, 30.0, [{"max_position_m": 1.0, "max_heading_deg": 1.0, "duration_s": 30.0}], {})
    assert out["windows"] == [] and "60" in out["window_reason"]


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """10 training and 12 held-out runs from one distribution of zigzags and turns (8-20 deg),
    in a world with a 0.14 m/s current the model lacks; fitted with leave-one-run-out calibration
    and predicted over 60 s windows."""
    d = tmp_path_factory.mktemp("cal")
    veh = load_vehicle("nps_auv2")
    rng = np.random.default_rng(3)

    def world(tag, i):
        a, kind = float(rng.uniform(8, 20)), rng.integers(2)
        m = (
            mv.zigzag(veh, a, dt=0.1, duration=180.0, first_sign=int(rng.choice([-1, 1])))
            if kind == 0
            else mv.turning_circle(veh, a, dt=0.1, duration=180.0)
        )
        tr = ef.world_track(
            veh,
            m,
            {"current": {"current_north_mps": 0.12, "current_east_mps": -0.08}},
            rng,
            noise=NOISE,
            sample_every=2,
            hold_inputs=True,
        )
        t = Track(tr.t, dict(tr.data), name=f"{tag}{i}_{m.name}", meta=tr.meta)
        write_csv(t, d / f"{t.name}.csv")
        return str(d / f"{t.name}.csv")

    train = [world("tr", i) for i in range(10)]
    held = [world("ho", i) for i in range(12)]
    assert main(["fit", "--vehicle", "nps_auv2", "--train", *train, "--max-nfev", "20", "--out", str(d / "fit")]) == 0
    assert (
        main(
            [
                "predict",
                "--model",
                str(d / "fit" / "model.json"),
                "--track",
                *held,
                "--window",
                "60",
                "--out",
                str(d / "pred"),
            ]
        )
        == 0
    )
    return d


def test_calibrated_bands_hold_their_coverage_and_parameter_bands_do_not(synthetic):
    P = json.loads((synthetic / "pred" / "predict.json").read_text())
    cov = P["bands"]["coverage"]
    for group in ("windows", "indices"):
        c = cov[group]["0.9"]
        assert c["n"] >= 20 and 0.80 <= c["coverage"] <= 0.97, (group, c)
    assert 0.35 <= cov["all"]["0.5"]["coverage"] <= 0.65
    po = P["bands"]["parameter_only"]
    assert po["n"] >= 20 and po["coverage"] < 0.5, po  # posterior draws alone: overconfident
    assert P["n_draws"] == 100
    rows = P["bands"]["indices"]
    assert all({"measured", "predicted", "band", "inside", "parameter_band_5_95"} <= set(r) for r in rows)
    doc = json.loads((synthetic / "fit" / "model.json").read_text())
    assert doc["calibration"]["n_folds"] == 10 and len(doc["calibration"]["window_scores"]["max_position_m"]) >= 20
    assert "## Calibration of the predictive bands" in (synthetic / "fit" / "report.md").read_text()
    rep = (synthetic / "pred" / "report.md").read_text()
    assert (
        "## Predictive bands and their coverage" in rep
        and (synthetic / "pred" / "figures" / "reliability.png").is_file()
    )
