"""The rudder's two-sided flow-straightening coefficient: ``gR`` (gamma_R for beta_R >= 0) and
``gRm`` (beta_R < 0), Yasukawa & Yoshimura (2015), KVLCC2 L7: 0.640 and 0.395. Without ``gRm`` the
model is the one-gamma_R model, bit for bit; the pair makes the port and starboard manoeuvres differ;
both kernels agree; a file with ``gRm`` loads, fits, and a bad value is refused naming the key."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from bayesid.estimation.identification import identify
from bayesid.estimation.indices import manoeuvre_indices
from bayesid.estimation.options import FitOptions
from bayesid.models import ship
from bayesid.models.ship import layout
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial

#: the paper's pair (Yasukawa & Yoshimura 2015, KVLCC2 L7)
PAIR = {"gR": 0.640, "gRm": 0.395}
MMG_FILE = Path(__file__).resolve().parents[1] / "docs" / "vessels" / "kvlcc2_7m_mmg.toml"
KVLCC2_FILE = Path(__file__).resolve().parents[1] / "bayesid" / "vehicles" / "kvlcc2_7m.toml"
IGR, IGRM = layout.COEFFICIENT_INDEX["gR"], layout.COEFFICIENT_INDEX["gRm"]


def _trial(vessel, kind, angle, duration=None):
    """A manoeuvre from the HSVA approach (1.179 m/s, 15.8 deg/s helm) and its ITTC indices."""
    speed, rpm = propulsion_point(vessel, 1.179)
    opts = TrialOptions(dt=0.1, duration=duration, rudder_rate_deg_s=15.8)
    tr = simulate_trial(vessel, kind, angle, speed=speed, rpm=rpm, options=opts).track
    return tr, manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])


def _states(tr):
    return np.column_stack([tr[c] for c in ("x", "y", "psi", "u", "v", "r", "delta_r")])


def _ship_file(tmp_path, extra: str, free_extra: str = "") -> Path:
    """kvlcc2_7m's file with lines added after ``gR`` (and names added to ``[fit] free``)."""
    text = KVLCC2_FILE.read_text()
    text = text.replace("\ngR = 0.50", "\n" + extra + "\ngR = 0.50", 1)
    if free_extra:
        text = text.replace('"gR", "dR0"]', f'"gR", {free_extra}, "dR0"]', 1)
    path = tmp_path / "kv.toml"
    path.write_text(text)
    return path


def test_without_gRm_the_model_is_the_one_gamma_r_model_bit_for_bit():
    kv = ship.load_ship("kvlcc2_7m")
    assert kv.tied["gRm"] == "gR" and kv.coefficients["gRm"] == kv.coefficients["gR"]
    prm = kv.params()
    assert prm[IGRM] == prm[IGR]
    # a zigzag of the file as it is and with gRm = gR given: the same states, bit for bit
    explicit = kv.with_coefficients({"gRm": kv.coefficients["gR"]})
    assert "gRm" not in explicit.tied
    for angle in (10.0, -10.0):
        a, _ = _trial(kv, "zigzag", angle, duration=80.0)
        b, _ = _trial(explicit, "zigzag", angle, duration=80.0)
        np.testing.assert_array_equal(_states(a), _states(b))
    # a tied gRm follows gR in with_coefficients and in a fit's parameter rows (gR free alone)
    assert kv.with_coefficients({"gR": 0.7}).params()[IGRM] == 0.7
    assert kv.params({"gR": 0.7})[IGRM] == 0.7 and kv.params({"gR": 0.7, "gRm": 0.3})[IGRM] == 0.3
    built = dataclasses.replace(kv, coefficients={k: v for k, v in kv.coefficients.items() if k != "gRm"}, follows={})
    assert built.tied["gRm"] == "gR" and built.params()[IGRM] == kv.coefficients["gR"]
    assert kv.with_coefficients({"gRm": 0.3}).with_coefficients({"gR": 0.7}).params()[IGRM] == 0.3
    m = ship.ShipModel(kv, free=["Yv", "gR"])
    rows, _, _ = m.kernel_params(np.array([[-0.3, 0.6], [-0.3, 0.9]]))
    np.testing.assert_array_equal(rows[:, IGRM], [0.6, 0.9])
    # freed, gRm is its own parameter, started at gR
    m2 = ship.ShipModel(kv, free=["gR", "gRm"])
    assert list(m2.theta0) == [kv.coefficients["gR"]] * 2
    rows, _, _ = m2.kernel_params(np.array([[0.6, 0.3]]))
    assert rows[0, IGR] == 0.6 and rows[0, IGRM] == 0.3


