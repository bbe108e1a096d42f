"""Generated kernels (bayesid.models.codegen) against the interpreted one (bayesid.models.dynamics),
the oracle: same tracks, same divergence flags, for the batch and the window drivers, 6-DOF and
the horizontal plane, random states, inputs and coefficient vectors.

The generated kernel evaluates every sum and product in the interpreted kernel's order, so the
tracks are expected bit-identical; the assertion allows round-off (rtol 1e-12 of the largest
state) so that a harmless reordering would not fail it, while a dropped or wrong term (a 1e-3
relative change of one coefficient moves the states by far more) does.
"""

from __future__ import annotations

import numpy as np
import pytest

from bayesid.data import terms
from bayesid.data.vehicle import load_vehicle
from bayesid.models import codegen
from bayesid.models.simulate import Manoeuvre, Simulator
from bayesid.models.submarine import EffectModel

RTOL = 1e-12


@pytest.fixture(scope="module")
def veh():
    return load_vehicle("nps_auv2")


def _random_manoeuvre(rng, mode, n_steps=300, dt=0.1) -> Manoeuvre:
    """Random piecewise-constant inputs (rudder, planes, rpm including reversals) from a random
    state near the vehicle's cruise (pitch, roll and their rates only in 6-DOF)."""
    inp = np.zeros((n_steps, 4))
    blocks = n_steps // 20 + 1
    inp[:, 0] = np.repeat(rng.uniform(-0.4, 0.4, blocks), 20)[:n_steps]
    inp[:, 3] = np.repeat(rng.uniform(-300.0, 900.0, blocks), 20)[:n_steps]
    s0 = np.zeros(12)
    s0[:2] = rng.normal(0, 10, 2)
    s0[5] = rng.uniform(-3, 3)
    s0[6], s0[7], s0[11] = rng.uniform(0.5, 2.5), rng.normal(0, 0.2), rng.normal(0, 0.1)
    if mode == "6dof":
        inp[:, 1] = np.repeat(rng.uniform(-0.3, 0.3, blocks), 20)[:n_steps]
        inp[:, 2] = np.repeat(rng.uniform(-0.3, 0.3, blocks), 20)[:n_steps]
        s0[2], s0[3], s0[4] = rng.uniform(0, 20), rng.normal(0, 0.1), rng.normal(0, 0.1)
        s0[8], s0[9], s0[10] = rng.normal(0, 0.1), rng.normal(0, 0.05), rng.normal(0, 0.05)
    return Manoeuvre("random", dt, inp, s0)


def _random_coefficients(rng, sim, B):
    """B coefficient vectors: every free coefficient perturbed by +-30 % around the vehicle."""
    base = sim.vehicle.coefficient_vector(sim.free)
    return base * (1.0 + rng.uniform(-0.3, 0.3, (B, base.size)))


def _assert_same(a, b):
    scale = max(1.0, float(np.nanmax(np.abs(a))))
    assert np.array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_allclose(np.nan_to_num(a), np.nan_to_num(b), rtol=0, atol=RTOL * scale)


@pytest.mark.parametrize("mode", ["6dof", "horizontal"])
@pytest.mark.parametrize("B", [1, 5])
def test_batch_driver_agrees_with_the_interpreted_kernel(veh, mode, B):
    """Random manoeuvre, random start, B random coefficient vectors (odd B: the second lane of
    the last pair is padding), sampled every 3rd step."""
    rng = np.random.default_rng(100 + B + len(mode))
    man = _random_manoeuvre(rng, mode)
    free = [
        n
        for n in terms.NAMES
        if terms.term(n).kind == "force"
        and veh.coefficients.get(n, 0.0) != 0.0
        and (mode == "6dof" or terms.term(n).horizontal)
    ] + ["Yvdot", "Nrdot", "Yrdot", "Nvdot"]
    runs = {k: Simulator(veh, man, free, mode=mode, sample_every=3, kernel=k) for k in codegen.KINDS}
    theta = _random_coefficients(rng, runs["generated"], B)
    gen, ref = runs["generated"].run(theta), runs["interpreted"].run(theta)
    _assert_same(gen.states, ref.states)
    assert np.array_equal(gen.status, ref.status) and np.array_equal(gen.fail_step, ref.fail_step)


@pytest.mark.parametrize("mode", ["6dof", "horizontal"])
def test_divergence_is_flagged_at_the_same_step_with_the_same_nan_fill(veh, mode):
    """A yaw damping of the wrong sign and ten times too large makes the turn run away: the
    track is flagged out of bounds at the same step by both kernels, and NaN from there on; the
    stable tracks of the same batch are unaffected."""
    rng = np.random.default_rng(7)
    man = _random_manoeuvre(rng, mode, n_steps=600)
    runs = {k: Simulator(veh, man, ["Nr", "Yr"], mode=mode, kernel=k) for k in codegen.KINDS}
    nr, yr = veh.coefficients["Nr"], veh.coefficients["Yr"]
    theta = np.array([[nr, yr], [-10 * nr, yr], [nr, yr * 1.1]])
    gen, ref = runs["generated"].run(theta), runs["interpreted"].run(theta)
    assert ref.status[1] != 0 and ref.status[0] == 0  # the test exercises a divergence
    _assert_same(gen.states, ref.states)
    assert np.array_equal(gen.status, ref.status) and np.array_equal(gen.fail_step, ref.fail_step)


