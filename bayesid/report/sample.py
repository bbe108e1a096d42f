"""The report of ``bayesid sample`` (``report.md`` beside ``sample.json``)."""

from __future__ import annotations

from pathlib import Path

from .markdown import fmt, md_table


def write_sample_report(doc: dict, out, command: str = "") -> None:
    """Write ``report.md`` of ``bayesid sample`` from its ``sample.json`` document: method and
    verdict, cost, error model, the coefficients the data determine, move or leave at their prior,
    the sloppy directions and collinearity of the user's tracks, and the figures.

    Parameters
    ----------
    doc : dict
        The ``sample.json`` document.
    out : str or Path
        The folder written to (it exists).
    command : str
        The command line, quoted at the top of the report (none when empty).
    """
    out = Path(out)
    v, em = doc["verdict"], doc["error_model"]
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
        *_criteria_lines(doc),
        f"Cost: one evaluation of the objective takes {1e3 * doc['cost']['seconds_per_evaluation']:.1f} ms per "
        f"parameter row; stages (s): " + ", ".join(f"{k} {fmt(s, 3)}" for k, s in doc["cost"]["seconds"].items()) + ".",
        "",
        *budget_lines(doc.get("budget")),
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
        *_coefficient_lines(doc),
        *_determined_lines(doc),
    ]
    (out / "report.md").write_text("\n".join(lines))


#: How each stage of the sampling is named in the report.
STAGE_NAMES = {
    "mode": "posterior mode and Laplace covariance",
    "importance": "importance draws",
    "mcmc": "MCMC",
    "noise_scales": "noise scales of the kept MCMC draws",
}


def budget_lines(budget: dict | None) -> list:
    """The wall budget and what it cut, stage by stage (none for a document without one).

    Parameters
    ----------
    budget : dict or None
        ``sample.json``'s ``budget``: ``max_minutes``, ``seconds`` and ``stages``, each
        ``{"unit", "planned", "done", "seconds", "estimate_s", "cut"}``.

    Returns
    -------
    list of str
        Markdown lines: a sentence and a table, and a blank line.
    """
    if not budget or not budget.get("stages"):
        return []
    st = budget["stages"]
    cut = [STAGE_NAMES.get(k, k) for k, v in st.items() if v["cut"]]
    head = (
        f"Budget: {fmt(budget['max_minutes'])} min for the whole sampling (`--max-minutes`); it took "
        f"{fmt(budget['seconds'], 3)} s. "
        + (
            f"**The budget cut: {', '.join(cut)}** (the result uses what those stages had done)."
            if cut
            else "Nothing was cut."
        )
    )
    rows = [
        [
            STAGE_NAMES.get(k, k),
            f"{v['done']} of {'up to ' if v['unit'] == 'steps' else ''}{v['planned']} {v['unit']}",
            fmt(v["seconds"], 3),
            "-" if v.get("estimate_s") is None else fmt(v["estimate_s"], 3),
            "**cut**" if v["cut"] else "complete",
        ]
        for k, v in st.items()
    ]
    return [
        head,
        "",
        md_table(["stage", "done", "seconds", "estimated for all (s)", "budget"], rows),
        "",
    ]


def criterion_text(c: dict) -> str:
    """One test of the sampler's verdict in words, e.g. ``importance ESS 281 < 400 (needs >= 400)``.

    Parameters
    ----------
    c : dict
        An entry of ``verdict_criteria`` in ``sample.json``: ``criterion``, ``value``, ``test``
        (``"<"``, ``"<="``, ``">="`` or ``"meets"``), ``threshold`` and ``passed``.

    Returns
    -------
    str
        The criterion, its value and how it compares with its threshold.
    """
    if c["test"] == "meets":
        return f"{c['criterion']} {fmt(c['value'], 4)} ({'meets' if c['passed'] else 'does not meet'} {c['threshold']})"
    negate = {"<": ">=", "<=": ">", ">=": "<"}
    op = c["test"] if c["passed"] else negate[c["test"]]
    return f"{c['criterion']} {fmt(c['value'], 4)} {op} {fmt(c['threshold'], 4)}" + (
        "" if c["passed"] else f" (needs {c['test']} {fmt(c['threshold'], 4)})"
    )


def _criteria_lines(doc: dict) -> list:
    """The verdict's tests as a table, the failed ones named, and the warning when ``--draws``
    cannot reach the ESS criterion (none for a document without them)."""
    crit = doc.get("verdict_criteria") or []
    lines = []
    if crit:
        failed = [c for c in crit if not c["passed"]]
        lines += [
            md_table(
                ["criterion", "value", "needs", "result"],
                [
                    [
                        c["criterion"],
                        fmt(c["value"], 4),
                        f"{c['test']} {c['threshold'] if isinstance(c['threshold'], str) else fmt(c['threshold'], 4)}",
                        "passed" if c["passed"] else "**failed**",
                    ]
                    for c in crit
                ],
            ),
            "",
            ("Failed: " + "; ".join(criterion_text(c) for c in failed) + "." if failed else "Every criterion passed."),
            "",
        ]
    first = doc["verdict"].get("importance_first")
    if first:
        from ..estimation.sampling import ESS_BULK_MIN
        from ..estimation.track_posterior import KHAT_MAX

        lines += [
            f"MCMC ran because the importance stage that came first (--method auto) was not reliable: Pareto k-hat "
            f"{fmt(first['k_hat'], 4)} (needs < {fmt(KHAT_MAX, 4)}), importance ESS {fmt(first['ess'], 4)} "
            f"(needs >= {fmt(ESS_BULK_MIN, 4)}).",
            "",
        ]
    if doc.get("draws_warning"):
        lines += [f"**Warning**: {doc['draws_warning']}.", ""]
    return lines


