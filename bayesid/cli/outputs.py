"""The ``--out`` of each subcommand: what it writes there, and the check of the folder (or file)
before any computation, with ``--overwrite`` and the resumption of a killed run."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

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


def check_out(path, command: str, overwrite: bool, resumable: bool = False) -> Path:
    """Check a command's ``--out`` before any computation.

    Parameters
    ----------
    path : str or Path
        The ``--out`` value: a folder that can be created and written, or for ``simulate`` a file.
    command : str
        The subcommand (a key of :data:`WRITES`, or ``"simulate"``).
    overwrite : bool
        ``--overwrite``: an existing non-empty folder is accepted, and what ``command`` writes
        there (and, for ``convert``, the CSVs its ``convert.json`` lists) is removed first, so
        nothing stale survives. Even so, a folder holding another command's output
        (:data:`MAIN_OUTPUT`), or files named like this command's output without its main file
        (the user's), is refused.
    resumable : bool
        A folder holding only this command's ``journal.jsonl`` and outputs but no main file (a
        killed run) is kept as it is, so the same command resumes it.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        Naming the option and the path.
    """
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
            _clear_own_output(out, command)
        parent = out
    probe = parent
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise ValueError(f"--out {out}: {probe} is a file, not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ValueError(f"--out {out}: cannot write into {probe} (permission denied)")
    return out


def _clear_own_output(out: Path, command: str) -> None:
    """--overwrite: remove this command's earlier output from ``out``, never another command's or
    the user's (ValueError)."""
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


def check_write_vehicle(path: str, overwrite: bool) -> None:
    """Check ``--write-vehicle`` before any computation: an existing file is not replaced without
    ``--overwrite``.

    Parameters
    ----------
    path : str
        The option's value ("" when not given).
    overwrite : bool
        ``--overwrite``.

    Raises
    ------
    ValueError
        Naming the option and the file when it exists and ``overwrite`` is False, or when it is a
        folder.
    """
    if not path:
        return
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"--write-vehicle {path}: is a folder; give a .toml file path")
    if p.exists() and not overwrite:
        raise ValueError(f"--write-vehicle {path}: the file exists (give another path, or --overwrite to replace it)")
