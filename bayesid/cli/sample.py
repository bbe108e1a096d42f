"""``bayesid sample``: the posterior of a fitted model's parameters given its training tracks,
written as ``sample.json``, ``posterior.nc``, ``report.md``, figures and
``posterior_model.json`` (the fit's model with this posterior, for ``bayesid predict``)."""

from __future__ import annotations

import sys
from pathlib import Path

from .. import tasks
from . import options as opt
from .inputs import free_list, naming_files, read_tracks
from .outputs import check_out
from .provenance import check_vehicle_unchanged, file_sha256, provenance, vehicle_ref

#: Units of each scored channel in reports: (factor from SI, label).
UNITS = {
    "x": (1.0, "m"),
    "y": (1.0, "m"),
    "psi": (57.29577951308232, "deg"),
    "u": (1.0, "m/s"),
    "v": (1.0, "m/s"),
    "r": (57.29577951308232, "deg/s"),
}


def add_parser(sub) -> None:
    """Declare ``bayesid sample`` and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    """
    sm = opt.add_subcommand(sub, "sample", "posterior of a fitted model's parameters given its training tracks")
    sm.add_argument("--model", default=None, help="model.json written by bayesid fit (or give --vehicle to fit first)")
    opt.add_vehicle(sm, "packaged id or TOML path: fit first with bayesid fit's defaults", default=None)
    opt.add_free(sm, "with --vehicle: comma-separated free coefficients")
    opt.add_effects(sm, "with --vehicle: comma-separated effects in the model")
    opt.add_tracks(sm, "--train", "the training Track CSVs")
    sm.add_argument(
        "--method",
        choices=("auto", "importance", "mcmc"),
        default="auto",
        help="importance: importance-reweighted Laplace; mcmc: emcee ensembles until converged; auto: "
        "importance, then MCMC when its Pareto k-hat >= 0.7 or ESS < 400",
    )
    opt.add_number(
        sm,
        "--draws",
        opt.NON_NEGATIVE,
        opt.at_least(100),
        kind=int,
        default=4000,
        help="importance draws (and posterior draws kept)",
    )
    positive = (lambda v: v > 0, "{option} must be positive, not {value:g}")
    opt.add_number(sm, "--df", positive, default=5.0, help="degrees of freedom of the Student-t proposal")
    opt.add_number(
        sm,
        "--max-minutes",
        positive,
        default=20.0,
        help="wall budget of the whole sampling (mode, importance draws, MCMC), min: a stage the budget ends keeps "
        "what it has, and sample.json's budget says what was cut",
    )
    opt.add_number(
        sm,
        "--max-steps",
        (lambda v: v >= 1, "{option} must be at least 1, not {value:g}"),
        kind=int,
        default=None,
        help="step budget of the MCMC refinement, steps per walker (reproducible on any machine, unlike "
        "--max-minutes); default: until converged",
    )
    opt.add_seed(sm, "random seed of every draw")
    opt.add_prior(
        sm, "file: Gaussian priors of the vehicle file's [prior] section; none: uniform in the model's bounds"
    )
    opt.add_jobs(sm)
    opt.add_out(sm, "output folder (resumed when it holds a killed run's journal)")
    opt.add_overwrite(sm)


