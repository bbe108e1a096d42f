"""The study contract: an output folder with ``figures/``, JSON files, and ``manifest.json``.

Each study run writes ``report.md``, ``figures/*.png``, ``results.json`` and ``manifest.json``
(command line, seed, git commit, package versions, wall time, quick or full) into its folder
(DESIGN.md); the commands write their JSON documents with :func:`write_json` too.
"""

from __future__ import annotations

import json
import platform
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

from ..tasks import jsonable

#: The packages whose versions a manifest records.
PACKAGES = (
    "numpy",
    "scipy",
    "numba",
    "emcee",
    "h5py",
    "arviz",
    "pysindy",
    "matplotlib",
    "tqdm",
    "joblib",
    "dask",
    "distributed",
)


def prepare_out(out: str | Path) -> Path:
    """Create a study's output folder and its ``figures`` folder.

    Parameters
    ----------
    out : str or Path
        The output folder (created with its parents).

    Returns
    -------
    Path
        ``out`` as a Path.
    """
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    return out


def write_json(path: str | Path, obj) -> None:
    """Write an object as indented JSON, creating the folder.

    Parameters
    ----------
    path : str or Path
        The file written.
    obj : object
        Dicts, lists, numbers and strings; numpy arrays and scalars are converted and non-finite
        floats written as the strings ``"nan"``, ``"inf"``, ``"-inf"`` (:func:`bayesid.tasks.jsonable`).
    """
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(jsonable(obj), indent=2) + "\n")


def git_commit() -> str:
    """The repository's current commit.

    Returns
    -------
    str
        The commit hash, with ``+dirty`` when code outside ``reports/`` has uncommitted changes,
        or ``"unknown"`` outside a git checkout.
    """
    root = Path(__file__).resolve().parents[2]  # the repository (this file: bayesid/report/study.py)
    try:
        h = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10
        ).stdout.strip()
        # the run's own outputs under reports/ do not make the code dirty
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", ".", ":!reports"],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
        return (h + ("+dirty" if dirty else "")) if h else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def write_manifest(out: Path, *, seed: int, quick: bool, t_start: float, extra: dict | None = None) -> None:
    """Write a study's ``manifest.json``.

    Parameters
    ----------
    out : Path
        The study's output folder.
    seed : int
        The run's random seed.
    quick : bool
        True for a ``--quick`` run.
    t_start : float
        :func:`time.perf_counter` at the start of the run (the manifest records the wall time).
    extra : dict, optional
        More entries of the manifest.

    Notes
    -----
    The manifest holds the command line, seed, git commit, Python, platform and package
    versions, wall time, the time it finished (UTC) and quick or full.
    """
    versions = {}
    for p in PACKAGES:
        try:
            versions[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            versions[p] = None
    man = dict(
        command=" ".join([Path(sys.executable).name] + sys.argv),
        seed=seed,
        quick=quick,
        mode="quick" if quick else "full",
        git_commit=git_commit(),
        python=platform.python_version(),
        platform=platform.platform(),
        packages=versions,
        wall_s=time.perf_counter() - t_start,
        finished_utc=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    )
    if extra:
        man.update(extra)
    write_json(out / "manifest.json", man)
