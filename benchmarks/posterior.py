"""Posterior sampling speed on the paper's Case 2: emcee's default stretch move in coefficient
space against the configuration the study uses, and the alternatives it was chosen from, in one
run.

A sampler configuration is ``moves[+logit][+redraw]@E``: ``moves`` "stretch" (emcee's default),
"de" (DE 0.8 + snooker 0.2) or "de-stretch" (:mod:`bayesid.estimation.sampling`), ``+logit`` to
sample in the unconstrained space of :class:`bayesid.estimation.posterior.TransformedLogPosterior`,
``+redraw`` to move stranded walkers onto others during burn-in
(``SamplerConfig.redraw_stranded``), ``E`` independent ensembles of 2P+2 = 30 walkers. Every
configuration checks its chains every 250 steps, as the study does. All start from the same Laplace-shaped ball on the
same noisy spiral (studies/posterior.py's setup). Each run is extended in blocks through its HDF5
checkpoint (resume); after each block the benchmark prints what was reached so far: steps,
sampling minutes (the diagnostics between blocks are not timed), tau (max over coefficients),
per-walker R-hat (the study's verdict), between-ensemble R-hat, minimum bulk and tail ESS,
minimum bulk ESS per second, log-probability evaluations per second, the burn-in
(``sampling.burn_in``) and the number of stranded walkers moved so far. Chains sampled in logit
space are mapped back to the coefficients before the diagnostics (R-hat and ESS are
rank-normalised, so the map does not change them); tau is the sampler's, in the space it samples.

The last lines: the minutes each configuration needed to reach per-walker R-hat <= 1.01 with
bulk and tail ESS >= 400 (the first block at which it did, or "not reached"), and
``ess_per_s_ratio_<config>_vs_stretch@4``: the minimum bulk ESS per second at the end of the
budget against emcee's default (stretch, 4 ensembles: the study's setup before issue 23).

    python benchmarks/posterior.py [--minutes 5] [--block 2500] [--sets stretch@4,de@2,de+redraw@2,...]
                                   [--out reports/benchmark_posterior.txt]
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

from bayesid.data.vehicle import load_vehicle  # noqa: E402
from bayesid.estimation import sampling  # noqa: E402
from bayesid.estimation.objective import Problem  # noqa: E402
from bayesid.estimation.posterior import (  # noqa: E402
    LogPosterior,
    TransformedLogPosterior,
    add_noise,
    laplace_covariance,
    laplace_start,
)
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=5.0, help="sampling budget per configuration")
    ap.add_argument("--block", type=int, default=2500, help="steps between reports")
    ap.add_argument("--seed", type=int, default=2003)
    ap.add_argument("--out", default=str(ROOT / "reports" / "benchmark_posterior.txt"))
    ap.add_argument(
        "--sets",
        default="stretch@4,de@2,de+redraw@2,de+logit+redraw@2",
        help="configurations moves[+logit][+redraw]@ensembles (see the module docstring)",
    )
    args = ap.parse_args()

    vehicle = load_vehicle("nps_auv2")
    truth = mv.spiral(vehicle, dt=study.DT_TRUTH)
    model = mv.spiral(vehicle, dt=study.DT_MODEL)
    clean = (
        Simulator(vehicle, truth, mode="horizontal", sample_every=int(round(study.SAMPLE_S / study.DT_TRUTH)))
        .run()
        .track(0)
    )
    target = add_noise(clean, study.NOISE, np.random.default_rng([args.seed, 1]))
    setup = study.make_setups(vehicle, np.random.default_rng(args.seed), ["case2"])["case2"]
    sim = Simulator(
        setup.case.vehicle(vehicle),
        model,
        free=setup.names,
        mode="horizontal",
        sample_every=int(round(study.SAMPLE_S / study.DT_MODEL)),
    )
    problem = Problem(sim, target, setup.reference, channels=study.CHANNELS)
    logpost = LogPosterior(problem, study.NOISE, setup.prior)
    theta_hat, theta_in, _ = study.optimum(setup, vehicle, model, target, quick=False)
    centre, cov = laplace_start(
        theta_in,
        laplace_covariance(problem, theta_hat, study.NOISE, setup.prior),
        setup.prior,
        margin=study.START_MARGIN,
    )

    lines = [
        f"Case 2 posterior, {len(setup.names)} coefficients, {2 * len(setup.names) + 2} walkers per ensemble, "
        f"spiral 600 s at dt {study.DT_MODEL} s, noise x,y {study.NOISE['x']} m, psi 0.2 deg; "
        f"sampling budget {args.minutes:g} min per configuration.",
        f"{'config':15s} {'steps':>6s} {'min':>6s} {'tau_max':>8s} {'Rhat':>7s} {'Rhat_ens':>8s} "
        f"{'ESSb_min':>8s} {'ESSt_min':>8s} {'ESSb/s':>7s} {'evals/s':>8s} {'burn':>6s} {'moved':>5s}",
    ]
    print("\n".join(lines), flush=True)
    final, reached = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for label in args.sets.split(","):
            kind, _, n_ens = label.partition("@")
            moves, *flags = kind.split("+")
            unknown = set(flags) - {"logit", "redraw"}
            if unknown or moves not in sampling.MOVES:
                ap.error(f"--sets: {label!r} is not moves[+logit][+redraw]@E with moves in {sampling.MOVES}")
            logit = "logit" in flags
            target_lp, c0, cov0, T = logpost, centre, cov, None
            if logit:  # the same starting ball, seen in z = logit of each bounded coefficient
                target_lp = TransformedLogPosterior(logpost, setup.prior)
                T = target_lp.transform
                c0 = T.to_z(centre)[0]
                dth = np.exp(T.log_jacobian_terms(c0[None])[0])  # d theta / d z at the centre
                cov0 = cov / np.outer(dth, dth)
            ck = Path(tmp) / f"{label}.h5"
            sampled, steps = 0.0, 0
            n0 = logpost.n_evaluations
            while sampled < 60.0 * args.minutes:
                steps += args.block
                cfg = sampling.SamplerConfig(
                    n_ensembles=int(n_ens or 4),
                    moves=moves,
                    min_steps=steps,
                    max_steps=steps,
                    check_every=250,
                    tau_factor=1e9,
                    redraw_stranded="redraw" in flags,
                )
                tic = time.perf_counter()
                res = sampling.run_ensembles(
                    target_lp,
                    c0,
                    cov0,
                    setup.names,
                    cfg,
                    np.random.default_rng([args.seed, 7]),
                    checkpoint=sampling.Checkpoint(ck),
                )
                sampled += time.perf_counter() - tic
                if logit:
                    shape = res.chains.shape
                    res = dataclasses.replace(res, chains=T.to_theta(res.chains.reshape(-1, shape[-1])).reshape(shape))
                burn = sampling.burn_in(res)
                d = sampling.diagnostics(sampling.to_inference_data(res, burn=burn), res)
                rate = (logpost.n_evaluations - n0) / sampled
                row = (
                    f"{label:15s} {res.n_steps:6d} {sampled / 60:6.2f} {d['tau_max']:8.1f} {d['rhat_max']:7.4f} "
                    f"{d['rhat_ensembles_max']:8.4f} {d['ess_bulk_min']:8.0f} {d['ess_tail_min']:8.0f} "
                    f"{d['ess_bulk_min'] / sampled:7.2f} {rate:8.0f} {burn:6d} {len(res.redraws):5d}"
                )
                print(row, flush=True)
                lines.append(row)
                final[label] = (d, sampled)
                ok = (
                    d["rhat_max"] <= sampling.RHAT_MAX
                    and d["ess_bulk_min"] >= sampling.ESS_BULK_MIN
                    and d["ess_tail_min"] >= sampling.ESS_TAIL_MIN
                )
                if ok and label not in reached:
                    reached[label] = sampled / 60
    for label, (d, sampled) in final.items():
        when = f"{reached[label]:.2f} min" if label in reached else f"not reached in {sampled / 60:.2f} min"
        lines.append(
            f"converged (per-walker R-hat <= 1.01, bulk and tail ESS >= 400) {label}: {when}; at the end "
            f"R-hat {d['rhat_max']:.4f}, bulk ESS {d['ess_bulk_min']:.0f}, tail ESS {d['ess_tail_min']:.0f}"
        )
    base = "stretch@4"
    if base in final:
        ref = final[base][0]["ess_bulk_min"] / final[base][1]
        for label, (d, sampled) in final.items():
            if label != base:
                lines.append(f"ess_per_s_ratio_{label}_vs_{base} {d['ess_bulk_min'] / sampled / ref:.3f}")
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines[-(len(final) * 2) :]))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
