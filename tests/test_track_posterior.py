"""``bayesid sample`` (issue 31): the error model recovers known noise scales and serial
correlation; priors of the vehicle file are applied; the command writes netCDF, verdict and
dossier on two small runs, resumes a killed run bit for bit and refuses another run's journal."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest

from bayesid.cli import main
from bayesid.data.track import Track, write_csv
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation import track_posterior as tp
from bayesid.models import manoeuvres as mv
from bayesid.models.world import LogOptions, world_track

NOISE = {"x": 0.1, "y": 0.1, "psi": math.radians(0.2), "u": 0.01, "v": 0.01, "r": math.radians(0.1)}


def _ar1(rng, n_windows, per_window, rho, sigma):
    """AR(1) errors restarting in every window (stationary start), and their window ids."""
    e = np.empty(n_windows * per_window)
    for w in range(n_windows):
        x = rng.normal(0.0, sigma)
        for i in range(per_window):
            e[w * per_window + i] = x
            x = rho * x + rng.normal(0.0, sigma * math.sqrt(1 - rho**2))
    return e, np.repeat(np.arange(n_windows), per_window)


@pytest.mark.parametrize("rho, sigma", [(0.0, 0.3), (0.8, 0.05), (0.97, 2.0)])
def test_the_error_model_recovers_known_ar1_noise(rho, sigma):
    rng = np.random.default_rng(1)
    e, win = _ar1(rng, 200, 100, rho, sigma)
    e[::37] = np.nan  # gaps: pairs across them are skipped
    a = tp.ar1_noise(e, win)
    assert abs(a["rho"] - rho) < max(4 * a["rho_se"], 0.01), a
    assert a["sigma"] == pytest.approx(sigma, rel=0.08)
    # the noise scale integrated out and drawn back: its 90 % interval holds the truth
    k = min((1 + a["rho"]) / (1 - a["rho"]), 100.0)
    n = np.isfinite(e).sum()
    em = tp.ErrorModel(
        ("x",),
        np.zeros(e.size, int),
        np.array([n], float),
        np.array([a["rho"]]),
        np.array([a["rho_se"]]),
        np.array([k]),
        np.array([1.0]),
        np.array([a["sigma"]]),
    )
    s = em.sigma_draws(np.full((4000, 1), np.nansum(e**2)), np.random.default_rng(2))[:, 0]
    lo, hi = np.quantile(s, [0.05, 0.95])
    assert lo < sigma < hi, (lo, hi)
    # the width follows the effective sample count: correlated errors give a wider interval
    assert (hi - lo) / sigma == pytest.approx(2 * 1.645 / math.sqrt(2 * n / k), rel=0.25)


def test_integrated_time_of_ar1_and_of_a_persistent_error_under_noise():
    rng = np.random.default_rng(4)
    for rho in (0.0, 0.8, 0.95):
        e, win = _ar1(rng, 300, 100, rho, 1.0)
        assert tp.integrated_time(e, win, 100) == pytest.approx((1 + rho) / (1 - rho), rel=0.25)
    # white noise plus an error constant over each window (half the variance): lag 1 sees 0.5,
    # yet every lag does, so the time is tens of samples where AR(1) would say 3
    e = rng.normal(size=200 * 60) + np.repeat(rng.normal(size=200), 60)
    win = np.repeat(np.arange(200), 60)
    assert tp.ar1_noise(e, win)["rho"] < 0.6
    assert tp.integrated_time(e, win, 60) > 20


def test_ar1_noise_refuses_mismatched_shapes():
    with pytest.raises(ValueError, match="shape"):
        tp.ar1_noise(np.zeros(5), np.zeros(4))


def test_the_log_likelihood_counts_effective_samples_only():
    em = tp.ErrorModel(
        ("x", "psi"),
        np.array([0, 0, 1, 1]),
        np.array([1000.0, 1000.0]),
        np.zeros(2),
        np.zeros(2),
        np.array([10.0, 100.0]),
        np.ones(2),
        np.ones(2),
    )
    ll = em.log_likelihood(np.array([[1.0, 1.0], [2.0, 1.0], [1.0, 2.0]]))
    # doubling the SSR of x costs (n_eff / 2) log 2 with n_eff = 1000 / 10
    assert ll[0] - ll[1] == pytest.approx(50 * math.log(2))
    assert ll[0] - ll[2] == pytest.approx(5 * math.log(2))
    assert em.log_likelihood(np.array([[np.nan, 1.0]]))[0] == -np.inf


def test_priors_of_the_vehicle_file_are_applied_and_bounds_hold():
    from bayesid.models import build_model
    from bayesid.models.ship import load_ship

    m = build_model(load_ship("kvlcc2_7m"), None, (), None)
    pr = tp.ParameterPrior.of_model(m)
    j = m.param_names.index("Yv")
    assert pr.gaussian[j] and pr.mean[j] == pytest.approx(-0.315) and pr.sd[j] == pytest.approx(0.0315)
    assert not pr.gaussian[m.param_names.index("Ycf")]  # uniform inside its bounds
    p = m.start()[None].repeat(3, axis=0)
    p[1, j] = -0.315 + 2 * 0.0315
    p[2, m.param_names.index("Ycf")] = -1.0  # below its lower bound 0
    lp = pr.logpdf(p)
    z0 = (m.start()[j] + 0.315) / 0.0315
    assert lp[1] - lp[0] == pytest.approx(-0.5 * 2.0**2 + 0.5 * z0**2)
    assert lp[2] == -np.inf
    flat = tp.ParameterPrior.of_model(m, use_file=False)
    assert not flat.gaussian.any() and np.all(flat.logpdf(p[:2]) == 0.0)


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    """Two short zigzags of NPS AUV II with noise, and a bayesid fit of them."""
    d = tmp_path_factory.mktemp("sample")
    veh = load_vehicle("nps_auv2")
    rng = np.random.default_rng(5)
    files = []
    for i, (a, sign) in enumerate(((15.0, 1), (20.0, -1))):
        m = mv.zigzag(veh, a, dt=0.1, duration=100.0, first_sign=sign)
        tr = world_track(veh, m, {}, rng, LogOptions(noise=NOISE, sample_every=2, hold_inputs=True))
        t = Track(tr.t, dict(tr.data), name=f"run{i}", meta=tr.meta)
        write_csv(t, d / f"run{i}.csv")
        files.append(str(d / f"run{i}.csv"))
    assert main(["fit", "--vehicle", "nps_auv2", "--train", *files, "--max-nfev", "15", "--out", str(d / "fit")]) == 0
    return d, files


def _sample(d, files, out, *extra):
    return main(
        [
            "sample",
            "--model",
            str(d / "fit" / "model.json"),
            "--train",
            *files,
            "--draws",
            "300",
            "--method",
            "importance",
        ]
        + ["--out", str(out)]
        + list(extra)
    )


def test_sample_writes_netcdf_verdict_and_dossier_and_resumes_bit_for_bit(two_runs, capsys):
    import arviz as az

    d, files = two_runs
    out = d / "s"
    assert _sample(d, files, out) == 0
    doc = json.loads((out / "sample.json").read_text())
    assert doc["method"] == "importance" and set(doc["verdict"]) >= {"converged", "text", "k_hat", "ess"}
    assert doc["verdict"]["k_hat"] < 0.7, doc["verdict"]
    dos = doc["dossier"]
    names = list(doc["fit_estimate"])
    assert set(dos["coefficients"]) == set(names) and len(dos["fisher_eigenvalues"]) == len(names)
    assert dos["collinearity"] and dos["sloppy"] and all(c["status"] for c in dos["coefficients"].values())
    assert set(doc["error_model"]) <= {"x", "y", "psi", "u", "v", "r"} and doc["error_model"]["x"]["n_eff"] > 0
    idata = az.from_netcdf(out / "posterior.nc")
    assert set(names) <= set(idata.posterior.data_vars) and idata.posterior.sizes["draw"] == 300
    assert "sigma_x" in idata.noise_scale and "log_weight" in idata.importance
    for f in ("marginals", "pairs", "weights", "fisher"):
        assert (out / "figures" / f"{f}.png").is_file()
    assert "## What these tracks determine" in (out / "report.md").read_text()
    # what sample writes, predict reads
    assert (
        main(["predict", "--model", str(out / "posterior_model.json"), "--track", files[0], "--out", str(d / "pred")])
        == 0
    )
    # killed after the first chunk of draws: only the journal's header and first task survive
    killed = d / "s_killed"
    killed.mkdir()
    lines = (out / "journal.jsonl").read_text().splitlines()
    assert len(lines) > 3
    (killed / "journal.jsonl").write_text("\n".join(lines[:2]) + "\n" + lines[2][: len(lines[2]) // 2])
    capsys.readouterr()
    assert _sample(d, files, killed) == 0
    assert "resuming" in capsys.readouterr().out
    again = az.from_netcdf(killed / "posterior.nc")
    for n in names:
        np.testing.assert_array_equal(again.posterior[n].values, idata.posterior[n].values)
    np.testing.assert_array_equal(again.importance["log_weight"].values, idata.importance["log_weight"].values)
    doc2 = json.loads((killed / "sample.json").read_text())
    assert doc2["marginals"] == doc["marginals"] and doc2["verdict"] == doc["verdict"]


def test_sample_refuses_the_journal_of_another_seed_or_other_data(two_runs, capsys):
    d, files = two_runs
    out = d / "s_refuse"
    assert _sample(d, files, out) == 0
    (out / "sample.json").unlink()  # as if killed before the end
    for p in ("posterior.nc", "posterior_model.json", "report.md"):
        (out / p).unlink()
    shutil.rmtree(out / "figures")
    capsys.readouterr()
    assert _sample(d, files, out, "--seed", "1") == 2
    err = capsys.readouterr().err
    assert "journal" in err and "seed" in err
    assert _sample(d, files[:1], out) == 2
    assert "inputs" in capsys.readouterr().err
    assert _sample(d, files, out, "--draws", "50") == 2  # too few draws: an error naming the option
    assert "--draws" in capsys.readouterr().err


def test_the_jackknife_factor_measures_the_scatter_between_runs():
    rng = np.random.default_rng(0)
    cov = np.diag([1.0, 4.0, 0.25])
    loo = rng.normal(size=(10, 3)) * np.sqrt(np.diag(cov))
    G = 10
    v = (G - 1) * (1.4826 * np.median(np.abs(loo - np.median(loo, 0)), 0)) ** 2  # robust jackknife variance
    f = tp.jackknife_factor(loo, cov)
    assert f["n_folds"] == 10 and f["per_parameter"] == pytest.approx(list(v / np.diag(cov)))
    assert f["factor"] == pytest.approx(max(1.0, float(np.median(v / np.diag(cov)))))
    # leave-one-out estimates that scatter 10 x more widen by 100 x (a variance ratio)
    assert tp.jackknife_factor(loo * 10, cov)["factor"] == pytest.approx(100 * float(np.median(v / np.diag(cov))))
    assert tp.jackknife_factor(np.zeros((10, 3)), cov)["factor"] == 1.0  # never narrower
    # one failed refit among the folds does not flatten the posterior
    bad = loo.copy()
    bad[3] += 1e3
    assert tp.jackknife_factor(bad, cov)["factor"] < 3 * max(f["factor"], 1.0)
    few = tp.jackknife_factor(np.ones((2, 3)), cov)
    assert few["n_folds"] == 2 and few["factor"] == 1.0  # too few folds: no factor


def test_sample_stops_mcmc_at_its_step_budget_and_repeats_it_exactly(two_runs):
    # --max-steps: a budget in steps, unlike --max-minutes the same on any machine; twice the same chains
    import arviz as az

    d, files = two_runs
    runs = []
    for k in range(2):
        out = d / f"s_steps{k}"
        assert _sample(d, files, out, "--method", "mcmc", "--max-steps", "30") == 0
        doc = json.loads((out / "sample.json").read_text())
        assert (
            doc["method"] == "mcmc" and "30 steps" in doc["verdict"]["text"] and "max_steps" in doc["verdict"]["text"]
        )
        runs.append(az.from_netcdf(out / "posterior.nc"))
    for n in runs[0].posterior.data_vars:
        np.testing.assert_array_equal(runs[0].posterior[n].values, runs[1].posterior[n].values)
    assert _sample(d, files, d / "s_bad", "--max-steps", "0") == 2  # named, exit code 2
