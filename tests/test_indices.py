"""Turning / zigzag classification and indices (issue 21: indices only where they mean something)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bayesid.data.vehicle import load_vehicle
from bayesid.estimation.indices import manoeuvre_indices
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Manoeuvre
from bayesid.models.world import world_track

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def veh():
    return load_vehicle("nps_auv2")


def _indices(veh, m):
    tr = world_track(veh, m, {}, np.random.default_rng(0), noise={})
    return manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])


def test_a_turning_circle_with_a_small_counter_rudder_is_a_turn(veh):
    m = mv.turning_circle(veh, 20.0, dt=0.1, duration=150.0)
    U = m.inputs.copy()
    k = int(60.0 / 0.1)
    U[k : k + 10, 0] = -np.radians(5.0)  # 1 s of 5 deg counter-rudder mid-turn
    d = _indices(veh, Manoeuvre("turn_blip", 0.1, U, m.initial_state))
    assert d["kind"] == "turning", d
    plain = _indices(veh, m)
    assert plain["kind"] == "turning" and 5.0 < plain["tactical_diameter_m"] < 100.0
    assert d["tactical_diameter_m"] == pytest.approx(plain["tactical_diameter_m"], rel=0.15)
    assert "first_overshoot_deg" not in d


@pytest.mark.parametrize("angle", [10.0, 20.0])
def test_a_zigzag_is_a_zigzag_with_overshoots_only(veh, angle):
    d = _indices(veh, mv.zigzag(veh, angle, dt=0.1, duration=150.0))
    assert d["kind"] == "zigzag", d
    assert 0.0 < d["first_overshoot_deg"] < 30.0 and np.isfinite(d["second_overshoot_deg"])
    assert "tactical_diameter_m" not in d


def test_random_rudder_and_a_short_turn_get_no_index_and_a_reason(veh):
    d = _indices(veh, mv.prbs(veh, 15.0, duration=200.0, rng=np.random.default_rng(3)))
    assert d["kind"] == "other" and "reason" in d and "first_overshoot_deg" not in d
    d = _indices(veh, mv.turning_circle(veh, 20.0, dt=0.1, duration=20.0))
    assert d["kind"] == "other" and "90" in d["reason"]


def test_the_esso_turn_of_724_degrees_is_a_turn():
    """The README's Esso example (turn_14-Oct-2020_15_06_53, -724 deg of heading) was called a
    zigzag with a 696 deg 'overshoot' because one rudder sign change counted as a reversal."""
    from bayesid.data import datasets

    src = ROOT.parent / "shared" / "data" / "real" / "esso-osaka-frt"
    runs = [p for p in datasets.list_runs(src, "esso-osaka")] if src.is_dir() else []
    run = next((p for p in runs if p.stem == "turn_14-Oct-2020_15_06_53"), None)
    if run is None:
        pytest.skip("real data not present")
    tr = datasets.read_run(run, "esso-osaka")
    d = manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
    assert d["kind"] in ("turning", "other") and "second_overshoot_deg" not in d, d
