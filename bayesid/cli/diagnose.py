"""``bayesid diagnose``: the sim-to-real gap of a vehicle's model on training and held-out
tracks -- where, which effect, how far (:mod:`bayesid.analysis.gap`) -- written as
``diagnosis.json``, ``report.md`` and figures."""

from __future__ import annotations

import sys
from pathlib import Path

from .. import tasks
from ..models.simulate import MODES
from . import options as opt
from .inputs import free_list, naming_files, read_tracks
from .outputs import check_out, check_write_vehicle


def add_parser(sub) -> None:
    """Declare ``bayesid diagnose`` and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    """
    d = opt.add_subcommand(sub, "diagnose", "sim-to-real gap: where / which effect / how far")
    opt.add_vehicle(d, "packaged id or TOML path (nominal coefficients)", required=True)
    opt.add_free(d, "comma-separated free coefficients (empty: the vehicle's; submarines Yv,Yr,Nv,Nr,Ydr,Ndr)")
    opt.add_tracks(d, "--train", "training Track CSVs")
    opt.add_tracks(d, "--heldout", "held-out Track CSVs")
    opt.add_score_window(d)
    opt.add_dt(
        d,
        None,
        "model integration step, s (none: 0.2 ships, 0.5 submarines, halved for a small or fast one until it is at "
        "most 0.18 of its length over its nominal speed)",
    )
    opt.add_fit_window(
        d,
        opt.NON_NEGATIVE,
        default=0.0,
        help="fit window: the multiple-shooting window of the training fits, s (0: 15 for a ship, "
        "--score-window for a submarine)",
    )
    d.add_argument(
        "--mode",
        choices=MODES,
        default="horizontal",
        help="submarines: horizontal (surge, sway, yaw) or 6dof equations; a ship's model is 3-DOF",
    )
    d.add_argument("--candidates", default="", help="comma-separated effects (empty: the whole catalogue)")
    d.add_argument("--exclude", default="", help="comma-separated effects left out of the candidates")
    opt.add_number(
        d,
        "--max-effects",
        opt.POSITIVE,
        kind=int,
        default=2,
        help="greedy rounds of effect addition (a contributor is added and the others tried on top)",
    )
    opt.add_start(d)
    opt.add_leadin(d)
    opt.add_inputs(d)
    opt.add_max_nfev(d, "least-squares iterations per fit")
    opt.add_seed(d, "random seed (noise-floor simulation, ensemble of the force-signature regression)")
    opt.add_weighting(d)
    opt.add_number(
        d,
        "--starts",
        opt.NON_NEGATIVE,
        kind=int,
        default=0,
        help="extra Latin-hypercube starts of the base fit (the lowest cost is kept; 0: the default start alone)",
    )
    d.add_argument(
        "--train-starts",
        choices=("fitted", "kinematic", "auto"),
        default="fitted",
        help="without a velocity log, the training fits' window starts: fitted with the model, held at the "
        "tracks' kinematics, or auto (held when the base-fit check finds the fitted ones inconsistent and "
        "the held ones predict the training tracks better)",
    )
    d.add_argument(
        "--heldout-propeller",
        choices=("logged", "approach"),
        default="logged",
        help="a ship's held-out runs' propeller speed: the logged rpm (default), or approach: when Where finds "
        "held-out runs at another propulsion point than the training runs (another basin, model, propeller or rpm "
        "control), the diagnosis is made again with their rpm scaled to the training runs' point for their own "
        "approach speed, so that the candidates are judged without the point's difference",
    )
    opt.add_floor(d)
    opt.add_discovery(d, default_on=True)
    opt.add_jobs(d)
    opt.add_out(d, "output folder")
    opt.add_overwrite(d)