def test_a_coefficient_zero_at_generation_but_free_is_not_dropped(veh):
    """Nprop (a yaw moment from propeller asymmetry) is zero for NPS AUV II. Fixed at zero it
    is not in the generated source; free, it is, and a non-zero value changes the track exactly
    as in the interpreted kernel."""
    assert veh.coefficients.get("Nprop", 0.0) == 0.0
    rng = np.random.default_rng(3)
    man = _random_manoeuvre(rng, "6dof")
    fixed = Simulator(veh, man, ["Yv"], mode="6dof")
    assert "Nprop" not in fixed.force_names
    freed = {k: Simulator(veh, man, ["Yv", "Nprop"], mode="6dof", kernel=k) for k in codegen.KINDS}
    assert "Nprop" in codegen.source(freed["generated"].force_names, "6dof").split("Terms:")[1].split()
    theta = np.array([[veh.coefficients["Yv"], 0.0], [veh.coefficients["Yv"], 0.002]])
    gen, ref = freed["generated"].run(theta), freed["interpreted"].run(theta)
    _assert_same(gen.states, ref.states)
    assert np.max(np.abs(gen.states[1] - gen.states[0])) > 1e-3  # the freed term acts


@pytest.mark.parametrize(
    "effects,mode", [(("waves", "thrust"), "horizontal"), (("crossflow",), "horizontal"), (("roll",), "6dof")]
)
def test_window_driver_agrees_through_the_effect_model(veh, effects, mode):
    """Exogenous forces (waves, thrust deficit), the cross-flow integral switched on per
    parameter vector, and the 6-DOF window kernel (roll), over several windows of a random
    track, with B = 3 parameter vectors."""
    rng = np.random.default_rng(11)
    man = _random_manoeuvre(rng, "horizontal", n_steps=900)
    truth = Simulator(veh, man, mode="horizontal").run()
    tr = truth.track(0, name="random")
    models = {k: EffectModel(veh, ["Yv", "Nr"], effects, mode=mode, dt=0.2, kernel=k) for k in codegen.KINDS}
    m = models["generated"]
    ctx = m.context(tr, 20.0)
    P = np.repeat(m.start()[None], 3, axis=0)
    lo, hi = m.bounds()
    P[:, m.n_theta :] = np.clip(
        P[:, m.n_theta :] * (1 + rng.uniform(-0.2, 0.2, (3, P.shape[1] - m.n_theta))), lo[m.n_theta :], hi[m.n_theta :]
    )
    P[:, : m.n_theta] *= 1 + rng.uniform(-0.2, 0.2, (3, m.n_theta))
    nu = rng.uniform(-1, 1, (3, max(m.n_nuisance, 1)))
    gen = models["generated"].simulate(ctx, P, nu)
    ref = models["interpreted"].simulate(models["interpreted"].context(tr, 20.0), P, nu)
    assert ctx.W > 2
    _assert_same(gen, ref)


def test_the_generated_source_unrolls_the_active_terms_only(veh):
    """The horizontal source multiplies only horizontal-plane degrees of freedom; the eps(eta)
    propulsion function appears only when an _eps term is active; the hash names the file."""
    names = ["Yv", "Nr", "Xvv"]
    src = codegen.source(names, "horizontal")
    assert "c_0[0]*u_0*v_0" in src and "F2_" not in src and "eps_" not in src
    src6 = codegen.source(names + ["Zq_eps"], "6dof")
    assert "eps_s1_0" in src6 and "c_0[3]*u_0*q_0*eps_s1_0" in src6
    with pytest.raises(ValueError, match="acceleration term"):
        codegen.source(["Yvdot"], "6dof")
    with pytest.raises(ValueError, match="kernel must be one of"):
        Simulator(veh, _random_manoeuvre(np.random.default_rng(0), "horizontal"), kernel="fast")


def test_a_simulator_pickles_without_its_kernel_and_reloads_it(veh):
    """joblib, Dask and deepcopy pickle models; the generated module is not picklable, so it is
    dropped and loaded again on first use, with the same tracks."""
    import pickle

    sim = Simulator(
        veh, _random_manoeuvre(np.random.default_rng(5), "horizontal", n_steps=100), ["Nr"], mode="horizontal"
    )
    a = sim.run()
    b = pickle.loads(pickle.dumps(sim)).run()
    assert np.array_equal(a.states, b.states)


@pytest.mark.parametrize("mode", ["6dof", "horizontal"])
def test_submarine_kernels_are_bit_identical(veh, mode):
    """The stronger claim the committed reports rely on: not only round-off, the same bits."""
    rng = np.random.default_rng(21)
    man = _random_manoeuvre(rng, mode, n_steps=400)
    free = ["Yv", "Nr", "Yr", "Nv", "Xvv", "Yvdot", "Nrdot"] + (["Zw", "Mq"] if mode == "6dof" else [])
    runs = {k: Simulator(veh, man, free, mode=mode, kernel=k) for k in codegen.KINDS}
    theta = _random_coefficients(rng, runs["generated"], 3)
    gen, ref = runs["generated"].run(theta), runs["interpreted"].run(theta)
    assert np.array_equal(gen.states, ref.states, equal_nan=True)


