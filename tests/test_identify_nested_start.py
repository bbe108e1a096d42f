"""A fit with an effect that contains the model without it (the effect's catalogue ``neutral``
value) is never left above that model's fit by the effect's own start (issues 67 and 69): the
fit from the effect's start values and the chain through the model without the effect (its fit,
then the full model from its optimum with the effect neutral) are both run, and the lower kept;
``model.json`` records both, and the fit report says which was kept.

The case: a 35 deg turn and a 20/20 zigzag of KVLCC2 flown with the file's model (90 s, 0.2 s
samples, 2 cm position noise), its 18 free coefficients refitted with noise weights and the
``coupling_speed`` effect started at MMG's ``c_U = 1``: from there the fit ends at SSR 11465,
above the 11048 of the model without the effect (the truth); the chain ends at 11048 with
``c_U`` 0."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from bayesid.estimation.identification import identify, neutral_start
from bayesid.estimation.modelfile import ModelDocument
from bayesid.estimation.options import FitOptions
from bayesid.models import ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial
from bayesid.report.fit import write_fit_report


@pytest.fixture(scope="module")
def kv():
    return ship.load_ship("kvlcc2_7m")


@pytest.fixture(scope="module")
def tracks(kv):
    speed, rpm = propulsion_point(kv, 1.179)
    opts = TrialOptions(dt=0.2, duration=90.0, rudder_rate_deg_s=15.8)
    rng = np.random.default_rng(1)
    out = []
    for kind, angle in (("turn", 35.0), ("zigzag", 20.0)):
        tr = simulate_trial(kv, kind, angle, speed=speed, rpm=rpm, options=opts).track
        for c in ("x", "y"):
            tr.data[c] = tr.data[c] + rng.normal(0.0, 0.02, tr.t.size)
        out.append(tr)
    return out


def _fit(kv, tracks, effects):
    # noise weights: the channel weights do not depend on the fit, so two fits' costs compare
    opts = FitOptions(
        free=tuple(kv.free),
        effects=effects,
        window_s=30.0,
        dt=0.2,
        max_nfev=30,
        prior=False,
        inputs="rate",
        weighting="noise",
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify(kv, tracks, opts, calibration=None)


def test_neutral_start_sets_only_the_effects_with_a_neutral_value(kv):
    m = ship.ShipModel(kv, ["Yv", "Nr"], ["sensor_lag", "wake_in_turn"])
    p0 = m.start()
    pn = neutral_start(m, p0)
    np.testing.assert_array_equal(pn[:2], p0[:2])  # the coefficients stay
    np.testing.assert_array_equal(pn[2:4], [0.0, 0.0])  # sensor_lag: neutral
    np.testing.assert_array_equal(pn[4:], p0[4:])  # wake_in_turn has none: its start stays
    assert neutral_start(ship.ShipModel(kv, ["Yv", "Nr"], ["wake_in_turn"]), p0[[0, 1, 4, 5, 6]]) is None


def test_a_fit_with_a_nesting_effect_ends_no_worse_than_the_model_without_it(kv, tracks, tmp_path):
    base = _fit(kv, tracks, ())
    res = _fit(kv, tracks, ("coupling_speed",))
    ns = res.nested_start
    assert ns["effects"] == ["coupling_speed"]
    # the effect's own start ends above the model without it; the chain through that model does not
    assert ns["cost_without"] == pytest.approx(base.fit.cost, rel=1e-9)
    assert ns["cost_effect_start"] > 1.02 * base.fit.cost
    assert ns["kept"] == "neutral" and res.fit.cost == ns["cost_neutral_start"] <= ns["cost_without"]
    assert dict(zip(res.model.param_names, res.fit.p))["coupling_speed.c_U"] < 0.05  # the truth: the file's form
    assert base.nested_start is None
    doc = ModelDocument.from_identify(res, "kvlcc2_7m", [t.name for t in tracks]).to_dict()
    assert doc["fit"]["nested_start"] == ns
    write_fit_report(doc, tmp_path)
    text = (tmp_path / "report.md").read_text()
    assert "Two starts" in text and "That second fit is kept" in text
