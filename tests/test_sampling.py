"""bayesid.estimation.sampling: posterior accuracy on a conjugate problem, resume after interruption,
-inf regions, initial balls, checkpoint mismatch, InferenceData and the convergence verdict."""

import signal
import subprocess
import sys
import textwrap

import emcee
import h5py
import numpy as np
import pytest

from bayesid.estimation.sampling import (
    Checkpoint,
    SamplerConfig,
    diagnostics,
    initial_ball,
    run_ensembles,
    to_inference_data,
)
from bayesid.tasks import Runner

# A correlated 2-D Gaussian for the bookkeeping tests (resume, mismatch, shapes).
MU2 = np.array([0.3, -0.2])
COV2 = np.array([[1.0, 0.6], [0.6, 0.5]])
PREC2 = np.linalg.inv(COV2)


def gauss2(theta):
    d = theta - MU2
    return -0.5 * np.einsum("bi,ij,bj->b", d, PREC2, d)


def stored_chains(path, n_ensembles):
    out = []
    for i in range(n_ensembles):
        b = emcee.backends.HDFBackend(str(path), name=f"ensemble{i}", read_only=True)
        out.append(b.get_chain() if b.iteration else np.empty((0, 16, 2)))
    return out


# -- 1. posterior accuracy ------------------------------------------------------------------------
def test_linear_gaussian_matches_analytic_posterior():
    """y = A theta + e, e ~ N(0, sigma^2 I), prior N(m0, S0): posterior N(mu, Sigma) with
    Sigma = (A'A / sigma^2 + S0^-1)^-1, mu = Sigma (A'y / sigma^2 + S0^-1 m0)."""
    rng = np.random.default_rng(11)
    n, sigma = 30, 0.3
    t = np.linspace(0, 1, n)
    A = np.column_stack([np.ones(n), t, t**2])  # strongly collinear columns (corr ~ 0.97)
    y = A @ np.array([0.5, -1.0, 2.0]) + sigma * rng.standard_normal(n)
    m0, S0inv = np.zeros(3), np.eye(3) / 10.0**2
    prec = A.T @ A / sigma**2 + S0inv
    Sigma = np.linalg.inv(prec)
    mu = Sigma @ (A.T @ y / sigma**2 + S0inv @ m0)

    def log_prob(theta):  # (B, 3) -> (B,)
        r = y[None] - theta @ A.T
        d = theta - m0
        return -0.5 * np.sum(r**2, axis=1) / sigma**2 - 0.5 * np.einsum("bi,ij,bj->b", d, S0inv, d)

    sd = np.sqrt(np.diag(Sigma))
    cfg = SamplerConfig(n_ensembles=4, moves="de", min_steps=500, max_steps=4000, check_every=250)
    res = run_ensembles(log_prob, mu + 1.0 * sd, 2.0 * Sigma, ["a", "b", "c"], cfg, np.random.default_rng(3))
    assert res.reached_tau_rule and res.n_steps < cfg.max_steps
    assert res.chains.shape == (4, res.n_steps, 16, 3)
    assert res.n_evaluations >= 4 * 16 * res.n_steps

    idata = to_inference_data(res)
    diag = diagnostics(idata, res)
    names = ["a", "b", "c"]
    draws = np.stack([idata.posterior[k].values.ravel() for k in names], axis=1)
    mean = draws.mean(axis=0)
    mcse = np.array([diag["mcse_mean"][k] for k in names])
    # ~4 MCSE: |error| / MCSE is ~N(0, 1), so 4 fails by chance with probability ~6e-5 per parameter.
    assert np.all(np.abs(mean - mu) < 4 * mcse), (mean - mu) / mcse
    # Covariance: with bulk ESS >= ~3000 the relative standard error of a variance is
    # sqrt(2 / ESS) < 3 %, of a correlation (1 - rho^2) / sqrt(ESS) < 0.02; 10 % and 0.06 are
    # >= 3 standard errors, yet far below what a mis-tuned sampler (wrong scale) produces.
    C = np.cov(draws.T)
    assert np.all(np.abs(np.diag(C) / np.diag(Sigma) - 1) < 0.10), np.diag(C) / np.diag(Sigma)
    corr_hat = C / np.sqrt(np.outer(np.diag(C), np.diag(C)))
    corr = Sigma / np.outer(sd, sd)
    assert np.max(np.abs(corr_hat - corr)) < 0.06, corr_hat - corr
    assert diag["rhat_max"] < 1.05 and diag["rhat_ensembles_max"] < 1.05
    # at ~50 tau the between-ensemble verdict passes; the strict per-walker one (the default) needs
    # ~120 tau on this problem, so it is not asserted here
    between = diagnostics(idata, res, ensembles_as_chains=True)
    assert between["converged"], between["verdict"]


