"""Third-order velocity terms of the submarine term grammar: ``Nvvr`` (N from v^2 r), ``Yrrr``,
``Yvvv``, ``Nvabsvr``, ... in prime form, divided by the speed through the water U (the feature
``1/U``; Gertler & Hagen 1967, Feldman 1979, Fossen 2011 cubic cross-flow terms):
``N = 0.5 rho L^4 N'vvr v^2 r / U``.

They are read from their names, act alike in the generated and interpreted kernels and in the
reference implementation, give the hand-computed regressor column and can be fitted.
"""

from pathlib import Path

import numpy as np
import pytest

from bayesid.cli import main
from bayesid.data import terms
from bayesid.data.track import read_csv
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation.fit import SolverOptions
from bayesid.estimation.fit import fit as fit_problem
from bayesid.estimation.objective import Problem
from bayesid.models import dynamics, inverse
from bayesid.models import manoeuvres as mv
from bayesid.models.reference import reference_features, simulate_reference
from bayesid.models.simulate import Manoeuvre, Simulator

ROOT = Path(__file__).resolve().parents[1]
# Max position difference (m), compiled RK4 at dt = 0.05 s vs the reference (as in test_reference:
# measured <= 1e-9 m on these turns, with and without the third-order term).
TURN_POSITION_TOL_M = 1e-7
REF_TOL = dict(rtol=1e-12, atol=1e-12)
#: the third-order terms of the tests and their values (prime)
VALUES = {"Nvvr": -0.02, "Yrrr": -0.1}


def _nps_with(tmp_path, extra: str) -> Path:
    """A copy of the packaged NPS AUV II file with ``extra`` lines at the top of [coefficients]."""
    text = (ROOT / "bayesid" / "vehicles" / "nps_auv2.toml").read_text()
    p = tmp_path / "nps_third_order.toml"
    p.write_text(text.replace("[coefficients]\n", "[coefficients]\n" + extra, 1))
    return p


def _max_position_difference(a, b) -> float:
    return float(np.max(np.linalg.norm(a[:, :3] - b[:, :3], axis=1)))


# ---------------------------------------------------------------------------------------------
# Grammar
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name,group,factors,k,category,horizontal",
    [
        ("Nvvr", "N", ("v", "v", "r", "1/U"), 4, "rotary", True),  # 2 + 1 rate + 1 moment
        ("Yrrr", "Y", ("r", "r", "r", "1/U"), 5, "rotary", True),
        ("Yvvv", "Y", ("v", "v", "v", "1/U"), 2, "static", True),
        ("Nvvv", "N", ("v", "v", "v", "1/U"), 3, "static", True),
        ("Yvvr", "Y", ("v", "v", "r", "1/U"), 3, "rotary", True),
        ("Yvrr", "Y", ("v", "r", "r", "1/U"), 4, "rotary", True),
        ("Nvrr", "N", ("v", "r", "r", "1/U"), 5, "rotary", True),
        ("Nrrr", "N", ("r", "r", "r", "1/U"), 6, "rotary", True),
        ("Nvabsvr", "N", ("v", "|v|", "r", "1/U"), 4, "rotary", True),
        ("Yrrabsr", "Y", ("r", "r", "|r|", "1/U"), 5, "rotary", True),
        ("Yuuv", "Y", ("u", "u", "v", "1/U"), 2, "static", True),  # not Yv (u v): another product
        ("Nvvrdr", "N", ("v", "v", "r", "dr", "1/U"), 4, "rotary", True),  # rudder: no velocity
        ("Zwww", "Z", ("w", "w", "w", "1/U"), 2, "static", False),
        ("Mqqq", "M", ("q", "q", "q", "1/U"), 6, "rotary", False),
        ("Nvvr_eps", "N", ("v", "v", "r", "1/U", "eps"), 4, "rotary", False),
    ],
)
def test_third_order_names_read_with_their_factors_and_power_of_L(name, group, factors, k, category, horizontal):
    t = terms.parse(name)
    assert (t.group, t.factors, t.L_power, t.category, t.horizontal, t.multiplicity, t.kind) == (
        group,
        factors,
        k,
        category,
        horizontal,
        1,
        "force",
    )
    assert terms.listed_name(name) is None  # no listed product is divided by U
    assert terms.term(name).factors == factors and terms.NAMES[terms.INDEX[name]] == name


def test_the_listed_table_and_second_order_names_are_unchanged():
    assert terms.FEATURES[:17] == (
        "1", "u", "v", "w", "p", "q", "r", "dr", "ds", "db", "eps", "|v|", "|r|", "prop", "|w|", "|q|", "|p|"
    )  # fmt: skip
    assert terms.F_INDEX["1/U"] == 17 == terms.N_FEATURES - 1
    assert not any("1/U" in terms.term(n).factors for n in terms.LISTED)
    assert terms.parse("Yrabsr").factors == ("r", "|r|") and terms.parse("Ndr").factors == ("u", "u", "dr")
    assert terms.parse("Yvdrdr").factors == ("u", "v", "dr", "dr")


