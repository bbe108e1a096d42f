"""A turning circle after course keeping (issue 50): the execute is the start of the last ramp into
the held turning angle (ITTC 7.5-04-02-01 Sec. 2.2.1, the time the rudder order is given), not the
first small rudder move of the approach; the run is a turning circle, not a pull-out or a zigzag.
The Esso Osaka turns (real, shared/data/real; skipped without it) steer their course with the
rudder for 110-200 s before the turn and return it amidships in the last seconds of the record."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bayesid.data.track import Track
from bayesid.estimation.indices import manoeuvre_indices, manoeuvre_kind
from bayesid.models import build_model
from bayesid.models import runs as mr
from bayesid.models.ship import load_ship
from bayesid.models.ship.trials import propulsion_point, service_condition

ESSO = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "esso-osaka-frt"
T_EXEC, ANGLE = 40.0, 35.0


def _both_sides(t):
    """Course keeping with +-4 deg of rudder, reversed every 6 s (holds on both sides)."""
    return np.radians(4.0) * np.sign(np.sin(2 * np.pi * t / 12.0)) * (t > 3) * (t < 36)


def _one_side(t):
    """Course keeping with 4.5 deg pulses of 3 s and -1.5 deg between (on one side beyond 3 deg,
    back within it between: one merged rudder hold with the turn's)."""
    return np.where((t % 10.0) < 3.0, np.radians(4.5), np.radians(-1.5)) * (t > 5) * (t < 36)


@pytest.fixture(scope="module")
def runs():
    """KVLCC2 (7 m model) 35 deg turns from its service approach, the rudder ramped at the service
    rate from T_EXEC, after a straight approach and after the two kinds of course keeping."""
    ship = load_ship("kvlcc2_7m")
    service = service_condition(ship)
    speed, rpm = propulsion_point(ship, service["speed"])
    model = build_model(ship)
    t = np.round(np.arange(0.0, 150.0, 0.1), 10)
    approach = mr.Approach(u=speed, rpm=rpm, rudder_rate=math.radians(service["rudder_rate_deg_s"]), duration_s=150.0)
    ramp = np.clip((t - T_EXEC) * math.radians(service["rudder_rate_deg_s"]), 0.0, math.radians(ANGLE))
    out = {}
    for name, wiggle in (("straight", lambda t: 0.0 * t), ("both sides", _both_sides), ("one side", _one_side)):
        delta = np.where(t < T_EXEC, wiggle(t), ramp)
        inputs = mr.input_track(t, delta, np.full_like(t, rpm), approach)
        out[name] = mr.simulate_run(model, model.start(), inputs, approach)
    return out


def _advance_by_hand(tr, t0: float) -> float:
    """The distance along the course at ``t0`` from the position there to where the heading has
    changed by 90 deg (linear between samples)."""
    t, x, y, psi = tr.t, tr["x"], tr["y"], np.unwrap(tr["psi"])
    h = np.abs(psi - np.interp(t0, t, psi))
    k = int(np.flatnonzero((h >= math.pi / 2) & (t > t0))[0])
    tc = float(np.interp(math.pi / 2, h[k - 1 : k + 1], t[k - 1 : k + 1]))
    c, s = math.cos(np.interp(t0, t, psi)), math.sin(np.interp(t0, t, psi))
    dx, dy = np.interp(tc, t, x) - np.interp(t0, t, x), np.interp(tc, t, y) - np.interp(t0, t, y)
    return float(c * dx + s * dy)


@pytest.mark.parametrize("name", ["both sides", "one side"])
def test_the_execute_of_a_turn_after_course_keeping_is_its_last_ramp(runs, name):
    tr = runs[name]
    assert np.ptp(np.degrees(tr["psi"][tr.t < T_EXEC])) < 5.0  # course kept
    d = manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
    assert d["kind"] == "turning", d
    assert d["execute_t_s"] == pytest.approx(T_EXEC, abs=1e-6) and d["rudder_deg"] == pytest.approx(ANGLE)
    assert d["advance_m"] == pytest.approx(_advance_by_hand(tr, T_EXEC), rel=0.02)
    straight = manoeuvre_indices(*(runs["straight"][k] for k in ("t", "x", "y", "psi", "delta_r")))
    for key in ("advance_m", "tactical_diameter_m"):
        assert d[key] == pytest.approx(straight[key], rel=0.03), key


@pytest.mark.parametrize("name", ["straight", "both sides", "one side"])
def test_a_turn_after_course_keeping_is_a_turning_circle(runs, name):
    tr = runs[name]
    assert manoeuvre_kind(tr) == "turning_circle"
    # a trial stopped as the rudder came back amidships (the Esso records' last seconds) is still
    # a turn; amidships for as long again is a pull-out
    delta = np.asarray(tr["delta_r"]).copy()
    for end_s, kind in ((3.0, "turning_circle"), (60.0, "pull_out")):
        d = np.where(tr.t > tr.t[-1] - end_s, 0.0, delta)
        assert manoeuvre_kind(Track(tr.t, {"x": tr["x"], "delta_r": d})) == kind, end_s


def _esso_turns():
    from bayesid.data import datasets

    return sorted(datasets.list_runs(ESSO, "esso-osaka")) if ESSO.is_dir() else []


@pytest.mark.skipif(not ESSO.is_dir(), reason="the Esso Osaka runs are not in ../shared/data/real")
def test_the_esso_turn_is_read_from_its_order_not_from_the_course_keeping():
    """turn_14-Oct-2020_15_06_53: course keeping with up to 40 deg of rudder on the turn's side
    (the model starts from rest), then at 110.0 s the rudder stepped from -3.5 to 20.2 deg and
    held: the advance from there, 9.2 m (3.1 L), was 34.3 m read from t = 0."""
    from bayesid.data import datasets

    run = next(p for p in _esso_turns() if Path(p).stem == "turn_14-Oct-2020_15_06_53")
    tr = datasets.read_run(run, "esso-osaka")
    d = manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
    assert d["kind"] == "turning" and d["execute_t_s"] == pytest.approx(110.0, abs=0.1)
    assert d["rudder_deg"] == pytest.approx(20.2, abs=0.1)
    assert 6.0 < d["advance_m"] < 12.0 and d["advance_m"] == pytest.approx(_advance_by_hand(tr, 110.0), rel=0.05)
    assert manoeuvre_kind(tr) == "turning_circle"


@pytest.mark.skipif(not ESSO.is_dir(), reason="the Esso Osaka runs are not in ../shared/data/real")
def test_every_esso_turn_is_a_turning_circle_from_the_step_into_its_held_angle():
    from bayesid.data import datasets

    turns = [p for p in _esso_turns() if Path(p).stem.startswith(("turn_", "turn_cut_"))]
    assert len(turns) >= 10
    for p in turns:
        tr = datasets.read_run(p, "esso-osaka")
        t, delta = tr.t, np.degrees(tr["delta_r"])
        # the held angle: the rudder's value three quarters into the record; the order, the last
        # sample before the rudder first stood at it for good
        m = 3 * t.size // 4
        held = delta[m]
        k = int(np.flatnonzero(np.abs(delta[:m] - held) > 0.6)[-1]) + 1
        d = manoeuvre_indices(t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
        assert manoeuvre_kind(tr) == "turning_circle", Path(p).stem
        assert d["kind"] == "turning", (Path(p).stem, d.get("reason"))
        assert t[k - 1] <= d["execute_t_s"] <= t[k], (Path(p).stem, d["execute_t_s"], t[k])
        assert d["rudder_deg"] == pytest.approx(held, abs=0.1)
        assert 2.0 < d["advance_m"] / 3.0 < 5.0 and 2.0 < d["tactical_diameter_m"] / 3.0 < 5.0, Path(p).stem
