"""Each run's propulsion point against the fitted model's (issue 67: "is it the basin's propulsion
point?"). Runs of a KVLCC2 whose wake fraction is 0.20 (another basin's propulsion point: the
rpm that holds 1.179 m/s is higher) against the packaged model (wP 0.40): at the rpm those runs log
on their approach, the packaged model settles faster than they go, and the check says
the held-out runs are at another propulsion point; runs at the packaged model's own point are
not. A run that accelerates on its approach is left out of the medians."""

from __future__ import annotations

import numpy as np
import pytest

from bayesid.analysis.gap.records import ApproachCheck
from bayesid.analysis.gap.where import approach_check
from bayesid.data.track import Track
from bayesid.models import ship
from bayesid.models.runs import approach_row, run_approach
from bayesid.models.ship.trials import T_EXECUTE, TrialOptions, propulsion_point, simulate_trial
from bayesid.report.diagnosis import _another_point_lines, _approach_lines


@pytest.fixture(scope="module")
def kv():
    return ship.load_ship("kvlcc2_7m")


def _runs(vessel, prefix):
    speed, rpm = propulsion_point(vessel, 1.179)
    opts = TrialOptions(dt=0.1, sample_every=2, duration=40.0, rudder_rate_deg_s=15.8)
    out = []
    for kind, angle in (("zigzag", 10.0), ("turn", -35.0)):
        tr = simulate_trial(vessel, kind, angle, speed=speed, rpm=rpm, options=opts).track
        out.append(Track(tr.t, dict(tr.data), name=f"{prefix}_{kind}"))
    return out, rpm


def test_run_approach_reads_the_samples_before_the_first_rudder_order(kv):
    (zz, _), rpm = _runs(kv, "a")
    a = run_approach(zz)
    assert a["seconds"] == pytest.approx(min(T_EXECUTE, 10.0), abs=0.25)  # the trials execute at 10 s
    assert a["speed_m_s"] == pytest.approx(1.179, rel=1e-6) and a["rpm"] == pytest.approx(rpm)
    assert abs(a["accel_m_s2"]) < 1e-6
    assert run_approach(Track(zz.t, {k: v for k, v in zz.data.items() if k != "n"}, name="no_n")) is None


def test_held_out_runs_at_another_propulsion_point_are_named(kv):
    model = ship.ShipModel(kv, kv.free)
    p = model.start()
    home, rpm_home = _runs(kv, "home")
    away, rpm_away = _runs(kv.with_coefficients({"wP": 0.20}), "away")
    assert rpm_away > rpm_home  # a smaller wake fraction: a faster inflow, more rpm for the same speed
    check = approach_check(model, p, home, away)
    assert check.training_error == pytest.approx(0.0, abs=1e-6)
    assert check.heldout_error > 0.05 and check.another_point
    assert "another propulsion point" in check.sentence()
    same = approach_check(model, p, home[:1], home[1:])
    assert not same.another_point and "the training runs' propulsion point" in same.sentence()
    # one held-out run from each: only the other basin's is at another point, and only it is matched
    mixed = approach_check(model, p, home[:1], [home[1], away[0]])
    assert mixed.off_runs == ["away_zigzag"] and "held-out run(s) away_zigzag" in mixed.sentence()
    kept, matched = mixed.matched([home[1], away[0]])
    assert kept is home[1] and matched is not away[0]
    # the JSON object reads back and renders the same table
    back = ApproachCheck.from_dict(check.to_dict())
    assert _approach_lines(back) == _approach_lines(check.to_dict())
    assert "away_turn" in "\n".join(_approach_lines(back))
    beside = "\n".join(_another_point_lines(back))
    assert "held-out run(s) away_zigzag, away_turn at another propulsion point" in beside
    assert _another_point_lines(same.to_dict()) == []


