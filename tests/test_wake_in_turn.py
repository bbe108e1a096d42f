"""The MMG 2015 wake in a turn and the ship's surge and propeller effects (issue 67).

``1 - w_P = (1 - wP) (1 + (1 - exp(-C1 |beta_P|)) (C2 - 1))``, ``C2m`` for ``beta_P < 0``
(Yasukawa & Yoshimura 2015, eq. 16): the thrust it gives is the hand-computed one; both kernels
agree; ``C1 = 0`` (a file without it) is the exp(-4 beta_P^2) form; a file with it loads and a bad
value names the key. The catalogue's coefficient shifts act on their coefficient only, are refused
beside that coefficient free, and are left out of a diagnosis that fits it, saying why."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bayesid.analysis.gap.diagnose import catalogue_candidates
from bayesid.models import ship
from bayesid.models.ship import dynamics, layout
from bayesid.models.ship.effects import SHIP_CATALOGUE
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial
from bayesid.tasks import Runner

KVLCC2_FILE = Path(__file__).resolve().parents[1] / "bayesid" / "vehicles" / "kvlcc2_7m.toml"
MMG = {"C1": 2.0, "C2": 1.6, "C2m": 1.1}  # Yasukawa & Yoshimura (2015), KVLCC2 L7


def _thrust_x(vessel, state, n_rps):
    """X of the interpreted kernel at ``state`` with the rudder at its neutral angle (no rudder
    drag: sin(dR0 - delta) = 0), and the thrust part computed by hand from the MMG form."""
    prm = vessel.params()
    out = np.empty((1, 3))
    inputs = np.array([[vessel.coefficients["dR0"], n_rps]])
    dynamics.forces(np.array([state], float), inputs, np.zeros((1, 2)), np.zeros(2), prm, out)
    return out[0, 0]


def test_the_wake_in_a_turn_gives_the_hand_computed_thrust_on_either_side():
    kv = ship.load_ship("kvlcc2_7m")
    turned = kv.with_coefficients(MMG)
    c, p = kv.coefficients, kv.particulars
    L, D, rho, n = p["L"], p["D_prop"], p["rho"], 10.0
    for v, r in ((-0.15, 0.02), (0.15, -0.02)):  # beta_P > 0 (a turn to starboard), then < 0
        state = (0.0, 0.0, 0.0, 1.0, v, r)
        vp = v + c["xP"] * L * r
        bP = math.atan2(-vp, 1.0)
        C2 = MMG["C2"] if bP > 0 else MMG["C2m"]

        def thrust(omw):
            J = min(max(omw * 1.0 / (n * D), -0.5), 1.2)
            return (1 - c["tP"]) * rho * n * n * D**4 * (c["k0"] + c["k1"] * J + c["k2"] * J * J)

        new = (1 - c["wP"]) * (1 + (1 - math.exp(-MMG["C1"] * abs(bP))) * (C2 - 1))
        old = 1 - c["wP"] * math.exp(-4 * vp * vp / (1 + vp * vp + 1e-12))
        # the hull and rudder parts are the same in both: the difference is the thrust's
        got = _thrust_x(turned, state, n) - _thrust_x(kv, state, n)
        assert got == pytest.approx(thrust(new) - thrust(old), rel=1e-9, abs=1e-12)
        assert abs(thrust(new) - thrust(old)) > 1e-3 * abs(thrust(old))
    # C2 acts for beta_P > 0 only, C2m for beta_P < 0 only
    starboard, port = (0.0, 0.0, 0.0, 1.0, -0.15, 0.02), (0.0, 0.0, 0.0, 1.0, 0.15, -0.02)
    only_c2 = kv.with_coefficients({**MMG, "C2": 1.3})
    assert _thrust_x(only_c2, port, n) == _thrust_x(turned, port, n)
    assert _thrust_x(only_c2, starboard, n) != _thrust_x(turned, starboard, n)


def test_both_kernels_agree_with_the_wake_in_a_turn_and_c1_zero_is_the_exp_form():
    kv = ship.load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(kv, 1.179)
    opts = TrialOptions(dt=0.1, duration=90.0, rudder_rate_deg_s=15.8)
    tr = simulate_trial(kv, "zigzag", 35.0, speed=speed, rpm=rpm, options=opts).track
    P = np.array([[2.0, 1.6, 1.1], [2.0, 1.1, 1.6], [0.5, 1.3, 1.3]])
    out = {}
    for kind in ("generated", "interpreted"):
        m = ship.ShipModel(kv, free=[], effects=["wake_in_turn"], kernel=kind)
        out[kind] = m.simulate(m.context(tr, window_s=30.0), P)
    gen, ref = out["generated"], out["interpreted"]
    assert np.isfinite(ref).all()
    scale = np.abs(ref).max(axis=(0, 1))
    ok = scale > 0
    assert (np.abs(gen - ref).max(axis=(0, 1))[ok] / scale[ok] < 1e-10).all()
    # the sides' C2 swapped: the speeds differ
    assert np.abs(ref[0, :, 6] - ref[1, :, 6]).max() > 1e-3
    # C1 = 0 given in a file is the file without it, bit for bit
    explicit = kv.with_coefficients({"C1": 0.0, "C2": 1.6})
    a = simulate_trial(explicit, "zigzag", 35.0, speed=speed, rpm=rpm, options=opts).track
    for k in ("x", "y", "psi", "u", "v", "r"):
        np.testing.assert_array_equal(np.asarray(a[k]), np.asarray(tr[k]))


def test_a_ship_file_with_the_wake_in_a_turn_loads_and_bad_values_name_the_keys(tmp_path):
    good = tmp_path / "kv.toml"
    good.write_text(KVLCC2_FILE.read_text().replace("\ngR = 0.50", "\nC1 = 2.0\nC2 = 1.6\ngR = 0.50", 1))
    kv = ship.load_ship(good)
    assert kv.coefficients["C2m"] == 1.6 and kv.tied["C2m"] == "C2"
    assert kv.params()[layout.COEFFICIENT_INDEX["C2m"]] == 1.6
    # the wake_in_turn effect starts from the file's own values
    assert list(SHIP_CATALOGUE["wake_in_turn"].start_values(kv)) == [2.0, 1.6, 1.6]
    for bad in ("C1 = 2.0", "C1 = -1.0", "C1 = 2.0\nC2 = 1.5\nC2m = -0.2"):
        path = tmp_path / "bad.toml"
        path.write_text(KVLCC2_FILE.read_text().replace("\ngR = 0.50", "\n" + bad + "\ngR = 0.50", 1))
        with pytest.raises(ship.ShipFileError, match=r"bad.toml: \[coefficients\] C1 = .*C2 = .*C2m"):
            ship.load_ship(path)


def test_a_coefficient_shift_moves_its_coefficient_only_and_is_refused_beside_it_free():
    kv = ship.load_ship("kvlcc2_7m")
    for name, coef in (("rudder_resistance", "tR"), ("thrust_deduction", "tP"), ("propulsion_point", "wP")):
        m = ship.ShipModel(kv, free=["Yv"], effects=[name])
        rows, _, _ = m.kernel_params(np.array([[kv.coefficients["Yv"], 0.1]]))
        changed = np.flatnonzero(rows[0] != kv.params())
        assert list(changed) == [layout.COEFFICIENT_INDEX[coef]]
        assert rows[0, changed[0]] == pytest.approx(kv.coefficients[coef] + 0.1)
        assert SHIP_CATALOGUE[name].vehicle_coefficients([0.1], kv) == {
            coef: pytest.approx(kv.coefficients[coef] + 0.1)
        }
    with pytest.raises(ValueError, match="wP free and the propulsion_point effect"):
        ship.ShipModel(kv, free=["wP"], effects=["propulsion_point"])
    with pytest.raises(ValueError, match="C1, C2 free and the wake_in_turn effect"):
        ship.ShipModel(kv, free=["C1", "C2", "Yv"], effects=["wake_in_turn"])


def test_the_catalogue_leaves_out_the_shifts_of_coefficients_the_base_model_fits():
    kv = ship.load_ship("kvlcc2_7m")
    said = []
    names = catalogue_candidates(ship.ShipModel, [], Runner(progress=said.append), free=kv.free)
    # KVLCC2's file frees Xuu and wP: their shifts are left out, said; the others compete
    assert "propulsion_point" not in names and "hull_resistance" not in names
    assert {"wake_in_turn", "rudder_resistance", "thrust_deduction", "current", "delay"} <= set(names)
    assert any("fits wP" in s and "propulsion_point" in s for s in said)
    assert any("fits Xuu" in s and "hull_resistance" in s for s in said)
    # without them free, they compete too
    names = catalogue_candidates(ship.ShipModel, [], Runner(), free=["Yv", "Nr"])
    assert {"propulsion_point", "hull_resistance"} <= set(names)


def test_a_named_wake_in_a_turn_written_by_write_vehicle_loads_and_fits(tmp_path):
    from types import SimpleNamespace

    from bayesid.cli.diagnose import _vehicle_values
    from bayesid.estimation.identification import identify
    from bayesid.estimation.options import FitOptions
    from bayesid.report.vehiclefile import write_vehicle_with_terms

    kv = ship.load_ship("kvlcc2_7m")
    effects = {"wake_in_turn": {"C1": 1.8, "C2": 1.5, "C2m": 1.2}, "rudder_resistance": {"dtR": -0.1}, "delay": {}}
    res = SimpleNamespace(discovered=None, after_fit={"coefficients": {}, "effects": effects})
    values, forms, named = _vehicle_values(res, kv)
    assert forms == {}
    assert values == {"C1": 1.8, "C2": 1.5, "C2m": 1.2, "tR": pytest.approx(kv.coefficients["tR"] - 0.1)}
    assert named == ["the wake_in_turn effect (C1, C2, C2m)", "the rudder_resistance effect (tR)"]
    path = write_vehicle_with_terms(KVLCC2_FILE, values, tmp_path / "kv_wake.toml", "test")
    written = ship.load_ship(path)
    assert {k: written.coefficients[k] for k in MMG} == {"C1": 1.8, "C2": 1.5, "C2m": 1.2}
    assert written.coefficients["tR"] == pytest.approx(kv.coefficients["tR"] - 0.1)
    # the written form is the one simulated: a turn differs from the file's; and it fits
    speed, rpm = propulsion_point(kv, 1.179)
    opts = TrialOptions(dt=0.1, duration=60.0, rudder_rate_deg_s=15.8)
    a = simulate_trial(written, "turn", 35.0, speed=speed, rpm=rpm, options=opts).track
    b = simulate_trial(kv, "turn", 35.0, speed=speed, rpm=rpm, options=opts).track
    assert abs(a["u"][-1] - b["u"][-1]) > 1e-3
    res = identify(written, [a], FitOptions(free=("Yv", "Nr"), window_s=30.0, dt=0.1, max_nfev=5, prior=False))
    assert res.fit.success and np.all(np.isfinite(res.fit.p))


def test_c2m_is_a_candidate_to_untie_only_where_it_acts():
    from bayesid.models.ship.library import ShipTerms

    kv = ship.load_ship("kvlcc2_7m")
    assert ShipTerms(kv).untied(ship.ShipModel(kv)) == ["gRm"]  # the exp form: C2m does not act
    turned = kv.with_coefficients({"C1": 2.0, "C2": 1.6})
    assert ShipTerms(turned).untied(ship.ShipModel(turned)) == ["gRm", "C2m"]
    # beside the wake_in_turn effect, which sets C2m
    free = [k for k in turned.free]
    assert ShipTerms(turned).untied(ship.ShipModel(turned, free=free, effects=["wake_in_turn"])) == ["gRm"]
