"""The inputs of a subcommand: its track files, read and checked once, errors that name the
file of the track they are about, and the free coefficients.

The library names a track by its name (``track 'run3'``, the file's stem); the command line
knows the file. :func:`read_tracks` names the file of any error raised while it reads one, and
:func:`naming_files` around the library calls that take the tracks re-raises their errors with
the file beside the track's name: ``track 'run3' (runs/run3.csv)``.
"""

from __future__ import annotations

import sys
from contextlib import contextmanager
from pathlib import Path

from ..report.markdown import grouped_warnings
from .options import split_names
from .provenance import file_sha256


class InputError(ValueError):
    """An error about a subcommand's input whose message names the file."""


def same_values(a, b, rtol: float = 1e-5) -> bool:
    """Whether two tracks hold the same samples up to the precision of an export.

    Parameters
    ----------
    a, b : Track
        The tracks.
    rtol : float
        Tolerance, relative to each column's largest magnitude.

    Returns
    -------
    bool
        True for the same number of rows, and ``t``, ``x``, ``y``, ``psi`` (those both have)
        equal within ``rtol`` (a 6-significant-digit copy of a full-precision file is the same
        log; two logs of one manoeuvre differ by their noise).
    """
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


@contextmanager
def _about_file(option: str, path: Path):
    """Errors raised inside that do not name ``path`` are re-raised naming option and file."""
    try:
        yield
    except (ValueError, KeyError) as exc:
        if str(path) in str(exc):
            raise
        raise InputError(f"{option} {path}: {exc}") from exc


def read_tracks(groups, vehicle=None) -> dict:
    """Read and check the track files of a subcommand's options, each once.

    Parameters
    ----------
    groups : list of (str, list)
        ``[(option, [paths])]``, e.g. ``[("--train", args.train)]``.
    vehicle : Vehicle or Ship, optional
        The vehicle the tracks are for (plausibility checks).

    Returns
    -------
    dict
        {option: [Track]}; the files' SHA-256 under ``"_sha256"`` ({file: hash}), the warnings
        under ``"_warnings"`` and each track's file under ``"_files"`` ({track name: file}).

    Raises
    ------
    ValueError
        A file given twice, a file whose content equals another one (a renamed copy) or whose
        samples do (:func:`same_values`: another export of one log), a folder, two tracks with
        the same name (naming both), or a track that fails
        :func:`bayesid.data.validate.check_track` (units; plausibility for ``vehicle``), naming
        the file. Warnings of the check are printed.
    FileNotFoundError
        A file that does not exist.
    """
    from ..data.track import read_csv
    from ..data.validate import check_track

    seen, names, out, hashes, warnings, read = {}, {}, {}, {}, [], []
    for option, paths in groups:
        out[option] = []
        for p in paths:
            p = Path(p)
            if p.is_dir():
                raise ValueError(f"{option} {p}: is a folder, not a track CSV")
            if not p.is_file():
                raise FileNotFoundError(f"{option} {p}: no such file")
            h = file_sha256(p)
            if h in seen:
                o, q = seen[h]
                raise ValueError(
                    f"{option} {p} has the same content as {o} {q}: a track may be given once"
                    + (" (training and held-out tracks must differ)" if o != option else "")
                )
            seen[h] = (option, p)
            with _about_file(option, p):
                tr = read_csv(p)
            if tr.name in names:
                raise ValueError(
                    f"{option} {p} and {names[tr.name]} are both named {tr.name!r}; rename one "
                    "(results are reported by track name)"
                )
            names[tr.name] = p
            hashes[str(p)] = h
            with _about_file(option, p):
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
    for w in grouped_warnings(warnings):
        print(f"warning: {w}", file=sys.stderr)
    out["_sha256"], out["_warnings"] = hashes, warnings
    out["_files"] = {name: str(p) for name, p in names.items()}
    return out


@contextmanager
def naming_files(got: dict):
    """Name the file of the track an error raised inside is about.

    Parameters
    ----------
    got : dict
        The tracks of :func:`read_tracks` (their files under ``"_files"``).

    Raises
    ------
    InputError
        A ValueError, KeyError or FileNotFoundError raised inside whose message names a track
        (``track 'run3'``), with the track's file beside its name (``track 'run3'
        (runs/run3.csv)``); other errors pass unchanged.
    """
    try:
        yield
    except (ValueError, KeyError, FileNotFoundError) as exc:
        message = named = str(exc)
        for name, path in got["_files"].items():
            named = named.replace(f"track {name!r}", f"track {name!r} ({path})")
        if named == message:
            raise
        raise InputError(named) from exc


def free_list(vehicle, text) -> list:
    """The free coefficients of a command.

    Parameters
    ----------
    vehicle : Vehicle or Ship
        The vehicle.
    text : str
        ``--free``; empty for the vehicle's default (ships: the file's ``[fit] free``;
        submarines: the horizontal-plane six).

    Returns
    -------
    list of str
        The names.

    Raises
    ------
    ValueError
        An unknown name, or one given twice.
    """
    from ..models import model_class

    family = model_class(vehicle)
    free = split_names(text, "--free") or family.default_free(vehicle)
    family.check_free(vehicle, free, "--free")
    return free
