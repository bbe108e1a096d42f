"""One vocabulary of manoeuvre kinds (issue 66): ``bayesid simulate``, the ship trials, the design's
menu and :func:`bayesid.estimation.indices.manoeuvre_kind` name a manoeuvre with the names of
:data:`bayesid.models.runs.MANOEUVRE_KINDS`; the older names (``turn``, ``pull-out``) are aliases."""

from __future__ import annotations

import pytest

from bayesid import cli
from bayesid.cli.simulate import MANOEUVRES
from bayesid.data.track import read_csv
from bayesid.estimation.indices import manoeuvre_kind
from bayesid.models import runs
from bayesid.models.ship import load_ship
from bayesid.models.ship import trials as ship_trials
from bayesid.models.ship.trials import TrialOptions, propulsion_point, service_condition, simulate_trial


def test_every_menu_names_kinds_of_the_one_vocabulary():
    for menu in (runs.KINDS, ship_trials.KINDS, MANOEUVRES):
        assert set(menu) <= set(runs.MANOEUVRE_KINDS), menu
    assert set(runs.KIND_ALIASES.values()) <= set(runs.MANOEUVRE_KINDS)


def test_an_alias_names_its_kind_and_an_unknown_name_lists_the_known():
    assert runs.canonical_kind("turn") == "turning_circle"
    assert runs.canonical_kind("pull-out") == "pull_out"
    assert runs.canonical_kind("zigzag") == "zigzag"
    with pytest.raises(ValueError, match=r"unknown ship manoeuvre 'spiral_steps'; known: .*turning_circle.*turn"):
        runs.canonical_kind("spiral_steps", ship_trials.KINDS, "ship manoeuvre")


@pytest.fixture(scope="module")
def kvlcc2():
    ship = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(ship, service_condition(ship)["speed"])
    return ship, speed, rpm, TrialOptions(dt=0.2, duration=120.0, hold=60.0)


@pytest.mark.parametrize(
    ("kind", "alias", "angle"),
    [
        ("turning_circle", "turn", -35.0),
        ("pull_out", "pull-out", 20.0),
        ("zigzag", None, 10.0),
        ("straight", None, 0.0),
    ],
)
def test_a_ship_trial_is_read_back_as_the_kind_it_was_run_as(kvlcc2, kind, alias, angle):
    ship, speed, rpm, opts = kvlcc2
    run = simulate_trial(ship, kind, angle, speed=speed, rpm=rpm, options=opts)
    assert manoeuvre_kind(run.track) == kind
    if alias is not None:  # the alias runs the same manoeuvre
        again = simulate_trial(ship, alias, angle, speed=speed, rpm=rpm, options=opts)
        assert again.name == run.name and (again.track["psi"] == run.track["psi"]).all()


def test_the_simulate_command_takes_a_kind_or_its_alias_and_records_the_kind(tmp_path):
    out = {}
    for name in ("turning_circle", "turn"):
        csv = tmp_path / f"{name}.csv"
        args = ["simulate", "--vehicle", "nps_auv2", "--manoeuvre", name, "--angle", "20", "--duration", "40"]
        assert cli.main(args + ["--out", str(csv), "--no-figure"]) == 0
        out[name] = read_csv(csv)
        assert '"name": "turning_circle"' in csv.with_suffix(".json").read_text()
    assert (out["turn"]["psi"] == out["turning_circle"]["psi"]).all()
    assert manoeuvre_kind(out["turn"]) == "turning_circle"
