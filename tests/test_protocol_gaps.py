"""The window protocol on tracks with gaps and empty cells (issue 21): no window starts in or
spans a gap, the scores equal those of the pieces scored as separate tracks, a 1e5 s gap costs
nothing, and a required channel that is entirely empty is an error naming the column."""

from __future__ import annotations

import numpy as np
import pytest

from bayesid.data.track import Track
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation import windows as wf
from bayesid.estimation.fit import FitResult
from bayesid.models import manoeuvres as mv
from bayesid.models.submarine import EffectModel
from bayesid.models.world import world_track


@pytest.fixture(scope="module")
def setup():
    veh = load_vehicle("nps_auv2")
    m = mv.zigzag(veh, 20.0, dt=0.1, duration=200.0)
    tr = world_track(veh, m, {"thrust": {"thrust_scale": 0.8}}, np.random.default_rng(0))
    model = EffectModel(veh, ["Yv", "Nr"], (), dt=0.5)
    fit = FitResult.fixed(model, model.start(), 1)
    return tr, model, fit


def _rows(tr, sel, name, shift=0.0):
    return Track(tr.t[sel] + shift, {k: np.asarray(v)[sel] for k, v in tr.data.items()}, name=name)


def _score(model, fit, tracks, start="measured"):
    lead = 10.0 if start == "fitted" else 0.0
    ctxs = [model.context(t, 30.0, start=start, leadin_s=lead) for t in tracks]
    return wf.scores(model, fit, ctxs), ctxs


@pytest.mark.parametrize("start", ["measured", "fitted"])
def test_a_stretch_of_empty_cells_splits_the_track_and_scores_like_its_pieces(setup, start):
    tr, model, fit = setup
    blank = (tr.t > 80.0) & (tr.t < 100.0)
    data = {k: np.array(v) for k, v in tr.data.items()}
    for k in ("x", "y", "psi", "u", "v", "r"):
        data[k][blank] = np.nan
    holed = Track(tr.t, data, name="holed")
    pieces = [_rows(tr, tr.t <= 80.0, "a"), _rows(tr, tr.t >= 100.0, "b")]
    (s_hole, [ctx]), (s_pieces, _) = _score(model, fit, [holed], start), _score(model, fit, pieces, start)
    assert ctx.n_pieces == 2
    assert not np.any((ctx.t_start > 80.0) & (ctx.t_start < 100.0))  # no window starts in the gap
    assert not np.any((ctx.t_start < 80.0) & (ctx.t_end > 80.0 + 1e-9))  # and none spans it
    # the fitted rule weights its start fit by the track's own noise estimate, which a split
    # track makes from other samples: equal to 1e-9 for the measured rule, 1e-2 for the fitted
    tol = 1e-9 if start == "measured" else 1e-2
    assert s_hole["rms_position_m"] == pytest.approx(s_pieces["rms_position_m"], rel=tol)
    assert s_hole["rms_heading_deg"] == pytest.approx(s_pieces["rms_heading_deg"], rel=tol)


def test_a_long_time_gap_costs_nothing_and_scores_like_its_pieces(setup):
    tr, model, fit = setup
    a, b = _rows(tr, tr.t <= 90.0, "a"), _rows(tr, tr.t >= 110.0, "b", shift=1e5)
    joined = Track(np.r_[a.t, b.t], {k: np.r_[a[k], b[k]] for k in tr.data}, name="joined")
    s_join, [ctx] = _score(model, fit, [joined])
    s_pieces, _ = _score(model, fit, [a, b])
    assert ctx.W == 6 and ctx.n_pieces == 2
    assert s_join["rms_position_m"] == pytest.approx(s_pieces["rms_position_m"], rel=1e-9)


def test_an_empty_required_channel_is_an_error_naming_it(setup):
    tr, model, _ = setup
    data = {k: np.array(v) for k, v in tr.data.items()}
    data["psi"][:] = np.nan
    with pytest.raises(ValueError, match="'psi' is empty"):
        model.context(Track(tr.t, data, name="nopsi"), 30.0)


def test_a_piece_too_short_for_a_window_is_skipped_and_counted(setup):
    tr, model, fit = setup
    data = {k: np.array(v) for k, v in tr.data.items()}
    for k in ("x", "y", "psi"):
        data[k][(tr.t > 50.0) & (tr.t < 60.0)] = np.nan
        data[k][(tr.t > 61.0) & (tr.t < 80.0)] = np.nan  # leaves a 1 s piece
    ctx = model.context(Track(tr.t, data, name="bits"), 30.0, start="fitted", leadin_s=10.0)
    assert ctx.n_pieces == 3 and ctx.skipped_pieces == 1


def test_a_hole_in_a_logged_input_splits_the_track_but_a_slower_input_log_does_not(setup):
    tr, model, fit = setup
    data = {k: np.array(v) for k, v in tr.data.items()}
    data["delta_r"][(tr.t > 80.0) & (tr.t < 100.0)] = np.nan  # rudder not logged for 20 s
    holed = Track(tr.t, data, name="holed")
    ctx = model.context(holed, 30.0)
    assert ctx.n_pieces == 2
    assert not np.any((ctx.ts > 80.0) & (ctx.ts < 100.0))  # no sample scored on a guessed rudder
    data = {k: np.array(v) for k, v in tr.data.items()}
    data["n"][np.arange(tr.t.size) % 10 != 0] = np.nan  # propeller logged at a tenth of the rate
    assert model.context(Track(tr.t, data, name="slow_n"), 30.0).n_pieces == 1
    with pytest.raises(ValueError, match="clock jump"):  # a 1e9 s gap is refused, not allocated
        a, b = _rows(tr, tr.t <= 90.0, "a"), _rows(tr, tr.t >= 110.0, "b", shift=1e9)
        model.context(Track(np.r_[a.t, b.t], {k: np.r_[a[k], b[k]] for k in tr.data}, name="jump"), 30.0)


