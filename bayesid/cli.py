"""The ``bayesid`` command.

    bayesid simulate --vehicle nps_auv2 --manoeuvre zigzag --angle 20 --mode horizontal --out track.csv
    bayesid convert --format esso-osaka ../shared/data/real/esso-osaka-frt --out tracks/esso

    bayesid diagnose --vehicle nps_auv2 --free Yv,Yr,Nv,Nr,Ydr,Ndr --train A.csv B.csv \
        --heldout C.csv --window 60 --out diag

    bayesid fit --vehicle esso_osaka_3m --train A.csv B.csv --effects wind --out fitdir
    bayesid predict --model fitdir/model.json --track C.csv --window 60 --out pred
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from . import protocol, tasks
from .data import datasets
from .data.track import write_csv
from .data.vehicle import load_vehicle
from .models import manoeuvres as mv
from .models.simulate import MODES, Simulator
from .report.convert import write_convert_report

#: Longest simulation ``bayesid simulate`` runs (model steps): 1e6 s at 0.1 s.
MAX_SIMULATE_STEPS = 10_000_000


def _simulate(args) -> int:
    _check_out(args.out, "simulate", args.overwrite)
    if not args.dt > 0 or not args.sample > 0:
        raise ValueError(f"--dt and --sample must be positive (s), got {args.dt} and {args.sample}")
    if args.duration is not None and args.duration / args.dt > MAX_SIMULATE_STEPS:
        raise ValueError(
            f"--duration {args.duration:g} s at --dt {args.dt:g} s is {args.duration / args.dt:.3g} steps "
            f"(at most {MAX_SIMULATE_STEPS:.0e}); shorten --duration or lengthen --dt"
        )
    from .models import ship

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


def _convert(args) -> int:
    """``bayesid convert``: third-party run files -> one Track CSV each + convert.json/.md."""
    out = _check_out(args.out, "convert", args.overwrite)
    sources, skipped, seen = [], [], set()
    for item in args.inputs:
        kept, skip = datasets.scan_runs(item, args.format)
        if not kept:
            raise ValueError(f"{item}: no {args.format} run files found")
        for p in kept:
            if p.resolve() not in seen:
                seen.add(p.resolve())
                sources.append(p)
        skipped += skip
    skipped = [(p, why) for p, why in skipped if p.resolve() not in seen]
    # Read and check every file before writing anything.
    options = {}
    if args.scale is not None:
        if args.format != "simman-marin":
            raise ValueError(
                f"--scale applies to --format simman-marin only (the {args.format} files are at model scale)"
            )
        options["scale"] = args.scale
    tracks = [datasets.read_run(p, args.format, **options) for p in sources]
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
            runs.append(
                {
                    "source": str(src),
                    "output": str(dest),
                    "n_samples": tr.n_samples,
                    "duration_s": duration,
                    "t_start_s": float(tr.t[0]),
                    "columns": ["t", *tr.state_columns, *tr.input_columns, *tr.exogenous_columns],
                    "sample_rate_hz": rate,
                    "vessel": tr.meta.get("vessel"),
                    "conversions": tr.meta.get("conversions", []),
                    "notes": tr.meta.get("notes", []),
                }
            )
            print(f"{src} -> {dest}: {tr.n_samples} samples, {duration:.1f} s" + (f" at {rate:g} Hz" if rate else ""))
        for p, why in skipped:
            print(f"skipped {p}: {why}")
        summary = {
            "command": "convert",
            "format": args.format,
            "out": str(out),
            "n_runs": len(runs),
            "runs": runs,
            "skipped": [{"source": str(p), "reason": why} for p, why in skipped],
        }
        write_convert_report(summary, out)
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise ValueError(f"cannot write to {out}: {exc}") from None
    print(f"wrote {out / 'convert.json'}: {len(runs)} run(s)")
    return 0


def _check_numbers(args) -> None:
    """Numeric options: finite, and positive (or non-negative) where they must be; ValueError
    naming the option."""
    import math

    for k, v in vars(args).items():
        if isinstance(v, float) and not math.isfinite(v):
            raise ValueError(f"--{k.replace('_', '-')} must be a finite number, not {v}")
    positive = ("dt", "sample", "max_nfev", "max_effects", "scale")
    non_negative = ("draws", "leadin", "fit_window", "duration", "seed")
    for k in positive:
        v = getattr(args, k, None)
        if v is not None and not v > 0:
            raise ValueError(f"--{k.replace('_', '-')} must be positive, not {v}")
    for k in non_negative:
        v = getattr(args, k, None)
        if v is not None and not v >= 0:
            raise ValueError(f"--{k.replace('_', '-')} must be >= 0, not {v}")


def _split_names(text, option: str = ""):
    """Comma-separated names of an option; a name given twice is a ValueError naming the option."""
    names = [n.strip() for n in text.split(",") if n.strip()] if text else []
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"{option or 'option'}: {', '.join(twice)} given twice")
    return names


#: What each command writes into its --out folder (removed first by --overwrite).
WRITES = {
    "diagnose": ("diagnosis.json", "report.md", "figures"),
    "fit": ("model.json", "report.md", "figures", "journal.jsonl"),
    "predict": ("predict.json", "report.md", "figures"),
    "sample": (
        "sample.json",
        "report.md",
        "figures",
        "journal.jsonl",
        "chains.h5",
        "posterior.nc",
        "posterior_model.json",
        "fit",
    ),
    "convert": ("convert.json", "convert.md"),
}


#: The file that marks a folder as a command's output.
MAIN_OUTPUT = {
    "diagnose": "diagnosis.json",
    "fit": "model.json",
    "predict": "predict.json",
    "convert": "convert.json",
    "sample": "sample.json",
}


def _check_out(path, command: str, overwrite: bool, resumable: bool = False) -> Path:
    """``--out`` checked before any computation: a folder (or for ``simulate`` a file) that can
    be created and written. An existing non-empty folder is refused unless ``overwrite``; then
    what ``command`` writes there (and, for ``convert``, the CSVs its ``convert.json`` lists) is
    removed first, so nothing stale survives. Even with ``overwrite``, a folder holding another
    command's output (:data:`MAIN_OUTPUT`), or files named like this command's output without
    its main file (the user's), is refused. With ``resumable``, a folder holding only this
    command's ``journal.jsonl`` and outputs but no main file (a killed run) is kept as it is, so
    the same command resumes it. Raises ValueError naming the option and path."""
    import os
    import shutil

    out = Path(path)
    if command == "simulate":
        if out.is_dir():
            raise ValueError(f"--out {out}: is a folder; give a file name for the track CSV")
        if out.exists() and not overwrite:
            raise ValueError(f"--out {out}: exists; pass --overwrite to replace it")
        parent = out.parent
    else:
        if out.exists() and not out.is_dir():
            raise ValueError(f"--out {out}: exists and is not a folder")
        interrupted = (
            resumable
            and not overwrite
            and out.is_dir()
            and (out / "journal.jsonl").is_file()
            and not (out / MAIN_OUTPUT[command]).exists()
            and all(q.name in WRITES.get(command, ()) for q in out.iterdir())
        )
        if interrupted:
            print(f"resuming the finished tasks of {out / 'journal.jsonl'}")
        elif out.is_dir() and any(out.iterdir()):
            if not overwrite:
                raise ValueError(
                    f"--out {out}: folder is not empty; pass --overwrite to replace what "
                    f"'bayesid {command}' writes there"
                )
            # --overwrite replaces this command's earlier output only, never another's or the user's
            for other, main in MAIN_OUTPUT.items():
                if other != command and (out / main).exists():
                    raise ValueError(
                        f"--out {out}: holds the output of 'bayesid {other}' ({main}); give "
                        f"'bayesid {command}' a folder of its own"
                    )
            own = [n for n in WRITES.get(command, ()) if (out / n).exists()]
            if own and not (out / MAIN_OUTPUT[command]).is_file():
                raise ValueError(
                    f"--out {out}: {', '.join(own)} exist(s) but no {MAIN_OUTPUT[command]}, so "
                    f"'bayesid {command}' did not write them; move them or choose another folder"
                )
            old = out / "convert.json"
            if command == "convert" and old.is_file():
                try:
                    listed = [Path(r["output"]) for r in json.loads(old.read_text()).get("runs", [])]
                except (ValueError, KeyError, TypeError):
                    listed = []
                for f in listed:
                    if f.is_file() and f.resolve().parent == out.resolve():
                        f.unlink()
            for name in WRITES.get(command, ()):
                q = out / name
                if q.is_dir():
                    shutil.rmtree(q)
                elif q.exists():
                    q.unlink()
        parent = out
    probe = parent
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise ValueError(f"--out {out}: {probe} is a file, not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ValueError(f"--out {out}: cannot write into {probe} (permission denied)")
    return out


def _file_sha256(path) -> str:
    import hashlib

    with open(path, "rb") as f:  # streamed: a 300 MB log is not held in memory to hash it
        return hashlib.file_digest(f, "sha256").hexdigest()


def same_values(a, b, rtol: float = 1e-5) -> bool:
    """True when two tracks hold the same samples up to the precision of an export: the same
    number of rows, and ``t``, ``x``, ``y``, ``psi`` (those both have) equal within ``rtol`` of
    each column's largest magnitude (a 6-significant-digit copy of a full-precision file is the
    same log; two logs of one manoeuvre differ by their noise)."""
    import numpy as np

    if a.n_samples != b.n_samples:
        return False
    for k in ("t", "x", "y", "psi"):
        if k != "t" and (k not in a or k not in b):
            continue
        u, v = np.asarray(a[k], float), np.asarray(b[k], float)
        if not np.array_equal(np.isnan(u), np.isnan(v)):
            return False
        ok = np.isfinite(u)
        scale = float(np.max(np.abs(u[ok]), initial=0.0))
        if ok.any() and np.max(np.abs(u[ok] - v[ok])) > rtol * scale + 1e-12:
            return False
    return True


#: Track name -> the file it was read from (this command's tracks), to name files in messages.
_TRACK_FILES: dict[str, str] = {}


def _with_files(message: str) -> str:
    """A message that names a track (``track 'run3'``) also names its file."""
    for name, path in _TRACK_FILES.items():
        message = message.replace(f"track {name!r}", f"track {name!r} ({path})")
    return message


def _read_tracks(groups, vehicle=None) -> dict:
    """Read the track files of each option (``[(option, [paths])]``) once: a file given twice, a
    file whose content equals another one (a renamed copy) or whose samples do
    (:func:`same_values`: another export of one log), a folder, and two tracks with the same name
    are errors naming both; every track passes :func:`bayesid.data.validate.check_track` (units;
    plausibility for ``vehicle``), whose warnings are printed. Returns {option: [Track]},
    the files' SHA-256 under ``"_sha256"`` and the warnings under ``"_warnings"``."""
    from .data.track import read_csv
    from .data.validate import check_track

    seen, names, out, hashes, warnings, read = {}, {}, {}, {}, [], []
    for option, paths in groups:
        out[option] = []
        for p in paths:
            p = Path(p)
            if p.is_dir():
                raise ValueError(f"{option} {p}: is a folder, not a track CSV")
            if not p.is_file():
                raise FileNotFoundError(f"{option} {p}: no such file")
            h = _file_sha256(p)
            if h in seen:
                o, q = seen[h]
                raise ValueError(
                    f"{option} {p} has the same content as {o} {q}: a track may be given once"
                    + (" (training and held-out tracks must differ)" if o != option else "")
                )
            seen[h] = (option, p)
            tr = read_csv(p)
            if tr.name in names:
                raise ValueError(
                    f"{option} {p} and {names[tr.name]} are both named {tr.name!r}; rename one "
                    "(results are reported by track name)"
                )
            names[tr.name] = p
            _TRACK_FILES[tr.name] = str(p)
            hashes[str(p)] = h
            warnings += check_track(tr, vehicle, str(p))
            for o, q, other in read:
                if same_values(tr, other):
                    raise ValueError(
                        f"{option} {p} holds the same samples as {o} {q} (another export of one log?): "
                        "a track may be given once"
                        + (" (training and held-out tracks must differ)" if o != option else "")
                    )
            read.append((option, p, tr))
            out[option].append(tr)
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)
    out["_sha256"], out["_warnings"] = hashes, warnings
    return out


