"""The generated ship kernel (bayesid.models.ship.kernel) against the interpreted one
(bayesid.models.ship.dynamics.simulate_windows), its oracle: same states to round-off (within 1e-10 of
each channel's largest magnitude over 300 steps; the measured differences are below 1.2e-15),
same status, same NaN layout after divergence."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from bayesid.data.track import Track
from bayesid.models import ship
from bayesid.models.ship import dynamics as shipdyn
from bayesid.models.ship import (
    hullterms,  # noqa: F401  (ship.hullterms)
    layout,
)
from bayesid.models.ship import kernel as shipkernel

#: agreement of the two kernels, relative to each state channel's largest magnitude
TOL = 1e-10
STARTS = np.array([0, 90, 170, 300])  # three windows, 300 steps
WIND_COEF = {"Cx1": -0.7, "Cx3": 0.1, "Cy1": -0.8, "Cy3": 0.05, "Cn1": -0.1, "Cn2": -0.05, "Cn3": 0.03}


def _case(ship_id, seed, B=7, windage=True):
    """Random kernel arguments: B parameter rows around the ship's (the hydrodynamic, propeller,
    rudder and wind coefficients perturbed by 10 % sd), random window-start states, rudder held
    10 steps, propeller in {-8, 0, 6, 12} rps held 30 steps (astern, stopped and reversing),
    random true wind and current. ``windage`` False: AT = AL = 0."""
    rng = np.random.default_rng(seed)
    base = ship.load_ship(ship_id).params(WIND_COEF)
    if not windage:
        base[[layout.PARTICULAR_INDEX["A_front"], layout.PARTICULAR_INDEX["A_lateral"]]] = 0.0
    elif base[layout.PARTICULAR_INDEX["A_lateral"]] == 0.0:  # KVLCC2 (tank): give it windage
        base[[layout.PARTICULAR_INDEX["A_front"], layout.PARTICULAR_INDEX["A_lateral"]]] = [0.5, 2.0]
    prm = np.repeat(base[None], B, axis=0)
    o = len(layout.PARTICULARS)
    nc = len(layout.COEFFICIENTS)
    prm[:, o : o + nc] *= 1.0 + 0.1 * rng.standard_normal((B, nc))  # the form slots stay as the file has them
    W, n = STARTS.size - 1, STARTS[-1]
    s0 = np.zeros((B, W, 6))
    s0[..., 0:2] = rng.normal(0.0, 5.0, (B, W, 2))
    s0[..., 2] = rng.uniform(-4.0, 4.0, (B, W))
    s0[..., 3] = rng.uniform(-0.3, 1.2, (B, W))
    s0[..., 4] = rng.normal(0.0, 0.1, (B, W))
    s0[..., 5] = rng.normal(0.0, 0.03, (B, W))
    inputs = np.empty((B, n, 2))
    inputs[..., 0] = np.repeat(rng.uniform(-0.6, 0.6, (B, n // 10)), 10, axis=1)
    inputs[..., 1] = np.repeat(rng.choice([-8.0, 0.0, 6.0, 12.0], (B, n // 30)), 30, axis=1)
    wind = rng.normal(0.0, 4.0, (n, 2))
    cur = rng.normal(0.0, 0.1, (B, 2))
    return [s0, STARTS, inputs, wind, cur, prm, 0.2]


def _run(fn, args):
    s0, starts = args[0], args[1]
    out = np.full((s0.shape[0], starts[-1] + s0.shape[1], 6), -1.0)
    status = np.full(s0.shape[:2], -1, dtype=np.int64)
    fn(*args, out, status)
    return out, status


def _assert_agree(args):
    ref, st_ref = _run(shipdyn.simulate_windows, args)
    gen, st_gen = _run(shipkernel.simulate_windows, args)
    np.testing.assert_array_equal(st_gen, st_ref)
    np.testing.assert_array_equal(np.isnan(gen), np.isnan(ref))
    scale = np.nanmax(np.abs(ref), axis=(0, 1))
    err = np.nan_to_num(np.abs(gen - ref)).max(axis=(0, 1)) / scale
    assert (err < TOL).all(), f"largest difference per channel, relative to its scale: {err}"
    return ref, st_ref


@pytest.mark.parametrize(
    "ship_id, seed, windage",
    [("esso_osaka_3m", 0, True), ("esso_osaka_3m", 1, False), ("kvlcc2_7m", 2, True), ("kvlcc2_7m", 3, False)],
)
def test_generated_kernel_agrees_with_the_interpreted_one(ship_id, seed, windage):
    ref, status = _assert_agree(_case(ship_id, seed, windage=windage))
    assert not status.any() and np.isfinite(ref).all()  # every window ran to its end
    assert np.ptp(ref[..., 2]) > 0.1 and np.ptp(ref[..., 4]) > 0.01  # turning and drifting


def test_rows_with_and_without_windage_in_one_call():
    """Every other row without windage: each lane pair of the generated kernel mixes the two."""
    args = _case("esso_osaka_3m", 4, B=6)
    args[5][::2, [layout.PARTICULAR_INDEX["A_front"], layout.PARTICULAR_INDEX["A_lateral"]]] = 0.0
    _assert_agree(args)


def test_rows_of_either_coupling_form_in_one_call():
    """Every other row with MMG 2015's coupling speed U (``[form] coupling_speed = "U"``): the two
    kernels agree, and those rows differ from the package's form ``Ut`` (the slot is read)."""
    args = _case("kvlcc2_7m", 6, B=6)
    ut, _ = _assert_agree(args)
    args[5][::2, layout.FORM_INDEX["coupling_rL"]] = 0.0
    mixed, _ = _assert_agree(args)
    np.testing.assert_array_equal(mixed[1::2], ut[1::2])
    assert np.nanmax(np.abs(mixed[::2, :, 5] - ut[::2, :, 5])) > 1e-4


