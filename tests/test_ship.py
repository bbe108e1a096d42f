"""The surface-ship model (bayesid.models.ship), the multiple-shooting fit and the window protocol on
ships (bayesid.estimation.identification), and the fit / predict / diagnose commands on real runs (skipped without
shared/data/real)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bayesid.data.track import Track
from bayesid.estimation import windows as wf
from bayesid.estimation.identification import identify
from bayesid.estimation.indices import manoeuvre_indices
from bayesid.estimation.options import FitOptions
from bayesid.estimation.prediction import predict
from bayesid.models import ship
from bayesid.models.ship import dynamics as shipdyn

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
KV = REAL / "kvlcc2-simman-hsva"
ROOT = Path(__file__).resolve().parents[1]


def synthetic(model, p, t, delta, rps, U0, rng=None, noise=None, name="syn"):
    """A track of the model itself from straight-ahead motion at U0 (noise sd per channel)."""
    base = Track(
        t,
        {
            "x": 0 * t,
            "y": 0 * t,
            "psi": 0 * t,
            "u": 0 * t + U0,
            "v": 0 * t,
            "r": 0 * t,
            "delta_r": delta,
            "n": 0 * t + rps * 60,
        },
        name=name,
    )
    s0 = np.zeros(12)
    s0[6] = U0
    ctx = model.context(base, None, s0=s0)
    S = model.simulate(ctx, np.asarray(p)[None], measured_start=False)[0]
    data = {"delta_r": delta[ctx.idx], "n": base["n"][ctx.idx]}
    for i, k in ((0, "x"), (1, "y"), (5, "psi"), (6, "u"), (7, "v"), (11, "r")):
        sd = (noise or {}).get(k, 0.0)
        data[k] = S[:, i] + (rng.normal(0, sd, S.shape[0]) if sd else 0.0)
    return Track(ctx.ts, data, name=name)


def zigzag_inputs(t, amp_deg=20.0, period=30.0):
    return np.where(np.sin(2 * np.pi * t / period) >= 0, -1.0, 1.0) * math.radians(amp_deg) * (t > 2)


NOISE = {"x": 0.01, "y": 0.01, "psi": math.radians(0.05), "u": 0.002, "v": 0.002, "r": math.radians(0.02)}


def _noisy_zigzag():
    """(nominal KVLCC2, a 120 s noisy zigzag of the truth Nr -0.07 / Yv -0.25, the noise sds)."""
    kv = ship.load_ship("kvlcc2_7m")
    mt = ship.ShipModel(kv.with_coefficients({"Nr": -0.07, "Yv": -0.25}), dt=0.1)
    t = np.arange(0, 120.0, 0.1)
    return kv, synthetic(mt, mt.start(), t, zigzag_inputs(t), 10.23, 1.179, np.random.default_rng(11), NOISE), NOISE


def test_packaged_ship_files_load_with_empirical_added_mass():
    kv = ship.load_ship("kvlcc2_7m")
    es = ship.load_ship("esso_osaka_3m")
    # Clarke et al. (1983) estimates against the MMG-published KVLCC2 values (Yasukawa & Yoshimura 2015)
    assert kv.coefficients["my"] == pytest.approx(0.223, rel=0.15)
    assert kv.coefficients["Jz"] == pytest.approx(0.011, rel=0.2)
    assert 0.01 < kv.coefficients["mx"] < 0.06
    assert es.wind_start["Cy1"] < 0 and all(es.coefficients[k] == 0.0 for k in ship.WIND)
    assert set(kv.free) <= set(ship.COEFFICIENTS)


def test_ship_file_with_unknown_coefficient_names_it(tmp_path):
    src = (ROOT / "bayesid" / "vehicles" / "kvlcc2_7m.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(src.replace("Yvrr = -0.391", "Yvrrq = -0.391"))
    with pytest.raises(ship.ShipFileError, match="Yvrrq") as e:
        ship.load_ship(bad)
    assert "bad.toml" in str(e.value)
    with pytest.raises(ship.ShipFileError, match="D_prop"):
        bad.write_text(src.replace("D_prop = 0.204\n", ""))
        ship.load_ship(bad)


def test_starboard_rudder_turns_to_starboard_and_speed_settles():
    kv = ship.load_ship("kvlcc2_7m")
    m = ship.ShipModel(kv, dt=0.1)
    t = np.arange(0, 120.0, 0.1)
    tr = synthetic(m, m.start(), t, np.where(t > 1, -math.radians(20), 0.0), 10.23, 1.179)
    assert tr["r"][-1] > math.radians(0.3)  # package rudder negative = to starboard: r > 0
    straight = synthetic(m, m.start(), t, 0 * t, 10.23, 1.179)
    du = np.abs(np.diff(straight["u"][-100:])).max()
    assert du < 1e-4 and 0.7 < straight["u"][-1] < 1.6  # settles at a plausible self-propulsion speed


def test_neutral_rudder_angle_shifts_the_rudder_zero():
    """With dR0 = a, the rudder at a gives the forces of the rudder at 0 with dR0 = 0, and the
    rudder at 0 gives a yaw moment of the sign of a rudder at -a."""
    kv = ship.load_ship("kvlcc2_7m")
    a = math.radians(2.0)
    s = np.array([[0, 0, 0, 1.1, 0.0, 0.0]], float)

    def F(delta, dR0):
        out = np.empty((1, 3))
        shipdyn.forces(s, np.array([[delta, 10.0]]), np.zeros((1, 2)), np.zeros(2), kv.params({"dR0": dR0}), out)
        return out[0]

    np.testing.assert_allclose(F(a, a), F(0.0, 0.0), rtol=1e-12, atol=1e-12)
    assert abs(F(0.0, 0.0)[2]) < 1e-12
    assert np.sign(F(0.0, a)[2]) == np.sign(F(-a, 0.0)[2]) != 0


@pytest.mark.parametrize(
    "state,n",
    [
        ((0, 0, 0, 0.0, 0.0, 0.0), 0.0),
        ((0, 0, 0, 0.0, 0.0, 0.2), 5.0),
        ((0, 0, 0, -0.3, 0.1, 0.05), -8.0),
        ((0, 0, 0, 0.0, 0.4, 0.0), 10.0),
        ((0, 0, 0, 1e-9, 0.0, 0.3), 0.0),
    ],
)
def test_forces_finite_at_low_speed_astern_and_on_the_spot(state, n):
    es = ship.load_ship("esso_osaka_3m")
    prm = es.params(es.wind_start)
    out = np.empty((1, 3))
    shipdyn.accelerations(np.array([state], float), np.array([[0.3, n]]), np.array([[1.0, 2.0]]), np.zeros(2), prm, out)
    assert np.all(np.isfinite(out))


def test_window_protocol_on_the_models_own_track_is_at_the_noise_level():
    kv = ship.load_ship("kvlcc2_7m")
    m = ship.ShipModel(kv, dt=0.1)
    rng = np.random.default_rng(3)
    t = np.arange(0, 180.0, 0.05)
    noise = {"x": 0.01, "y": 0.01, "psi": math.radians(0.05), "r": math.radians(0.02)}
    tr = synthetic(m, m.start(), t, zigzag_inputs(t), 10.23, 1.179, rng, noise)
    tr = Track(tr.t, {k: tr[k] for k in ("x", "y", "psi", "r", "delta_r", "n")}, name="syn")  # u, v unmeasured
    pr = predict(m, m.start(), [tr], 30.0)
    # noise 0.01 m: the start-state velocity (from 2 s of noisy positions) errs by a few mm/s,
    # which grows to ~0.1 m over 30 s; without noise the protocol reproduces the track exactly
    assert pr.pooled["rms_position_m"] < 0.2
    clean = synthetic(m, m.start(), t, zigzag_inputs(t), 10.23, 1.179)
    clean = Track(clean.t, {k: clean[k] for k in ("x", "y", "psi", "r", "delta_r", "n")}, name="clean")
    assert predict(m, m.start(), [clean], 30.0).pooled["rms_position_m"] < 0.02
    ctx = m.context(tr, 30.0)
    # windows never overlap, and start after 2 s of history when velocities are derived
    assert np.all(np.diff(ctx.t_start) == pytest.approx(30.0)) and ctx.t_start[0] >= tr.t[0] + 2.0 - 1e-9
    # a window's start state never uses data from its future: change the future, same state
    fut = Track(
        tr.t,
        {
            k: np.where(tr.t > ctx.t_start[2] + 1e-9, 0.0 if k != "n" else 600.0, tr[k])
            for k in ("x", "y", "psi", "r", "delta_r", "n")
        },
        name="fut",
    )
    assert np.allclose(m.context(fut, 30.0).s_meas[2], ctx.s_meas[2])


def test_multiple_shooting_fit_recovers_coefficients_from_the_equation_error_seed():
    kv = ship.load_ship("kvlcc2_7m")
    truth = kv.with_coefficients({"Yv": -0.35, "Nr": -0.055, "Nv": -0.12})
    mt = ship.ShipModel(truth, dt=0.1)
    rng = np.random.default_rng(7)
    t = np.arange(0, 150.0, 0.1)
    noise = {"x": 0.01, "y": 0.01, "psi": math.radians(0.05), "u": 0.002, "v": 0.002, "r": math.radians(0.02)}
    tracks = [
        synthetic(mt, mt.start(), t, zigzag_inputs(t, a, p), 10.23, 1.179, rng, noise, name=f"z{a}")
        for a, p in ((20, 30), (10, 24))
    ]
    res = identify(kv, tracks, FitOptions(free=("Yv", "Nv", "Nr"), window_s=30.0, dt=0.1, max_nfev=30))
    est = dict(zip(res.model.param_names, res.fit.p))
    assert est["Yv"] == pytest.approx(-0.35, rel=0.05)
    assert est["Nv"] == pytest.approx(-0.12, rel=0.05)
    assert est["Nr"] == pytest.approx(-0.055, rel=0.05)
    assert res.seed["used"] or res.seed.get("cost_seed") is not None


def test_residual_weighting_follows_the_structural_error():
    """Two-step feasible GLS: the second fit's channel sds are the first fit's residual RMS, at
    least the noise sd; on the model's own noisy track they stay near the noise; with a model
    that cannot fit (wrong free set) they grow above it."""

    kv, tr, noise = _noisy_zigzag()
    sd = {k: noise[k] for k in ("x", "y", "psi", "u", "v", "r")}
    right = ship.ShipModel(kv, ["Nr", "Yv"], dt=0.1)
    ctx = [right.context(tr, 30.0)]
    f, sd2 = wf.fit_weighted(wf.WindowProblem(right, ctx, sd, max_nfev=20), weighting="residual")
    assert set(sd2) == set(sd) and all(sd2[k] >= sd[k] for k in sd)
    # the model is right: residuals ~ noise (x, y, psi ~3x: the start-state noise propagates)
    assert all(sd2[k] < 5 * sd[k] for k in sd)
    assert dict(zip(right.param_names, f.p))["Nr"] == pytest.approx(-0.07, rel=0.05)
    wrong = ship.ShipModel(kv, ["Xuu"], dt=0.1)  # cannot change the turning: structural error
    cw = [wrong.context(tr, 30.0)]
    fw, sdw = wf.fit_weighted(wf.WindowProblem(wrong, cw, sd, max_nfev=10), weighting="residual")
    assert sdw["psi"] > 5 * sd2["psi"] and sdw["x"] > 5 * sd2["x"]
    assert sdw == pytest.approx(
        wf.residual_sd(wrong, wf.fit_model(wf.WindowProblem(wrong, cw, sd, max_nfev=10)), cw, sd), rel=0.2
    )
    with pytest.raises(ValueError, match="weighting"):
        wf.fit_weighted(wf.WindowProblem(right, ctx, sd), weighting="robust")


def test_fit_channels_leave_a_corrupted_velocity_channel_out_of_the_objective(tmp_path, capsys):
    """A logged yaw rate with a slow calibration error (1 deg/s, zero at the window starts, so
    the start states hardly see it) pulls Yv off by > 8 % when every channel is fitted; fitting
    x, y, psi only recovers it within 2 %. Unknown channels and a track measuring none of the
    fitted channels are errors that name them."""
    from bayesid import cli

    kv, tr, noise = _noisy_zigzag()
    bad = tr.with_columns(r=tr["r"] + math.radians(1.0) * np.sin(2 * np.pi * tr.t / 30.0))
    m = ship.ShipModel(kv, ["Nr", "Yv"], dt=0.1)
    ctx = [m.context(bad, 30.0)]
    every = wf.fit_model(wf.WindowProblem(m, ctx, noise, max_nfev=20))
    pos = wf.fit_model(wf.WindowProblem(m, ctx, noise, channels=("x", "y", "psi"), max_nfev=20))
    assert pos.channels == ("x", "y", "psi") and pos.n_residuals == every.n_residuals // 2
    assert dict(zip(m.param_names, pos.p))["Yv"] == pytest.approx(-0.25, rel=0.02)
    assert dict(zip(m.param_names, pos.p))["Nr"] == pytest.approx(-0.07, rel=0.05)
    assert abs(dict(zip(m.param_names, every.p))["Yv"] / -0.25 - 1) > 0.08
    res = identify(
        kv, [bad], FitOptions(free=("Nr", "Yv"), window_s=30.0, dt=0.1, max_nfev=20, channels=("x", "y", "psi"))
    )
    assert res.fit.channels == ("x", "y", "psi") and np.all(np.isfinite(res.cov))
    with pytest.raises(ValueError, match="'q'|q;"):
        wf.fit_model(wf.WindowProblem(m, ctx, noise, channels=("x", "q")))
    no_u = Track(tr.t, {k: tr[k] for k in ("x", "y", "psi", "delta_r", "n")}, name="no_velocities")
    with pytest.raises(ValueError, match="no_velocities"):
        wf.fit_model(wf.WindowProblem(m, [m.context(no_u, 30.0)], noise, channels=("u",)))
    from bayesid.data.track import write_csv

    write_csv(bad, tmp_path / "bad.csv")
    rc = cli.main(
        [
            "fit",
            "--vehicle",
            "kvlcc2_7m",
            "--train",
            str(tmp_path / "bad.csv"),
            "--free",
            "Yv",
            "--fit-channels",
            "x,y,heading",
            "--out",
            str(tmp_path / "fit"),
        ]
    )
    assert rc != 0 and "heading" in capsys.readouterr().err


def test_ship_fits_use_the_ship_fit_window_whatever_the_scoring_window():
    """``bayesid diagnose --score-window 60`` on a ship scores 60 s windows but fits over
    ``ship.FIT_WINDOW_S`` (15 s) ones, and so does ``identify`` without a window; an
    explicit fit window wins."""
    from bayesid.analysis import gap

    kv = ship.load_ship("kvlcc2_7m")
    mt = ship.ShipModel(kv, dt=0.2)
    t = np.arange(0, 130.0, 0.2)
    tracks = [
        synthetic(mt, mt.start(), t, zigzag_inputs(t, a, p), 10.23, 1.179, name=f"z{a}")
        for a, p in ((20, 30), (10, 24))
    ]
    kw = dict(candidates=["delay"], window_s=60.0, dt=0.2, max_nfev=1)
    res = gap.diagnose(kv, ["Nr"], tracks[:1], tracks[1:], gap.DiagnoseOptions(**kw)).to_dict()
    assert res["settings"]["fit_window_s"] == ship.FIT_WINDOW_S == 15.0 and res["settings"]["window_s"] == 60.0
    assert (
        gap.diagnose(kv, ["Nr"], tracks[:1], tracks[1:], gap.DiagnoseOptions(fit_window_s=45.0, **kw)).to_dict()[
            "settings"
        ]["fit_window_s"]
        == 45.0
    )
    assert identify(kv, tracks[:1], FitOptions(free=("Nr",), dt=0.2, max_nfev=1)).window_s == 15.0


def test_paired_window_test_detects_a_consistent_improvement():
    from bayesid.analysis import gap

    rng = np.random.default_rng(0)
    before = rng.uniform(0.5, 1.5, 40)
    assert gap.paired_window_test(before, before * 0.8) < 1e-6
    assert gap.paired_window_test(before, before * 1.2) > 0.99
    assert gap.paired_window_test(before[:4], before[:4] * 0.5) == 1.0  # too few windows


def test_manoeuvre_indices_of_a_circle_and_a_zigzag():
    t = np.linspace(0, 100, 2001)
    R = 20.0
    w = 0.1
    psi = np.where(t > 10, w * (t - 10), 0.0)
    x = np.where(t > 10, 10 + R * np.sin(psi), t)
    y = np.where(t > 10, R * (1 - np.cos(psi)), 0.0)
    d = np.where(t > 10, -0.6, 0.0)
    ind = manoeuvre_indices(t, x, y, psi, d)
    assert ind["kind"] == "turning"
    assert ind["tactical_diameter_m"] == pytest.approx(2 * R, rel=0.01)
    assert ind["advance_m"] == pytest.approx(R, rel=0.01)  # from the execute position
    # the rudder reverses where the heading passes +-10 deg outwards (t = 4.65 s, then every 20 s);
    # the heading peaks at 15 deg: the overshoot from the check heading is 15 - h(4.65 s)
    h = np.radians(15) * np.sin(2 * np.pi * t / 40)
    dz = np.where(((t - 4.65) % 40) < 20, -0.35, 0.35)
    zi = manoeuvre_indices(t, 0 * t, 0 * t, h, dz)
    expect = 15 - 15 * np.sin(2 * np.pi * 4.65 / 40)
    assert zi["kind"] == "zigzag" and zi["first_overshoot_deg"] == pytest.approx(expect, abs=0.1)  # one sample


@pytest.mark.skipif(not KV.is_dir(), reason="shared/data/real absent")
def test_fit_predict_diagnose_commands_on_two_converted_runs(tmp_path):
    runs = [KV / "HSVA_CPMC_KVLCC2_Z_10_10_P.dat", KV / "HSVA_CPMC_KVLCC2_Z_10_10_S.dat"]
    conv = tmp_path / "csv"
    py = [sys.executable, "-m", "bayesid.cli"]
    subprocess.run(py + ["convert", "--format", "simman-hsva", *map(str, runs), "--out", str(conv)], check=True)
    a, b = sorted(conv.glob("*.csv"))
    subprocess.run(
        py
        + [
            "fit",
            "--vehicle",
            "kvlcc2_7m",
            "--train",
            str(a),
            "--free",
            "Yv,Nr",
            "--max-nfev",
            "3",
            "--out",
            str(tmp_path / "fit"),
        ],
        check=True,
    )
    doc = json.loads((tmp_path / "fit" / "model.json").read_text())
    assert doc["param_names"] == ["Yv", "Nr"] and len(doc["cov"]) == 2
    subprocess.run(
        py
        + [
            "predict",
            "--model",
            str(tmp_path / "fit" / "model.json"),
            "--track",
            str(b),
            "--score-window",
            "30",
            "--draws",
            "3",
            "--out",
            str(tmp_path / "pred"),
        ],
        check=True,
    )
    pr = json.loads((tmp_path / "pred" / "predict.json").read_text())
    assert pr["window_s"] == 30 and pr["pooled"]["rms_position_m"] > 0 and pr["windows"]
    assert pr["indices"][b.stem]["measured"]["kind"] == "zigzag"
    subprocess.run(
        py
        + [
            "diagnose",
            "--vehicle",
            "kvlcc2_7m",
            "--free",
            "Yv,Nr",
            "--train",
            str(a),
            "--heldout",
            str(b),
            "--score-window",
            "30",
            "--candidates",
            "delay",
            "--max-nfev",
            "2",
            "--no-discover",  # the round's ranking is what this test reads; discovery has its own
            "--out",
            str(tmp_path / "diag"),
        ],
        check=True,
    )
    dg = json.loads((tmp_path / "diag" / "diagnosis.json").read_text())
    assert dg["settings"]["window_s"] == 30 and dg["ranking"][0]["effect"] == "delay"
    assert dg["settings"]["weighting"] == "residual" and {"cause", "contributors", "remainder"} <= set(dg)
    assert 0.0 <= dg["ranking"][0]["window_p_value"] <= 1.0


@pytest.mark.skipif(not REAL.is_dir(), reason="shared/data/real absent")
def test_real_ships_quick_writes_results(tmp_path):
    subprocess.run(
        [sys.executable, str(ROOT / "studies" / "real_ships.py"), "--quick", "--out", str(tmp_path)],
        check=True,
        cwd=ROOT,
    )
    R = json.loads((tmp_path / "results.json").read_text())
    for ds in ("esso_osaka", "kvlcc2_hsva"):
        d = R[ds]
        for k in (
            "train_runs",
            "heldout_runs",
            "window_s",
            "heldout_rms_position_m_base",
            "heldout_rms_position_m_after",
            "verdict",
            "ranking",
            "shrinkage",
            "w30",
            "w60",
            "whole_run",
        ):
            assert k in d, (ds, k)
        for w in ("w30", "w60"):
            assert set(d[w]) >= {"heldout_rms_position_m_base", "heldout_rms_position_m_after", "shrinkage"}
        assert not set(d["train_runs"]) & set(d["heldout_runs"])
    lit = R["kvlcc2_hsva"]["literature_baseline"]
    assert all(lit[w] > 0 for w in ("w30", "w60", "whole_run"))
    assert set(lit["turning_circles_35deg"]) == {"starboard", "port"}
    assert lit["coefficients"]["Yv"] == pytest.approx(ship.load_ship("kvlcc2_7m").coefficients["Yv"])


@pytest.mark.parametrize("g_deg", [30.0, 90.0, 125.0, -60.0])
def test_wind_loads_follow_the_fourier_form(g_deg):
    """Ship at rest heading north, true wind from g off the bow: the loads are Fujiwara's
    truncated series, each harmonic with its own coefficient (Cn3 sin 3g included)."""
    es = ship.load_ship("esso_osaka_3m")
    c = {"Cx1": -0.7, "Cx3": 0.1, "Cy1": -0.8, "Cy3": 0.05, "Cn1": 0.02, "Cn2": -0.05, "Cn3": 0.03}
    g, VA = math.radians(g_deg), 3.0
    wind = np.array([[-VA * math.cos(g), -VA * math.sin(g)]])  # velocity it blows with (north, east)
    s = np.zeros((1, 6))
    F = {}
    for key, coef in (("on", c), ("off", {k: 0.0 for k in c})):
        out = np.empty((1, 3))
        shipdyn.forces(s, np.array([[0.0, 0.0]]), wind, np.zeros(2), es.params(coef), out)
        F[key] = out[0]
    pr, qa = es.particulars, 0.5 * es.particulars["rho_air"] * VA**2
    want = [
        qa * pr["A_front"] * (c["Cx1"] * math.cos(g) + c["Cx3"] * math.cos(3 * g)),
        qa * pr["A_lateral"] * (c["Cy1"] * math.sin(g) + c["Cy3"] * math.sin(3 * g)),
        qa
        * pr["A_lateral"]
        * pr["L"]
        * (c["Cn1"] * math.sin(g) + c["Cn2"] * math.sin(2 * g) + c["Cn3"] * math.sin(3 * g)),
    ]
    np.testing.assert_allclose(F["on"] - F["off"], want, rtol=1e-10, atol=1e-12)