def run(args) -> int:
    """Run ``bayesid sample`` on the model of ``--model``, or of a fit with ``bayesid fit``'s
    defaults of ``--vehicle`` (written to ``--out/fit``).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.

    Returns
    -------
    int
        The exit code (0).
    """
    from ..estimation.modelfile import load_model
    from ..models import load_any_vehicle

    if (args.model is None) == (args.vehicle is None):
        raise ValueError("give --model (a model.json of bayesid fit) or --vehicle (fit first), not both or neither")
    tasks.check_jobs(args.jobs, args.scheduler)
    out = check_out(args.out, "sample", args.overwrite, resumable=True)
    if args.model is not None:
        model, p, _cov, doc = load_model(args.model)
        check_vehicle_unchanged(doc, model.vehicle, args.model, False)
        got = read_tracks([("--train", args.train)], model.vehicle)
        fitted = set((doc.provenance.get("input_sha256") or {}).values())
        other = [f for f, h in got["_sha256"].items() if fitted and h not in fitted]
        if other:
            w = f"{', '.join(other)}: not among the tracks {args.model} was fitted on; the posterior is over these tracks"
            print(f"warning: {w}", file=sys.stderr)
            got["_warnings"].append(w)
        if doc.fit.get("retimed_moves"):
            w = (
                f"{args.model} was fitted with --retime: the posterior here reads every rudder movement within one "
                "log interval at its middle (--inputs rate), not at the fitted times, and does not count their "
                "uncertainty; the fit's Laplace covariance does"
            )
            print(f"warning: {w}", file=sys.stderr)
            got["_warnings"].append(w)
        model_sha = file_sha256(args.model)
    else:
        vehicle_arg = args.vehicle
        vehicle = load_any_vehicle(vehicle_arg)
        got = read_tracks([("--train", args.train)], vehicle)
        with naming_files(got):
            model, p, doc, model_sha = _fit_first(args, vehicle, got, out)
    draws_note = _draws_warning(args.method, args.draws)
    if draws_note:
        print(f"warning: {draws_note}", file=sys.stderr)
    with naming_files(got):
        res, rule = _sample(args, model, p, doc, got, model_sha, out)
        sdoc = _document(args, (model, p, doc, model_sha), got, res, rule, out)
        sdoc["draws_warning"] = draws_note
        _write(args, res, sdoc, (p, doc), model_sha, out)
    return 0


def _draws_warning(method: str, draws: int) -> str | None:
    """The warning when ``--draws`` cannot reach the importance stage's ESS criterion at all (its
    ESS is at most the number of draws); None when it can, or for MCMC (whose ESS is over the
    chains, not the draws kept)."""
    from ..estimation.sampling import ESS_BULK_MIN

    if method == "mcmc" or draws >= ESS_BULK_MIN:
        return None
    return (
        f"--draws {draws} cannot reach the ESS criterion (ESS >= {ESS_BULK_MIN:.0f}): an importance ESS is at most "
        f"the number of draws, so the importance stage is never judged reliable"
        + ("; --method auto goes on to MCMC" if method == "auto" else "")
        + f"; give --draws {ESS_BULK_MIN:.0f} or more (a few times more when the weights are uneven)"
    )


def _criteria(res) -> list:
    """The tests of the sampler's verdict, each with its value, threshold and result: Pareto
    k-hat and importance ESS for the importance stage; R-hat, bulk and tail ESS and the
    autocorrelation-time rule for MCMC (:func:`bayesid.estimation.sampling.diagnostics`)."""
    from ..estimation.sampling import ESS_BULK_MIN, ESS_TAIL_MIN, RHAT_MAX
    from ..estimation.track_posterior import TRACK_SAMPLER as cfg

    v = res.verdict
    if v["method"] == "importance":
        rows = [
            ("Pareto k-hat", v["k_hat"], "<", v["k_hat_max"], v["k_hat"] < v["k_hat_max"]),
            ("importance ESS", v["ess"], ">=", v["ess_min"], v["ess"] >= v["ess_min"]),
        ]
    else:
        r = res.mcmc["result"]
        rows = [
            ("R-hat (max over parameters)", v["rhat_max"], "<=", RHAT_MAX, v["rhat_max"] <= RHAT_MAX),
            (
                "bulk ESS (min over parameters)",
                v["ess_bulk_min"],
                ">=",
                ESS_BULK_MIN,
                v["ess_bulk_min"] >= ESS_BULK_MIN,
            ),
            (
                "tail ESS (min over parameters)",
                v["ess_tail_min"],
                ">=",
                ESS_TAIL_MIN,
                v["ess_tail_min"] >= ESS_TAIL_MIN,
            ),
            (
                "steps / autocorrelation time",
                r.n_steps / v["tau_max"] if v["tau_max"] > 0 else None,
                "meets",
                f"the tau rule: >= {cfg.tau_factor:g} tau and >= {cfg.min_steps} steps",
                bool(r.reached_tau_rule),
            ),
        ]
    return [
        {"criterion": n, "value": None if x is None else float(x), "test": op, "threshold": th, "passed": bool(ok)}
        for n, x, op, th, ok in rows
    ]


