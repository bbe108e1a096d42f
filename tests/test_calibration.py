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
from bayesid.estimation.calibration import Calibration, conformal_quantile, excitation
from bayesid.models import manoeuvres as mv
from bayesid.models.world import LogOptions, world_track

NOISE = {"x": 0.1, "y": 0.1, "psi": math.radians(0.2), "u": 0.01, "v": 0.01, "r": math.radians(0.1)}


def test_conformal_quantile_is_the_finite_sample_order_statistic():
    s = np.arange(1.0, 10.0)  # 9 scores
    assert conformal_quantile(s, 0.9) == 9.0  # ceil(10 * 0.9) = 9th smallest
    assert conformal_quantile(s, 0.5) == 5.0  # ceil(10 * 0.5) = 5th
    assert conformal_quantile(s[:8], 0.9) == math.inf  # 8 scores cannot support 90 %
    assert conformal_quantile([1.0, float("nan"), None, 2.0], 0.5) == 2.0
    with pytest.raises(ValueError):
        conformal_quantile(s, 1.0)


def _cal(index_rows=(), window_rows=(), window_s=60.0, **fields):
    """A calibration as leave_one_run_out writes it, from fold rows (one fold)."""
    return Calibration(
        folds=[{"runs": ["a"], "indices": list(index_rows), "windows": list(window_rows)}], window_s=window_s, **fields
    )


def test_index_scores_are_normalised_by_parameter_spread_and_relative_structural_error():
    # first overshoot: 3 rows (too few: pooled); second: 10 rows, 2-20 % relative errors
    first = [{"index": "first_overshoot_deg", "measured": 5.5, "predicted": 5.0, "sd": 0.01}] * 3
    second = [
        {"index": "second_overshoot_deg", "measured": 10.0 + 0.2 * e, "predicted": 10.0, "sd": 0.0}
        for e in range(1, 11)
    ]
    cal = _cal(first + second + [{"index": "advance_m", "measured": None, "predicted": 3.0, "sd": 1.0}])
    kappas, scores = cal.normalised_index_scores()
    rel = [0.1] * 3 + [0.02 * e for e in range(1, 11)]
    assert kappas["all"] == pytest.approx(np.median(rel)) and kappas["first_overshoot_deg"] == pytest.approx(0.1)
    kappa = kappas["second_overshoot_deg"]
    assert kappa == pytest.approx(0.11)  # its own median relative error
    assert scores["second_overshoot_deg"] == pytest.approx([0.2 * e / (kappa * 10) for e in range(1, 11)])
    assert scores["first_overshoot_deg"][0] == pytest.approx(0.5 / math.hypot(0.01, 0.1 * 5.0))
    assert "advance_m" not in scores  # nothing measured: no score
    # a journaled fit stores a non-finite value as text: such a row is left out, not a TypeError
    text = [{"index": "speed_loss", "measured": "nan", "predicted": 0.3, "sd": "nan"}] * 3
    assert _cal(first + second + text).normalised_index_scores() == (kappas, scores)
    b = cal.index_band("first_overshoot_deg", 5.0, 0.5, 0.9)
    pooled = scores["first_overshoot_deg"] + scores["second_overshoot_deg"]
    assert b["pooled"] and b["n_scores"] == 13 and b["q"] == conformal_quantile(pooled, 0.9)
    assert b["hi"] - 5.0 == pytest.approx(b["q"] * math.hypot(0.5, 0.1 * 5.0))
    # a turning circle from these zigzag scores: pooled, and the band scales with the index's size
    td = cal.index_band("tactical_diameter_m", 40.0, 0.0, 0.9)
    assert td["pooled"] and td["lo"] > 0 and td["hi"] - 40.0 == pytest.approx(td["q"] * kappas["all"] * 40.0)
    b2 = cal.index_band("second_overshoot_deg", 10.0, 0.0, 0.9)
    assert not b2["pooled"] and b2["hi"] == pytest.approx(12.0)  # the largest of 10 errors, rescaled
    # a calibration written with the older score (rows with "score", stale index_scores) gets the current one
    old = _cal([dict(r, score=99.0) for r in first + second], index_scores={"second_overshoot_deg": [99.0] * 10})
    assert old.index_band("second_overshoot_deg", 10.0, 0.0, 0.9)["hi"] == pytest.approx(b2["hi"])


