"""Posterior sampling speed on the paper's Case 2: emcee's default stretch move against the
configuration the study uses (differential-evolution moves), each in coefficient space and in the
unconstrained (logit) space of :class:`bayesid.estimation.posterior.TransformedLogPosterior`, in
one run.

For each move set the same 4 ensembles x 30 walkers start from the same Laplace-shaped ball on the
same noisy spiral (studies/posterior.py's setup); the run is extended in blocks through its HDF5
checkpoint (resume), and after each block the benchmark prints what was reached so far: steps,
minutes, tau, per-walker R-hat (the verdict's), between-ensemble R-hat, minimum bulk ESS, ESS per
minute, and log-probability evaluations per second. Chains sampled in logit space are mapped back
to the coefficients before the diagnostics (R-hat and ESS are rank-normalised, so the map does not
change them); tau is the sampler's, in the space it samples.

    python benchmarks/posterior.py [--minutes 6] [--block 500] [--out reports/benchmark_posterior.txt]
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "studies"))
import posterior as study  # noqa: E402  (the study's setup, so both measure the same problem)

from bayesid.models import manoeuvres as mv
from bayesid.estimation import sampling  # noqa: E402
from bayesid.estimation.objective import Problem  # noqa: E402
from bayesid.estimation.posterior import (LogPosterior, TransformedLogPosterior, add_noise,  # noqa: E402
                                         laplace_covariance, laplace_start)
from bayesid.models.simulate import Simulator  # noqa: E402
from bayesid.data.vehicle import load_vehicle  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=6.0, help="wall budget per move set")
    ap.add_argument("--block", type=int, default=500, help="steps between reports")
    ap.add_argument("--seed", type=int, default=2003)
    ap.add_argument("--out", default=str(ROOT / "reports" / "benchmark_posterior.txt"))
    ap.add_argument("--sets", default="stretch,de,stretch-logit,de-logit",
                    help="move sets, each optionally -logit (sampled in the unconstrained space)")
    args = ap.parse_args()

    vehicle = load_vehicle("nps_auv2")
    truth = mv.spiral(vehicle, dt=study.DT_TRUTH)
    model = mv.spiral(vehicle, dt=study.DT_MODEL)
    clean = Simulator(vehicle, truth, mode="horizontal",
                      sample_every=int(round(study.SAMPLE_S / study.DT_TRUTH))).run().track(0)
    target = add_noise(clean, study.NOISE, np.random.default_rng([args.seed, 1]))
    setup = study.make_setups(vehicle, np.random.default_rng(args.seed), ["case2"])["case2"]
    sim = Simulator(setup.case.vehicle(vehicle), model, free=setup.names, mode="horizontal",
                    sample_every=int(round(study.SAMPLE_S / study.DT_MODEL)))
    problem = Problem(sim, target, setup.reference, channels=study.CHANNELS)
    logpost = LogPosterior(problem, study.NOISE, setup.prior)
    theta_hat, theta_in, _ = study.optimum(setup, vehicle, model, target, quick=False)
    centre, cov = laplace_start(theta_in, laplace_covariance(problem, theta_hat, study.NOISE, setup.prior),
                                setup.prior, margin=study.START_MARGIN)

    lines = [f"Case 2 posterior, {len(setup.names)} coefficients, 4 ensembles x {2 * len(setup.names) + 2} "
             f"walkers, spiral 600 s at dt {study.DT_MODEL} s, noise x,y {study.NOISE['x']} m, psi 0.2 deg; "
             f"budget {args.minutes:g} min per move set.",
             f"{'moves':14s} {'steps':>6s} {'min':>6s} {'tau_max':>8s} {'Rhat':>7s} {'Rhat_ens':>8s} "
             f"{'ESS_min':>8s} {'ESS/min':>8s} {'evals/s':>8s}"]
    print("\n".join(lines), flush=True)
    summary = {}
    with tempfile.TemporaryDirectory() as tmp:
        for label in args.sets.split(","):
            moves, logit = label.removesuffix("-logit"), label.endswith("-logit")
            target_lp, c0, cov0, T = logpost, centre, cov, None
            if logit:  # the same starting ball, seen in z = logit of each bounded coefficient
                target_lp = TransformedLogPosterior(logpost, setup.prior)
                T = target_lp.transform
                c0 = T.to_z(centre)[0]
                dth = np.exp(T.log_jacobian_terms(c0[None])[0])     # d theta / d z at the centre
                cov0 = cov / np.outer(dth, dth)
            ck = Path(tmp) / f"{label}.h5"
            t0, steps = time.perf_counter(), 0
            n0 = logpost.n_evaluations
            while time.perf_counter() - t0 < 60.0 * args.minutes:
                steps += args.block
                cfg = sampling.SamplerConfig(n_ensembles=4, moves=moves, min_steps=steps, max_steps=steps,
                                             check_every=args.block, tau_factor=1e9)
                res = sampling.run_ensembles(target_lp, c0, cov0, setup.names, cfg,
                                             np.random.default_rng([args.seed, 7]), checkpoint=ck)
                if logit:
                    shape = res.chains.shape
                    res = dataclasses.replace(res, chains=T.to_theta(res.chains.reshape(-1, shape[-1])).reshape(shape))
                minutes = (time.perf_counter() - t0) / 60.0
                d = sampling.diagnostics(sampling.to_inference_data(res), res)
                rate = (logpost.n_evaluations - n0) / (60.0 * minutes)
                row = (f"{label:14s} {res.n_steps:6d} {minutes:6.2f} {d['tau_max']:8.1f} {d['rhat_max']:7.3f} "
                       f"{d['rhat_ensembles_max']:8.3f} {d['ess_bulk_min']:8.0f} {d['ess_bulk_min'] / minutes:8.1f} "
                       f"{rate:8.0f}")
                print(row, flush=True)
                lines.append(row)
                summary[label] = (d, minutes)
    for moves, (d, minutes) in summary.items():
        lines.append(f"final {moves}: {d['verdict']} ({minutes:.1f} min)")
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines[-2:]))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