def test_the_candidates_a_vehicle_lacks_share_one_open_kernel_with_the_same_bits(veh):
    """Discovery frees, one refit at a time, a coefficient the vehicle lacks. Each such model
    runs in the one open kernel of the vehicle's terms (no compile per candidate), with the
    candidate taken at run time, and its tracks are the interpreted kernel's bits; the candidate
    acts. Nprop sits before some of the vehicle's yaw terms in the table: adding it after them
    would change the sum's order, so it gets a kernel generated for all its terms."""
    rng = np.random.default_rng(17)
    man = _random_manoeuvre(rng, "horizontal", n_steps=300)
    modules = set()
    for cand in ("Nvvr", "Yabsrdrdr", "Cd0"):
        free = ["Yv", "Nr", cand]
        runs = {k: Simulator(veh, man, free, mode="horizontal", kernel=k) for k in codegen.KINDS}
        if cand == "Cd0":  # the vehicle has it: not a further term, the generated kernel as before
            assert runs["generated"].further_names == []
            assert not isinstance(runs["generated"].kernel, codegen.Open)
            continue
        kern = runs["generated"].kernel
        assert isinstance(kern, codegen.Open) and runs["generated"].further_names == [cand]
        modules.add(kern.module.__name__)
        theta = np.repeat(veh.coefficient_vector(["Yv", "Nr"])[None], 3, axis=0)
        theta = np.hstack([theta, [[0.0], [0.01], [-0.02]]])
        gen, ref = runs["generated"].run(theta), runs["interpreted"].run(theta)
        assert np.array_equal(gen.states, ref.states, equal_nan=True)
        assert np.array_equal(gen.status, ref.status)
        assert np.max(np.abs(gen.states[1] - gen.states[0])) > 1e-3  # the candidate acts
    assert len(modules) == 1
    assert not codegen.further_terms_last(["Yv", "Nprop", "Nr"], ["Nprop"])
    assert not isinstance(Simulator(veh, man, ["Yv", "Nprop"], mode="horizontal").kernel, codegen.Open)


def test_an_open_kernel_reorders_columns_and_computes_every_factor_as_generated(veh):
    """A further term that precedes some of the vehicle's terms of another degree of freedom in
    the table: the open kernel takes its ``tcoef`` columns in another order (``perm``). The
    further terms' factors include 1/U (a third velocity factor, Nvvr) and the propeller's
    ``prop`` (Cd0), computed in the loop as in the generated right-hand side: the batch and the
    window drivers give the interpreted kernel's bits. (eps(eta) terms act out of the horizontal
    plane; the loop computes them as the generated 6-DOF right-hand side does.)"""
    import dataclasses

    keep = ("Yv", "Yr", "Ydr", "Nv", "Nr", "Ndr", "Xuu", "Yvdot", "Nrdot")
    small = dataclasses.replace(veh, coefficients={k: veh.coefficients[k] for k in keep if k in veh.coefficients})
    ydof = terms.term("Yv").dof
    y_after = next(
        t.name
        for t in terms.TERMS[terms.INDEX["Ydr"] + 1 :]
        if t.kind == "force" and t.dof == ydof and t.horizontal and t.name not in keep
    )
    further = [y_after, "Nvvr", "Cd0"]
    free = ["Yv", "Nr", *further]
    rng = np.random.default_rng(23)
    man = _random_manoeuvre(rng, "horizontal", n_steps=300)
    runs = {k: Simulator(small, man, free, mode="horizontal", kernel=k) for k in codegen.KINDS}
    kern = runs["generated"].kernel
    assert isinstance(kern, codegen.Open) and kern.perm is not None
    theta = np.repeat(small.coefficient_vector(["Yv", "Nr"])[None], 3, axis=0)
    theta = np.hstack([theta, rng.normal(0.0, 0.005, (3, len(further)))])
    gen, ref = runs["generated"].run(theta), runs["interpreted"].run(theta)
    assert np.array_equal(gen.states, ref.states, equal_nan=True)
    tr = runs["interpreted"].run().track(0, name="random")
    models = {k: EffectModel(small, free, ("thrust",), mode="horizontal", dt=0.2, kernel=k) for k in codegen.KINDS}
    ctx = {k: m.context(tr, 10.0) for k, m in models.items()}
    P = np.repeat(models["generated"].start()[None], 2, axis=0)
    P[1, 2 : len(free)] = rng.normal(0.0, 0.005, len(further))
    nu = np.zeros((2, max(models["generated"].n_nuisance, 1)))
    a = models["generated"].simulate(ctx["generated"], P, nu)
    b = models["interpreted"].simulate(ctx["interpreted"], P, nu)
    assert ctx["generated"].W > 1 and np.array_equal(a, b, equal_nan=True)
