"""How the logged inputs are reconstructed between samples (issue 50): ``hold`` (the default) keeps
each sample until the next; ``linear`` interpolates between samples, its integral evaluated exactly
at the model's steps and substeps."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayesid.cli import main
from bayesid.data.track import Track
from bayesid.estimation.modelfile import load_model
from bayesid.estimation.options import FitOptions
from bayesid.models import build_model, load_any_vehicle
from bayesid.models.context import TrackContext


def _ramp(rate=0.01, hz=1.0, duration=20.0) -> Track:
    """A straight run whose rudder ramps at ``rate`` rad/s, logged at ``hz``; the propeller
    ramps too (500 -> 520 rpm)."""
    t = np.arange(0.0, duration + 1e-9, 1.0 / hz)
    zero = np.zeros_like(t)
    return Track(
        t, {"x": t, "y": zero, "psi": zero, "delta_r": rate * t, "n": 500.0 + t * 20.0 / duration}, name="ramp"
    )


def test_hold_step_inputs_are_the_held_samples_averaged_over_each_step():
    model = build_model(load_any_vehicle("kvlcc2_7m"), dt=0.4)
    tr = _ramp()
    ctx = model.context(tr, None)
    assert ctx.input_reconstruction == "hold"
    # by hand: the sample at or before each time, averaged over the step [k dt, (k + 1) dt)
    fine = np.arange(0.0, ctx.n_steps * 0.4, 0.001) + 0.0005
    held = 0.01 * np.floor(fine + 1e-12)
    want = held.reshape(ctx.n_steps, -1).mean(axis=1)
    np.testing.assert_allclose(ctx.step_inputs[:, 0], want, atol=1e-9)
    # the explicit option is the same arrays, byte for byte
    same = TrackContext(model, tr, None, 1.0, inputs="hold")
    assert np.array_equal(same.step_inputs, ctx.step_inputs)


def test_linear_step_and_substep_averages_of_a_ramp_logged_at_1_hz_are_exact():
    vehicle = load_any_vehicle("kvlcc2_7m")
    model = build_model(vehicle, dt=0.2, inputs="linear")
    ctx = model.context(_ramp(), None)
    assert ctx.input_reconstruction == "linear"
    mid = ctx.t_grid[:-1] + 0.1
    np.testing.assert_allclose(ctx.step_inputs[:, 0], 0.01 * mid, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ctx.step_inputs[:, 3], 500.0 + mid, rtol=0, atol=1e-9)
    # delayed substep averages: the ramp shifted by the delay (held at its first value before t0)
    d = 0.3
    sub = ctx.average_inputs(np.array([d]), fine=True)[0]
    h = 0.2 / ctx.substeps
    mids = ctx.t0 + h * (np.arange(sub.shape[0]) + 0.5)
    np.testing.assert_allclose(sub[:, 0], 0.01 * np.clip(mids - d, 0.0, None), rtol=0, atol=1e-12)


def test_linear_fills_a_missing_input_sample_between_its_neighbours():
    tr = _ramp()
    r = np.array(tr["delta_r"], float)
    r[5] = np.nan
    holed = Track(tr.t, {**{k: tr[k] for k in tr.data}, "delta_r": r}, name="holed")
    model = build_model(load_any_vehicle("kvlcc2_7m"), dt=0.2, inputs="linear")
    ctx = model.context(holed, None)
    np.testing.assert_allclose(ctx.step_inputs[:, 0], 0.01 * (ctx.t_grid[:-1] + 0.1), atol=1e-12)


def test_an_unknown_reconstruction_is_refused_by_name():
    with pytest.raises(ValueError, match="inputs must be one of hold, linear"):
        build_model(load_any_vehicle("kvlcc2_7m"), inputs="cubic")
    with pytest.raises(ValueError, match="FitOptions.inputs"):
        FitOptions(inputs="spline")
    with pytest.raises(ValueError, match="inputs must be one of"):
        TrackContext(build_model(load_any_vehicle("kvlcc2_7m")), _ramp(), None, 1.0, inputs="cubic")


def test_fit_with_linear_inputs_from_the_command_line_records_the_option(tmp_path, capsys):
    track = tmp_path / "zz.csv"
    sim = ["simulate", "--manoeuvre", "zigzag", "--angle", "20", "--duration", "60", "--mode", "horizontal"]
    assert main([*sim, "--sample", "0.5", "--out", str(track)]) == 0
    out = tmp_path / "fit"
    args = ["fit", "--vehicle", "nps_auv2", "--train", str(track), "--free", "Yv,Nr", "--max-nfev", "3"]
    assert main([*args, "--calibration", "none", "--inputs", "linear", "--out", str(out)]) == 0
    doc = json.loads((out / "model.json").read_text())
    assert doc["inputs"] == "linear"
    assert "inputs interpolated linearly between samples" in (out / "report.md").read_text()
    # predict and sample build the model from the file: it reads the inputs as the fit did
    model, _p, _cov, _doc = load_model(out / "model.json")
    assert model.inputs == "linear"
    # a model file from before the option holds the inputs
    del doc["inputs"]
    (out / "old.json").write_text(json.dumps(doc))
    assert load_model(out / "old.json")[0].inputs == "hold"


def test_a_bad_inputs_value_exits_2_naming_the_option(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["fit", "--vehicle", "nps_auv2", "--train", "x.csv", "--inputs", "cubic", "--out", str(tmp_path / "f")])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "--inputs" in err and "cubic" in err


def _gear(orders, rate, t_fine):
    """A steering gear moving at ``rate`` (rad/s) toward ``orders`` (rad, on ``t_fine``)."""
    u = np.zeros_like(t_fine)
    h = t_fine[1] - t_fine[0]
    for k in range(1, t_fine.size):
        u[k] = u[k - 1] + np.clip(orders[k] - u[k - 1], -rate * h, rate * h)
    return u


def test_a_rate_limited_rudder_logged_at_2_hz_is_rebuilt_exactly_between_its_samples():
    # a zigzag-like gear at 16 deg/s reversing +-20 deg every 7.3 s, orders off the log's clock: the
    # reconstruction is exact to rounding at 2 and 5 Hz where linear interpolation misses the corners
    # by up to 1.9 and 0.8 deg; at 1 Hz it is exact but at the last reversal, which no later sample
    # places (measured: mean error 0.03 deg against 0.39 deg linear)
    from bayesid.models.context import rate_limited_knots

    rate = np.radians(16.0)
    tf = np.arange(0.0, 60.0, 0.001)
    u = _gear(np.where((tf // 7.3) % 2 == 0, 1.0, -1.0) * np.radians(20.0) * (tf > 2.1), rate, tf)
    for hz, lin_worst in ((2.0, 1.9), (5.0, 0.79)):
        ts = np.arange(0.0, 59.5, 1.0 / hz)
        us = np.interp(ts, tf, u)
        tk, uk = rate_limited_knots(ts, us, rate)
        inside = tf <= ts[-1]
        assert np.all(np.diff(tk) > 0) and set(ts) <= set(tk)
        assert np.degrees(np.abs(np.interp(tf[inside], tk, uk) - u[inside]).max()) < 1e-6
        assert np.degrees(np.abs(np.interp(tf[inside], ts, us) - u[inside]).max()) > lin_worst
    ts = np.arange(0.0, 60.0, 1.0)
    tk, uk = rate_limited_knots(ts, np.interp(ts, tf, u), rate)
    inside = tf <= 58.0  # before the last reversal, which starts in the last interval
    assert np.degrees(np.abs(np.interp(tf[inside], tk, uk) - u[inside]).max()) < 1e-6
    # a move the rate cannot make in its interval, and a lone move, as the docstring says
    tk, uk = rate_limited_knots(np.array([0.0, 1.0, 2.0, 3.0]), np.array([0.0, 0.0, 0.1, 0.1]), 0.2)
    np.testing.assert_allclose(tk, [0.0, 1.0, 1.25, 1.75, 2.0, 3.0])
    np.testing.assert_allclose(uk, [0.0, 0.0, 0.0, 0.1, 0.1, 0.1])
    tk, uk = rate_limited_knots(np.array([0.0, 1.0, 2.0]), np.array([0.0, 0.5, 0.5]), 0.2)
    np.testing.assert_allclose(tk, [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="rate must be positive"):
        rate_limited_knots(ts, ts, 0.0)


def test_fit_with_rate_inputs_reads_the_gear_rate_from_the_ship_file_or_the_option(tmp_path, capsys):
    # KVLCC2's file gives [service] rudder_rate_deg_s = 15.8; a submarine's file gives none: the option
    # must, and without it the command exits 2 naming it
    kv = build_model(load_any_vehicle("kvlcc2_7m"), inputs="rate")
    assert kv.rudder_rate_deg_s == 15.8
    assert build_model(load_any_vehicle("kvlcc2_7m"), inputs="rate", rudder_rate_deg_s=5.0).rudder_rate_deg_s == 5.0
    with pytest.raises(ValueError, match="--rudder-rate"):
        build_model(load_any_vehicle("nps_auv2"), inputs="rate")
    # the model's step averages are the rebuilt gear's: a lone 0.1 rad move between samples 1 and 2 s
    tr = Track(
        np.arange(0.0, 4.0),
        {"x": np.arange(0.0, 4.0), "y": np.zeros(4), "psi": np.zeros(4), "delta_r": [0, 0, 0.1, 0.1], "n": [600.0] * 4},
    )
    ctx = build_model(load_any_vehicle("kvlcc2_7m"), dt=0.25, inputs="rate", rudder_rate_deg_s=np.degrees(0.2)).context(
        tr, None
    )
    mid = ctx.t_grid[:-1] + 0.125
    want = np.clip((mid - 1.25) * 0.2, 0.0, 0.1)  # linear within each step of 0.25 s: the mid value
    np.testing.assert_allclose(ctx.step_inputs[:, 0], want, atol=1e-12)
    track = tmp_path / "zz.csv"
    sim = ["simulate", "--manoeuvre", "zigzag", "--angle", "20", "--duration", "60", "--mode", "horizontal"]
    assert main([*sim, "--sample", "0.5", "--out", str(track)]) == 0
    args = ["fit", "--vehicle", "nps_auv2", "--train", str(track), "--free", "Yv,Nr", "--max-nfev", "3"]
    args += ["--calibration", "none", "--inputs", "rate"]
    assert main([*args, "--out", str(tmp_path / "none")]) == 2
    assert "--rudder-rate" in capsys.readouterr().err
    out = tmp_path / "fit"
    assert main([*args, "--rudder-rate", "16", "--out", str(out)]) == 0
    doc = json.loads((out / "model.json").read_text())
    assert doc["inputs"] == "rate" and doc["rudder_rate_deg_s"] == 16.0
    assert "the rudder and planes at the gear's rate (16 deg/s) between samples" in (out / "report.md").read_text()
    model = load_model(out / "model.json")[0]
    assert model.inputs == "rate" and model.rudder_rate_deg_s == 16.0
