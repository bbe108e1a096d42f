"""Benchmark of ``bayesid sample``'s posterior objective on real data: what one evaluation of
:meth:`bayesid.estimation.track_posterior.TrackPosterior.evaluate` costs, batched and one row at a
time, and from that the wall time of importance-reweighted Laplace against full MCMC, in one run.

Data sets (``../shared/data/real``; the benchmark prints a message and exits 0 without them):

* KVLCC2 7 m model, HSVA zigzags: all 13 runs, packaged vehicle ``kvlcc2_7m``, no effects;
* Esso Osaka 3 m model, Osaka University pond: all runs except the trimmed ``turn_cut_*`` copy
  (the first rows of another run: 34 distinct runs), ``esso_osaka_3m`` with the wind effect, as
  ``studies/real_ships.py`` uses it.

Per data set:

1. fit as ``bayesid fit`` does with its defaults (:func:`bayesid.estimation.identify`: the
   vehicle's free coefficients, the family's window, step, weighting and start rule, the vehicle
   file's priors) but ``calibration=None`` and ``max_nfev`` capped (``--max-nfev``, default 30);
2. build the posterior exactly as :func:`~bayesid.estimation.track_posterior.sample_tracks` does
   (``WindowObjective`` with the fit's ``fit_sd``, channels, window and start rule; the held-out
   nuisances when the model has any; :func:`error_model`; ``ParameterPrior.of_model``;
   ``TrackPosterior``), and its mode and Laplace covariance (:func:`posterior_mode`, timed);
3. time ``post.evaluate`` on batches of 1, 8, 32, 64 rows and on the batches emcee asks for
   (``W / 2`` rows for the DE move, ``W / 4`` for the snooker move, ``W = max(2 P + 2, 16)``
   walkers) in turn for ``--repeats`` rounds (each call its own rows; the median call, and the best
   in brackets, since other load only ever slows a call down), rows drawn from the
   importance proposal (Student-t, df 5, around the mode with the Laplace covariance) inside the
   prior's support so that every row is simulated;
4. estimate the wall time of importance sampling with 4000 draws (chunks of 64 rows) and of MCMC
   with 2 emcee ensembles of W walkers run for 50 tau steps (tau 100, 500, 2000 steps; at least
   the 500 steps ``sample_tracks`` asks for): ``steps x W x 2 x`` ms per row at emcee's batch, and
   which fits the 20-minute budget of ``bayesid sample --max-minutes``;
5. run :func:`importance_laplace` for real with ``--draws`` (1000) draws on one worker and report its
   wall time, Pareto k-hat and ESS.

    python benchmarks/sample.py [--quick] [--sets kvlcc2,esso|synthetic] [--max-nfev 30] [--draws 1000]
                                [--draws-log 400] [--budget-minutes 2] [--repeats 5] [--data DIR]
                                [--out reports/benchmark_sample.txt]

6. with and without a velocity log (issue 50), on the same runs: where every run logs u, v and r,
   the importance stage's wall time per draw (:func:`importance_laplace`, ``--draws-log`` draws,
   chunks of 16, one worker) with the measured start rule, and with the velocity columns dropped
   (start states fitted) on the old path (every draw's start states fitted from the measured
   guess, ``SampleOptions(start_profile="full")``) and on the new one (from the mode's
   linearisation, :class:`~bayesid.estimation.track_posterior.StartLinearisation`), with the
   ratios, the largest log-posterior difference between the two paths near the mode and both
   paths' k-hat and ESS; then ``sample_tracks`` under ``--budget-minutes`` (2) without the
   velocity log on both paths: wall time and what the budget cut.

Without the real data, step 6 runs on synthetic runs (``--sets synthetic``, the default then):
four KVLCC2 7 m manoeuvres (10/10 and 20/20 zigzags, a 35 deg turn, a 20 deg pull-out) simulated
with ``bayesid simulate`` at 5 Hz, with noise (x, y 2 cm; psi 0.1 deg; u, v 5 mm/s; r 0.05 deg/s).

``--quick``: 3 runs per data set, ``max_nfev`` 4, 200 draws, 2 repeats, 100 draws per path in
step 6 and no budget run (unless ``--budget-minutes`` is given), and no report file unless
``--out`` is given. Times are ``time.perf_counter`` wall clock with numba's default threads (all
cores); compile time is excluded (one warm-up evaluation first). The last lines are
machine-readable ``key value`` pairs.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np

from bayesid.estimation.track_posterior import ImportanceOptions

ROOT = Path(__file__).resolve().parent.parent

BATCHES = (1, 8, 16, 32, 64)
IS_DRAWS = 4000  # bayesid sample --draws default
IS_CHUNK = ImportanceOptions().chunk  # importance_laplace's chunk of rows
TAUS = (100, 500, 2000)
TAU_FACTOR = 50
MIN_STEPS = 500  # sample_tracks' SamplerConfig(min_steps=500)
N_ENSEMBLES = 2
BUDGET_MIN = 20.0  # bayesid sample --max-minutes default
SETS = {
    "kvlcc2": ("KVLCC2 HSVA", "kvlcc2-simman-hsva", "simman-hsva", "kvlcc2_7m", []),
    "esso": ("Esso Osaka", "esso-osaka-frt", "esso-osaka", "esso_osaka_3m", ["wind"]),
}
#: The synthetic runs of step 6 without the real data: (manoeuvre, angle in deg).
SYNTHETIC = (("zigzag", "10"), ("zigzag", "-20"), ("turn", "35"), ("pull-out", "-20"))
#: Their noise sds (SI).
SYNTHETIC_NOISE = {
    "x": 0.02,
    "y": 0.02,
    "psi": math.radians(0.1),
    "u": 0.005,
    "v": 0.005,
    "r": math.radians(0.05),
}
VELOCITY = ("u", "v", "r")


def _header(args) -> list[str]:
    import numba

    from bayesid._numba import use_package_threading_layer
    from bayesid.report import git_commit

    use_package_threading_layer()  # before numba.get_num_threads() below starts the thread pool

    def ver(p):
        try:
            return metadata.version(p)
        except metadata.PackageNotFoundError:
            return "-"

    return [
        f"# benchmarks/sample.py: cost of bayesid sample's posterior objective on real data (synthetic runs without it){' (QUICK)' if args.quick else ''}",
        f"# machine {platform.node()} ({platform.machine()}, {os.cpu_count()} cores), {platform.platform()}",
        f"# date {time.strftime('%Y-%m-%d %H:%M:%S %Z')}, git commit {git_commit()}",
        f"# python {platform.python_version()}, numpy {ver('numpy')}, numba {ver('numba')} "
        f"({numba.get_num_threads()} threads, layer {numba.config.THREADING_LAYER}), scipy {ver('scipy')}, "
        f"emcee {ver('emcee')}, arviz {ver('arviz')}",
        f"# command: {' '.join([Path(sys.executable).name] + sys.argv)}",
        "# load average at start (1/5/15 min): "
        + " ".join(f"{v:.2f}" for v in os.getloadavg())
        + " (other processes on the machine slow every timing down)",
        f"# fits: bayesid fit defaults but calibration=None and max_nfev capped at {args.max_nfev} "
        "(the benchmark times the posterior, not the fit; a fuller fit moves the mode, not the cost)",
    ]


def _tracks(data: Path, key: str, quick: bool):
    from bayesid.data import datasets

    _, folder, fmt, _, _ = SETS[key]
    paths = [p for p in datasets.list_runs(data / folder, fmt) if "turn_cut" not in p.name]
    if quick:
        paths = paths[:3]
    return [datasets.read_run(p, fmt) for p in paths]


def build(vehicle_id, effects, train, max_nfev, say):
    """Fit (``bayesid fit`` defaults, no calibration) and the posterior as ``sample_tracks`` builds it."""
    from bayesid.estimation import track_posterior as tp
    from bayesid.estimation import windows as wf
    from bayesid.estimation.identification import identify
    from bayesid.estimation.options import FitOptions
    from bayesid.models import load_any_vehicle

    vehicle = load_any_vehicle(vehicle_id)
    t = time.perf_counter()
    res = identify(vehicle, train, FitOptions(effects=effects, max_nfev=max_nfev, prior=True), calibration=None)
    fit_s = time.perf_counter() - t
    model, p0 = res.model, np.asarray(res.fit.p, float)
    say(f"  fit: {fit_s:.1f} s, {res.fit.n_simulations} simulations, success {res.fit.success}")
    # --- as sample_tracks (the model.json round trip keeps these values) ---
    t = time.perf_counter()
    ctxs = [model.context(tr, res.window_s, start=res.start_rule) for tr in train]
    ob = wf.WindowObjective(model, ctxs, res.fit_sd, p0, channels=res.channels)
    nuisance = np.zeros(0)
    if model.n_nuisance:
        fr = type("Fitted", (), {"p": p0})()
        nuisance = np.concatenate(wf.heldout_nuisance(model, fr, ctxs, res.fit_sd))
    errors = tp.error_model(ob, np.concatenate([p0, nuisance]))
    prior = tp.ParameterPrior.of_model(model, True)
    post = tp.TrackPosterior(ob, errors, prior, nuisance)
    setup_s = time.perf_counter() - t
    return res, post, fit_s, setup_s


def proposal_rows(post, center, cov, n, rng):
    """``n`` rows of the importance proposal (as :func:`importance_laplace` draws them) inside the
    prior's support."""
    from scipy.stats import multivariate_t

    scale = np.where(np.diag(cov) > 0, np.sqrt(np.clip(np.diag(cov), 0, None)), 1.0)
    corr = cov / np.outer(scale, scale) + 1e-12 * np.eye(center.size)
    dist = multivariate_t(loc=np.zeros(center.size), shape=corr, df=5.0, allow_singular=True)
    out = []
    while sum(len(o) for o in out) < n:
        X = center + dist.rvs(size=4 * n, random_state=rng).reshape(4 * n, -1) * scale
        out.append(X[np.isfinite(post.prior.logpdf(X))])
    return np.vstack(out)[:n]