def test_diverging_rows_get_the_same_status_and_nan_layout():
    """Rows 1 and 5 move in one degree of freedom only (no rudder, propeller, windage, sway-yaw
    coupling or cross-flow drag: the other velocities stay exactly 0) with a pushing hull damping:
    u (Xuu > 0) and v (Yv > 0) grow from 20 m/s past the 50 m/s limit by ~3 m/s a step. Row 3
    with an unstable yaw damping (Nr > 0) turns ever faster past 10 rad/s. Status 1 in those
    windows, the rest of each NaN, the other rows untouched; an odd B leaves one lane idle."""
    args = _case("esso_osaka_3m", 5, B=7)
    s0, inputs, prm = args[0], args[2], args[5]
    for b, channel, name in ((1, 3, "Xuu"), (5, 4, "Yv")):
        prm[
            b, [layout.PARTICULAR_INDEX["A_front"], layout.PARTICULAR_INDEX["A_lateral"], layout.PARTICULAR_INDEX["xG"]]
        ] = 0.0
        prm[b, [layout.COEFFICIENT_INDEX[k] for k in ("Xvv", "Ycf", "Ncf", "gR", "gRm")]] = 0.0
        prm[b, layout.COEFFICIENT_INDEX[name]] = 0.005
        inputs[b] = 0.0
        s0[b, :, 3:] = 0.0
        s0[b, :, channel] = 20.0
    prm[3, layout.COEFFICIENT_INDEX["Nr"]] = 0.3
    ref, status = _assert_agree(args)
    assert status[[1, 5]].all() and status[3].any() and not status[[0, 2, 4, 6]].any()
    for b, channel in ((1, 3), (5, 4)):
        for w in range(STARTS.size - 1):
            rows = ref[b, STARTS[w] + w : STARTS[w + 1] + w + 1]
            last = np.argmax(np.isnan(rows[:, 0])) - 1  # the last state within the limits
            assert 45.0 < rows[last, channel] <= 50.0 and np.isnan(rows[last + 1 :]).all()


