"""``bayesid convert``: third-party run files to one Track CSV each, with ``convert.json`` and
``convert.md`` listing them."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from ..data import datasets
from ..data.track import write_csv
from ..report.convert import write_convert_report
from . import options as opt
from .outputs import check_out


def add_parser(sub) -> None:
    """Declare ``bayesid convert`` and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    """
    c = opt.add_subcommand(sub, "convert", "third-party data files -> Track CSVs (one per run)")
    c.add_argument(
        "--format", required=True, choices=datasets.FORMATS, help="data set format (see bayesid.data.datasets)"
    )
    c.add_argument(
        "inputs", nargs="+", metavar="IN", help="run file or data set folder (searched recursively; duplicates skipped)"
    )
    opt.add_out(c, "output folder (created if absent)")
    opt.add_number(
        c,
        "--scale",
        opt.POSITIVE,
        default=None,
        help="simman-marin only: Froude scale lambda from the full-scale files to the model "
        f"(none: {datasets.KVLCC2_SCALE:.5g}, the 7 m KVLCC2 model of kvlcc2_7m; 1 keeps full scale)",
    )
    c.add_argument(
        "--vessel",
        default=None,
        metavar="ID",
        help="the vessel the runs are of, written as each CSV's '# vessel:' line (the vehicle id, or a "
        "vehicle TOML whose [vehicle] id is taken), so that fit / predict / diagnose / sample --vehicle ID "
        "take them; none: the data set's own vessel",
    )
    opt.add_overwrite(c)


def vessel_name(text: str) -> str:
    """The vessel named by ``--vessel``: a vehicle TOML's ``[vehicle] id`` (else its file stem),
    or the text itself (a packaged id or any name).

    Parameters
    ----------
    text : str
        The option's value.

    Returns
    -------
    str
        The name written in the ``# vessel:`` line.

    Raises
    ------
    ValueError
        An empty name, or a ``.toml`` file that does not exist or cannot be read (naming it).
    """
    text = str(text).strip()
    if not text:
        raise ValueError("--vessel: empty name; give the vehicle id or its TOML file")
    p = Path(text)
    if p.suffix.lower() != ".toml":
        return text
    try:
        with open(p, "rb") as fh:
            doc = tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"--vessel {text}: cannot read the vehicle file ({exc})") from None
    return str(doc.get("vehicle", {}).get("id") or p.stem)


def _set_vessel(track, vessel: str) -> None:
    """Make ``vessel`` the track's declared vessel (``meta["vessel"]`` and its ``# vessel:`` line),
    keeping what the data set said in a note."""
    said = track.meta.get("vessel")
    comments = [c for c in track.meta.get("comments", []) if not re.match(r"\s*vessel\s*[:=]", str(c), re.I)]
    at = next((i for i, c in enumerate(comments) if str(c).startswith("source:")), -1) + 1
    comments.insert(at, f"vessel: {vessel}")
    if said and said != vessel:
        note = f"vessel line set by bayesid convert --vessel; the data set says: {said}"
        comments.append(f"note: {note}")
        track.meta["notes"] = [*track.meta.get("notes", []), note]
    track.meta["comments"] = comments
    track.meta["vessel"] = vessel


def run(args) -> int:
    """Run ``bayesid convert``: every file is read and checked before anything is written.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.

    Returns
    -------
    int
        The exit code (0).
    """
    out = check_out(args.out, "convert", args.overwrite)
    sources, skipped = _sources(args)
    options = {}
    if args.scale is not None:
        if args.format != "simman-marin":
            raise ValueError(
                f"--scale applies to --format simman-marin only (the {args.format} files are at model scale)"
            )
        options["scale"] = args.scale
    vessel = vessel_name(args.vessel) if args.vessel is not None else None
    tracks = [datasets.read_run(p, args.format, **options) for p in sources]
    for tr in tracks if vessel is not None else ():
        _set_vessel(tr, vessel)
    try:
        out.mkdir(parents=True, exist_ok=True)
        runs = _write_tracks(sources, tracks, out)
        for p, why in skipped:
            print(f"skipped {p}: {why}")
        summary = {
            "command": "convert",
            "format": args.format,
            "vessel": vessel,
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


def _sources(args):
    """The run files of the inputs (files or folders searched recursively), each once, and the
    files skipped with the reason; ValueError for an input without any run file."""
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
    return sources, skipped


def _write_tracks(sources, tracks, out) -> list:
    """Write each track as ``out/<source stem>.csv`` (names made unique); returns the runs of
    ``convert.json``."""
    runs, used = [], set()
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
    return runs