# -- 2. resume -----------------------------------------------------------------------------------
CFG_RESUME = SamplerConfig(n_ensembles=2, min_steps=300, max_steps=300, check_every=100)


class Interrupted(Exception):
    pass


def test_resume_after_exception_loses_nothing_and_redraws_nothing(tmp_path):
    reference = run_ensembles(gauss2, MU2, COV2, ["a", "b"], CFG_RESUME, np.random.default_rng(5))
    path = tmp_path / "chk.h5"
    calls = [0]

    def failing(theta):
        calls[0] += 1
        if calls[0] > 600:  # mid-way through ensemble 0's second block or later
            raise Interrupted
        return gauss2(theta)

    with pytest.raises(Interrupted):
        run_ensembles(failing, MU2, COV2, ["a", "b"], CFG_RESUME, np.random.default_rng(5), checkpoint=Checkpoint(path))
    before = stored_chains(path, 2)
    n_before = [len(c) for c in before]
    assert 0 < max(n_before) < 300

    resumed = run_ensembles(
        gauss2, MU2, COV2, ["a", "b"], CFG_RESUME, np.random.default_rng(5), checkpoint=Checkpoint(path)
    )
    assert resumed.n_steps == reference.n_steps == 300
    for i, c in enumerate(before):  # stored part untouched
        np.testing.assert_array_equal(resumed.chains[i, : len(c)], c.reshape(-1, 16, 2))
    # emcee stores the walkers' random state with the steps: the resumed chain is the chain.
    np.testing.assert_array_equal(resumed.chains, reference.chains)
    np.testing.assert_array_equal(resumed.log_prob, reference.log_prob)
    assert resumed.n_evaluations < reference.n_evaluations
    # A finished run re-run with the same arguments does no new work.
    again = run_ensembles(
        gauss2, MU2, COV2, ["a", "b"], CFG_RESUME, np.random.default_rng(5), checkpoint=Checkpoint(path)
    )
    assert again.n_evaluations == 0 and again.n_steps == 300