def test_ship_model_simulates_a_track_the_same_with_either_kernel(monkeypatch):
    """Through ShipModel.simulate: a 120 s zigzag track with wind columns, the wind, current and
    delay effects on, three parameter rows; kernel="generated" runs the generated kernel."""
    generated, calls = shipkernel.simulate_windows, []

    def spy(*args):
        calls.append(len(args))
        return generated(*args)

    monkeypatch.setattr(shipkernel, "simulate_windows", spy)
    es = ship.load_ship("esso_osaka_3m")
    t = np.arange(0.0, 120.0, 0.5)
    delta = np.where(np.sin(2 * np.pi * t / 40) >= 0, -1.0, 1.0) * math.radians(20.0)
    U = 0.6
    tr = Track(
        t,
        {
            "x": U * t,
            "y": 0 * t,
            "psi": 0 * t,
            "u": 0 * t + U,
            "v": 0 * t,
            "r": 0 * t,
            "delta_r": delta,
            "n": 0 * t + 600.0,
            "wind_speed": 3.0 + np.sin(t / 20),
            "wind_dir": 0.5 + 0.3 * np.cos(t / 30),
        },
        name="zigzag",
    )
    S = {}
    for kind in shipkernel.KINDS:
        m = ship.ShipModel(es, effects=("wind", "current", "delay"), dt=0.2, kernel=kind)
        ctx = m.context(tr, 30.0)
        P = np.repeat(m.start()[None], 3, axis=0)
        P[1, m.param_names.index("Nr")] *= 1.2
        P[2, m.param_names.index("current.current_x_mps")] = 0.05
        P[2, m.param_names.index("delay.delay_s")] = 0.7
        S[kind] = m.simulate(ctx, P)
    assert calls == [9]
    ref, gen = S["interpreted"], S["generated"]
    assert ref.shape == gen.shape and ref.shape[0] == 3 and np.isfinite(ref).all()
    assert (np.abs(gen - ref) <= TOL * np.abs(ref).max(axis=(0, 1))).all()
    assert np.abs(ref[1] - ref[0]).max() > 0.01  # the rows differ: the comparison sees the parameters


def test_unknown_kernel_is_named():
    with pytest.raises(ValueError, match="kernel.*'compiled'"):
        ship.ShipModel(ship.load_ship("kvlcc2_7m"), kernel="compiled")
    with pytest.raises(ValueError, match="'compiled'"):
        shipkernel.kernel("compiled")


#: extra hull terms of every kind: a constant, a cubic (1/U), rudder powers and |.| forms, fourth-order
#: surge terms (1/U^2; Yasukawa & Yoshimura 2015's X'vvvv of KVLCC2, 0.771)
EXTRA_TERMS = {
    "N0": 0.002,
    "Y0": -0.003,
    "Yvvv": -0.6,
    "Nrrr": -0.02,
    "Ndrabsdr": 0.01,
    "Nabsdr": 0.004,
    "Xabsvdr": 0.01,
    "Xvvvv": 0.771,
    "Xvvabsvabsr": -0.2,
}


def test_generated_kernel_with_extra_hull_terms_agrees_with_the_interpreted_one():
    # the generated kernel reads each term's degree of freedom, exponents and coefficient from the row
    shp = ship.load_ship("kvlcc2_7m").with_coefficients(EXTRA_TERMS)
    args = _case("kvlcc2_7m", 4)
    terms = shp.hull_terms
    tail = ship.hullterms.encode(terms, shp.coefficients)
    rng = np.random.default_rng(4)
    prm = np.concatenate([args[5], np.repeat(tail[None], args[5].shape[0], axis=0)], axis=1)
    cidx = list(ship.hullterms.index(terms).values())
    prm[:, cidx] *= 1.0 + 0.3 * rng.standard_normal((prm.shape[0], len(cidx)))
    args[5] = prm
    ref, st_ref = _run(shipdyn.simulate_windows, args)
    gen, st_gen = _run(lambda *a: shipkernel.simulate_windows(*a, terms=ship.hullterms.signature(terms)), args)
    np.testing.assert_array_equal(st_gen, st_ref)
    scale = np.nanmax(np.abs(ref), axis=(0, 1))
    assert (np.nan_to_num(np.abs(gen - ref)).max(axis=(0, 1)) / scale < TOL).all()
    # and the terms change the motion (the kernels do not ignore them)
    base, _ = _run(shipdyn.simulate_windows, [*args[:5], args[5][:, : layout.NP], args[6]])
    assert np.nanmax(np.abs(base[..., 5] - ref[..., 5])) > 1e-3
    # one compiled kernel serves every term set (a compile per set cost 8-17 s, one per candidate
    # term discovery refits); the kernel without terms is the one without the term loop
    other = ship.hullterms.signature(ship.load_ship("kvlcc2_7m").with_coefficients({"Nvvv": 0.01}).hull_terms)
    assert shipkernel.generated(2, other) is shipkernel.generated(2, ship.hullterms.signature(terms))
    assert shipkernel.generated(2, ()) is not shipkernel.generated(2, other)
    assert "_terms(" not in shipkernel.source(2, ()) and "_terms(" in shipkernel.source(2, other)


