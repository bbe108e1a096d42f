"""``bayesid fit``: multiple-shooting identification of a model on training tracks, written as
``model.json`` with ``report.md`` (and the multistart figure)."""

from __future__ import annotations

import sys

from .. import tasks
from . import options as opt
from .inputs import free_list, naming_files, read_tracks
from .outputs import check_out
from .provenance import provenance, vehicle_ref


def add_parser(sub) -> None:
    """Declare ``bayesid fit`` and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    """
    f = opt.add_subcommand(sub, "fit", "identify a model on training tracks (multiple shooting)")
    opt.add_vehicle(f, "packaged id or TOML path (ship or submarine)", required=True)
    opt.add_tracks(f, "--train", "training Track CSVs")
    opt.add_free(f, "comma-separated free coefficients (empty: the vehicle's)")
    opt.add_effects(f, "comma-separated effects in the model (ships: wind, current, delay)")
    opt.add_fit_window(
        f,
        (lambda v: v > 0, "{option} must be a positive number of seconds, not {value:g}"),
        default=None,
        help="fit window: the multiple-shooting window of the fit, s (none: 15 for a ship, "
        "bayesid.models.ship.FIT_WINDOW_S; 30 for a submarine)",
        dest="window",
        alias=True,
    )
    opt.add_dt(
        f,
        None,
        "model step, s (none: 0.2 ships, 0.5 submarines, halved for a small or fast one until it is at most 0.18 "
        "of its length over its nominal speed), or 'auto': from that, halved and refitted while "
        "halving it moves the estimate by more than 0.5 sd (every fit reports that check)",
        auto=True,
    )
    opt.add_max_nfev(f, "least-squares iterations")
    opt.add_weighting(f)
    f.add_argument(
        "--fit-channels",
        default="",
        help="comma-separated scored channels in the objective, e.g. "
        "x,y,psi when the logged u, v, r are derived from positions and heading (empty: all measured)",
    )
    opt.add_start(f)
    opt.add_inputs(f)
    f.add_argument(
        "--retime",
        action="store_true",
        help="with --inputs rate: estimate, with the coefficients, when each rudder movement that lies within one log "
        "interval happened (a fast actuator's or a logged order's closed-loop reversals), and widen the coefficients' "
        "intervals by what the data leave of those times; model.json records them (fit.retimed_moves)",
    )
    opt.add_number(
        f,
        "--starts",
        opt.NON_NEGATIVE,
        kind=int,
        default=0,
        help="extra Latin-hypercube starts of a multistart fit (the lowest cost is kept; the report shows "
        "how many reach it and how far apart the near-best optima are)",
    )
    opt.add_seed(f, "random seed of the multistart starts and calibration draws")
    f.add_argument(
        "--calibration",
        choices=("loro", "none"),
        default="loro",
        help="loro: with 3 or more training runs, calibrate the predictive bands leave one run out (refit "
        "without each run, score the prediction of it); predict then reports bands that include the "
        "model's structural error",
    )
    opt.add_number(
        f,
        "--calibration-window",
        (lambda v: v > 0, "{option} must be positive, not {value:g}"),
        default=60.0,
        help="scoring window (s) of the calibrated window bands (predict --score-window must match)",
    )
    opt.add_number(
        f, "--calibration-draws", opt.at_least(3), kind=int, default=40, help="posterior draws per calibration fold"
    )
    opt.add_prior(
        f,
        "file: Gaussian priors of the vehicle file's [prior] section (captive-test values with their "
        "error), a MAP fit; none: the data alone",
    )
    opt.add_jobs(f)
    opt.add_out(f, "output folder (model.json, report.md)")
    opt.add_overwrite(f)


def run(args) -> int:
    """Run ``bayesid fit``: ``model.json`` and ``report.md`` in ``--out``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.

    Returns
    -------
    int
        The exit code (0).
    """
    from ..models import load_any_vehicle

    tasks.check_jobs(args.jobs, args.scheduler)
    out = check_out(args.out, "fit", args.overwrite, resumable=bool(args.starts) or args.calibration == "loro")
    vehicle = load_any_vehicle(args.vehicle)
    free = free_list(vehicle, args.free)
    got = read_tracks([("--train", args.train)], vehicle)
    with naming_files(got):
        res, doc = _identify(args, out, vehicle, free, got)
        doc.fit["max_nfev"] = args.max_nfev
        _write(res, doc, got["--train"], out)
    return 0