def _free_list(vehicle, text):
    """The free coefficients of a command: ``--free`` or the vehicle's default (ships: the
    file's ``[fit] free``; submarines: the horizontal-plane six). Unknown names raise."""
    from .models import model_class

    family = model_class(vehicle)
    free = _split_names(text, "--free") or family.default_free(vehicle)
    family.check_free(vehicle, free, "--free")
    return free


def _vehicle_ref(arg: str) -> str:
    p = Path(arg)
    return str(p.resolve()) if p.suffix or p.exists() else arg


def _provenance(vehicle, input_sha256: dict) -> dict:
    """What produced a model: package version, the vehicle file (path, SHA-256, values) and the
    SHA-256 of every input file."""
    from . import __version__

    vf = Path(vehicle.file_path) if vehicle.file_path else None
    return {
        "bayesid_version": __version__,
        "vehicle_file": str(vf) if vf else None,
        "vehicle_sha256": _file_sha256(vf) if vf and vf.is_file() else None,
        "vehicle_coefficients": dict(vehicle.coefficients),
        "input_sha256": dict(input_sha256),
    }


def _check_vehicle_unchanged(doc: dict, vehicle, model_path, allow: bool) -> None:
    """Refuse (ValueError) to predict with a model whose vehicle file changed after the fit; with
    ``allow`` print a warning instead."""

    want = (doc.get("provenance") or {}).get("vehicle_sha256")
    vf = Path(vehicle.file_path) if vehicle.file_path else None
    if want is None or vf is None or not vf.is_file():
        return
    if _file_sha256(vf) != want:
        msg = (
            f"--model {model_path}: the vehicle file {vf} changed after the fit (SHA-256 differs); the "
            "non-free coefficients and particulars the model was fitted with may differ"
        )
        if not allow:
            raise ValueError(msg + "; pass --allow-changed-vehicle to predict anyway")
        print(f"WARNING: {msg}", file=sys.stderr)


