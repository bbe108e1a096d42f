"""Reproduce Furlong, Hearn, Veres & Rogers (IFAC GCUV 2003), Cases 1-3, on NPS AUV II.

Method (the paper's Sections 3-4): simulate the 10-minute spiral with the true coefficients in
the horizontal-plane mode to make the target track; for each case draw starting coefficients
(seeded), fit the free coefficients with SLSQP on the cost V(p) (sum of squared x, y, z, phi,
theta, psi differences at 1 s samples), and also with trust-region least squares; compare tracks,
coefficients and costs with the paper.

    python studies/furlong2003.py [--quick] [--out DIR] [--seed N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bayesid import cases
from bayesid.analysis import identifiability
from bayesid.data import terms
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation.fit import SolverOptions
from bayesid.estimation.fit import fit as fit_problem
from bayesid.estimation.objective import Problem
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator
from bayesid.report import fmt, md_table, plots, prepare_out, write_json, write_manifest

#: The paper's Table 1 and Section 4.1 (quoted for comparison; Furlong et al. 2003).
PAPER = {
    "case1": dict(start_cost=3.3e8, final_cost=2.0e-2, max_position_error_m=2e-3),
    "case2": dict(start_cost=1.1e8, final_cost=1.0e-3, max_position_error_m=1e-3),
    "case3": dict(start_cost=1.3e8, final_cost=2.3e2, max_position_error_m=0.5),
}
PAPER_CASE3_TRUE_COST = 1.3e5
SAMPLE_S = 1.0  # cost sample interval, s


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short spiral, fewer iterations (CI)")
    ap.add_argument("--out", default="reports/furlong2003")
    ap.add_argument("--seed", type=int, default=2003)
    return ap.parse_args()


def run_case(number, vehicle, spiral, target, rng, quick):
    case = cases.make_case(number, vehicle, rng)
    sim = Simulator(
        case.vehicle(vehicle), spiral, free=case.free, mode="horizontal", sample_every=int(round(SAMPLE_S / spiral.dt))
    )
    problem = Problem(sim, target, case.reference())
    bounds = case.scaled_bounds()
    p0 = np.ones(len(case.free))
    fits = {
        "slsqp": fit_problem(problem, p0, bounds, SolverOptions(method="slsqp", maxiter=100 if quick else 400)),
        "least_squares": fit_problem(problem, p0, bounds, SolverOptions(max_nfev=60 if quick else 600)),
    }
    out = {}
    for key, fit in fits.items():
        est = sim.run(fit.theta[None]).track(0)
        err = np.hypot(est["x"] - target["x"], est["y"] - target["y"])
        r, J = problem.jacobian(fit.p)
        _, s, Vt = np.linalg.svd(J, full_matrices=False)
        weak = identifiability.Direction(float(s[-1] ** 2), Vt[-1], case.free).label()
        out[key] = dict(fit=fit, error=err, track=est, svals=s, weakest=weak)
    true_p = problem.scaled(np.array([case.true[n] for n in case.free]))
    return case, problem, out, problem.cost(true_p), structural_nulls(case, vehicle, sim)


def structural_nulls(case, vehicle, sim):
    """Exact null directions from equation-row invariances, each checked by simulation: move
    the true coefficients 2 % along it and record the largest change of the track (m)."""
    N, causes = identifiability.structural_null_space(case.free, vehicle)
    base = np.array([case.true[n] for n in case.free])
    out = []
    if N.shape[1]:
        st = sim.run(np.vstack([base] + [base * (1 + 0.02 * N[:, k]) for k in range(N.shape[1])])).states
        for k in range(N.shape[1]):
            d = identifiability.Direction(0.0, N[:, k], case.free)
            out.append(
                dict(
                    direction=d.label(threshold=0.15),
                    weights=d.weights(0.05),
                    track_change_m=float(np.nanmax(np.abs(st[0, :, :2] - st[k + 1, :, :2]))),
                )
            )
    return dict(dimension=int(N.shape[1]), causes=causes, directions=out)


def case_json(case, res, true_cost):
    fit = res["fit"]
    ratio = {n: fit.theta[i] / case.true[n] for i, n in enumerate(case.free)}
    return dict(
        n_free=len(case.free),
        free=case.free,
        known=case.known,
        start_cost=fit.start_cost,
        final_cost=fit.cost,
        max_position_error_m=float(np.max(res["error"])),
        coefficient_ratio=ratio,
        start_ratio={n: case.start[n] / case.true[n] for n in case.free},
        known_ratio={n: case.known_values[n] / case.true[n] for n in case.known},
        at_bound=fit.at_bound,
        true_outside_bounds=case.true_outside_bounds(),
        n_iterations=fit.n_iterations,
        n_simulations=fit.n_simulations,
        wall_s=fit.wall_s,
        true_coefficients_cost=true_cost,
        jacobian_condition_number=float(res["svals"][0] / res["svals"][-1]),
        weakest_direction=res["weakest"],
        monitor=dict(**fit.summary(), history=fit.history),
    )


def main():
    import matplotlib

    matplotlib.use("Agg")  # the study writes its figures, it never shows them
    args = parse_args()
    t_start = time.perf_counter()
    out = prepare_out(args.out)
    figs = out / "figures"
    rng = np.random.default_rng(args.seed)

    # 1. Vehicle and the paper's spiral manoeuvre; the target track (noise-free, as the paper).
    vehicle = load_vehicle("nps_auv2")
    if args.quick:
        spiral = mv.spiral(vehicle, duration=180.0, t_straight=20.0, rudder_steps_deg=(5, 10, 15, 20))
    else:
        spiral = mv.spiral(vehicle)
    truth_sim = Simulator(vehicle, spiral, mode="horizontal", sample_every=int(round(SAMPLE_S / spiral.dt)))
    target = truth_sim.run().track(0, name="target")
    plots.track_xy(
        {"spiral (target)": target},
        figs / "fig1_spiral_track.png",
        f"Spiral manoeuvre, NPS AUV II ({spiral.duration:g} s)",
    )
    plots.inputs_time(target, figs / "fig1b_spiral_inputs.png", "Spiral inputs")

    # 2. The three cases, each fitted by SLSQP (the paper's method) and by least squares.
    results, runs = {}, {}
    for number in (1, 2, 3):
        case, problem, res, true_cost, nulls = run_case(number, vehicle, spiral, target, rng, args.quick)
        runs[case.name] = (case, res)
        results[case.name] = case_json(case, res["slsqp"], true_cost)
        results[case.name]["least_squares"] = case_json(case, res["least_squares"], true_cost)
        results[case.name]["structural_nulls"] = nulls
        print(
            f"{case.name}: V {res['slsqp']['fit'].start_cost:.3g} -> SLSQP {res['slsqp']['fit'].cost:.3g}"
            f" / LSQ {res['least_squares']['fit'].cost:.3g}",
            flush=True,
        )

    # 3. Figures like the paper's Figs. 2-5, plus convergence and Jacobian spectra.
    plots.position_error(
        target.t,
        {k.replace("case", "Case "): runs[k][1]["slsqp"]["error"] for k in runs},
        figs / "fig2_position_error.png",
        "Positional error of the converged tracks (SLSQP)",
    )
    all_names = cases.horizontal_coefficients(vehicle)
    for i, (k, (case, res)) in enumerate(runs.items()):
        r = results[k]
        plots.coefficient_ratios(
            all_names,
            r["start_ratio"],
            r["coefficient_ratio"],
            r["known_ratio"],
            figs / f"fig{3 + i}_coefficients_{k}.png",
            f"{k.replace('case', 'Case ')}: estimated / true (SLSQP)",
            bounds=(
                {n: case.lower[n] / case.true[n] for n in case.free},
                {n: case.upper[n] / case.true[n] for n in case.free},
            ),
        )
    plots.convergence(
        {
            f"{k} {m}": [h["cost"] for h in runs[k][1][m]["fit"].history]
            for k in runs
            for m in ("slsqp", "least_squares")
        },
        figs / "fig6_convergence.png",
        "Cost per iteration",
    )
    plots.singular_values(
        {k: runs[k][1]["slsqp"]["svals"] for k in runs},
        figs / "fig7_jacobian_singular_values.png",
        "Residual Jacobian at the SLSQP optimum (scaled parameters)",
    )

    # 4. Evidence for the discussion, computed here.
    st = truth_sim.run().states[0]
    turning = np.abs(st[:, 11]) > 1e-4
    corr_vr = float(np.corrcoef(st[turning, 7], st[turning, 11])[0, 1])
    summary = dict(
        vehicle=vehicle.id,
        manoeuvre=spiral.description,
        sample_interval_s=SAMPLE_S,
        n_samples=int(target.n_samples),
        seed=args.seed,
        quick=args.quick,
        track_length_m=float(np.sum(np.hypot(np.diff(target["x"]), np.diff(target["y"])))),
        corr_v_r_turning=corr_vr,
        paper=PAPER,
        paper_case3_true_cost=PAPER_CASE3_TRUE_COST,
    )
    write_json(out / "results.json", dict(study="furlong2003", summary=summary, cases=results))
    (out / "report.md").write_text(render_report(results, summary, runs))
    write_manifest(out, seed=args.seed, quick=args.quick, t_start=t_start)
    print(f"wrote {out} in {time.perf_counter() - t_start:.1f} s")


def render_report(R, S, runs) -> str:
    c1, c2, c3 = R["case1"], R["case2"], R["case3"]
    P = S["paper"]
    lines = [
        "# Furlong et al. (2003) reproduced on NPS AUV II",
        "",
        f"Run: {'QUICK (short spiral, CI)' if S['quick'] else 'full'}; seed {S['seed']}; every number and figure "
        "below comes from this run (`results.json`, `manifest.json`).",
        "",
        "**Setup.** Vehicle NPS AUV II (Healey & Lienard 1993; L = 5.3 m, prime coefficients, polynomial "
        "cross-flow terms derived from its strip integral), the stand-in for the paper's classified submarine. "
        f"Horizontal-plane mode (paper Sec. 4). Manoeuvre: {S['manoeuvre']} "
        f"Target track noise-free, {S['n_samples']} samples at {S['sample_interval_s']:g} s, "
        f"track length {S['track_length_m']:.0f} m. Cost V(p) = sum of squared x, y, z, phi, theta, psi "
        "differences (metres and radians summed as in the paper's Eq. 6). Parameters scaled as ratios to "
        "their starting values. RK4, dt 0.1 s.",
        "",
        "![spiral](figures/fig1_spiral_track.png) ![inputs](figures/fig1b_spiral_inputs.png)",
        "",
        "## Table 1: cost at start and convergence (SLSQP, the paper's method)",
        "",
        md_table(
            [
                "case",
                "free",
                "start V (ours)",
                "start V (paper)",
                "final V (ours)",
                "final V (paper)",
                "max position error (ours)",
                "max position error (paper)",
                "coefficients at a bound",
            ],
            [
                [
                    k.replace("case", "Case "),
                    R[k]["n_free"],
                    fmt(R[k]["start_cost"]),
                    fmt(P[k]["start_cost"]),
                    fmt(R[k]["final_cost"]),
                    fmt(P[k]["final_cost"]),
                    f"{fmt(R[k]['max_position_error_m'] * 1e3)} mm",
                    f"< {fmt(P[k]['max_position_error_m'] * 1e3)} mm",
                    ", ".join(R[k]["at_bound"]) or "none",
                ]
                for k in ("case1", "case2", "case3")
            ],
        ),
        "",
        "![error](figures/fig2_position_error.png)",
        "",
        "## Coefficients (estimated / true)",
        "",
        "Squares: start; circles: converged (SLSQP); crosses: known, not identified (Case 3: perturbed); "
        "grey bars: bounds.",
        "",
        "![c1](figures/fig3_coefficients_case1.png)",
        "![c2](figures/fig4_coefficients_case2.png)",
        "![c3](figures/fig5_coefficients_case3.png)",
        "",
    ]
    rows = []
    names = list(dict.fromkeys(c1["free"]))
    for n in names:
        rows.append(
            [
                n,
                terms.term(n).group,
                terms.term(n).category,
                fmt(c1["start_ratio"][n], 4),
                fmt(c1["coefficient_ratio"][n], 4),
                fmt(c1["least_squares"]["coefficient_ratio"][n], 4),
                fmt(c2["coefficient_ratio"].get(n), 4) if n in c2["coefficient_ratio"] else "known",
                fmt(c3["coefficient_ratio"].get(n), 4)
                if n in c3["coefficient_ratio"]
                else f"known x{fmt(c3['known_ratio'][n], 4)}",
            ]
        )
    lines += [
        md_table(
            [
                "coefficient",
                "group",
                "category",
                "Case 1 start",
                "Case 1 SLSQP",
                "Case 1 LSQ",
                "Case 2 SLSQP",
                "Case 3 SLSQP",
            ],
            rows,
        ),
        "",
    ]

    # SLSQP vs least squares
    cmp_rows = []
    for k in ("case1", "case2", "case3"):
        for key, label in (("slsqp", "SLSQP"), ("least_squares", "least squares (trf)")):
            r = R[k] if key == "slsqp" else R[k]["least_squares"]
            m = r["monitor"]
            cmp_rows.append(
                [
                    k.replace("case", "Case "),
                    label,
                    m["n_iterations"],
                    m["n_simulations"],
                    m["n_sim_cost"],
                    m["n_sim_gradient"],
                    m["n_sim_linesearch"],
                    fmt(m["final_cost"]),
                    f"{fmt(r['max_position_error_m'] * 1e3)} mm",
                    f"{m['wall_s']:.1f}",
                    f"{100 * m['sim_share']:.0f} %",
                    m["message"],
                ]
            )
    lines += [
        "## SLSQP versus least squares, and the SQP activity monitor",
        "",
        "Simulations are single tracks: at accepted iterates (cost), for finite-difference Jacobians "
        "(one batched call of P or P+1 tracks), and at rejected trial points (line search / rejected "
        "trust-region steps). Simulation share = wall time inside the batched simulator / total.",
        "",
        md_table(
            [
                "case",
                "method",
                "iterations",
                "simulations",
                "on cost",
                "on gradients",
                "on line search",
                "final V",
                "max error",
                "wall s",
                "in simulation",
                "stop",
            ],
            cmp_rows,
        ),
        "",
        "![convergence](figures/fig6_convergence.png)",
        "",
        "Per-iteration monitor of SLSQP for Case 1 (cost, step length in scaled units, active bounds); every "
        "iteration of every fit is in `results.json` under `cases.<case>.monitor.history`:",
        "",
    ]
    hist = c1["monitor"]["history"]
    sel = hist if len(hist) <= 16 else hist[:8] + hist[-8:]
    lines += [
        md_table(
            ["iteration", "V", "step", "active bounds"],
            [[h["iteration"], fmt(h["cost"]), fmt(h["step"]), ", ".join(h["active_bounds"]) or "-"] for h in sel],
        ),
        "",
    ]

    # Discussion
    ratio_dev = {n: abs(v - 1) for n, v in c1["coefficient_ratio"].items()}
    worst1 = sorted(ratio_dev, key=ratio_dev.get, reverse=True)[:4]
    dev2 = {n: abs(v - 1) for n, v in c2["coefficient_ratio"].items()}
    dev3 = {n: abs(v - 1) for n, v in c3["coefficient_ratio"].items()}
    worst3 = sorted(dev3, key=dev3.get, reverse=True)[:4]
    lsq3 = c3["least_squares"]
    worst1_txt = ", ".join(f"{n} {fmt(c1['coefficient_ratio'][n], 4)}" for n in worst1)
    worst3_txt = ", ".join(f"{n} {fmt(c3['coefficient_ratio'][n], 4)}" for n in worst3)
    lines += [
        "## Discussion: where we agree with the paper, where we differ, and why",
        "",
        f"**A near-perfect track fit does not pin the coefficients down (agrees).** In Case 1 SLSQP drove V from "
        f"{fmt(c1['start_cost'])} to {fmt(c1['final_cost'])} (largest position error "
        f"{fmt(c1['max_position_error_m'] * 1e3)} mm over a {S['track_length_m']:.0f} m track), yet the coefficients "
        f"are off by up to {100 * max(ratio_dev.values()):.1f} % ({worst1_txt}). "
        f"Least squares went further (V = {fmt(c1['least_squares']['final_cost'])}) and still left "
        f"{sum(abs(v - 1) > 0.01 for v in c1['least_squares']['coefficient_ratio'].values())} of {c1['n_free']} "
        "coefficients more than 1 % from truth. The reason is structural, not numerical: Case 1 has "
        f"{c1['structural_nulls']['dimension']} exact null directions ({'; '.join(c1['structural_nulls']['causes'])}). "
        "Multiplying one equation of M nu_dot = tau by (1 + a) leaves the motion unchanged, and when every "
        "coefficient of that equation is free, the rigid-body parts it also scales (m u r in Y, m v r in X, "
        "I_z r_dot in N) are absorbed by Yr, Xvr and Nrdot. Moving the true coefficients 2 % along each of "
        "these directions changes the track by at most "
        f"{fmt(max(d['track_change_m'] for d in c1['structural_nulls']['directions']))} m (round-off). So no "
        "track, however long or rich, identifies the Case 1 set. This is the paper's point 2 (\"some of the Y "
        'and N coefficients could be described as linear combinations of the remaining coefficients") made '
        "exact. The directions, in relative coefficient changes:",
        "",
        md_table(
            ["cause", "direction (relative changes)", "track change for a 2 % move"],
            [
                [c, d["direction"], f"{fmt(d['track_change_m'])} m"]
                for c, d in zip(c1["structural_nulls"]["causes"], c1["structural_nulls"]["directions"])
            ],
        ),
        "",
        f"Fixing the static coefficients (Cases 2 and 3) removes every such invariance: dimension "
        f"{c2['structural_nulls']['dimension']}. The residual Jacobian at the optimum (figure below) shows the "
        f"rest: condition numbers {fmt(c1['jacobian_condition_number'])} (Case 1; forward differences, so the "
        f"exact nulls appear at the finite-difference noise floor) and {fmt(c2['jacobian_condition_number'])} "
        f"(Case 2), whose weakest direction is {c2['weakest_direction']}. Issue 9 turns this into a posterior.",
        "",
        "![svals](figures/fig7_jacobian_singular_values.png)",
        "",
        f"In Case 1 the paper's protocol also leaves {len(c1['true_outside_bounds'])} true value(s) outside the "
        f"bounds ({', '.join(c1['true_outside_bounds']) or 'none'}): a start drawn more than 1/11 (9.1 %) below "
        "or above the truth puts the truth outside +-10 % of the start. The paper does not mention this.",
        "",
        f"**Knowing the static coefficients helps (agrees).** In Case 2 the worst coefficient is "
        f"{100 * max(dev2.values()):.2g} % off with SLSQP (V = {fmt(c2['final_cost'])}); least squares recovers "
        f"every coefficient to {100 * max(abs(v - 1) for v in c2['least_squares']['coefficient_ratio'].values()):.2g} % "
        f"(V = {fmt(c2['least_squares']['final_cost'])}). Jacobian condition number {fmt(c2['jacobian_condition_number'])}, "
        f"against {fmt(c1['jacobian_condition_number'])} in Case 1; none of it structural.",
        "",
        f"**1 % errors in the known coefficients move the identified ones far from truth (agrees), but the "
        f"track fit does not suffer (differs).** Case 3 coefficients deviate by up to {100 * max(dev3.values()):.1f} % "
        f"({worst3_txt}). The true values of the "
        f"identified coefficients, with the perturbed known ones, cost {fmt(c3['true_coefficients_cost'])}, "
        f"{fmt(c3['true_coefficients_cost'] / c3['final_cost'])} times the identified set's {fmt(c3['final_cost'])} "
        f"(paper: {fmt(PAPER_CASE3_TRUE_COST)} vs {fmt(P['case3']['final_cost'])}, about 500 times). Unlike the paper, "
        f"our Case 3 fit is still almost exact: SLSQP reached {fmt(c3['final_cost'])} "
        f"({fmt(c3['max_position_error_m'] * 1e3)} mm) and least squares {fmt(lsq3['final_cost'])} "
        f"({fmt(lsq3['max_position_error_m'] * 1e3)} mm), against the paper's 2.3e2 and 0.5 m. The free rotary "
        "terms absorb the errors in the static ones because on the spiral the sway velocity and yaw rate move "
        f"together: their correlation over the turning samples is {S['corr_v_r_turning']:.3f}, so a u*v term and a "
        "u*r term are nearly interchangeable (the paper's point 4). Why the paper's Case 3 fit stalled at 0.5 m "
        "we cannot check, because neither its coefficients nor its input sequence are published; a manoeuvre "
        "that excited v and r more independently, more free-running time per coefficient, or an optimiser "
        "stopped early would each explain it.",
        "",
        f"**Cost magnitudes differ (expected).** Our start costs ({fmt(c1['start_cost'])}, {fmt(c2['start_cost'])}, "
        f"{fmt(c3['start_cost'])}) are 2-4 orders of magnitude below the paper's (3.3e8, 1.1e8, 1.3e8). V sums "
        "squared metres over samples, so it scales with the square of the track size and with the number of "
        f"samples: NPS AUV II is a 5.3 m vehicle at 1.9 m/s covering {S['track_length_m']:.0f} m in 10 minutes, where a "
        "large naval submarine at several metres per second covers kilometres and turns on circles of hundreds "
        "of metres, so the same relative coefficient error produces far larger position errors. The paper's "
        "sample interval is not stated (ours is 1 s). Final costs are limited by the optimiser's stopping rule "
        "and floating point, not by the model, because target and model are the same equations.",
        "",
        f"**Optimiser.** SLSQP (the paper's SQP) and least squares both reach sub-millimetre fits. Least squares "
        "uses the structure of a sum of squares (Gauss-Newton steps) and reaches far lower costs where the problem "
        f"is well conditioned (Case 2: {fmt(c2['least_squares']['final_cost'])} vs {fmt(c2['final_cost'])}); on the "
        f"ill-conditioned Case 1 it needs many iterations ({c1['least_squares']['n_iterations']}). SLSQP on the raw "
        "cost (gradients of order 1e6 in scaled units) stopped after its first QP subproblem without moving in "
        "scipy 1.17; we give it V/V(p0), which changes no minimiser. Almost all wall time is spent simulating "
        "(the 'in simulation' column), which is why the simulator is compiled and batched.",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