def _flat_prior_status(dos: dict) -> None:
    """Relabel, in place, the dossier's coefficients without a Gaussian prior: "determined"
    relative to a flat prior only says the bounds are wide. Their status becomes ``flat prior``,
    ``sd_ratio`` None when the bounds are open (a ratio to an infinite sd), and ``relative_sd``
    (posterior sd / |posterior mean|) is added to every coefficient."""
    for c in dos["coefficients"].values():
        c["relative_sd"] = c["sd"] / abs(c["mean"]) if c["mean"] else None
        if c["prior"] != "normal":
            c["status"] = "flat prior"
            if c["prior_sd"] is None:
                c["sd_ratio"] = None


def _fit_first(args, vehicle, got: dict, out: Path):
    """Fit with ``bayesid fit``'s defaults, written as ``out/fit/model.json``; returns the model
    as read back, its parameters, its document and the file's SHA-256."""
    import warnings

    from ..data.validate import BayesidWarning
    from ..estimation.identification import identify
    from ..estimation.modelfile import ModelDocument, load_model
    from ..estimation.options import FitOptions
    from ..report.fit import budget_advice, budget_exhausted

    print("  fitting first (bayesid fit with its defaults)", flush=True)
    options = FitOptions(
        free=free_list(vehicle, args.free),
        effects=opt.split_names(args.effects, "--effects"),
        prior=args.prior == "file",
    )
    with warnings.catch_warnings():  # the files' checks were printed on reading them
        warnings.simplefilter("ignore", BayesidWarning)
        res = identify(
            vehicle,
            got["--train"],
            options,
            runner=tasks.Runner(args.jobs, args.scheduler, progress=lambda m: print(f"  {m}", flush=True)),
        )
    fdoc = ModelDocument.from_identify(
        res,
        vehicle_ref(args.vehicle),
        [t.name for t in got["--train"]],
        provenance=dict(provenance(vehicle, got["_sha256"]), warnings=got["_warnings"]),
    )
    fdoc.fit["max_nfev"] = options.max_nfev
    fdoc.to_json(out / "fit" / "model.json")
    if budget_exhausted(fdoc.fit):
        print(
            f"warning: the fit made first: {budget_advice(fdoc.fit)}; sample has no --max-nfev: run bayesid fit "
            "with it, then bayesid sample --model",
            file=sys.stderr,
        )
    model, p, _cov, doc = load_model(out / "fit" / "model.json")
    model_sha = file_sha256(out / "fit" / "model.json")
    return model, p, doc, model_sha


def _sample(args, model, p, doc, got: dict, model_sha: str, out: Path):
    """The posterior draws (resumable through ``out/journal.jsonl`` and ``out/chains.h5``) and
    the window start rule."""
    from ..estimation import track_posterior as tp
    from ..estimation.sampling import Checkpoint
    from ..estimation.windows import WindowProblem
    from ..protocol import resolve_start

    train = got["--train"]
    rule = resolve_start(doc.start_rule, train)
    identity = {
        "command": "sample",
        "model_sha256": model_sha,
        "inputs": sorted(got["_sha256"].values()),
        "seed": args.seed,
        "method": args.method,
        "draws": args.draws,
        "df": args.df,
        "prior": args.prior,
        # the start states' profile changes the draws' log posterior: a journal of the other one is refused
        "start_profile": "linearised" if rule == "fitted" else "measured",
    }
    journal = tasks.Journal(out / "journal.jsonl", identity)
    problem = WindowProblem(
        model, [model.context(t, doc.fit_window_s, start=rule) for t in train], doc.fit_sd, doc.fit_channels
    )
    res = tp.sample_tracks(
        problem,
        p,
        tp.SampleOptions(
            method=args.method,
            use_prior=args.prior == "file",
            seed=args.seed,
            max_minutes=args.max_minutes,
            max_steps=args.max_steps,
        ),
        importance=tp.ImportanceOptions(n_draws=args.draws, df=args.df),
        folds=doc.calibration.fold_optima() if doc.calibration is not None else [],
        checkpoint=Checkpoint(out / "chains.h5", identity),
        runner=tasks.Runner(args.jobs, args.scheduler, journal, progress=lambda m: print(f"  {m}", flush=True)),
    )
    return res, rule