def run(args) -> int:
    """Run ``bayesid diagnose``: base fit, then where / which / how far.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.

    Returns
    -------
    int
        The exit code (0).
    """
    from ..analysis.gap.discovery import check_compare
    from ..models import build_model, default_dt, load_any_vehicle, model_class

    check_outputs(args)
    vehicle = load_any_vehicle(args.vehicle)
    family = model_class(vehicle)
    if args.heldout_propeller == "approach" and getattr(family, "steady_speed", None) is None:
        raise ValueError(
            f"--heldout-propeller approach: {args.vehicle} has no propeller model to match (only a ship's model has "
            "one); leave the option out"
        )
    free = free_list(vehicle, args.free)
    got = read_tracks([("--train", args.train), ("--heldout", args.heldout)], vehicle)
    train, held = got["--train"], got["--heldout"]
    with naming_files(got):
        cands = _candidates(args, family, train + held, free, vehicle)
        found, design = opt.discovery_options(args)
        if not args.no_discover:
            check_compare(build_model(vehicle, free, mode=args.mode), found)
        options = diagnose_options(
            args,
            candidates=cands,
            fit_window_s=args.fit_window if args.fit_window else None,
            dt=args.dt if args.dt is not None else default_dt(vehicle),
            mode=args.mode,
            max_effects=args.max_effects,
            weighting=args.weighting or None,
            base_starts=args.starts,
            train_starts=args.train_starts,
            discover=None if args.no_discover else found,
            design=None if args.no_discover else design,
            inputs=args.inputs,
            rudder_rate_deg_s=args.rudder_rate,
            heldout_propeller=args.heldout_propeller,
        )
        run_and_write(args, vehicle, free, got, options)
    return 0


def check_outputs(args) -> None:
    """The checks of ``diagnose`` and ``discover`` before any computation: ``--jobs`` /
    ``--scheduler``, the ``--out`` folder and ``--write-vehicle``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.
    """
    tasks.check_jobs(args.jobs, args.scheduler)
    check_out(args.out, "diagnose", args.overwrite)
    check_write_vehicle(args.write_vehicle, args.overwrite)


def diagnose_options(args, **fields):
    """The diagnosis' options from the options ``diagnose`` and ``discover`` share (window, start
    rule, lead-in, iterations, floor), and ``fields``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.
    **fields
        The other :class:`~bayesid.analysis.gap.DiagnoseOptions` fields.

    Returns
    -------
    DiagnoseOptions
        The options.
    """
    from ..analysis.gap import DiagnoseOptions

    return DiagnoseOptions(
        window_s=None if args.window <= 0 else args.window,
        max_nfev=args.max_nfev,
        start=args.start,
        leadin_s=args.leadin if args.leadin > 0 else None,
        floor=args.floor,
        **fields,
    )


def run_and_write(args, vehicle, free, got: dict, options):
    """Run the diagnosis, write its report (and ``--write-vehicle``) and print the verdict.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options (``jobs``, ``scheduler``, ``seed``, ``out``, ``write_vehicle``,
        ``overwrite``).
    vehicle : Vehicle or Ship
        The vehicle.
    free : list of str
        The free coefficients.
    got : dict
        :func:`~bayesid.cli.inputs.read_tracks` of ``--train`` and ``--heldout``.
    options : DiagnoseOptions
        The diagnosis' options.

    Returns
    -------
    Diagnosis
        The diagnosis written.
    """
    import numpy as np

    from ..analysis.gap import diagnose
    from ..report import write_diagnosis
    from ..report.vehiclefile import write_vehicle_with_terms

    train, held = got["--train"], got["--heldout"]
    runner = tasks.Runner(args.jobs, args.scheduler, progress=_progress)
    res = diagnose(vehicle, free, train, held, options, rng=np.random.default_rng(args.seed), runner=runner)
    inputs = {"warnings": got["_warnings"], "input_sha256": got["_sha256"]}
    write_diagnosis(res, args.out, held, command="bayesid " + " ".join(sys.argv[1:]), inputs=inputs)
    last = res.gap_discovered or res.gap_after  # the model the verdict names, discovered terms included
    print(
        f"verdict: {res.verdict}; held-out RMS {res.gap_before['heldout_rms_m']:.3f} m -> "
        f"{last['heldout_rms_m']:.3f} m (noise floor {res.noise_floor['heldout_rms_m']:.3f} m, "
        f"window starts {res.settings['start_rule']}); wrote {Path(args.out) / 'diagnosis.json'}"
    )
    found = res.discovered
    if found is not None and found.found:
        print(
            f"discovered: {', '.join(found.found)}: held-out RMS {found.heldout_rms_before_m:.3f} m -> "
            f"{found.heldout_rms_after_m:.3f} m"
        )
    if args.write_vehicle:
        values, forms, named = _vehicle_values(res, vehicle)
        if not values and not forms:
            print(f"--write-vehicle: no term was kept and no model form named, {args.write_vehicle} not written")
        else:
            note = f"discovered by bayesid ({Path(args.out) / 'diagnosis.json'}); a start value for bayesid fit"
            src = vehicle.file_path
            path = write_vehicle_with_terms(src, values, args.write_vehicle, note, args.overwrite, forms)
            print(f"wrote {path}: {src} with {', '.join(named)} added")
    return res


