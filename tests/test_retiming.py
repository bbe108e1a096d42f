"""When did the rudder move? Movements within single log intervals placed, found, and estimated
with the coefficients (``bayesid fit --inputs rate --retime``, issue 50)."""

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
from bayesid.estimation.retiming import project_timing
from bayesid.models import build_model
from bayesid.models import manoeuvres as mv
from bayesid.models.context import lone_moves, rate_limited_knots

FREE = ("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr")
CHI2_6_90 = 10.6446


def test_a_movement_within_one_interval_sits_where_it_is_placed():
    t = np.arange(6.0)
    u = np.radians([0.0, 0.0, 10.0, 10.0, 10.0, 10.0])  # 10 deg in interval 1 at 20 deg/s: 0.5 s
    rate = math.radians(20.0)
    for f, start in ((0.0, 1.0), (0.5, 1.25), (1.0, 1.5)):
        tk, uk = rate_limited_knots(t, u, rate, {1: f})
        assert np.interp(start - 1e-9, tk, uk) == pytest.approx(0.0, abs=1e-9)
        assert np.interp(start + 0.5 + 1e-9, tk, uk) == pytest.approx(u[2], abs=1e-9)
    # the default is the middle, as before the option
    assert np.array_equal(rate_limited_knots(t, u, rate)[0], rate_limited_knots(t, u, rate, {1: 0.5})[0])


def test_lone_moves_are_the_movements_within_single_intervals():
    t = np.arange(10.0)
    # a lone jump (interval 1), a ramp over intervals 3-5, a jump too large for the gear (7)
    u = np.radians([0, 0, 10, 10, 14, 18, 22, 22, 90, 90])
    assert lone_moves(t, u, math.radians(20.0)).tolist() == [1]
    assert lone_moves(t, u, math.radians(20.0), min_step=math.radians(20.0)).tolist() == []


def _reversals_between_samples(hz: float = 2.0, seed: int = 0) -> list:
    """NPS AUV II 20/20 zigzags to both sides whose instantaneous reversals fall between the log
    samples (decided every 0.01 s), logged at ``hz`` with 5 cm and 0.3 deg noise, no u, v, r."""
    veh = load_vehicle("nps_auv2")
    model = build_model(veh, dt=0.01)
    rng = np.random.default_rng(seed)
    k = int(round(1.0 / (hz * 0.01)))
    out = []
    for side in (1, -1):
        m = mv.zigzag(veh, 20, 20, dt=0.01, duration=100.0, first_sign=side)
        u = {c: np.append(m.inputs[:, j], m.inputs[-1, j]) for j, c in enumerate(INPUT_NAMES)}
        ctx = model.context(Track(m.t, u), None, s0=m.initial_state)
        S = model.simulate(ctx, model.start()[None], measured_start=False)[0]
        d = {c: S[::k, STATE_NAMES.index(c)].copy() for c in ("x", "y", "psi")}
        d["x"] += rng.normal(0.0, 0.05, d["x"].size)
        d["y"] += rng.normal(0.0, 0.05, d["y"].size)
        d["psi"] += rng.normal(0.0, math.radians(0.3), d["psi"].size)
        d.update({c: u[c][::k] for c in u})
        out.append(Track(m.t[::k], d, name=f"z20_{side}"))
    return out


def _d2(res) -> float:
    n = len(FREE)
    d = res.fit.p[:n] - load_vehicle("nps_auv2").coefficient_vector(list(FREE))
    return float(d @ np.linalg.solve(res.cov[:n, :n], d))


def test_retiming_the_reversals_makes_the_intervals_honest_where_mid_interval_does_not():
    # measured (reports/benchmark_reversal_timing.txt): the truth's Mahalanobis distance ~200
    # with every reversal mid-interval, inside the joint 90 % region once they are retimed
    train = _reversals_between_samples()
    base = dict(free=FREE, prior=False, inputs="rate", rudder_rate_deg_s=1000.0, max_nfev=40)
    mid = identify(load_vehicle("nps_auv2"), train, FitOptions(**base), calibration=None)
    timed = identify(load_vehicle("nps_auv2"), train, FitOptions(**base, retime=True), calibration=None)
    assert mid.retimed_moves is None
    assert _d2(timed) < CHI2_6_90 < _d2(mid)
    # every reversal (and the execute) found and placed; the sds widen by the timing
    moves = timed.retimed_moves
    assert set(moves) == {"z20_1", "z20_-1"} and all(len(v) >= 6 for v in moves.values())
    assert all(sd is not None and 0.0 < sd < 0.5 for v in moves.values() for _t, sd in v)
    # the times explain the misfit the middle leaves
    assert timed.train_scores["rms_position_m"] < 0.8 * mid.train_scores["rms_position_m"]
    # the execute at t = 10 s (between the samples 9.5 and 10.0): estimated near its true time
    first = min(t for t, _sd in moves["z20_1"])
    assert abs(first - 10.0) < 0.15


def test_retime_needs_the_rate_inputs_and_is_recorded(tmp_path, capsys):
    with pytest.raises(ValueError, match="--retime .* needs --inputs rate"):
        FitOptions(retime=True)
    track = tmp_path / "zz.csv"
    sim = ["simulate", "--manoeuvre", "zigzag", "--angle", "20", "--duration", "60", "--mode", "horizontal"]
    assert main([*sim, "--sample", "0.5", "--out", str(track)]) == 0
    args = ["fit", "--vehicle", "nps_auv2", "--train", str(track), "--free", "Yv,Nr", "--max-nfev", "3"]
    assert main([*args, "--retime", "--out", str(tmp_path / "bad")]) == 2
    assert "--inputs rate" in capsys.readouterr().err
    rate = ["--inputs", "rate", "--rudder-rate", "1000", "--retime", "--calibration", "none"]
    assert main([*args, *rate, "--out", str(tmp_path / "fit")]) == 0
    doc = json.loads((tmp_path / "fit" / "model.json").read_text())
    (moves,) = doc["fit"]["retimed_moves"].values()
    assert len(moves) >= 3
    assert "Retimed:" in (tmp_path / "fit" / "report.md").read_text()
    # sampling from the model reads the movements mid-interval again: it says so
    capsys.readouterr()
    sample = ["sample", "--model", str(tmp_path / "fit" / "model.json"), "--train", str(track)]
    assert main([*sample, "--method", "importance", "--draws", "100", "--out", str(tmp_path / "s")]) == 0
    assert "was fitted with --retime" in capsys.readouterr().err


def test_projecting_the_times_out_widens_the_coefficients_covariance():
    # two coefficients, one timing column correlated with the first: the Schur complement
    rng = np.random.default_rng(1)
    Jp = rng.normal(size=(200, 2))
    jf = (0.9 * Jp[:, 0] + 0.3 * rng.normal(size=200))[:, None]

    class Fit:
        jac = Jp.copy()
        model = type("M", (), {"n_params": 2})()

    f = Fit()
    sd_f = project_timing(f, jf)
    joint = np.linalg.inv(np.hstack([Jp, jf]).T @ np.hstack([Jp, jf]))
    np.testing.assert_allclose(np.linalg.inv(f.jac.T @ f.jac), joint[:2, :2], rtol=1e-9)
    assert joint[0, 0] > 2.0 * np.linalg.inv(Jp.T @ Jp)[0, 0]
    assert sd_f[0] == pytest.approx(math.sqrt(joint[2, 2]), rel=1e-9)