def _line(sd, rate_hz, rng, velocity_log=False):
    t = np.arange(0.0, 60.0, 1.0 / rate_hz)
    data = {
        "x": t + rng.normal(0, sd, t.size),
        "y": rng.normal(0, sd, t.size),
        "psi": 0 * t,
        "delta_r": 0 * t,
        "n": 0 * t + 1500.0,
    }
    if velocity_log:
        data.update(u=0 * t + 1.0, v=0 * t, r=0 * t)
    return Track(t, data, name=f"line_{sd}_{rate_hz}")


def test_auto_start_rule_keeps_the_measured_rule_for_precise_positions():
    """'auto' takes the fitted rule only when the positions are too noisy for the measured rule's
    1 s slope estimate (KVLCC2 tank runs: mm positions, no u, v logged, measured rule better)."""
    from bayesid.protocol import AUTO_MAX_SLOPE_SD, resolve_start, slope_sd

    rng = np.random.default_rng(5)
    tank, gps = _line(1e-4, 20, rng), _line(0.2, 5, rng)
    assert resolve_start("auto", [tank]) == "measured"
    assert resolve_start("auto", [gps]) == "fitted" and resolve_start("auto", [tank, gps]) == "fitted"
    assert resolve_start("auto", [_line(0.2, 5, rng, velocity_log=True)]) == "measured"
    assert slope_sd(tank) < AUTO_MAX_SLOPE_SD < slope_sd(gps)
    # slope_sd is the spread of 1 s least-squares slopes of x
    slopes = []
    for _ in range(200):
        tr = _line(0.05, 10, rng)
        sel = tr.t < 1.0 - 1e-9
        slopes.append(np.polyfit(tr.t[sel], tr["x"][sel], 1)[0])
    assert slope_sd(_line(0.05, 10, rng)) == pytest.approx(np.std(slopes), rel=0.25)


def test_a_gap_ending_between_model_steps_starts_its_window_on_the_first_sample_after_it(setup):
    # 10 Hz samples, a 0.5 s model step: the gap ends at a sample 0.1 s after a model step. The
    # window after it must start at or after that sample (a start 0.1 s before it has no sample
    # to estimate the causal start state from: it was all zeros, a 50 m error)
    tr, model, fit = setup
    sel = (tr.t < 80.0) | (tr.t > 90.05)
    gapped = _rows(tr, sel, "gapped")
    ctx = model.context(gapped, 30.0)
    first_after = gapped.t[gapped.t > 90.0][0]
    w = int(np.flatnonzero(ctx.t_start > 80.0)[0])
    assert ctx.t_start[w] >= first_after - 1e-9
    assert np.all(np.abs(ctx.s_meas[w, [0, 1, 6]]) > 0)  # a measured state, not zeros
    after = _rows(tr, tr.t > 90.05, "after")
    sc_gapped = wf.scores(model, fit, [ctx])["rms_position_m"]
    sc_before = wf.scores(model, fit, [model.context(_rows(tr, tr.t < 80.0, "before"), 30.0)])["rms_position_m"]
    assert sc_gapped < 3 * max(sc_before, wf.scores(model, fit, [model.context(after, 30.0)])["rms_position_m"])


@pytest.mark.parametrize("start", ["measured", "fitted"])
def test_one_evaluation_gives_the_scores_window_errors_and_states_of_the_shooting_simulation(setup, start):
    from bayesid.estimation import shooting
    from bayesid.models import context as ctxmod

    tr, model, fit = setup
    pieces = [_rows(tr, tr.t <= 80.0, "a"), _rows(tr, tr.t >= 100.0, "b")]
    ctxs = [model.context(t, 30.0, start=start, leadin_s=10.0 if start == "fitted" else 0.0) for t in pieces]
    sd = {"x": 0.1, "y": 0.1, "psi": 0.01}
    ev = wf.evaluate(model, fit.p, ctxs)
    assert ev.scores(sd).to_dict() == wf.scores(model, fit, ctxs, sd=sd).to_dict()
    windows = ev.window_rms()
    np.testing.assert_array_equal(windows, wf.window_rms(model, fit, ctxs))
    assert windows.shape == (sum(c.W for c in ctxs),)
    np.testing.assert_array_equal(ev.window_runs(), np.repeat([0, 1], [c.W for c in ctxs]))
    for ctx, S0, e, st in zip(ctxs, ev.states, ev.errors, ev.starts):
        S = shooting.simulate(model, ctx, fit.p[None])  # the start rule applied as the fits apply it
        np.testing.assert_array_equal(S0, S[0])
        for k, v in ctxmod.errors(ctx, S).items():
            np.testing.assert_array_equal(e[k], v[0])
        assert (st is None) == (start != "fitted")
        if st is not None:
            np.testing.assert_array_equal(st, wf.window_starts(model, fit.p, ctx))