def _fit(args) -> int:
    """``bayesid fit``: multiple-shooting identification -> DIR/model.json + report.md."""
    import numpy as np

    from .estimation import msfit
    from .models import load_any_vehicle
    from .report import write_fit_report, write_json

    if args.window is not None and not args.window > 0:
        raise ValueError(f"--window must be a positive number of seconds, not {args.window:g}")
    if args.starts < 0:
        raise ValueError(f"--starts must be >= 0, not {args.starts}")
    tasks.check_jobs(args.jobs, args.scheduler)
    if not args.calibration_window > 0 or args.calibration_draws < 3:
        raise ValueError(
            f"--calibration-window must be positive and --calibration-draws at least 3, not "
            f"{args.calibration_window:g} and {args.calibration_draws}"
        )
    out = _check_out(args.out, "fit", args.overwrite, resumable=bool(args.starts) or args.calibration == "loro")
    vehicle = load_any_vehicle(args.vehicle)
    free = _free_list(vehicle, args.free)
    got = _read_tracks([("--train", args.train)], vehicle)
    train = got["--train"]
    effects = _split_names(args.effects, "--effects")
    channels = _split_names(args.fit_channels, "--fit-channels") or None
    journal = None
    calibrate = args.calibration == "loro" and len(train) >= 3
    if args.starts or calibrate:
        # finished starts survive a killed run: the same command resumes them
        journal = tasks.Journal(
            out / "journal.jsonl",
            {
                "command": "fit",
                "inputs": sorted(got["_sha256"].values()),
                "vehicle": _provenance(vehicle, {})["vehicle_sha256"] or args.vehicle,
                "free": free,
                "effects": effects,
                "window": args.window,
                "dt": args.dt,
                "max_nfev": args.max_nfev,
                "weighting": args.weighting,
                "channels": channels,
                "start": args.start,
                "starts": args.starts,
                "seed": args.seed,
                "prior": args.prior,
                "calibration": args.calibration if calibrate else "none",
                "calibration_window": args.calibration_window,
                "calibration_draws": args.calibration_draws,
            },
        )
    res = msfit.identify(
        vehicle,
        train,
        free,
        effects,
        window_s=args.window,
        dt=args.dt,
        max_nfev=args.max_nfev,
        progress=lambda m: print(f"  {m}", flush=True),
        weighting=args.weighting or None,
        channels=channels,
        start=args.start,
        starts=args.starts,
        rng=np.random.default_rng(args.seed),
        jobs=args.jobs,
        scheduler=args.scheduler,
        journal=journal,
        prior=args.prior == "file",
        calibrate=calibrate,
        calibration_window_s=args.calibration_window,
        calibration_draws=args.calibration_draws,
        calibration_seed=args.seed,
    )
    doc = msfit.model_document(
        res,
        _vehicle_ref(args.vehicle),
        [t.name for t in train],
        provenance=dict(_provenance(vehicle, got["_sha256"]), warnings=got["_warnings"]),
    )
    circles = None
    if res["multistart"] is not None:
        circles = _multistart_circles(res, doc, train)
    write_json(out / "model.json", doc)
    write_fit_report(doc, out, command="bayesid " + " ".join(sys.argv[1:]))
    if res["multistart"] is not None:
        from .report import plots

        (out / "figures").mkdir(parents=True, exist_ok=True)
        plots.multistart(doc["multistart"], circles, out / "figures" / "multistart.png")
    print(
        f"training RMS position {res['train_scores']['rms_position_m']:.3f} m over {res['window_s']:g} s windows; "
        f"wrote {out / 'model.json'}"
    )
    return 0


