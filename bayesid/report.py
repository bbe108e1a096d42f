"""Report layer shared by the study scripts: output folder, manifest, JSON and markdown tables.

The study contract (DESIGN.md): each run writes ``report.md``, ``figures/*.png``,
``results.json`` and ``manifest.json`` (command line, seed, git commit, package versions, wall
time, quick or full) into its folder.
"""
from __future__ import annotations

import json
import math
import platform
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np

PACKAGES = ("numpy", "scipy", "numba", "emcee", "h5py", "arviz", "pysindy", "matplotlib", "tqdm")


def prepare_out(out: str | Path) -> Path:
    """Create ``out`` and ``out/figures``; return ``out`` as a Path."""
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    return out


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        x = float(x)
        return x if math.isfinite(x) else ("inf" if x > 0 else "-inf" if x < 0 else "nan")
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_json(path: str | Path, obj) -> None:
    """Write ``obj`` as indented JSON; numpy types converted, non-finite floats as strings."""
    Path(path).write_text(json.dumps(_jsonable(obj), indent=2) + "\n")


def git_commit() -> str:
    """Current commit hash (``+dirty`` if code outside ``reports/`` has uncommitted changes), or
    ``"unknown"``."""
    root = Path(__file__).resolve().parent.parent
    try:
        h = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
                           timeout=10).stdout.strip()
        # the run's own outputs under reports/ do not make the code dirty
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".",
                                ":!reports"], cwd=root,
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return (h + ("+dirty" if dirty else "")) if h else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def write_manifest(out: Path, *, seed: int, quick: bool, t_start: float, extra: dict | None = None) -> None:
    """Write ``manifest.json``: command line, seed, git commit, versions, wall time, quick/full."""
    versions = {}
    for p in PACKAGES:
        try:
            versions[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            versions[p] = None
    man = dict(command=" ".join([Path(sys.executable).name] + sys.argv), seed=seed,
               quick=quick, mode="quick" if quick else "full", git_commit=git_commit(),
               python=platform.python_version(), platform=platform.platform(),
               packages=versions, wall_s=time.perf_counter() - t_start,
               finished_utc=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
    if extra:
        man.update(extra)
    write_json(out / "manifest.json", man)


def md_table(header, rows) -> str:
    """Markdown table from a header list and row lists (values formatted by the caller)."""
    lines = ["| " + " | ".join(str(h) for h in header) + " |",
             "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def fmt(x, digits: int = 3) -> str:
    """Compact number format for reports: ``1.23e-05``, ``0.123``, ``inf``."""
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    if x == 0:
        return "0"
    if 1e-3 <= abs(x) < 1e4:
        return f"{x:.{digits}g}"
    return f"{x:.{max(digits - 1, 1)}e}"
