"""Headings as compasses log them (issue 69): a heading wrapped to (-pi, pi] or [0, 2 pi) is
unwrapped on reading, with a note; a jump that is not a wrap is refused, naming psi."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayesid.data.track import Track, TrackFormatError, read_csv, unwrap_heading, write_csv
from bayesid.data.validate import check_track
from bayesid.models.ship import load_ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial


@pytest.fixture(scope="module")
def turn():
    """A KVLCC2 35 deg turn (about 540 deg of heading in 300 s) logged at 5 Hz with 0.5 deg of
    heading noise."""
    ship = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(ship, 1.179)
    tr = simulate_trial(ship, "turn", 35.0, speed=speed, rpm=rpm, options=TrialOptions(sample_every=2, duration=300.0))
    tr = tr.track
    psi = np.asarray(tr["psi"], float) + np.random.default_rng(69).normal(0, math.radians(0.5), tr.t.size)
    return tr.with_columns(psi=psi)


@pytest.mark.parametrize("wrap", ["(-pi, pi]", "[0, 2 pi)"])
def test_a_wrapped_heading_reads_as_the_continuous_one(turn, wrap, tmp_path):
    psi = np.asarray(turn["psi"], float)
    assert np.abs(np.diff(psi)).max() < 0.1 and np.abs(psi).max() > 3 * math.pi  # continuous, > 1.5 turns
    wrapped = np.angle(np.exp(1j * psi)) if wrap == "(-pi, pi]" else np.mod(psi, 2 * math.pi)
    path = tmp_path / "turn.csv"
    write_csv(turn.with_columns(psi=wrapped), path)
    got = read_csv(path)
    # the first sample's branch is kept: the log's, which is the turn's own here (it starts at ~0)
    shift = 2 * math.pi * np.round((psi[0] - got["psi"][0]) / (2 * math.pi))
    np.testing.assert_allclose(got["psi"] + shift, psi, atol=1e-9)
    assert got.meta["psi_wraps"] >= 1 and any("unwrapped on reading" in c for c in got.meta["comments"])
    assert any("column 'psi'" in w and "unwrapped on reading" in w for w in check_track(got))
    # a continuous heading is read as it is, without a note
    write_csv(turn, tmp_path / "plain.csv")
    plain = read_csv(tmp_path / "plain.csv")
    np.testing.assert_array_equal(plain["psi"], psi)
    assert "psi_wraps" not in plain.meta and not any("unwrapped" in w for w in check_track(plain))


def test_a_jump_that_is_not_a_wrap_is_refused_naming_psi(turn, tmp_path):
    t = np.arange(0.0, 20.0, 0.2)
    psi = np.where(t < 10.0, 0.1, 0.1 - 4.0)  # -4 rad: 2.28 rad even as a wrap of 2 pi
    z = np.zeros_like(t)
    path = tmp_path / "jump.csv"
    write_csv(Track(t, {"x": t, "y": z, "psi": psi, "delta_r": z, "n": z + 600.0}), path)
    with pytest.raises(TrackFormatError, match=r"psi.*jump.*t = 10 s") as exc:
        read_csv(path)
    assert "jump.csv" in str(exc.value)
    # NaN samples are skipped and kept; a heading beyond 2 pi is left as it is (unwrapped, or degrees)
    # a step of less than pi reads no wrap: the track is as it was (write_csv -> read_csv stays bit for bit)
    glitch = np.where(t < 10.0, -1.0, 1.28)
    got, n = unwrap_heading(glitch, t)
    assert n == 0
    np.testing.assert_array_equal(got, glitch)
    got, n = unwrap_heading([3.1, np.nan, -3.1, -3.0])
    assert n == 1 and np.isnan(got[1]) and got[2] == pytest.approx(2 * math.pi - 3.1)
    deg = np.array([350.0, 355.0, 2.0])
    assert unwrap_heading(deg)[1] == 0
    # a turning vessel logged with a 10 s gap: 2 rad between two samples 10 s apart is a turn
    tt = np.r_[np.arange(0.0, 5.0, 0.5), np.arange(15.0, 20.0, 0.5)]
    turning = 0.2 * tt
    np.testing.assert_array_equal(unwrap_heading(turning, tt)[0], turning)