#: Units of each scored channel in reports: (factor from SI, label).
_UNITS = {
    "x": (1.0, "m"),
    "y": (1.0, "m"),
    "psi": (57.29577951308232, "deg"),
    "u": (1.0, "m/s"),
    "v": (1.0, "m/s"),
    "r": (57.29577951308232, "deg/s"),
}


def _sample(args) -> int:
    """``bayesid sample``: the posterior of a fitted model given its training tracks ->
    DIR/sample.json, posterior.nc, report.md, figures, posterior_model.json."""
    import numpy as np

    from . import __version__
    from .analysis.dossier import AT_PRIOR, DETERMINED, data_dossier
    from .estimation import msfit
    from .estimation import track_posterior as tp
    from .models import load_any_vehicle
    from .protocol import resolve_start
    from .report import plots, write_json, write_sample_report

    if (args.model is None) == (args.vehicle is None):
        raise ValueError("give --model (a model.json of bayesid fit) or --vehicle (fit first), not both or neither")
    if args.draws < 100:
        raise ValueError(f"--draws must be at least 100, not {args.draws}")
    if not args.df > 0 or not args.max_minutes > 0:
        raise ValueError(f"--df and --max-minutes must be positive, not {args.df:g} and {args.max_minutes:g}")
    tasks.check_jobs(args.jobs, args.scheduler)
    out = _check_out(args.out, "sample", args.overwrite, resumable=True)
    vehicle_arg = args.vehicle
    if args.model is not None:
        model, p, _cov, doc = msfit.load_model(args.model)
        _check_vehicle_unchanged(doc, model.vehicle, args.model, False)
        got = _read_tracks([("--train", args.train)], model.vehicle)
        fitted = set(((doc.get("provenance") or {}).get("input_sha256") or {}).values())
        other = [f for f, h in got["_sha256"].items() if fitted and h not in fitted]
        if other:
            w = f"{', '.join(other)}: not among the tracks {args.model} was fitted on; the posterior is over these tracks"
            print(f"warning: {w}", file=sys.stderr)
            got["_warnings"].append(w)
        model_sha = _file_sha256(args.model)
    else:
        vehicle = load_any_vehicle(vehicle_arg)
        got = _read_tracks([("--train", args.train)], vehicle)
        print("  fitting first (bayesid fit with its defaults)", flush=True)
        res = msfit.identify(
            vehicle,
            got["--train"],
            _free_list(vehicle, args.free),
            _split_names(args.effects, "--effects"),
            progress=lambda m: print(f"  {m}", flush=True),
            prior=args.prior == "file",
            jobs=args.jobs,
            scheduler=args.scheduler,
        )
        doc = msfit.model_document(
            res,
            _vehicle_ref(vehicle_arg),
            [t.name for t in got["--train"]],
            provenance=dict(_provenance(vehicle, got["_sha256"]), warnings=got["_warnings"]),
        )
        (out / "fit").mkdir(parents=True, exist_ok=True)
        write_json(out / "fit" / "model.json", doc)
        model, p, _cov, doc = msfit.load_model(out / "fit" / "model.json")
        model_sha = _file_sha256(out / "fit" / "model.json")
    train = got["--train"]
    rule = resolve_start(doc.get("start_rule", "auto"), train)
    identity = {
        "command": "sample",
        "model_sha256": model_sha,
        "inputs": sorted(got["_sha256"].values()),
        "seed": args.seed,
        "method": args.method,
        "draws": args.draws,
        "df": args.df,
        "prior": args.prior,
    }
    journal = tasks.Journal(out / "journal.jsonl", identity)
    res = tp.sample_tracks(
        model,
        p,
        train,
        window_s=doc["fit_window_s"],
        start_rule=rule,
        fit_sd=doc.get("fit_sd") or doc["noise_sd"],
        channels=doc.get("fit_channels"),
        use_prior=args.prior == "file",
        method=args.method,
        n_draws=args.draws,
        df=args.df,
        seed=args.seed,
        max_minutes=args.max_minutes,
        folds=[f["p"] for f in ((doc.get("calibration") or {}).get("folds") or []) if "p" in f],
        jobs=args.jobs,
        scheduler=args.scheduler,
        journal=journal,
        checkpoint=out / "chains.h5",
        run_key=identity,
        progress=lambda m: print(f"  {m}", flush=True),
    )
    names, draws, prior = res["names"], res["draws"], res["prior"]
    scales = model.scales()
    dos = data_dossier(
        names,
        res["mode"]["fisher"],
        res["mode"]["jac"],
        scales,
        prior.marginal_mean(),
        prior.marginal_sd(),
        prior.gaussian,
        draws,
    )
    q05, q95 = np.quantile(draws, [0.05, 0.95], axis=0)
    em = res["errors"].to_dict()
    for j, c in enumerate(res["errors"].channels):
        f, unit = _UNITS.get(c, (1.0, ""))
        s = res["sigma"][:, j] * f
        em[c]["unit"] = unit
        em[c]["sigma_at_mode"] *= f
        em[c]["sigma_posterior"] = {
            "mean": float(np.mean(s)),
            "q05": float(np.quantile(s, 0.05)),
            "q95": float(np.quantile(s, 0.95)),
        }
    label = {
        "importance": f"importance-reweighted Laplace ({args.draws} multivariate Student-t draws, df {args.df:g}, "
        "Pareto-smoothed weights, resampled)",
        "mcmc": "MCMC (2 independent emcee ensembles, DE moves, run until converged or the budget)",
    }[res["method"]]
    sdoc = {
        "format": "bayesid-sample-1",
        "model": str(args.model) if args.model else str(out / "fit" / "model.json"),
        "vehicle": doc["vehicle"],
        "train_runs": [t.name for t in train],
        "input_sha256": got["_sha256"],
        "warnings": got["_warnings"],
        "seed": args.seed,
        "method_requested": args.method,
        "method": res["method"],
        "method_label": label,
        "n_draws": int(draws.shape[0]),
        "df": args.df,
        "window_s": doc["fit_window_s"],
        "start_rule": rule,
        "start_states": (
            "measured (causal 1 s estimate at each window start)"
            if rule == "measured"
            else "profiled: fitted for every parameter draw, as in the fit (6 per window; sampling them would add "
            f"{6 * res['n_windows']} dimensions)"
        ),
        "verdict": res["verdict"],
        "cost": {
            "seconds_per_evaluation": res["seconds_per_evaluation"],
            "n_windows": res["n_windows"],
            "n_parameters": len(names),
            "seconds": res["seconds"],
        },
        "error_model": em,
        "between_runs": dict(res["between_runs"], per_parameter=dict(zip(names, res["between_runs"]["per_parameter"]))),
        "prior": {
            "used": args.prior == "file",
            "source": getattr(model.vehicle, "prior_source", ""),
            **prior.to_dict(),
        },
        "fit_estimate": dict(zip(names, map(float, p))),
        "mode": dict(zip(names, map(float, res["mode"]["p"]))),
        "laplace_sd": dict(zip(names, map(float, np.sqrt(np.diag(res["mode"]["cov"]))))),
        "marginals": {
            n: {
                "mean": float(draws[:, j].mean()),
                "sd": float(draws[:, j].std(ddof=1)),
                "q05": float(q05[j]),
                "q95": float(q95[j]),
            }
            for j, n in enumerate(names)
        },
        "thresholds": {"determined": DETERMINED, "at_prior": AT_PRIOR},
        "dossier": dos,
        "figures": {"sampler": "trace" if res["method"] == "mcmc" else "weights"},
        "provenance": {
            "version": __version__,
            "command": "bayesid " + " ".join(sys.argv[1:]),
            "model_sha256": model_sha,
        },
    }
    idata = tp.inference_data(
        res, {"bayesid_version": __version__, "seed": args.seed, "method": res["method"], "model_sha256": model_sha}
    )
    tmp = out / "posterior.nc.part"
    idata.to_netcdf(str(tmp))
    tmp.replace(out / "posterior.nc")
    figs = out / "figures"
    figs.mkdir(parents=True, exist_ok=True)
    pdict = prior.to_dict()
    plots.prior_posterior_marginals(draws, names, pdict, figs / "marginals.png", dict(zip(names, p)))
    pairs = [tuple(r["pair"]) for r in dos["correlations"][:3]]
    plots.pair_scatter(draws, names, pairs, figs / "pairs.png", title="Most correlated coefficients (posterior)")
    if res["method"] == "mcmc":
        r = res["mcmc"]["result"]
        show = list(dict.fromkeys([a for pr in pairs for a in pr]))[:6]
        plots.walker_traces(r.chains, names, show, figs / "trace.png", burn=res["mcmc"]["burn"])
    else:
        imp = res["importance"]
        plots.importance_weights(imp["weights"], imp["k_hat"], imp["ess"], figs / "weights.png")
    plots.fim_spectra(
        {"these tracks": dos["fisher_eigenvalues"]},
        figs / "fisher.png",
        title="Fisher information of the tracks",
        ylabel="Cramér–Rao sd along it (in typical sizes of the parameters)",
    )
    # the fit's model with this posterior: predict draws from it
    pm = json.loads(Path(sdoc["model"]).read_text())
    if not Path(pm["vehicle"]).is_absolute() and (Path(sdoc["model"]).parent / pm["vehicle"]).is_file():
        pm["vehicle"] = str((Path(sdoc["model"]).parent / pm["vehicle"]).resolve())
    cov = msfit.psd_covariance(np.cov(draws, rowvar=False))
    pm.update(p=res["mode"]["p"].tolist(), cov=cov.tolist(), sd=np.sqrt(np.diag(cov)).tolist())
    pm["posterior_source"] = {
        "sample": str(out / "sample.json"),
        "method": res["method"],
        "converged": bool(res["verdict"]["converged"]),
    }
    write_json(out / "posterior_model.json", pm)
    write_json(out / "sample.json", sdoc)
    write_sample_report(sdoc, out, command=sdoc["provenance"]["command"])
    print(f"{res['verdict']['text']} wrote {out / 'sample.json'}")
    return 0


