"""Which manoeuvres make which coefficients identifiable: richness metrics, a model-free SINDy
term check, cross-prediction between manoeuvres, and a designed manoeuvre (paper point 1).

Method
------
- Coefficients: the paper's Case 2 free set of NPS AUV II (rotary and added-mass X, Y, N
  coefficients; static ones known). Noise: x, y 0.2 m, psi 0.2 deg at 1 s samples.
- Richness per manoeuvre of :func:`bayesid.models.manoeuvres.library` and per combination: Fisher
  information at the true coefficients (D, E, condition number, collinearity index of the whole
  set, Cramér–Rao relative sd per coefficient) and SINDy inclusion probabilities from a noisy
  navigation log (x, y, psi as above; u, v 0.01 m/s, r 0.05 deg/s; :mod:`bayesid.analysis.sindy`).
- Cross-prediction (paper point 1): the Case 3 setting (known coefficients off by up to 1 %),
  identify on manoeuvre A by least squares from the case's start within +-25 % bounds on a noisy
  track, then simulate manoeuvre B with the identified set and report the RMS position error
  against B's true track.
- Design: multisine rudder inputs (relative amplitude and phase at 8 frequencies, 20 deg peak, 600 s
  like the spiral) maximising (a) log det F and (b) minimising the predicted sd along the
  sloppiest Xvr/Xrr combination. The predicted sd ratio (designed / spiral, from F with the
  +-25 % box as a Gaussian prior precision) is checked against the measured one: the spread of
  least-squares estimates over independent noise realisations on each manoeuvre.

    python studies/manoeuvre_richness.py [--quick] [--out DIR] [--seed N] [--jobs N] [--scheduler ADDRESS]

The Monte-Carlo fits are tasks of :mod:`bayesid.tasks` (``--jobs``, ``--scheduler``); their noise
and starts are drawn in order before they run, so the results do not depend on where they run.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from bayesid import cases
from bayesid.analysis import richness, sindy
from bayesid.data.track import Track
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation.fit import SolverOptions
from bayesid.estimation.fit import fit as fit_problem
from bayesid.estimation.objective import JointProblem, Problem
from bayesid.estimation.posterior import add_noise
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator
from bayesid.report import fmt, md_table, plots, prepare_out, write_json, write_manifest
from bayesid.tasks import Runner, Task, TaskError, add_arguments, parse_checked, run_tasks

NOISE = {"x": 0.2, "y": 0.2, "psi": math.radians(0.2)}
CHANNELS = ("x", "y", "psi")
#: DVL-grade body velocities and a fibre-optic gyro's yaw rate, for the SINDy check (m/s, rad/s).
VELOCITY_NOISE = {"u": 0.01, "v": 0.01, "r": math.radians(0.05)}
SAMPLE_S = 1.0
BOUND = 0.25  # +-25 % of truth, the Case 2/3 bounds
PRIOR_PRECISION = 1.0 / (2 * BOUND) ** 2 * 12.0  # the box as a Gaussian: var = width^2 / 12
COMBINATIONS = {
    "spiral+zigzag20_20": ("spiral", "zigzag20_20"),
    "spiral+multisine": ("spiral", "multisine"),
    "turns+zigzags": ("turn+20", "turn-20", "zigzag10_10", "zigzag20_20"),
}


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default="reports/manoeuvre_richness")
    ap.add_argument("--seed", type=int, default=2003)
    add_arguments(ap)
    return parse_checked(ap)


def mode_of(m) -> str:
    return "6dof" if np.any(m.inputs[:, 1:3] != 0.0) else "horizontal"


def problem_for(vehicle, m, free, reference, target=None):
    """Problem on manoeuvre ``m`` (1 s samples); noise-free truth target unless given."""
    sim = Simulator(vehicle, m, free=free, mode=mode_of(m), sample_every=int(round(SAMPLE_S / m.dt)))
    if target is None:
        target = sim.run(np.asarray(reference)[None]).track(0, name=m.name)
    return Problem(sim, target, reference, channels=CHANNELS)


def sindy_check(vehicle, m, rng, n_models):
    """Inclusion probabilities (term -> p) from a noisy navigation log of manoeuvre ``m``:
    x, y, psi with NOISE and body velocities u, v, r with VELOCITY_NOISE (DVL and gyro)."""
    tr = Simulator(vehicle, m, mode="horizontal").run().track(0, name=m.name)
    nav = Track.from_arrays(
        tr.t,
        states={c: tr[c] for c in ("x", "y", "psi", "u", "v", "r")},
        inputs={c: tr[c] for c in ("delta_r", "n")},
        name=m.name,
    )
    noisy = add_noise(nav, {**NOISE, **VELOCITY_NOISE}, rng)
    inc = sindy.inclusion_probabilities(noisy, vehicle, sindy.SindyOptions(n_models=n_models), rng=rng)
    flat = {t: p for eq in sindy.EQUATIONS for t, p in inc[eq].items()}
    return flat, sindy.compare_with_model(inc, vehicle)


def fit_on(case, vehicle_k, problems, quick):
    pb = problems[0] if len(problems) == 1 else JointProblem(problems)
    fit = fit_problem(
        pb,
        np.array([case.start[n] for n in case.free]) / pb.reference,
        case.scaled_bounds(),
        SolverOptions(max_nfev=30 if quick else 200),
    )
    return fit.theta


def rms_position_error(sim, theta, truth_track) -> float:
    st = sim.run(np.asarray(theta)[None]).states[0]
    e = np.hypot(st[:, 0] - truth_track["x"], st[:, 1] - truth_track["y"])
    return float(np.sqrt(np.mean(e**2))) if np.all(np.isfinite(e)) else math.inf


def mc_fit(problem, p0, max_nfev: int) -> list:
    """One Monte-Carlo realisation (a task): the least-squares estimate - 1 (relative units)."""
    lo, hi = np.full(p0.size, 1 - BOUND), np.full(p0.size, 1 + BOUND)
    return (fit_problem(problem, p0, (lo, hi), SolverOptions(max_nfev=max_nfev)).p - 1.0).tolist()


def monte_carlo_sd(vehicle, m, case, theta_true, n, rng, quick, w, jobs=1, scheduler=None):
    """Spread of least-squares estimates over ``n`` noise realisations (relative units):
    (per-coefficient sd (P,), sd along unit direction w). The realisations are drawn here, in
    order, and fitted as tasks (:mod:`bayesid.tasks`), so the result does not depend on where
    they run."""
    clean = problem_for(vehicle, m, case.free, theta_true)
    truth = clean.sim.run(theta_true[None]).track(0)
    tasks = []
    for i in range(n):
        pb = Problem(clean.sim, add_noise(truth, NOISE, rng), theta_true, channels=CHANNELS)
        p0 = 1.0 + rng.uniform(-0.1, 0.1, theta_true.size)
        tasks.append(Task(f"mc{i:04d}", {"realisation": i}, (pb, p0, 30 if quick else 150)))
    outs = run_tasks(mc_fit, tasks, Runner(jobs=jobs, scheduler=scheduler))
    failed = [o for o in outs if isinstance(o, TaskError)]
    if failed:
        raise RuntimeError(f"{len(failed)} Monte-Carlo fit(s) failed; first: {failed[0]}")
    E = np.array(outs)
    return E.std(axis=0, ddof=1), float((E @ w).std(ddof=1))


def main():
    import matplotlib

    matplotlib.use("Agg")  # the study writes its figures, it never shows them
    args = parse_args()
    t_start = time.perf_counter()
    out = prepare_out(args.out)
    fig = out / "figures"
    vehicle = load_vehicle("nps_auv2")
    lib = mv.library(vehicle, dt=0.1, seed=args.seed)
    if args.quick:
        lib = {k: lib[k] for k in ("spiral", "turn+20", "zigzag20_20", "multisine", "vertical_zigzag10_10")}
    case2 = cases.make_case(2, vehicle, np.random.default_rng(args.seed))
    free = case2.free
    theta = np.array([case2.true[n] for n in free])

    # 1. richness per manoeuvre and per combination
    results, spectra, incl, compare = {}, {}, {}, {}
    problems = {k: problem_for(vehicle, m, free, theta) for k, m in lib.items()}
    combos = {k: v for k, v in COMBINATIONS.items() if all(x in lib for x in v)}
    for key in list(lib) + list(combos):
        pb = problems[key] if key in lib else JointProblem([problems[x] for x in combos[key]])
        met = richness.fisher_metrics(pb, theta, NOISE)
        spectra[key] = np.linalg.eigvalsh(met["F"]).tolist()
        results[key] = {
            k: met[k]
            for k in ("logdet_fim", "min_eigenvalue", "condition_number", "max_collinearity_index", "cramer_rao_sd")
        }
        results[key]["duration_s"] = lib[key].duration if key in lib else sum(lib[x].duration for x in combos[key])
        results[key]["description"] = lib[key].description if key in lib else " + ".join(combos[key])
        if key in lib and mode_of(lib[key]) == "horizontal":
            incl[key], compare[key] = sindy_check(
                vehicle, lib[key], np.random.default_rng([args.seed, len(incl)]), n_models=20 if args.quick else 100
            )
            results[key]["sindy_inclusion"] = incl[key]
            results[key]["sindy_vs_model"] = compare[key]
        else:
            results[key]["sindy_inclusion"] = {}
        print(f"[richness] {key}: logdet {fmt(results[key]['logdet_fim'])}", flush=True)

    # 2. cross-prediction (Case 3 setting, noisy tracks)
    case3 = cases.make_case(3, vehicle, np.random.default_rng([args.seed, 3]))
    veh3 = case3.vehicle(vehicle)
    horiz = [k for k in lib if mode_of(lib[k]) == "horizontal"]
    truth_tracks = {k: problems[k].sim.run(theta[None]).track(0) for k in horiz}
    noisy_pb = {
        k: Problem(
            Simulator(veh3, lib[k], free=free, mode="horizontal", sample_every=int(round(SAMPLE_S / lib[k].dt))),
            add_noise(truth_tracks[k], NOISE, np.random.default_rng([args.seed, 7, i])),
            case3.reference(),
            channels=CHANNELS,
        )
        for i, k in enumerate(horiz)
    }
    fit_sets = {k: (k,) for k in horiz}
    fit_sets.update({k: v for k, v in combos.items() if all(x in horiz for x in v)})
    cross = {}
    for a, members in fit_sets.items():
        th = fit_on(case3, veh3, [noisy_pb[x] for x in members], args.quick)
        cross[a] = {b: rms_position_error(noisy_pb[b].sim, th, truth_tracks[b]) for b in horiz}
        print(f"[richness] fitted on {a}: " + ", ".join(f"{b} {cross[a][b]:.2f}" for b in horiz), flush=True)

    # 3. design (600 s, 20 deg peak), against the spiral at the same duration and step
    dt_d = 0.5
    spiral_d = mv.spiral(vehicle, dt=dt_d)

    def make(m):
        return problem_for(vehicle, m, free, theta)

    met_sp = richness.fisher_metrics(make(spiral_d), theta, NOISE)
    P = len(free)
    prior = np.full(P, PRIOR_PRECISION)
    ix, ir = free.index("Xvr"), free.index("Xrr")
    Csp = np.linalg.inv(met_sp["F"] + np.diag(prior))[np.ix_([ix, ir], [ix, ir])]
    ev, V = np.linalg.eigh(Csp)
    w = np.zeros(P)
    w[[ix, ir]] = V[:, -1] * np.sign(V[np.argmax(np.abs(V[:, -1])), -1])
    label = f"{w[ix]:.2f}*Xvr {'+' if w[ir] >= 0 else '-'} {abs(w[ir]):.2f}*Xrr"
    design = {}
    n_mc = 4 if args.quick else 16
    sd_sp, dir_sp = monte_carlo_sd(
        vehicle,
        spiral_d,
        case2,
        theta,
        n_mc,
        np.random.default_rng([args.seed, 11]),
        args.quick,
        w,
        args.jobs,
        args.scheduler,
    )
    designs = {}
    for crit in ("D", "direction"):
        options = richness.RichnessOptions(
            criterion=crit,
            direction=w,
            prior_precision=prior,
            duration=600.0,
            dt=dt_d,
            maxiter=2 if args.quick else 12,
            popsize=3 if args.quick else 5,
        )
        d = richness.design_multisine(vehicle, make, theta, NOISE, options, rng=np.random.default_rng([args.seed, 21]))
        designs[crit] = d
        met_d = richness.fisher_metrics(make(d.manoeuvre), theta, NOISE)
        cr_sp = np.sqrt(np.diag(np.linalg.inv(met_sp["F"] + np.diag(prior))))
        cr_d = np.sqrt(np.diag(np.linalg.inv(met_d["F"] + np.diag(prior))))
        sd_d, dir_d = monte_carlo_sd(
            vehicle,
            d.manoeuvre,
            case2,
            theta,
            n_mc,
            np.random.default_rng([args.seed, 12]),
            args.quick,
            w,
            args.jobs,
            args.scheduler,
        )
        if crit == "D":  # geometric mean of the per-coefficient sds
            pred = float(np.exp(np.mean(np.log(cr_d / cr_sp))))
            meas = float(np.exp(np.mean(np.log(sd_d / sd_sp))))
        else:
            pred = richness.direction_sd(met_d["F"], w, prior) / richness.direction_sd(met_sp["F"], w, prior)
            meas = dir_d / dir_sp
        design[crit] = dict(
            predicted_sd_ratio=pred,
            measured_sd_ratio=meas,
            logdet_fim=met_d["logdet_fim"],
            spiral_logdet_fim=met_sp["logdet_fim"],
            start_value=d.start_value,
            value=d.value,
            weights=d.weights.tolist(),
            phases_rad=d.phases.tolist(),
            n_evaluations=d.n_evaluations,
            description=d.manoeuvre.description,
            n_noise_realisations=n_mc,
            direction=label if crit == "direction" else "all coefficients (geometric mean)",
        )
        print(f"[richness] design {crit}: predicted {pred:.3f}, measured {meas:.3f}", flush=True)

    # figures
    plots.track_xy({k: truth_tracks[k] for k in horiz}, fig / "tracks.png", title="Manoeuvre library (true tracks)")
    plots.inclusion_heatmap(
        incl,
        fig / "sindy_inclusion.png",
        vehicle=vehicle,
        title="SINDy inclusion probability (noisy x, y, psi, u, v, r)",
    )
    plots.fim_spectra(
        {k: v for k, v in spectra.items()},
        fig / "fim_spectra.png",
        title="Fisher information per manoeuvre (Case 2 free set)",
    )
    plots.cross_prediction(cross, fig / "cross_prediction.png")
    plots.design_inputs(
        {"spiral": spiral_d, **{f"designed ({k})": d.manoeuvre for k, d in designs.items()}}, fig / "designed.png"
    )
    plots.predicted_vs_measured(design, fig / "design_gain.png")

    write_json(
        out / "results.json",
        dict(
            free=free,
            noise_sd=dict(x_m=NOISE["x"], y_m=NOISE["y"], psi_deg=0.2),
            manoeuvres=results,
            cross_prediction_rms_m=cross,
            design=design,
            sloppy_direction=dict(zip(free, w.tolist())),
            sloppy_direction_label=label,
        ),
    )
    write_report(out, args, results, cross, design, compare, label, free)
    write_manifest(out, seed=args.seed, quick=args.quick, t_start=t_start)
    print(f"[richness] wrote {out} in {time.perf_counter() - t_start:.0f} s")


def write_report(out, args, results, cross, design, compare, label, free):
    L = [
        "# Manoeuvre richness: which manoeuvres identify which coefficients",
        "",
        f"Run: {'quick' if args.quick else 'full'}, seed {args.seed}; every number below comes from this run.",
        "",
        "Coefficients: the paper's Case 2 free set (" + ", ".join(free) + "). Noise: x, y 0.2 m, psi 0.2 deg "
        "at 1 s. Fisher information at the true coefficients, relative units.",
        "",
        "## Richness per manoeuvre",
        "",
        "![tracks](figures/tracks.png)",
        "",
        "![FIM](figures/fim_spectra.png)",
        "",
    ]
    hdr = [
        "manoeuvre",
        "duration, s",
        "log det F",
        "min eigenvalue",
        "condition number",
        "collinearity index",
        "worst CR sd (coefficient)",
    ]
    rows = []
    for k, r in sorted(
        results.items(), key=lambda kv: -kv[1]["logdet_fim"] if np.isfinite(kv[1]["logdet_fim"]) else 1e99
    ):
        worst = max(r["cramer_rao_sd"], key=lambda n: r["cramer_rao_sd"][n])
        rows.append(
            [
                k,
                fmt(r["duration_s"]),
                fmt(r["logdet_fim"]),
                fmt(r["min_eigenvalue"]),
                fmt(r["condition_number"]),
                fmt(r["max_collinearity_index"]),
                f"{fmt(r['cramer_rao_sd'][worst])} ({worst})",
            ]
        )
    L += [md_table(hdr, rows), ""]
    hdr = ["coefficient"] + list(results)
    rows = [[n] + [fmt(results[k]["cramer_rao_sd"][n]) for k in results] for n in free]
    L += ["Cramér–Rao relative sd per coefficient (1 = 100 %):", "", md_table(hdr, rows), ""]
    L += [
        "## Model-free check (ensemble SINDy on a noisy navigation log)",
        "",
        "Track: x, y 0.2 m, psi 0.2 deg, u, v 0.01 m/s, r 0.05 deg/s noise; 100 bootstrap models per "
        "equation (pysindy EnsembleOptimizer around STLSQ, threshold 0.05 of the normalised force). "
        "The bootstrap resamples single samples of smoothed (correlated) signals, so the probabilities "
        "are sharper than a block bootstrap would give.",
        "",
        "![SINDy](figures/sindy_inclusion.png)",
        "",
    ]
    for k, c in compare.items():
        L += [
            f"- **{k}**: "
            + "; ".join(
                f"{eq}: sees {len(c[eq]['excited_and_in_model'])}/{len(c[eq]['in_model'])} model terms"
                + (f", misses {', '.join(c[eq]['in_model_not_seen'])}" if c[eq]["in_model_not_seen"] else "")
                + (f", spurious {', '.join(c[eq]['spurious'])}" if c[eq]["spurious"] else "")
                for eq in sindy.EQUATIONS
            )
        ]
    L += [
        "",
        "## Cross-prediction (identify on A, predict B; RMS position error, m)",
        "",
        "![cross](figures/cross_prediction.png)",
        "",
    ]
    preds = list(next(iter(cross.values())))
    L += [
        md_table(["fitted on \\ predicted"] + preds, [[a] + [fmt(v[b]) for b in preds] for a, v in cross.items()]),
        "",
    ]
    sp = cross.get("spiral")
    if sp:
        own = sp["spiral"]
        worst = max((b for b in preds if b != "spiral"), key=lambda b: sp[b])
        L += [
            f"Fitted on the spiral: {fmt(own)} m on the spiral itself, up to {fmt(sp[worst])} m on {worst}. "
            "Mean over the other manoeuvres by fit set: "
            + ", ".join(
                f"{a} {fmt(np.mean([v[b] for b in preds if b not in COMBINATIONS.get(a, (a,))]))}"
                for a, v in cross.items()
            )
            + " m.",
            "",
        ]
    L += ["## Designed manoeuvre", "", "![designed](figures/designed.png)", "", "![gain](figures/design_gain.png)", ""]
    hdr = [
        "criterion",
        "direction",
        "log det F (designed / spiral)",
        "predicted sd ratio",
        "measured sd ratio",
        "noise realisations",
    ]
    rows = [
        [
            k,
            d["direction"],
            f"{fmt(d['logdet_fim'])} / {fmt(d['spiral_logdet_fim'])}",
            fmt(d["predicted_sd_ratio"]),
            fmt(d["measured_sd_ratio"]),
            d["n_noise_realisations"],
        ]
        for k, d in design.items()
    ]
    L += [
        md_table(hdr, rows),
        "",
        f"The sloppy Xvr/Xrr combination on the spiral is `{label}` (relative units). Ratios are designed / "
        "spiral; below 1 means the designed manoeuvre determines the coefficients better. Predicted: from the "
        "Fisher information with the +-25 % box as a Gaussian prior; measured: spread of least-squares "
        "estimates (bounded to the box) over independent noise realisations.",
        "",
    ]
    L += conclusions(results, cross, design, compare, label)
    (out / "report.md").write_text("\n".join(L) + "\n")


def worst_sentence(single) -> str:
    """Which coefficient each informative manoeuvre determines worst, in words."""
    worst = {
        k: max(r["cramer_rao_sd"], key=r["cramer_rao_sd"].get)
        for k, r in single.items()
        if np.isfinite(r["logdet_fim"])
    }
    if not worst:
        return ""
    names, counts = np.unique(list(worst.values()), return_counts=True)
    top = names[np.argmax(counts)]
    sds = [single[k]["cramer_rao_sd"][top] for k, n in worst.items() if n == top]
    return (
        f"The worst-determined coefficient is {top} on {int(counts.max())} of {len(worst)} informative "
        f"manoeuvres (Cramér–Rao sd {fmt(min(sds))} to {fmt(max(sds))}, i.e. {fmt(100 * min(sds))} % or more): "
        "no single manoeuvre at one speed and 20 deg of rudder pins it down."
    )


def conclusions(results, cross, design, compare, label) -> list:
    """The findings in words, every number from this run."""
    single = {k: r for k, r in results.items() if k not in COMBINATIONS}
    ranked = sorted((k for k in single if np.isfinite(single[k]["logdet_fim"])), key=lambda k: -single[k]["logdet_fim"])
    blind = [k for k in single if not np.isfinite(single[k]["logdet_fim"])]
    L = ["## Conclusions", ""]
    L += [
        f"1. **Richness.** By log det F the single manoeuvres rank {', '.join(ranked)}"
        + (
            f"; {', '.join(blind)} leave some free coefficients without any information (log det F = -inf)"
            if blind
            else ""
        )
        + ". "
        + worst_sentence(single)
    ]
    if "spiral" in cross:
        sp = cross["spiral"]
        others = [b for b in sp if b != "spiral"]
        worst = max(others, key=lambda b: sp[b])
        mean = {a: float(np.mean([v[b] for b in v if b not in COMBINATIONS.get(a, (a,))])) for a, v in cross.items()}
        best = min(mean, key=mean.get)
        L += [
            f"2. **The paper's point (1) reproduces.** Identified on the spiral, the model tracks the spiral to "
            f"{fmt(sp['spiral'])} m RMS but misses the other manoeuvres by {fmt(mean['spiral'])} m on average and "
            f"{fmt(sp[worst])} m on {worst}. The fit set that predicts the others best is {best} "
            f"({fmt(mean[best])} m on average)."
            + (
                f" Adding a manoeuvre to the spiral helps: spiral+multisine {fmt(mean['spiral+multisine'])} m."
                if "spiral+multisine" in mean
                else ""
            )
        ]
    seen_all = [k for k, c in compare.items() if all(not c[eq]["in_model_not_seen"] for eq in sindy.EQUATIONS)]
    L += [
        f"3. **Model-free check.** On a realistic navigation log, ensemble SINDy sees every model term on "
        f"{', '.join(seen_all) if seen_all else 'no manoeuvre'}; it also includes cubic extras (vvv, rrr, vvr, vrr) "
        "with high probability almost everywhere, because on these tracks they are nearly collinear with the "
        "model's |v|v, |r|r, |v|r terms: SINDy can say which force *directions* a manoeuvre excites, not which "
        "of two collinear bases the vehicle uses."
    ]
    if design:
        d, c = design.get("D"), design.get("direction")
        L += [
            f"4. **Design.** A 600 s multisine with the spiral's 20 deg peak raises log det F from "
            f"{fmt(d['spiral_logdet_fim'])} to {fmt(d['logdet_fim'])}; predicted geometric-mean sd ratio "
            f"{fmt(d['predicted_sd_ratio'])}, measured {fmt(d['measured_sd_ratio'])}. Designed for the sloppy "
            f"`{label}` combination: predicted sd ratio {fmt(c['predicted_sd_ratio'])}, measured "
            f"{fmt(c['measured_sd_ratio'])}. The measured ratios come from {c['n_noise_realisations']} noise "
            "realisations per manoeuvre (an sd from 16 draws is itself uncertain by about 18 %) and from "
            "estimates bounded to the +-25 % box, which caps the spread of the sloppiest coefficients on both "
            "manoeuvres; the Fisher prediction is local and treats the box as a Gaussian."
        ]
    return L + [""]


if __name__ == "__main__":
    main()
