"""Richness metrics, joint problems and manoeuvre design (issue 4)."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bayesid import cases
from bayesid.analysis import richness
from bayesid.estimation.objective import JointProblem, Problem
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator

ROOT = Path(__file__).resolve().parents[1]
NOISE = {"x": 0.2, "y": 0.2, "psi": math.radians(0.2)}


def _problem(vehicle, m, free):
    theta = np.array([vehicle.coefficients[n] for n in free])
    sim = Simulator(vehicle, m, free=free, mode="horizontal", sample_every=int(round(1.0 / m.dt)))
    return Problem(sim, sim.run(theta[None]).track(0), theta, channels=("x", "y", "psi")), theta


def test_straight_line_gives_rotary_terms_no_information(nps):
    free = ["Yr", "Nr", "Yv", "Xudot"]
    pb_s, theta = _problem(nps, mv.straight(nps, dt=0.5, duration=120.0), free)
    pb_t, _ = _problem(nps, mv.turning_circle(nps, 20.0, dt=0.5, duration=120.0), free)
    Fs = richness.fisher_metrics(pb_s, theta, NOISE)["F"]
    Ft = richness.fisher_metrics(pb_t, theta, NOISE)["F"]
    for n in ("Yr", "Nr", "Yv"):
        j = free.index(n)
        assert Fs[j, j] < 1e-12 * Ft[j, j], n  # r = v = 0 on a straight line
    assert richness.fisher_metrics(pb_s, theta, NOISE)["logdet_fim"] == -math.inf


def test_joint_problem_adds_information(nps):
    free = ["Yr", "Nr", "Yv", "Nv"]
    a, theta = _problem(nps, mv.turning_circle(nps, 20.0, dt=0.5, duration=100.0), free)
    b, _ = _problem(nps, mv.zigzag(nps, 20.0, dt=0.5, duration=100.0), free)
    j = JointProblem([a, b])
    Fa, Fb, Fj = (richness.fisher_metrics(p, theta, NOISE)["F"] for p in (a, b, j))
    np.testing.assert_allclose(Fj, Fa + Fb, rtol=1e-6, atol=1e-9 * np.abs(Fj).max())
    assert j.cost(np.ones(4)) == pytest.approx(0.0, abs=1e-18)
    with pytest.raises(ValueError, match="names"):
        JointProblem([a, _problem(nps, mv.zigzag(nps, 20.0, dt=0.5, duration=100.0), ["Yr", "Nr"])[0]])


def test_direction_sd_of_a_diagonal_information():
    F = np.diag([4.0, 1.0])
    assert richness.direction_sd(F, np.array([1.0, 0.0])) == pytest.approx(0.5)
    w = np.array([1.0, 1.0]) / np.sqrt(2)
    assert richness.direction_sd(F, w, np.array([0.0, 3.0])) == pytest.approx(np.sqrt(0.5 * (0.25 + 0.25)))


def test_designed_multisine_beats_the_spiral_d_criterion(nps):
    case = cases.make_case(2, nps, np.random.default_rng(0))
    theta = np.array([case.true[n] for n in case.free])

    def make(m):
        sim = Simulator(nps, m, free=case.free, mode="horizontal", sample_every=2)
        return Problem(sim, sim.run(theta[None]).track(0), theta, channels=("x", "y", "psi"))

    spiral = richness.fisher_metrics(make(mv.spiral(nps, dt=0.5)), theta, NOISE)["logdet_fim"]
    options = richness.RichnessOptions(criterion="D", duration=600.0, dt=0.5, maxiter=1, popsize=2)
    d = richness.design_multisine(nps, make, theta, NOISE, options, rng=np.random.default_rng(1))
    assert d.manoeuvre.duration == pytest.approx(600.0)
    assert np.max(np.abs(np.degrees(d.manoeuvre.inputs[:, 0]))) == pytest.approx(20.0)
    assert d.value >= d.start_value
    assert d.value > spiral
    with pytest.raises(ValueError, match="direction"):
        richness.design_multisine(nps, make, theta, NOISE, richness.RichnessOptions(criterion="direction"))


def test_manoeuvre_richness_quick(tmp_path):
    out = tmp_path / "mr"
    subprocess.run(
        [sys.executable, str(ROOT / "studies" / "manoeuvre_richness.py"), "--quick", "--out", str(out)],
        check=True,
        cwd=ROOT,
        timeout=900,
    )
    res = json.loads((out / "results.json").read_text())
    for name, m in res["manoeuvres"].items():
        for key in ("logdet_fim", "min_eigenvalue", "condition_number", "max_collinearity_index", "sindy_inclusion"):
            assert key in m, (name, key)
    assert all(0.0 <= p <= 1.0 for p in res["manoeuvres"]["spiral"]["sindy_inclusion"].values())
    cp = res["cross_prediction_rms_m"]
    assert "spiral" in cp and "spiral" in cp["spiral"]
    for crit in ("D", "direction"):
        assert {"predicted_sd_ratio", "measured_sd_ratio"} <= set(res["design"][crit])
    assert (out / "report.md").exists() and len(list((out / "figures").glob("*.png"))) >= 6