def test_extending_max_steps_continues_the_stored_chain(tmp_path):
    path = tmp_path / "chk.h5"
    short = SamplerConfig(n_ensembles=2, min_steps=100, max_steps=200, check_every=100)
    first = run_ensembles(gauss2, MU2, COV2, ["a", "b"], short, np.random.default_rng(5), checkpoint=Checkpoint(path))
    assert first.n_steps == 200 and first.stop_reason == "max_steps"
    longer = run_ensembles(
        gauss2, MU2, COV2, ["a", "b"], CFG_RESUME, np.random.default_rng(5), checkpoint=Checkpoint(path)
    )
    reference = run_ensembles(gauss2, MU2, COV2, ["a", "b"], CFG_RESUME, np.random.default_rng(5))
    assert longer.n_steps == 300
    np.testing.assert_array_equal(longer.chains[:, :200], first.chains)
    np.testing.assert_array_equal(longer.chains, reference.chains)
    assert longer.n_evaluations == 2 * 16 * 100  # each step evaluates every walker once
    assert reference.n_evaluations == 2 * 16 * 300 + 2 * 16  # + the initial balls


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs POSIX SIGKILL")
def test_resume_after_sigkill(tmp_path):
    path = tmp_path / "chk.h5"
    script = textwrap.dedent(f"""
        import os, signal
        import numpy as np
        from bayesid.estimation.sampling import Checkpoint, SamplerConfig, run_ensembles
        MU2 = np.array({MU2.tolist()}); PREC2 = np.linalg.inv(np.array({COV2.tolist()}))
        calls = [0]
        def lp(theta):
            calls[0] += 1
            if calls[0] > 700:
                os.kill(os.getpid(), signal.SIGKILL)
            d = theta - MU2
            return -0.5 * np.einsum("bi,ij,bj->b", d, PREC2, d)
        cfg = SamplerConfig(n_ensembles=2, min_steps=300, max_steps=300, check_every=100)
        run_ensembles(lp, MU2, np.array({COV2.tolist()}), ["a", "b"], cfg, np.random.default_rng(5),
                      checkpoint=Checkpoint({str(path)!r}))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    before = stored_chains(path, 2)
    assert 0 < max(len(c) for c in before) < 300
    resumed = run_ensembles(
        gauss2, MU2, COV2, ["a", "b"], CFG_RESUME, np.random.default_rng(5), checkpoint=Checkpoint(path)
    )
    reference = run_ensembles(gauss2, MU2, COV2, ["a", "b"], CFG_RESUME, np.random.default_rng(5))
    np.testing.assert_array_equal(resumed.chains, reference.chains)


def test_seeded_only_by_the_generator_passed_in():
    cfg = SamplerConfig(n_ensembles=2, min_steps=50, max_steps=50, check_every=50)
    np.random.seed(1)
    a = run_ensembles(gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(9))
    np.random.seed(2)
    b = run_ensembles(gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(9))
    c = run_ensembles(gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(10))
    np.testing.assert_array_equal(a.chains, b.chains)
    assert not np.array_equal(a.chains, c.chains)
    assert not np.array_equal(a.chains[0], a.chains[1])  # ensembles are independent


# -- 3. diverged region --------------------------------------------------------------------------
def test_minus_inf_and_nan_regions_are_never_entered():
    """Gaussian centred at 0.9 truncated at theta_0 > 1 (-inf) and NaN ("diverged simulation")
    for theta_1 > 1.2: proposals there are rejected, nothing crashes, no NaN is stored."""
    prec = np.linalg.inv(np.array([[0.09, 0.0], [0.0, 0.25]]))

    def log_prob(theta):
        d = theta - np.array([0.9, 0.0])
        lp = -0.5 * np.einsum("bi,ij,bj->b", d, prec, d)
        lp[theta[:, 0] > 1.0] = -np.inf
        lp[theta[:, 1] > 1.2] = np.nan
        return lp

    cfg = SamplerConfig(n_ensembles=2, min_steps=400, max_steps=400, check_every=200)
    res = run_ensembles(
        log_prob, np.array([0.6, 0.0]), np.diag([0.04, 0.25]), ["x", "y"], cfg, np.random.default_rng(2)
    )
    assert res.n_steps == 400
    assert np.all(np.isfinite(res.log_prob)) and np.all(np.isfinite(res.chains))
    assert res.chains[..., 0].max() <= 1.0 and res.chains[..., 1].max() <= 1.2
    assert res.chains[..., 0].max() > 0.95  # the walkers did reach the edge
    assert np.all(res.acceptance > 0.05)


# -- 4. initial ball -----------------------------------------------------------------------------
def test_initial_ball_redraws_minus_inf_rows():
    calls = []

    def half_plane(theta):  # uniform prior theta_0 >= 0
        calls.append(len(theta))
        return np.where(theta[:, 0] >= 0, 0.0, -np.inf)

    pos = initial_ball(np.zeros(2), np.eye(2), 32, np.random.default_rng(0), half_plane)
    assert pos.shape == (32, 2) and np.all(pos[:, 0] >= 0)
    assert len(calls) > 1 and calls[0] == 32 and calls[1] < 32  # only the failed rows redrawn
    assert np.std(pos[:, 1]) > 0.5  # still the Laplace-shaped ball

    with pytest.raises(RuntimeError, match="16 of 16 walkers"):
        initial_ball(
            np.zeros(2), np.eye(2), 16, np.random.default_rng(0), lambda th: np.full(len(th), -np.inf), max_tries=5
        )
    with pytest.raises(ValueError, match="positive definite"):
        initial_ball(np.zeros(2), np.ones((2, 2)), 16, np.random.default_rng(0), gauss2)


# -- 5. checkpoint of another problem ------------------------------------------------------------
def test_mismatched_checkpoint_raises_naming_the_file(tmp_path):
    path = tmp_path / "other_problem.h5"
    cfg = SamplerConfig(n_ensembles=2, min_steps=20, max_steps=20, check_every=20)
    run_ensembles(gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(0), checkpoint=Checkpoint(path))
    with pytest.raises(ValueError, match=r"other_problem\.h5.*names"):
        run_ensembles(gauss2, MU2, COV2, ["a", "c"], cfg, np.random.default_rng(0), checkpoint=Checkpoint(path))
    with pytest.raises(ValueError, match=r"other_problem\.h5.*n_walkers 16 in the file, 20 now"):
        run_ensembles(
            gauss2,
            MU2,
            COV2,
            ["a", "b"],
            SamplerConfig(n_ensembles=2, n_walkers=20, min_steps=20, max_steps=20, check_every=20),
            np.random.default_rng(0),
            checkpoint=Checkpoint(path),
        )
    gauss3 = lambda th: -0.5 * np.sum(th**2, axis=1)  # noqa: E731
    with pytest.raises(ValueError, match=r"other_problem\.h5.*ndim 2 in the file, 3 now"):
        run_ensembles(
            gauss3, np.zeros(3), np.eye(3), ["a", "b", "c"], cfg, np.random.default_rng(0), checkpoint=Checkpoint(path)
        )
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f.create_group("mcmc")
    with pytest.raises(ValueError, match=r"foreign\.h5.*not written by bayesid"):
        run_ensembles(gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(0), checkpoint=Checkpoint(foreign))


# -- 6. InferenceData and verdict ----------------------------------------------------------------
def test_inference_data_layout_and_verdict_on_a_too_short_run():
    cfg = SamplerConfig(n_ensembles=3, min_steps=40, max_steps=40, check_every=20)
    res = run_ensembles(gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(1))
    E, N, W, P = res.chains.shape
    assert (E, N, W, P) == (3, 40, 16, 2) and res.log_prob.shape == (3, 40, 16)
    assert res.acceptance.shape == (3, 16) and res.tau.shape == (2,)
    assert not res.reached_tau_rule and res.stop_reason == "max_steps"

    idata = to_inference_data(res, burn=10, thin=3, truth={"a": 0.3})
    assert list(idata.posterior.data_vars) == ["a", "b"]
    assert idata.posterior["a"].shape == (E * W, 10)  # steps 10, 13, ..., 37
    assert list(idata.posterior["draw"].values) == list(range(10, 40, 3))
    e, w = 2, 5
    np.testing.assert_array_equal(idata.posterior["b"].values[e * W + w], res.chains[e, 10::3, w, 1])
    np.testing.assert_array_equal(idata.sample_stats["lp"].values[e * W + w], res.log_prob[e, 10::3, w])
    assert float(idata.constant_data["truth_a"]) == 0.3
    default = to_inference_data(res)
    assert default.posterior.sizes["draw"] == N - min(N // 2, int(2 * np.max(res.tau)))
    with pytest.raises(ValueError, match="burn"):
        to_inference_data(res, burn=40)
    with pytest.raises(ValueError, match="truth"):
        to_inference_data(res, truth={"z": 1.0})

    diag = diagnostics(default, res)
    for key in ("rhat", "ess_bulk", "ess_tail", "mcse_mean", "rhat_ensembles"):
        assert set(diag[key]) == {"a", "b"}
    for key in (
        "rhat_max",
        "ess_bulk_min",
        "ess_tail_min",
        "tau_max",
        "acceptance_mean",
        "n_steps",
        "rhat_ensembles_max",
        "converged",
        "verdict",
    ):
        assert key in diag
    assert diag["converged"] is False
    assert "tau rule not met: 40 steps" in diag["verdict"] and "max_steps" in diag["verdict"]
    assert f"bulk ESS min {diag['ess_bulk_min']:.0f}" in diag["verdict"]  # ~ 3 x 16 x 20 draws


def test_wall_time_limit_stops_gracefully():
    cfg = SamplerConfig(n_ensembles=2, min_steps=100, max_steps=10_000, check_every=50, max_wall_s=0.0)
    res = run_ensembles(gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(0))
    assert res.n_steps == 50 and res.stop_reason == "max_wall_s" and not res.reached_tau_rule


def test_arrival_burn_waits_for_a_stranded_walker():
    from bayesid.estimation.sampling import SamplerResult, arrival_burn

    rng = np.random.default_rng(0)
    E, N, W = 2, 1000, 8
    lp = rng.normal(0.0, 1.0, (E, N, W))
    lp[1, :300, 5] -= 50.0  # one walker far down the tail for 300 steps
    res = SamplerResult(
        chains=np.zeros((E, N, W, 1)),
        log_prob=lp,
        acceptance=np.zeros((E, W)),
        tau=np.array([10.0]),
        n_steps=N,
        n_evaluations=0,
        wall_s=0.0,
        reached_tau_rule=True,
        names=["a"],
    )
    assert 300 <= arrival_burn(res) <= 305
    lp[1, :300, 5] += 50.0
    assert arrival_burn(res) < 100  # without it only noise-level dips remain
    lp[0, :, 2] -= 50.0  # stranded throughout: capped at half the run
    assert arrival_burn(res) == N // 2
    lp[0, :, 2] += 50.0
    from bayesid.estimation.sampling import burn_in

    assert burn_in(res) < 100
    res.redraws = [(150, 0, 2), (700, 1, 4)]  # the chains are valid only after the last move
    assert burn_in(res) == 700


def test_a_checkpoint_of_another_run_is_refused(tmp_path):
    """A checkpoint records the run's key (seed, data, settings); another run's key is refused,
    so its chains are never reported as this run's."""
    path = tmp_path / "ck.h5"
    cfg = SamplerConfig(n_ensembles=2, min_steps=20, max_steps=20, check_every=20)
    run_ensembles(
        gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(0), checkpoint=Checkpoint(path, {"seed": 2003})
    )
    run_ensembles(
        gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(0), checkpoint=Checkpoint(path, {"seed": 2003})
    )  # the same run resumes
    with pytest.raises(ValueError, match=r"ck\.h5.*run_key"):
        run_ensembles(
            gauss2, MU2, COV2, ["a", "b"], cfg, np.random.default_rng(0), checkpoint=Checkpoint(path, {"seed": 7})
        )


def test_until_converged_runs_past_the_tau_rule_to_a_converged_verdict():
    """On the 2-D Gaussian the 50-tau rule stops before the strict per-walker R-hat holds; with
    ``until_converged`` the run goes on and stops as soon as the verdict is 'converged', and a
    budget too small for that stops on max_steps with the verdict saying what failed."""
    base = dict(n_ensembles=4, moves="de", min_steps=200, max_steps=20000, check_every=100)
    tau_only = run_ensembles(gauss2, MU2, COV2, ["a", "b"], SamplerConfig(**base), np.random.default_rng(5))
    d0 = diagnostics(to_inference_data(tau_only), tau_only)
    assert tau_only.stop_reason == "tau rule" and not d0["converged"]  # the point of the option
    res = run_ensembles(
        gauss2, MU2, COV2, ["a", "b"], SamplerConfig(**base, until_converged=True), np.random.default_rng(5)
    )
    from bayesid.estimation.sampling import burn_in

    d = diagnostics(to_inference_data(res, burn=burn_in(res)), res)
    assert res.stop_reason == "converged" and d["converged"] and res.n_steps > tau_only.n_steps
    assert d["rhat_max"] <= 1.01 and d["ess_tail_min"] >= 400
    short = run_ensembles(
        gauss2,
        MU2,
        COV2,
        ["a", "b"],
        SamplerConfig(**{**base, "max_steps": tau_only.n_steps}, until_converged=True),
        np.random.default_rng(5),
    )
    assert short.stop_reason == "max_steps"
    assert not diagnostics(to_inference_data(short, burn=burn_in(short)), short)["converged"]


# -- stranded walkers ------------------------------------------------------------------------------
def trap(theta):
    """A 2-D standard Gaussian cut at radius 6, and a flat trap (log p = -40) of radius 1 at
    (20, 0): a walker that starts in the trap sees only -inf around it once the ensemble has
    contracted, so DE moves leave it there."""
    th = np.atleast_2d(theta)
    lp = np.where(np.hypot(*th.T) < 6.0, -0.5 * np.sum(th**2, axis=1), -np.inf)
    return np.where(np.hypot(th[:, 0] - 20.0, th[:, 1]) < 1.0, -40.0, lp)


TRAP_START = (np.zeros(2), np.diag([100.0, 1.0]))  # the ball puts a walker in the trap (seed 7)
CFG_TRAP = dict(n_ensembles=2, min_steps=600, max_steps=600, check_every=100)


def test_stranded_walkers_are_those_far_below_the_typical_set_for_the_whole_window():
    from bayesid.estimation.sampling import stranded_walkers

    lp = np.random.default_rng(0).normal(0.0, 1.0, (2, 50, 16))
    assert not stranded_walkers(lp).any()
    lp[1, :, 3] -= 40.0  # far down for the whole window
    lp[0, :25, 7] -= 40.0  # arrived half-way through: not stranded
    s = stranded_walkers(lp)
    assert s[1, 3] and s.sum() == 1
    lp[1, :, :5] -= 40.0  # 6 of 16 down: the ensemble is still burning in
    assert not stranded_walkers(lp)[1].any()
    with pytest.raises(ValueError, match=r"\(E, w, W\)"):
        stranded_walkers(lp[0])


def test_a_stranded_walker_is_moved_and_burn_in_ends_at_the_move():
    from bayesid.estimation.sampling import arrival_burn, burn_in

    plain = run_ensembles(trap, *TRAP_START, ["a", "b"], SamplerConfig(**CFG_TRAP), np.random.default_rng(7))
    assert (plain.log_prob[:, 0] == -40.0).sum() == 1 and plain.redraws == []
    # without moves it sits in the trap past the first check (100 steps), where the move below
    # frees it; how much longer depends on the DE proposals' random stream (161 steps with numpy
    # 2.4, over 200 before)
    assert arrival_burn(plain) > 150
    res = run_ensembles(
        trap, *TRAP_START, ["a", "b"], SamplerConfig(**CFG_TRAP, redraw_stranded=True), np.random.default_rng(7)
    )
    assert res.redraws == [(100, 0, 2)]  # found at the first block's end
    assert not (res.log_prob[:, 100:] == -40.0).any()
    assert burn_in(res) == 100
    np.testing.assert_array_equal(res.chains[:, :100], plain.chains[:, :100])  # nothing else changed
    # the moved walker took another walker's place, log-probability included
    assert res.log_prob[0, 100, 2] > -20.0


@pytest.mark.parametrize("extra_calls", [1, 150])
def test_resume_after_a_redraw_gives_the_uninterrupted_chain(tmp_path, extra_calls):
    cfg = SamplerConfig(**{**CFG_TRAP, "min_steps": 300, "max_steps": 300}, redraw_stranded=True)
    reference = run_ensembles(trap, *TRAP_START, ["a", "b"], cfg, np.random.default_rng(7))
    calls = [0]

    def counting(theta):
        calls[0] += 1
        return trap(theta)

    run_ensembles(
        counting,
        *TRAP_START,
        ["a", "b"],
        SamplerConfig(**{**CFG_TRAP, "min_steps": 100, "max_steps": 100}),
        np.random.default_rng(7),
    )
    at_move, calls[0] = calls[0], 0

    def failing(theta):
        calls[0] += 1
        if calls[0] > at_move + extra_calls - 1:  # right after the move, or in the next block
            raise Interrupted
        return trap(theta)

    path = tmp_path / "trap.h5"
    with pytest.raises(Interrupted):
        run_ensembles(failing, *TRAP_START, ["a", "b"], cfg, np.random.default_rng(7), checkpoint=Checkpoint(path))
    resumed = run_ensembles(trap, *TRAP_START, ["a", "b"], cfg, np.random.default_rng(7), checkpoint=Checkpoint(path))
    np.testing.assert_array_equal(resumed.chains, reference.chains)
    assert resumed.redraws == reference.redraws == [(100, 0, 2)]
    with pytest.raises(ValueError, match="redraw_stranded"):  # a checkpoint of the other setting
        run_ensembles(
            trap,
            *TRAP_START,
            ["a", "b"],
            SamplerConfig(**{**CFG_TRAP, "min_steps": 300, "max_steps": 300}),
            np.random.default_rng(7),
            checkpoint=Checkpoint(path),
        )


def _gauss3(theta):
    """A correlated 3-D Gaussian, elementwise (no BLAS): the same numbers in any process."""
    t = np.atleast_2d(theta)
    return -0.5 * (t[:, 0] ** 2 + (t[:, 1] - 0.5 * t[:, 0]) ** 2 / 0.25 + t[:, 2] ** 2 / 4.0)


def test_ensembles_as_tasks_give_the_serial_chains_bit_for_bit(tmp_path):
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    cfg = SamplerConfig(n_ensembles=2, min_steps=300, max_steps=300, check_every=100)
    args = (_gauss3, np.zeros(3), np.eye(3), ["a", "b", "c"], cfg)
    serial = run_ensembles(*args, np.random.default_rng(11))
    par = run_ensembles(*args, np.random.default_rng(11), runner=Runner(jobs=2))
    np.testing.assert_array_equal(par.chains, serial.chains)
    np.testing.assert_array_equal(par.log_prob, serial.log_prob)
    np.testing.assert_array_equal(par.acceptance, serial.acceptance)
    assert par.n_evaluations == serial.n_evaluations
    # checkpointed in parallel, resumed serially with a longer budget: the serial chain again
    ck = tmp_path / "ck.h5"
    run_ensembles(*args, np.random.default_rng(11), checkpoint=Checkpoint(ck), runner=Runner(jobs=2))
    longer = SamplerConfig(n_ensembles=2, min_steps=500, max_steps=500, check_every=100)
    a = run_ensembles(
        _gauss3, np.zeros(3), np.eye(3), ["a", "b", "c"], longer, np.random.default_rng(11), checkpoint=Checkpoint(ck)
    )
    b = run_ensembles(_gauss3, np.zeros(3), np.eye(3), ["a", "b", "c"], longer, np.random.default_rng(11))
    np.testing.assert_array_equal(a.chains, b.chains)
