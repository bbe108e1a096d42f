"""Rows of a batch whose input effects (delay, servo) have the same parameters share one
computation of their inputs (``TrackContext.inputs``; issue 68: a finite-difference Jacobian
perturbs one parameter per row, so most rows have the same delay): the batch is the same to the bit
as each row simulated alone."""

from __future__ import annotations

import numpy as np
import pytest

from bayesid import load_any_vehicle
from bayesid.models import build_model
from bayesid.models import context as ctxmod
from bayesid.models import manoeuvres as mv
from bayesid.models.world import LogOptions, world_track


@pytest.fixture(scope="module")
def zigzag():
    veh = load_any_vehicle("nps_auv2")
    return veh, world_track(veh, mv.zigzag(veh, 20.0, duration=60.0), {}, np.random.default_rng(1), LogOptions())


@pytest.mark.parametrize("effects", [["delay"], ["actuator"], ["delay", "actuator"]])
def test_rows_with_the_same_input_parameters_share_their_inputs_and_match_each_row_alone(zigzag, effects, monkeypatch):
    veh, track = zigzag
    m = build_model(veh, ["Yv", "Nr"], effects, dt=0.2)
    ctx = m.context(track, 20.0)
    P = np.repeat(m.start()[None], 7, axis=0)
    P[1, -1] += 0.05  # an input effect's parameter: a row of its own
    P[3, 0] += 1e-3  # a coefficient: the inputs of row 0
    P[5, -1] += 0.01
    sizes = []
    average = ctxmod.TrackContext.average_inputs
    monkeypatch.setattr(
        ctxmod.TrackContext, "average_inputs", lambda s, d, fine=False: sizes.append(d.size) or average(s, d, fine)
    )
    S = m.simulate(ctx, P)
    assert sizes == [3]  # rows 0, 2, 3, 4, 6 computed once, rows 1 and 5 apart
    alone = np.concatenate([m.simulate(ctx, P[b : b + 1]) for b in range(len(P))])
    np.testing.assert_array_equal(S, alone)
