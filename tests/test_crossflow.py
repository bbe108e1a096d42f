"""Polynomial equivalent of the cross-flow integral."""

import math

import pytest

from bayesid.models import crossflow
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import simulate


def test_packaged_polynomial_reproduces_from_its_derivation(nps):
    fit = crossflow.fit_polynomial_equivalent(nps, crossflow.envelope_manoeuvres(nps))
    for name, value in fit["coefficients"].items():
        assert nps.coefficients[name] == pytest.approx(value, rel=1e-5), name
    assert fit["relative_rms_residual"]["Y"] < 0.02 and fit["relative_rms_residual"]["N"] < 0.02


@pytest.mark.parametrize("deg", [10.0, 20.0])
def test_polynomial_and_integral_turns_agree(nps, deg):
    """Cross-check (equations.md notes): R10 = 29.46 m, R20 = 16.29 m with the strip sum."""
    radii = {}
    for model in ("polynomial", "integral"):
        s = simulate(nps.with_crossflow(model), mv.turning_circle(nps, deg, duration=300.0), mode="horizontal").states[
            0
        ]
        radii[model] = math.hypot(s[-1, 6], s[-1, 7]) / abs(s[-1, 11])
    assert radii["polynomial"] == pytest.approx(radii["integral"], rel=0.01)
    assert radii["integral"] == pytest.approx({10.0: 29.46, 20.0: 16.29}[deg], rel=0.01)


def test_integral_variant_zeroes_polynomial_terms(nps):
    vi = nps.with_crossflow("integral")
    assert vi.coefficients["Yvabsv"] == 0.0 and vi.crossflow_model == "integral"
