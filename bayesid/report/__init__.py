"""Report layer: output folder, manifest, JSON and markdown tables shared by the study scripts,
and the report writers of the commands (:func:`write_diagnosis` of a gap diagnosis,
:func:`write_fit_report` of ``bayesid fit``); algorithm modules write no files of their own.

The study contract (DESIGN.md): each run writes ``report.md``, ``figures/*.png``,
``results.json`` and ``manifest.json`` (command line, seed, git commit, package versions, wall
time, quick or full) into its folder.
"""

from __future__ import annotations

import json
import math
import platform
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np

from ..tasks import jsonable

PACKAGES = (
    "numpy",
    "scipy",
    "numba",
    "emcee",
    "h5py",
    "arviz",
    "pysindy",
    "matplotlib",
    "tqdm",
    "joblib",
    "dask",
    "distributed",
)


def prepare_out(out: str | Path) -> Path:
    """Create ``out`` and ``out/figures``; return ``out`` as a Path."""
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    return out


def write_json(path: str | Path, obj) -> None:
    """Write ``obj`` as indented JSON (the folder created); numpy types converted, non-finite
    floats as strings."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(jsonable(obj), indent=2) + "\n")


def git_commit() -> str:
    """Current commit hash (``+dirty`` if code outside ``reports/`` has uncommitted changes), or
    ``"unknown"``."""
    root = Path(__file__).resolve().parents[2]  # the repository (this file: bayesid/report/__init__.py)
    try:
        h = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10
        ).stdout.strip()
        # the run's own outputs under reports/ do not make the code dirty
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", ".", ":!reports"],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
        return (h + ("+dirty" if dirty else "")) if h else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def write_manifest(out: Path, *, seed: int, quick: bool, t_start: float, extra: dict | None = None) -> None:
    """Write ``manifest.json``: command line, seed, git commit, versions, wall time, quick/full."""
    versions = {}
    for p in PACKAGES:
        try:
            versions[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            versions[p] = None
    man = dict(
        command=" ".join([Path(sys.executable).name] + sys.argv),
        seed=seed,
        quick=quick,
        mode="quick" if quick else "full",
        git_commit=git_commit(),
        python=platform.python_version(),
        platform=platform.platform(),
        packages=versions,
        wall_s=time.perf_counter() - t_start,
        finished_utc=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    )
    if extra:
        man.update(extra)
    write_json(out / "manifest.json", man)


def md_table(header, rows) -> str:
    """Markdown table from a header list and row lists (values formatted by the caller)."""
    lines = ["| " + " | ".join(str(h) for h in header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def fmt(x, digits: int = 3) -> str:
    """Compact number format for reports: ``1.23e-05``, ``0.123``, ``inf``."""
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    if x == 0:
        return "0"
    if 1e-3 <= abs(x) < 1e4:
        return f"{x:.{digits}g}"
    return f"{x:.{max(digits - 1, 1)}e}"


# --- the gap diagnosis (bayesid diagnose, studies/real_ships.py) -------------------------------


def attribution_lines(res: dict) -> list[str]:
    """The verdict of a diagnosis (:meth:`bayesid.analysis.gap.Diagnosis.to_dict`) in words:
    cause, contributors (with their shares) and the remainder."""
    out = []
    if res.get("cause"):
        out.append(f"Cause: **{res['cause']}** (with it the held-out error is inside the noise-floor band).")
    for c in res.get("contributors", []):
        out.append(
            f"- Contributor **{c['effect']}** ({'added' if c['added'] else 'not added'}): removes "
            f"{fmt(c['share_of_excess'])} of the base model's excess (held-out {fmt(c['heldout_rms_m'])} m; "
            f"paired window test p = {fmt(c['window_p_value'])}, ΔBIC {fmt(c['delta_bic'], 4)})."
        )
    rem = res.get("remainder")
    if rem and res["significant_gap"]:
        out.append(
            f"Remainder: {fmt(rem['fraction_of_excess'])} of the excess over the floor "
            f"(held-out {fmt(rem['heldout_rms_m'])} m), "
            + ("still significant: no candidate explains it." if rem["significant"] else "inside the band.")
        )
    return out


def write_diagnosis(diag, out, heldout: list, command: str = "") -> None:
    """Write ``diagnosis.json``, ``report.md`` and ``figures/*.png`` of a
    :class:`bayesid.analysis.gap.Diagnosis` into the folder ``out`` (created); ``heldout``: the
    held-out Tracks (the first one's windows are plotted)."""
    from ..analysis.gap import window_xy
    from . import plots

    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    res = diag.to_dict()
    write_json(out / "diagnosis.json", res)
    figs = []
    if res["ranking"]:
        figs.append(
            plots.gap_ranking(
                res["ranking"],
                res["gap_before"]["heldout_rms_m"],
                res["noise_floor"]["heldout_rms_m"],
                out / "figures" / "ranking.png",
            )
        )
    figs.append(plots.gap_channels(res["where"], out / "figures" / "channels.png"))
    figs.append(plots.gap_regions(res["where"], out / "figures" / "regions.png"))
    if diag.base is not None and heldout:
        w = res["settings"]["window_s"]
        rule, lead = res["settings"]["start_rule"], res["settings"]["leadin_s"]
        meas, before = window_xy(diag.base.model, diag.base.fit, heldout[0], w, start=rule, leadin_s=lead)
        after = None
        if res["effects_added"]:
            anu = diag.after.nuisance
            _, after = window_xy(
                diag.after.model,
                diag.after.fit,
                heldout[0],
                w,
                None if anu is None else anu[0],
                start=rule,
                leadin_s=lead,
            )
        figs.append(
            plots.window_tracks(
                None,
                meas,
                before,
                after,
                out / "figures" / "heldout_track.png",
                title=f"{heldout[0].name}: {w} s windows",
            )
        )
    gb, ga = res["gap_before"], res["gap_after"]
    lines = [
        "# Gap diagnosis",
        "",
        f"`{command}`" if command else "",
        "",
        *(["**Input warnings:** " + "; ".join(res["warnings"]), ""] if res.get("warnings") else []),
        f"**Verdict: {res['verdict']}**"
        + (f" (effects added: {', '.join(res['effects_added'])})" if res["effects_added"] else ""),
        "",
        f"Training tracks: {', '.join(res['train_tracks'])}; held-out: {', '.join(res['heldout_tracks'])}. "
        f"Free coefficients: {', '.join(res['settings']['free']) or 'none'}. Protocol windows: "
        f"{res['settings']['window_s']} s; model step {res['settings']['dt']} s; channel weights of the fits: "
        f"{res['settings'].get('weighting', 'noise')} sds ({', '.join(f'{k} {fmt(v)}' for k, v in res.get('fit_sd', {}).items())}).",
        "",
        "## How far",
        "",
        md_table(
            [
                "",
                "train RMS (m)",
                "held-out RMS (m)",
                "held-out max (m)",
                "heading RMS (deg)",
                "train log-lik. (nats)",
                "held-out log-lik. (nats)",
            ],
            [
                [
                    label,
                    fmt(g["train_rms_m"]),
                    fmt(g["heldout_rms_m"]),
                    fmt(g["heldout_max_m"]),
                    fmt(g["heading_rms_deg"]),
                    fmt(g.get("train_log_likelihood"), 5),
                    fmt(g.get("heldout_log_likelihood"), 5),
                ]
                for label, g in (("base model", gb), ("with " + ("+".join(res["effects_added"]) or "nothing"), ga))
            ],
        ),
        "Log-likelihood: Gaussian at the fits' channel sds, samples treated as independent (a "
        "before/after comparison on the same samples, not a calibrated likelihood).",
        "",
        f"Held-out shrinkage {fmt(res['heldout_shrinkage'])}; noise floor (perfect model at the "
        f"estimated noise) {fmt(res['noise_floor']['heldout_rms_m'])} m; gap ratio "
        f"{fmt(res['gap_ratio'])} (significant above {res['thresholds']['none_ratio']}).",
        "",
        "## Which",
        "",
        md_table(
            ["effect", "held-out RMS (m)", "excess removed", "window test p", "ΔBIC (train)", "role", "parameters"],
            [
                [
                    r["effect"],
                    fmt(r["heldout_rms_m"]),
                    fmt(r["excess_removed"]),
                    fmt(r.get("window_p_value")),
                    fmt(r["delta_bic"], 4),
                    r.get("role") or "-",
                    ", ".join(f"{k} {fmt(v)}" for k, v in r["parameters"].items() if k != "per_track_nuisance"),
                ]
                for r in res["ranking"]
            ],
        ),
        "",
        *attribution_lines(res),
        "",
        f"Rules: an effect is the cause if, added, the held-out error falls within "
        f"{res['thresholds']['none_ratio']} x the floor, it removes >= {res['thresholds']['explain_fraction']} "
        f"of the excess and its ΔBIC <= {res['thresholds']['bic_threshold']}; a contributor improves the "
        f"held-out windows (paired Wilcoxon p < {res['thresholds']['partial_p']}, ΔBIC <= "
        f"{res['thresholds']['bic_threshold']}) without closing the gap and is added, the next round trying the "
        "others on top of it; `+unexplained` marks a remainder still above the band; `none`: the gap is not "
        f"significant. Window starts: {res['settings'].get('start_rule', 'measured')} rule"
        + (
            f" (lead-in {fmt(res['settings'].get('leadin_s'))} s)"
            if res["settings"].get("start_rule") == "fitted"
            else ""
        )
        + ".",
        "",
        "Sparse-regression support (ensemble STLSQ inclusion probability of each effect's force "
        "signature in the missing forces; sensor bias leaves none): "
        + ", ".join(f"{k} {fmt(v)}" for k, v in res["sindy_support"].items() if not isinstance(v, str)),
        "",
        "## Where",
        "",
        md_table(
            ["channel", "RMS", "noise sd", "floor RMS", "ratio"],
            [
                [c, fmt(d.get("rms")), fmt(d.get("noise_sd")), fmt(d.get("floor_rms")), fmt(d.get("excess_ratio"))]
                for c, d in res["where"]["channels"].items()
            ],
        ),
        "",
        f"Dominant channel: {res['where']['dominant_channel']}; dominant region: "
        f"{res['where']['dominant_region']['region']} (error growth {fmt(res['where']['dominant_region']['growth_ratio'])}"
        " x the mean).",
        "",
    ]
    ph = res["where"]["phases"]
    lines += [
        "Phases: "
        + "; ".join(
            f"{k}: {fmt(v['fraction_of_time'])} of the time, growth {fmt(v['mean_error_growth_mps'])} m/s"
            for k, v in ph.items()
        ),
        "",
    ]
    if res["where"].get("forces"):
        lines += [
            "Missing forces (RMS, inverse dynamics of the first held-out track's smoothed motion minus "
            "the fitted model): "
            + ", ".join(f"{k} {fmt(v)}" for k, v in res["where"]["forces"].items() if not isinstance(v, str)),
            "",
        ]
    if res["where"].get("wind_correlation"):
        lines += [
            "Apparent-wind dependence: correlation of the missing X, Y, N with the wind-load signatures "
            "(0.5 rho_a VA^2 A cos g, sin g) over the held-out tracks: "
            + ", ".join(f"{k} {fmt(v)}" for k, v in res["where"]["wind_correlation"].items()),
            "",
        ]
    for k, v in res["where"].get("spectrum", {}).items():
        wb = res["where"]["whiteness"].get(k, {})
        ic = res["where"]["input_correlation"].get(k, {})
        lines.append(
            f"- {k}: spectral peak at {fmt(v['peak_period_s'])} s ({fmt(v['peak_to_median'])} x median); "
            f"Ljung-Box p = {fmt(wb.get('p_value'))}; "
            + ", ".join(f"corr with {n} {fmt(c['max_abs_corr'])} at lag {fmt(c['lag_s'])} s" for n, c in ic.items())
        )
    lines += ["", *[f"![{p.stem}](figures/{p.name})" for p in figs], ""]
    (out / "report.md").write_text("\n".join(lines))


# --- bayesid fit ----------------------------------------------------------------------------


def write_fit_report(doc: dict, out, command: str = "") -> None:
    """``report.md`` of ``bayesid fit``: the identified coefficients with Laplace sds."""
    out = Path(out)
    rows = [
        [n, fmt(s0, 4), fmt(p, 4), fmt(sd, 3)]
        for n, s0, p, sd in zip(doc["param_names"], doc["start"], doc["p"], doc["sd"])
    ]
    ts = doc["train_scores"]
    warn = (doc.get("provenance") or {}).get("warnings") or []
    lines = [
        "# Identified model",
        "",
        f"`{command}`" if command else "",
        "",
        *(["**Input warnings:** " + "; ".join(warn), ""] if warn else []),
        f"Vehicle {doc['vehicle_id']}; effects: {', '.join(doc['effects']) or 'none'}; "
        f"multiple shooting over {doc['fit_window_s']} s windows, step {doc['dt']} s; "
        f"{len(doc['train_runs'])} training run(s).",
        "",
        f"Equation-error seed: {'used' if doc['seed'].get('used') else 'not used'} "
        f"(R^2 X/Y/N: {', '.join(fmt(v) for v in doc['seed'].get('r2', {}).values()) or '-'}).",
        "",
        f"Training RMS position error {fmt(ts['rms_position_m'])} m, heading {fmt(ts['rms_heading_deg'])} deg "
        f"({doc['fit_window_s']} s windows). Fit: {doc['fit']['nfev']} evaluations, {doc['fit']['message']}",
        "",
        "Posterior: Laplace approximation, residual variance x AR(1) inflation "
        f"{fmt(doc['posterior']['ar1_inflation'])}; Jacobian condition number "
        f"{fmt(doc['posterior']['condition_number'])}.",
        "",
        md_table(["parameter", "start", "identified", "sd (Laplace)"], rows),
        "",
    ]
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
    cal = doc.get("calibration")
    if cal:
        from ..estimation.calibration import (
            EXCITATION_MEASURES,
            LEVELS,
            conformal_quantile,
            excitation_range,
            index_scores,
            window_band,
        )

        failed = [f for f in cal["folds"] if "error" in f]
        wb = {a: window_band(cal, a) for a in LEVELS}
        kappa, scores = index_scores(cal)
        keys = sorted(scores)
        lines += [
            "## Calibration of the predictive bands",
            "",
            f"{cal['method']}: {cal['n_runs']} runs in {cal['n_folds']} folds"
            + (
                f" ({len(failed)} failed: " + "; ".join(f"{', '.join(f['runs'])}: {f['error']}" for f in failed) + ")"
                if failed
                else ""
            )
            + f"; {len(cal['window_scores']['max_position_m'])} windows of {cal['window_s']:g} s and "
            f"{sum(len(v) for v in scores.values())} manoeuvre indices scored on the left-out runs "
            f"({cal['n_draws']} posterior draws per fold). `bayesid predict --window {cal['window_s']:g}` reports "
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
                    "The bands are calibrated for runs like these (95th percentiles of |delta_r| and |r|): "
                    + ", ".join(
                        f"{label} {xr[key][0]:.3g}-{xr[key][1]:.3g} {unit}"
                        for key, label, unit in EXCITATION_MEASURES
                        if key in xr
                    )
                    + "; `predict` names a run outside 0.8x-1.25x this range.",
                    "",
                ]
                if (xr := excitation_range(cal))
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
        ]
    ms = doc.get("multistart")
    if ms:
        lines += _multistart_lines(ms)
    (out / "report.md").write_text("\n".join(lines))


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


# --- bayesid sample ---------------------------------------------------------------------------


def write_sample_report(doc: dict, out, command: str = "") -> None:
    """``report.md`` of ``bayesid sample`` from its ``sample.json`` document: method and verdict,
    cost, error model, the coefficients the data determine, move or leave at their prior, the
    sloppy directions and collinearity of the user's tracks, and the figures."""
    out = Path(out)
    v, em, dos = doc["verdict"], doc["error_model"], doc["dossier"]
    lines = [
        "# Posterior of the model's parameters given the training tracks",
        "",
        f"`{command}`" if command else "",
        "",
        f"Tracks: {', '.join(doc['train_runs'])} ({doc['cost']['n_windows']} windows of {doc['window_s']:g} s). "
        f"Start states of the windows: {doc['start_states']}.",
        "",
        "## Method and verdict",
        "",
        f"Method: **{doc['method_label']}** (requested: {doc['method_requested']}). {v['text']}",
        "",
        f"Cost: one evaluation of the objective takes {1e3 * doc['cost']['seconds_per_evaluation']:.1f} ms per "
        f"parameter row; stages (s): " + ", ".join(f"{k} {fmt(s, 3)}" for k, s in doc["cost"]["seconds"].items()) + ".",
        "",
        "## Error model",
        "",
        "Per channel, the integrated autocorrelation time of the errors within a window (Geyer's initial "
        "positive sequence; (1 + rho) / (1 - rho) for AR(1) errors with lag-1 correlation rho) gives the variance "
        "inflation, capped at the samples per window, and n / inflation independent errors of evidence. The "
        "noise scale is integrated out (Jeffreys prior) and drawn afterwards.",
        "",
        md_table(
            ["channel", "samples", "rho", "inflation", "effective samples", "sigma (5-95 %)"],
            [
                [
                    c,
                    e["n"],
                    fmt(e["rho"], 4),
                    fmt(e["inflation"]),
                    fmt(e["n_eff"]),
                    f"{fmt(e['sigma_posterior']['q05'])} - {fmt(e['sigma_posterior']['q95'])} {e['unit']}",
                ]
                for c, e in em.items()
            ],
        ),
        "",
        (
            f"Between runs: the leave-one-run-out estimates of the fit's calibration ({doc['between_runs']['n_folds']} "
            f"folds) scatter {doc['between_runs']['median_ratio']:.2f} x the posterior variance (median over the "
            "parameters, jackknife); "
            + (
                "the effective samples above are divided by that factor."
                if doc["between_runs"]["factor"] > 1
                else "no widening needed."
            )
            + " Parameters that scatter more than their posterior sd says (variance ratio > 1): "
            + (
                ", ".join(
                    f"{n} {r:.2f}" for n, r in doc["between_runs"]["per_parameter"].items() if r is not None and r > 1
                )
                or "none"
            )
            + "."
            if doc["between_runs"]["n_folds"]
            else "Between runs: no leave-one-run-out folds in the model (fewer than 3 runs, or --calibration none): "
            "the posterior is not widened for the scatter between runs."
        ),
        "",
        "## Coefficients: prior, fit, posterior",
        "",
        f"Status: *determined* when the posterior sd is below {doc['thresholds']['determined']} x the prior sd, "
        f"*at prior* above {doc['thresholds']['at_prior']} x; z: posterior mean against a Gaussian prior, in prior sds.",
        "",
        md_table(
            ["parameter", "prior", "fit", "posterior mean", "sd", "5-95 %", "sd / prior sd", "z", "status"],
            [
                [
                    n,
                    (
                        f"N({fmt(c['prior_mean'])}, {fmt(c['prior_sd'])})"
                        if c["prior"] == "normal"
                        else "uniform in bounds"
                    ),
                    fmt(doc["fit_estimate"][n]),
                    fmt(c["mean"]),
                    fmt(c["sd"]),
                    f"{fmt(doc['marginals'][n]['q05'])} - {fmt(doc['marginals'][n]['q95'])}",
                    fmt(c["sd_ratio"], 2),
                    fmt(c["z"], 2) if c["z"] is not None else "",
                    c["status"],
                ]
                for n, c in dos["coefficients"].items()
            ],
        ),
        "",
        f"The data moved (|z| > 1): {', '.join(dos['moved']) or 'none'}; beyond 3 prior sds: "
        f"{', '.join(dos['moved_beyond_3sd']) or 'none'}.",
        "",
        "## What these tracks determine",
        "",
        f"Fisher information of the tracks (parameters in units of their typical size): condition number "
        f"{fmt(dos['fim_condition_number'])}. The sloppiest directions, with the spread of the prior and of "
        "the posterior along each:",
        "",
        md_table(
            ["direction", "Cramér-Rao sd", "posterior sd", "prior sd"],
            [
                [r["direction"], fmt(r["cramer_rao_sd"]), fmt(r["posterior_sd"]), fmt(r["prior_sd"])]
                for r in dos["sloppy"]
            ],
        ),
        "",
        "Most collinear subsets (collinearity index, Brun et al. 2001; above 10-15: not separately identifiable):",
        "",
        md_table(
            ["subset", "collinearity index"], [["-".join(r["subset"]), fmt(r["gamma"])] for r in dos["collinearity"]]
        ),
        "",
        "Strongest posterior correlations: "
        + ", ".join(f"{a}-{b} {r['r']:+.2f}" for r in dos["correlations"][:6] for a, b in [r["pair"]])
        + ".",
        "",
        "![marginals](figures/marginals.png)",
        "",
        "![pairs](figures/pairs.png)",
        "",
        f"![{doc['figures']['sampler']}](figures/{doc['figures']['sampler']}.png)",
        "",
        "![fisher](figures/fisher.png)",
        "",
        f"Files: `posterior.nc` (ArviZ InferenceData), `sample.json`, `posterior_model.json` (the fit's model "
        f"with this posterior's mode and covariance, for `bayesid predict`). bayesid {doc['provenance']['version']}, "
        f"seed {doc['seed']}.",
        "",
    ]
    (out / "report.md").write_text("\n".join(lines))
