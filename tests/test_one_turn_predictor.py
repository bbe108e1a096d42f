"""One predictor of a standard manoeuvre (issue 66): a fitted model's turning circle is the same
whether ``turning_circles`` (``bayesid fit --starts``, the studies) or a diagnosis's standard
predictions ask for it, both from the logged runs' approach with the rudder moved at their rate;
the steady turn's diameter and speed loss are reported beside the ITTC indices (issue 67)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from bayesid.analysis.gap import design as dz
from bayesid.estimation.prediction import TURNING_INDICES, FittedModel, turning_circles
from bayesid.models import build_model
from bayesid.models.runs import T_EXECUTE, approach_condition
from bayesid.models.ship import load_ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial


@pytest.fixture(scope="module")
def kvlcc2():
    ship = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(ship, 1.179)
    opts = TrialOptions(dt=0.1, sample_every=2, duration=120.0, rudder_rate_deg_s=15.8)
    train = [simulate_trial(ship, "zigzag", 20.0, speed=speed, rpm=rpm, options=opts).track]
    return ship, build_model(ship, ship.free), train


def test_turning_circles_and_the_standard_predictions_agree(kvlcc2):
    ship, model, train = kvlcc2
    approach = approach_condition(train)
    assert math.degrees(approach.rudder_rate) == pytest.approx(15.8, rel=0.05)  # the logged gear's rate
    p = np.asarray(model.start(), float)
    D = 300.0
    tc = turning_circles(FittedModel(model, p, None), 0, None, approach, 35.0, D - T_EXECUTE)
    stage = SimpleNamespace(model=model, fit=SimpleNamespace(p=p))
    setup = SimpleNamespace(vehicle=ship, train=train, fit_window_s=None)
    std = dz.standard_predictions({"m": stage}, setup, dz.DiscriminationOptions(n_draws=0, duration_s=D))
    turns = {r["side"]: r["models"]["m"] for r in std if r["kind"] == "turning_circle"}
    assert set(turns) == {"port", "starboard"}
    for side, got in turns.items():
        assert set(got) == set(TURNING_INDICES)
        for k in TURNING_INDICES:
            assert got[k]["value"] == tc[side]["predicted"][k], (side, k)
    # a 35 deg turn held 295 s settles: the steady turn's diameter is smaller than the tactical
    # diameter and the ship slows in it
    for side in ("port", "starboard"):
        pr = tc[side]["predicted"]
        assert 0.0 < pr["steady_turning_diameter_m"] < pr["tactical_diameter_m"]
        assert 0.1 < pr["speed_loss"] < 0.9


def test_the_rudder_moves_at_the_approach_rate(kvlcc2):
    # a slower gear reaches 35 deg later, and the ship advances further before it turns
    ship, model, train = kvlcc2
    approach = approach_condition(train)
    p = np.asarray(model.start(), float)
    fast = turning_circles(FittedModel(model, p, None), 0, None, approach, 35.0, 200.0)
    slow = turning_circles(
        FittedModel(model, p, None),
        0,
        None,
        type(approach)(approach.u, approach.rpm, math.radians(2.0), 0.0),
        35.0,
        200.0,
    )
    for side in ("port", "starboard"):
        assert slow[side]["predicted"]["advance_m"] > fast[side]["predicted"]["advance_m"] + 0.1


@pytest.fixture(scope="module")
def turns(kvlcc2):
    """35 deg turns of three KVLCC2 hulls (as packaged, X'vr changed: the surge in the turn, N'r
    30 % larger: the yaw damping) and a zigzag, 300 s, sampled at 2 Hz."""
    ship, model, _ = kvlcc2
    speed, rpm = propulsion_point(ship, 1.179)
    opts = TrialOptions(dt=0.1, sample_every=5, duration=300.0, rudder_rate_deg_s=15.8)
    out = {}
    for label, change in (("as packaged", {}), ("Xvr", {"Xvr": -0.25}), ("Nr", {"Nr": 1.3 * ship.coefficients["Nr"]})):
        truth = ship.with_coefficients(change) if change else ship
        out[label] = simulate_trial(truth, "turn", 35.0, speed=speed, rpm=rpm, options=opts).track
    out["zigzag"] = simulate_trial(ship, "zigzag", 20.0, speed=speed, rpm=rpm, options=opts).track
    return out


def test_a_model_that_cannot_fly_its_training_turn_is_said_to_and_a_component_suspected(kvlcc2, turns):
    from bayesid.estimation.prediction import training_turns

    _, model, _ = kvlcc2
    nominal = FittedModel(model, np.asarray(model.start(), float), None)
    got = {t["run"]: t for t in training_turns(nominal, [turns["zigzag"], turns["as packaged"]])}
    assert list(got) == [turns["as packaged"].name]  # the zigzag is not a turning circle
    (own,) = got.values()
    assert own["reproduced"] and own["suspect"] is None and own["predicted_unread"] is None
    assert abs(own["rel_error"]["steady_turning_diameter_m"]) < 0.01
    # measured: steady diameter -38 %, speed loss 0.54 against 0.73
    (surge,) = training_turns(nominal, [turns["Xvr"]])
    assert surge["reproduced"] is False and surge["suspect"] == "speed in the turn"
    # measured: steady diameter -17 %, speed loss 0.71 against 0.73
    (yaw,) = training_turns(nominal, [turns["Nr"]])
    assert yaw["reproduced"] is False and yaw["suspect"] == "turning forces"


def test_bayesid_fit_reports_a_training_turn_it_cannot_reproduce(turns, tmp_path):
    import json

    from bayesid import cli
    from bayesid.data.track import write_csv

    path = tmp_path / "turn.csv"
    write_csv(turns["Xvr"], path)
    out = tmp_path / "fit"
    rc = cli.main(["-q", "fit", "--vehicle", "kvlcc2_7m", "--free", "Yv,Nr", "--train", str(path)]
                  + ["--max-nfev", "3", "--out", str(out)])  # fmt: skip
    assert rc == 0
    doc = json.loads((out / "model.json").read_text())
    (turn,) = doc["training_turns"]
    assert turn["reproduced"] is False and turn["suspect"] == "speed in the turn"
    report = (out / "report.md").read_text()
    assert "## The training turning circles" in report and "does not reproduce its own training turn" in report


def _with_wind(track, speed_mps: float, from_rad: float = 0.5):
    from bayesid.data.track import Track

    data = {k: np.asarray(track[k], float) for k in track.data}
    data["wind_speed"] = np.full(track.n_samples, speed_mps)
    data["wind_dir"] = np.full(track.n_samples, from_rad)
    return Track(track.t, data, name=track.name)


def test_a_logged_wind_the_model_lacks_is_suspected_before_the_surge(kvlcc2, turns):
    import dataclasses

    from bayesid.estimation.prediction import WIND_SUSPECT_RATIO, training_turns
    from bayesid.models.ship.dynamics import wind_to_resistance

    ship, _, _ = kvlcc2
    # the tank's KVLCC2 has no windage: give it a superstructure's
    windy = dataclasses.replace(ship, particulars={**ship.particulars, "A_front": 0.12, "A_lateral": 0.45})
    model = build_model(windy, windy.free)
    nominal = FittedModel(model, np.asarray(model.start(), float), None)
    calm, gale = turns["Xvr"], _with_wind(turns["Xvr"], 20.0)
    assert wind_to_resistance(windy, calm) is None and wind_to_resistance(ship, gale) is None  # no wind, no windage
    ratio = wind_to_resistance(windy, gale)
    assert ratio > WIND_SUSPECT_RATIO
    # the true wind alone (no u, v logged): the force goes with the wind speed squared
    bare = {k: gale[k] for k in gale.data if k not in ("u", "v")}
    half = {**bare, "wind_speed": bare["wind_speed"] / 2}
    from bayesid.data.track import Track

    r1, r2 = (wind_to_resistance(windy, Track(gale.t, d, name="w")) for d in (bare, half))
    assert r1 == pytest.approx(4.0 * r2, rel=1e-9)
    (t,) = training_turns(nominal, [gale])
    assert t["reproduced"] is False and t["suspect"] == "wind" and t["wind_to_resistance"] == pytest.approx(ratio)
    (t,) = training_turns(nominal, [calm])
    assert t["suspect"] == "speed in the turn" and "wind_to_resistance" not in t
    (t,) = training_turns(nominal, [_with_wind(turns["Xvr"], 0.3)])  # a breeze: the surge again
    assert t["suspect"] == "speed in the turn" and t["wind_to_resistance"] < WIND_SUSPECT_RATIO
    with_wind = build_model(windy, windy.free, ["wind"])
    (t,) = training_turns(FittedModel(with_wind, np.asarray(with_wind.start(), float), None), [gale])
    assert t["suspect"] != "wind" and "wind_to_resistance" not in t


def test_a_coefficient_the_fit_left_on_a_bound_is_said_and_named_beside_a_missed_turn():
    from bayesid.report.fit import _bound_lines, _training_turn_lines

    doc = {"fit": {"at_bound": ["wP"]}, "param_names": ["Xuu", "wP"], "p": [-0.0087, 0.0]}
    (line, _) = _bound_lines(doc)
    assert line.startswith("**At a bound:** wP = 0.") and "model form strains" in line
    assert _bound_lines({"fit": {}, "param_names": [], "p": []}) == []
    # an effect's parameter on its bound (a delay of 0 s) is not a strain of the model form
    (effect, _) = _bound_lines({"fit": {"at_bound": ["delay.delay_s"]}, "param_names": ["delay.delay_s"], "p": [0.0]})
    assert effect.startswith("Effect parameters on a bound: delay.delay_s = 0") and "strains" not in effect
    missed = {
        "run": "turn_a",
        "measured": {"tactical_diameter_m": 12.6, "steady_turning_diameter_m": 10.9, "speed_loss": 0.44},
        "predicted": {"tactical_diameter_m": 10.1, "steady_turning_diameter_m": 10.0, "speed_loss": 0.41},
        "rel_error": {"tactical_diameter_m": -0.2, "steady_turning_diameter_m": -0.077, "speed_loss": None},
        "reproduced": False,
        "suspect": "turning forces",
    }
    text = "\n".join(_training_turn_lines([missed], ["wP"]))
    assert "does not reproduce its own training turn turn_a" in text and "also left wP on a bound" in text
    assert "on a bound" not in "\n".join(_training_turn_lines([dict(missed, reproduced=True)], ["wP"]))
