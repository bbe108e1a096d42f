"""FitResult.at_bound and the history's active bounds name only coefficients on a finite bound
(issue 69: with infinite bounds every coefficient was listed, ``inf <= inf``)."""

from __future__ import annotations

import numpy as np

from bayesid.estimation.fit import _active


def test_only_finite_bounds_are_reached():
    inf = np.inf
    p = np.array([0.5, -3.0, 2.0, 1.0 - 1e-9, -2.0])
    lo = np.array([-inf, -3.0, -inf, 0.0, -inf])
    hi = np.array([inf, inf, inf, 1.0, 5.0])
    assert _active(p, lo, hi) == [1, 3]
    assert _active(p, np.full(5, -inf), np.full(5, inf)) == []


def test_the_history_of_a_window_fit_gives_each_iterates_cost():
    """Issue 69: the window objective keeps state (fitted start states warm-started), so its
    iterates cannot be evaluated again as the solver saw them; the history gives the cost the solver
    evaluated at each iterate (it printed NaN), starting at the fit's start cost and never above it."""
    from bayesid.data.vehicle import load_vehicle
    from bayesid.estimation.fit import SolverOptions, fit
    from bayesid.estimation.windows import WindowObjective
    from bayesid.models import manoeuvres as mv
    from bayesid.models.submarine import EffectModel
    from bayesid.models.world import LogOptions, world_track

    veh = load_vehicle("nps_auv2")
    tr = world_track(veh, mv.zigzag(veh, 15.0, duration=60.0), {}, np.random.default_rng(0), LogOptions())
    model = EffectModel(veh.with_coefficients({"Nr": 1.3 * veh.coefficients["Nr"]}), ["Nv", "Nr"], [], dt=0.5)
    obj = WindowObjective(
        model,
        [model.context(tr, 20.0, start="fitted")],
        {"x": 0.1, "y": 0.1, "psi": 0.01, "u": 0.05, "v": 0.05, "r": 0.01},
    )
    assert not obj.cache_residuals
    f = fit(obj, obj.x0, (np.full(2, -1.0), np.full(2, 1.0)), SolverOptions(max_nfev=5))
    costs = [h["cost"] for h in f.history]
    assert len(costs) >= 2 and np.isfinite(costs).all(), f.history
    assert costs[0] == f.start_cost and max(costs) <= costs[0] and f.cost <= costs[0]
