"""``bayesid simulate``: simulate a standard manoeuvre of a vehicle file (a submarine or a surface
ship), print its ITTC indices and write the track as a Track CSV (the format ``bayesid fit``
reads), with a JSON summary (vehicle, settings, indices, version, command line) and a figure with
the indices marked beside it."""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path

from ..data.track import write_csv
from ..estimation import indices as ix
from ..models.runs import KIND_ALIASES, canonical_kind
from ..models.simulate import MODES
from . import options as opt
from .outputs import check_out

#: Longest simulation ``bayesid simulate`` runs (model steps): 1e6 s at 0.1 s.
MAX_SIMULATE_STEPS = 10_000_000
#: The manoeuvres (``--manoeuvre``): kinds of :data:`bayesid.models.runs.MANOEUVRE_KINDS`; the
#: aliases of :data:`bayesid.models.runs.KIND_ALIASES` (``turn``, ``pull-out``) are accepted too.
MANOEUVRES = ("spiral", "turning_circle", "zigzag", "pull_out", "straight")
#: How the indices are printed: (key, label, unit).
_PRINTED = (
    ("first_overshoot_deg", "first overshoot", "deg"),
    ("second_overshoot_deg", "second overshoot", "deg"),
    ("initial_turning_time_s", "initial turning time", "s"),
    ("time_to_check_yaw_s", "time to check yaw", "s"),
    ("period_s", "period", "s"),
    ("advance_m", "advance", "m"),
    ("transfer_m", "transfer", "m"),
    ("tactical_diameter_m", "tactical diameter", "m"),
    ("steady_turning_diameter_m", "steady turning diameter", "m"),
    ("speed_loss", "speed loss", ""),
    ("yaw_rate_at_release_deg_s", "yaw rate at release", "deg/s"),
    ("residual_yaw_rate_deg_s", "residual yaw rate", "deg/s"),
)


def add_parser(sub) -> None:
    """Declare ``bayesid simulate`` and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    """
    s = opt.add_subcommand(sub, "simulate", "simulate a manoeuvre, print its ITTC indices and write a Track CSV")
    opt.add_vehicle(
        s, "packaged id (nps_auv2, remus100, kvlcc2_7m, esso_osaka_3m) or a vehicle TOML", default="nps_auv2"
    )
    s.add_argument(
        "--manoeuvre",
        choices=MANOEUVRES + tuple(a for a, k in KIND_ALIASES.items() if k in MANOEUVRES),
        default="spiral",
        help="spiral: a submarine's the paper's inward spiral, a ship's the direct/reverse spiral (steady "
        "yaw rate per rudder angle); turning_circle (or turn); zigzag: heading-triggered; pull_out (or "
        "pull-out): a steady turn, then rudder amidships; straight",
    )
    opt.add_number(
        s,
        "--angle",
        default=20.0,
        help="rudder angle, deg, + to port (the package's sign): a negative angle turns, or starts a "
        "zigzag, to starboard; the largest angle of a ship's spiral",
    )
    opt.add_number(
        s,
        "--check",
        opt.POSITIVE,
        default=None,
        help="zigzag check heading, deg: the heading change that reverses the rudder (none: --angle's size)",
    )
    opt.add_number(
        s,
        "--speed",
        opt.POSITIVE,
        default=None,
        help="approach speed, m/s at the file's scale (none: a ship file's [service] speed; a submarine's "
        "steady speed at --rpm); without --rpm the propeller is set to hold it",
    )
    opt.add_number(
        s,
        "--rpm",
        opt.POSITIVE,
        default=None,
        help="propeller speed, rpm, constant (none: a submarine's nominal; a ship's [service] rpm, else the "
        "model's self-propulsion point at --speed)",
    )
    opt.add_number(
        s,
        "--rudder-rate",
        opt.NON_NEGATIVE,
        default=None,
        help="steering gear rate, deg/s, 0: instantaneous (none: a ship file's [service] rudder_rate_deg_s, "
        "else 0; submarines: zigzag only)",
    )
    opt.add_number(
        s,
        "--duration",
        opt.POSITIVE,
        default=None,
        help="length of the run, s (none: submarines 150 s turn, 120 s zigzag, 180 s pull-out, 60 s "
        "straight; ships 10 s approach and 60 ship-length times L/U, a pull-out 80; not for a spiral)",
    )
    opt.add_number(
        s,
        "--hold",
        opt.POSITIVE,
        default=None,
        help="ships: time at each spiral step, or at the pull-out's angle, s (none: 20 or 40 ship-length "
        "times L/U); submarine pull-out: the hold (none: 60 s)",
    )
    opt.add_dt(s, 0.1, "integration step, s")
    opt.add_number(s, "--sample", opt.POSITIVE, default=0.1, help="output sample interval, s (a multiple of --dt)")
    s.add_argument(
        "--mode",
        choices=MODES,
        default=None,
        help="submarines: 6dof or horizontal (surge, sway, yaw only); none: 6dof; a ship's model is 3-DOF (horizontal)",
    )
    s.add_argument(
        "--crossflow",
        choices=["polynomial", "integral"],
        default=None,
        help="submarines: the cross-flow drag form (none: the vehicle file's); ships always integrate it",
    )
    opt.add_out(
        s,
        "the Track CSV written; beside it, with its suffix replaced, the summary .json (vehicle, settings, "
        "indices, version, command line) and the figure .png",
    )
    s.add_argument(
        "--no-figure",
        action="store_true",
        help="write no .png figure beside the CSV (without it the figure is written, the indices marked)",
    )
    opt.add_overwrite(s)