def test_window_bands_hold_jointly_for_position_and_heading():
    # independent position and heading errors: marginal 50 % radii would hold jointly ~25 % of the time
    rng = np.random.default_rng(0)

    def rows(n):
        return [{"max_position_m": a, "max_heading_deg": b} for a, b in zip(rng.gamma(2, 0.5, n), rng.gamma(2, 3.0, n))]

    cal = _cal(window_rows=rows(399))
    fresh = rows(4000)
    for a in (0.5, 0.9):
        b = cal.window_band(a)
        held = np.mean(
            [w["max_position_m"] <= b["max_position_m"] and w["max_heading_deg"] <= b["max_heading_deg"] for w in fresh]
        )
        assert abs(held - a) < 0.04, (a, held)
    marg = [np.quantile([w[k] for w in cal.folds[0]["windows"]], 0.5) for k in ("max_position_m", "max_heading_deg")]
    assert np.mean([w["max_position_m"] <= marg[0] and w["max_heading_deg"] <= marg[1] for w in fresh]) < 0.35
    # a prediction with another window length gets no window band, and says why
    out = cal.bands(30.0, [{"max_position_m": 1.0, "max_heading_deg": 1.0, "duration_s": 30.0}], {})
    assert out["windows"] == [] and "60" in out["window_reason"]