def _identify(args, out, vehicle, free, got):
    """The fit (resumable through ``out/journal.jsonl`` with multistart or calibration) and its
    model document."""
    import warnings

    from ..data.validate import BayesidWarning
    from ..estimation.identification import identify
    from ..estimation.modelfile import ModelDocument
    from ..estimation.options import CalibrationOptions, FitOptions

    train = got["--train"]
    options = FitOptions(
        free=free,
        effects=opt.split_names(args.effects, "--effects"),
        window_s=args.window,
        dt=None if args.dt == "auto" else args.dt,
        refine_step=args.dt == "auto",
        max_nfev=args.max_nfev,
        weighting=args.weighting or None,
        channels=opt.split_names(args.fit_channels, "--fit-channels") or None,
        start=args.start,
        starts=args.starts,
        random_seed=args.seed,
        prior=args.prior == "file",
        inputs=args.inputs,
        rudder_rate_deg_s=args.rudder_rate,
        retime=args.retime,
    )
    calibration = None
    if args.calibration == "loro" and len(train) >= 3:
        calibration = CalibrationOptions(window_s=args.calibration_window, draws=args.calibration_draws, seed=args.seed)
    journal = None
    if args.starts or calibration is not None:
        # finished starts and folds survive a killed run: the same command resumes them
        journal = tasks.Journal(
            out / "journal.jsonl",
            {
                "command": "fit",
                "inputs": sorted(got["_sha256"].values()),
                "vehicle": provenance(vehicle, {})["vehicle_sha256"] or args.vehicle,
                "fit": options.to_dict(),
                "calibration": None if calibration is None else calibration.to_dict(),
            },
        )
    with warnings.catch_warnings():  # the command prints its own (the files' checks, the step check)
        warnings.simplefilter("ignore", BayesidWarning)
        res = identify(
            vehicle,
            train,
            options,
            calibration,
            runner=tasks.Runner(args.jobs, args.scheduler, journal, progress=lambda m: print(f"  {m}", flush=True)),
        )
    doc = ModelDocument.from_identify(
        res,
        vehicle_ref(args.vehicle),
        [t.name for t in train],
        provenance=dict(provenance(vehicle, got["_sha256"]), warnings=got["_warnings"]),
    )
    return res, doc


def _write(res, doc, train, out) -> None:
    """``model.json``, ``report.md`` and, for a multistart fit, its turning circles and figure."""
    from ..estimation.laplace import covariance_sentence
    from ..estimation.prediction import FittedModel, training_turns
    from ..report import write_fit_report
    from ..report.fit import budget_advice, budget_exhausted, coefficients_at_bound, training_turn_sentence

    circles = None
    if res.multistart is not None:
        circles = _multistart_circles(res, doc, train)
    doc.training_turns = training_turns(FittedModel(res.model, res.fit.p, None), train) or None
    doc.to_json(out / "model.json")
    figures = _training_figures(res, train, out / "figures")
    write_fit_report(doc.to_dict(), out, command="bayesid " + " ".join(sys.argv[1:]), training_figures=figures)
    if res.multistart is not None:
        from ..report import plots

        plots.multistart(doc.multistart, circles, out / "figures" / "multistart.png")
    print(
        f"training RMS position {res.train_scores['rms_position_m']:.3f} m over {res.window_s:g} s windows; "
        f"wrote {out / 'model.json'}"
    )
    if budget_exhausted(doc.fit):
        print(f"warning: {budget_advice(doc.fit)} (see {out / 'report.md'})", file=sys.stderr)
    if res.step_check is not None and res.step_check.too_coarse:
        print(f"warning: {res.step_check.sentence()} (see {out / 'report.md'})", file=sys.stderr)
    if covariance_sentence(res.posterior):
        print(f"warning: {covariance_sentence(res.posterior)} (see {out / 'report.md'})", file=sys.stderr)
    bound = coefficients_at_bound(res.fit.at_bound)
    if bound:
        print(
            f"warning: the fit left {', '.join(bound)} on a bound: the runs ask for more than its range allows, and "
            f"its estimate and sd are the bound's (see {out / 'report.md'})",
            file=sys.stderr,
        )
    points = res.training_points or {}
    if points.get("apart"):
        print(f"warning: {points['sentence']} (see {out / 'report.md'})", file=sys.stderr)
    for turn in doc.training_turns or []:
        if turn["reproduced"] is False:
            print(f"warning: {training_turn_sentence(turn)} (see {out / 'report.md'})", file=sys.stderr)


