"""``bayesid predict``: score a fitted model on tracks with the window protocol (and over whole
runs), with the manoeuvre indices and the calibrated predictive bands, written as
``predict.json``, ``report.md`` and figures."""

from __future__ import annotations

import sys

from . import options as opt
from .inputs import naming_files, read_tracks
from .outputs import check_out
from .provenance import check_vehicle_unchanged


def add_parser(sub) -> None:
    """Declare ``bayesid predict`` and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    """
    pp = opt.add_subcommand(sub, "predict", "score a fitted model on tracks with the window protocol")
    pp.add_argument("--model", required=True, help="model.json written by bayesid fit")
    opt.add_tracks(pp, "--track", "Track CSVs")
    opt.add_score_window(pp)
    opt.add_number(
        pp,
        "--draws",
        opt.NON_NEGATIVE,
        kind=int,
        default=100,
        help="posterior draws for the index bands (100 gives a 5 %% quantile to about 2 draws)",
    )
    opt.add_seed(pp, "random seed of the posterior draws")
    opt.add_start(pp)
    opt.add_leadin(pp)
    opt.add_out(pp, "output folder")
    opt.add_overwrite(pp)
    pp.add_argument(
        "--propeller",
        choices=("logged", "approach"),
        default="logged",
        help="the propeller speed the model is driven with: the logged rpm (default), or, for a ship, each run's "
        "logged rpm scaled to what the model needs for the run's own approach speed (a run from another basin, "
        "model or propeller, whose propulsion point is not the model's; predict.json records the factors)",
    )
    pp.add_argument(
        "--allow-changed-vehicle",
        action="store_true",
        help="predict even if the vehicle file changed after the fit (a warning is printed)",
    )