def output_paths(out, figure: bool = True) -> dict:
    """The files ``bayesid simulate --out OUT`` writes: the CSV itself, and beside it the JSON
    summary and (``figure``) the PNG, named as ``OUT`` with its suffix replaced (one ``--out`` names
    every output, as in the other commands, and ``--overwrite`` covers them all).

    Parameters
    ----------
    out : str or Path
        The ``--out`` value.
    figure : bool, default True
        Whether the figure is written (not with ``--no-figure``).

    Returns
    -------
    dict
        ``"csv"``, ``"json"`` and, with ``figure``, ``"png"``: Paths.

    Raises
    ------
    ValueError
        ``--out`` ends in ``.json`` or ``.png``: the CSV and a summary would share a name.
    """
    out = Path(out)
    if out.suffix.lower() in (".json", ".png"):
        raise ValueError(
            f"--out {out}: the summary and figure are written beside the CSV as {out.stem}.json and "
            f"{out.stem}.png; give the CSV another suffix (e.g. {out.stem}.csv)"
        )
    paths = {"csv": out, "json": out.with_suffix(".json")}
    if figure:
        paths["png"] = out.with_suffix(".png")
    return paths


def run(args) -> int:
    """Run ``bayesid simulate``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.

    Returns
    -------
    int
        The exit code (0).

    Raises
    ------
    ValueError
        An option that does not apply to the vehicle or manoeuvre, or a bad value, naming the
        option; a simulation that diverges.
    """
    args.manoeuvre = canonical_kind(args.manoeuvre, MANOEUVRES)
    paths = output_paths(args.out, not args.no_figure)
    check_out(args.out, "simulate", args.overwrite)
    for what, path in paths.items():  # refused when it exists, as the CSV always was
        if what != "csv" and (path.is_dir() or (path.exists() and not args.overwrite)):
            raise ValueError(
                f"--out {args.out}: {path} (the {what.upper()} written beside the CSV) "
                + ("is a folder" if path.is_dir() else "exists; pass --overwrite to replace it")
            )
    if args.duration is not None and args.duration / args.dt > MAX_SIMULATE_STEPS:
        raise ValueError(
            f"--duration {args.duration:g} s at --dt {args.dt:g} s is {args.duration / args.dt:.3g} steps "
            f"(at most {MAX_SIMULATE_STEPS:.0e}); shorten --duration or lengthen --dt"
        )
    every = int(round(args.sample / args.dt))
    if every < 1 or abs(args.sample / args.dt - every) > 1e-6:
        raise ValueError(f"--sample {args.sample:g} s is not a whole multiple of --dt {args.dt:g} s")
    if args.check is not None and args.manoeuvre != "zigzag":
        raise ValueError(f"--check applies to --manoeuvre zigzag, not {args.manoeuvre}")
    from ..models import ship

    if ship.is_ship_file(args.vehicle):
        track, settings = _ship(args, every)
    else:
        track, settings = _submarine(args, every)
    check = (args.check if args.check is not None else abs(args.angle)) if args.manoeuvre == "zigzag" else None
    indices = _report(track, args.manoeuvre, check)
    paths["csv"].parent.mkdir(parents=True, exist_ok=True)  # checked writable by check_out
    write_csv(track, paths["csv"])
    print(f"wrote {paths['csv']}: {track.n_samples} samples ({settings['run']})")
    _write_summary(args, settings, indices, paths)
    if "png" in paths:
        from ..report import plots

        plots.simulated_run(
            track,
            paths["png"],
            title=f"{settings['vehicle']['id']}: {settings['description']}",
            indices=indices.get("_raw"),
        )
        print(f"wrote {paths['png']}")
    return 0