def _training_figures(res, train, figs) -> list:
    """Measured against simulated track and heading of each training run under the fit's windows
    and start rule, as its training scores are computed, a zigzag's or turn's ITTC indices marked
    on the measured run; returns the file names written in
    ``figs`` (a run without x, y and psi gets none)."""
    import numpy as np

    from ..estimation import shooting
    from ..report import plots

    figs.mkdir(parents=True, exist_ok=True)
    names = []
    per_run = res.train_scores.get("per_track_rms_position_m") or {}
    for tr in train:
        ctx = res.model.context(tr, res.window_s, start=res.start_rule)
        if not all(c in ctx.meas for c in ("x", "y", "psi")):
            continue
        S = shooting.simulate(res.model, ctx, res.fit.p[None])[0]
        k = max(1, ctx.ts.size // 100000)  # a figure needs no more than 1e5 points a line
        name = f"training_{tr.name}.png"
        rms = per_run.get(tr.name)
        plots.training_fit(
            ctx.ts[::k],
            # the whole run, lead-in included, so that its indices are read as the tables read them
            {
                c: np.asarray(tr.t if c == "t" else tr[c], float)[::k]
                for c in ("t", "x", "y", "psi", "delta_r")
                if c == "t" or c in tr.data
            },
            {"x": S[::k, 0], "y": S[::k, 1], "psi": S[::k, 5]},
            ctx.win[::k],
            figs / name,
            title=f"{tr.name}: training fit, {res.window_s:g} s windows"
            + (f" (RMS position {rms:.3g} m)" if rms is not None else ""),
        )
        names.append(name)
    return names


def _multistart_circles(res, doc, train, rudder_deg: float = 35.0, most: int = 6):
    """35 deg turning circles (starboard) of the distinct near-best optima of a multistart fit,
    from the training runs' approach speed and propeller rate, the rudder moved at their rate
    (:func:`bayesid.models.runs.approach_condition`); their indices go into
    ``doc.multistart["distinct_optima"]``. Returns [(label, x, y)] for the figure, or None when the
    model cannot simulate a turn from these tracks (said in the doc)."""
    import math

    import numpy as np

    from ..estimation.prediction import FittedModel, turning_circles
    from ..models.runs import approach_condition

    ms = doc.multistart
    try:
        approach = approach_condition(train)
    except ValueError as exc:
        ms["turning_circle"] = {"error": str(exc)}
        return None
    ms["turning_circle"] = {
        "rudder_deg": rudder_deg,
        "side": "starboard",
        "speed_mps": approach.u,
        "rps": approach.rpm / 60.0,
        "rudder_rate_deg_s": math.degrees(approach.rudder_rate),
    }
    out = []
    for k, optimum in enumerate(ms["distinct_optima"][:most]):
        p = np.array([optimum["coefficients"][n] for n in doc.param_names])
        fitted = FittedModel(res.model, p, None)
        tc = turning_circles(fitted, 0, np.random.default_rng(0), approach, rudder_deg)["starboard"]
        optimum["turning_circle"] = tc["predicted"]
        S = tc["_S"][0]
        out.append(
            (
                f"optimum {k + 1}: cost +{100 * optimum['relative_cost']:.2f} %, tactical diameter "
                f"{tc['predicted']['tactical_diameter_m']:.3g} m",
                S[:, 0],
                S[:, 1],
            )
        )
    td = [o["turning_circle"]["tactical_diameter_m"] for o in ms["distinct_optima"][:most]]
    td = [v for v in td if v is not None and np.isfinite(v)]
    ms["tactical_diameter_range_m"] = [min(td), max(td)] if td else None
    return out
