"""The report of ``bayesid fit`` (``report.md`` beside ``model.json``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..estimation.laplace import covariance_sentence
from ..estimation.prediction import TURN_TOLERANCE
from .imo import fit_imo_lines
from .markdown import fmt, md_table, warning_lines

#: Distance from the prior mean (in prior sds) beyond which a coefficient is flagged "far".
FAR_FROM_PRIOR = 3.0
#: How the solvers say they stopped at their budget (scipy's least_squares, SLSQP).
_BUDGET_MESSAGES = ("maximum number of function evaluations", "iteration limit reached")


def budget_exhausted(fit: dict) -> bool:
    """Whether a fit stopped because its optimiser budget (``--max-nfev``) ran out.

    Parameters
    ----------
    fit : dict
        The ``fit`` entry of a model document: ``success`` and the solver's ``message``.

    Returns
    -------
    bool
        True when the solver did not converge and its message says the budget ran out.
    """
    msg = str(fit.get("message", "")).lower()
    return not fit.get("success", True) and any(m in msg for m in _BUDGET_MESSAGES)


def budget_advice(fit: dict) -> str:
    """The sentence a fit whose budget ran out prints and writes: what happened and what to do.

    Parameters
    ----------
    fit : dict
        The ``fit`` entry of a model document (``max_nfev`` when the command recorded it).

    Returns
    -------
    str
        One sentence, without markup.
    """
    n = fit.get("max_nfev")
    budget = f"--max-nfev {n}" if n else "--max-nfev"
    more = f"--max-nfev {2 * int(n)}" if n else "a larger --max-nfev"
    return (
        f"the optimiser stopped at its budget ({budget} least-squares iterations) before converging: the estimate "
        "is where it stopped, not an optimum, and its sds and scores describe that point; rerun with "
        f"{more} (or more) until the fit ends on a convergence test"
    )


def write_fit_report(doc: dict, out, command: str = "", training_figures: list | None = None) -> None:
    """Write ``report.md`` of ``bayesid fit``: the identified coefficients beside the vehicle file's
    values and the priors, their Laplace sds, the weakly determined directions, the training fit's
    figures, the calibration of the predictive bands and the multistart.

    Parameters
    ----------
    doc : dict
        The model document (``model.json``) of the fit.
    out : str or Path
        The folder written to (it exists).
    command : str
        The command line, quoted at the top of the report (none when empty).
    training_figures : list of str, optional
        File names in ``out/figures`` of the training fit's figures (measured against simulated
        track and heading per training run), linked from the report.
    """
    out = Path(out)
    ts = doc["train_scores"]
    warn = (doc.get("provenance") or {}).get("warnings") or []
    lines = [
        "# Identified model",
        "",
        f"`{command}`" if command else "",
        "",
        *warning_lines(warn),
        f"Vehicle {doc['vehicle_id']}; effects: {', '.join(doc['effects']) or 'none'}; "
        f"multiple shooting over {doc['fit_window_s']} s windows, step {doc['dt']} s" + _inputs_phrase(doc) + "; "
        f"{len(doc['train_runs'])} training run(s).",
        "",
        f"Equation-error seed: {'used' if doc['seed'].get('used') else 'not used'} "
        f"(R^2 X/Y/N: {', '.join(fmt(v) for v in doc['seed'].get('r2', {}).values()) or '-'}).",
        "",
        f"Training RMS position error {fmt(ts['rms_position_m'])} m, heading {fmt(ts['rms_heading_deg'])} deg "
        f"({doc['fit_window_s']} s windows). Fit: {doc['fit']['nfev']} evaluations, {doc['fit']['message']}",
        "",
        *([f"**Budget ran out**: {budget_advice(doc['fit'])}.", ""] if budget_exhausted(doc["fit"]) else []),
        *_bound_lines(doc),
        *_step_lines(doc["fit"]),
        *_retime_lines(doc["fit"]),
        *_nested_start_lines(doc["fit"]),
        *_training_points_lines(doc["fit"]),
        _ar1_sentence(doc["posterior"]),
        "",
        *_coefficient_lines(doc),
        *_training_figure_lines(training_figures),
    ]
    lines += _prior_lines(doc) + _weak_direction_lines(doc) + _calibration_lines(doc)
    lines += fit_imo_lines(doc)  # ships: the IMO criteria of the training runs
    apart = (doc["fit"].get("training_points") or {}).get("apart") or []
    lines += _training_turn_lines(doc.get("training_turns"), coefficients_at_bound(doc["fit"].get("at_bound")), apart)
    ms = doc.get("multistart")
    if ms:
        lines += _multistart_lines(ms)
    (out / "report.md").write_text("\n".join(lines))


_SUSPECTS = {
    "wind": (
        "the run logs a wind that pushes with a large share of the hull's resistance and the model has no wind "
        "effect, so the wind is the first suspect: fit with the wind effect (--effects wind) before judging the surge"
    ),
    "speed in the turn": (
        "the speed in the turn is off too, so the surge equation is the first suspect (hull resistance in the turn, "
        "the propeller's inflow and thrust deduction, the rudder's drag: bayesid diagnose tests them as the "
        "hull_resistance, wake_in_turn, thrust_deduction and rudder_resistance effects and the X terms of discovery)"
    ),
    "turning forces": (
        "the speed in the turn is right, so the sway force and yaw moment of the hull and rudder in the turn are the "
        "first suspects (bayesid diagnose tests the hull's coupling form in a hard turn as the coupling_speed effect, "
        "and the Y and N terms of discovery)"
    ),
}


def training_turn_sentence(turn: dict) -> str:
    """One line on a training turning circle the fitted model does not reproduce
    (:func:`bayesid.estimation.prediction.training_turns`).

    Parameters
    ----------
    turn : dict
        One entry of ``training_turns``.

    Returns
    -------
    str
        E.g. ``the model does not reproduce its own training turn T: steady turning diameter
        -34 %, tactical diameter -8 % -- a structural miss; ...``.
    """
    errs = ", ".join(
        f"{k.removesuffix('_m').replace('_', ' ')} {100 * v:+.1f} %"
        for k, v in turn["rel_error"].items()
        if v is not None and k in ("tactical_diameter_m", "steady_turning_diameter_m")
    )
    return (
        f"the model does not reproduce its own training turn {turn['run']}: {errs} -- a structural miss of the model "
        f"form, not a prediction error; {_SUSPECTS.get(turn['suspect'], 'no suspect')}"
    )


def coefficients_at_bound(names) -> list:
    """The model coefficients among the parameters a fit left on a bound (``FitResult.at_bound``,
    ``model.json``'s ``fit.at_bound``): an effect's parameters, named ``effect.name``, left out.

    Parameters
    ----------
    names : list of str or None
        Parameter names.

    Returns
    -------
    list of str
        The coefficients, in order.
    """
    return [n for n in names or [] if "." not in n]


def _bound_lines(doc: dict) -> list:
    """The parameters the fit left on a bound, with what that means (none when none is): a model
    coefficient there strains the model form; an effect's parameter (``effect.name``) on its bound
    may be the effect's own neutral value (a delay of 0 s)."""
    names = doc["fit"].get("at_bound") or []
    value = dict(zip(doc["param_names"], doc["p"]))
    coefs = coefficients_at_bound(names)
    effects = [n for n in names if n not in coefs]
    out = []
    if coefs:
        out += [
            f"**At a bound:** {', '.join(f'{n} = {fmt(value.get(n), 4)}' for n in coefs)}. The runs ask for a value "
            "beyond the range the coefficient's physics allows: its estimate and sd are the bound's, not the data's, "
            "and the model form strains there (another component does what this one cannot); read the other "
            "coefficients with that in mind.",
            "",
        ]
    if effects:
        out += [
            f"Effect parameters on a bound: {', '.join(f'{n} = {fmt(value.get(n), 4)}' for n in effects)} (at the "
            "effect's neutral value, e.g. a delay of 0 s, the runs do not ask for the effect; elsewhere they ask for "
            "more than its catalogued range).",
            "",
        ]
    return out


def _training_turn_lines(turns: list | None, at_bound: list | None = None, apart: list | None = None) -> list:
    """The training turning circles as measured and as the fitted model flies them; ``at_bound``:
    the coefficients the fit left on a bound, named beside a turn the model misses; ``apart``: the
    training runs at another propulsion point than the others (``fit.training_points``), named
    first where one is a missed turn."""
    if not turns:
        return []
    keys = ("advance_m", "tactical_diameter_m", "steady_turning_diameter_m", "speed_loss")
    rows = []
    for t in turns:
        for k in keys:
            m, q = t["measured"].get(k), t["predicted"].get(k)
            e = t["rel_error"].get(k)
            rows.append([t["run"], k.replace("_", " "), fmt(m), fmt(q), "-" if e is None else f"{100 * e:+.1f} %"])
    said = [training_turn_sentence(t) for t in turns if t["reproduced"] is False]
    said += [
        f"the training run {t['run']} is at another propulsion point than the others (above): one propeller model holds "
        "them all, so the speed in this turn carries the compromise before any hull term"
        for t in turns
        if t["reproduced"] is False and t["run"] in (apart or [])
    ]
    if said and at_bound:
        said.append(
            f"the fit also left {', '.join(at_bound)} on a bound (above): the same strain of the model form may show "
            "in both"
        )
    said += [
        f"the index reader does not read the model's run of {t['run']} as a turning circle, while it reads the "
        f"measured run as one ({t['predicted_unread']}): whether the model misses this turn is not said here"
        for t in turns
        if t.get("predicted_unread")
    ]
    ok = [t["run"] for t in turns if t["reproduced"]]
    return [
        "## The training turning circles",
        "",
        "Each training run that reads as a turning circle, predicted whole from its measured first state with its "
        "logged rudder and propeller (speed loss: 1 - u/U0 in the steady turn). A fitted model that misses the turn "
        "it was fitted to cannot be right on others.",
        "",
        md_table(["run", "index", "measured", "predicted", "error"], rows),
        "",
        *[f"- **{s[0].upper() + s[1:]}.**" for s in said],
        *(
            [f"- Reproduced within {fmt(100 * TURN_TOLERANCE)} % (tactical and steady diameters): {', '.join(ok)}."]
            if ok
            else []
        ),
        "",
    ]


def _ar1_sentence(post: dict) -> str:
    """The Laplace posterior and its AR(1) inflation in words
    (:func:`bayesid.estimation.laplace.ar1_inflation`)."""
    infl = post["ar1_inflation"]
    bad = covariance_sentence(post)
    return (f"**Covariance:** {bad[0].upper() + bad[1:]}. " if bad else "") + (
        "Posterior: Laplace approximation (Gauss-Newton covariance at the optimum, scaled by the residual "
        f"variance) x AR(1) inflation {fmt(infl)}; Jacobian condition number {fmt(post['condition_number'])}. "
        "The inflation is there because the simulation errors of neighbouring samples in a window are correlated: "
        "n such samples carry the evidence of only about n (1 - rho) / (1 + rho) independent ones (rho their median "
        "lag-1 autocorrelation; capped so that every window counts as at least one), so the covariance is multiplied "
        f"by (1 + rho) / (1 - rho) = {fmt(infl)} and every sd widened by its square root, {fmt(float(infl) ** 0.5)} x."
    )


def _coefficient_lines(doc: dict) -> list:
    """The table of each parameter's vehicle-file value, prior, estimate and Laplace sd, the
    distance of the estimate from its prior in prior sds, coefficients far from their prior
    flagged."""
    file_values = (doc.get("provenance") or {}).get("vehicle_coefficients") or {}
    pr = doc.get("prior") or {}
    pc = pr.get("coefficients") or {} if pr.get("used") else {}
    rows, far = [], []
    for n, p, sd in zip(doc["param_names"], doc["p"], doc["sd"]):
        c = pc.get(n)
        z = None if c is None else c["z"]
        if z is not None and abs(z) > FAR_FROM_PRIOR:
            far.append(f"{n} ({fmt(z, 2)} prior sd)")
        rows.append(
            [
                n,
                fmt(file_values.get(n), 4),
                f"N({fmt(c['mean'], 4)}, {fmt(c['sd'], 3)})" if c is not None else "none",
                fmt(p, 4),
                fmt(sd, 3),
                "-" if z is None else (f"**{fmt(z, 2)} (far)**" if abs(z) > FAR_FROM_PRIOR else fmt(z, 2)),
            ]
        )
    seed = doc.get("seed") or {}
    lines = [
        md_table(
            ["parameter", "vehicle file", "prior N(mean, sd)", "identified", "sd (Laplace)", "from prior (prior sd)"],
            rows,
        ),
        "",
        "The fit started from "
        + ("the equation-error seed, not the file's values" if seed.get("used") else "the vehicle file's values")
        + "; 'from prior': (identified - prior mean) / prior sd"
        + (
            f". **Far from their prior** (more than {FAR_FROM_PRIOR:g} prior sd): {', '.join(far)}: the data pull "
            "these away from the prior's values; check the prior, or the model the data are fitted with."
            if far
            else (
                f"; none is more than {FAR_FROM_PRIOR:g} prior sd from its prior."
                if pc
                else ". No prior in this fit (--prior none, or no [prior] section for these coefficients in the "
                "vehicle file): the data alone set the estimates."
            )
        ),
        "",
    ]
    return lines


def _training_figure_lines(figures: list | None) -> list:
    """Links to the training fit's figures (none without them)."""
    if not figures:
        return []
    return [
        "## Training fit",
        "",
        "Measured against simulated track and heading of each training run, restarted at every fit window as the "
        "fit scores it (multiple shooting):",
        "",
        *[f"![{Path(f).stem}](figures/{f})" for f in figures],
        "",
    ]


def _prior_lines(doc: dict) -> list:
    """The priors of the vehicle file against the identified values (none when not used)."""
    lines = []
    pr = doc.get("prior") or {}
    if pr.get("used"):
        prow = [
            [
                n,
                fmt(c["mean"], 4),
                fmt(c["sd"], 3),
                fmt(c["identified"], 4),
                fmt(c["posterior_sd"], 3),
                fmt(c["z"], 2),
                fmt(c["z_without_prior"], 2),
            ]
            for n, c in pr["coefficients"].items()
        ]
        lines += [
            "## Priors from the vehicle file",
            "",
            f"Source: {pr.get('source') or '(not given)'}. MAP fit: the data residuals weigh as a likelihood "
            f"of residual sd {fmt(pr['data_weight_sd'])} (residual variance {fmt(pr['residual_variance'])} x "
            f"serial-correlation inflation {fmt(pr['ar1_inflation'])}); z = (identified - prior mean) / prior sd.",
            "",
            md_table(
                [
                    "coefficient",
                    "prior mean",
                    "prior sd",
                    "identified",
                    "posterior sd (Laplace)",
                    "z",
                    "z without the prior",
                ],
                prow,
            ),
            "",
            "The data moved (|z| > 1): "
            + (", ".join(pr["moved"]) or "none")
            + "; beyond 3 prior sd: "
            + (", ".join(pr["beyond_3sd"]) or "none")
            + ".",
            "",
        ]
    return lines


def _weak_direction_lines(doc: dict) -> list:
    """The directions the training runs determine least."""
    lines = []
    weak = doc["posterior"].get("weak_directions") or []
    if weak:
        from ..analysis.identifiability import Direction

        lines += [
            "Directions the training runs determine least (eigenvectors of the scaled Gauss-Newton "
            "information; parameters in units of their typical size, smallest eigenvalue first): "
            + "; ".join(
                f"`{Direction(w['eigenvalue'], np.array(w['vector']), doc['param_names']).label()}` "
                f"(eigenvalue {fmt(w['eigenvalue'])})"
                for w in weak
            )
            + ". An ill-conditioned covariance means these combinations are set by the start and the "
            "bounds more than by the data.",
            "",
        ]
    return lines


def _calibration_lines(doc: dict) -> list:
    """The calibration of the predictive bands (none without one)."""
    lines = []
    if doc.get("calibration"):
        from ..estimation.calibration import EXCITATION_MEASURES, LEVELS, Calibration, conformal_quantile

        cal = Calibration.from_dict(doc["calibration"])
        failed = [f for f in cal.folds or [] if "error" in f]
        wb = {a: cal.window_band(a) for a in LEVELS}
        kappa, scores = cal.normalised_index_scores()
        keys = sorted(scores)
        lines += [
            "## Calibration of the predictive bands",
            "",
            f"{cal.method}: {cal.n_runs} runs in {cal.n_folds} folds"
            + (
                f" ({len(failed)} failed: " + "; ".join(f"{', '.join(f['runs'])}: {f['error']}" for f in failed) + ")"
                if failed
                else ""
            )
            + f"; {len(cal.window_scores['max_position_m'])} windows of {cal.window_s:g} s and "
            f"{sum(len(v) for v in scores.values())} manoeuvre indices scored on the left-out runs "
            f"({cal.n_draws} posterior draws per fold). `bayesid predict --score-window {cal.window_s:g}` reports "
            "these bands and their coverage.",
            "",
            md_table(
                ["nominal", "window position radius (m)", "window heading (deg)", *[f"{k} (q)" for k in keys]],
                [
                    [
                        f"{100 * a:g} %",
                        fmt(wb[a]["max_position_m"]),
                        fmt(wb[a]["max_heading_deg"]),
                        *[fmt(conformal_quantile(scores[k], a)) for k in keys],
                    ]
                    for a in LEVELS
                ],
            ),
            "",
            *(
                [
                    "The bands are calibrated for runs like these (95th percentiles of |delta_r|, |r| and r' = |r| L / U): "
                    + ", ".join(
                        f"{label} {xr[key][0]:.3g}-{xr[key][1]:.3g}{' ' + unit if unit else ''}"
                        for key, label, unit in EXCITATION_MEASURES
                        if key in xr
                    )
                    + "; `predict` names a run outside 0.8x-1.25x this range.",
                    "",
                ]
                if (xr := cal.excitation_range())
                else []
            ),
            "Index columns: the factor q of the band predicted +- q x sqrt(sd^2 + (kappa x predicted)^2), sd "
            "the posterior draws' spread of the index and kappa the median relative error of the left-out runs' "
            "values of that index (the structural error: "
            + ", ".join(f"{k} {fmt(v)}" for k, v in kappa.items())
            + ", 'all' for an index with fewer than 3); inf "
            "where too few scores for the level (predict then pools the scores of every index; an index no "
            "training run had, e.g. a turning circle from zigzags, is flagged extrapolated and not counted as "
            "calibrated).",
            "",
            *_extrapolation_fold_lines(cal, wb),
        ]
    return lines


def _extrapolation_fold_lines(cal, wb: dict) -> list:
    """What the calibration's folds are: how many leave out the only run of a manoeuvre kind (their
    scores are those of predicting a new kind), and what data would make the bands usable."""
    ext = cal.extrapolation_folds()
    infinite = [a for a, b in wb.items() if not np.isfinite(b.get("max_position_m", np.inf))]
    if not ext and not infinite:
        return []
    out = []
    if ext:
        lone = sorted({k for f in ext for k in f["kinds"]})
        counts = {k: sum(v == k for v in cal.kinds.values()) for k in lone}
        out.append(
            f"**{len(ext)} of {len(cal.folds)} folds are extrapolations**: each leaves out the only training run of "
            + ", ".join(f"{k.replace('_', ' ')} ({counts[k]} run{'s' if counts[k] != 1 else ''})" for k in lone)
            + ", so its scores are the errors of predicting a kind of manoeuvre the refit never saw. The bands "
            "above hold those errors: for predictions within the training kinds they are wider than they need be. "
            "A second run of each of these kinds in training makes every fold a prediction within its kinds."
        )
    if infinite:
        n = wb[infinite[0]].get("n_scores", 0)
        # the fewest scores with a finite conformal quantile: ceil((n + 1) a) <= n
        need = {a: next(n for n in range(1, 10**6) if math.ceil((n + 1) * a) <= n) for a in infinite}
        out.append(
            "Unbounded window bands at "
            + ", ".join(f"{a:g} (needs at least {need[a]} left-out windows)" for a in infinite)
            + f": the folds scored {n}. More or longer training runs (windows of {cal.window_s:g} s each) give "
            "the scores."
        )
    return [" ".join(out), ""]


def _multistart_lines(ms: dict) -> list:
    """The multistart section of a fit report: counts, distances and the distinct optima."""
    tc = ms.get("turning_circle") or {}
    head = ["optimum", "starts", "cost / best - 1"]
    if tc.get("speed_mps") is not None:
        head += ["advance (m)", "tactical diameter (m)"]
    rows = []
    for k, o in enumerate(ms["distinct_optima"]):
        r = [str(k + 1), str(len(o["starts"])), fmt(o["relative_cost"], 3)]
        if tc.get("speed_mps") is not None:
            c = o.get("turning_circle") or {}
            r += [fmt(c.get("advance_m")), fmt(c.get("tactical_diameter_m"))]
        rows.append(r)
    worst = sorted(ms["spread_near_best_scales"].items(), key=lambda kv: -kv[1])[:5]
    lines = [
        "## Multistart",
        "",
        f"{ms['n_starts']} starts (the default and {ms['n_starts'] - 1} Latin-hypercube starts); the best came from "
        f"the {ms['best_kind']} start. **{ms['n_near_best']} of {ms['n_starts']}** reach the best cost within "
        f"{100 * ms['cost_tolerance']:g} %; they form **{ms['n_distinct_near_best']} distinct optimum/optima** "
        f"(optima differing by more than {ms['distinct_tolerance_scales']:g} of a parameter's scale), at most "
        f"{fmt(ms['max_scaled_distance_near_best'])} scales apart.",
        "",
    ]
    if worst:
        lines += [
            "Largest spread of the near-best optima (in parameter scales): "
            + ", ".join(f"{n} {fmt(v)}" for n, v in worst)
            + ".",
            "",
        ]
    if tc.get("speed_mps") is not None:
        rng = ms.get("tactical_diameter_range_m")
        lines += [
            f"Turning circles: {tc['rudder_deg']:g} deg rudder to {tc['side']} from {fmt(tc['speed_mps'])} m/s, "
            f"{fmt(tc['rps'])} rev/s (the training runs' approach)"
            + (f"; tactical diameter {fmt(rng[0])}-{fmt(rng[1])} m across the distinct optima." if rng else "."),
            "",
        ]
    elif tc.get("error"):
        lines += [f"No turning circles: {tc['error']}.", ""]
    lines += [md_table(head, rows), "", "![multistart](figures/multistart.png)", ""]
    return lines


def _step_lines(fit: dict) -> list:
    """The step-halving check (:mod:`bayesid.estimation.stepcheck`) in words, bold when the step
    is too coarse for the data (nothing for a model file from before the check)."""
    from ..estimation.stepcheck import StepCheck

    sc = fit.get("step_check")
    if not sc:
        return []
    known = {k: sc[k] for k in ("dt", "dt_check", "shift_sd", "max_shift_sd", "worst", "d2", "steps_tried") if k in sc}
    text = StepCheck(**known).sentence()
    return [f"**Step check:** {text}.", ""] if sc.get("too_coarse") else [f"Step check: {text}.", ""]


def _retime_lines(fit: dict) -> list:
    """The retimed rudder movements (``--retime``, :mod:`bayesid.estimation.retiming`) in words."""
    moves = fit.get("retimed_moves")
    if not moves:
        return []
    n = sum(len(v) for v in moves.values())
    sds = [m[1] for v in moves.values() for m in v if m[1] is not None]
    spread = f", each to within a median sd of {float(np.median(sds)):.2g} s" if sds else ""
    return [
        f"Retimed: {n} rudder movement(s) within single log intervals in {len(moves)} run(s), their times estimated "
        f"with the coefficients{spread}; the coefficients' sds count what the data leave of those times "
        "(model.json fit.retimed_moves).",
        "",
    ]


def _training_points_lines(fit: dict) -> list:
    """Training runs at different propulsion points (:func:`bayesid.models.runs.training_points`)."""
    tp = fit.get("training_points")
    if not tp or not tp.get("apart"):
        return []
    s = tp["sentence"]
    return [f"**Propulsion points:** {s[0].upper() + s[1:]}. (model.json fit.training_points)", ""]


def _nested_start_lines(fit: dict) -> list:
    """The two starts of a fit with effects that contain the model without them
    (:func:`bayesid.estimation.identification.neutral_start`) in words."""
    ns = fit.get("nested_start")
    if not ns:
        return []
    names = ", ".join(ns["effects"])
    kept = ns["kept"] == "neutral"
    return [
        f"Two starts: from the effects' start values the fit ended at SSR {fmt(ns['cost_effect_start'], 6)}; the model "
        f"without {names} fitted to {fmt(ns['cost_without'], 6)} and, from its optimum with {names} neutral, the "
        f"full model to {fmt(ns['cost_neutral_start'], 6)} (one set of channel weights). "
        + ("That second fit is kept: the effects' start led to a worse optimum." if kept else "The first is kept.")
        + " (model.json fit.nested_start)",
        "",
    ]


def _inputs_phrase(doc: dict) -> str:
    """How the fit read the logged inputs between samples, for the report's first lines (nothing
    for the default hold)."""
    how = doc.get("inputs", "hold")
    if how == "linear":
        return "; inputs interpolated linearly between samples"
    if how == "rate":
        return f"; the rudder and planes at the gear's rate ({doc.get('rudder_rate_deg_s'):g} deg/s) between samples"
    return ""
