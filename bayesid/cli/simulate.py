"""``bayesid simulate``: simulate a manoeuvre of a submarine vehicle file and write a Track CSV."""

from __future__ import annotations

from ..data.track import write_csv
from ..data.vehicle import load_vehicle
from ..models import manoeuvres as mv
from ..models.simulate import MODES, Simulator
from . import options as opt
from .outputs import check_out

#: Longest simulation ``bayesid simulate`` runs (model steps): 1e6 s at 0.1 s.
MAX_SIMULATE_STEPS = 10_000_000


def add_parser(sub) -> None:
    """Declare ``bayesid simulate`` and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    """
    s = opt.add_subcommand(sub, "simulate", "simulate a manoeuvre and write a Track CSV")
    opt.add_vehicle(s, "packaged id or TOML path", default="nps_auv2")
    s.add_argument("--manoeuvre", choices=["spiral", "turn", "zigzag", "straight"], default="spiral")
    opt.add_number(s, "--angle", default=20.0, help="rudder angle, deg (turn, zigzag)")
    opt.add_number(s, "--duration", opt.NON_NEGATIVE, default=None, help="s (turn, zigzag, straight)")
    opt.add_dt(s, 0.1, "integration step, s")
    opt.add_number(s, "--sample", opt.POSITIVE, default=0.1, help="output sample interval, s")
    s.add_argument("--mode", choices=MODES, default="6dof")
    s.add_argument("--crossflow", choices=["polynomial", "integral"], default=None)
    opt.add_out(s)
    opt.add_overwrite(s)


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
    """
    check_out(args.out, "simulate", args.overwrite)
    if args.duration is not None and args.duration / args.dt > MAX_SIMULATE_STEPS:
        raise ValueError(
            f"--duration {args.duration:g} s at --dt {args.dt:g} s is {args.duration / args.dt:.3g} steps "
            f"(at most {MAX_SIMULATE_STEPS:.0e}); shorten --duration or lengthen --dt"
        )
    from ..models import ship

    if ship.is_ship_file(args.vehicle):
        raise ValueError(
            f"--vehicle {args.vehicle}: a surface ship; 'bayesid simulate' runs submarine vehicle "
            f"files (nps_auv2 or your own TOML)"
        )
    vehicle = load_vehicle(args.vehicle)
    if args.crossflow:
        vehicle = vehicle.with_crossflow(args.crossflow)
    if args.manoeuvre == "spiral":
        m = mv.spiral(vehicle, dt=args.dt)
    elif args.manoeuvre == "turn":
        m = mv.turning_circle(vehicle, args.angle, dt=args.dt, duration=args.duration or 150.0)
    elif args.manoeuvre == "zigzag":
        m = mv.zigzag(vehicle, args.angle, dt=args.dt, duration=args.duration or 120.0)
    else:
        m = mv.straight(vehicle, dt=args.dt, duration=args.duration or 60.0)
    every = int(round(args.sample / args.dt))
    if every < 1 or abs(args.sample / args.dt - every) > 1e-6:
        raise ValueError(f"--sample {args.sample:g} s is not a whole multiple of --dt {args.dt:g} s")
    res = Simulator(vehicle, m, mode=args.mode, sample_every=every).run()
    if res.diverged[0]:
        raise ValueError(
            f"the simulation diverged at step {res.fail_step[0]} (t = {res.fail_step[0] * args.dt:g} s): "
            f"--angle {args.angle:g} deg or --dt {args.dt:g} s too large for {vehicle.id}?"
        )
    track = res.track(0, name=m.name)
    track.meta["comments"] = [
        f"bayesid simulate: vehicle {vehicle.id}, {m.description}, mode {args.mode}",
        f"vessel: {vehicle.id}",
    ]
    write_csv(track, args.out)
    print(f"wrote {args.out}: {track.n_samples} samples")
    return 0