def test_an_accelerating_approach_is_left_out(kv):
    model = ship.ShipModel(kv, kv.free)
    home, _ = _runs(kv, "home")
    tr = home[0]
    u = np.asarray(tr["u"], float) + 0.02 * (tr.t - tr.t[0])  # +0.2 m/s over 10 s
    fast = Track(tr.t, dict(tr.data, u=u), name="accelerating")
    check = approach_check(model, model.start(), home[1:], [fast])
    assert check is None  # its only held-out approach is not steady: nothing to say
    assert approach_check(ship.ShipModel(kv, kv.free), model.start(), home, []) is None


def test_matching_the_rpm_of_runs_at_another_point_restores_their_speed(kv):
    model = ship.ShipModel(kv, kv.free)
    p = model.start()
    home, _ = _runs(kv, "home")
    away, _ = _runs(kv.with_coefficients({"wP": 0.20}), "away")
    check = approach_check(model, p, home, away)
    matched = check.matched(away)
    for tr, m in zip(away, matched):
        k = np.asarray(m["n"]) / np.asarray(tr["n"])
        assert np.allclose(k, k[0]) and k[0] < 1.0  # one factor per run: less rpm for the packaged model
        # at the matched rpm the packaged model holds the run's approach speed
        assert model.steady_speed(p, float(np.asarray(m["n"])[0])) == pytest.approx(1.179, rel=1e-6)
    scored = check.with_scores(1.0, 0.4, 0.2)
    assert scored.share_of_excess == pytest.approx(0.75)
    assert "from 1 m to 0.4 m" in scored.sentence() and "75% of the excess" in scored.sentence()
    assert ApproachCheck.from_dict(scored.to_dict()).share_of_excess == pytest.approx(0.75)
    worse = check.with_scores(1.0, 1.2, 0.2)  # matching the rpm made it worse: not the rpm's scale alone
    assert worse.share_of_excess == pytest.approx(-0.25) and "makes it worse" in worse.sentence()
    assert "makes the held-out error worse" in "\n".join(_another_point_lines(worse))
    assert "share_of_excess" not in check.to_dict()  # unscored: the optional fields stay out


def test_the_diagnosis_reports_held_out_runs_at_another_point(kv):
    """End to end on the smallest runs: two 40 s runs to train, two held out from another point:
    the same ship whose rpm log reads 8 % high (another propeller, or the rpm's scaling), so that
    matching the rpm to the approach is the whole difference."""
    import warnings

    import bayesid
    from bayesid.tasks import Runner

    home, _ = _runs(kv, "home")
    away = [Track(t.t, dict(t.data, n=1.08 * np.asarray(t["n"])), name=t.name.replace("home", "away")) for t in home]
    said = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = bayesid.diagnose(
            kv,
            ["Xuu", "Yv", "Nr"],
            home,
            away,
            bayesid.DiagnoseOptions(candidates=(), window_s=20.0, fit_window_s=20.0, max_nfev=5, start="measured"),
            rng=np.random.default_rng(0),
            runner=Runner(progress=said.append),
        )
    ap = ApproachCheck.from_dict(d.where["approach"])
    assert ap.another_point and ap.share_of_excess > 0.9
    assert ap.heldout_rms_m == pytest.approx(d.gap_before["heldout_rms_m"])
    assert any("another propulsion point" in m for m in said)


