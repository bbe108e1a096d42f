"""A model step fine enough for the vehicle when the user gives none (issue 69's newcomer: a REMUS-like
AUV diagnosed through the Python API at the submarine's 0.5 s step diverged, and the diagnosis
failed with "track 'run2' (90 s) is too short for a window")."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bayesid.analysis.gap.verdict import DivergedSimulation, noise_floor
from bayesid.data.track import Track
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation.fit import FitResult
from bayesid.models import build_model, default_dt, load_any_vehicle
from bayesid.models import manoeuvres as mv
from bayesid.models.ship import load_ship
from bayesid.models.world import LogOptions, world_track

REMUS = Path(__file__).resolve().parents[1] / "bayesid" / "vehicles" / "remus100.toml"
FREE = ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"]


@pytest.fixture(scope="module")
def remus_runs():
    """REMUS 100 (the docs' file) flying a 15 deg zigzag and a 15 deg turn for 90 s, logged at 5 Hz
    without noise (x, y, psi and the inputs)."""
    veh = load_any_vehicle(str(REMUS))
    log = LogOptions(noise={}, sample_every=4, hold_inputs=True)
    out = []
    for m in (mv.zigzag(veh, 15.0, dt=0.05, duration=90.0), mv.turning_circle(veh, 15.0, dt=0.05, duration=90.0)):
        tr = world_track(veh, m, {}, np.random.default_rng(0), log)
        keep = ("x", "y", "psi", "delta_r", "delta_s", "delta_b", "n")
        out.append(Track(tr.t, {k: tr[k] for k in keep if k in tr}, name=m.name))
    return veh, out


def test_the_default_step_is_the_familys_for_the_vehicles_it_was_chosen_on():
    assert default_dt(load_vehicle("nps_auv2")) == 0.5  # every NPS AUV II result is as before
    assert default_dt(load_ship("kvlcc2_7m")) == default_dt(load_ship("esso_osaka_3m")) == 0.2
    assert build_model(load_vehicle("nps_auv2"), FREE).dt == 0.5


def test_a_small_auv_gets_a_step_its_integration_holds(remus_runs):
    veh, runs = remus_runs
    assert default_dt(veh) == 0.125  # 0.5 halved until at most 0.178 x 1.33 m / 1.54 m/s
    for dt, finite in ((None, True), (0.5, False)):
        m = build_model(veh, FREE, dt=dt)
        S = [m.simulate(m.context(tr, None, start="measured"), m.start()[None])[0] for tr in runs]
        assert all(np.isfinite(s).all() for s in S) is finite, (dt, m.dt)


def test_a_diverging_simulation_names_the_track_and_the_step_not_a_window(remus_runs):
    veh, runs = remus_runs
    m = build_model(veh, FREE, dt=0.5)
    ctxs = [m.context(tr, 60.0, start="measured") for tr in runs]
    nominal = FitResult.fixed(m, m.start(), len(runs), "nominal")
    sd = {"x": 0.5, "y": 0.5, "psi": math.radians(0.5)}
    with pytest.raises(DivergedSimulation, match=r"zigzag.*not finite from t = .* model step of 0.5 s"):
        noise_floor(m, nominal, ctxs, runs, sd, np.random.default_rng(0))
    assert isinstance(DivergedSimulation("x"), ValueError)  # the commands exit 2 with the sentence


def test_a_vehicle_file_without_crossflow_data_leaves_the_crossflow_candidate_out():
    # the newcomer's next failure: the default catalogue's crossflow candidate on a file without a
    # [crossflow] section stopped the diagnosis in round 1
    from bayesid.analysis.gap.diagnose import catalogue_candidates
    from bayesid.models import model_class
    from bayesid.tasks import Runner

    veh, said = load_any_vehicle(str(REMUS)), []
    family = model_class(veh)
    names = catalogue_candidates(family, [], Runner(progress=said.append), vehicle=veh)
    assert "crossflow" not in names and "current" in names
    assert said == ["the vehicle file has no [crossflow] section: the crossflow candidate is left out"]
    assert "crossflow" in catalogue_candidates(family, [], vehicle=load_vehicle("nps_auv2"))
    with pytest.raises(ValueError, match=r"remus100: the vehicle file has no \[crossflow\] section"):
        build_model(veh, FREE, ["crossflow"])