def _write_summary(args, settings: dict, indices: dict, paths: dict) -> None:
    """The JSON summary of a simulation: the bayesid version, the command line, the vehicle, the
    manoeuvre's settings (the options as given and the speed, rpm and rudder rate resolved), the
    indices as printed (value at full precision, NaN as null) and the files written."""
    from .. import __version__

    doc = {
        "bayesid_version": __version__,
        "command": "bayesid " + " ".join(sys.argv[1:]),
        "vehicle": settings["vehicle"],
        "manoeuvre": dict(
            {k: v for k, v in settings.items() if k not in ("vehicle", "run")},
            name=args.manoeuvre,
            run=settings["run"],
            angle_deg=args.angle,
            check_deg=args.check,
            duration_s=args.duration,
            hold_s=args.hold,
            dt_s=args.dt,
            sample_s=args.sample,
        ),
        "indices": {k: v for k, v in indices.items() if k != "_raw"},
        "files": {k: str(v) for k, v in paths.items() if k != "json"},
    }
    paths["json"].write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n")
    print(f"wrote {paths['json']}")


#: The manoeuvres whose rudder order is ``--angle`` (a spiral's largest step for a ship; a
#: submarine's spiral is the paper's, at its own angles).
_ANGLE_MANOEUVRES = {
    "ship": ("spiral", "turning_circle", "zigzag", "pull_out"),
    "submarine": ("turning_circle", "zigzag", "pull_out"),
}


def _check_angle(args, family: str, vessel_id: str, limit_deg: float | None) -> None:
    """Refuse an ``--angle`` beyond the vessel's rudder limit (``[limits] rudder_max_deg`` of its
    file; None: no limit) for a manoeuvre that orders it, naming the option and the limit."""
    if limit_deg is None or args.manoeuvre not in _ANGLE_MANOEUVRES[family]:
        return
    if abs(args.angle) > limit_deg + 1e-9:
        raise ValueError(
            f"--angle {args.angle:g}: beyond the rudder limit of {vessel_id} ({limit_deg:g} deg, [limits] "
            "rudder_max_deg of its file)"
        )


def _ship(args, every):
    """Simulate a ship file's manoeuvre; the track (comments set) and a description."""
    from ..models.ship import load_ship
    from ..models.ship.trials import TrialOptions, propulsion_point, service_condition, simulate_trial

    vessel = load_ship(args.vehicle)
    _check_angle(args, "ship", vessel.id, vessel.rudder_max_deg)
    if args.mode == "6dof":
        raise ValueError(f"--mode 6dof: {vessel.id} is a 3-DOF surface ship; leave --mode out or give horizontal")
    if args.crossflow:
        raise ValueError(f"--crossflow: applies to submarines; the ship model {vessel.id} integrates its cross-flow")
    service = service_condition(vessel)
    speed = args.speed if args.speed is not None else (None if args.rpm is not None else service.get("speed"))
    rpm = args.rpm if args.rpm is not None else (None if args.speed is not None else service.get("rpm"))
    if speed is None and rpm is None:
        raise ValueError(
            f"--speed: {vessel.id} gives no service speed ([service] speed in {vessel.file_path}); give "
            "--speed (m/s) or --rpm"
        )
    speed, rpm = propulsion_point(vessel, speed, rpm)
    rate = args.rudder_rate if args.rudder_rate is not None else service.get("rudder_rate_deg_s", 0.0)
    steps = (args.duration or 0.0) + (args.hold or 0.0) * (25 if args.manoeuvre == "spiral" else 1)
    if steps / args.dt > MAX_SIMULATE_STEPS:
        raise ValueError(f"--hold {args.hold:g} s: {steps / args.dt:.3g} steps (at most {MAX_SIMULATE_STEPS:.0e})")
    if args.manoeuvre == "spiral" and args.duration is not None:
        raise ValueError("--duration does not apply to a ship's spiral; --hold sets each step's time")
    trial = simulate_trial(
        vessel,
        args.manoeuvre,
        args.angle,
        check_deg=args.check,
        speed=speed,
        rpm=rpm,
        options=TrialOptions(
            dt=args.dt, sample_every=every, duration=args.duration, hold=args.hold, rudder_rate_deg_s=rate
        ),
    )
    track = trial.track
    track.meta["comments"] = [
        f"bayesid simulate: vehicle {vessel.id}, {trial.description}",
        f"vessel: {vessel.id}",
    ]
    print(f"{vessel.id}: {trial.description}")
    return track, {
        "vehicle": {"id": vessel.id, "family": "surface ship", "file": str(vessel.file_path)},
        "run": trial.name,
        "description": trial.description,
        "speed_m_s": float(speed),
        "rpm": float(rpm),
        "rudder_rate_deg_s": float(rate),
    }


