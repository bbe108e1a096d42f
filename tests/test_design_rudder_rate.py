"""The designed runs move the rudder as fast as the training runs' rudder moves (issue 49): the
rate is read from the intervals where the rudder moves, not from all of them (a rudder held
between orders gave the 95th percentile 0, and the designed runs a 1 deg/s ramp)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayesid.data.track import Track
from bayesid.models.runs import approach_condition, rudder_rate


def _run(delta_deg, dt, name="run"):
    t = np.arange(delta_deg.size) * dt
    z = np.zeros_like(t)
    return Track(t, {"x": 1.8 * t, "y": z, "psi": z, "delta_r": np.radians(delta_deg), "n": z + 1500.0}, name=name)


def _zigzag_orders(t, angle, period):
    return angle * np.where(np.sin(2 * np.pi * t / period) >= 0, 1.0, -1.0) * (t > 5.0)


def _slewed(target, dt, rate):
    out = np.zeros_like(target)
    for i in range(1, target.size):
        out[i] = out[i - 1] + np.clip(target[i] - out[i - 1], -rate * dt, rate * dt)
    return out


def test_a_step_logged_rudder_moves_as_fast_as_the_log_says():
    # 20 deg zigzags logged at 5 Hz with the rudder held between orders: each order a 40 deg jump
    # (20 at the first) within one 0.2 s interval; the held rudder is most of the samples
    dt = 0.2
    t = np.arange(0, 150, dt)
    runs = [_run(_zigzag_orders(t, a, p), dt, f"z{a}") for a, p in ((20.0, 40.0), (10.0, 30.0))]
    got = math.degrees(rudder_rate(runs))
    assert got >= 99.0, got  # jumps of 20-40 deg over 0.2 s; the old percentile gave 0 -> 1 deg/s
    assert math.degrees(approach_condition(runs).rudder_rate) == pytest.approx(got)


@pytest.mark.parametrize("rate, noise_deg", [(2.32, 0.0), (5.0, 0.0), (5.0, 0.1), (15.8, 0.1)])
def test_a_slewed_rudder_reads_as_its_rate_with_or_without_jitter(rate, noise_deg):
    dt = 0.1
    t = np.arange(0, 200, dt)
    rng = np.random.default_rng(3)
    delta = _slewed(_zigzag_orders(t, 20.0, 50.0), dt, rate) + rng.normal(0.0, noise_deg, t.size)
    assert math.degrees(rudder_rate([_run(delta, dt)])) == pytest.approx(rate, rel=0.2)


def test_a_rudder_that_never_moves_has_no_rate_and_the_design_assumes_5_deg_s():
    dt = 0.2
    runs = [_run(np.zeros(500), dt)]
    assert rudder_rate(runs) is None
    assert approach_condition(runs).rudder_rate == pytest.approx(math.radians(5.0))
