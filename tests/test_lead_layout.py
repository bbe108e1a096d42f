"""The start fit's simulations stop at each window start (``TrackContext.layout("lead")``): the
lead-in residuals are exactly those of the whole windows simulated, for both model families, with
effects that change the inputs, the forces and the sensors, and with a gap in the record."""

from __future__ import annotations

import numpy as np
import pytest

from bayesid.data.track import Track
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation import shooting
from bayesid.models import build_model
from bayesid.models import manoeuvres as mv
from bayesid.models.ship import load_ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, service_condition, simulate_trial
from bayesid.models.world import LogOptions, world_track

KEEP = ("x", "y", "psi", "delta_r", "delta_s", "delta_b", "n")


def _residuals(model, ctx, P, D, whole: bool) -> np.ndarray:
    saved = ctx.lead_starts
    if whole:  # the windows' layout: every window simulated to its end
        ctx.lead_starts = None
    try:
        return shooting.lead_residuals(model, ctx, P, None, D, shooting._weights(ctx, None))
    finally:
        ctx.lead_starts = saved


def _compare(model, tracks, window_s=40.0, leadin_s=10.0):
    rng = np.random.default_rng(0)
    p = model.start()
    P = p[None] * (1.0 + 0.02 * rng.normal(size=(3, p.size))) + 1e-4 * rng.normal(size=(3, p.size))
    for tr in tracks:
        ctx = model.context(tr, window_s, start="fitted", leadin_s=leadin_s)
        assert ctx.lead_starts is not None and ctx.lead_starts[-1] < ctx.n_virtual
        D = 0.02 * rng.normal(size=(3, ctx.W, 6))
        short, whole = _residuals(model, ctx, P, D, False), _residuals(model, ctx, P, D, True)
        assert short.shape == whole.shape and short.size > 0
        np.testing.assert_array_equal(short, whole)


def _nps_tracks():
    veh = load_vehicle("nps_auv2")
    rng = np.random.default_rng(1)
    log = LogOptions(noise={"x": 0.05, "y": 0.05, "psi": 0.002}, sample_every=2)
    runs = [mv.zigzag(veh, 20.0, duration=120.0), mv.prbs(veh, 15.0, duration=100.0, rng=np.random.default_rng(2))]
    tracks = [world_track(veh, m, {}, rng, log) for m in runs]
    out = [Track(tr.t, {c: tr[c] for c in KEEP}, name=f"run_{i}") for i, tr in enumerate(tracks)]
    # a gap of 20 s in the second run: windows of two continuous pieces
    t = out[1].t
    cut = (t > 45.0) & (t < 65.0)
    out[1] = Track(t[~cut], {c: np.asarray(out[1][c])[~cut] for c in KEEP}, name="run_gap")
    return veh, out


@pytest.mark.parametrize("effects", [[], ["delay", "current", "sensor_lag", "actuator", "waves"], ["roll"]])
def test_the_submarine_lead_in_residuals_are_those_of_the_whole_windows(effects):
    veh, tracks = _nps_tracks()
    _compare(build_model(veh, ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"], effects), tracks)


@pytest.mark.parametrize("effects", [[], ["wake_in_turn", "current", "delay"]])
def test_the_ship_lead_in_residuals_are_those_of_the_whole_windows(effects):
    ship = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(ship, service_condition(ship)["speed"])
    opts = TrialOptions(duration=150.0)
    runs = [
        simulate_trial(ship, k, a, speed=speed, rpm=rpm, options=opts) for k, a in (("zigzag", 20.0), ("turn", -35.0))
    ]
    tracks = [
        Track(r.track.t, {c: r.track[c] for c in ("x", "y", "psi", "delta_r", "n")}, name=r.track.name) for r in runs
    ]
    _compare(build_model(ship, None, effects), tracks)


def test_without_a_lead_in_the_start_fit_reads_the_whole_windows():
    veh, tracks = _nps_tracks()
    model = build_model(veh, ["Yv", "Nr"])
    ctx = model.context(tracks[0], 40.0, start="fitted", leadin_s=0.0)
    assert ctx.lead_starts is None
    assert np.array_equal(ctx.layout("lead"), ctx.starts)


def test_a_prepared_simulation_is_the_simulation_and_is_refused_for_another_track_rows_or_inputs():
    veh, tracks = _nps_tracks()
    model = build_model(veh, ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"], ["delay", "current"])
    ctx, other = (model.context(tr, 40.0, start="fitted", leadin_s=10.0) for tr in tracks)
    P = model.start()[None].repeat(2, axis=0) * np.array([[1.0], [1.05]])
    D = 0.01 * np.random.default_rng(3).normal(size=(2, ctx.W, 6))
    prep = model.prepare(ctx, P)
    for samples in ("lead", "scored"):
        a = model.simulate(ctx, P, starts=D, samples=samples)
        b = model.simulate(ctx, P, starts=D, samples=samples, prepared=prep)
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="prepared for another track"):
        model.simulate(other, P, prepared=prep)
    with pytest.raises(ValueError, match="prepared for another track"):
        model.simulate(ctx, P * 1.01, prepared=prep)
    ctx.inputs_version += 1  # as TrackContext.retime does when it rebuilds the inputs
    with pytest.raises(ValueError, match="prepared for another track"):
        model.simulate(ctx, P, prepared=prep)


def test_the_start_fit_prepares_its_rows_once_and_finds_the_same_offsets(monkeypatch):
    veh, tracks = _nps_tracks()
    model = build_model(veh, ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"])
    ctx = model.context(tracks[0], 40.0, start="fitted", leadin_s=10.0)
    P = model.start()[None] * 1.03
    calls = []
    real = model.prepare
    monkeypatch.setattr(model, "prepare", lambda *a: calls.append(1) or real(*a), raising=False)
    with_prep = shooting.fit_starts(model, ctx, P)
    assert len(calls) == 2  # the rows, and the rows of the finite-difference batch
    monkeypatch.setattr(shooting, "_prepare", lambda *a: None)
    np.testing.assert_array_equal(with_prep, shooting.fit_starts(model, ctx, P))
