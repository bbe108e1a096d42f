"""The compiled simulator (bayesid.models.dynamics / bayesid.models.simulate) against the independent reference
implementation (bayesid.models.reference): features, generalized forces, state derivatives, trajectories.

The reference writes the rigid-body Coriolis force in Fossen's matrix form, hydrostatics as rotated
weight/buoyancy vectors and kinematics as R(Theta), T(Theta) products, so agreement to round-off
checks the kernel's hand-expanded terms. An "asymmetric" vehicle (x_G, y_G, r_B non-zero, W != B,
full inertia tensor) exercises the terms that vanish for the packaged NPS AUV II.
"""

import dataclasses
import math

import numpy as np
import pytest

from bayesid.data import terms
from bayesid.data.vehicle import load_vehicle
from bayesid.models import dynamics
from bayesid.models import manoeuvres as mv
from bayesid.models.reference import ReferenceModel, reference_features, simulate_reference
from bayesid.models.simulate import Manoeuvre, Simulator, simulate

# Reference tolerances for the trajectory tests: tight enough that the reference's own error
# (rtol 1e-12 vs 1e-13: <= 3e-8 m on these runs) is far below the RK4 error being bounded.
REF_TOL = dict(rtol=1e-12, atol=1e-12)

# Max position difference (m), compiled RK4 at dt = 0.05 s vs the reference, 60 s runs.
# Measured (polynomial / integral cross-flow, 6-DOF / horizontal): turning circle 0.7e-9 .. 7.7e-9,
# zigzag 2.1e-8 .. 6.1e-6, 30 s all-input 6-DOF run 2.8e-6. Tolerances are ~10x the largest.
# The turning circle is smooth between input steps on the grid, so RK4's global error ~ dt^4
# (measured 7e-10 -> 5e-11 from dt 0.05 to 0.025). The zigzag error is larger and converges
# irregularly: v|v|, v|r|, r|r| (and the strip sum) have a kink where v or r changes sign, which
# drops RK4 to low order on the step that crosses it; the zigzag crosses r = 0 at every swing.
TURN_POSITION_TOL_M = 1e-7
ZIGZAG_POSITION_TOL_M = 6e-5
MIXED_POSITION_TOL_M = 3e-5

# Round-off level agreement of forces and derivatives (same equations, different arithmetic).
RHS_RTOL = 1e-10
FEATURE_RTOL = 1e-12


@pytest.fixture(scope="module")
def nps():
    return load_vehicle("nps_auv2")


def asymmetric(vehicle):
    """NPS AUV II with every rigid-body/hydrostatic term switched on."""
    return dataclasses.replace(
        vehicle,
        rG=np.array([0.12, -0.07, 0.061]),
        rB=np.array([-0.03, 0.02, -0.01]),
        weight=53300.0,
        inertia=np.array([[2038.0, 40.0, -25.0], [40.0, 13587.0, 60.0], [-25.0, 60.0, 13000.0]]),
    )


VEHICLES = {
    "nps-polynomial": lambda v: v,
    "nps-integral": lambda v: v.with_crossflow("integral"),
    "asym-polynomial": asymmetric,
    "asym-integral": lambda v: asymmetric(v).with_crossflow("integral"),
}


def random_inputs(rng, n):
    return np.column_stack([rng.uniform(-0.35, 0.35, (n, 3)), rng.uniform(-1500, 1500, n)])


def random_states(rng, n, mode):
    s = rng.normal(scale=0.4, size=(n, 12))
    s[:, 0:3] = rng.normal(scale=50.0, size=(n, 3))
    s[:, 3:6] = rng.uniform(-1.2, 1.2, (n, 3))
    s[:, 6] = rng.uniform(-3.0, 3.0, n)
    if mode == "horizontal":
        s[:, [3, 4, 8, 9, 10]] = 0.0
    return s


def kernel_force_and_rhs(sim, theta, s, uin):
    """dynamics.generalized_force's tau (6,) and dynamics.rhs's ds (12,), arrays built as in
    Simulator.run."""
    C = sim.coefficient_matrix(theta)
    tcoef = np.ascontiguousarray(C[:, sim.force_idx] * sim.tscale)[0]
    Minv = sim.inverse_mass_matrices(C)[0]
    f, tau, ds = np.empty(terms.N_FEATURES), np.empty(6), np.empty(12)
    s, uin = np.ascontiguousarray(s, dtype=float), np.ascontiguousarray(uin, dtype=float)
    dynamics.rhs(s, uin, np.zeros(6), sim.vp, sim.tfac, sim.tdof, tcoef, Minv, sim.xs, sim.ws, f, tau, ds)
    return tau, ds


def max_position_difference(a, b):
    """Max over samples of the 3-D position distance (m) between two SimResults, track 0."""
    return float(np.max(np.linalg.norm(a.states[0, :, :3] - b.states[0, :, :3], axis=1)))


# ---------------------------------------------------------------------------------------------
# Features
# ---------------------------------------------------------------------------------------------


