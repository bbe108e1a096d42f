"""Issue 4: model-free term check with (ensemble) SINDy, horizontal plane."""

import math

import numpy as np
import pytest

from bayesid.analysis import sindy
from bayesid.data import terms
from bayesid.data.track import Track
from bayesid.estimation.posterior import add_noise
from bayesid.models import dynamics, manoeuvres
from bayesid.models.simulate import Simulator

N_MODELS = 30


def _track(vehicle, manoeuvre):
    return Simulator(vehicle, manoeuvre, mode="horizontal").run().track(0)


def _without(track, *cols):
    return Track(track.t, {c: v for c, v in track.data.items() if c not in cols}, name=track.name)


@pytest.fixture(scope="module")
def multisine_track(nps):
    return _track(nps, manoeuvres.multisine(nps))


@pytest.fixture(scope="module")
def multisine_result(nps, multisine_track):
    return sindy.inclusion_probabilities(
        multisine_track, nps, sindy.SindyOptions(n_models=N_MODELS), rng=np.random.default_rng(0)
    )


def _true_normalised(vehicle, track):
    """|C'_true| * rms(column) / rms(target) per candidate: the share of the force each model
    term carries on this record (independent of the regression)."""
    motion = sindy.estimate_motion(track)
    u = track.inputs()
    F = sindy.force_targets(motion, vehicle, u, known=sindy.ADDED_MASS)
    Theta, names = sindy.candidate_library(motion, u, vehicle, exclude=sindy.ADDED_MASS)
    out = {}
    for j, k in enumerate(names):
        e = sindy.EQUATIONS.index(sindy.equation_of(k))
        out[k] = (
            abs(vehicle.coefficients.get(k, 0.0)) * np.sqrt(np.mean(Theta[:, j] ** 2)) / np.sqrt(np.mean(F[:, e] ** 2))
        )
    return out


def test_inverse_dynamics_and_library_reproduce_the_simulator(nps):
    """Exact accelerations from the simulator's right-hand side: target - library @ true
    coefficients = 0 to rounding in all three equations (checks M_RB, C_RB, scales, Cd0)."""
    m = manoeuvres.prbs(nps, rng=np.random.default_rng(2), duration=60.0)
    sim = Simulator(nps, m, mode="horizontal")
    res = sim.run()
    tcoef, Minv = sim.kernel_arrays()
    S, U = res.states[0], res.inputs
    acc = np.zeros((S.shape[0], 12))
    f, tau = np.empty(terms.N_FEATURES), np.empty(6)
    for i in range(S.shape[0]):
        dynamics.rhs(
            S[i].copy(),
            U[i].copy(),
            np.zeros(6),
            sim.vp,
            sim.tfac,
            sim.tdof,
            tcoef[0],
            Minv[0],
            sim.xs,
            sim.ws,
            f,
            tau,
            acc[i],
        )
    motion = dict(
        u=S[:, 6],
        v=S[:, 7],
        r=S[:, 11],
        u_dot=acc[:, 6],
        v_dot=acc[:, 7],
        r_dot=acc[:, 11],
        dr_dot=np.zeros(S.shape[0]),
        input_hold="sample",
    )
    F = sindy.force_targets(motion, nps, U)
    Theta, names = sindy.candidate_library(motion, U, nps)
    c = np.array([nps.coefficients.get(k, 0.0) for k in names])
    for e, g in enumerate(sindy.EQUATIONS):
        idx = [j for j, k in enumerate(names) if sindy.equation_of(k) == g]
        r = F[:, e] - Theta[:, idx] @ c[idx]
        assert np.sqrt(np.mean(r**2)) < 1e-9 * np.sqrt(np.mean(F[:, e] ** 2)), g


def test_smoothed_motion_keeps_the_true_model(nps, multisine_track):
    """Estimated motion (measured u, v, r, default window, ZOH inputs): the true model explains
    every force target to < 1 % RMS, because input columns are smoothed like the motion."""
    motion = sindy.estimate_motion(multisine_track)
    u = multisine_track.inputs()
    F = sindy.force_targets(motion, nps, u, known=sindy.ADDED_MASS)
    Theta, names = sindy.candidate_library(motion, u, nps, exclude=sindy.ADDED_MASS)
    c = np.array([nps.coefficients.get(k, 0.0) for k in names])
    sl = slice(10, -10)
    for e, g in enumerate(sindy.EQUATIONS):
        idx = [j for j, k in enumerate(names) if sindy.equation_of(k) == g]
        r = (F[:, e] - Theta[:, idx] @ c[idx])[sl]
        assert np.sqrt(np.mean(r**2)) < 0.01 * np.sqrt(np.mean(F[sl, e] ** 2)), g