def _multistart_circles(res, doc, train, rudder_deg: float = 35.0, most: int = 6):
    """35 deg turning circles (starboard) of the distinct near-best optima of a multistart fit,
    from the training runs' approach speed and propeller rate; their advance and tactical
    diameter go into ``doc["multistart"]["distinct_optima"]``. Returns [(label, x, y)] for the
    figure, or None when the model cannot simulate a turn from these tracks (said in the doc)."""
    import numpy as np

    from .estimation import msfit

    ms = doc["multistart"]
    try:
        u0, rps = msfit.approach_condition(train)
    except ValueError as exc:
        ms["turning_circle"] = {"error": str(exc)}
        return None
    ms["turning_circle"] = {"rudder_deg": rudder_deg, "side": "starboard", "speed_mps": u0, "rps": rps}
    out = []
    for k, opt in enumerate(ms["distinct_optima"][:most]):
        p = np.array([opt["coefficients"][n] for n in doc["param_names"]])
        tc = msfit.turning_circles(res["model"], p, None, 0, np.random.default_rng(0), u0, rps, rudder_deg)["starboard"]
        opt["turning_circle"] = tc["predicted"]
        S = tc["_S"][0]
        out.append(
            (
                f"optimum {k + 1}: cost +{100 * opt['relative_cost']:.2f} %, tactical diameter "
                f"{tc['predicted']['tactical_diameter_m']:.3g} m",
                S[:, 0],
                S[:, 1],
            )
        )
    td = [o["turning_circle"]["tactical_diameter_m"] for o in ms["distinct_optima"][:most]]
    td = [v for v in td if v is not None and np.isfinite(v)]
    ms["tactical_diameter_range_m"] = [min(td), max(td)] if td else None
    return out