def test_runs_driven_outside_the_training_range_are_named():
    t = np.arange(0.0, 100.0, 0.1)

    def run(name, rudder_deg, yaw_deg_s, log_r=True):
        d = {"delta_r": np.radians(rudder_deg) * np.sign(np.sin(t / 10)), "psi": np.radians(yaw_deg_s) * t}
        if log_r:
            d["r"] = np.full_like(t, np.radians(yaw_deg_s))
        return Track(t, d, name=name)

    train = [run("a", 10, 2.0), run("b", 35, 3.5)]
    cal = _cal(
        window_rows=[{"track": "x", "max_position_m": 1.0, "max_heading_deg": 1.0}] * 20,
        excitation={tr.name: excitation(tr) for tr in train},
    )
    assert excitation(train[0])["rudder_deg"] == pytest.approx(10.0)
    assert excitation(run("c", 20, 3.0, log_r=False))["yaw_rate_deg_s"] == pytest.approx(3.0)  # from psi
    assert cal.outside_excitation(excitation(run("in", 20, 2.5))) == []
    why = cal.outside_excitation(excitation(run("small", 5, 0.8)))
    assert len(why) == 2 and why[0].startswith("rudder 5 deg below the training runs' 10-35 deg")
    assert Calibration().outside_excitation(excitation(run("small", 5, 0.8))) == []  # older calibrations: no claim
    w = [{"track": n, "max_position_m": 0.5, "max_heading_deg": 0.5, "duration_s": 60.0} for n in ("in", "small")]
    exc = {"in": excitation(run("in", 20, 2.5)), "small": excitation(run("small", 5, 0.8))}
    out = cal.bands(60.0, w, {}, excitations=exc)
    assert list(out["outside_range"]) == ["small"]
    # 20 window scores support 90 % (finite band) but not 96 %: those claims are counted as unbounded
    assert out["coverage"]["windows"]["0.9"]["unbounded"] == 0
    wide = cal.bands(60.0, w, {}, levels=(0.9, 0.96), excitations=exc)
    assert wide["coverage"]["windows"]["0.96"] == {"n": 2, "inside": 2, "coverage": 1.0, "unbounded": 2}
    assert out["coverage"]["windows"]["0.9"]["n"] == 2 and out["coverage_in_range"]["windows"]["0.9"]["n"] == 1


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
        tr = world_track(
            veh,
            m,
            {"current": {"current_north_mps": 0.12, "current_east_mps": -0.08}},
            rng,
            LogOptions(noise=NOISE, sample_every=2, hold_inputs=True),
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
                "--score-window",
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
    assert len(doc["calibration"]["excitation"]) == 10 and P["bands"]["outside_range"] == {}  # one distribution
    fit_report = (synthetic / "fit" / "report.md").read_text()
    assert "## Calibration of the predictive bands" in fit_report and "calibrated for runs like these" in fit_report
    rep = (synthetic / "pred" / "report.md").read_text()
    assert (
        "## Predictive bands and their coverage" in rep
        and (synthetic / "pred" / "figures" / "reliability.png").is_file()
    )


def test_a_manoeuvre_the_training_runs_lacked_is_flagged_extrapolated_not_counted_as_calibrated(tmp_path):
    """Zigzag-only training, turning circles predicted: their bands borrow the overshoots' scores
    and would not hold (here under half of the tactical diameters and windows), so predict keeps
    them out of the calibrated coverage and says so; the held-out zigzags stay calibrated."""
    veh = load_vehicle("nps_auv2")
    rng = np.random.default_rng(5)

    def world(tag, i, turn):
        a = float(rng.uniform(8, 20))
        m = (
            mv.turning_circle(veh, a, dt=0.1, duration=150.0)
            if turn
            else mv.zigzag(veh, a, dt=0.1, duration=150.0, first_sign=int(rng.choice([-1, 1])))
        )
        cur = {"current": {"current_north_mps": 0.12, "current_east_mps": -0.08}}
        tr = world_track(veh, m, cur, rng, LogOptions(noise=NOISE, sample_every=2, hold_inputs=True))
        t = Track(tr.t, dict(tr.data), name=f"{tag}{i}_{m.name}", meta=tr.meta)
        write_csv(t, tmp_path / f"{t.name}.csv")
        return str(tmp_path / f"{t.name}.csv")

    train = [world("tr", i, False) for i in range(6)]
    held = [world("tc", i, True) for i in range(6)] + [world("zz", i, False) for i in range(3)]
    fit = ["fit", "--vehicle", "nps_auv2", "--train", *train, "--max-nfev", "15", "--out", str(tmp_path / "fit")]
    assert main(fit) == 0
    pred = ["predict", "--model", str(tmp_path / "fit" / "model.json"), "--track", *held, "--score-window", "60"]
    assert main([*pred, "--out", str(tmp_path / "pred")]) == 0
    B = json.loads((tmp_path / "pred" / "predict.json").read_text())["bands"]
    ext = B["extrapolated"]
    assert ext["kinds"] == ["turning"] and len(ext["runs"]) == 6 and all(r.startswith("tc") for r in ext["runs"])
    assert {"advance_m", "tactical_diameter_m"} <= set(ext["index_kinds"])
    rows = B["indices"]
    assert all(r["extrapolated"] == r["track"].startswith("tc") for r in rows)
    assert all(w["extrapolated"] == w["track"].startswith("tc") for w in B["windows"])
    # the calibrated coverage counts the zigzags only; the borrowed turning bands do not hold
    assert B["coverage"]["indices"]["0.9"]["n"] == sum(not r["extrapolated"] for r in rows) > 0
    td = [r["inside"]["0.9"] for r in rows if r["index"] == "tactical_diameter_m"]
    assert len(td) == 6 and np.mean(td) < 0.5, td
    xw = ext["coverage"]["windows"]["0.9"]
    assert xw["n"] >= 12 and xw["coverage"] < 0.5, xw
    assert "Extrapolated, not calibrated" in (tmp_path / "pred" / "report.md").read_text()


def test_the_report_says_which_folds_are_extrapolations_and_what_data_would_help():
    """Issue 50: with one training run of each kind every leave-one-run-out fold predicts a kind
    the refit never saw; the fit report says so, names the kinds, and says what to add."""
    from bayesid.report.fit import _extrapolation_fold_lines

    rng = np.random.default_rng(1)
    wins = [{"max_position_m": a, "max_heading_deg": 1.0} for a in rng.gamma(2, 0.5, 5)]
    kinds = {"z10": "zigzag", "t35": "turning_circle", "p20": "pull_out", "z20": "zigzag"}
    folds = [{"runs": [r], "indices": [], "windows": wins} for r in kinds]
    cal = Calibration(folds=folds, window_s=60.0, kinds=kinds, n_folds=4)
    ext = cal.extrapolation_folds()
    assert [f["runs"] for f in ext] == [["t35"], ["p20"]]  # the zigzags have each other
    assert [f["kinds"] for f in ext] == [["turning_circle"], ["pull_out"]]
    wb = {a: cal.window_band(a) for a in (0.5, 0.9, 0.95)}
    text = " ".join(_extrapolation_fold_lines(cal, wb))
    assert "**2 of 4 folds are extrapolations**" in text and "pull out (1 run), turning circle (1 run)" in text
    assert "A second run of each of these kinds" in text
    assert "Unbounded window bands at 0.95 (needs at least 19 left-out windows): the folds scored 20" not in text
    assert "0.95 (needs at least 19" not in text  # 20 windows: bounded
    # a file of an older version has no kinds: nothing said; round trip through JSON keeps them
    assert Calibration(folds=folds, window_s=60.0).extrapolation_folds() == []
    assert Calibration.from_dict(json.loads(json.dumps(cal.to_dict()))).kinds == kinds
    few = Calibration(folds=[{"runs": ["z10"], "indices": [], "windows": wins[:3]}], window_s=60.0, kinds=kinds)
    text = " ".join(_extrapolation_fold_lines(few, {a: few.window_band(a) for a in (0.9, 0.95)}))
    assert "Unbounded window bands at 0.9 (needs at least 9 left-out windows), 0.95 (needs at least 19" in text
    assert "the folds scored 3" in text


def _circle(name, radius, speed, L=7.0, noise=0.0, seed=0):
    """A run around a circle of ``radius`` m at ``speed`` m/s, 20 Hz, positions with ``noise`` m."""
    t = np.arange(0.0, 120.0, 0.05)
    a = speed * t / radius
    rng = np.random.default_rng(seed)
    x, y = radius * np.sin(a), radius * (1.0 - np.cos(a))
    return Track(
        t,
        {"x": x + rng.normal(0, noise, t.size), "y": y + rng.normal(0, noise, t.size), "psi": a, "delta_r": 0 * t},
        name=name,
    )


def test_the_nondimensional_yaw_rate_is_length_over_radius_whatever_the_speed():
    # a 5.2 m circle of a 7 m ship at 0.31 m/s (the nominal KVLCC2's steady 35 deg turn) and a 16 m one
    # at 0.9 m/s: r' = L / R, from positions and heading (positions with 2 cm noise)
    from bayesid.estimation.calibration import yaw_rate_prime

    for radius, speed in ((5.2, 0.31), (16.0, 0.9)):
        tr = _circle("c", radius, speed, noise=0.02)
        rp = yaw_rate_prime(tr.t, tr["x"], tr["y"], tr["psi"], 7.0)
        assert np.median(rp) == pytest.approx(7.0 / radius, rel=0.03)
        assert excitation(tr, 7.0)["yaw_rate_prime"] == pytest.approx(7.0 / radius, rel=0.06)
    assert "yaw_rate_prime" not in excitation(tr)  # without the length: as before


def test_predict_warns_where_the_models_own_run_turns_tighter_than_any_training_run():
    # the calibration's runs reached r' 0.09-0.60 (the HSVA zigzags); a whole-run prediction around a
    # 5.2 m circle of a 7 m ship (r' 1.35) is beyond 1.25 x that; one around a 16 m circle is not
    from types import SimpleNamespace

    from bayesid.cli.predict import model_excursion

    cal = _cal(excitation={"a": {"yaw_rate_prime": 0.09}, "b": {"yaw_rate_prime": 0.60}})
    doc = SimpleNamespace(calibration=cal)
    sims = {}
    for name, radius in (("tight", 5.2), ("wide", 16.0)):
        tr = _circle(name, radius, 0.5)
        S = np.zeros((tr.n_samples, 12))
        S[:, 0], S[:, 1], S[:, 5] = tr["x"], tr["y"], tr["psi"]
        sims[name] = (SimpleNamespace(ts=tr.t), S)
    whole = SimpleNamespace(simulated=sims)
    tracks = [SimpleNamespace(name="tight"), SimpleNamespace(name="wide")]
    w = model_excursion(doc, whole, tracks, 7.0)
    assert len(w) == 1 and w[0].startswith("tight: the model's own run turns at r' = r L / U 1.3"), w
    assert "above the training runs' 0.09-0.60" in w[0]
    assert model_excursion(SimpleNamespace(calibration=_cal()), whole, tracks, 7.0) == []  # older: no claim
    assert model_excursion(SimpleNamespace(calibration=None), whole, tracks, 7.0) == []