def _error_model(res) -> dict:
    """The error model of each channel in report units, with the posterior of its noise scale."""
    import numpy as np

    em = res.errors.to_dict()
    for j, c in enumerate(res.errors.channels):
        f, unit = UNITS.get(c, (1.0, ""))
        s = res.sigma[:, j] * f
        em[c]["unit"] = unit
        em[c]["sigma_at_mode"] *= f
        em[c]["sigma_posterior"] = {
            "mean": float(np.mean(s)),
            "q05": float(np.quantile(s, 0.05)),
            "q95": float(np.quantile(s, 0.95)),
        }
    return em


def _document(args, fitted: tuple, got: dict, res, rule: str, out: Path) -> dict:
    """The ``sample.json`` document: method and verdict, cost, error model, prior, fit, mode,
    marginals and the identifiability dossier of the tracks (``fitted``: the model, its
    parameters, its document and the model file's SHA-256)."""
    import numpy as np

    from .. import __version__
    from ..analysis.dossier import AT_PRIOR, DETERMINED, data_dossier
    from ..estimation import track_posterior as tp

    model, p, doc, model_sha = fitted
    names, draws, prior = res.names, res.draws, res.prior
    train = got["--train"]
    scales = model.scales()
    dos = data_dossier(
        names,
        res.mode["fisher"],
        res.mode["jac"],
        scales,
        prior,
        draws,
    )
    _flat_prior_status(dos)
    q05, q95 = np.quantile(draws, [0.05, 0.95], axis=0)
    reliable = bool(res.verdict["converged"])
    em = _error_model(res)
    label = {
        "importance": f"importance-reweighted Laplace ({args.draws} multivariate Student-t draws, df {args.df:g}, "
        "Pareto-smoothed weights, resampled)",
        "mcmc": f"MCMC ({tp.TRACK_SAMPLER.n_ensembles} independent emcee ensembles, "
        f"{tp.TRACK_SAMPLER.moves.upper()} moves, run until converged or the budget)",
    }[res.method]
    return {
        "format": "bayesid-sample-1",
        "model": str(args.model) if args.model else str(out / "fit" / "model.json"),
        "vehicle": doc.vehicle,
        "train_runs": [t.name for t in train],
        "input_sha256": got["_sha256"],
        "warnings": got["_warnings"],
        "seed": args.seed,
        "method_requested": args.method,
        "method": res.method,
        "method_label": label,
        "n_draws": int(draws.shape[0]),
        # importance: the draws whose posterior was evaluated (the budget may end the stage early); the
        # n_draws above are resampled from them
        "n_draws_evaluated": int((res.importance or {}).get("done", draws.shape[0]))
        if res.method == "importance"
        else int(draws.shape[0]),
        "df": args.df,
        "window_s": doc.fit_window_s,
        "start_rule": rule,
        "start_states": (
            "measured (causal 1 s estimate at each window start)"
            if rule == "measured"
            else "profiled: fitted for every parameter draw, as in the fit"
            + (
                ", continued from the posterior mode's (a Gauss-Newton step with the start-state Jacobian carried to "
                "the draw where it would still gain more than 0.01 nats, the full fit where it would keep gaining)"
                if res.budget.get("start_profile") == "linearised"
                else ""
            )
            + f" (6 per window; sampling them would add {6 * res.n_windows} dimensions)"
        ),
        "verdict": res.verdict,
        "reliable": reliable,
        "verdict_criteria": _criteria(res),
        "cost": {
            "seconds_per_evaluation": res.seconds_per_evaluation,
            "n_windows": res.n_windows,
            "n_parameters": len(names),
            "seconds": res.seconds,
        },
        "budget": res.budget,
        "error_model": em,
        "between_runs": dict(res.between_runs, per_parameter=dict(zip(names, res.between_runs["per_parameter"]))),
        "prior": {
            "used": args.prior == "file",
            "source": getattr(model.vehicle, "prior_source", ""),
            **prior.to_dict(),
        },
        "fit_estimate": dict(zip(names, map(float, p))),
        "mode": dict(zip(names, map(float, res.mode["p"]))),
        "laplace_sd": dict(zip(names, map(float, np.sqrt(np.diag(res.mode["cov"]))))),
        "marginals": {
            n: {
                "mean": float(draws[:, j].mean()),
                "sd": float(draws[:, j].std(ddof=1)),
                "q05": float(q05[j]),
                "q95": float(q95[j]),
                "reliable": reliable,
            }
            for j, n in enumerate(names)
        },
        "thresholds": {"determined": DETERMINED, "at_prior": AT_PRIOR},
        "dossier": dos,
        "figures": {"sampler": "trace" if res.method == "mcmc" else "weights"},
        "provenance": {
            "version": __version__,
            "command": "bayesid " + " ".join(sys.argv[1:]),
            "model_sha256": model_sha,
        },
    }