def time_batches(post, rows, batches, repeats):
    """{B: (median s per call, median s per row, best s per row, finite fraction)}: the batch sizes
    timed in turn, ``repeats`` rounds (so a passing load hits them alike), each call its own rows."""
    ts = {B: [] for B in batches}
    fin = {B: [] for B in batches}
    k = 0
    for _ in range(repeats):
        for B in batches:
            X = rows[np.arange(k, k + B) % rows.shape[0]]
            k += B
            t = time.perf_counter()
            lp, _ = post.evaluate(X)
            ts[B].append(time.perf_counter() - t)
            fin[B].append(np.isfinite(lp).mean())
    out = {}
    for B in batches:
        med = float(np.median(ts[B]))
        out[B] = (med, med / B, float(np.min(ts[B])) / B, float(np.mean(fin[B])))
    return out


def fmt_time(s: float) -> str:
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.1f} min"
    return f"{s / 3600:.1f} h"


def bench_set(key, args, data, say, keys):
    from bayesid.estimation import track_posterior as tp
    from bayesid.estimation.sampling import SamplerConfig

    label, _, _, vehicle_id, effects = SETS[key]
    train = _tracks(data, key, args.quick)
    dur = sum(float(tr.t[-1] - tr.t[0]) for tr in train)
    say("")
    say(f"== {label}: {len(train)} runs, {dur:.0f} s of data, vehicle {vehicle_id}, effects {effects or 'none'} ==")
    res, post, fit_s, setup_s = build(vehicle_id, effects, train, args.max_nfev, say)
    P = len(post.names)
    W = SamplerConfig().walkers(P)
    n_win = sum(c.W for c in post.ob.ctxs)
    n_res = int((post.errors.column >= 0).sum())
    say(
        f"  posterior: {P} parameters, {n_win} windows of {res.window_s:g} s, start rule {res.start_rule}"
        + (f" ({post.ob.n_starts} profiled start states)" if post.ob.vp else "")
        + f", dt {post.ob.model.dt:g} s, {n_res} measured residuals, channels {', '.join(post.errors.channels)}, "
        f"{int(post.prior.gaussian.sum())} Gaussian priors, {post.nuisance.size} held nuisances; built in {setup_s:.1f} s"
    )
    say(
        "  error model: "
        + ", ".join(
            f"{c} rho {r:.3f} k {k:.1f} n_eff {n:.0f}"
            for c, r, k, n in zip(post.errors.channels, post.errors.rho, post.errors.inflation, post.errors.n_eff)
        )
    )
    p0 = np.asarray(res.fit.p, float)
    # warm-up (numba kernels loaded/compiled), then sample_tracks' own cost line
    post.evaluate(p0[None])
    t = time.perf_counter()
    post.evaluate(np.repeat(p0[None], 8, axis=0))
    st_eval = (time.perf_counter() - t) / 8
    t = time.perf_counter()
    mode = tp.posterior_mode(post, p0)
    mode_s = time.perf_counter() - t
    say(
        f"  posterior mode + Laplace covariance (posterior_mode, max_nfev 30): {mode_s:.1f} s; "
        f"sample_tracks' own cost line (p0 x 8): {1e3 * st_eval:.1f} ms per row"
    )
    rng = np.random.default_rng([args.seed, 1])
    batches = sorted(set(BATCHES) | {W // 2, max(W // 4, 1)})
    rows = proposal_rows(post, mode["p"], mode["cov"], sum(batches) * args.repeats, rng)
    tb = time_batches(post, rows, batches, args.repeats)
    single = tb[1][1]
    say(
        f"  post.evaluate, {args.repeats} rounds over the batch sizes, median (and best) call; proposal rows inside "
        f"the prior's support; load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}"
    )
    say(f"  {'batch':>6s} {'ms/call':>10s} {'ms/row':>9s} {'(best)':>9s} {'single/batch':>13s} {'finite':>7s}")
    for B in batches:
        c, r, b, f = tb[B]
        tag = " (emcee DE half-ensemble)" if B == W // 2 else (" (emcee snooker)" if B == max(W // 4, 1) else "")
        say(f"  {B:6d} {1e3 * c:10.1f} {1e3 * r:9.2f} {1e3 * b:9.2f} {single / r:13.2f} {f:7.2f}{tag}")
    best = min(batches, key=lambda B: tb[B][1])
    say(
        f"  cheapest row at batch {best} ({1e3 * tb[best][1]:.2f} ms); importance_laplace's chunk of {IS_CHUNK} costs "
        f"{tb[IS_CHUNK][1] / tb[best][1]:.2f} x that per row"
    )
    # estimates
    is_row = tb[IS_CHUNK][1]
    is_s = IS_DRAWS * is_row
    mc_row = 0.8 * tb[W // 2][1] + 0.2 * tb[max(W // 4, 1)][1]  # DE 0.8 + snooker 0.2
    say(
        f"  estimate, importance-reweighted Laplace, {IS_DRAWS} draws in chunks of {IS_CHUNK}: "
        f"{IS_DRAWS} x {1e3 * is_row:.2f} ms = {fmt_time(is_s)} (+ mode {mode_s:.0f} s)"
    )
    say(
        f"  estimate, MCMC: {N_ENSEMBLES} ensembles x {W} walkers (2P+2 or 16), {TAU_FACTOR} tau steps, "
        f"{1e3 * mc_row:.2f} ms per row (0.8 x batch {W // 2} + 0.2 x batch {max(W // 4, 1)}):"
    )
    fits = {}
    for tau in TAUS:
        steps = max(TAU_FACTOR * tau, MIN_STEPS)
        s = steps * W * N_ENSEMBLES * mc_row
        fits[tau] = s <= 60 * BUDGET_MIN
        say(
            f"    tau {tau:5d}: {steps:6d} steps x {W} x {N_ENSEMBLES} = {steps * W * N_ENSEMBLES:8d} rows -> "
            f"{fmt_time(s):>9s} = {s / is_s:6.0f} x importance; "
            f"{'fits' if fits[tau] else 'does NOT fit'} {BUDGET_MIN:g} min"
        )
        keys[f"{key}_mcmc_minutes_tau{tau}"] = s / 60
    s_min = MIN_STEPS * W * N_ENSEMBLES * mc_row
    say(
        f"    sample_tracks' min_steps {MIN_STEPS} alone: {fmt_time(s_min)} "
        f"({'within' if s_min <= 60 * BUDGET_MIN else 'beyond'} the {BUDGET_MIN:g} min budget)"
    )
    keys[f"{key}_mcmc_minutes_min_steps"] = s_min / 60
    steps_budget = 60 * BUDGET_MIN / (W * N_ENSEMBLES * mc_row)
    say(
        f"  in {BUDGET_MIN:g} min the MCMC gets {steps_budget:.0f} steps per walker: enough for 50 tau up to tau "
        f"{steps_budget / TAU_FACTOR:.0f}; importance sampling with {IS_DRAWS} draws uses "
        f"{100 * is_s / (60 * BUDGET_MIN):.1f} % of the budget"
    )
    say(
        f"  with --jobs 2 (the 2 ensembles, or the importance chunks, as tasks on 2 workers) at most 2x faster "
        f"(numba already runs each batch on {os.cpu_count()} threads; reports/benchmark_tasks.txt measured 1.5x): "
        f"MCMC 50 tau in {BUDGET_MIN:g} min up to tau {2 * steps_budget / TAU_FACTOR:.0f} at best"
    )
    # a real importance run
    t = time.perf_counter()
    imp = tp.importance_laplace(
        post, mode["p"], mode["cov"], np.random.default_rng([args.seed, 2]), tp.ImportanceOptions(n_draws=args.draws)
    )
    imp_s = time.perf_counter() - t
    inside = int(np.isfinite(post.prior.logpdf(imp["draws"])).sum())
    say(
        f"  importance_laplace, {args.draws} draws, jobs=1: {imp_s:.1f} s; {inside} draws inside the prior's support "
        f"(simulated; {1e3 * imp_s / max(inside, 1):.2f} ms each), {imp['finite']} with a finite posterior; "
        f"Pareto k-hat {imp['k_hat']:.3f} ({'<' if imp['reliable'] else '>='} {tp.KHAT_MAX}), ESS {imp['ess']:.1f} "
        f"({100 * imp['ess'] / args.draws:.1f} % of the draws; {IS_DRAWS} draws at this rate: ESS ~"
        f"{imp['ess'] * IS_DRAWS / args.draws:.0f}, 400 needed; measured rate for {IS_DRAWS} draws: "
        f"{fmt_time(imp_s * IS_DRAWS / args.draws)})"
    )
    if inside < args.draws:
        out_b = ~np.all((imp["draws"] >= post.prior.lo) & (imp["draws"] <= post.prior.hi), axis=0)
        viol = np.sum((imp["draws"] < post.prior.lo) | (imp["draws"] > post.prior.hi), axis=0)
        worst = np.argsort(-viol)[: min(5, int(out_b.sum()))]
        say(
            "  draws outside the bounds, by parameter (most often first): "
            + ", ".join(f"{post.names[j]} {viol[j]}" for j in worst if viol[j])
        )
    keys.update(
        {
            f"{key}_n_params": P,
            f"{key}_n_windows": n_win,
            f"{key}_fit_s": fit_s,
            f"{key}_mode_s": mode_s,
            f"{key}_best_batch": best,
            **{f"{key}_ms_per_row_b{B}": 1e3 * tb[B][1] for B in batches},
            **{f"{key}_batch{B}_vs_single": single / tb[B][1] for B in BATCHES if B > 1},
            f"{key}_importance{IS_DRAWS}_minutes_est": is_s / 60,
            f"{key}_importance{args.draws}_s_measured": imp_s,
            f"{key}_importance{args.draws}_khat": imp["k_hat"],
            f"{key}_importance{args.draws}_ess": imp["ess"],
            f"{key}_importance{args.draws}_inside_support": inside,
            f"{key}_mcmc_over_importance_tau500": (max(TAU_FACTOR * 500, MIN_STEPS) * W * N_ENSEMBLES * mc_row / is_s),
        }
    )
    return {
        "is_s": is_s,
        "fits": fits,
        "tau_max": steps_budget / TAU_FACTOR,
        "khat": imp["k_hat"],
        "ess": imp["ess"],
    }


def synthetic_tracks(folder: Path, seed: int) -> list:
    """The runs of :data:`SYNTHETIC`: ``bayesid simulate`` of KVLCC2 7 m at 5 Hz, with
    :data:`SYNTHETIC_NOISE` added (velocities logged: step 6 drops them)."""
    from bayesid.cli import main as cli
    from bayesid.data.track import Track, read_csv

    rng = np.random.default_rng(seed)
    out = []
    for i, (kind, angle) in enumerate(SYNTHETIC):
        f = folder / f"run{i}.csv"
        args = ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", kind, "--angle", angle, "--sample", "0.2"]
        if cli([*args, "--no-figure", "--overwrite", "--out", str(f)]) != 0:
            raise RuntimeError(f"bayesid simulate {kind} {angle} failed")
        tr = read_csv(f)
        data = {k: np.asarray(tr[k], float) for k in ("x", "y", "psi", "u", "v", "r", "delta_r", "n")}
        for k, sd in SYNTHETIC_NOISE.items():
            data[k] = data[k] + rng.normal(0.0, sd, tr.t.size)
        out.append(Track(tr.t, data, name=f"{kind}{angle}", meta=tr.meta))
    return out


def without_velocity(tracks) -> list:
    """The same runs with the u, v, r columns dropped (as logged without a velocity log)."""
    from bayesid.data.track import Track

    return [
        Track(t.t, {k: v for k, v in t.data.items() if k not in VELOCITY}, name=t.name, meta=t.meta) for t in tracks
    ]


def _importance_cost(post, mode, n, seed):
    """importance_laplace's wall time per draw and its result (one worker, chunks of 16)."""
    from bayesid.estimation import track_posterior as tp

    t = time.perf_counter()
    imp = tp.importance_laplace(
        post, mode["p"], mode["cov"], np.random.default_rng(seed), tp.ImportanceOptions(n_draws=n)
    )
    return (time.perf_counter() - t) / imp["done"], imp


def bench_velocity_log(key, label, vehicle_id, effects, tracks, args, say, keys):
    """Step 6: the importance stage with and without a velocity log, old and new path, and the
    budget run without one."""
    from bayesid.estimation import track_posterior as tp
    from bayesid.estimation.identification import identify
    from bayesid.estimation.options import FitOptions
    from bayesid.estimation.windows import WindowProblem
    from bayesid.models import load_any_vehicle

    bare = without_velocity(tracks)
    dur = sum(float(tr.t[-1] - tr.t[0]) for tr in tracks)
    say("")
    say(
        f"== {label}: the importance stage with and without a velocity log ({len(tracks)} runs, {dur:.0f} s, "
        f"{1 / float(np.median(np.diff(tracks[0].t))):.0f} Hz) =="
    )
    t = time.perf_counter()
    vehicle = load_any_vehicle(vehicle_id)
    res = identify(vehicle, bare, FitOptions(effects=effects, max_nfev=args.max_nfev, prior=True), calibration=None)
    say(f"  fit without the velocity log (start rule {res.start_rule}): {time.perf_counter() - t:.1f} s")
    model, p0 = res.model, np.asarray(res.fit.p, float)
    # the same scored channels and weights both ways: the velocities only give the start states
    channels = tuple(c for c in ("x", "y", "psi") if c in res.fit_sd)
    posts, imps, times = {}, {}, {}
    for name, runs, rule in (("log", tracks, "measured"), ("no_log", bare, "fitted")):
        problem = WindowProblem(
            model, [model.context(tr, res.window_s, start=rule) for tr in runs], res.fit_sd, channels
        )
        post = tp._track_posterior(problem, p0, True, lambda m: None)[0]
        post.evaluate(p0[None])  # warm-up: compiled kernels loaded
        mode = tp.posterior_mode(post, p0)
        imps[(name, "full")] = _importance_cost(post, mode, args.draws_log, args.seed)[1]
        posts[(name, "full")] = (post, None)
        if rule == "fitted":
            t = time.perf_counter()
            lin = post.linearise_starts(mode["p"], mode["cov"])
            lin_s = time.perf_counter() - t
            imps[(name, "linearised")] = _importance_cost(post, mode, args.draws_log, args.seed)[1]
            posts[(name, "linearised")] = (post, lin)
            full, fast = imps[(name, "full")], imps[(name, "linearised")]
            near = full["log_prob"] > full["log_prob"].max() - 30.0
            dlp = fast["log_prob"] - full["log_prob"]
            say(
                f"  linearisation at the mode: {lin_s:.2f} s; {lin.stats['simulated'] / lin.stats['rows']:.2f} "
                f"simulations per draw, {lin.stats['fallback']} of {lin.stats['rows']} draws fitted fully; log posterior "
                f"minus the full profile's within 30 nats of the best draw: mean {dlp[near].mean():+.4f}, "
                f"{dlp[near].min():+.4f} to {dlp[near].max():+.4f} ({int(near.sum())} draws)"
            )
            keys[f"{key}_linearised_dlp_near_max_abs"] = float(np.max(np.abs(dlp[near])))
            keys[f"{key}_linearised_dlp_near_mean"] = float(dlp[near].mean())
            keys[f"{key}_linearised_simulations_per_draw"] = lin.stats["simulated"] / lin.stats["rows"]
            keys[f"{key}_linearised_fallback_share"] = lin.stats["fallback"] / lin.stats["rows"]
    # the timing: the same 64 proposal draws in chunks of 16 on each path, the paths in turn for
    # --repeats rounds (a passing load hits them alike); the median round
    rows = imps[("no_log", "full")]["draws"][:64]
    for _ in range(max(args.repeats, 1)):
        for k, (post, lin) in posts.items():
            post.linear = lin
            t = time.perf_counter()
            for i in range(0, rows.shape[0], IS_CHUNK):
                post.evaluate(rows[i : i + IS_CHUNK])
            times.setdefault(k, []).append((time.perf_counter() - t) / rows.shape[0])
    sec = {k: float(np.median(v)) for k, v in times.items()}
    base = sec[("log", "full")]
    say(
        f"  per draw: median of {max(args.repeats, 1)} rounds over {rows.shape[0]} proposal draws in chunks of "
        f"{IS_CHUNK}; k-hat and ESS of importance_laplace with {args.draws_log} draws"
    )
    say(f"  {'importance stage':40s} {'ms/draw':>9s} {'/ log':>7s} {'k-hat':>6s} {'ESS':>7s}")
    for (name, path), imp in imps.items():
        what = "velocity log (measured starts)" if name == "log" else f"no velocity log, {path} profile"
        s_ = sec[(name, path)]
        say(f"  {what:40s} {1e3 * s_:9.2f} {s_ / base:7.2f} {imp['k_hat']:6.2f} {imp['ess']:7.0f}")
        tag = "log" if name == "log" else f"no_log_{path}"
        keys[f"{key}_is_ms_per_draw_{tag}"] = 1e3 * s_
        keys[f"{key}_is_khat_{tag}"] = imp["k_hat"]
        keys[f"{key}_is_ess_{tag}"] = imp["ess"]
    keys[f"{key}_no_log_full_over_log"] = sec[("no_log", "full")] / base
    keys[f"{key}_no_log_linearised_over_log"] = sec[("no_log", "linearised")] / base
    keys[f"{key}_linearised_speedup"] = sec[("no_log", "full")] / sec[("no_log", "linearised")]
    if args.budget_minutes:
        problem = WindowProblem(
            model, [model.context(tr, res.window_s, start="fitted") for tr in bare], res.fit_sd, channels
        )
        for path in ("full", "linearised"):
            t = time.perf_counter()
            out = tp.sample_tracks(problem, p0, tp.SampleOptions(max_minutes=args.budget_minutes, start_profile=path))
            wall = time.perf_counter() - t
            cut = [k for k, v in out.budget["stages"].items() if v["cut"]]
            st = ", ".join(
                f"{k} {v['done']}/{v['planned']} {v['unit']} {v['seconds']:.0f} s"
                for k, v in out.budget["stages"].items()
            )
            say(
                f"  sample_tracks --max-minutes {args.budget_minutes:g} without the velocity log, {path} profile: "
                f"{wall:.0f} s wall, method {out.method}, cut: {', '.join(cut) or 'nothing'} ({st}); {out.verdict['text']}"
            )
            keys[f"{key}_budget{args.budget_minutes:g}_wall_s_{path}"] = wall
            keys[f"{key}_budget{args.budget_minutes:g}_importance_done_{path}"] = out.budget["stages"]["importance"][
                "done"
            ]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 runs per set, few iterations: a smoke test")
    ap.add_argument(
        "--sets",
        default=None,
        help="comma-separated: kvlcc2, esso (real data), synthetic (step 6 only); default kvlcc2,esso, or "
        "synthetic without the real data",
    )
    ap.add_argument("--max-nfev", type=int, default=30, help="cap on the fit's least-squares iterations")
    ap.add_argument("--draws", type=int, default=1000, help="draws of the real importance_laplace run")
    ap.add_argument("--draws-log", type=int, default=400, help="draws per path of step 6 (velocity log or not)")
    ap.add_argument(
        "--budget-minutes",
        type=float,
        default=None,
        help="step 6's sample_tracks budget, min (default 2; none with --quick; 0: no budget run)",
    )
    ap.add_argument("--repeats", type=int, default=5, help="timed calls per batch size (median)")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--data", default=str(ROOT / ".." / "shared" / "data" / "real"))
    ap.add_argument("--out", default=None, help="report file (default reports/benchmark_sample.txt; none with --quick)")
    args = ap.parse_args()
    data = Path(args.data)
    real = [s for s in SETS if (data / SETS[s][1]).is_dir()]
    sets = [s for s in (args.sets or (",".join(SETS) if real else "synthetic")).split(",") if s]
    bad = [s for s in sets if s not in SETS and s != "synthetic"]
    if bad:
        ap.error(f"--sets: unknown {', '.join(bad)} (choose from {', '.join(SETS)}, synthetic)")
    missing = [SETS[s][1] for s in sets if s in SETS and s not in real]
    if missing:
        print(f"real data not found ({', '.join(str(data / m) for m in missing)}): nothing to benchmark")
        return 0
    if args.quick:
        args.max_nfev, args.draws, args.repeats = min(args.max_nfev, 4), min(args.draws, 200), min(args.repeats, 2)
        args.draws_log = min(args.draws_log, 100)
    if args.budget_minutes is None:
        args.budget_minutes = 0.0 if args.quick else 2.0
    args.draws_log = max(args.draws_log, 100)
    out = args.out or (None if args.quick else str(ROOT / "reports" / "benchmark_sample.txt"))

    lines: list[str] = []

    def say(m: str) -> None:
        print(m, flush=True)
        lines.append(m)

    t0 = time.perf_counter()
    for h in _header(args):
        say(h)
    keys: dict = {}
    summ = {}
    for s in sets:
        if s == "synthetic":
            import tempfile

            with tempfile.TemporaryDirectory() as tmp:
                runs = synthetic_tracks(Path(tmp), args.seed)
            bench_velocity_log("synthetic", "KVLCC2 7 m, synthetic runs", "kvlcc2_7m", [], runs, args, say, keys)
            continue
        summ[s] = bench_set(s, args, data, say, keys)
        runs = _tracks(data, s, args.quick)
        if all(k in tr for tr in runs for k in VELOCITY):
            bench_velocity_log(s, SETS[s][0], SETS[s][3], SETS[s][4], runs, args, say, keys)
        else:
            say(f"  (no velocity log in every run of {SETS[s][0]}: the with/without comparison is skipped)")
    if summ:
        say("")
        say(f"== verdict ({BUDGET_MIN:g}-minute budget of bayesid sample, this {os.cpu_count()}-core machine) ==")
    for s, r in summ.items():
        say(
            f"  {SETS[s][0]}: importance sampling ({IS_DRAWS} draws, all simulated) {fmt_time(r['is_s'])}: fits; "
            f"MCMC (50 tau) fits only for tau <= {r['tau_max']:.0f} (tau 100 / 500 / 2000: "
            + " / ".join("fits" if f else "no" for f in r["fits"].values())
            + f"; with --jobs 2 at best tau <= {2 * r['tau_max']:.0f}); measured importance k-hat {r['khat']:.2f}, ESS {r['ess']:.0f} of {args.draws} draws"
        )
    say(
        f"  wall time of this benchmark {fmt_time(time.perf_counter() - t0)}; load average at the end "
        + " ".join(f"{v:.2f}" for v in os.getloadavg())
    )
    say("")
    for k, v in keys.items():
        say(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}")
    if out:
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        Path(out).write_text("\n".join(lines) + "\n")
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