def _vehicle_values(res, vehicle) -> tuple[dict, dict, list]:
    """What ``--write-vehicle`` writes: the coefficients (the kept terms at the final model's
    values, the effects may have been fitted on top of them, and the vehicle-file coefficients of
    the named effects that have them, ``vehicle_coefficients``: the ship's wake in a turn, a shifted
    MMG coefficient), the model-form choices of the named effects that are forms (``vehicle_form``:
    the ship's coupling speed), and what they are, for the message."""
    from ..models import model_class

    values, forms, named = {}, {}, []
    found = res.discovered
    if found is not None and found.found:
        final = res.after_fit["coefficients"]
        values.update({n: final.get(n, found.after_coefficients[n]) for n in found.found})
        named += list(found.found)
    family = model_class(vehicle)
    for name, params in (res.after_fit.get("effects") or {}).items():
        effect = family.get_effect(name)
        if hasattr(effect, "vehicle_coefficients"):
            q = [params[k] for k in effect.params]
            got = effect.vehicle_coefficients(q, vehicle)
            values.update(got)
            named.append(f"the {name} effect ({', '.join(got)})")
        if hasattr(effect, "vehicle_form"):
            got = effect.vehicle_form([params[k] for k in effect.params], vehicle)
            forms.update(got)
            named.append(f"the {name} effect ([form] {', '.join(f'{k} = {v!r}' for k, v in got.items())})")
    return values, forms, named


def _candidates(args, family, tracks, free=(), vehicle=None) -> list | None:
    """The candidate effects: ``--candidates``, or None without ``--exclude``: the catalogue less
    the effects whose columns not every track has, left to :func:`~bayesid.analysis.gap.diagnose`
    (which says them); less ``--exclude``. An excluded effect of the catalogue that the tracks'
    columns already left out is said and skipped (e.g. ``--exclude wind`` on tracks without wind
    columns: what the user asked for holds); ValueError for any other name not among the
    candidates, and for a ``--candidates`` effect that sets a coefficient of ``free`` (the base
    model's free list: a shift of ``wP`` with ``wP`` free has one parameter twice)."""
    from ..analysis.gap.diagnose import catalogue_candidates

    if not args.candidates and not args.exclude:
        return None
    if args.candidates:
        cands = opt.split_names(args.candidates, "--candidates")
        for c in cands:
            clash = family.effect_clash(family.get_effect(c), free) if hasattr(family, "effect_clash") else []
            if clash:
                raise ValueError(
                    f"--candidates {c}: the {c} effect sets {', '.join(clash)}, which the base model fits "
                    f"(--free or the vehicle file's [fit] free): leave {', '.join(clash)} out of --free to test it"
                )
    else:  # the catalogue as diagnose() takes it, said as its progress is
        cands = catalogue_candidates(family, tracks, tasks.Runner(progress=_progress), free, vehicle)
    for c in opt.split_names(args.exclude, "--exclude"):
        if c in cands:
            cands.remove(c)
        elif not args.candidates and c in family.CATALOGUE:
            _progress(f"--exclude {c}: already left out (said above)")
        else:
            raise ValueError(f"--exclude {c}: not among the candidates {cands}")
    return cands


def _progress(message: str) -> None:
    """Print a progress message of the diagnosis, indented under the command's own lines."""
    print(f"  {message}", flush=True)