def test_extra_hull_terms_in_the_forces_are_the_prime_form_columns():
    # kernel forces with the terms minus without them = sum of coefficient x hullterms.columns
    shp0 = ship.load_ship("kvlcc2_7m")
    shp = shp0.with_coefficients(EXTRA_TERMS)
    rng = np.random.default_rng(5)
    n = 40
    st = np.column_stack([np.zeros((n, 2)), rng.normal(size=n), 0.2 + rng.random(n), 0.1 * rng.normal(size=(n, 2))])
    inp = np.column_stack([0.3 * rng.normal(size=n), np.full(n, 10.0)])
    F0, F1 = np.empty((n, 3)), np.empty((n, 3))
    for prm, F in ((shp0.params(), F0), (shp.params(), F1)):
        shipdyn.forces(st, inp, np.zeros((n, 2)), np.zeros(2), prm, F)
    P = shp.particulars
    C = ship.hullterms.columns(shp.hull_terms, st[:, 3], st[:, 4], st[:, 5], inp[:, 0], P["L"], P["rho"], P["d"])
    expect = np.zeros((n, 3))
    for k, t in enumerate(shp.hull_terms):
        expect[:, t.dof] += EXTRA_TERMS[t.name] * C[:, k]
    np.testing.assert_allclose(F1 - F0, expect, rtol=1e-10, atol=1e-12 * np.abs(expect).max())
    # the prime form by hand for two terms: N0 = q L U^2 N0', Yvvv = q v^3 / U Yvvv'
    q = 0.5 * P["rho"] * P["L"] * P["d"]
    U = np.hypot(st[:, 3], st[:, 4])
    np.testing.assert_allclose(C[:, 0], q * P["L"] * U**2)
    np.testing.assert_allclose(C[:, 2], q * st[:, 4] ** 3 / U)
    # and a fourth-order surge term: Xvvvv = q v^4 / U^2 Xvvvv'
    np.testing.assert_allclose(C[:, 7], q * st[:, 4] ** 4 / U**2)


def test_surge_terms_reach_fourth_order_in_the_velocities_only():
    from bayesid.models.ship.library import ShipTerms, surge_products

    assert ship.hullterms.parse("Xvvvv").factors == ("v",) * 4
    assert ship.hullterms.parse("Xvvrr").n_velocity == 4
    for bad in ("Yvvvv", "Nvvrr", "Xvvvdr", "Xvvvvv"):  # sway, yaw, a rudder factor, fifth order
        with pytest.raises(ship.hullterms.HullTermError, match="factors"):
            ship.hullterms.parse(bad)
    # the library offers the fourth-order surge products even in v, r (X(v, r) = X(-v, -r)) in X only
    bodies = surge_products()
    assert {"vvvv", "vvvr", "vvrr", "vrrr", "rrrr"} <= set(bodies) and "vvvabsv" not in bodies
    lib = ShipTerms(ship.load_ship("kvlcc2_7m"))
    model = SimpleNamespace(free=[])
    names = [n for n in lib.candidates(model, 3, ("X", "Y", "N")) if ship.hullterms.is_term(n)]
    assert {"Xvvvv", "Xvvrr", "Xrrrr"} <= set(names)
    assert max(len(ship.hullterms.parse(n).factors) for n in names if n[0] in "YN") == 3
    assert "Xvvvv" not in lib.candidates(model, 2, ("X",))
    assert not any(n.startswith("X") for n in lib.candidates(model, 3, ("Y", "N")))