def test_heldout_propeller_approach_judges_the_held_out_runs_at_their_own_point(kv):
    """The same two runs from another point, diagnosed with ``heldout_propeller="approach"``: the
    diagnosis is made again with their rpm matched, and the gap, all of it the point's, is gone."""
    import warnings

    import bayesid
    from bayesid.tasks import Runner

    home, _ = _runs(kv, "home")
    away = [Track(t.t, dict(t.data, n=1.08 * np.asarray(t["n"])), name=t.name.replace("home", "away")) for t in home]
    got, said = {}, []
    for propeller in ("logged", "approach"):
        opts = bayesid.DiagnoseOptions(
            candidates=(), window_s=20.0, fit_window_s=20.0, max_nfev=5, start="measured", heldout_propeller=propeller
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            got[propeller] = bayesid.diagnose(
                kv,
                ["Xuu", "Yv", "Nr"],
                home,
                away,
                opts,
                rng=np.random.default_rng(0),
                runner=Runner(progress=said.append),
            )
    logged, matched = got["logged"], got["approach"]
    assert logged.significant_gap and logged.verdict != "none"
    # the held-out runs, twins of the training runs but for the rpm log, are predicted as well as
    # the training runs once their rpm is matched (0.006 m against 0.17 m with the logged rpm)
    before, after = logged.gap_before["heldout_rms_m"], matched.gap_before["heldout_rms_m"]
    assert after < 0.1 * before and after == pytest.approx(matched.gap_before["train_rms_m"], rel=0.1)
    ap = ApproachCheck.from_dict(matched.where["approach"])
    assert ap.rediagnosed and ap.off_runs == ["away_zigzag", "away_turn"] and ap.share_of_excess > 0.9
    assert "judged with those runs at the matched rpm" in ap.sentence()
    assert (
        "--heldout-propeller approach (DiagnoseOptions" in ApproachCheck.from_dict(logged.where["approach"]).sentence()
    )
    assert matched.settings["heldout_propeller"] == "approach" and "heldout_propeller" not in logged.settings
    assert any("diagnosed again with their rpm matched" in m for m in said)
    # the second diagnosis (on the matched runs) says nothing more of their point, nor advises the option again
    assert not any(
        "--heldout-propeller approach (DiagnoseOptions" in m
        for m in said[said.index(next(m for m in said if "diagnosed again" in m)) :]
    )


def test_heldout_propeller_approach_needs_a_propeller_model(tmp_path, capsys):
    import bayesid
    from bayesid import cli

    runs = [Track([0.0, 1.0], {"x": [0.0, 1.0]}, name=n) for n in ("a", "b")]
    with pytest.raises(ValueError, match="no propeller model"):
        bayesid.diagnose(
            bayesid.load_any_vehicle("nps_auv2"),
            None,
            runs[:1],
            runs[1:],
            bayesid.DiagnoseOptions(heldout_propeller="approach"),
        )
    with pytest.raises(ValueError, match="heldout_propeller must be one of logged, approach, matched"):
        bayesid.DiagnoseOptions(heldout_propeller="rated")
    csv = tmp_path / "z.csv"
    assert (
        cli.main(
            [
                "-q",
                "simulate",
                "--vehicle",
                "nps_auv2",
                "--manoeuvre",
                "zigzag",
                "--angle",
                "10",
                "--duration",
                "30",
                "--out",
                str(csv),
                "--no-figure",
            ]
        )
        == 0
    )
    args = ["diagnose", "--vehicle", "nps_auv2", "--train", str(csv), "--heldout", str(csv), "--heldout-propeller"]
    assert cli.main([*args, "approach", "--out", str(tmp_path / "d")]) == 2
    assert "--heldout-propeller approach: nps_auv2 has no propeller model" in capsys.readouterr().err


def test_predict_warns_about_a_run_at_another_propulsion_point(kv, tmp_path, capsys):
    import json

    from bayesid import cli
    from bayesid.data.track import write_csv

    home, _ = _runs(kv, "home")
    away = [Track(t.t, dict(t.data, n=1.08 * np.asarray(t["n"])), name=t.name.replace("home", "away")) for t in home]
    files = {}
    for tr in home + away:
        files[tr.name] = tmp_path / f"{tr.name}.csv"
        write_csv(tr, files[tr.name])
    fit = ["fit", "--vehicle", "kvlcc2_7m", "--train", str(files["home_zigzag"]), "--free", "Yv,Nr"]
    assert cli.main(["-q", *fit, "--max-nfev", "3", "--calibration", "none", "--out", str(tmp_path / "f")]) == 0
    pred = ["predict", "--model", str(tmp_path / "f" / "model.json"), "--draws", "0"]
    assert (
        cli.main(
            ["-q", *pred, "--track", str(files["away_zigzag"]), str(files["home_turn"]), "--out", str(tmp_path / "p")]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert "away_zigzag: at the" in err and "another propulsion point" in err and "home_turn: at the" not in err
    res = json.loads((tmp_path / "p" / "predict.json").read_text())
    rows = {r["run"]: r for r in res["approach"]}
    assert rows["away_zigzag"]["speed_error"] > 0.03 and "warning" not in rows["home_turn"]
    # --propeller approach drives each run at the rpm the model needs for its approach: the run read
    # 8 % high is driven at 1 / 1.08 of its log, and predicted as well as its twin at the model's point
    more = ["--propeller", "approach", "--out", str(tmp_path / "q")]
    assert cli.main(["-q", *pred, "--track", str(files["away_zigzag"]), str(files["home_turn"]), *more]) == 0
    res2 = json.loads((tmp_path / "q" / "predict.json").read_text())
    fac = {r["run"]: r["rpm_factor"] for r in res2["approach"]}
    assert fac["away_zigzag"] == pytest.approx(fac["home_turn"] / 1.08, rel=1e-9) and res2["propeller"] == "approach"
    before = res["per_track"]["away_zigzag"]["rms_position_m"]
    after = res2["per_track"]["away_zigzag"]["rms_position_m"]
    assert after < 0.5 * before


def test_a_fit_on_runs_at_two_propulsion_points_says_so(kv, tmp_path, capsys):
    import json

    from bayesid import cli
    from bayesid.data.track import write_csv
    from bayesid.estimation.identification import identify
    from bayesid.estimation.options import FitOptions
    from bayesid.models.runs import PropulsionPointWarning

    home, rpm = _runs(kv, "home")
    opts_t = TrialOptions(dt=0.1, sample_every=2, duration=40.0, rudder_rate_deg_s=15.8)
    other = simulate_trial(kv, "turn", 20.0, speed=1.179, rpm=rpm, options=opts_t).track
    away = Track(other.t, dict(other.data, n=1.10 * np.asarray(other["n"])), name="away_turn")  # rpm log 10 % high
    opts = FitOptions(free=("Yv", "Nr"), max_nfev=3, window_s=20.0)
    with pytest.warns(PropulsionPointWarning, match="away_turn are at another propulsion point"):
        res = identify(kv, [*home, away], opts, calibration=None)
    assert res.training_points["apart"] == ["away_turn"]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", PropulsionPointWarning)
        same = identify(kv, home, opts, calibration=None)
    assert same.training_points["apart"] == []
    files = []
    for tr in [*home, away]:
        files.append(str(tmp_path / f"{tr.name}.csv"))
        write_csv(tr, files[-1])
    argv = ["-q", "fit", "--vehicle", "kvlcc2_7m", "--train", *files, "--free", "Yv,Nr", "--max-nfev", "3"]
    assert cli.main([*argv, "--calibration", "none", "--out", str(tmp_path / "f")]) == 0
    assert "away_turn are at another propulsion point" in capsys.readouterr().err
    doc = json.loads((tmp_path / "f" / "model.json").read_text())
    assert doc["fit"]["training_points"]["apart"] == ["away_turn"]
    report = (tmp_path / "f" / "report.md").read_text()
    assert "**Propulsion points:** Training run(s) away_turn" in report


def test_a_missed_training_turn_at_another_propulsion_point_is_said_so():
    from bayesid.report.fit import _training_turn_lines

    ind = {"tactical_diameter_m": 20.0, "steady_turning_diameter_m": 15.0}
    turn = {
        "run": "away_turn",
        "reproduced": False,
        "measured": ind,
        "predicted": {k: 0.8 * v for k, v in ind.items()},
        "rel_error": {k: -0.2 for k in ind},
        "suspect": "speed in the turn",
    }
    said = "\n".join(_training_turn_lines([turn], None, ["away_turn"]))
    assert "The training run away_turn is at another propulsion point than the others" in said
    assert "another propulsion point" not in "\n".join(_training_turn_lines([turn], None, ["home_turn"]))


def test_an_approach_read_from_positions_alone_is_judged_steady_or_not(kv):
    (zz, _), _ = _runs(kv, "a")
    pos = Track(zz.t, {k: v for k, v in zz.data.items() if k not in ("u", "v", "r")}, name="positions")
    a = run_approach(pos)
    assert a["speed_m_s"] == pytest.approx(1.179, rel=1e-3) and abs(a["accel_m_s2"]) < 1e-3
    t = np.asarray(zz.t) - zz.t[0]
    x = np.asarray(zz["x"]) + 0.5 * 0.05 * t**2 * np.cos(np.asarray(zz["psi"]))  # speeding up at 0.05 m/s^2
    y = np.asarray(zz["y"]) + 0.5 * 0.05 * t**2 * np.sin(np.asarray(zz["psi"]))
    fast = run_approach(Track(zz.t, dict(pos.data, x=x, y=y), name="speeding_up"))
    assert fast["accel_m_s2"] == pytest.approx(0.05, rel=0.05)


def test_runs_at_another_point_and_another_speed_name_the_other_explanation(kv):
    from bayesid.models.runs import other_speed_note

    assert other_speed_note([1.17], [1.18, 1.18]) == ""
    assert "not the others' (1.18 m/s)" in other_speed_note([0.9], [1.18, 1.18])
    model = ship.ShipModel(kv, kv.free)
    home, _ = _runs(kv, "home")
    speed, rpm = propulsion_point(kv, 0.9)
    opts = TrialOptions(dt=0.1, sample_every=2, duration=40.0, rudder_rate_deg_s=15.8)
    slow = simulate_trial(kv, "turn", 20.0, speed=speed, rpm=rpm, options=opts).track
    slow = Track(slow.t, dict(slow.data, n=1.08 * np.asarray(slow["n"])), name="slow_turn")
    check = approach_check(model, model.start(), home, [slow])
    assert check.another_point and "a resistance or thrust curve the model misses" in check.sentence()
    same_speed = approach_check(model, model.start(), home[:1], home[1:] + [away_at_speed(kv, 1.179)])
    assert same_speed.another_point and "resistance or thrust curve" not in same_speed.sentence()


def away_at_speed(kv, speed):
    """A 20 deg turn at ``speed`` whose rpm log reads 8 % high."""
    s, rpm = propulsion_point(kv, speed)
    opts = TrialOptions(dt=0.1, sample_every=2, duration=40.0, rudder_rate_deg_s=15.8)
    tr = simulate_trial(kv, "turn", -20.0, speed=s, rpm=rpm, options=opts).track
    return Track(tr.t, dict(tr.data, n=1.08 * np.asarray(tr["n"])), name="away_turn20")


def test_a_run_starting_from_rest_with_the_propeller_ordered_is_not_judged(kv):
    """The Esso Osaka turns start at a few mm/s with the propeller at 600 rpm (no equilibrium): one
    read as steady over its first 2 s was named at +3843 % before the model's speed had to be within
    half of the run's."""
    model = ship.ShipModel(kv, kv.free)
    home, _ = _runs(kv, "home")
    tr = home[1]
    u = np.full(tr.t.size, 0.011)
    rest = Track(tr.t, dict(tr.data, u=u, x=np.asarray(tr["x"])[0] + 0.011 * (tr.t - tr.t[0])), name="from_rest")
    row = approach_row(model, model.start(), rest)
    assert row["speed_error"] > 10 and not row["steady"]
    assert approach_check(model, model.start(), home, [rest]) is None
