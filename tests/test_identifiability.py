"""Identifiability dossier: Fisher information, sloppy directions, collinearity, structural nulls."""

import numpy as np
import pytest

from bayesid import cases
from bayesid.analysis import identifiability as ida
from bayesid.estimation.objective import Problem
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator

SIG = dict(x=0.2, y=0.2, z=0.2, phi=np.radians(0.2), theta=np.radians(0.2), psi=np.radians(0.2))


def test_exactly_collinear_pair_is_the_sloppiest_direction_and_flagged():
    rng = np.random.default_rng(3)
    n = 400
    S = rng.normal(size=(n, 4))
    S[:, 2] = S[:, 1]  # terms b and c have identical sensitivities
    names = ["a", "b", "c", "d"]
    F = ida.fisher_information(S, np.full(n, 0.5))
    sloppiest = ida.eigen_directions(F, names)[0]
    assert abs(sloppiest.eigenvalue) < 1e-10 * np.abs(F).max()
    np.testing.assert_allclose(np.abs(sloppiest.vector), [0, 1 / np.sqrt(2), 1 / np.sqrt(2), 0], atol=1e-8)
    assert sloppiest.vector[1] * sloppiest.vector[2] < 0  # their difference
    table = ida.collinearity_table(S, names, sizes=(2,), top=3)
    assert table[0]["subset"] == ["b", "c"] and table[0]["gamma"] > 1e6
    assert table[1]["gamma"] < 2.0  # the other pairs are near-orthogonal
    assert ida.condition_number(F) > 1e12


def test_label_names_the_combination():
    d = ida.Direction(1e-3, np.array([0.71, -0.70, 0.05]), ["Xvr", "Xrr", "Yv"])
    assert d.label() == "0.71*Xvr - 0.70*Xrr"
    assert d.sd_relative == pytest.approx(1 / np.sqrt(1e-3))


@pytest.fixture(scope="module")
def case1_zigzag(nps):
    case = cases.make_case(1, nps, np.random.default_rng(0))
    base = np.array([nps.coefficients[n] for n in case.free])
    sim = Simulator(nps, mv.zigzag(nps, 20.0, duration=60.0), free=case.free, mode="horizontal", sample_every=5)
    pb = Problem(sim, sim.run(base[None]).track(0), base)
    return case, base, sim, pb


def test_structural_nulls_leave_the_track_unchanged(nps, case1_zigzag):
    case, base, sim, _ = case1_zigzag
    N, causes = ida.structural_null_space(case.free, nps)
    assert N.shape[1] == 3 and all("scale" in c for c in causes)
    moved = [base * (1 + 0.02 * N[:, k]) for k in range(N.shape[1])]
    rnd = np.random.default_rng(1).normal(size=base.size)
    moved.append(base * (1 + 0.02 * rnd / np.linalg.norm(rnd)))  # a generic direction for contrast
    st = sim.run(np.vstack([base] + moved)).states
    change = [np.max(np.abs(st[0, :, :2] - st[k, :, :2])) for k in range(1, st.shape[0])]
    assert max(change[:-1]) < 1e-9  # round-off (m)
    assert change[-1] > 1e-3  # the same step in a generic direction moves the track


def test_fisher_null_space_is_the_structural_one(nps, case1_zigzag):
    case, base, _, pb = case1_zigzag
    S = ida.relative_sensitivity(pb, base)
    F = ida.fisher_information(S, pb.noise_vector(SIG))
    dirs = ida.eigen_directions(F, case.free)
    lam = np.array([d.eigenvalue for d in dirs])
    # structural: at the round-off floor (~1e-17 of the largest); the next, merely sloppy,
    # direction is orders of magnitude above it (measured 1e-13 on this short zigzag)
    assert np.all(np.abs(lam[:3]) < 1e-15 * lam[-1])
    assert lam[3] > 100 * np.max(np.abs(lam[:3]))
    N, _ = ida.structural_null_space(case.free, nps)
    E = np.array([d.vector for d in dirs[:3]]).T
    assert np.max(ida.principal_angles_deg(E, N)) < 0.5


def test_case2_has_no_structural_null(nps):
    case = cases.make_case(2, nps, np.random.default_rng(0))
    N, causes = ida.structural_null_space(case.free, nps)
    assert N.shape[1] == 0 and causes == []
    assert ida.row_transform_direction(case.free, nps, "Y", "Y") is None


def test_noise_vector_names_missing_channel(case1_zigzag):
    _, _, _, pb = case1_zigzag
    with pytest.raises(KeyError, match="psi"):
        pb.noise_vector(dict(x=1, y=1, z=1, phi=1, theta=1))


def test_round_off_null_space_is_reported_by_its_projector_not_by_its_arbitrary_eigenvectors():
    # a 3-dimensional exact null space of a 6-parameter Fisher information, seen through two
    # slightly different round-off perturbations: the eigenvectors inside the null space rotate
    # between the two, the projector's diagonal does not
    rng = np.random.default_rng(3)
    names = [f"c{k}" for k in range(6)]
    Q, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    null = Q[:, :3]
    F0 = Q[:, 3:] @ np.diag([1.0, 1e3, 1e6]) @ Q[:, 3:].T
    out = []
    for seed in (1, 2):
        E = np.random.default_rng(seed).normal(size=(6, 6)) * 1e-4
        dirs = ida.eigen_directions(F0 + E @ E.T, names)
        W = np.column_stack([d.vector for d in dirs[:3]])
        out.append((W, ida.subspace_participation(W, names, threshold=0.0)))
    (W1, p1), (W2, p2) = out
    assert abs(abs(W1[:, 0] @ W2[:, 0]) - 1.0) > 1e-3  # the first null eigenvector is not reproducible
    expected = np.sum(null**2, axis=1)
    np.testing.assert_allclose([p1[n] for n in names], expected, atol=1e-6)
    np.testing.assert_allclose([p2[n] for n in names], expected, atol=1e-6)
    assert abs(sum(p1.values()) - 3.0) < 1e-10
    assert list(p1) == sorted(p1, key=p1.get, reverse=True)  # largest first
