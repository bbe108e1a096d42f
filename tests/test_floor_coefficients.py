"""Issue 67: the noise floor with the base fit's coefficient uncertainty (``DiagnoseOptions.floor``,
``bayesid diagnose --floor``). A KVLCC2 fitted on zigzags logged at 2 Hz without a velocity log,
nothing hidden, predicts a held-out turn worse than a perfect model does: its coefficients are
known only as well as the zigzags tell them. With the floor of a perfect model that reads as a gap
(``reports/ship_surge``: two of four controls "unexplained"); with the coefficients' uncertainty in
the floor it does not."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from bayesid.analysis import gap
from bayesid.analysis.gap.verdict import coefficient_draws
from bayesid.data.track import Track
from bayesid.models.ship import load_ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial

NOISE = {"x": 0.02, "y": 0.02, "psi": math.radians(0.1)}


def _fit(J, p, lo=-np.inf, hi=np.inf):
    model = SimpleNamespace(bounds=lambda: (np.full(p.size, lo), np.full(p.size, hi)))
    return SimpleNamespace(p=np.asarray(p, float), jac=np.asarray(J, float) if J is not None else None, model=model)


def test_the_draws_are_antithetic_around_the_fit_with_the_inverse_fisher_information_marginal_over_the_starts():
    rng = np.random.default_rng(3)
    # two coefficients and one start offset, the offset correlated with the first coefficient
    J = rng.normal(size=(400, 3))
    J[:, 2] += 2.0 * J[:, 0]
    p = np.array([1.0, -2.0])
    draws = coefficient_draws(_fit(J, p), n=4000, seed=1)
    assert draws.shape == (4000, 2)
    np.testing.assert_allclose(draws.mean(axis=0), p, atol=1e-12)  # antithetic pairs
    marginal = np.linalg.inv(J.T @ J)[:2, :2]  # over the offset, not conditional on it
    conditional = np.linalg.inv(J[:, :2].T @ J[:, :2])
    assert marginal[0, 0] > 2 * conditional[0, 0]
    scale = np.sqrt(np.outer(np.diag(marginal), np.diag(marginal)))
    np.testing.assert_allclose(np.cov(draws.T) / scale, marginal / scale, atol=0.05)


def test_the_draws_stay_inside_the_bounds_and_need_a_jacobian():
    J = np.eye(2) * 0.5  # sd 2 around 0: half the draws beyond +-1
    draws = coefficient_draws(_fit(J, np.zeros(2), lo=-1.0, hi=1.0), n=200)
    assert draws.min() >= -1.0 and draws.max() <= 1.0
    with pytest.raises(ValueError, match="no Jacobian"):
        coefficient_draws(_fit(None, np.zeros(2)))
    with pytest.raises(ValueError, match="floor must be one of"):
        gap.DiagnoseOptions(floor="perfect")


def _runs():
    """Two zigzags to train and a 35 deg turn held out, 2 Hz positions and heading, no velocity log;
    the truth is the vehicle file."""
    kv = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(kv, 1.179)
    rng = np.random.default_rng(7)
    out = []
    for kind, angle in (("zigzag", 10.0), ("zigzag", -20.0), ("turn", 35.0)):
        opts = TrialOptions(dt=0.1, sample_every=5, rudder_rate_deg_s=15.8, duration=150.0)
        tr = simulate_trial(kv, kind, angle, speed=speed, rpm=rpm, options=opts).track
        data = {k: np.asarray(tr[k], float) + rng.normal(0, s, tr.t.size) for k, s in NOISE.items()}
        data.update(delta_r=np.asarray(tr["delta_r"], float), n=np.asarray(tr["n"], float))
        out.append(Track(np.asarray(tr.t, float), data, name=f"{kind}{angle:+.0f}", meta=tr.meta))
    return kv, out[:2], out[2:]


@pytest.fixture(scope="module")
def control():
    """The same control diagnosed with either floor (no candidates: the floor and the gap alone)."""
    kv, train, held = _runs()
    opts = {
        f: gap.DiagnoseOptions(candidates=(), window_s=60.0, max_nfev=20, floor=f) for f in ("noise", "coefficients")
    }
    return {f: gap.diagnose(kv, kv.free, train, held, o) for f, o in opts.items()}


def test_a_control_whose_turn_the_zigzags_do_not_determine_is_clean_only_with_the_coefficients_in_the_floor(control):
    noise, coef = control["noise"], control["coefficients"]
    # the same base fit and held-out error; only the floor differs
    assert noise.gap_before["heldout_rms_m"] == pytest.approx(coef.gap_before["heldout_rms_m"])
    assert noise.noise_floor.coefficient_draws is None and coef.noise_floor.coefficient_draws == 4
    assert coef.noise_floor.diverged_share == 0.0
    assert coef.noise_floor.heldout_rms_m > 2 * noise.noise_floor.heldout_rms_m
    assert noise.significant_gap and noise.verdict != "none"
    assert not coef.significant_gap and coef.verdict == "none"
    assert coef.settings["floor"] == "coefficients" and noise.settings["floor"] == "noise"


@pytest.mark.parametrize("command", ["diagnose", "discover", "design"])
def test_the_commands_that_diagnose_take_the_floor_option(command):
    from bayesid.cli import build_parser
    from bayesid.cli.diagnose import diagnose_options

    base = ["--train", "a.csv", "--heldout", "b.csv", "--out", "o"]
    base += ["--vehicle", "kvlcc2_7m"] if command == "diagnose" else ["--model", "m.json"]
    args = build_parser().parse_args([command, *base])
    assert args.floor == "coefficients" and diagnose_options(args).floor == "coefficients"
    args = build_parser().parse_args([command, *base, "--floor", "noise"])
    assert diagnose_options(args).floor == "noise"