def _submarine(args, every):
    """Simulate a submarine vehicle file's manoeuvre; the track (comments set) and its name."""
    from ..data.vehicle import load_vehicle
    from ..models import manoeuvres as mv
    from ..models.simulate import Simulator

    vehicle = load_vehicle(args.vehicle)
    _check_angle(args, "submarine", vehicle.id, math.degrees(vehicle.limits.rudder_max))
    if args.crossflow:
        vehicle = vehicle.with_crossflow(args.crossflow)
    mode = args.mode or "6dof"
    rpm = args.rpm
    if args.speed is not None and rpm is None:
        rpm = args.speed / vehicle.steady_speed(1.0)  # the steady speed is linear in rpm
    if args.rudder_rate not in (None, 0.0) and args.manoeuvre != "zigzag":
        raise ValueError(f"--rudder-rate applies to a submarine's zigzag, not its {args.manoeuvre}")
    if args.hold is not None and args.manoeuvre != "pull_out":
        raise ValueError(f"--hold applies to a submarine's pull-out, not its {args.manoeuvre}")
    if args.manoeuvre == "spiral":
        m = mv.spiral(vehicle, dt=args.dt, rpm=rpm)
    elif args.manoeuvre == "turning_circle":
        m = mv.turning_circle(vehicle, args.angle, dt=args.dt, duration=args.duration or 150.0, rpm=rpm)
    elif args.manoeuvre == "zigzag":
        m = mv.zigzag(
            vehicle,
            abs(args.angle),
            args.check,
            dt=args.dt,
            duration=args.duration or 120.0,
            rpm=rpm,
            first_sign=1 if args.angle >= 0 else -1,
            options=mv.ZigzagOptions(rate_deg_s=args.rudder_rate or 0.0),
        )
    elif args.manoeuvre == "pull_out":
        hold = args.hold or 60.0
        m = mv.pull_out(
            vehicle, args.angle, t_hold=hold, duration=args.duration or max(180.0, 10.0 + 2 * hold), dt=args.dt, rpm=rpm
        )
    else:
        m = mv.straight(vehicle, dt=args.dt, duration=args.duration or 60.0, rpm=rpm)
    if args.speed is not None and args.rpm is not None:  # start at the given speed, not the rpm's
        s0 = m.initial_state.copy()
        s0[6] = args.speed
        m = dataclasses.replace(m, initial_state=s0)
    res = Simulator(vehicle, m, mode=mode, sample_every=every).run()
    if res.diverged[0]:
        raise ValueError(
            f"the simulation diverged at step {res.fail_step[0]} (t = {res.fail_step[0] * args.dt:g} s): "
            f"--angle {args.angle:g} deg or --dt {args.dt:g} s too large for {vehicle.id}?"
        )
    track = res.track(0, name=m.name)
    track.meta["comments"] = [
        f"bayesid simulate: vehicle {vehicle.id}, {m.description}, mode {mode}",
        f"vessel: {vehicle.id}",
    ]
    return track, {
        "vehicle": {"id": vehicle.id, "family": "submarine", "file": vehicle.path or str(args.vehicle)},
        "run": m.name,
        "description": m.description,
        "mode": mode,
        "crossflow": args.crossflow,
        "rpm": None if rpm is None else float(rpm),
        "rudder_rate_deg_s": float(args.rudder_rate or 0.0),
    }


