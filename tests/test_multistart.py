"""Multistart identification (issue 32): on a problem with two known minima both are found and
told apart; the same result serially and on workers; the starts lie inside the bounds; a fit
with --starts resumes its journal and writes the multistart report."""

from __future__ import annotations

import json
import sys

import cloudpickle
import numpy as np
import pytest
from scipy.optimize import least_squares

from bayesid.estimation.multistart import DISTINCT_TOLERANCE, run_starts, start_points
from bayesid.tasks import Runner

cloudpickle.register_pickle_by_value(sys.modules[__name__])


def double_well(p0, shift: float):
    """Least squares with two minima: r = (x0^2 - 1, 10 (x1 - shift), 1) -> x0 = +-1, x1 = shift,
    both at cost 1 (the constant residual plays the noise)."""
    res = least_squares(lambda x: np.array([x[0] ** 2 - 1.0, 10 * (x[1] - shift), 1.0]), p0, bounds=([-2, -2], [2, 2]))
    return {
        "p": res.x.tolist(),
        "cost": float(2 * res.cost),
        "success": bool(res.success),
        "nfev": int(res.nfev),
        "message": str(res.message),
    }


def test_two_known_minima_are_both_found_and_told_apart():
    rng = np.random.default_rng(3)
    starts = np.vstack([[0.5, 0.0], start_points([0.0, 0.0], [2.0, 2.0], [-2, -2], [2, 2], 12, rng)])
    kinds = ["default"] + ["lhs"] * 12
    ms = run_starts(double_well, (0.3,), ["x0", "x1"], starts, kinds, [1.0, 1.0])
    assert len(ms.near_best) == 13  # every start reaches cost ~0
    assert len(ms.distinct) == 2
    minima = sorted(round(ms.fits[g[0]]["p"][0], 6) for g in ms.distinct)
    assert minima == [-1.0, 1.0]
    assert ms.max_distance == pytest.approx(2.0, abs=1e-6) and ms.spread["x0"] == pytest.approx(2.0, abs=1e-6)
    d = ms.to_dict()
    assert d["n_distinct_near_best"] == 2 and d["sorted_costs"] == sorted(d["sorted_costs"])
    parallel = run_starts(double_well, (0.3,), ["x0", "x1"], starts, kinds, [1.0, 1.0], runner=Runner(jobs=2))
    assert json.dumps(parallel.to_dict()) == json.dumps(d)


def test_one_minimum_is_one_optimum_and_a_worse_start_is_not_near_best():
    starts = np.array([[1.2, 0.0], [0.9, 1.0], [1.5, -1.0]])
    ms = run_starts(double_well, (0.3,), ["x0", "x1"], starts, ["default", "lhs", "lhs"], [1.0, 1.0])
    assert len(ms.distinct) == 1 and DISTINCT_TOLERANCE < 1
    ms.fits[2]["cost"] = 5.0  # an optimum far above the best is counted out
    from bayesid.estimation.multistart import summarise_starts

    s2 = summarise_starts(ms.names, ms.starts, ms.kinds, ms.fits, [1.0, 1.0])
    assert 2 not in s2.near_best and s2.order[-1] == 2


def test_starts_stay_inside_the_bounds_and_the_box():
    rng = np.random.default_rng(0)
    P = start_points([0.0, 1.0, 5.0], [1.0, 0.1, 10.0], [-0.5, -np.inf, 0.0], [np.inf, np.inf, 8.0], 50, rng)
    assert P.shape == (50, 3)
    assert (P[:, 0] >= -0.5).all() and (P[:, 0] <= 1.0).all()
    assert (P[:, 1] >= 0.9).all() and (P[:, 1] <= 1.1).all()
    assert (P[:, 2] >= 0.0).all() and (P[:, 2] <= 8.0).all()
    # a Latin hypercube: every one of 50 strata of each coordinate holds one start
    u = (P[:, 1] - 0.9) / 0.2
    assert sorted(np.floor(u * 50).astype(int)) == list(range(50))
    with pytest.raises(ValueError):
        start_points([0.0], [1.0], [-1], [1], -1, rng)


def test_fit_starts_writes_the_multistart_report_and_resumes_a_killed_run(tmp_path, capsys):
    from bayesid.cli import main

    for args in (
        ["--manoeuvre", "zigzag", "--angle", "20", "--out", str(tmp_path / "z.csv")],
        ["--manoeuvre", "turn", "--angle", "15", "--out", str(tmp_path / "t.csv")],
    ):
        assert main(["simulate", "--mode", "horizontal", "--duration", "90", "--sample", "0.5", *args]) == 0
    fit = [
        "fit",
        "--vehicle",
        "nps_auv2",
        "--train",
        str(tmp_path / "z.csv"),
        str(tmp_path / "t.csv"),
        "--starts",
        "3",
        "--max-nfev",
        "8",
        "--free",
        "Yv,Nr,Ndr",
    ]
    assert main([*fit, "--out", str(tmp_path / "a")]) == 0
    doc = json.loads((tmp_path / "a" / "model.json").read_text())
    ms = doc["multistart"]
    assert ms["n_starts"] == 4 and len(ms["sorted_costs"]) == 4 and 1 <= ms["n_near_best"] <= 4
    assert ms["distinct_optima"][0]["turning_circle"]["tactical_diameter_m"] > 0
    assert (tmp_path / "a" / "figures" / "multistart.png").is_file()
    assert "## Multistart" in (tmp_path / "a" / "report.md").read_text()
    # killed after the starts were journaled: the same command resumes them and ends the same
    for name in ("model.json", "report.md"):
        (tmp_path / "a" / name).unlink()
    capsys.readouterr()
    assert main([*fit, "--out", str(tmp_path / "a")]) == 0
    assert "resuming the finished tasks" in capsys.readouterr().out
    again = json.loads((tmp_path / "a" / "model.json").read_text())
    assert again["p"] == doc["p"] and again["multistart"]["sorted_costs"] == ms["sorted_costs"]
    # another seed draws other starts: the journal is refused, naming what differs
    (tmp_path / "a" / "model.json").unlink()
    (tmp_path / "a" / "report.md").unlink()
    assert main([*fit, "--seed", "5", "--out", str(tmp_path / "a")]) == 2
    assert "fit.random_seed: journal 0, this run 5" in capsys.readouterr().err