def _coefficient_lines(doc: dict) -> list:
    """Prior, fit and posterior of each coefficient, and its status."""
    dos = doc["dossier"]
    coef = dos["coefficients"]
    flat = [n for n, c in coef.items() if c["prior"] != "normal"]
    return [
        "## Coefficients: prior, fit, posterior",
        "",
        f"Status: *determined* when the posterior sd is below {doc['thresholds']['determined']} x the prior sd, "
        f"*at prior* above {doc['thresholds']['at_prior']} x; z: posterior mean against a Gaussian prior, in prior sds."
        + (
            f" {', '.join(flat)}: *flat prior* (uniform in the model's bounds, or flat where they are open: no "
            "proper prior to judge against); a ratio to it would only say how wide the bounds are, so no status is "
            "given: read their posterior sd in absolute terms and as a share of the posterior mean (relative sd)."
            if flat
            else ""
        )
        + (
            ""
            if doc.get("reliable", True)
            else " **The posterior is not reliable** (the verdict above): the means and sds are those of its "
            "draws, and no 5-95 % interval is given (its draws do not hold one)."
        ),
        "",
        md_table(
            [
                "parameter",
                "prior",
                "fit",
                "posterior mean",
                "sd",
                "5-95 %",
                "relative sd (sd / abs. mean)",
                "sd / prior sd",
                "z",
                "status",
            ],
            [
                [
                    n,
                    (f"N({fmt(c['prior_mean'])}, {fmt(c['prior_sd'])})" if c["prior"] == "normal" else _flat_label(c)),
                    fmt(doc["fit_estimate"][n]),
                    fmt(c["mean"]),
                    fmt(c["sd"]),
                    f"{fmt(doc['marginals'][n]['q05'])} - {fmt(doc['marginals'][n]['q95'])}"
                    if doc["marginals"][n].get("reliable", True)
                    else "not reliable",
                    fmt(c["sd"] / abs(c["mean"]), 2) if c["mean"] else "-",
                    fmt(c["sd_ratio"], 2) if c["prior"] == "normal" else "-",
                    fmt(c["z"], 2) if c["z"] is not None else "",
                    c["status"] if c["prior"] == "normal" else "flat prior",
                ]
                for n, c in coef.items()
            ],
        ),
        "",
        f"The data moved (|z| > 1): {', '.join(dos['moved']) or 'none'}; beyond 3 prior sds: "
        f"{', '.join(dos['moved_beyond_3sd']) or 'none'}.",
        "",
    ]


def _flat_label(c: dict) -> str:
    """How a coefficient without a Gaussian prior is labelled: uniform in finite bounds, or flat."""
    return "uniform in bounds" if c.get("prior_sd") is not None else "flat (open bounds)"


def _round_off_lines(dos: dict) -> list:
    """The round-off null space of the tracks' Fisher information, when it has one: its rows are
    any basis of it, so the space is given by how much each coefficient lies in it."""
    k = dos.get("n_round_off_eigenvalues") or 0
    if not k:
        return []
    part = ", ".join(f"{n} {w:.2f}" for n, w in dos["round_off_participation"].items())
    return [
        f"{k} Fisher eigenvalue(s) are at round-off level: the tracks say nothing about the {k}-dimensional space "
        "they span, and the rows marked round-off are any basis of it. How much each coefficient lies in that "
        f"space (1 = wholly, sum = {k}): {part}.",
        "",
    ]


def _determined_lines(doc: dict) -> list:
    """What the tracks determine: sloppy directions, collinear subsets, correlations, the figures
    and the files."""
    dos = doc["dossier"]
    return [
        "## What these tracks determine",
        "",
        f"Fisher information of the tracks (parameters in units of their typical size): condition number "
        f"{fmt(dos['fim_condition_number'])}. The sloppiest directions, with the spread of the prior and of "
        "the posterior along each:",
        "",
        md_table(
            ["direction", "Cramér-Rao sd", "posterior sd", "prior sd"],
            [
                [
                    r["direction"] + (" (round-off)" if r.get("round_off") else ""),
                    fmt(r["cramer_rao_sd"]),
                    fmt(r["posterior_sd"]),
                    fmt(r["prior_sd"]),
                ]
                for r in dos["sloppy"]
            ],
        ),
        "",
        *_round_off_lines(dos),
        "Most collinear subsets (collinearity index, Brun et al. 2001; above 10-15: not separately identifiable):",
        "",
        md_table(
            ["subset", "collinearity index"], [["-".join(r["subset"]), fmt(r["gamma"])] for r in dos["collinearity"]]
        ),
        "",
        (
            "Strongest posterior correlations: "
            + ", ".join(f"{a}-{b} {r['r']:+.2f}" for r in dos["correlations"][:6] for a, b in [r["pair"]])
            + "."
            if dos["correlations"]
            else "One free coefficient: no correlations."
        ),
        "",
        "![marginals](figures/marginals.png)",
        "",
        *(["![pairs](figures/pairs.png)", ""] if dos["correlations"] else []),
        f"![{doc['figures']['sampler']}](figures/{doc['figures']['sampler']}.png)",
        "",
        "![fisher](figures/fisher.png)",
        "",
        f"Files: `posterior.nc` (ArviZ InferenceData), `sample.json`, `posterior_model.json` (the fit's model "
        f"with this posterior's mode and covariance, for `bayesid predict`). bayesid {doc['provenance']['version']}, "
        f"seed {doc['seed']}.",
        "",
    ]