@pytest.mark.parametrize(
    "name,match",
    [
        ("Yvvvv", r"'Yvvvv': 4 velocity factors; a prime-form term has at most 3 .*1/U\*\*2"),
        ("Nvvrr", r"4 velocity factors"),
        ("Nvvwq", r"4 velocity factors"),
        ("Nrrabsvabsv", r"4 velocity factors"),
        ("Nvvrdrdr", r"6 factors \(v v r dr dr 1/U\); at most 5 \(1/U of the third velocity factor counts as one\)"),
        ("Yvvv_epsx", r"cannot read"),
    ],
)
def test_four_velocity_factors_or_too_many_factors_are_refused(name, match):
    n_before = len(terms.NAMES)
    with pytest.raises(terms.UnknownCoefficientError, match=match):
        terms.term(name)
    assert name not in terms.INDEX and len(terms.NAMES) == n_before


# ---------------------------------------------------------------------------------------------
# The feature 1/U
# ---------------------------------------------------------------------------------------------


def test_the_feature_is_the_inverse_speed_floored_alike_in_kernel_and_reference(nps):
    rng = np.random.default_rng(3)
    S = rng.normal(scale=0.5, size=(50, 12))
    S[:3, 6:9] = [[0.0, 0.0, 0.0], [1e-4, -2e-4, 0.0], [0.0, 0.0, -2.5]]  # at rest, below the floor, w only
    U = np.column_stack([rng.uniform(-0.3, 0.3, (50, 3)), np.full(50, 1200.0)])
    hand = 1.0 / np.maximum(np.sqrt(np.sum(S[:, 6:9] ** 2, axis=1)), dynamics.U_MIN_EPS)
    fk = dynamics.features_array(S, U, nps)[:, terms.F_INDEX["1/U"]]
    fr = reference_features(S, U, nps)[:, terms.F_INDEX["1/U"]]
    np.testing.assert_allclose(fk, hand, rtol=1e-14)
    np.testing.assert_allclose(fr, hand, rtol=1e-14)
    assert fk[0] == fk[1] == 1.0 / dynamics.U_MIN_EPS and fk[2] == pytest.approx(0.4)


# ---------------------------------------------------------------------------------------------
# Simulation: both kernels against the reference
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def turn(nps):
    """A 40 s 20 deg turning circle at dt = 0.05 s and the track without any third-order term
    (interpreted kernel: no kernel to generate for it)."""
    m = mv.turning_circle(nps, 20.0, dt=0.05, duration=40.0)
    return m, {
        mode: Simulator(nps, m, mode=mode, kernel="interpreted").run().states[0] for mode in ("6dof", "horizontal")
    }


@pytest.mark.parametrize("name,mode", [("Nvvr", "6dof"), ("Yrrr", "6dof"), ("Nvvr", "horizontal")])
def test_a_vehicle_file_with_a_third_order_term_simulates_as_the_reference(tmp_path, turn, name, mode):
    """The file loads; generated and interpreted kernels give the same track, the reference
    (numpy + solve_ivp) the same to RK4's error, and the term moves the track by metres, a
    million times the tolerance (so a wrong or missing 1/U fails)."""
    m, base = turn
    veh = load_vehicle(_nps_with(tmp_path, f"{name} = {VALUES[name]}\n"))
    assert veh.coefficients[name] == VALUES[name]
    gen = Simulator(veh, m, mode=mode, kernel="generated")
    assert name in gen.force_names
    rg = gen.run()
    ri = Simulator(veh, m, mode=mode, kernel="interpreted").run()
    rr = simulate_reference(veh, m, mode=mode, **REF_TOL)
    assert rg.status[0] == ri.status[0] == rr.status[0] == 0
    np.testing.assert_allclose(rg.states[0], ri.states[0], rtol=0, atol=1e-9)
    assert _max_position_difference(rg.states[0], rr.states[0]) < TURN_POSITION_TOL_M
    assert _max_position_difference(rg.states[0], base[mode]) > 0.1  # metres