def run(args) -> int:
    """Run ``bayesid predict``: ``predict.json``, ``report.md`` and figures in ``--out``.

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
    from ..report import write_json, write_predict_report
    from ..report.predict import window_distribution

    out = check_out(args.out, "predict", args.overwrite)
    model, p, cov, doc = load_model(args.model)
    if args.propeller == "approach" and getattr(model, "steady_speed", None) is None:
        raise ValueError(
            f"--propeller approach: {args.model} has no propeller model to match (only a ship's model has one); "
            "predict it with the logged rpm"
        )
    check_vehicle_unchanged(doc, model.vehicle, args.model, args.allow_changed_vehicle)
    got = read_tracks([("--track", args.track)], model.vehicle)
    tracks = got["--track"]
    window = None if args.window <= 0 else args.window
    _warn(doc, got, window)
    with naming_files(got):
        approach = approach_rows(model, p, tracks)
        if args.propeller == "approach":
            tracks = matched_to_approach(model, approach, tracks, got["_warnings"])
        pr, whole, indices, bands = _predict(args, (model, p, cov), doc, tracks, window, out)
        excursions = model_excursion(doc, whole, tracks, getattr(model.vehicle, "L", None))
        notes = [] if args.propeller == "approach" else [r["warning"] for r in approach if r.get("warning")]
        for w in excursions + notes:
            print(f"warning: {w}", file=sys.stderr)
            got["_warnings"].append(w)
        _figures(pr, bands, indices, doc, tracks, window, out)
        res = {
            "model": str(args.model),
            "window_s": window,
            "start_rule": pr.start_rule,
            "leadin_s": pr.leadin_s,
            "start": _start_note(args.start, pr.start_rule, tracks),
            "warnings": got["_warnings"],
            "input_sha256": got["_sha256"],
            "pooled": pr.pooled,
            "per_track": pr.per_track,
            "windows": pr.windows,
            "window_distribution": window_distribution(pr.windows),
            "whole_run": {"pooled": whole.pooled, "per_track": whole.per_track},
            "indices": indices,
            **({"approach": approach} if approach else {}),
            "propeller": args.propeller,
            "n_draws": args.draws,
            "bands": bands,
        }
        write_json(out / "predict.json", res)
        write_predict_report(res, out, [t.name for t in tracks], command=f"bayesid {' '.join(sys.argv[1:])}")
    print(_summary(pr, bands, (window, res["window_distribution"]), out))
    return 0


def _warn(doc, got: dict, window) -> None:
    """Warnings (printed, and added to the inputs' warnings) for a model whose covariance is a
    posterior ``bayesid sample`` judged not reliable, for a track the model was fitted on and for a
    track shorter than one window."""
    src = doc.posterior_source or {}
    if src and not src.get("reliable", src.get("converged", True)):
        w = (
            f"the model's covariance is a posterior that bayesid sample judged not reliable ({src.get('sample')}, "
            f"{src.get('method')}): the bands below do not hold; sample again (a longer budget, --method mcmc) or "
            "predict from the fit's model.json"
        )
        print(f"warning: {w}", file=sys.stderr)
        got["_warnings"].append(w)
    trained = {h: f for f, h in (doc.provenance.get("input_sha256") or {}).items()}
    for f, h in got["_sha256"].items():
        if h in trained:
            w = (
                f"{f}: the model was fitted on this file ({trained[h]}): its scores are training scores, "
                "not a prediction of unseen data"
            )
            print(f"warning: {w}", file=sys.stderr)
            got["_warnings"].append(w)
    for tr in got["--track"]:
        if window is not None and tr.t[-1] - tr.t[0] < window:
            w = (
                f"{tr.name}: lasts {tr.t[-1] - tr.t[0]:.3g} s, less than one {window:g} s window: its score is "
                "over that shorter span, not comparable with full windows"
            )
            print(f"warning: {w}", file=sys.stderr)
            got["_warnings"].append(w)


def approach_rows(model, p, tracks) -> list[dict]:
    """Each track's propulsion point against the model's (ships,
    :func:`bayesid.models.runs.approach_row`): at the rpm the run logs on its approach, the
    speed the model settles at against the measured approach speed, with a ``warning`` where they
    differ by more than :data:`~bayesid.models.runs.APPROACH_TOLERANCE` on a steady
    approach (a run at another propulsion point: another basin, model, propeller or rpm control).

    Parameters
    ----------
    model : SimulationModel
        The fitted model (one without ``steady_speed`` gives no rows).
    p : ndarray, shape (n_params,)
        Its parameters.
    tracks : list of Track
        The runs.

    Returns
    -------
    list of dict
        Per run with an approach: the :func:`~bayesid.models.runs.approach_row`,
        ``matched_rpm`` (the rpm the model needs for the approach speed) and, when off,
        ``warning``.
    """
    from ..models.runs import APPROACH_TOLERANCE, approach_row

    if getattr(model, "steady_speed", None) is None:
        return []
    rows = []
    for tr in tracks:
        row = approach_row(model, p, tr, matched=True)
        if row is None:
            continue
        err = row["speed_error"]
        if row["matched_rpm"] is None:  # no equilibrium at its approach speed: not judged
            row["steady"] = False
        if row["steady"] and abs(err) > APPROACH_TOLERANCE:
            row["warning"] = (
                f"{tr.name}: at the {row['rpm']:.4g} rpm it logs on its approach the model settles at "
                f"{row['model_speed_m_s']:.3g} m/s against {row['speed_m_s']:.3g} m/s measured ({err:+.1%}): the run is "
                "at another propulsion point than the model's (another basin, model, propeller or rpm control), so the "
                "predicted speed, and the turning indices that rest on it (steady turning diameter, speed loss), carry "
                "that difference"
            )
        rows.append(row)
    return rows


def matched_to_approach(model, rows: list, tracks: list, warnings_out: list) -> list:
    """``--propeller approach``: each track with a steady approach driven at its logged rpm scaled
    to what the model needs for the run's own approach speed (``model.self_propulsion_rpm``); the
    factor is written into its row (``rpm_factor``). A track without a steady approach keeps its
    logged rpm, with a warning (added to ``warnings_out`` and printed).

    Parameters
    ----------
    model : SimulationModel
        The fitted model (a ship's).
    rows : list of dict
        :func:`approach_rows` of the tracks (updated in place).
    tracks : list of Track
        The tracks.
    warnings_out : list of str
        Receives the warnings.

    Returns
    -------
    list of Track
        The tracks, copies where the rpm was scaled.
    """
    from ..models.runs import with_rpm_scaled

    by_run = {r["run"]: r for r in rows}
    out = []
    for tr in tracks:
        r = by_run.get(tr.name)
        if r is None or not r["steady"] or not r.get("matched_rpm"):
            w = f"{tr.name}: no steady approach to match the propeller to: driven at its logged rpm (--propeller approach)"
            print(f"warning: {w}", file=sys.stderr)
            warnings_out.append(w)
            out.append(tr)
            continue
        r["rpm_factor"] = r["matched_rpm"] / r["rpm"]
        out.append(with_rpm_scaled(tr, r["rpm_factor"]))
    return out


def _start_note(asked: str, rule: str, tracks) -> dict:
    """How the window start rule was resolved (:func:`bayesid.protocol.resolve_start`): the rule
    asked for, the rule used, the tracks without a velocity log (u, v, r not all logged) and the
    reason in words."""
    import numpy as np

    from ..protocol import AUTO_MAX_SLOPE_SD, slope_sd

    def logs(tr, k):
        return k in tr and bool(np.isfinite(np.asarray(tr[k], float)).any())

    missing = {tr.name: [k for k in ("u", "v", "r") if not logs(tr, k)] for tr in tracks}
    bare = {n: m for n, m in missing.items() if m}
    groups = {}
    for n, m in bare.items():
        groups.setdefault(", ".join(m), []).append(n)

    def names(ns):
        return ", ".join(ns[:4]) + (f" and {len(ns) - 4} more" if len(ns) > 4 else "")

    listed = "; ".join(f"{names(ns)} {'lacks' if len(ns) == 1 else 'lack'} {m}" for m, ns in groups.items())
    if asked != "auto":
        reason = f"asked for with --start {asked}" + (" (every track logs u, v and r)" if not bare else f" ({listed})")
    elif not bare:
        reason = "--start auto: every track logs u, v and r, so the measured velocities start each window"
    else:
        sd = {tr.name: slope_sd(tr) for tr in tracks if tr.name in bare}
        worst = max(sd, key=sd.get)
        if rule == "measured":
            reason = (
                f"--start auto: {listed}, but the positions are precise enough for a 1 s slope estimate of the "
                f"velocity (standard error at most {sd[worst]:.2g} m/s, {worst}; limit {AUTO_MAX_SLOPE_SD:g} m/s)"
            )
        else:
            reason = (
                f"--start auto: {listed}, and the positions are too noisy for a 1 s slope estimate of the "
                f"velocity (standard error {sd[worst]:.2g} m/s on {worst}, above {AUTO_MAX_SLOPE_SD:g} m/s)"
            )
    return {"asked": asked, "rule": rule, "without_velocity_log": sorted(bare), "reason": reason}


def model_excursion(doc, whole, tracks, length_m) -> list[str]:
    """Warnings for runs on which the model's own whole-run prediction turns tighter than any
    training run did: its nondimensional yaw rate ``r' = r L / U`` (95th percentile,
    :func:`~bayesid.estimation.calibration.yaw_rate_prime`) above 1.25 x the training runs'
    largest (``model.json``'s calibration records theirs). There the hull forces are
    extrapolated, and the indices that rest on them with them: a KVLCC2 model fitted on the HSVA
    zigzags (r' up to 0.60) turns its 35 deg circle at r' 1.3, losing 73 % of its speed, and its
    steady turning diameter is half its tactical diameter (issue 50).

    Parameters
    ----------
    doc : ModelDocument
        The fitted model's document (its calibration's excitation range).
    whole : Prediction
        The whole-run prediction (``simulated``: ``{run: (ctx, states)}``).
    tracks : list of Track
        The runs.
    length_m : float or None
        The vessel's length, m (None: no check).

    Returns
    -------
    list of str
        One warning per run beyond the range; empty without a calibration that recorded ``r'``.
    """
    import numpy as np

    from ..estimation.calibration import yaw_rate_prime

    rng = doc.calibration.excitation_range().get("yaw_rate_prime") if doc.calibration is not None else None
    if rng is None or length_m is None:
        return []
    out = []
    for tr in tracks:
        if tr.name not in whole.simulated:
            continue
        ctx, S = whole.simulated[tr.name]
        rp = yaw_rate_prime(ctx.ts, S[:, 0], S[:, 1], S[:, 5], length_m)
        x = float(np.percentile(rp, 95)) if rp.size else None
        if x is not None and x > 1.25 * rng[1]:
            out.append(
                f"{tr.name}: the model's own run turns at r' = r L / U {x:.2f} (95th percentile), above the "
                f"training runs' {rng[0]:.2f}-{rng[1]:.2f}: its hull forces are extrapolated there, and so are the "
                "indices that rest on them (a steady turning diameter first)"
            )
    return out


def _predict(args, fitted, doc, tracks, window, out):
    """The windowed and whole-run predictions, each track's manoeuvre indices with their
    posterior band, and the calibrated bands (``out/figures`` is created on the way)."""
    import numpy as np

    from ..estimation.calibration import excitation, uncalibrated_bands
    from ..estimation.prediction import FittedModel, predict, turning_band

    model, p, cov = fitted
    lead = args.leadin if args.leadin > 0 else None
    pr = predict(model, p, tracks, window, start=args.start, leadin_s=lead)
    whole = predict(model, p, tracks, None, start=args.start, leadin_s=lead)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    indices = {}
    for tr in tracks:
        tb = turning_band(
            FittedModel(model, p, cov), tr, args.draws, rng, start=whole.start_rule, leadin_s=whole.leadin_s
        )
        indices[tr.name] = {k: v for k, v in tb.items() if not k.startswith("_")}
    if doc.calibration is None:
        bands = uncalibrated_bands(indices)
    else:
        L = getattr(model.vehicle, "L", None)
        bands = doc.calibration.bands(
            window, pr.windows, indices, excitations={t.name: excitation(t, L) for t in tracks}
        )
    return pr, whole, indices, bands


def _figures(pr, bands: dict, indices: dict, doc, tracks, window, out) -> None:
    """Each track's windowed prediction (a ``Prediction``) with its 90 % band and its manoeuvre
    indices as ``predict.json`` gives them (``indices``), and the reliability diagram; the
    simulations are dropped from ``pr`` once drawn."""
    import numpy as np

    from ..report import plots

    level = 0.9
    b90 = dict(doc.calibration.window_band(level), level=level) if bands.get("windows") else {}
    for tr in tracks:
        ctx, S = pr.simulated[tr.name]
        k = max(1, ctx.ts.size // 100000)  # a figure needs no more than 1e5 points a line
        km = max(1, tr.n_samples // 100000)
        plots.prediction_band(
            # the whole measured run, lead-in included: the indices are read from all of it
            {c: np.asarray(tr[c], float)[::km] for c in ("t", "x", "y", "psi", "delta_r")},
            {"t": ctx.ts[::k], "win": ctx.win[::k], "x": S[::k, 0], "y": S[::k, 1], "psi": S[::k, 5]},
            b90,
            out / "figures" / f"{tr.name}.png",
            title=f"{tr.name}: {window or 'whole-run'} s windows, identified model"
            + (
                " (extrapolated: band not calibrated)"
                if tr.name in (bands.get("extrapolated") or {}).get("runs", [])
                else ""
            ),
            indices=indices.get(tr.name),
        )
        del pr.simulated[tr.name]
    if bands.get("coverage"):
        groups = {
            g: bands["coverage"][g]
            for g in ("windows", "indices")
            if any(v["n"] for v in bands["coverage"][g].values())
        }
        plots.reliability(groups, out / "figures" / "reliability.png", bands["parameter_only"])


def _summary(pr, bands: dict, windows: tuple, out) -> str:
    """The line printed at the end: pooled score and the windows' median and 90th percentile
    (``windows``: the window length and the per-window distribution), coverage of the 90 % bands,
    runs outside the training runs' range or extrapolated."""
    window, dist = windows
    c90 = ((bands.get("coverage") or {}).get("all") or {}).get("0.9") or {}
    ext = (bands.get("extrapolated") or {}).get("runs") or []
    per = dist.get("rms_position_m")
    return (
        f"pooled RMS position {pr.pooled['rms_position_m']:.3f} m ({window} s windows)"
        + (
            f"; per window median {per['median']:.3f} m, 90th percentile {per['p90']:.3f} m over "
            f"{dist['n_windows']} windows (report.md names the worst)"
            if per
            else ""
        )
        + (f"; calibrated 90 % bands hold {c90['inside']} of {c90['n']} claims" if c90.get("n") else "")
        + (f" ({c90['unbounded']} of them unbounded: too few training scores for 90 %)" if c90.get("unbounded") else "")
        + (
            f" ({len(bands['outside_range'])} run(s) outside the training runs' range: see report.md)"
            if bands.get("outside_range")
            else ""
        )
        + (
            f"; {len(ext)} run(s) extrapolated (a manoeuvre the training runs lacked: bands not calibrated)"
            if ext
            else ""
        )
        + f"; wrote {out / 'predict.json'}"
    )
