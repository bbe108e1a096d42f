"""Posterior over the coefficients for the paper's Cases 1-3 and a Bayesian Case 3, with an
identifiability dossier: which coefficient combinations the spiral determines, and which it does not.

Method
------
1. Data: the paper's 10-minute spiral simulated with the true NPS AUV II coefficients
   (horizontal-plane mode, RK4 at dt 0.1 s), sampled at 1 s, with Gaussian navigation noise
   added to x, y (0.2 m) and psi (0.2 deg) -- one noisy track shared by all cases.
2. Model: the same equations integrated at dt 1 s (the step-size error over the prior is
   measured and reported; it is orders of magnitude below the noise).
3. Per case: least-squares optimum from the case's start, its Laplace covariance, then the
   posterior with :data:`N_ENSEMBLES` independent emcee ensembles (DE moves) started in a
   Laplace-shaped ball and run until the convergence verdict holds (or the case's budget),
   HDF5 checkpoints (re-running resumes), ArviZ diagnostics.
   Priors: uniform within the case bounds (the paper's setting); the Bayesian Case 3 ("case3b")
   adds the towing-tank ("known") coefficients as Gaussian nuisance parameters centred on their
   perturbed values with 1 % standard deviation.
4. Dossier at the optimum: relative sensitivities, Fisher information, eigen-directions,
   collinearity indices, relative influence, structural nulls (checked by simulation), the
   posterior spread along each Fisher direction against its Cramer-Rao prediction.

    python studies/posterior.py [--quick] [--out DIR] [--seed N] [--cases 2,1,3,3b] [--jobs N] [--scheduler ADDRESS]

The cases are tasks of :mod:`bayesid.tasks`: ``--jobs 1`` (the default) samples one case at a time
with every core for the batched simulations, which on 2 cores beats two cases side by side;
on a cluster (``--scheduler``) the cases run at once. With ``--ensembles-as-tasks`` the cases run
one after another and the ensembles of each case run at once as tasks instead (the same chains,
bit for bit). Each case resumes from its own checkpoint.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from bayesid import cases
from bayesid.analysis.dossier import ROUND_OFF, direction_convergence, dossier
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation import sampling
from bayesid.estimation.fit import SolverOptions
from bayesid.estimation.fit import fit as fit_problem
from bayesid.estimation.objective import Problem
from bayesid.estimation.posterior import (
    CoefficientPrior,
    LogPosterior,
    add_noise,
    laplace_covariance,
    laplace_start,
    marginal_table,
    prior_sd,
    top_correlations,
)
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator
from bayesid.report import fmt, md_table, plots, prepare_out, write_json, write_manifest
from bayesid.tasks import Runner, Task, TaskError, add_arguments, parse_checked, run_tasks

NOISE = {"x": 0.2, "y": 0.2, "psi": math.radians(0.2)}  # realistic navigation noise (m, m, rad)
CHANNELS = ("x", "y", "psi")
DT_TRUTH, DT_MODEL, SAMPLE_S = 0.1, 1.0, 1.0
START_MARGIN = 0.05  # walkers' centre at least this fraction of the prior width inside the bounds
KNOWN_SD = 0.01  # Bayesian Case 3: relative sd of the towing-tank values
LEVEL = 0.9  # credible interval shown: central (equal-tailed) 90 %
DETERMINED = 0.5  # a direction is "determined" when its Cramer-Rao sd < this x prior sd along it
CASE_KEYS = ("case2", "case1", "case3", "case3b")
#: Sampling budget per case, minutes: a cap, as each case stops when its chains converge
#: (issue 23's target for Case 2: converged in under 5 minutes). Case 1's 24 coefficients have
#: tau ~ 2200 steps (the last run): the per-walker R-hat <= 1.01 needs ~250000 steps of its
#: 2 x 50 walkers at ~9000 evaluations/s, ~47 minutes.
BUDGET_MIN = {"case2": 14.0, "case1": 55.0, "case3": 8.0, "case3b": 20.0}
#: Independent ensembles. The verdict's per-walker R-hat falls as 1/(steps per walker), and a
#: step of every walker costs the same whatever the split, so fewer, longer ensembles converge
#: sooner: on Case 2 (benchmarks/posterior.py, reports/benchmark_posterior.txt) 2 ensembles of
#: 30 walkers reached per-walker R-hat 1.010 after 2.2 min, 4 ensembles 1.019 after 3.4 min.
#: Two keep a between-ensemble R-hat.
N_ENSEMBLES = 2
#: Per-case keys repeated at the top level of results.json (issue 9's list).
SUMMARY_KEYS = (
    "rhat_max",
    "ess_bulk_min",
    "ess_tail_min",
    "tau_max",
    "n_steps",
    "acceptance_mean",
    "correlation",
    "sloppiest_direction",
    "fim_condition_number",
    "coverage_90",
    "converged",
    "wall_s",
)


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="50 steps per case (a smoke test)")
    ap.add_argument("--out", default="reports/posterior")
    ap.add_argument("--seed", type=int, default=2003)
    ap.add_argument(
        "--cases",
        default=",".join(k.removeprefix("case") for k in CASE_KEYS),
        help="comma-separated subset of 1,2,3,3b",
    )
    ap.add_argument(
        "--fresh",
        action="store_true",
        help="delete the checkpoints of the cases run and sample anew (default: resume or re-report)",
    )
    ap.add_argument(
        "--extend",
        action="store_true",
        help="sample further from finished checkpoints (default: re-report their chains)",
    )
    ap.add_argument(
        "--tau-factor",
        type=float,
        default=50.0,
        help="run at least this many autocorrelation times (emcee's rule), then on until the convergence verdict holds",
    )
    ap.add_argument("--max-minutes", type=float, default=None, help=f"wall-time budget per case (default {BUDGET_MIN})")
    add_arguments(ap)  # cases in parallel: on 2 cores one case at a time with both cores is faster
    ap.add_argument(
        "--ensembles-as-tasks",
        action="store_true",
        help="sample the cases one after another and run each case's ensembles as tasks on --jobs / "
        "--scheduler instead (a cluster with more workers than cases)",
    )
    return parse_checked(ap)


@dataclass
class Setup:
    key: str
    case: cases.Case
    names: list  # sampled coefficients (free, then nuisance)
    nuisance: list  # Gaussian-prior coefficients (Bayesian Case 3)
    prior: CoefficientPrior
    truth: dict  # name -> true value for every sampled name
    reference: np.ndarray  # scaling reference of the Problem


def make_setups(vehicle, rng, keys) -> dict:
    built = {n: cases.make_case(n, vehicle, rng) for n in (1, 2, 3)}  # drawn in a fixed order
    out = {}
    for key in keys:
        number = int(key[4])
        c = built[number]
        nuis = list(c.known) if key == "case3b" else []
        uniform = {n: (c.lower[n], c.upper[n]) for n in c.free}
        normal = {n: (c.known_values[n], KNOWN_SD * abs(c.known_values[n])) for n in nuis}
        prior = CoefficientPrior.build(uniform=uniform, normal=normal)
        names = list(c.free) + nuis
        ref = np.array([c.start[n] for n in c.free] + [c.known_values[n] for n in nuis])
        out[key] = Setup(key, c, names, nuis, prior, {n: c.true[n] for n in names}, ref)
    return out


def optimum(setup, vehicle, spiral, target, quick):
    """Least-squares optimum of the free coefficients (nuisance at their prior means), and the
    walkers' centre: the optimum again within bounds pulled in by ``START_MARGIN`` of the prior
    width, so that a ball around it lies inside the prior AND on the ridge of the likelihood
    (moving an at-bound optimum inside without refitting leaves the ball off the ridge, and a few
    walkers then take thousands of steps to arrive)."""
    c = setup.case
    sim = Simulator(
        c.vehicle(vehicle), spiral, free=c.free, mode="horizontal", sample_every=int(round(SAMPLE_S / spiral.dt))
    )
    pb = Problem(sim, target, c.reference(), channels=CHANNELS)
    lo, hi = c.scaled_bounds()
    fit = fit_problem(pb, np.ones(len(c.free)), (lo, hi), SolverOptions(max_nfev=40 if quick else 300))
    m = START_MARGIN * (hi - lo)
    inner = fit_problem(
        pb, np.clip(fit.p, lo + m, hi - m), (lo + m, hi - m), SolverOptions(max_nfev=20 if quick else 100)
    )

    def full(theta_free):
        th = dict(zip(c.free, theta_free))
        th.update({n: c.known_values[n] for n in setup.nuisance})
        return np.array([th[n] for n in setup.names])

    return full(fit.theta), full(inner.theta), fit


def step_size_error(vehicle, setup, draws, fine_dt=0.05):
    """Largest position difference (m) between the model's dt and ``fine_dt`` over ``draws``."""
    c = setup.case
    err = []
    for dt in (DT_MODEL, fine_dt):
        sp = mv.spiral(vehicle, dt=dt)
        sim = Simulator(
            c.vehicle(vehicle), sp, free=setup.names, mode="horizontal", sample_every=int(round(SAMPLE_S / dt))
        )
        err.append(sim.run(draws).states[:, :, :2])
    return float(np.nanmax(np.hypot(*(err[0] - err[1]).transpose(2, 0, 1))))