def _finite(value):
    """A float for JSON: NaN and infinities as None (null)."""
    return float(value) if math.isfinite(value) else None


def _report(track, manoeuvre: str, check_deg: float | None = None) -> dict:
    """Print the manoeuvre's indices (ITTC definitions, :mod:`bayesid.estimation.indices`), add
    them to the track's comments and return them for the JSON summary: ``kind``, ``standard`` and
    ``values``: per printed index its ``name``, ``value`` (SI units and degrees, full precision, null when not
    reached), ``sd`` (its measurement uncertainty, where the index has one) and ``unit``; a zigzag's
    executes, check headings (and their sds), the times its heading reached the nominal check angle
    ``check_deg`` and the times of its extremes; a spiral's ``steady_yaw_rates``; ``reason`` when
    there are none; ``_raw`` the :func:`~bayesid.estimation.indices.manoeuvre_indices` result of a
    turn or zigzag."""
    t, delta, r = track.t, track["delta_r"], track["r"]
    standard = "ITTC 7.5-04-02-01 (2017) Sec. 2.2"
    if manoeuvre == "spiral":
        # the straight approach before the first step (rudder amidships from the first sample)
        # is no step of the spiral, however long it is held
        rows = [row for row in ix.steady_yaw_rates(t, delta, r) if row["t_start_s"] > t[0] or row["rudder_deg"] != 0]
        print("steady yaw rate per rudder angle (mean over the last third of each hold; drift: its change there)")
        print("  rudder deg   yaw rate deg/s   drift deg/s")
        for row in rows:
            print(f"  {row['rudder_deg']:10.3g}   {row['yaw_rate_deg_s']:14.4g}   {row['drift_deg_s']:11.2g}")
        track.meta["comments"].append(
            "steady yaw rate (rudder deg: deg/s): "
            + ", ".join(f"{row['rudder_deg']:.3g}: {row['yaw_rate_deg_s']:.4g}" for row in rows)
        )
        return {
            "kind": "spiral",
            "standard": standard + ".4",
            "steady_yaw_rates": [{k: _finite(v) for k, v in row.items()} for row in rows],
        }
    raw = None
    if manoeuvre == "pull_out":
        got = ix.pull_out_rates(t, delta, r)
        kind = "pull_out"
    elif manoeuvre in ("turning_circle", "zigzag"):
        got = raw = ix.manoeuvre_indices(t, track["x"], track["y"], track["psi"], delta, check_deg=check_deg)
        kind = got["kind"]
    else:
        return {"kind": "straight", "reason": "a straight run has no manoeuvre indices"}
    if not got or kind == "other":
        reason = got.get("reason", "the rudder is never released")
        print(f"no {manoeuvre} indices: {reason}")
        return {"kind": "other", "reason": reason, "_raw": raw}
    print(f"{kind} indices (ITTC 7.5-04-02-01):")
    shown, values = [], {}
    for key, label, unit in _PRINTED:
        if key in got:
            value, sd = got[key], got.get(key + "_sd")
            text = "n/a" if not math.isfinite(value) else f"{value:.4g}"
            spread = f"  (sd {sd:.2g})" if sd is not None and math.isfinite(value) and math.isfinite(sd) else ""
            print(f"  {label:<24} {text} {unit}".rstrip() + spread)
            shown.append(f"{key} {text}")
            values[key] = {"name": label, "value": _finite(value), "unit": unit}
            if sd is not None:
                values[key]["sd"] = _finite(sd)
    track.meta["comments"].append(f"{kind} indices: " + ", ".join(shown))
    zigzag = ("executes_t_s", "executes_t_s_sd", "check_heading_deg", "check_heading_deg_sd", "check_crossing_t_s")
    extra = {k: [_finite(v) for v in got[k]] for k in (*zigzag, "overshoot_t_s") if kind == "zigzag" and k in got}
    return dict({"kind": kind, "standard": standard, "values": values}, **extra, _raw=raw)
