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
