"""The heading against the course over ground (``validate.heading_course``): a heading counted
counterclockwise or from the x axis is refused naming the column and the fix, an offset is warned
about, a vessel crabbing sideways with u, v logged is not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayesid import cli
from bayesid.data import validate
from bayesid.data.track import Track, write_csv
from bayesid.models import ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial


@pytest.fixture(scope="module")
def runs():
    """KVLCC2 (packaged model): a 35 deg turning circle and a 20/20 zigzag, logged at 1 Hz with x,
    y, psi and the inputs (a user's GPS log), position noise 0.05 m, heading noise 0.2 deg."""
    kv = ship.load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(kv, 1.179)
    rng = np.random.default_rng(3)
    out = {}
    for kind, angle, check in (("turn", 35.0, None), ("zigzag", 20.0, 20.0)):
        tr = simulate_trial(
            kv, kind, angle, check_deg=check, speed=speed, rpm=rpm, options=TrialOptions(duration=300.0)
        ).track
        keep = np.arange(0, tr.n_samples, int(round(1.0 / float(np.median(np.diff(tr.t))))))
        data = {k: np.asarray(tr[k], float)[keep] for k in ("x", "y", "psi", "delta_r", "n")}
        data["x"] = data["x"] + rng.normal(0, 0.05, keep.size)
        data["y"] = data["y"] + rng.normal(0, 0.05, keep.size)
        data["psi"] = data["psi"] + rng.normal(0, math.radians(0.2), keep.size)
        out["turning_circle" if kind == "turn" else kind] = Track(tr.t[keep], data, name=kind)
    return out


def _with(tr: Track, **cols) -> Track:
    return Track(tr.t, {**{k: np.asarray(v) for k, v in tr.data.items()}, **cols}, name=tr.name)


@pytest.mark.parametrize("kind", ["turning_circle", "zigzag"])
def test_a_heading_in_the_package_convention_turns_with_the_track(runs, kind):
    got = validate.heading_course(runs[kind])
    assert got["turn_agreement"] > 0.85 and got["n_turns"] >= 10
    assert got["as_logged"] < 30.0  # a 35 deg turn drifts by about 26 deg
    assert not [w for w in validate.check_track(runs[kind], ship.load_ship("kvlcc2_7m")) if "course" in w]


@pytest.mark.parametrize("kind", ["turning_circle", "zigzag"])
def test_a_heading_counted_counterclockwise_is_refused_naming_the_fix(runs, kind):
    tr = _with(runs[kind], psi=-np.asarray(runs[kind]["psi"]))
    assert validate.heading_course(tr)["turn_agreement"] < validate.TURN_AGREEMENT
    with pytest.raises(ValueError, match=r"column 'psi'.*turns the other way.*negate psi and r"):
        validate.check_track(tr, None, "ccw.csv")


def test_a_mathematical_heading_from_the_x_axis_is_refused_naming_it(runs):
    tr = runs["turning_circle"]
    tr = _with(tr, psi=np.angle(np.exp(1j * (math.pi / 2 - np.asarray(tr["psi"])))))
    with pytest.raises(ValueError, match=r"measured from the other axis.*pi/2 - psi"):
        validate.check_track(tr, None, "math.csv")


def test_a_heading_offset_is_warned_about(runs):
    tr = runs["turning_circle"]
    tr = _with(tr, psi=np.angle(np.exp(1j * (np.asarray(tr["psi"]) + 1.2))))
    warned = [w for w in validate.check_track(tr, None, "offset.csv") if "course over ground" in w]
    assert len(warned) == 1 and "offset.csv: column 'psi'" in warned[0]
    assert validate.heading_course(tr)["as_logged"] > 40.0  # 1.2 rad = 69 deg, less the drift


def test_a_vessel_crabbing_sideways_is_warned_about_only_without_u_and_v():
    # heading north, moving east at 0.5 m/s (v = 0.5, u = 0): the course is 90 deg from the heading
    t = np.arange(0.0, 200.0, 0.5)
    zero = 0 * t
    base = {"x": zero, "y": 0.5 * t, "psi": zero, "delta_r": zero, "n": zero + 60.0}
    bare = Track(t, base, name="crab")
    assert [w for w in validate.check_track(bare) if "going astern or sideways" in w]
    logged = Track(t, {**base, "u": zero, "v": zero + 0.5}, name="crab")
    assert validate.heading_course(logged)["as_logged"] < 1.0
    assert not [w for w in validate.check_track(logged) if "course over ground" in w]


def test_the_commands_refuse_a_counterclockwise_heading_with_exit_2(runs, tmp_path, capsys):
    tr = runs["turning_circle"]
    p = tmp_path / "ccw.csv"
    write_csv(_with(tr, psi=-np.asarray(tr["psi"])), p)
    rc = cli.main(["fit", "--vehicle", "kvlcc2_7m", "--train", str(p), "--max-nfev", "2", "--out", str(tmp_path / "f")])
    msg = capsys.readouterr().err
    assert rc == 2 and str(p) in msg and "column 'psi'" in msg and "Traceback" not in msg, msg


def test_a_clock_in_minutes_gives_no_verdict_on_the_turns(runs):
    # 5 "s" of a clock in minutes spans a quarter of the run, over which the turning circle's heading
    # turns by more than 60 deg: the course's turns alias, so no verdict
    tr = runs["turning_circle"]
    slow = Track(tr.t / 60.0, {k: np.asarray(v) for k, v in tr.data.items()}, name="minutes")
    assert validate.heading_course(slow)["turn_agreement"] is None
    try:
        validate.check_track(slow, None, "minutes.csv")
    except ValueError as exc:
        assert "turns the other way" not in str(exc), exc


def test_a_fast_zigzag_logged_at_10_hz_turns_with_its_course():
    """REMUS 100's 10/10 zigzag (a 7 s period) with 2 cm position noise: a 5-s chord lags its
    heading so far that the turns read reversed (the docs walkthrough's fit was refused); the
    chords are as short as the noise allows, the heading averaged along them."""

    from bayesid.models import load_any_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models.world import LogOptions, world_track

    veh = load_any_vehicle("remus100")
    noise = {"x": 0.02, "y": 0.02, "psi": math.radians(0.2)}
    tr = world_track(
        veh, mv.zigzag(veh, 10.0, dt=0.1, duration=120.0), {}, np.random.default_rng(1), LogOptions(noise=noise)
    )
    got = validate.heading_course(tr)
    assert got["turn_agreement"] > 0.9 and got["as_logged"] < 5.0, got
    assert not [w for w in validate.check_track(tr) if "course over ground" in w]
    flipped = _with(tr, psi=-np.asarray(tr["psi"]), r=-np.asarray(tr["r"]))
    assert validate.heading_course(flipped)["turn_agreement"] < validate.TURN_AGREEMENT