def test_positions_route_recovers_body_velocities(nps):
    """x, y, psi (psi wrapped to (-pi, pi]) -> u, v, r close to the simulated ones."""
    tr = _track(nps, manoeuvres.turning_circle(nps, 20.0, duration=120.0))
    assert np.ptp(tr["psi"]) > 2 * math.pi  # more than a full turn: unwrapping matters
    wrapped = np.angle(np.exp(1j * tr["psi"]))
    pos = _without(tr, "u", "v", "r").with_columns(psi=wrapped)
    motion = sindy.estimate_motion(pos, window_s=1.0)
    assert motion["source"] == "positions" and motion["smoother"]["passes"] == 2
    sl = slice(20, -20)
    for c in ("u", "v", "r"):  # measured relative RMS errors: 2e-5, 4e-4, 1.5e-3
        err = motion[c][sl] - tr[c][sl]
        assert np.sqrt(np.mean(err**2)) < 5e-3 * np.sqrt(np.mean(tr[c][sl] ** 2)), c


def test_rich_input_noise_free_finds_active_and_rejects_extras(nps, multisine_track, multisine_result):
    """Issue 4 test 1: multisine rudder, noise-free, measured u, v, r: model terms that carry
    >= 2x threshold of their force get probability >= 0.8; model terms well below it and
    every extra (true value 0) get <= 0.2."""
    res = multisine_result
    xi = _true_normalised(nps, multisine_track)
    thr = res["threshold"]
    excited = [k for k, x in xi.items() if x >= 2 * thr]
    # the linear manoeuvring derivatives are all among them
    for k in ("Yv", "Yr", "Ydr", "Nv", "Nr", "Ndr", "Xvv", "Xvr", "Cd0"):
        assert k in excited
    for k in excited:
        assert res[sindy.equation_of(k)][k] >= 0.8, (k, xi[k])
    for k in sindy.EXTRAS:
        assert res[sindy.equation_of(k)][k] <= 0.2, k
    for k, x in xi.items():
        if k not in sindy.EXTRAS and nps.coefficients.get(k, 0.0) != 0.0 and x < 0.4 * thr:
            assert res[sindy.equation_of(k)][k] <= 0.2, (k, x)
    cmp = sindy.compare_with_model(res, nps)
    for g in sindy.EQUATIONS:
        assert cmp[g]["spurious"] == []
    assert {"Yv", "Yr", "Ydr"} <= set(cmp["Y"]["excited_and_in_model"])
    # median coefficients close to the truth for the dominant terms (prime)
    for k in ("Yv", "Yr", "Ydr", "Nv", "Nr", "Ndr"):
        assert res["coefficients"][sindy.equation_of(k)][k] == pytest.approx(nps.coefficients[k], rel=0.1)


def test_straight_line_does_not_excite_rotary_terms(nps):
    """Issue 4 test 2: straight run (v = r = 0): Yr, Nr (and all sway/yaw terms) get 0."""
    tr = _track(nps, manoeuvres.straight(nps, duration=40.0))
    res = sindy.inclusion_probabilities(tr, nps, sindy.SindyOptions(n_models=N_MODELS), rng=np.random.default_rng(1))
    for k in ("Yr", "Nr", "Yv", "Nv", "Xrr", "Xvr"):
        g = sindy.equation_of(k)
        assert res[g][k] <= 0.2
        assert k in res["not_excited"][g]
    assert all(p == 0.0 for g in sindy.EQUATIONS for p in res[g].values())