def test_the_papers_pair_makes_the_port_and_starboard_runs_differ():
    # symmetric gamma_R: the port and starboard runs mirror each other. The paper's pair (the larger
    # gamma_R for beta_R >= 0, the stern moving to port as in a turn to starboard) takes rudder
    # inflow angle away in starboard turns and adds it in port turns: the overshoots to port grow
    # (a 10/10 zigzag to port first: its 1st; to starboard first: its 2nd), those to starboard
    # shrink, and the 35 deg turn to port tightens while the one to starboard widens.
    kv = ship.load_ship("kvlcc2_7m")
    asym = kv.with_coefficients(PAIR)
    idx = {}
    for name, vessel in (("sym", kv), ("asym", asym)):
        for angle in (10.0, -10.0):
            idx[name, "zigzag", angle] = _trial(vessel, "zigzag", angle)[1]
        for angle in (35.0, -35.0):
            idx[name, "turn", angle] = _trial(vessel, "turn", angle)[1]
    for k in ("first_overshoot_deg", "second_overshoot_deg"):
        assert idx["sym", "zigzag", 10.0][k] == pytest.approx(idx["sym", "zigzag", -10.0][k], rel=1e-9)
    td = "tactical_diameter_m"
    assert idx["sym", "turn", 35.0][td] == pytest.approx(idx["sym", "turn", -35.0][td], rel=1e-9)

    def change(kind, angle, key):
        return idx["asym", kind, angle][key] - idx["sym", kind, angle][key]

    # port first (+10): 1st overshoot (to port) up, 2nd (to starboard) down; starboard first: reversed
    assert change("zigzag", 10.0, "first_overshoot_deg") > 0.2
    assert change("zigzag", 10.0, "second_overshoot_deg") < -0.2
    assert change("zigzag", -10.0, "first_overshoot_deg") < -0.2
    assert change("zigzag", -10.0, "second_overshoot_deg") > 0.2
    assert change("turn", 35.0, td) < -0.1 and change("turn", -35.0, td) > 0.1


def test_generated_and_interpreted_kernels_agree_with_the_pair():
    kv = ship.load_ship("kvlcc2_7m").with_coefficients(PAIR)
    tr, _ = _trial(kv, "zigzag", 20.0, duration=120.0)
    P = np.array([[0.64, 0.395, 0.0], [0.5, 0.5, 0.01], [0.3, 0.9, -0.01]])
    out = {}
    for kind in ("generated", "interpreted"):
        m = ship.ShipModel(kv, free=["gR", "gRm", "dR0"], kernel=kind)
        out[kind] = m.simulate(m.context(tr, window_s=30.0), P)
    gen, ref = out["generated"], out["interpreted"]
    assert np.isfinite(ref).all()
    scale = np.abs(ref).max(axis=(0, 1))
    ok = scale > 0
    assert (np.abs(gen - ref).max(axis=(0, 1))[ok] / scale[ok] < 1e-10).all()
    # gRm acts in both: rows 0 and 1 differ in the heading after a window (psi, column 5)
    assert np.abs(ref[0, :, 5] - ref[1, :, 5]).max() > 1e-3
    assert np.abs(gen[0, :, 5] - gen[1, :, 5]).max() > 1e-3


def test_a_file_with_gRm_loads_fits_and_a_bad_value_names_the_key(tmp_path):
    path = _ship_file(tmp_path, "gRm = 0.395", '"gRm"')
    text = path.read_text().replace("gR = { rel_sd = 0.20 }", "gR = { rel_sd = 0.20 }\ngRm = { rel_sd = 0.25 }")
    path.write_text(text)
    kv = ship.load_ship(path)
    assert kv.coefficients["gRm"] == 0.395 and "gRm" not in kv.tied and "gRm" in kv.free
    assert kv.prior["gRm"] == pytest.approx((0.395, 0.25 * 0.395))
    assert kv.params()[IGRM] == 0.395 and kv.params()[IGR] == 0.5
    # the docs' MMG file gives the paper's pair, frees both and gives both a prior
    mmg = ship.load_ship(MMG_FILE)
    assert {k: mmg.coefficients[k] for k in PAIR} == PAIR and {"gR", "gRm"} <= set(mmg.free)
    assert {"gR", "gRm"} <= set(mmg.prior)
    # a small fit with both free recovers the pair from the symmetric start (noise-free zigzags)
    truth = kv.with_coefficients(PAIR)
    tracks = [_trial(truth, "zigzag", a, duration=100.0)[0] for a in (20.0, -20.0)]
    start = kv.with_coefficients({"gR": 0.5, "gRm": 0.5})
    res = identify(
        start,
        tracks,
        FitOptions(free=("gR", "gRm"), window_s=30.0, dt=0.1, max_nfev=30, equation_error_seed=False, prior=False),
    )
    est = dict(zip(res.model.param_names, res.fit.p))
    assert est["gR"] == pytest.approx(0.640, abs=0.02) and est["gRm"] == pytest.approx(0.395, abs=0.02)
    # bad values: named with the file, section and key
    for bad in ("gRm = -0.3", 'gRm = "x"', "gRm = nan"):
        with pytest.raises(ship.ShipFileError, match=r"\[coefficients\] gRm"):
            ship.load_ship(_ship_file(tmp_path, bad))
    neg = tmp_path / "neg.toml"
    neg.write_text(KVLCC2_FILE.read_text().replace("\ngR = 0.50", "\ngR = -0.5", 1))
    with pytest.raises(ship.ShipFileError, match=r"\[coefficients\] gR = -0.5"):
        ship.load_ship(neg)


def test_the_vessel_guides_comparison_of_the_two_kvlcc2_files_holds():
    # docs/vessel.rst: with --angle -10, the MMG file's second overshoot is the larger; its 35 deg
    # turns are the tighter to either side
    kv, mmg = ship.load_ship("kvlcc2_7m"), ship.load_ship(MMG_FILE)
    so = "second_overshoot_deg"
    assert _trial(mmg, "zigzag", -10.0)[1][so] > _trial(kv, "zigzag", -10.0)[1][so]
    td = "tactical_diameter_m"
    for angle in (35.0, -35.0):
        assert _trial(mmg, "turn", angle)[1][td] < _trial(kv, "turn", angle)[1][td]
    assert math.isfinite(_trial(mmg, "turn", 35.0)[1][td])
