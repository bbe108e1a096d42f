"""The designed runs and the standard predictions stay within the vehicle's rudder limit (issue
49): a run the vessel cannot fly is no answer. Found with ``bayesid discover`` on NPS AUV II
(its file limits the rudder to 20 deg; ``bayesid simulate`` refuses more), which was offered a
35/35 zigzag and 35 deg turning circles."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import n0_against_nabsdr

from bayesid.analysis.gap import design as dz
from bayesid.data.vehicle import load_vehicle
from bayesid.models import ship
from bayesid.models.runs import Approach, menu


@pytest.mark.parametrize(
    "vehicle, limit",
    [
        (lambda: load_vehicle("nps_auv2"), 20.0),
        (lambda: ship.load_ship("kvlcc2_7m"), 35.0),
        (lambda: dataclasses.replace(ship.load_ship("kvlcc2_7m"), rudder_max_deg=None), 35.0),  # no [limits]
        (lambda: dataclasses.replace(ship.load_ship("kvlcc2_7m"), rudder_max_deg=25.0), 25.0),
    ],
)
def test_the_menus_largest_rudder_is_the_vehicles_limit_where_smaller(vehicle, limit):
    options = dz.within_limits(dz.DiscriminationOptions(), vehicle())
    assert options.max_rudder_deg == pytest.approx(limit)
    approach = Approach(u=1.0, rpm=600.0, rudder_rate=math.radians(5.0), duration_s=120.0)
    runs = menu(approach, options.max_rudder_deg, options.duration_s)
    assert max(r.rudder_deg for r in runs) == pytest.approx(limit)
    assert len({r.name for r in runs}) == len(runs)  # each run once
    assert dz.within_limits(dz.DiscriminationOptions(max_rudder_deg=15.0), vehicle()).max_rudder_deg == 15.0


def test_design_and_standard_predictions_keep_within_a_15_deg_gear():
    stages, setup = n0_against_nabsdr(dataclasses.replace(ship.load_ship("kvlcc2_7m"), rudder_max_deg=15.0))
    options = dz.DiscriminationOptions(n_draws=0, duration_s=120.0)
    rows = dz.design(stages, setup, options)
    assert rows and max(r["rudder_deg"] for r in rows) == pytest.approx(15.0)
    for r in rows:  # the schedules themselves, not only their labels
        assert np.max(np.abs(r["inputs"]["delta_r"])) <= math.radians(15.0) + 1e-9, r["name"]
    std = dz.standard_predictions(stages, setup, options)
    assert [r["name"] for r in std] == [
        "turning circle 15 deg port",
        "turning circle 15 deg starboard",
        "zigzag 10/10 port",
        "zigzag 15/15 port",
    ]
