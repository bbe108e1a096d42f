"""Per-row inputs (``TrackContext.with_row_inputs``): one batched simulation flies a different
input schedule for each parameter row, exactly as each row flown alone; the design's free runs
(each parameter draw's own zigzag) use it."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bayesid import load_any_vehicle
from bayesid.data.track import Track
from bayesid.models import build_model
from bayesid.models import runs as mr

APPROACH = mr.Approach(u=0.0, rpm=0.0, rudder_rate=math.radians(5.0), duration_s=60.0)


def _runs(u: float, rpm: float, n_runs: int, hz: float = 2.0) -> list[Track]:
    """Input-only tracks on the same times: rudder steps of different sizes and times."""
    t = np.arange(0.0, 40.0 + 1e-9, 1.0 / hz)
    out = []
    for i in range(n_runs):
        delta = math.radians(5.0 + 7.0 * i) * (t > 3.0 + 2.0 * i) * (1 - 2 * (i % 2))
        out.append(mr.input_track(t, delta, np.full_like(t, rpm + 3.0 * i), replace(APPROACH, u=u)))
    return out


@pytest.mark.parametrize(
    "vehicle, effects, reading",
    [
        ("kvlcc2_7m", (), "hold"),
        ("kvlcc2_7m", ("delay",), "linear"),  # delayed: the per-row integrals
        ("nps_auv2", (), "hold"),
        ("nps_auv2", ("delay", "actuator"), "hold"),  # the servo's substeps
    ],
)
def test_each_row_flies_its_own_inputs_as_it_would_alone(vehicle, effects, reading):
    veh = load_any_vehicle(vehicle)
    model = build_model(veh, effects=effects, inputs=reading)
    ship = vehicle.startswith("kvlcc2")
    u, rpm = (1.179, 600.0) if ship else (1.5, 0.0)
    approach = replace(APPROACH, u=u, rpm=rpm)
    runs = _runs(u, rpm, 3)
    p = np.asarray(model.start(), float)
    P = np.repeat(p[None], 3, axis=0)
    if model.n_params > model.n_theta:  # each row its own effect parameters
        P[:, model.n_theta :] += 0.1 * np.arange(3)[:, None] * np.abs(P[:, model.n_theta :] + 0.1)
    together = mr.simulate_runs(model, P, runs, approach)
    alone = [mr.simulate_run(model, P[b], runs[b], approach) for b in range(3)]
    for a, b in zip(together, alone):
        assert a is not None and b is not None
        for k in ("x", "y", "psi", "delta_r", "n"):
            np.testing.assert_array_equal(a[k], b[k])
    # the rows differ (the inputs were not all row 0's)
    assert np.abs(together[0]["psi"] - together[1]["psi"]).max() > 1e-3


def test_a_context_with_inputs_for_other_rows_is_refused():
    model = build_model(load_any_vehicle("kvlcc2_7m"))
    runs = _runs(1.179, 600.0, 2)
    ctx = model.context(runs[0], None, s0=np.r_[0, 0, 0, 0, 0, 0, 1.179, 0, 0, 0, 0, 0]).with_row_inputs(runs)
    assert ctx.row_inputs.shape == (2, ctx.n_steps, 4)
    with pytest.raises(ValueError, match="inputs for 2 parameter rows, not 3"):
        model.simulate(ctx, np.repeat(np.asarray(model.start(), float)[None], 3, axis=0), measured_start=False)
    with pytest.raises(ValueError, match="2 input schedules for 3 parameter vectors"):
        mr.simulate_runs(model, np.zeros((3, model.n_params)), runs, replace(APPROACH, u=1.179))
    with pytest.raises(ValueError, match="at least one track"):
        ctx.with_row_inputs([])


@pytest.mark.parametrize("vehicle", ["kvlcc2_7m", "nps_auv2"])
def test_each_draws_zigzag_found_in_lock_step_is_the_one_it_finds_alone(vehicle):
    """The lock-step search (one batched simulation per pass) reverses each row's rudder where
    that row's heading passes the check angle, as the one-row search does."""
    veh = load_any_vehicle(vehicle)
    free = veh.free if vehicle.startswith("kvlcc2") else ["Yv", "Nr", "Ndr"]
    model = build_model(veh, free)
    ship = vehicle.startswith("kvlcc2")
    approach = replace(APPROACH, u=1.179 if ship else 1.5, rpm=600.0 if ship else 0.0, duration_s=120.0)
    run = mr.ManoeuvreRun("zigzag", 20.0, 10.0, "port", approach.rpm, 120.0)
    t = np.arange(0.0, 120.0, min(0.1, model.dt))
    p = np.asarray(model.start(), float)
    P = np.repeat(p[None], 4, axis=0)
    P[:, : model.n_theta] *= np.array([1.0, 0.7, 1.3, 0.85])[:, None]  # four hulls that turn differently
    rows = mr.zigzag_rudders(model, P, run, approach, t)
    for b in range(4):
        _, alone, _ = mr.run_inputs(model, P[b], run, approach)
        np.testing.assert_array_equal(rows[b], alone)
    # the switches differ between the hulls, and each zigzag reversed several times
    switches = [np.flatnonzero(np.diff(np.sign(np.round(r, 9))) != 0).size for r in rows]
    assert min(switches) >= 3
    assert len({tuple(np.round(r[::50], 6)) for r in rows}) > 1


def test_a_long_zigzag_keeps_reversing_to_the_end_of_the_run():
    """A zigzag with more reversals than the search once allowed (12) reverses at every check
    angle to the run's end: its heading stays about the original course, and the indices read a
    zigzag (the search held the 13th rudder to the end: a turn, and NaN overshoots)."""
    from bayesid.estimation.indices import manoeuvre_indices

    model = build_model(load_any_vehicle("nps_auv2"), ["Yv", "Nr", "Ndr"])
    approach = replace(APPROACH, u=1.5, rpm=1500.0, duration_s=240.0)
    run = mr.ManoeuvreRun("zigzag", 10.0, 10.0, "port", 1500.0, 240.0)
    t = np.arange(0.0, 240.0, min(0.1, model.dt))
    P = np.repeat(np.asarray(model.start(), float)[None], 2, axis=0)
    P[1, : model.n_theta] *= 1.2  # another hull: other switch times
    rows = mr.zigzag_rudders(model, P, run, approach, t)
    tracks = [mr.input_track(t, r, np.full_like(t, 1500.0), approach) for r in rows]
    for rudder, sim in zip(rows, mr.simulate_runs(model, P, tracks, approach)):
        held = np.abs(rudder) > 1e-9
        side = np.sign(rudder[held])
        reversals = t[held][1:][np.diff(side) != 0]
        assert reversals.size > 12, reversals.size  # measured: 14 and 15 in 240 s
        assert reversals[-1] > 240.0 - 2.0 * np.diff(reversals).max()  # still reversing at the end
        heading = np.degrees(np.unwrap(sim["psi"]) - sim["psi"][0])
        assert np.abs(heading).max() < 25.0, np.abs(heading).max()  # measured 17.6-18.8 deg
        got = manoeuvre_indices(sim.t, sim["x"], sim["y"], sim["psi"], sim["delta_r"])
        assert got["kind"] == "zigzag" and np.isfinite(got["second_overshoot_deg"]), got.get("reason")