def run_case(setup, vehicle, spiral_model, target, args, out, rng):
    t0 = time.perf_counter()
    c = setup.case
    sim = Simulator(
        c.vehicle(vehicle),
        spiral_model,
        free=setup.names,
        mode="horizontal",
        sample_every=int(round(SAMPLE_S / DT_MODEL)),
    )
    problem = Problem(sim, target, setup.reference, channels=CHANNELS)
    logpost = LogPosterior(problem, NOISE, setup.prior)
    theta_hat, theta_in, fit = optimum(setup, vehicle, spiral_model, target, args.quick)
    cov = laplace_covariance(problem, theta_hat, NOISE, setup.prior)
    centre, cov0 = laplace_start(theta_in, cov, setup.prior, margin=START_MARGIN)
    cfg = sampling.SamplerConfig(
        n_ensembles=N_ENSEMBLES,
        moves="de",
        tau_factor=args.tau_factor,
        progress=not args.quick,
        until_converged=not args.quick,
        redraw_stranded=True,
        check_every=25 if args.quick else 250,
        min_steps=50 if args.quick else 1000,
        max_steps=50 if args.quick else 400000,
        max_wall_s=60.0 * (args.max_minutes or BUDGET_MIN[setup.key]),
    )
    ck = out / "checkpoints"
    ck.mkdir(exist_ok=True)
    ckfile = ck / f"{setup.key}{'_quick' if args.quick else ''}.h5"
    done = ckfile.with_suffix(".done.json")
    if args.fresh:
        for f in (ckfile, done):
            f.unlink(missing_ok=True)
    stored = json.loads(done.read_text()) if done.exists() and not args.extend else None
    if stored:  # a finished run: report its chains again, do not sample more
        cfg.max_steps = int(stored["n_steps"])
        cfg.min_steps = min(cfg.min_steps, cfg.max_steps)
    n_eval0 = logpost.n_evaluations
    t_s = time.perf_counter()
    run_key = {
        "seed": args.seed,
        "quick": bool(args.quick),
        "case": setup.key,
        "target_sha256": hashlib.sha256(
            np.ascontiguousarray(np.column_stack([target.t] + [target[k] for k in target.state_columns])).tobytes()
        ).hexdigest(),
    }
    stored_key = stored.get("run_key") if stored else None
    if stored and stored_key is not None and stored_key != run_key:
        raise ValueError(f"{done}: finished under {stored_key}, not {run_key}; pass --fresh or another --out")
    where = {"jobs": args.jobs, "scheduler": args.scheduler} if args.ensembles_as_tasks else {}
    result = sampling.run_ensembles(
        logpost,
        centre,
        cov0,
        setup.names,
        cfg,
        rng,
        checkpoint=sampling.Checkpoint(ckfile, run_key),
        runner=Runner(**where),
    )
    sample_s = sampled_s = time.perf_counter() - t_s
    # rows evaluated on workers count in the result, not in this process's log posterior
    n_new = result.n_evaluations if where else logpost.n_evaluations - n_eval0
    evals_per_s = n_new / sample_s if n_new else None
    if stored:  # timing and stop reason of the run that drew the chains
        sample_s, evals_per_s = stored["sampling_wall_s"], stored["log_prob_evals_per_s"]
        result.stop_reason, result.n_evaluations = stored["stop_reason"], stored["n_evaluations"]
    elif n_new:
        done.write_text(
            json.dumps(
                dict(
                    n_steps=result.n_steps,
                    sampling_wall_s=sample_s,
                    log_prob_evals_per_s=evals_per_s,
                    stop_reason=result.stop_reason,
                    n_evaluations=result.n_evaluations,
                    run_key=run_key,
                )
            )
        )
    # burn-in: 2 tau, or longer until the last stranded walker has reached the typical set
    burn = sampling.burn_in(result)
    idata = sampling.to_inference_data(result, burn=burn, truth=setup.truth)
    diag = sampling.diagnostics(idata, result)
    samples = result.chains[:, burn:].reshape(-1, len(setup.names))
    # thinned copy for the netCDF file, 25 draws per walker (the diagnostics above use every draw)
    thin = max(1, int(result.n_steps - burn) // 25)
    sampling.to_inference_data(result, burn=burn, thin=thin, truth=setup.truth).to_netcdf(
        out / f"posterior_{setup.key}.nc"
    )

    marg = marginal_table(samples, setup.names, setup.prior, setup.truth, level=LEVEL)
    for r, k, a, b in zip(marg, setup.prior.kind, setup.prior.a, setup.prior.b):
        r["prior_lo"], r["prior_hi"] = (a, b) if k == "uniform" else (a - 2 * b, a + 2 * b)
    dos = dossier(
        problem,
        theta_hat,
        prior_sd(setup.prior),
        [setup.truth[n] for n in setup.names],
        vehicle,
        samples,
        NOISE,
        determined=DETERMINED,
    )
    determined = np.array([d["determined"] for d in dos["directions"]])
    conv_dirs = direction_convergence(result, burn, dos["W"], theta_hat, determined)
    idx = np.random.default_rng(0).choice(samples.shape[0], size=min(64, samples.shape[0]), replace=False)
    dt_err = step_size_error(vehicle, setup, samples[idx])

    C = np.corrcoef(samples, rowvar=False)
    fig = out / "figures"
    worst = sorted(setup.names, key=lambda n: -diag["rhat"][n])[:6]
    plots.walker_traces(
        result.chains,
        setup.names,
        worst,
        fig / f"trace_{setup.key}.png",
        burn=burn,
        truth=setup.truth,
        title=f"{setup.key}: walker traces, six largest R-hat",
    )
    E, _, Wk, _ = result.chains.shape
    pooled = {n: result.chains[:, burn:, :, j].reshape(E, -1) for j, n in enumerate(setup.names) if n in worst}
    plots.rank_histograms(
        pooled,
        fig / f"rank_{setup.key}.png",
        title=f"{setup.key}: rank plots, each ensemble's pooled draws as one chain",
    )
    corr = top_correlations(samples, setup.names, k=10)
    pairs = [tuple(k.split("–")) for k in list(corr)[:3]]
    if "Xvr" in setup.names and "Xrr" in setup.names and {"Xvr", "Xrr"} not in [set(p) for p in pairs]:
        pairs.append(("Xvr", "Xrr"))
    bounds = {
        n: (a, b) for n, k, a, b in zip(setup.names, setup.prior.kind, setup.prior.a, setup.prior.b) if k == "uniform"
    }
    plots.pair_scatter(
        samples,
        setup.names,
        pairs,
        fig / f"pairs_{setup.key}.png",
        truth=setup.truth,
        bounds=bounds,
        title=f"{setup.key}: most correlated pairs (dashed: prior box; star: truth)",
    )
    plots.correlation_heatmap(
        C, setup.names, fig / f"correlation_{setup.key}.png", title=f"{setup.key}: posterior correlation"
    )
    plots.marginals_vs_truth(
        marg,
        fig / f"marginals_{setup.key}.png",
        title=f"{setup.key}: posterior mean and {100 * LEVEL:.0f} % interval / truth",
    )

    coverage = float(np.mean([r["covers"] for r in marg]))
    sl = dos["sloppiest"]
    return dict(
        description=c.description
        + (
            f" Known coefficients sampled with Gaussian priors (mean: the perturbed value; sd {100 * KNOWN_SD:g} %)."
            if setup.nuisance
            else ""
        ),
        n_params=len(setup.names),
        names=setup.names,
        nuisance=setup.nuisance,
        rhat_max=diag["rhat_max"],
        ess_bulk_min=diag["ess_bulk_min"],
        ess_tail_min=diag["ess_tail_min"],
        tau_max=diag["tau_max"],
        n_steps=diag["n_steps"],
        acceptance_mean=diag["acceptance_mean"],
        correlation=corr,
        sloppiest_direction=sl.weights(0.05),
        sloppiest_label=sl.label(),
        fim_condition_number=dos["fim_condition_number"],
        coverage_90=coverage,
        converged=diag["converged"],
        wall_s=time.perf_counter() - t0 - sampled_s + sample_s,
        verdict=diag["verdict"],
        rhat_ensembles_max=diag["rhat_ensembles_max"],
        convergence_by_direction=conv_dirs,
        stop_reason=result.stop_reason,
        n_walkers=Wk,
        n_ensembles=E,
        burn=burn,
        n_draws=diag["n_draws"],
        redraws=[list(r) for r in result.redraws],
        sampling_wall_s=sample_s,
        log_prob_evals_per_s=evals_per_s,
        n_evaluations=result.n_evaluations,
        step_size_error_m=dt_err,
        optimum=dict(zip(setup.names, theta_hat.tolist())),
        optimum_cost=fit.cost,
        optimum_at_bound=fit.at_bound,
        marginals=marg,
        rhat=diag["rhat"],
        ess_bulk=diag["ess_bulk"],
        ess_tail=diag["ess_tail"],
        mcse_mean=diag["mcse_mean"],
        dossier={k: v for k, v in dos.items() if k not in ("F", "lam", "W", "sloppiest")},
        fim_eigenvalues=dos["lam"].tolist(),
        relative_prior_sd=float(np.sqrt(np.mean((prior_sd(setup.prior) / np.abs(theta_hat)) ** 2))),
    )


def vr_coupling(track) -> float:
    """Correlation of v and r over the turning part of a track (paper point 4)."""
    v, r = track["v"], track["r"]
    on = np.abs(r) > 1e-6
    return float(np.corrcoef(v[on], r[on])[0, 1])


def write_report(out, res, args, target_info):
    L = ["# Posterior over the coefficients and the identifiability dossier", ""]
    L += [
        f"Run: {'quick' if args.quick else 'full'}, seed {args.seed}. Everything below comes from this run "
        f"(`results.json`, `manifest.json`); chains resumed from a checkpoint were drawn under the same seed "
        "and data (the checkpoint records them and refuses another run's)."
        + (
            f" Cases of the previous report not re-run now, dropped: {', '.join(target_info['dropped_cases'])}."
            if target_info.get("dropped_cases")
            else ""
        ),
        "",
    ]
    L += [
        "## Setup",
        "",
        f"- Data: the paper's spiral ({target_info['description']}) simulated with the true NPS AUV II "
        f"coefficients at dt {DT_TRUTH} s, sampled every {SAMPLE_S:g} s ({target_info['n_samples']} samples), "
        f"with Gaussian noise sd {NOISE['x']} m on x and y and {math.degrees(NOISE['psi']):.2g} deg on psi.",
        f"- Model: the same equations at dt {DT_MODEL} s. Measured step-size error (largest position "
        f"difference against dt 0.05 s, 64 posterior draws per case): "
        + ", ".join(f"{k} {fmt(v['step_size_error_m'])} m" for k, v in res.items())
        + ".",
        "- Likelihood: independent Gaussian errors on x, y, psi with the noise sd above (known).",
        "- Priors: uniform within each case's bounds (the paper's); in case3b the towing-tank coefficients "
        f"are Gaussian nuisance parameters (mean: the perturbed value used in Case 3, sd {100 * KNOWN_SD:g} %).",
        f"- Sampler: emcee, {N_ENSEMBLES} independent ensembles, 2P+2 walkers each, differential-evolution "
        "moves (DE 0.8 + snooker 0.2), started in a Laplace-shaped ball around the least-squares optimum; "
        f"run until the convergence verdict below holds (at least {args.tau_factor:g} autocorrelation times, "
        "per-walker R-hat <= 1.01, bulk and tail ESS >= 400; checked each time the run has grown by 15 %) "
        "or the case's budget ("
        + ", ".join(f"{k} {args.max_minutes or BUDGET_MIN[k]:g} min" for k in res)
        + "). The ensemble "
        "count, moves and walkers come from `benchmarks/posterior.py` (`reports/benchmark_posterior.txt`). "
        "Walkers stranded in the tails (highest log-probability over the last quarter of the run "
        "since the last such move more than 10 robust sigmas below the median) are moved onto "
        "randomly chosen walkers of their ensemble at the 250-step checks (at most a quarter of an "
        "ensemble at once; `sampling.stranded_walkers`); the draws before the last move are burn-in. "
        "Burn-in: the longest of 2 tau, the last move, and the arrival of the last walker in the "
        "typical set (log-probability above the median less 10 robust sigmas of the second half; at "
        "most half the run; `sampling.burn_in`). Checkpoints in `checkpoints/` (not committed): an interrupted run resumes; a finished case is "
        "re-reported from its chains (with the sampling time of the run that drew them) unless `--extend`. "
        "`posterior_<case>.nc`: ArviZ InferenceData after burn-in, thinned to 25 draws per walker.",
        f"- Interval shown: central (equal-tailed) {100 * LEVEL:.0f} % credible interval. R-hat: "
        "rank-normalised split R-hat with every walker as a chain (the verdict); also with each "
        "ensemble's pooled draws as one chain.",
        "",
    ]
    L += ["## Convergence", ""]
    hdr = [
        "case",
        "P",
        "walkers",
        "steps",
        "burn-in",
        "moved",
        "tau max",
        "R-hat max",
        "R-hat (ensembles)",
        "bulk ESS min",
        "tail ESS min",
        "accept.",
        "evals/s",
        "sampling, min",
        "wall, min",
        "converged",
    ]
    rows = [
        [
            k,
            v["n_params"],
            f"{v['n_ensembles']}x{v['n_walkers']}",
            v["n_steps"],
            v["burn"],
            len(v.get("redraws", [])),
            fmt(v["tau_max"]),
            fmt(v["rhat_max"], 4),
            fmt(v["rhat_ensembles_max"], 4),
            fmt(v["ess_bulk_min"]),
            fmt(v["ess_tail_min"]),
            fmt(v["acceptance_mean"]),
            fmt(v["log_prob_evals_per_s"]),
            fmt(v["sampling_wall_s"] / 60),
            fmt(v["wall_s"] / 60),
            "yes" if v["converged"] else "no",
        ]
        for k, v in res.items()
    ]
    L += [
        md_table(hdr, rows),
        "",
        "`moved`: stranded walkers moved onto other walkers (the draws up to the last move are part of "
        "the burn-in); `sampling, min`: the sampler's wall time, the target of issue 23 (Case 2 under 5 "
        "min); `wall, min`: the whole case, optimum, dossier and report included.",
        "",
    ]
    for k, v in res.items():
        cd = v["convergence_by_direction"]
        L += [
            f"- **{k}**: {v['verdict']} Stopped by: {v['stop_reason']}. Along the "
            f"{cd['determined']['n']} Fisher directions the data determine (Cramér–Rao sd < {DETERMINED} x prior sd): "
            f"R-hat max {fmt(cd['determined']['rhat_max'], 4)}, bulk ESS min {fmt(cd['determined']['ess_bulk_min'])}; "
            f"along the {cd['undetermined']['n']} others (posterior = prior box): R-hat max "
            f"{fmt(cd['undetermined']['rhat_max'], 4)}, bulk ESS min {fmt(cd['undetermined']['ess_bulk_min'])}."
        ]
    L += ["", "Figures: `figures/trace_<case>.png`, `figures/rank_<case>.png`.", ""]
    L += ["## Marginals against truth", ""]
    for k, v in res.items():
        L += [
            f"### {k} (coverage of the {100 * LEVEL:.0f} % intervals: {100 * v['coverage_90']:.0f} %)",
            "",
            f"![marginals](figures/marginals_{k}.png)",
            "",
        ]
        hdr = ["coefficient", "truth", "mean", "sd", "90 % interval", "mean/truth", "sd/prior sd", "holds truth"]
        rows = [
            [
                r["name"],
                fmt(r["truth"]),
                fmt(r["mean"]),
                fmt(r["sd"]),
                f"[{fmt(r['lower'])}, {fmt(r['upper'])}]",
                fmt(r["mean_ratio"]),
                fmt(r["sd_over_prior"]),
                "yes" if r["covers"] else "**no**",
            ]
            for r in v["marginals"]
        ]
        L += [md_table(hdr, rows), ""]
    L += ["## Identifiability dossier", "", "![FIM spectra](figures/fim_spectra.png)", ""]
    for k, v in res.items():
        d = v["dossier"]
        L += [
            f"### {k}",
            "",
            f"- Fisher information condition number {fmt(v['fim_condition_number'])}; smallest/largest eigenvalue "
            f"{fmt(d['lam_ratio_min'])}. " + _sloppiest_sentence(v, d),
            f"- Widest posterior axis: `{d['posterior_axis_widest']}` "
            f"({fmt(d['angle_sloppiest_vs_widest_posterior_axis_deg'])} deg from the sloppiest Fisher direction); "
            f"narrowest: `{d['posterior_axis_narrowest']}` "
            f"({fmt(d['angle_stiffest_vs_narrowest_posterior_axis_deg'])} deg from the stiffest).",
            "",
        ]
        hdr = ["Fisher direction (relative changes)", "Cramér–Rao sd", "posterior sd", "prior sd", "determined"]
        rows = [
            [
                f"`{r['direction']}`",
                fmt(r["cramer_rao_sd"]),
                fmt(r["posterior_sd"]),
                fmt(r["prior_sd"]),
                "round-off" if r.get("round_off") else ("yes" if r["determined"] else "no"),
            ]
            for r in d["directions"]
        ]
        L += [
            "Spread along each Fisher eigen-direction, sloppiest first (relative units: 0.01 = 1 %):",
            "",
            md_table(hdr, rows),
            "",
        ]
        if d["structural_nulls"]:
            L += ["Structural (exact) null directions, each checked by moving the true coefficients 2 % along it:", ""]
            hdr = ["direction", "cause", "track change, m", "posterior sd", "prior sd"]
            rows = [
                [
                    f"`{s['direction']}`",
                    s["cause"],
                    fmt(s["track_change_m"]),
                    fmt(s["posterior_sd"]),
                    fmt(s["prior_sd"]),
                ]
                for s in d["structural_nulls"]
            ]
            L += [
                md_table(hdr, rows),
                "",
                f"{d['n_round_off_eigenvalues']} Fisher eigenvalues are at round-off level (below {ROUND_OFF:g} x the "
                f"largest). Principal angles between these nulls and the span of those eigenvectors: "
                f"{', '.join(fmt(a) for a in d['structural_null_fim_angles_deg'])} deg (near 0: the nulls lie in "
                f"the numerically null space; more round-off eigenvalues than structural nulls = further exact "
                f"dependences on this data, e.g. Y<->N mixing where v*r <= 0 throughout the spiral).",
                "",
            ]
        else:
            L += [
                "No structural null direction for this free set (no equation-row transformation is "
                "representable by the free coefficients).",
                "",
            ]
        L += [f"![pairs](figures/pairs_{k}.png)", "", f"![correlation](figures/correlation_{k}.png)", ""]
        L += [
            "Strongest posterior correlations: " + ", ".join(f"{p} {c:+.3f}" for p, c in v["correlation"].items()),
            "",
        ]
        hdr = ["subset", "collinearity index"]
        rows = [[", ".join(r["subset"]), fmt(r["gamma"])] for r in d["collinearity"]]
        L += [
            "Most collinear subsets (Brun et al. 2001; > 10-15 = practically non-identifiable):",
            "",
            md_table(hdr, rows),
            "",
        ]
    L += answers(res, target_info)
    (out / "report.md").write_text("\n".join(L) + "\n")


def answers(res, target_info) -> list:
    """The paper's points (2)-(4) answered with this run's numbers."""
    L = ["## The paper's points (2)-(4), in numbers", ""]
    c2 = res.get("case2") or next(iter(res.values()))
    c1 = res.get("case1")
    if c1:
        d = c1["dossier"]
        worst = d["collinearity"][0]
        L += [
            f"**(2) Y and N coefficients as linear combinations of the others.** Case 1 has "
            f"{len(d['structural_nulls'])} exact null directions; moving 2 % along them changes the track by at most "
            f"{fmt(max([s['track_change_m'] for s in d['structural_nulls']] or [0]))} m. They are rescalings of whole "
            f"equation rows (" + "; ".join(s["cause"] for s in d["structural_nulls"]) + "), so the dependence is "
            "exact, not a near-miss: the likelihood is flat along them, and the posterior spread along them "
            "(sd " + ", ".join(f"{fmt(s['posterior_sd'])}" for s in d["structural_nulls"]) + ") is set by the "
            "prior box where it meets the determined combinations (unconditioned prior sd "
            + ", ".join(f"{fmt(s['prior_sd'])}" for s in d["structural_nulls"])
            + ")"
            + f". Largest collinearity index in Case 1: {fmt(worst['gamma'])} "
            f"({', '.join(worst['subset'])}).",
            "",
        ]
    infl = c2["dossier"]["relative_influence"]
    order = sorted(infl, key=infl.get)
    marg = {r["name"]: r for r in c2["marginals"]}
    key2 = "case2" if "case2" in res else next(iter(res))
    L += [
        f"**(3) Small-effect coefficients.** Relative influence on the track ({key2}; RMS change of the "
        f"noise-scaled track per 100 % change): smallest "
        + ", ".join(f"{n} {fmt(infl[n])}" for n in order[:4])
        + "; largest "
        + ", ".join(f"{n} {fmt(infl[n])}" for n in order[-3:])
        + ". The posterior follows: sd/prior sd is "
        + ", ".join(f"{n} {fmt(marg[n]['sd_over_prior'])}" for n in order[:4])
        + " for the smallest and "
        + ", ".join(f"{n} {fmt(marg[n]['sd_over_prior'])}" for n in order[-3:])
        + " for the largest.",
        "",
    ]
    corr = {}
    for k, v in res.items():
        C = {tuple(p.split("–")): r for p, r in v["correlation"].items()}
        for pair in (("Xvr", "Xrr"), ("Xrr", "Xvr")):
            if pair in C:
                corr[k] = C[pair]
    L += [
        f"**(4) v-r coupling and cancellation.** On the spiral corr(v, r) = {target_info['corr_vr']:+.4f}, so "
        f"terms in rr, vr and vv move together. "
        + (
            "Posterior correlation Xvr–Xrr (when among the ten strongest): "
            + ", ".join(f"{k} {c:+.3f}" for k, c in corr.items())
            + ". "
            if corr
            else "Xvr–Xrr is not among the ten strongest posterior correlations in any case. "
        )
        + f"The sloppiest Fisher direction of {key2} is `{c2['sloppiest_label']}`.",
        "",
    ]
    return L


def _sloppiest_sentence(v: dict, d: dict) -> str:
    """The sloppiest Fisher direction, or, when the smallest eigenvalues are at round-off level,
    the round-off null space they span: its individual eigenvectors are any basis of it (the last
    bits of a simulation pick one), so only the subspace is reported as a result."""
    k = d["n_round_off_eigenvalues"]
    if not k:
        return f"Sloppiest direction: `{v['sloppiest_label']}`."
    part = ", ".join(f"{n} {w:.2f}" for n, w in d["round_off_participation"].items())
    return (
        f"The {k} sloppiest directions are at round-off level: the {k}-dimensional null space they span "
        f"is reproducible, while its individual eigenvectors (rows marked round-off below) are any "
        f"basis of it and change with the last bits of the simulation. How much each coefficient lies in "
        f"that space (1 = wholly, sum = {k}): {part}."
    )


def main():
    import matplotlib

    matplotlib.use("Agg")  # the study writes its figures, it never shows them
    args = parse_args()
    t_start = time.perf_counter()
    out = prepare_out(args.out)
    rng = np.random.default_rng(args.seed)
    keys = [f"case{k.strip()}" for k in args.cases.split(",")]
    bad = [k for k in keys if k not in CASE_KEYS]
    if bad:
        raise SystemExit(f"unknown case(s) {bad}; choose from 1, 2, 3, 3b")

    vehicle = load_vehicle("nps_auv2")
    spiral_truth = mv.spiral(vehicle, dt=DT_TRUTH)
    spiral_model = mv.spiral(vehicle, dt=DT_MODEL)
    clean = (
        Simulator(vehicle, spiral_truth, mode="horizontal", sample_every=int(round(SAMPLE_S / DT_TRUTH)))
        .run()
        .track(0, name="spiral")
    )
    target = add_noise(clean, NOISE, np.random.default_rng([args.seed, 1]))
    info = dict(description=spiral_truth.description, n_samples=target.n_samples, corr_vr=vr_coupling(clean))
    setups = make_setups(vehicle, rng, keys)
    for key in keys:
        print(f"[posterior] {key}: {len(setups[key].names)} coefficients", flush=True)
    # each case resumes from its own HDF5 checkpoint, so the cases need no journal of their own
    tasks = [
        Task(
            key,
            {"case": key},
            (setups[key], vehicle, spiral_model, target, args, out, np.random.default_rng([args.seed, 100 + i])),
        )
        for i, key in enumerate(keys)
    ]

    def done(task, r, seconds):
        if not isinstance(r, TaskError):
            print(
                f"  {task.key}: R-hat {r['rhat_max']:.4f}, ESS {r['ess_bulk_min']:.0f}, tau {r['tau_max']:.1f}, "
                f"{r['n_steps']} steps, {fmt(r['log_prob_evals_per_s'])} evals/s, {r['wall_s']:.0f} s",
                flush=True,
            )

    if args.ensembles_as_tasks:
        outs = run_tasks(run_case, tasks, on_done=done)
    else:
        outs = run_tasks(run_case, tasks, Runner(jobs=args.jobs, scheduler=args.scheduler), on_done=done)
    failed = [o for o in outs if isinstance(o, TaskError)]
    if failed:  # a checkpoint of another run, a bad option: named, after the other cases finished
        raise ValueError("; ".join(str(f) for f in failed))
    results = dict(zip(keys, outs))

    dropped = []
    if (out / "results.json").exists():
        try:
            dropped = [k for k in json.loads((out / "results.json").read_text()).get("cases", {}) if k not in results]
        except ValueError:
            dropped = []
    if dropped:
        print(
            f"[posterior] cases {', '.join(dropped)} of the previous report in {out} are not in this run and are "
            "dropped from its report (their checkpoints remain)",
            flush=True,
        )
    info["dropped_cases"] = dropped
    spectra = {k: v["fim_eigenvalues"] for k, v in results.items()}
    plots.fim_spectra(
        spectra,
        out / "figures" / "fim_spectra.png",
        prior_level={k: v["relative_prior_sd"] for k, v in results.items()},
        title="Fisher information at the optimum (dashed: RMS relative prior sd)",
    )
    write_json(
        out / "results.json",
        dict(
            noise_sd=dict(x_m=NOISE["x"], y_m=NOISE["y"], psi_deg=math.degrees(NOISE["psi"])),
            dt_model_s=DT_MODEL,
            dt_truth_s=DT_TRUTH,
            sample_s=SAMPLE_S,
            credible_interval=f"central {LEVEL:.0%}",
            corr_vr_spiral=info["corr_vr"],
            cases=results,
            **{k: {f: v[f] for f in SUMMARY_KEYS} for k, v in results.items()},
        ),
    )
    write_report(out, results, args, info)
    write_manifest(
        out,
        seed=args.seed,
        quick=args.quick,
        t_start=t_start,
        extra=dict(log_prob_evals_per_s={k: v["log_prob_evals_per_s"] for k, v in results.items()}),
    )
    print(f"[posterior] wrote {out} in {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    try:
        main()
    except ValueError as e:  # a checkpoint of another run, a bad option: a message, not a traceback
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)
