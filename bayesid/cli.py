"""The ``bayesid`` command.

    bayesid simulate --vehicle nps_auv2 --manoeuvre zigzag --angle 20 --mode horizontal --out track.csv
    bayesid convert --format esso-osaka ../shared/data/real/esso-osaka-frt --out tracks/esso

    bayesid diagnose --vehicle nps_auv2 --free Yv,Yr,Nv,Nr,Ydr,Ndr --train A.csv B.csv \
        --heldout C.csv --window 60 --out diag

Later issues add ``fit`` and ``predict`` (DESIGN.md "Command line").
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from . import datasets
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


def _convert(args) -> int:
    """``bayesid convert``: third-party run files -> one Track CSV each + convert.json/.md."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a folder")
    sources, skipped, seen = [], [], set()
    for item in args.inputs:
        kept, skip = datasets._scan_runs(item, args.format)
        if not kept:
            raise ValueError(f"{item}: no {args.format} run files found")
        for p in kept:
            if p.resolve() not in seen:
                seen.add(p.resolve())
                sources.append(p)
        skipped += skip
    skipped = [(p, why) for p, why in skipped if p.resolve() not in seen]
    # Read and check every file before writing anything.
    tracks = [datasets.read_run(p, args.format) for p in sources]
    runs, used = [], set()
    try:
        out.mkdir(parents=True, exist_ok=True)
        for src, tr in zip(sources, tracks):
            stem = re.sub(r"[^A-Za-z0-9._-]+", "_", src.stem).strip("._-") or "run"
            name, k = stem, 1
            while name.lower() in used:
                k += 1
                name = f"{stem}_{k}"
            used.add(name.lower())
            dest = out / f"{name}.csv"
            write_csv(tr, dest)
            duration = float(tr.t[-1] - tr.t[0])
            rate = tr.meta.get("sample_rate_hz")
            runs.append({
                "source": str(src), "output": str(dest), "n_samples": tr.n_samples,
                "duration_s": duration, "t_start_s": float(tr.t[0]),
                "columns": ["t", *tr.state_columns, *tr.input_columns, *tr.exogenous_columns],
                "sample_rate_hz": rate, "vessel": tr.meta.get("vessel"),
                "conversions": tr.meta.get("conversions", []), "notes": tr.meta.get("notes", []),
            })
            print(f"{src} -> {dest}: {tr.n_samples} samples, {duration:.1f} s"
                  + (f" at {rate:g} Hz" if rate else ""))
        for p, why in skipped:
            print(f"skipped {p}: {why}")
        summary = {"command": "convert", "format": args.format, "out": str(out),
                   "n_runs": len(runs), "runs": runs,
                   "skipped": [{"source": str(p), "reason": why} for p, why in skipped]}
        (out / "convert.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
        lines = [f"# bayesid convert --format {args.format}", "",
                 f"{len(runs)} run(s) converted to Track CSVs (SI, rad, rpm; rudder + = to port).", "",
                 "| output | samples | duration (s) | rate (Hz) | notes |", "|---|---|---|---|---|"]
        lines += [f"| {Path(r['output']).name} | {r['n_samples']} | {r['duration_s']:.1f} | "
                  f"{r['sample_rate_hz']} | {'; '.join(r['notes']) or '-'} |" for r in runs]
        if skipped:
            lines += ["", "Skipped:", *[f"- {p}: {why}" for p, why in skipped]]
        (out / "convert.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise ValueError(f"cannot write to {out}: {exc}") from None
    print(f"wrote {out / 'convert.json'}: {len(runs)} run(s)")
    return 0


def _diagnose(args) -> int:
    """``bayesid diagnose``: base fit, where / which / how far (bayesid.gap)."""
    import numpy as np

    from . import effects, gap
    from .track import read_csv

    vehicle = load_vehicle(args.vehicle)
    free = [n.strip() for n in args.free.split(",") if n.strip()] if args.free else []
    from . import terms
    terms.check_names(free, "--free")
    train = [read_csv(p) for p in args.train]
    held = [read_csv(p) for p in args.heldout]
    cands = list(effects.CATALOGUE) if not args.candidates else [c.strip() for c in args.candidates.split(",")]
    for c in (args.exclude.split(",") if args.exclude else []):
        if c.strip() not in cands:
            raise ValueError(f"--exclude {c.strip()}: not among the candidates {cands}")
        cands.remove(c.strip())
    window = None if args.window <= 0 else args.window
    res = gap.diagnose(vehicle, free, train, held, candidates=cands, window_s=window, dt=args.dt,
                       mode=args.mode, rng=np.random.default_rng(args.seed), max_nfev=args.max_nfev,
                       max_effects=args.max_effects, progress=lambda m: print(f"  {m}", flush=True))
    gap.write_report(res, args.out, held, command="bayesid " + " ".join(sys.argv[1:]))
    print(f"verdict: {res['verdict']}; held-out RMS {res['gap_before']['heldout_rms_m']:.3f} m -> "
          f"{res['gap_after']['heldout_rms_m']:.3f} m; wrote {Path(args.out) / 'diagnosis.json'}")
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
    c = sub.add_parser("convert", help="third-party data files -> Track CSVs (one per run)")
    c.add_argument("--format", required=True, choices=datasets.FORMATS,
                   help="data set format (see bayesid.datasets)")
    c.add_argument("inputs", nargs="+", metavar="IN",
                   help="run file or data set folder (searched recursively; duplicates skipped)")
    c.add_argument("--out", required=True, help="output folder (created if absent)")
    d = sub.add_parser("diagnose", help="sim-to-real gap: where / which effect / how far")
    d.add_argument("--vehicle", required=True, help="packaged id or TOML path (nominal coefficients)")
    d.add_argument("--free", default="Yv,Yr,Nv,Nr,Ydr,Ndr", help="comma-separated free coefficients")
    d.add_argument("--train", nargs="+", required=True, metavar="CSV", help="training Track CSVs")
    d.add_argument("--heldout", nargs="+", required=True, metavar="CSV", help="held-out Track CSVs")
    d.add_argument("--window", type=float, default=60.0, help="protocol window, s (<= 0: whole run)")
    d.add_argument("--dt", type=float, default=0.5, help="model integration step, s")
    d.add_argument("--mode", choices=MODES, default="horizontal")
    d.add_argument("--candidates", default="", help="comma-separated effects (default: whole catalogue)")
    d.add_argument("--exclude", default="", help="comma-separated effects left out of the candidates")
    d.add_argument("--max-effects", type=int, default=1, help="greedy rounds of effect addition")
    d.add_argument("--max-nfev", type=int, default=60, help="least-squares iterations per fit")
    d.add_argument("--seed", type=int, default=0)
    d.add_argument("--out", required=True, help="output folder")
    args = ap.parse_args(argv)
    try:
        run = {"convert": _convert, "simulate": _simulate, "diagnose": _diagnose}[args.command]
        return run(args)
    except (ValueError, KeyError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