def _predict(args) -> int:
    """``bayesid predict``: the window protocol (and whole run) on tracks -> DIR/predict.json."""
    import numpy as np

    from .estimation import msfit
    from .estimation.calibration import calibrated_bands, excitation, window_band
    from .report import plots, write_json, write_predict_report

    out = _check_out(args.out, "predict", args.overwrite)
    model, p, cov, doc = msfit.load_model(args.model)
    _check_vehicle_unchanged(doc, model.vehicle, args.model, args.allow_changed_vehicle)
    got = _read_tracks([("--track", args.track)], model.vehicle)
    tracks = got["--track"]
    trained = {h: f for f, h in ((doc.get("provenance") or {}).get("input_sha256") or {}).items()}
    for f, h in got["_sha256"].items():
        if h in trained:
            w = (
                f"{f}: the model was fitted on this file ({trained[h]}): its scores are training scores, "
                "not a prediction of unseen data"
            )
            print(f"warning: {w}", file=sys.stderr)
            got["_warnings"].append(w)
    window = None if args.window <= 0 else args.window
    for tr in tracks:
        if window is not None and tr.t[-1] - tr.t[0] < window:
            w = (
                f"{tr.name}: lasts {tr.t[-1] - tr.t[0]:.3g} s, less than one {window:g} s window: its score is "
                "over that shorter span, not comparable with full windows"
            )
            print(f"warning: {w}", file=sys.stderr)
            got["_warnings"].append(w)
    lead = args.leadin if args.leadin > 0 else None
    pr = msfit.predict(model, p, tracks, window, start=args.start, leadin_s=lead)
    whole = msfit.predict(model, p, tracks, None, start=args.start, leadin_s=lead)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    indices = {}
    for tr in tracks:
        tb = msfit.turning_band(
            model, p, cov, tr, args.draws, rng, start=whole["start_rule"], leadin_s=whole["leadin_s"]
        )
        indices[tr.name] = {k: v for k, v in tb.items() if not k.startswith("_")}
    bands = calibrated_bands(
        doc.get("calibration"), window, pr["windows"], indices, excitations={t.name: excitation(t) for t in tracks}
    )
    b90 = window_band(doc["calibration"], 0.9) if bands.get("windows") else {}
    for tr in tracks:
        ctx, S = pr["_sim"][tr.name]
        k = max(1, ctx.ts.size // 100000)  # a figure needs no more than 1e5 points a line
        dr = np.asarray(tr["delta_r"], float)[ctx.idx]
        plots.prediction_band(
            ctx.ts[::k],
            {"x": ctx.meas["x"][::k], "y": ctx.meas["y"][::k], "psi": ctx.meas["psi"][::k], "delta_r": dr[::k]},
            {"x": S[::k, 0], "y": S[::k, 1], "psi": S[::k, 5]},
            ctx.win[::k],
            b90,
            out / "figures" / f"{tr.name}.png",
            title=f"{tr.name}: {window or 'whole-run'} s windows, identified model"
            + (
                " (extrapolated: band not calibrated)"
                if tr.name in (bands.get("extrapolated") or {}).get("runs", [])
                else ""
            ),
        )
        del pr["_sim"][tr.name]
    if bands.get("coverage"):
        groups = {
            g: bands["coverage"][g]
            for g in ("windows", "indices")
            if any(v["n"] for v in bands["coverage"][g].values())
        }
        plots.reliability(groups, out / "figures" / "reliability.png", bands["parameter_only"])
    res = {
        "model": str(args.model),
        "window_s": window,
        "start_rule": pr["start_rule"],
        "leadin_s": pr["leadin_s"],
        "warnings": got["_warnings"],
        "input_sha256": got["_sha256"],
        "pooled": pr["pooled"],
        "per_track": pr["per_track"],
        "windows": pr["windows"],
        "whole_run": {"pooled": whole["pooled"], "per_track": whole["per_track"]},
        "indices": indices,
        "n_draws": args.draws,
        "bands": bands,
    }
    write_json(out / "predict.json", res)
    write_predict_report(res, out, [t.name for t in tracks], command=f"bayesid {' '.join(sys.argv[1:])}")
    c90 = ((bands.get("coverage") or {}).get("all") or {}).get("0.9") or {}
    ext = (bands.get("extrapolated") or {}).get("runs") or []
    print(
        f"pooled RMS position {pr['pooled']['rms_position_m']:.3f} m ({window} s windows)"
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
    return 0


def _diagnose(args) -> int:
    """``bayesid diagnose``: base fit, where / which / how far (bayesid.analysis.gap)."""
    import numpy as np

    from .analysis.gap import diagnose
    from .models import load_any_vehicle, model_class
    from .report import write_diagnosis

    tasks.check_jobs(args.jobs, args.scheduler)
    _check_out(args.out, "diagnose", args.overwrite)
    vehicle = load_any_vehicle(args.vehicle)
    family = model_class(vehicle)
    free = _free_list(vehicle, args.free)
    got = _read_tracks([("--train", args.train), ("--heldout", args.heldout)], vehicle)
    train, held = got["--train"], got["--heldout"]
    cands = list(family.CATALOGUE) if not args.candidates else _split_names(args.candidates, "--candidates")
    if not args.candidates:
        for name in list(cands):
            need = family.CATALOGUE[name].needs_columns
            if not all(c in t for t in train + held for c in need):
                cands.remove(name)
                print(f"  no {', '.join(need)} columns in every track: the {name} candidate is left out")
    for c in _split_names(args.exclude, "--exclude"):
        if c not in cands:
            raise ValueError(f"--exclude {c}: not among the candidates {cands}")
        cands.remove(c)
    window = None if args.window <= 0 else args.window
    dt = args.dt if args.dt is not None else family.DEFAULT_DT
    res = diagnose(
        vehicle,
        free,
        train,
        held,
        candidates=cands,
        window_s=window,
        dt=dt,
        mode=args.mode,
        rng=np.random.default_rng(args.seed),
        max_nfev=args.max_nfev,
        max_effects=args.max_effects,
        progress=lambda m: print(f"  {m}", flush=True),
        fit_window_s=args.fit_window if args.fit_window else None,
        weighting=args.weighting or None,
        start=args.start,
        leadin_s=args.leadin if args.leadin > 0 else None,
        progress_bars=True,
        jobs=args.jobs,
        scheduler=args.scheduler,
    )
    res.warnings = got["_warnings"]
    res.input_sha256 = got["_sha256"]
    write_diagnosis(res, args.out, held, command="bayesid " + " ".join(sys.argv[1:]))
    print(
        f"verdict: {res.verdict}; held-out RMS {res.gap_before['heldout_rms_m']:.3f} m -> "
        f"{res.gap_after['heldout_rms_m']:.3f} m (noise floor {res.noise_floor['heldout_rms_m']:.3f} m, "
        f"window starts {res.settings['start_rule']}); wrote {Path(args.out) / 'diagnosis.json'}"
    )
    return 0


START_HELP = (
    "window start states: measured (causal 1 s estimate), fitted (with the model, over a lead-in), "
    "auto (fitted when a track does not log u, v and r and its positions are too noisy for a 1 s "
    "slope estimate of the velocity)"
)
WEIGHTINGS = ("", "noise", "residual")
WEIGHTING_HELP = (
    "channel weights of the fits: noise sds, or the residual RMS of a first fit (two-step "
    "feasible GLS); default residual for ships, noise for submarines"
)


def main(argv=None) -> int:
    from . import __version__

    fmt = argparse.ArgumentDefaultsHelpFormatter
    ap = argparse.ArgumentParser(
        prog="bayesid", description="hydrodynamic coefficient identification", formatter_class=fmt
    )
    ap.add_argument("--version", action="version", version=f"bayesid {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)
    s = sub.add_parser("simulate", formatter_class=fmt, help="simulate a manoeuvre and write a Track CSV")
    s.add_argument("--vehicle", default="nps_auv2", help="packaged id or TOML path")
    s.add_argument("--manoeuvre", choices=["spiral", "turn", "zigzag", "straight"], default="spiral")
    s.add_argument("--angle", type=float, default=20.0, help="rudder angle, deg (turn, zigzag)")
    s.add_argument("--duration", type=float, default=None, help="s (turn, zigzag, straight)")
    s.add_argument("--dt", type=float, default=0.1, help="integration step, s")
    s.add_argument("--sample", type=float, default=0.1, help="output sample interval, s")
    s.add_argument("--mode", choices=MODES, default="6dof")
    s.add_argument("--crossflow", choices=["polynomial", "integral"], default=None)
    s.add_argument("--out", required=True)
    c = sub.add_parser("convert", formatter_class=fmt, help="third-party data files -> Track CSVs (one per run)")
    c.add_argument(
        "--format", required=True, choices=datasets.FORMATS, help="data set format (see bayesid.data.datasets)"
    )
    c.add_argument(
        "inputs", nargs="+", metavar="IN", help="run file or data set folder (searched recursively; duplicates skipped)"
    )
    c.add_argument("--out", required=True, help="output folder (created if absent)")
    c.add_argument(
        "--scale",
        type=float,
        default=None,
        help="simman-marin only: Froude scale lambda from the full-scale files to the model "
        f"(none: {datasets.KVLCC2_SCALE:.5g}, the 7 m KVLCC2 model of kvlcc2_7m; 1 keeps full scale)",
    )
    d = sub.add_parser("diagnose", formatter_class=fmt, help="sim-to-real gap: where / which effect / how far")
    d.add_argument("--vehicle", required=True, help="packaged id or TOML path (nominal coefficients)")
    d.add_argument(
        "--free",
        default="",
        help="comma-separated free coefficients (empty: the vehicle's; submarines Yv,Yr,Nv,Nr,Ydr,Ndr)",
    )
    d.add_argument("--train", nargs="+", required=True, metavar="CSV", help="training Track CSVs")
    d.add_argument("--heldout", nargs="+", required=True, metavar="CSV", help="held-out Track CSVs")
    d.add_argument("--window", type=float, default=60.0, help="protocol window, s (<= 0: whole run)")
    d.add_argument("--dt", type=float, default=None, help="model integration step, s (none: 0.5; ships 0.2)")
    d.add_argument(
        "--fit-window",
        type=float,
        default=0.0,
        help="window of the training fits, s (0: 15 for a ship, --window for a submarine)",
    )
    d.add_argument("--mode", choices=MODES, default="horizontal")
    d.add_argument("--candidates", default="", help="comma-separated effects (empty: the whole catalogue)")
    d.add_argument("--exclude", default="", help="comma-separated effects left out of the candidates")
    d.add_argument(
        "--max-effects",
        type=int,
        default=2,
        help="greedy rounds of effect addition (a contributor is added and the others tried on top)",
    )
    d.add_argument("--start", choices=protocol.START_RULES, default="auto", help=START_HELP)
    d.add_argument(
        "--leadin",
        type=float,
        default=0.0,
        help=f"lead-in of the fitted start rule, s (0: {protocol.LEADIN_S:g} s or "
        f"{protocol.LEADIN_SAMPLES} samples of the slowest log, at most --window)",
    )
    d.add_argument("--max-nfev", type=int, default=60, help="least-squares iterations per fit")
    d.add_argument(
        "--seed",
        type=int,
        default=0,
        help="random seed (noise-floor simulation, ensemble of the force-signature regression)",
    )
    d.add_argument("--weighting", choices=WEIGHTINGS, default="", help=WEIGHTING_HELP)
    tasks.add_arguments(d)
    d.add_argument("--out", required=True, help="output folder")
    f = sub.add_parser("fit", formatter_class=fmt, help="identify a model on training tracks (multiple shooting)")
    f.add_argument("--vehicle", required=True, help="packaged id or TOML path (ship or submarine)")
    f.add_argument("--train", nargs="+", required=True, metavar="CSV", help="training Track CSVs")
    f.add_argument("--free", default="", help="comma-separated free coefficients (empty: the vehicle's)")
    f.add_argument("--effects", default="", help="comma-separated effects in the model (ships: wind, current, delay)")
    f.add_argument(
        "--window",
        type=float,
        default=None,
        help="multiple-shooting window, s (none: 15 for a ship, bayesid.models.ship.FIT_WINDOW_S; 30 for a submarine)",
    )
    f.add_argument("--dt", type=float, default=None, help="model step, s (none: 0.2 ships, 0.5 submarines)")
    f.add_argument("--max-nfev", type=int, default=60, help="least-squares iterations")
    f.add_argument("--weighting", choices=WEIGHTINGS, default="", help=WEIGHTING_HELP)
    f.add_argument(
        "--fit-channels",
        default="",
        help="comma-separated scored channels in the objective, e.g. "
        "x,y,psi when the logged u, v, r are derived from positions and heading (empty: all measured)",
    )
    f.add_argument("--start", choices=protocol.START_RULES, default="auto", help=START_HELP)
    f.add_argument(
        "--starts",
        type=int,
        default=0,
        help="extra Latin-hypercube starts of a multistart fit (the lowest cost is kept; the report shows "
        "how many reach it and how far apart the near-best optima are)",
    )
    f.add_argument("--seed", type=int, default=0, help="random seed of the multistart starts and calibration draws")
    f.add_argument(
        "--calibration",
        choices=("loro", "none"),
        default="loro",
        help="loro: with 3 or more training runs, calibrate the predictive bands leave one run out (refit "
        "without each run, score the prediction of it); predict then reports bands that include the "
        "model's structural error",
    )
    f.add_argument(
        "--calibration-window",
        type=float,
        default=60.0,
        help="protocol window (s) of the calibrated window bands (predict --window must match)",
    )
    f.add_argument("--calibration-draws", type=int, default=40, help="posterior draws per calibration fold")
    f.add_argument(
        "--prior",
        choices=("file", "none"),
        default="file",
        help="file: Gaussian priors of the vehicle file's [prior] section (captive-test values with their "
        "error), a MAP fit; none: the data alone",
    )
    tasks.add_arguments(f)
    f.add_argument("--out", required=True, help="output folder (model.json, report.md)")
    pp = sub.add_parser("predict", formatter_class=fmt, help="score a fitted model on tracks with the window protocol")
    pp.add_argument("--model", required=True, help="model.json written by bayesid fit")
    pp.add_argument("--track", nargs="+", required=True, metavar="CSV", help="Track CSVs")
    pp.add_argument("--window", type=float, default=60.0, help="protocol window, s (<= 0: whole run)")
    pp.add_argument(
        "--draws",
        type=int,
        default=100,
        help="posterior draws for the index bands (100 gives a 5 %% quantile to about 2 draws)",
    )
    pp.add_argument("--seed", type=int, default=0, help="random seed of the posterior draws")
    pp.add_argument("--start", choices=protocol.START_RULES, default="auto", help=START_HELP)
    pp.add_argument(
        "--leadin",
        type=float,
        default=0.0,
        help=f"lead-in of the fitted start rule, s (0: {protocol.LEADIN_S:g} s or "
        f"{protocol.LEADIN_SAMPLES} samples of the slowest log, at most --window)",
    )
    pp.add_argument("--out", required=True, help="output folder")
    sm = sub.add_parser(
        "sample", formatter_class=fmt, help="posterior of a fitted model's parameters given its training tracks"
    )
    sm.add_argument("--model", default=None, help="model.json written by bayesid fit (or give --vehicle to fit first)")
    sm.add_argument("--vehicle", default=None, help="packaged id or TOML path: fit first with bayesid fit's defaults")
    sm.add_argument("--free", default="", help="with --vehicle: comma-separated free coefficients")
    sm.add_argument("--effects", default="", help="with --vehicle: comma-separated effects in the model")
    sm.add_argument("--train", nargs="+", required=True, metavar="CSV", help="the training Track CSVs")
    sm.add_argument(
        "--method",
        choices=("auto", "importance", "mcmc"),
        default="auto",
        help="importance: importance-reweighted Laplace; mcmc: emcee ensembles until converged; auto: "
        "importance, then MCMC when its Pareto k-hat >= 0.7 or ESS < 400",
    )
    sm.add_argument("--draws", type=int, default=4000, help="importance draws (and posterior draws kept)")
    sm.add_argument("--df", type=float, default=5.0, help="degrees of freedom of the Student-t proposal")
    sm.add_argument("--max-minutes", type=float, default=20.0, help="wall budget of the whole run incl. MCMC, min")
    sm.add_argument("--seed", type=int, default=0, help="random seed of every draw")
    sm.add_argument(
        "--prior",
        choices=("file", "none"),
        default="file",
        help="file: Gaussian priors of the vehicle file's [prior] section; none: uniform in the model's bounds",
    )
    tasks.add_arguments(sm)
    sm.add_argument("--out", required=True, help="output folder (resumed when it holds a killed run's journal)")
    for p in (s, c, d, f, pp, sm):
        p.add_argument(
            "--overwrite",
            action="store_true",
            help="replace what this command wrote before in --out (a non-empty --out is refused otherwise)",
        )
    pp.add_argument(
        "--allow-changed-vehicle",
        action="store_true",
        help="predict even if the vehicle file changed after the fit (a warning is printed)",
    )
    args = ap.parse_args(argv)
    try:
        _check_numbers(args)
        run = {
            "convert": _convert,
            "simulate": _simulate,
            "diagnose": _diagnose,
            "fit": _fit,
            "predict": _predict,
            "sample": _sample,
        }[args.command]
        return run(args)
    except (ValueError, KeyError, FileNotFoundError) as e:
        print(f"error: {_with_files(str(e))}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