def test_noisy_positions_only_runs_and_returns_probabilities(nps, multisine_track):
    """Issue 4 test 3: 0.2 m / 0.2 deg noise on x, y, psi, no u, v, r columns."""
    noisy = add_noise(multisine_track, {"x": 0.2, "y": 0.2, "psi": math.radians(0.2)}, np.random.default_rng(5))
    noisy = _without(noisy, "u", "v", "r")
    res = sindy.inclusion_probabilities(noisy, nps, sindy.SindyOptions(n_models=20), rng=np.random.default_rng(2))
    assert res["source"] == "positions" and res["window_s"] == pytest.approx(8.1)
    for g in sindy.EQUATIONS:
        cand = [k for k in sindy.horizontal_terms(g) if k not in sindy.ADDED_MASS] + [
            k for k in sindy.EXTRAS if sindy.equation_of(k) == g
        ]
        assert list(res[g]) == cand
        for k, p in res[g].items():
            assert 0.0 <= p <= 1.0
            assert math.isfinite(res["coefficients"][g][k])
    # the yaw equation stays well determined from 0.2 deg heading noise
    assert res["r2"]["N"] > 0.9
    assert res["N"]["Nr"] >= 0.8 and res["N"]["Ndr"] >= 0.8


def test_randomness_only_from_rng(nps, multisine_track):
    state = np.random.get_state()[1].copy()
    a, b = (
        sindy.inclusion_probabilities(
            multisine_track, nps, sindy.SindyOptions(n_models=5), rng=np.random.default_rng(7)
        )
        for _ in range(2)
    )
    assert a["Y"] == b["Y"] and a["coefficients"] == b["coefficients"]
    assert np.array_equal(np.random.get_state()[1], state)  # global state untouched


def test_clear_errors(nps, multisine_track):
    """Issue 4 test 4 and friends: errors name what is missing."""
    rng = np.random.default_rng(0)
    no_psi = _without(multisine_track, "psi")
    with pytest.raises(ValueError, match="'psi'"):
        sindy.inclusion_probabilities(no_psi, nps, sindy.SindyOptions(n_models=2), rng=rng)
    with pytest.raises(ValueError, match="'psi'"):
        sindy.estimate_motion(no_psi)
    with pytest.raises(ValueError, match="'x'"):
        sindy.estimate_motion(_without(multisine_track, "u", "v", "r", "x"))
    with pytest.raises(ValueError, match="'delta_r'"):
        sindy.inclusion_probabilities(
            _without(multisine_track, "delta_r"), nps, sindy.SindyOptions(n_models=2), rng=rng
        )
    with pytest.raises(ValueError, match="Yvdot"):
        sindy.inclusion_probabilities(
            multisine_track, nps, sindy.SindyOptions(n_models=2, known=("Xudot", "Yrdot", "Nvdot", "Nrdot")), rng=rng
        )
    with pytest.raises(ValueError, match="Zw"):
        sindy.force_targets(sindy.estimate_motion(multisine_track), nps, multisine_track.inputs(), known=("Zw",))
    with pytest.raises(TypeError, match="Generator"):
        sindy.inclusion_probabilities(multisine_track, nps, sindy.SindyOptions(n_models=2), rng=None)
    with pytest.raises(ValueError, match="'u_dot'"):
        sindy.force_targets({"u": np.ones(3), "v": np.ones(3), "r": np.ones(3)}, nps)
    with pytest.raises(ValueError, match="Kp"):
        sindy.equation_of("Kp")
    with pytest.raises(ValueError, match="level"):
        sindy.compare_with_model({"X": {}, "Y": {}, "N": {}}, nps, level=0.0)


def test_compare_with_model_lists(nps):
    inc = {
        "X": {"Xvv": 0.9, "X0": 0.7, "Xrr": 0.1},
        "Y": {"Yv": 1.0, "Yr": 0.2, "Yvvv": 0.1},
        "N": {"Nr": 0.6, "Nprop": 0.8},
    }
    out = sindy.compare_with_model(inc, nps, level=0.5)
    assert out["X"] == {
        "in_model": ["Xvv", "Xrr"],
        "included": ["Xvv", "X0"],
        "excited_and_in_model": ["Xvv"],
        "in_model_not_seen": ["Xrr"],
        "spurious": ["X0"],
    }
    assert out["Y"]["in_model_not_seen"] == ["Yr"] and out["Y"]["spurious"] == []
    assert out["N"]["spurious"] == ["Nprop"]  # Nprop = 0 in NPS AUV II
