"""The propeller against a logged thrust (issue 67): ``ShipModel.logged_thrust`` and the Where
section's ``thrust`` check (:func:`bayesid.analysis.gap.where._thrust_check`)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from bayesid.analysis.gap.where import _thrust_check
from bayesid.models.ship import load_ship
from bayesid.models.ship.model import ShipModel
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial


def _mmg_thrust(ship, track) -> np.ndarray:
    """The MMG thrust written out here (Yasukawa & Yoshimura 2015, eqs. 9-12), with the package's
    wake ``wP exp(-4 beta_P^2)``: the oracle of the kernel's."""
    c, p = ship.coefficients, ship.particulars
    L, D, rho = ship.L, p["D_prop"], ship.rho
    u, v, r = track["u"], track["v"], track["r"]
    n = np.asarray(track["n"]) / 60.0
    vp = v + c["xP"] * L * r
    w = c["wP"] * np.exp(-4.0 * vp**2 / (u**2 + vp**2))
    J = np.clip((1.0 - w) * u / (n * D), -0.5, 1.2)
    return rho * n**2 * D**4 * (c["k0"] + c["k1"] * J + c["k2"] * J**2)


@pytest.fixture(scope="module")
def zigzag():
    """A 20/20 zigzag of the packaged KVLCC2 (u, v, r logged) and the ship."""
    ship = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(ship, 1.179)
    tr = simulate_trial(ship, "zigzag", 20.0, speed=speed, rpm=rpm, options=TrialOptions(dt=0.1, duration=90.0)).track
    return ship, tr.with_columns(thrust=_mmg_thrust(ship, tr))


def test_the_models_thrust_is_the_mmg_thrust_along_the_logged_motion(zigzag):
    ship, tr = zigzag
    model = ShipModel(ship)
    d = model.logged_thrust(SimpleNamespace(p=model.start()), tr)
    assert d.model.shape == d.logged.shape == d.t.shape
    # the truth's own thrust: equal to the oracle's (the column) to the smoothing of the motion
    assert np.max(np.abs(d.model / d.logged - 1.0)) < 0.01
    assert d.t_p == pytest.approx(ship.coefficients["tP"])
    assert np.max(np.abs(d.beta_p)) > math.radians(3.0)  # the zigzag drifts the propeller


def test_no_thrust_column_no_check(zigzag):
    ship, tr = zigzag
    model = ShipModel(ship)
    plain = tr.with_columns()
    plain.data.pop("thrust", None)
    assert model.logged_thrust(SimpleNamespace(p=model.start()), plain) is None


def test_a_propeller_short_of_thrust_is_seen_and_carries_the_missing_surge_force(zigzag):
    """A model whose open-water curve gives 20 % less thrust than the ship that logged it: the
    check reads the deficit, and the logged thrust in its place removes the missing surge force
    (the model is otherwise the truth)."""
    ship, tr = zigzag
    c = ship.coefficients
    weak = ShipModel(ship.with_coefficients({k: 0.8 * c[k] for k in ("k0", "k1", "k2")}))
    fit = SimpleNamespace(p=weak.start())
    motion, F, inputs = weak.missing_forces(fit, tr)
    th = _thrust_check(weak, fit, [(motion, inputs, tr)], [F])
    assert th.tracks == 1
    assert th.bias_fraction == pytest.approx(-0.2, abs=0.01)
    assert th.missing_x_rms_logged_thrust_n < 0.2 * th.missing_x_rms_n
    assert th.propeller_share > 0.9
    # the truth itself: no deficit, and the logged thrust changes nothing
    true = ShipModel(ship)
    fit = SimpleNamespace(p=true.start())
    motion, F, inputs = true.missing_forces(fit, tr)
    th = _thrust_check(true, fit, [(motion, inputs, tr)], [F])
    assert abs(th.bias_fraction) < 0.005
    assert th.rms_n < 0.01 * th.logged_mean_n


def test_the_report_says_whose_the_surge_miss_is():
    from bayesid.report.diagnosis import _thrust_lines

    th = {
        "tracks": 2,
        "logged_mean_n": 47.4,
        "model_mean_n": 35.8,
        "bias_fraction": -0.243,
        "rms_n": 11.8,
        "error_corr_abs_beta_p": 0.29,
        "missing_x_rms_n": 4.3,
        "missing_x_rms_logged_thrust_n": 9.6,
        "propeller_share": -3.9,
    }
    text = " ".join(_thrust_lines(th))
    assert "-24.3 %" in text and "absorbed the thrust error" in text
    text = " ".join(_thrust_lines({**th, "missing_x_rms_logged_thrust_n": 1.0, "propeller_share": 0.95}))
    assert "carries 0.95 of the missing surge force" in text
    assert _thrust_lines(None) == []