def test_features_agree(nps):
    rng = np.random.default_rng(11)
    n = 400
    S = random_states(rng, n, "6dof")
    U = random_inputs(rng, n)
    # edge cases: u around the 1e-3 floor (both signs, exactly 0), n = 0 and n < 0 with u < 0
    S[:8, 6] = [0.0, 1e-4, -1e-4, 1e-3, -1e-3, 1.0001e-3, -5e-4, -2.0]
    U[:8, 3] = [1500.0, -1500.0, 0.0, 700.0, -700.0, 0.0, 1500.0, -300.0]
    assert (S[:, 6] < 0).any() and (U[:, 3] < 0).any()
    fk = dynamics.features_array(S, U, nps)
    fr = reference_features(S, U, nps)
    assert fr.shape == (n, terms.N_FEATURES)
    scale = np.maximum(np.abs(fr), 1e-300)
    np.testing.assert_array_less(np.abs(fk - fr) / scale, FEATURE_RTOL)
    assert np.all(np.isfinite(fr))


def test_features_eps_is_zero_at_eta_one(nps):
    s = np.zeros((1, 12))
    s[0, 6] = nps.steady_speed(1500.0)
    f = reference_features(s, np.array([[0, 0, 0, 1500.0]]), nps)
    assert abs(f[0, terms.F_INDEX["eps"]]) < 1e-12
    assert abs(f[0, terms.F_INDEX["prop"]]) < 1e-12


# ---------------------------------------------------------------------------------------------
# Generalized force and state derivative at random states
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("mode", ["6dof", "horizontal"])
@pytest.mark.parametrize("which", list(VEHICLES))
def test_rhs_agrees(nps, which, mode):
    veh = VEHICLES[which](nps)
    rng = np.random.default_rng([list(VEHICLES).index(which), len(mode)])
    m = mv.straight(veh, dt=0.05, duration=1.0)
    # free coefficients (added mass among them) set away from the vehicle's values, so the
    # Simulator's coefficient and mass-matrix assembly is checked too
    free = ["Yvdot", "Nrdot", "Yr", "Nv", "Xvv"]
    theta = np.array([veh.coefficients[n] for n in free]) * rng.uniform(0.7, 1.3, len(free))
    sim = Simulator(veh, m, free=free, mode=mode)
    ref = ReferenceModel(veh, dict(zip(free, theta)), mode)
    dofs = [0, 1, 5] if mode == "horizontal" else list(range(6))
    n = 60
    S, U = random_states(rng, n, mode), random_inputs(rng, n)
    tau_r = ref.generalized_force(S, U)
    ds_r = ref.rhs(S, U)
    for i in range(n):
        tau_k, ds_k = kernel_force_and_rhs(sim, theta[None], S[i], U[i])
        t_scale = np.max(np.abs(tau_r[i, dofs]))
        assert np.max(np.abs(tau_k[dofs] - tau_r[i, dofs])) <= RHS_RTOL * t_scale, (i, tau_k, tau_r[i])
        for block in (slice(0, 3), slice(3, 6), slice(6, 12)):
            scale = np.max(np.abs(ds_r[i, block]))
            assert np.max(np.abs(ds_k[block] - ds_r[i, block])) <= RHS_RTOL * scale, (i, block, ds_k, ds_r[i])
    if mode == "horizontal":
        assert np.all(ds_r[:, [2, 3, 4, 8, 9, 10]] == 0.0)


def test_rhs_check_can_fail(nps):
    """The comparison above resolves a 1e-6 change of one rigid-body quantity (z_G)."""
    veh = asymmetric(nps)
    moved = dataclasses.replace(veh, rG=veh.rG + np.array([0.0, 0.0, 1e-6]))
    rng = np.random.default_rng(5)
    S, U = random_states(rng, 5, "6dof"), random_inputs(rng, 5)
    sim = Simulator(veh, mv.straight(veh, dt=0.05, duration=1.0))
    ds_r = ReferenceModel(moved).rhs(S, U)
    worst = max(
        np.max(np.abs(kernel_force_and_rhs(sim, None, S[i], U[i])[1][6:] - ds_r[i, 6:])) / np.max(np.abs(ds_r[i, 6:]))
        for i in range(5)
    )
    assert worst > 100 * RHS_RTOL


# ---------------------------------------------------------------------------------------------
# Trajectories
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def trajectory_cases(nps):
    """(variant, manoeuvre name) -> (vehicle, manoeuvre at dt = 0.05 s, 60 s)."""
    out = {}
    for variant in ("polynomial", "integral"):
        veh = nps if variant == "polynomial" else nps.with_crossflow("integral")
        out[variant, "turn"] = veh, mv.turning_circle(veh, 20.0, dt=0.05, duration=60.0)
        out[variant, "zigzag"] = veh, mv.zigzag(veh, 20.0, 20.0, dt=0.05, duration=60.0)
    return out


