"""Structure discovery on NPS AUV II (issue 40): a term a catalogue effect partly mimics takes
round 1 from it; a constant moment outside the model is named as constant, not as growing with
speed (discovery without a velocity log: tests/test_discovery_nps_starts.py).

Split from tests/test_discovery.py so that the slow diagnoses of the two files run on different
test workers (``pytest -n auto --dist loadfile``)."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from conftest import yaw_moment_effect

from bayesid.analysis import gap
from bayesid.analysis.gap import discovery as dv

#: the measurement noise of the logged runs (m, rad, m/s, rad/s)
NOISE = {"x": 0.01, "y": 0.01, "psi": math.radians(0.05), "u": 0.002, "v": 0.002, "r": math.radians(0.02)}


def test_a_term_a_catalogue_effect_partly_mimics_takes_round_one_from_it(tmp_path):
    # an NPS AUV II whose model lacks its constant yaw moment (Nprop; the world has 5e-4): waves and a
    # sensor bias each absorb part of it, and round 1 alone would add waves (held-out 15.6 -> 4.0 m,
    # measured). Discovery beside round 1, on the base model, keeps Nprop and takes the round, so the
    # verdict names the term first and the effects are tried on top of it
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models.world import world_track

    veh = load_vehicle("nps_auv2")
    world = veh.with_coefficients({"Nprop": 5e-4})
    rng = np.random.default_rng(5)
    runs = {
        "train": [mv.zigzag(veh, 20.0, dt=0.1, duration=150.0), mv.prbs(veh, 15.0, duration=150.0, rng=rng)],
        "held": [
            mv.zigzag(veh, 10.0, dt=0.1, duration=150.0, first_sign=-1),
            mv.prbs(veh, 10.0, duration=150.0, rng=np.random.default_rng(2)),
        ],
    }
    train, held = ([world_track(world, m, {}, rng, name=f"{k}_{i}") for i, m in enumerate(v)] for k, v in runs.items())
    options = gap.DiagnoseOptions(
        candidates=("sensor_bias", "waves", "crossflow"), window_s=60.0, max_nfev=40, discover=dv.DiscoveryOptions()
    )
    d = gap.diagnose(veh, ["Yv", "Nr", "Ndr"], train, held, options, rng=np.random.default_rng(0))
    F = d.discovery_first
    assert F["effect"] == d.ranking[0]["effect"] and F["effect_role"] in ("cause", "contributor")
    assert F["took_round"] and F["found"] == ["Nprop"] == d.discovery.found
    assert F["heldout_rms_m"] < F["effect_heldout_rms_m"]
    assert d.verdict.startswith("discovered: Nprop"), d.verdict
    assert d.discovery.settings["reference_effects"] == []  # found on the base model
    # the model after the rounds has the term, fitted near the world's value
    assert d.after_fit["coefficients"]["Nprop"] == pytest.approx(5e-4, rel=0.2)
    assert d.gap_after["heldout_rms_m"] <= F["heldout_rms_m"] + 1e-12
    json.dumps(d.to_dict())
    from bayesid.report import write_diagnosis

    write_diagnosis(d, tmp_path, held)
    report = (tmp_path / "report.md").read_text()
    assert "the terms took round 1" in report and "| with Nprop" in report
    assert (tmp_path / "figures" / "discovery_track.png").is_file()
    # the same data with discovery only after the rounds: waves is added first
    late = gap.diagnose(
        veh, ["Yv", "Nr", "Ndr"], train, held, dataclasses.replace(options, discover=None), rng=np.random.default_rng(0)
    )
    assert late.effects_added[:1] == [F["effect"]] and late.discovery_first == {}


def test_a_constant_moment_outside_the_model_is_named_as_constant_not_as_growing_with_speed():
    # the world has a yaw moment of 150 N m at every speed (a body-frame force outside the term table, so
    # the world does not share the model's Nconst code), on runs between about 1 and 2 m/s (a speed-step
    # run trains): discovery names Nconst, not Nprop (a moment in u^2), at its value 150 / (0.5 rho L^3)
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models.world import LogOptions, world_track

    hidden = yaw_moment_effect()
    veh = load_vehicle("nps_auv2")
    rng = np.random.default_rng(4)
    runs = {
        "train": [mv.speed_steps(veh, (1000.0, 700.0, 1400.0), hold_s=60.0, rudder_deg=8.0), mv.zigzag(veh, 20.0)],
        "held": [
            mv.zigzag(veh, 10.0, duration=150.0, first_sign=-1),
            mv.prbs(veh, 15.0, duration=150.0, rng=np.random.default_rng(2)),
            mv.speed_steps(veh, (1300.0, 800.0), hold_s=70.0, rudder_deg=-6.0),
        ],
    }
    log = LogOptions(noise={k: v for k, v in NOISE.items()})
    train, held = (
        [world_track(veh, m, {hidden: {"N_Nm": 150.0}}, rng, log, name=f"{k}_{i}") for i, m in enumerate(v)]
        for k, v in runs.items()
    )
    speeds = np.concatenate([t["u"] for t in train])
    assert speeds.min() < 1.3 and speeds.max() > 1.8  # the speed changes: u^2 by a factor of 2 or more
    options = gap.DiagnoseOptions(candidates=(), window_s=60.0, max_nfev=40, discover=dv.DiscoveryOptions())
    d = gap.diagnose(veh, ["Yv", "Nr", "Ndr"], train, held, options, rng=np.random.default_rng(0))
    D = d.discovery.to_dict()
    assert D["found"] == ["Nconst"], (d.verdict, D["found"])
    # measured: 23.2 -> 0.171 m held out; the true model scores 0.164 m, above the noise floor (0.049 m)
    # because the nominal model misses a noise-free zigzag of this world by 0.28 m under this protocol
    # too, so "+unexplained" follows
    assert d.verdict.startswith("unexplained -> discovered: Nconst"), d.verdict
    row = next(r for r in D["discovered"] if r["term"] == "Nconst")
    assert row["coefficient"] == pytest.approx(150.0 / (0.5 * veh.rho * veh.L**3), rel=0.2)
    assert D["heldout_rms_after_m"] < 0.5 * D["heldout_rms_before_m"]