def _write(args, res, sdoc: dict, fitted: tuple, model_sha: str, out: Path) -> None:
    """``posterior.nc``, the figures, ``posterior_model.json``, ``sample.json`` and ``report.md``."""
    from .. import __version__
    from ..estimation import track_posterior as tp
    from ..report import write_json, write_sample_report
    from ..report.sample import criterion_text

    idata = tp.inference_data(
        res, {"bayesid_version": __version__, "seed": args.seed, "method": res.method, "model_sha256": model_sha}
    )
    tmp = out / "posterior.nc.part"
    idata.to_netcdf(str(tmp))
    tmp.replace(out / "posterior.nc")
    p, doc = fitted
    _figures(res, sdoc["dossier"], p, out / "figures")
    _posterior_model(res, doc, out).to_json(out / "posterior_model.json")
    write_json(out / "sample.json", sdoc)
    write_sample_report(sdoc, out, command=sdoc["provenance"]["command"])
    failed = [c for c in sdoc["verdict_criteria"] if not c["passed"]]
    print(
        f"{res.verdict['text']}"
        + (f" Failed: {'; '.join(criterion_text(c) for c in failed)}." if failed else "")
        + f" wrote {out / 'sample.json'}"
    )
    if sdoc["draws_warning"]:
        print(f"warning: {sdoc['draws_warning']}", file=sys.stderr)


def _figures(res, dos: dict, p, figs: Path) -> None:
    """Prior and posterior marginals, the most correlated pairs, the sampler's trace or weights,
    and the Fisher information's spectrum."""
    from ..report import plots

    names, draws, prior = res.names, res.draws, res.prior
    figs.mkdir(parents=True, exist_ok=True)
    pdict = prior.to_dict()
    plots.prior_posterior_marginals(draws, names, pdict, figs / "marginals.png", dict(zip(names, p)))
    pairs = [tuple(r["pair"]) for r in dos["correlations"][:3]]
    if pairs:  # none with one free coefficient
        plots.pair_scatter(draws, names, pairs, figs / "pairs.png", title="Most correlated coefficients (posterior)")
    if res.method == "mcmc":
        r = res.mcmc["result"]
        show = list(dict.fromkeys([a for pr in pairs for a in pr]))[:6]
        plots.walker_traces(r.chains, names, show, figs / "trace.png", burn=res.mcmc["burn"])
    else:
        imp = res.importance
        plots.importance_weights(imp["weights"], imp["k_hat"], imp["ess"], figs / "weights.png")
    plots.fim_spectra(
        {"these tracks": dos["fisher_eigenvalues"]},
        figs / "fisher.png",
        title="Fisher information of the tracks",
        ylabel="Cramér–Rao sd along it (in typical sizes of the parameters)",
    )


def _posterior_model(res, doc, out: Path):
    """The fit's model document with this posterior's mode and covariance: predict draws from it."""
    import numpy as np

    ok = bool(res.verdict["converged"])
    source = {"sample": str(out / "sample.json"), "method": res.method, "converged": ok, "reliable": ok}
    return doc.with_posterior(res.mode["p"], np.cov(res.draws, rowvar=False), source)