def test_bayesid_simulate_takes_the_vehicle_file(nps, tmp_path, capsys):
    """The command's track is the file's model (the interpreted kernel on the track's own inputs
    gives it back), not the packaged vehicle's."""
    path = _nps_with(tmp_path, f"Nvvr = {VALUES['Nvvr']}\n")
    out = tmp_path / "turn.csv"
    args = ["simulate", "--vehicle", str(path), "--manoeuvre", "turn", "--angle", "20", "--duration", "30"]
    assert main([*args, "--mode", "horizontal", "--dt", "0.1", "--sample", "0.1", "--out", str(out)]) == 0
    tr = read_csv(out)
    m = Manoeuvre("cli turn", 0.1, tr.inputs(fill=0.0)[:-1], tr.states()[0])
    with_term = Simulator(load_vehicle(path), m, mode="horizontal", kernel="interpreted").run().states[0]
    without = Simulator(nps, m, mode="horizontal", kernel="interpreted").run().states[0]
    assert _max_position_difference(tr.states(), with_term) < 1e-6
    assert _max_position_difference(tr.states(), without) > 0.1


# ---------------------------------------------------------------------------------------------
# Regressor column and fit
# ---------------------------------------------------------------------------------------------


def test_library_column_is_the_prime_force_by_hand(nps, turn):
    m, base = turn
    S = base["horizontal"][::20]
    u, v, r = S[:, 6], S[:, 7], S[:, 11]
    u, v, r = np.append(u, 0.0), np.append(v, 0.0), np.append(r, 0.1)  # at rest but turning: U floored
    n = u.size
    motion = {"u": u, "v": v, "r": r, "u_dot": np.zeros(n), "v_dot": np.zeros(n), "r_dot": np.zeros(n)}
    inputs = np.column_stack([np.full(n, np.radians(20.0)), np.zeros((n, 2)), np.full(n, 1500.0)])
    cols = inverse.library_columns(["Nvvr", "Yrrr", "Nv"], motion, inputs, nps)
    speed = np.maximum(np.sqrt(u**2 + v**2), dynamics.U_MIN_EPS)
    half_rho = 0.5 * nps.rho
    np.testing.assert_allclose(cols[:, 0], half_rho * nps.L**4 * v**2 * r / speed, rtol=1e-13)
    np.testing.assert_allclose(cols[:, 1], half_rho * nps.L**5 * r**3 / speed, rtol=1e-13)
    np.testing.assert_allclose(cols[:, 2], half_rho * nps.L**3 * u * v, rtol=1e-13)
    assert cols[-1, 1] == pytest.approx(half_rho * nps.L**5 * 0.1**3 / dynamics.U_MIN_EPS)
    assert np.max(np.abs(cols[:-1, 0])) > 0.0 and np.all(np.isfinite(cols))


def test_a_short_fit_recovers_the_third_order_coefficient(nps):
    """Noise-free 60 s zigzag 20/20 with Nvvr = -0.02; Nvvr free from -0.01 with the linear
    yaw damping Nr: least squares recovers both."""
    m = mv.zigzag(nps, 20.0, 20.0, dt=0.05, duration=60.0)
    truth = nps.with_coefficients({"Nvvr": VALUES["Nvvr"]})
    target = Simulator(truth, m, mode="horizontal", sample_every=5).run().track(0)
    free = ["Nvvr", "Nr"]
    sim = Simulator(nps, m, free=free, mode="horizontal", sample_every=5)
    reference = np.array([-0.01, nps.coefficients["Nr"] * 1.05])
    pb = Problem(sim, target, reference)
    res = fit_problem(pb, np.ones(2), (np.full(2, 0.1), np.full(2, 10.0)), SolverOptions(max_nfev=40))
    assert res.theta[0] == pytest.approx(VALUES["Nvvr"], rel=1e-4)
    assert res.theta[1] == pytest.approx(nps.coefficients["Nr"], rel=1e-4)
    assert res.cost < 1e-8 * res.start_cost


# ---------------------------------------------------------------------------------------------
# The submarine term library offers them (issue 49: every product of up to three motion factors)
# ---------------------------------------------------------------------------------------------


def test_the_submarine_library_offers_every_product_of_three_motion_factors_once():
    from bayesid.models import build_model
    from bayesid.models.library import motion_products, term_library

    vehicle = load_vehicle("nps_auv2")
    model = build_model(vehicle, ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"])
    cands = term_library(model).candidates(model)
    products = {}
    for name in cands:
        t = terms.parse(name)
        key = (t.dof, tuple(sorted(t.factors)))
        assert key not in products, f"{name} and {products[key]} are one product"
        products[key] = name
    listed = {
        (terms.parse(k).dof, tuple(sorted(terms.parse(k).factors)))
        for k, v in vehicle.coefficients.items()
        if v != 0.0 and k[0] in "YN"
    }
    for g in "YN":
        for body in motion_products(3, rudder_abs=False):
            t = terms.parse(terms.listed_name(g + body) or g + body)
            key = (t.dof, tuple(sorted(t.factors)))
            assert key in products or key in listed, f"{g + body} is neither listed nor a candidate"
    assert {"Nvvr", "Yrrr", "Nvrr", "Yvvr"} <= set(cands)
