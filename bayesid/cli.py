"""The ``bayesid`` command.

    bayesid simulate --vehicle nps_auv2 --manoeuvre zigzag --angle 20 --mode horizontal --out track.csv

Later issues add ``fit``, ``predict``, ``diagnose`` and ``convert`` (DESIGN.md "Command line").
"""
from __future__ import annotations

import argparse
import sys

from . import manoeuvres as mv
from .simulate import MODES, Simulator
from .track import write_csv
from .vehicle import load_vehicle


def _simulate(args) -> int:
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
    every = max(1, int(round(args.sample / args.dt)))
    res = Simulator(vehicle, m, mode=args.mode, sample_every=every).run()
    if res.diverged[0]:
        print(f"error: simulation diverged at step {res.fail_step[0]}", file=sys.stderr)
        return 1
    track = res.track(0, name=m.name)
    track.meta["comments"] = [f"bayesid simulate: vehicle {vehicle.id}, {m.description}, mode {args.mode}"]
    write_csv(track, args.out)
    print(f"wrote {args.out}: {track.n_samples} samples")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="bayesid", description="hydrodynamic coefficient identification")
    sub = ap.add_subparsers(dest="command", required=True)
    s = sub.add_parser("simulate", help="simulate a manoeuvre and write a Track CSV")
    s.add_argument("--vehicle", default="nps_auv2", help="packaged id or TOML path")
    s.add_argument("--manoeuvre", choices=["spiral", "turn", "zigzag", "straight"], default="spiral")
    s.add_argument("--angle", type=float, default=20.0, help="rudder angle, deg (turn, zigzag)")
    s.add_argument("--duration", type=float, default=None, help="s (turn, zigzag, straight)")
    s.add_argument("--dt", type=float, default=0.1, help="integration step, s")
    s.add_argument("--sample", type=float, default=0.1, help="output sample interval, s")
    s.add_argument("--mode", choices=MODES, default="6dof")
    s.add_argument("--crossflow", choices=["polynomial", "integral"], default=None)
    s.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    try:
        return _simulate(args)
    except (ValueError, KeyError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