@pytest.mark.parametrize("mode", ["6dof", "horizontal"])
@pytest.mark.parametrize("variant", ["polynomial", "integral"])
@pytest.mark.parametrize("name", ["turn", "zigzag"])
def test_trajectory_agrees(trajectory_cases, name, variant, mode):
    veh, m = trajectory_cases[variant, name]
    rc = simulate(veh, m, mode=mode)
    rr = simulate_reference(veh, m, mode=mode, **REF_TOL)
    assert rc.status[0] == 0 and rr.status[0] == 0 and rr.fail_step[0] == -1
    assert rr.states.shape == rc.states.shape and np.array_equal(rr.t, rc.t)
    assert np.array_equal(rr.inputs, rc.inputs)
    tol = TURN_POSITION_TOL_M if name == "turn" else ZIGZAG_POSITION_TOL_M
    assert max_position_difference(rc, rr) < tol
    # the run is a real manoeuvre, not a trivially straight line
    assert np.ptp(rr.states[0, :, 5]) > math.radians(20.0)


def test_trajectory_all_inputs_6dof(nps):
    """30 s, 6-DOF, asymmetric vehicle, steps on all four inputs (stern and bow planes, rudder,
    shaft speed): the vertical plane and large roll/pitch angles through the integrators."""
    veh = asymmetric(nps)
    dt, n = 0.05, 600
    t = np.arange(n) * dt
    inputs = np.zeros((n, 4))
    inputs[:, 3] = 1500.0
    inputs[t >= 2.0, 1] = math.radians(-5.0)
    inputs[t >= 5.0, 2] = math.radians(8.0)
    inputs[t >= 10.0, 0] = math.radians(10.0)
    inputs[t >= 15.0, 1] = math.radians(6.0)
    inputs[t >= 20.0, 3] = 1200.0
    s0 = mv.steady_state(veh)
    m = Manoeuvre("mixed", dt, inputs, s0)
    rc = simulate(veh, m)
    rr = simulate_reference(veh, m, **REF_TOL)
    assert rc.status[0] == 0 and rr.status[0] == 0
    assert np.ptp(rr.states[0, :, 2]) > 5.0 and np.ptp(rr.states[0, :, 4]) > math.radians(20.0)
    assert max_position_difference(rc, rr) < MIXED_POSITION_TOL_M


@pytest.mark.parametrize("name, relative_change", [("turn", 0.01), ("zigzag", 0.01), ("turn", 1e-5)])
def test_trajectory_check_can_fail(trajectory_cases, name, relative_change):
    """One coefficient changed in the reference only: the difference exceeds the tolerance (the
    1e-5 case shows the margin: the test resolves a 0.001 % change of N'r)."""
    veh, m = trajectory_cases["polynomial", name]
    rc = simulate(veh, m, mode="6dof")
    rr = simulate_reference(
        veh, m, mode="6dof", coefficients={"Nr": veh.coefficients["Nr"] * (1 + relative_change)}, **REF_TOL
    )
    tol = TURN_POSITION_TOL_M if name == "turn" else ZIGZAG_POSITION_TOL_M
    assert max_position_difference(rc, rr) > tol


# ---------------------------------------------------------------------------------------------
# simulate_reference behaviour
# ---------------------------------------------------------------------------------------------


def test_divergence_flagged_like_kernel(nps):
    """An unstable sway coefficient: both leave the physical bounds in the same step."""
    m = mv.turning_circle(nps, 20.0, dt=0.05, duration=20.0)
    rc = Simulator(nps, m, free=["Yv"]).run(np.array([[0.5]]))
    rr = simulate_reference(nps, m, coefficients={"Yv": 0.5})
    assert rc.status[0] == dynamics.OUT_OF_BOUNDS and rr.status[0] == dynamics.OUT_OF_BOUNDS
    assert rr.fail_step[0] == rc.fail_step[0]
    np.testing.assert_array_equal(np.isnan(rr.states), np.isnan(rc.states))


def test_sample_every(nps):
    m = mv.turning_circle(nps, 20.0, dt=0.05, duration=20.0)
    full = simulate_reference(nps, m, mode="horizontal")
    sub = simulate_reference(nps, m, mode="horizontal", sample_every=4)
    assert sub.states.shape == (1, m.n_steps // 4 + 1, 12)
    np.testing.assert_allclose(sub.t, full.t[::4])
    np.testing.assert_allclose(sub.states[0], full.states[0, ::4], rtol=0, atol=1e-9)
    assert np.array_equal(sub.inputs, simulate(nps, m, mode="horizontal", sample_every=4).inputs)
    with pytest.raises(ValueError, match="sample_every"):
        simulate_reference(nps, m, sample_every=7)


def test_errors(nps):
    m = mv.straight(nps, dt=0.1, duration=1.0)
    with pytest.raises(terms.UnknownCoefficientError, match="Yvvvv"):  # quartic: no prime product
        simulate_reference(nps, m, coefficients={"Yvvvv": 1.0})
    with pytest.raises(ValueError, match="mode"):
        simulate_reference(nps, m, mode="vertical")
    s0 = m.initial_state.copy()
    s0[9] = 0.1
    with pytest.raises(ValueError, match="p = 0"):
        simulate_reference(nps, Manoeuvre("rolling", 0.1, m.inputs, s0), mode="horizontal")
