"""A fit with fitted window starts reports the cost and the start states of the point the solver
accepted, not of a trial it rejected (issue 69: a 5 Hz AUV fit ended with its reported cost
2,000 x its start while its iterates' costs, as the solver saw them, fell)."""

from __future__ import annotations

import numpy as np
import pytest

from bayesid.estimation.windows import WindowObjective, WindowProblem, window_residuals


@pytest.fixture(scope="module")
def fitted():
    from test_discovery import NOISE, _runs

    from bayesid.models.ship import ShipModel

    kv, train, _ = _runs({"Nabsdr": 0.004}, velocity_log=False, duration=100.0)
    model = ShipModel(kv, dt=0.1)
    sd = {k: NOISE[k] for k in ("x", "y", "psi")}
    ctxs = [model.context(t, 30.0, start="fitted") for t in train]
    fits = {n: WindowProblem(model, ctxs, sd, max_nfev=n).fit() for n in (3, 12)}
    return model, ctxs, sd, fits


@pytest.mark.parametrize("n", [3, 12])
def test_the_reported_cost_is_the_accepted_iterates_and_its_starts_reproduce_it(fitted, n):
    model, ctxs, sd, fits = fitted
    fit = fits[n]
    seen = [h["cost"] for h in fit.history]
    assert fit.cost == pytest.approx(seen[-1], rel=1e-12)  # as the solver saw its last iterate
    assert fit.cost <= min(seen) * (1 + 1e-12) and fit.cost <= fit.start_cost
    ob = WindowObjective(model, ctxs, sd)
    P = np.asarray(fit.p, float)[None]
    nus = [None] * len(ctxs)
    starts = [np.asarray(s)[None] for s in fit.window_starts]
    R, _ = window_residuals(model, ctxs, ob.wts, P, nus, starts)
    assert float(R[0] @ R[0]) == pytest.approx(fit.cost, rel=1e-9)  # its window starts give its cost
