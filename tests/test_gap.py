"""Gap diagnosis (issue 5): effect catalogue, window protocol, diagnose(), bayesid diagnose,
studies/sim_to_real.py --quick."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import load_study

from bayesid import cli, protocol
from bayesid.analysis import gap
from bayesid.data.track import write_csv
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation import windows as wf
from bayesid.estimation.fit import FitResult
from bayesid.models import effects as ef
from bayesid.models import manoeuvres as mv
from bayesid.models.context import errors
from bayesid.models.submarine import EffectModel
from bayesid.models.world import WORLD_NOISE, LogOptions, draw_parameters, world_track

ROOT = Path(__file__).resolve().parents[1]
FREE = ["Yv", "Nr", "Ndr"]


@pytest.fixture(scope="module")
def veh():
    return load_vehicle("nps_auv2")


@pytest.fixture(scope="module")
def scenario(veh):
    """Short training and held-out manoeuvres (inputs only; the world adds the effect)."""
    train = [
        mv.zigzag(veh, 20.0, dt=0.1, duration=150.0),
        mv.prbs(veh, 15.0, duration=150.0, rng=np.random.default_rng(1)),
    ]
    held = [mv.zigzag(veh, 10.0, dt=0.1, duration=150.0, first_sign=-1)]
    return train, held


def world(veh, scenario, effects, seed):
    rng = np.random.default_rng(seed)
    tm, hm = scenario
    train = [world_track(veh, m, effects, rng, name=f"train_{m.name}") for m in tm]
    held = [world_track(veh, m, effects, rng, name=f"heldout_{m.name}") for m in hm]
    return train, held


# --- protocol -----------------------------------------------------------------------------
def test_windows_do_not_overlap_and_cover_the_run():
    t = np.arange(0, 125.01, 0.1)
    s = protocol.window_starts(t, 30.0)
    assert np.allclose(s, [0, 30, 60, 90, 120])
    assert np.all(np.diff(s) == 30.0)
    assert np.allclose(protocol.window_starts(t, None), [0.0])
    with pytest.raises(ValueError):
        protocol.window_starts(t, 0.0)


def test_window_start_state_uses_no_future_data(veh):
    m = mv.zigzag(veh, 20.0, dt=0.1, duration=60.0)
    tr = world_track(veh, m, {}, np.random.default_rng(0))
    t0 = 30.0
    s1 = protocol.state_at(tr, t0)
    late = tr.t > t0
    garbled = tr.with_columns(**{k: np.where(late, tr[k] + 100.0, tr[k]) for k in ("x", "y", "psi", "u", "v", "r")})
    assert np.array_equal(protocol.state_at(garbled, t0), s1)
    # but the past does count
    early = (tr.t <= t0) & (tr.t > t0 - 1.0)
    moved = tr.with_columns(x=np.where(early, tr["x"] + 5.0, tr["x"]))
    assert protocol.state_at(moved, t0)[0] != s1[0]


def test_noise_estimate_recovers_the_sd(veh):
    m = mv.zigzag(veh, 20.0, dt=0.1, duration=120.0)
    tr = world_track(veh, m, {}, np.random.default_rng(3))
    sd = protocol.estimate_noise(tr, ["x", "psi", "u", "r"])
    for k in sd:
        assert sd[k] == pytest.approx(WORLD_NOISE[k], rel=0.25), k  # r: rudder steps are not smooth at 10 Hz


def test_protocol_on_the_models_own_track_is_at_the_noise_level(veh):
    """The window protocol with the true model on its own noisy track: the pooled error is the
    noise floor (well under a metre), and the nominal model reproduces a noise-free track."""
    m = mv.zigzag(veh, 20.0, dt=0.1, duration=180.0)
    clean = world_track(veh, m, {}, np.random.default_rng(0), LogOptions(noise={}))
    model = EffectModel(veh, (), (), dt=0.1)
    ctx = model.context(clean, None)
    e = errors(ctx, model.simulate(ctx, model.start()[None]))
    assert np.max(np.abs(e["x"])) < 1e-6 and np.max(np.abs(e["psi"])) < 1e-8
    noisy = world_track(veh, m, {}, np.random.default_rng(1))
    model = EffectModel(veh, (), (), dt=0.5)
    ctx = model.context(noisy, 60.0)
    sc = protocol.pooled_scores([{k: v[0] for k, v in errors(ctx, model.simulate(ctx, model.start()[None])).items()}])
    assert 0.15 < sc["rms_position_m"] < 1.0
    assert ctx.W == 3 and list(ctx.starts) == [0, 120, 240, 360]


# --- effects ------------------------------------------------------------------------------
def test_catalogue_has_the_issues_effects_with_sources():
    assert set(ef.CATALOGUE) >= {"current", "actuator", "delay", "sensor_bias", "crossflow", "thrust", "roll", "waves"}
    for e in ef.CATALOGUE.values():
        assert len(e.magnitudes) == 3 and e.source and e.description
        assert len(e.params) == len(e.lo) == len(e.hi) == len(e.start) == len(e.scale)
        for mag in e.magnitudes:
            for k, v in draw_parameters(e.name, e.magnitudes.index(mag), np.random.default_rng(0)).items():
                i = e.params.index(k)
                assert e.lo[i] <= v <= e.hi[i], (e.name, k)
    with pytest.raises(ValueError, match="unknown effect 'tide'"):
        ef.get("tide")


def test_the_nesting_effects_declare_a_neutral_value_inside_their_bounds():
    nesting = {n for n, e in ef.CATALOGUE.items() if e.neutral is not None}
    assert nesting == {"thrust", "actuator", "delay", "current", "sensor_bias", "waves", "sensor_lag"}
    for n in nesting:
        e = ef.CATALOGUE[n]
        assert all(lo <= v <= hi for lo, v, hi in zip(e.lo, e.neutral, e.hi)), n


@pytest.mark.parametrize("name", ["thrust", "actuator", "delay", "current", "sensor_bias", "waves", "sensor_lag"])
def test_an_effect_at_its_neutral_value_changes_nothing(veh, name):
    """Thrust scale 1, no lag and an unlimited rate, no delay, zero current, zero bias, zero
    wave amplitude (the catalogue's ``neutral``): the effect model reproduces the base model."""
    m = mv.zigzag(veh, 20.0, dt=0.1, duration=60.0)
    tr = world_track(veh, m, {}, np.random.default_rng(0))
    base = EffectModel(veh, (), (), dt=0.5)
    cb = base.context(tr, 30.0)
    Sb = base.simulate(cb, base.start()[None])
    e = ef.get(name)
    neutral = e.neutral
    em = EffectModel(veh, (), (name,), dt=0.5)
    ce = em.context(tr, 30.0)
    Se = em.simulate(ce, np.array(neutral)[None], np.zeros((1, max(e.n_nuisance, 1))))
    assert np.max(np.abs(Se - Sb)) < 1e-9


def test_sensor_lag_filters_the_logged_velocities_and_skews_the_positions(veh):
    """Logged u, v, r = the true ones through the discrete first-order lag (scipy.signal.lfilter
    as the oracle); logged x, y = the true position skew_s earlier (first order in skew)."""
    from scipy import signal

    m = mv.zigzag(veh, 20.0, dt=0.1, duration=90.0)
    true = world_track(veh, m, {}, np.random.default_rng(0), LogOptions(noise={}))
    lag = world_track(
        veh, m, {"sensor_lag": {"lag_s": 1.0, "skew_s": 0.0}}, np.random.default_rng(0), LogOptions(noise={})
    )
    a = np.exp(-0.1 / 1.0)
    for k in ("u", "v", "r"):
        want, _ = signal.lfilter([1 - a], [1, -a], true[k], zi=[a * true[k][0]])
        assert np.allclose(lag[k], want, rtol=0, atol=1e-12 * max(1.0, np.abs(want).max())), k
    assert np.allclose(lag["x"], true["x"]) and np.allclose(lag["psi"], true["psi"])
    skew = world_track(
        veh, m, {"sensor_lag": {"lag_s": 0.0, "skew_s": 0.5}}, np.random.default_rng(0), LogOptions(noise={})
    )
    late = np.interp(true.t - 0.5, true.t, true["x"])
    sel = true.t > 1.0
    assert np.max(np.abs(skew["x"][sel] - late[sel])) < 0.01
    assert np.allclose(skew["u"], true["u"])


def test_current_acts_through_the_relative_velocity(veh):
    """Noise-free world with a current = the model with the same current, to round-off; and the
    track drifts by V_c t against the same vehicle without current."""
    m = mv.zigzag(veh, 20.0, dt=0.1, duration=60.0)
    par = {"current_north_mps": 0.2, "current_east_mps": -0.1}
    tr = world_track(veh, m, {"current": par}, np.random.default_rng(0), LogOptions(noise={}))
    still = world_track(veh, m, {}, np.random.default_rng(0), LogOptions(noise={}))
    assert tr["x"][-1] - still["x"][-1] == pytest.approx(0.2 * 60.0, abs=1e-9)
    assert tr["y"][-1] - still["y"][-1] == pytest.approx(-0.1 * 60.0, abs=1e-9)
    model = EffectModel(veh, (), ("current",), dt=0.1)
    ctx = model.context(tr, 20.0)
    e = errors(ctx, model.simulate(ctx, np.array([[0.2, -0.1]])))
    assert np.max(np.abs(e["x"])) < 0.05 and np.max(np.abs(e["y"])) < 0.1  # window starts from a 1 s causal fit


# --- diagnosis: each effect named ---------------------------------------------------------
CASES = {  # effect -> (level, distractor candidates)
    "current": (2, ["thrust", "sensor_bias"]),
    "actuator": (2, ["delay", "waves"]),
    "delay": (2, ["current", "thrust"]),
    # a heading bias drifts the track sideways like a cross current while the heading stays near
    # one value; on these 150 s tracks current wins on held-out RMS (0.54 vs 0.68 m), so the
    # current is not a distractor here (the 240 s benchmark separates them: 2 of 3 right).
    "sensor_bias": (0, ["thrust", "delay"]),
    "crossflow": (2, ["thrust", "delay"]),
    "thrust": (2, ["current", "crossflow"]),
    # roll coupling shows as extra sway/yaw damping: on these short tracks the cross-flow
    # candidate beats it (0.56 vs 0.61 m held-out), so cross-flow is not a distractor here; the
    # benchmark's roll cases (1 of 3 right) are the honest measure.
    "roll": (2, ["thrust", "current"]),
    "waves": (2, ["actuator", "current"]),
}


@pytest.mark.parametrize(
    "effect",
    [
        pytest.param(
            e,
            marks=pytest.mark.xfail(
                strict=True,
                reason="known weakness: the 1-parameter roll candidate removes only 17 % of the "
                "held-out excess on 150 s tracks (verdict 'none'); benchmark: roll 1/3",
            ),
        )
        if e == "roll"
        else e
        for e in CASES
    ],
)
def test_diagnosis_names_the_withheld_effect(veh, scenario, effect):
    level, distractors = CASES[effect]
    truth = {effect: draw_parameters(effect, level, np.random.default_rng(4))}
    train, held = world(veh, scenario, truth, seed=11)
    res = gap.diagnose(
        veh,
        FREE,
        train,
        held,
        gap.DiagnoseOptions(candidates=[effect] + distractors, window_s=60.0, max_nfev=40),
        rng=np.random.default_rng(0),
    ).to_dict()
    assert res["verdict"] == effect, (
        res["verdict"],
        [(r["effect"], r["heldout_rms_m"], r["excess_removed"], r["delta_bic"]) for r in res["ranking"]],
    )
    assert res["gap_after"]["heldout_rms_m"] < res["gap_before"]["heldout_rms_m"]
    assert res["gap_after"]["heldout_log_likelihood"] > res["gap_before"]["heldout_log_likelihood"]


def test_scores_log_likelihood_is_the_gaussian_density_of_the_errors(veh):
    """``scores(..., sd=)``: sum over channels and finite samples of -e^2/(2 sd^2) - ln(sd sqrt(2 pi))."""
    m = mv.zigzag(veh, 20.0, dt=0.1, duration=60.0)
    tr = world_track(veh, m, {"thrust": {"thrust_scale": 0.8}}, np.random.default_rng(3))
    model = EffectModel(veh, ("Nr",), (), dt=0.5)
    ctx = [model.context(tr, 30.0)]
    f = FitResult.fixed(model, model.start(), 1)
    sd = {c: 0.5 + i for i, c in enumerate(protocol.CHANNELS)}
    e = errors(ctx[0], model.simulate(ctx[0], f.p[None]))
    want = sum(
        float(np.sum(-0.5 * (v[0][np.isfinite(v[0])] / sd[c]) ** 2 - np.log(sd[c] * np.sqrt(2 * np.pi))))
        for c, v in e.items()
    )
    assert wf.scores(model, f, ctx, sd=sd)["log_likelihood"] == pytest.approx(want, rel=1e-12)
    assert "log_likelihood" not in wf.scores(model, f, ctx)


def test_no_effect_gives_none_and_a_missing_candidate_gives_unexplained(veh, scenario):
    train, held = world(veh, scenario, {}, seed=21)
    res = gap.diagnose(
        veh,
        FREE,
        train,
        held,
        gap.DiagnoseOptions(candidates=["current", "thrust", "delay"], max_nfev=40),
        rng=np.random.default_rng(0),
    ).to_dict()
    assert res["verdict"] == "none", res["gap_ratio"]
    assert res["gap_ratio"] < res["thresholds"]["none_ratio"]
    truth = {"current": draw_parameters("current", 2, np.random.default_rng(4))}
    train, held = world(veh, scenario, truth, seed=22)
    res = gap.diagnose(
        veh,
        FREE,
        train,
        held,
        gap.DiagnoseOptions(candidates=["thrust", "delay"], max_nfev=40),
        rng=np.random.default_rng(0),
    ).to_dict()
    assert res["verdict"] == "unexplained"
    assert res["significant_gap"]
    assert res["where"]["dominant_channel"] in ("x", "y", "u", "v")


def test_a_nesting_candidate_never_fits_the_training_tracks_worse_than_the_base_model(veh, scenario):
    """A candidate equals the base model at its neutral value, so its training dBIC is at most
    k ln n, even when its fits from the catalogue start stop early (4 evaluations here): the
    diagnosis then starts it once more at the base optimum. (Before the actuator's rate bound
    covered the logged rudder steps, no-effect benchmark cases showed actuator dBIC of +2e4.)"""
    train, held = world(veh, scenario, {}, seed=21)
    res = gap.diagnose(
        veh,
        FREE,
        train,
        held,
        gap.DiagnoseOptions(candidates=["actuator", "delay", "thrust"], max_nfev=4),
        rng=np.random.default_rng(0),
    ).to_dict()
    ln_n = np.log(res["base_fit"]["n_residuals"])
    for r in res["ranking"]:
        assert r["delta_bic"] <= len(r["parameters"]) * ln_n + 1e-6, (r["effect"], r["delta_bic"], r["parameters"])


def test_shrinkage_is_scored_on_held_out_tracks_disjoint_from_training(veh, scenario):
    truth = {"thrust": {"thrust_scale": 0.7}}
    train, held = world(veh, scenario, truth, seed=31)
    with pytest.raises(ValueError, match="overlap"):
        gap.diagnose(veh, FREE, train, [train[0]], gap.DiagnoseOptions(candidates=["thrust"])).to_dict()
    res = gap.diagnose(
        veh,
        FREE,
        train,
        held,
        gap.DiagnoseOptions(candidates=["thrust", "delay"], max_nfev=40),
        rng=np.random.default_rng(0),
    ).to_dict()
    assert set(res["train_tracks"]).isdisjoint(res["heldout_tracks"])
    assert res["heldout_tracks"] == [t.name for t in held]
    expect = 1 - res["gap_after"]["heldout_rms_m"] / res["gap_before"]["heldout_rms_m"]
    assert res["heldout_shrinkage"] == pytest.approx(expect)
    # the held-out score is the protocol on the held-out track, not on a training one
    model = EffectModel(veh, FREE, ("thrust",), dt=0.5)
    f = FitResult.fixed(
        model,
        np.r_[list(res["after_fit"]["coefficients"].values()), res["after_fit"]["effects"]["thrust"]["thrust_scale"]],
        1,
    )
    held_score = wf.scores(model, f, [model.context(t, 60.0) for t in held])["rms_position_m"]
    assert held_score == pytest.approx(res["gap_after"]["heldout_rms_m"], rel=1e-9)


# --- command line -------------------------------------------------------------------------
def test_bayesid_diagnose_writes_the_contract(veh, scenario, tmp_path):
    truth = {"actuator": draw_parameters("actuator", 2, np.random.default_rng(0))}
    train, held = world(veh, scenario, truth, seed=41)
    paths = []
    for tr in train + held:
        p = tmp_path / f"{tr.name}.csv"
        write_csv(tr, p)
        paths.append(str(p))
    out = tmp_path / "diag"
    rc = cli.main(
        [
            "diagnose",
            "--vehicle",
            "nps_auv2",
            "--free",
            ",".join(FREE),
            "--train",
            *paths[:2],
            "--heldout",
            paths[2],
            "--score-window",
            "60",
            "--candidates",
            "actuator,current",
            "--max-nfev",
            "30",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    d = json.loads((out / "diagnosis.json").read_text())
    for k in ("verdict", "ranking", "gap_before", "gap_after", "where"):
        assert k in d
    for k in ("train_rms_m", "heldout_rms_m", "heldout_max_m", "heading_rms_deg"):
        assert k in d["gap_before"] and k in d["gap_after"]
    for r in d["ranking"]:
        assert {"effect", "heldout_rms_m", "delta_bic", "parameters"} <= set(r)
    assert d["verdict"] == "actuator"
    assert (out / "report.md").exists() and (out / "figures" / "ranking.png").exists()


def test_bayesid_diagnose_names_bad_file_row_and_coefficient(veh, scenario, tmp_path, capsys):
    train, held = world(veh, scenario, {}, seed=51)
    good = tmp_path / "good.csv"
    write_csv(train[0], good)
    lines = good.read_text().splitlines()
    header_rows = sum(1 for ln in lines if ln.startswith("#")) + 1
    bad_row = header_rows + 5
    cells = lines[bad_row - 1].split(",")
    cells[2] = "oops"
    lines[bad_row - 1] = ",".join(cells)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    rc = cli.main(
        ["diagnose", "--vehicle", "nps_auv2", "--train", str(bad), "--heldout", str(good), "--out", str(tmp_path / "o")]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "bad.csv" in err and f"row {bad_row}" in err
    toml = (ROOT / "bayesid" / "vehicles" / "nps_auv2.toml").read_text().replace("Yv = -1.0e-1", "Yvv_typo = -1.0e-1")
    vfile = tmp_path / "typo.toml"
    vfile.write_text(toml)
    rc = cli.main(
        [
            "diagnose",
            "--vehicle",
            str(vfile),
            "--train",
            str(good),
            "--heldout",
            str(good),
            "--out",
            str(tmp_path / "o"),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "Yvv_typo" in err
    rc = cli.main(
        [
            "diagnose",
            "--vehicle",
            "nps_auv2",
            "--free",
            "Yv,Nfoo",
            "--train",
            str(good),
            "--heldout",
            str(good),
            "--out",
            str(tmp_path / "o"),
        ]
    )
    assert rc == 2 and "Nfoo" in capsys.readouterr().err


# --- study --------------------------------------------------------------------------------
def test_sim_to_real_quick_writes_results(tmp_path):
    out = tmp_path / "s2r"
    r = subprocess.run(
        [sys.executable, str(ROOT / "studies" / "sim_to_real.py"), "--quick", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.loads((out / "results.json").read_text())
    for k in (
        "confusion",
        "overall",
        "with_velocity_log",
        "without_velocity_log",
        "false_alarm_rate",
        "open_set_no_bare_name_rate",
        "cases",
    ):
        assert k in res
    assert len(res["cases"]) == 4
    for c in res["cases"]:
        assert {"truth", "verdict", "gap_before", "gap_after", "logging", "true_model"} <= set(c)
        assert c["logging"]["clock_start_s"] > 0 and c["start_rule"] == (
            "measured" if c["logging"]["velocity_log"] else "fitted"
        )
    assert (out / "report.md").exists() and (out / "manifest.json").exists()
    # a re-run resumes the journaled cases and reports the same; another seed is refused, naming it
    before = (out / "results.json").read_text()
    r = subprocess.run(
        [sys.executable, str(ROOT / "studies" / "sim_to_real.py"), "--quick", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert r.returncode == 0 and "4 case(s) resumed from" in r.stdout and ", 0 to run" in r.stdout, (
        r.stdout + r.stderr[-2000:]
    )
    assert (out / "results.json").read_text() == before
    r = subprocess.run(
        [sys.executable, str(ROOT / "studies" / "sim_to_real.py"), "--quick", "--out", str(out), "--seed", "7"],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert r.returncode == 2 and "seed: journal 2026, this run 7" in r.stderr and "Traceback" not in r.stderr


def test_the_benchmarks_true_model_reproduces_noise_free_world_tracks(veh, scenario):
    """The study's ceiling reference: the true model (nominal coefficients, the world's effect
    parameters and per-track wave phases) predicts noise-free held-out tracks as well as the
    protocol allows (0.28 m without any effect: windows start from a 1 s causal fit of a curving
    track), while the base model misses them by metres."""
    s2r = load_study("sim_to_real")
    truth = {
        "waves": draw_parameters("waves", 1, np.random.default_rng(0)),
        "thrust": draw_parameters("thrust", 2, np.random.default_rng(0)),
    }
    rng = np.random.default_rng(5)
    held = [world_track(veh, m, truth, rng, LogOptions(noise={}), name=f"heldout_{m.name}") for m in scenario[1]]
    true = s2r.true_model_scores(veh, held, truth, s2r.WINDOW, {"start_rule": "measured", "leadin_s": 0.0})[
        "heldout_rms_m"
    ]
    base = EffectModel(veh, s2r.FREE, (), dt=s2r.DT)
    fb = FitResult.fixed(base, base.start(), 1)
    missed = wf.scores(base, fb, [base.context(t, s2r.WINDOW) for t in held])["rms_position_m"]
    assert true < 0.35 and missed > 10 * true, (true, missed)


def test_two_simultaneous_effects_are_both_added_when_neither_explains_half_alone(veh):
    """Thrust deficit and waves together (240 s tracks, 16 held-out windows of 30 s): alone,
    thrust removes 0.39 and waves 0.36 of the held-out excess, so a one-round diagnosis says
    'unexplained'. With two greedy rounds the first (significant) effect is a stepping stone,
    the waves candidate starts from its own seeds on top of it, and the pair explains the gap."""
    D = 240.0
    tm = [mv.zigzag(veh, 20.0, dt=0.1, duration=D), mv.prbs(veh, 15.0, duration=D, rng=np.random.default_rng(1))]
    hm = [mv.zigzag(veh, 10.0, dt=0.1, duration=D, first_sign=-1), mv.multisine(veh, 15.0, duration=D)]
    truth = {
        "thrust": draw_parameters("thrust", 1, np.random.default_rng(0)),
        "waves": draw_parameters("waves", 1, np.random.default_rng(0)),
    }
    train, held = world(veh, (tm, hm), truth, seed=41)
    res = gap.diagnose(
        veh,
        FREE,
        train,
        held,
        gap.DiagnoseOptions(candidates=["thrust", "waves", "delay"], window_s=30.0, max_nfev=40, max_effects=2),
        rng=np.random.default_rng(0),
    ).to_dict()
    first = res["rounds"][0]
    assert all(r["excess_removed"] < res["thresholds"]["explain_fraction"] for r in first), [
        (r["effect"], r["excess_removed"]) for r in first
    ]
    assert sorted(res["effects_added"]) == ["thrust", "waves"], (res["verdict"], res["rounds"])
    assert res["gap_after"]["heldout_rms_m"] < 1.5 * res["noise_floor"]["heldout_rms_m"]


def test_scores_log_likelihood_leaves_out_channels_the_fit_had_no_sd_for(veh):
    """Training tracks without a yaw-rate log give fitted sds without ``r``; a held-out track
    that logs ``r`` is scored over the fitted channels only (it raised KeyError: 'r' before)."""
    m = mv.zigzag(veh, 20.0, dt=0.1, duration=60.0)
    tr = world_track(veh, m, {}, np.random.default_rng(0))
    model = EffectModel(veh, (), (), dt=0.5)
    ctx = [model.context(tr, 30.0)]
    f = FitResult.fixed(model, model.start(), 1)
    sd = {c: 0.5 + i for i, c in enumerate(protocol.CHANNELS)}
    assert "r" in errors(ctx[0], model.simulate(ctx[0], f.p[None]))  # the track logs r
    full = wf.scores(model, f, ctx, sd=sd)["log_likelihood"]
    part = wf.scores(model, f, ctx, sd={c: v for c, v in sd.items() if c != "r"})["log_likelihood"]
    assert np.isfinite(part) and part != full


def test_a_diagnosis_reads_back_from_its_json_and_writes_the_same_json(veh, scenario):
    """Issue 51: ``Diagnosis.from_dict`` of ``diagnosis.json`` gives the diagnosis whose JSON is that
    file (the models left out); a misspelt key is named."""
    from bayesid.analysis.gap.diagnose import Diagnosis
    from bayesid.tasks import jsonable

    truth = {"current": draw_parameters("current", 2, np.random.default_rng(4))}
    train, held = world(veh, scenario, truth, seed=22)
    d = gap.diagnose(veh, FREE, train, held, gap.DiagnoseOptions(candidates=["current"], max_nfev=4))
    text = json.dumps(jsonable(d.to_dict()), allow_nan=False)
    back = Diagnosis.from_dict(json.loads(text))
    assert back.verdict == d.verdict and back.base is None and back.discovered is None
    assert json.dumps(jsonable(back.to_dict()), allow_nan=False) == text
    raw = json.loads(text)
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['verdikt'\]"):
        Diagnosis.from_dict({**raw, "verdikt": raw["verdict"]})
    with pytest.raises(ValueError, match=r"missing key\(s\) \['gap_ratio'\]"):
        Diagnosis.from_dict({k: v for k, v in raw.items() if k != "gap_ratio"})
