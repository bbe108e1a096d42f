"""Manoeuvre generators."""
import math

import numpy as np
import pytest

from bayesid import manoeuvres as mv
from bayesid.simulate import simulate


def test_spiral_is_ten_minutes_within_limits(nps):
    m = mv.spiral(nps)
    assert m.duration == pytest.approx(600.0)
    assert np.all(m.inputs[:, 3] == nps.nominal_rpm)
    assert np.max(np.abs(m.inputs[:, 0])) == pytest.approx(nps.limits.rudder_max)
    assert np.all(np.diff(m.inputs[:, 0]) >= 0)        # rudder only ever steps up: a tightening spiral


def test_limits_are_enforced(nps):
    with pytest.raises(ValueError, match="delta_r.*exceeds"):
        mv.turning_circle(nps, 25.0)


@pytest.mark.parametrize("angle", [10.0, 20.0])
def test_zigzag_reverses_on_heading(nps, angle):
    m = mv.zigzag(nps, angle, duration=120.0)
    res = simulate(nps, m, mode="horizontal")
    psi = np.degrees(res.states[0][:, 5])
    rud = m.inputs[:, 0]
    k_exec = int(round(10.0 / m.dt))
    switches = np.flatnonzero(np.diff(np.sign(rud[k_exec:])) != 0) + k_exec + 1
    assert len(switches) >= 4
    for k in switches:
        # the rudder changed on the step after the heading crossed +-angle (within one step's turn)
        assert abs(abs(psi[k]) - angle) < 0.6
    assert np.max(np.abs(rud)) == pytest.approx(math.radians(angle))
    # positive first rudder turns to port: first trigger at -angle
    assert psi[switches[0]] < 0
