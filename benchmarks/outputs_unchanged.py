"""Guard, not a timing: the CLI's and the quick studies' outputs of an old revision against the
working tree's, key by key, timings and provenance aside (issue 66: a restructuring lands with
its outputs unchanged).

What is run, in a process of its own per revision, each importing ``bayesid`` from its tree (the
old one a ``git worktree`` of ``--old``, default ``HEAD``), on the same input files:

* the CLI on synthetic KVLCC2 runs (written once, by the old revision: two zigzags and a turning
  circle of the packaged ship with its ``N'r`` 15 % larger, to train; a zigzag and a turning circle
  the other way held out; 0.05 m and 0.05 deg of seeded noise at 2 Hz): ``bayesid fit``,
  ``bayesid predict``, ``bayesid diagnose`` with discovery and the design;
* every study's ``--quick`` run (``real_ships`` and the studies that read ``--data`` only when
  ``../shared/data/real`` is there).

Every ``.json`` either revision writes is compared after dropping the keys that record when, how
long, where and by what the run was made (:data:`VOLATILE`), with the output folder's path replaced
by ``<OUT>``; so is every diagnosis's ``report.md``, line by line. The differences are listed by file and key path; the last lines are
machine-readable: ``identical <n files>``, ``different <n files>``, ``missing <n files>``.

    python benchmarks/outputs_unchanged.py [--old REV] [--only cli,furlong2003,...] [--keep DIR] [--old-only] [--compare-only]

A run takes 20-40 minutes per revision on 2 cores (the quick studies dominate); ``--only`` picks
the steps, ``--keep`` keeps both revisions' outputs (``DIR/old``, ``DIR/new``) and, when it already
holds ``old``, reuses it rather than running the old revision again.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "real"
#: Keys whose values say when, how long, where or by what a run was made: not outputs.
VOLATILE = re.compile(
    r"^(.*wall_s|seconds|.*_seconds_total|seconds_per_.*|sim_share|elapsed.*|.*_seconds|timings?|runtime.*|created|"
    r".*_utc|timestamp|date|started|finished|"
    r"version|package_version|git.*|commit|command|command_line|argv|cwd|host.*|platform|python|numpy|scipy|"
    r"numba|.*evals_per_s|.*_per_s|pid|user|machine|cpu.*|jobs)$"
)
STUDIES = (
    "furlong2003",
    "structure_discovery",
    "manoeuvre_richness",
    "base_fit_check",
    "kvlcc2_structures",
    "fit_sensitivity",
    "sim_to_real",
    "closing_the_loop",
    "posterior",
    "real_ships",
    "ship_surge",
    "esso_turns",
    "newcomer_auv",
)
#: Studies that need the real data (skipped without it).
NEEDS_DATA = {"real_ships", "kvlcc2_structures", "fit_sensitivity", "esso_turns"}


# ---------------------------------------------------------------- the synthetic runs (old tree)
DATA_SCRIPT = r"""
import sys, tomllib, numpy as np
from pathlib import Path
from bayesid.models import ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial
from bayesid.data.track import write_csv, Track

out = Path(sys.argv[1])
base = ship.load_ship("kvlcc2_7m")
truth = base.with_coefficients({"Nr": 1.15 * base.coefficients["Nr"]})
speed, rpm = propulsion_point(base, 1.179)
opts = TrialOptions(dt=0.1, sample_every=5, rudder_rate_deg_s=15.8)
rng = np.random.default_rng(66)
runs = [("zigzag", 10.0, "z10p"), ("zigzag", -20.0, "z20s"), ("turn", 35.0, "t35p"),
        ("zigzag", -10.0, "z10s_held"), ("turn", -35.0, "t35s_held")]
for kind, angle, name in runs:
    tr = simulate_trial(truth, kind, angle, speed=speed, rpm=rpm, options=opts).track
    data = {k: np.asarray(tr[k], float).copy() for k in ("x", "y", "psi", "u", "v", "r", "delta_r", "n")}
    data["x"] += rng.normal(0, 0.05, data["x"].size)
    data["y"] += rng.normal(0, 0.05, data["y"].size)
    data["psi"] += rng.normal(0, np.radians(0.05), data["psi"].size)
    write_csv(Track(np.asarray(tr.t, float), data, name=name, meta=tr.meta), out / f"{name}.csv")
"""


def _env(tree: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), MPLBACKEND="Agg")
    env.pop("BAYESID_CACHE", None)
    return env


def _bayesid(tree: Path, args: list, log) -> int:
    cmd = [sys.executable, "-c", "import sys; from bayesid.cli import main; sys.exit(main(sys.argv[1:]))", *args]
    r = subprocess.run(cmd, env=_env(tree), cwd=tree, capture_output=True, text=True)
    log.write(f"$ bayesid {' '.join(args)}\nexit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-4000:]}\n")
    return r.returncode


def _cli(tree: Path, runs: Path, out: Path, log) -> None:
    """The CLI examples on the synthetic runs."""
    train = [str(runs / f"{n}.csv") for n in ("z10p", "z20s", "t35p")]
    held = [str(runs / f"{n}.csv") for n in ("z10s_held", "t35s_held")]
    _bayesid(
        tree, ["fit", "--vehicle", "kvlcc2_7m", "--train", *train, "--max-nfev", "30", "--out", str(out / "fit")], log
    )
    _bayesid(
        tree,
        [
            "predict",
            "--model",
            str(out / "fit" / "model.json"),
            "--track",
            *held,
            "--score-window",
            "60",
            "--out",
            str(out / "pred"),
        ],
        log,
    )
    _bayesid(
        tree,
        [
            "diagnose", "--vehicle", "kvlcc2_7m", "--train", *train, "--heldout", *held,
            "--score-window", "60", "--candidates", "current,delay", "--max-nfev", "30", "--out", str(out / "diag"),
        ],
        log,
    )  # fmt: skip


def _study(tree: Path, name: str, out: Path, log) -> None:
    args = [sys.executable, str(tree / "studies" / f"{name}.py"), "--out", str(out / name)]
    args.append("--quick")
    if name in NEEDS_DATA:
        args += ["--data", str(DATA)]
    r = subprocess.run(args, env=_env(tree), cwd=tree, capture_output=True, text=True)
    log.write(f"$ {' '.join(args)}\nexit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-4000:]}\n")


def run_tree(tree: Path, runs: Path, out: Path, steps: list) -> None:
    """Every step of ``steps`` with ``tree``'s package, its outputs under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "log.txt", "a") as log:
        for step in steps:
            print(f"  {tree.name}: {step}", flush=True)
            if step == "cli":
                _cli(tree, runs, out, log)
            else:
                _study(tree, step, out, log)
            log.flush()


# ---------------------------------------------------------------- the comparison
#: The old revision's git worktree in a path (a vehicle file's, say).
_TREE = re.compile(r"/[^\s\"']*/bayesid-old-[^/]+/tree")


def _clean(x, out: str):
    if isinstance(x, dict):
        return {k: _clean(v, out) for k, v in x.items() if not VOLATILE.match(str(k))}
    if isinstance(x, list):
        return [_clean(v, out) for v in x]
    if isinstance(x, str):
        return _TREE.sub("<TREE>", x.replace(out, "<OUT>").replace(str(ROOT), "<TREE>"))
    return x


def _differences(a, b, path: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = [f"{path}/{k}: only old" for k in a.keys() - b.keys()]
        out += [f"{path}/{k}: only new" for k in b.keys() - a.keys()]
        for k in a.keys() & b.keys():
            out += _differences(a[k], b[k], f"{path}/{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} items old, {len(b)} new"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differences(x, y, f"{path}[{i}]")]
    same = a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))
    return [] if same else [f"{path}: {str(a)[:60]} -> {str(b)[:60]}"]


def _text_differences(a: Path, b: Path, old: Path, new: Path) -> list[str]:
    """The lines of two text reports that differ (output folders and trees replaced)."""
    A = _clean(a.read_text(), str(old)).splitlines()
    B = _clean(b.read_text(), str(new)).splitlines()
    if len(A) != len(B):
        return [f"{len(A)} lines old, {len(B)} new"] + [
            f"line {i + 1}: {x[:60]!r} -> {y[:60]!r}" for i, (x, y) in enumerate(zip(A, B)) if x != y
        ][:5]
    return [f"line {i + 1}: {x[:60]!r} -> {y[:60]!r}" for i, (x, y) in enumerate(zip(A, B)) if x != y]


def compare(old: Path, new: Path) -> tuple[int, int, int]:
    """Print each JSON file's differences, and each diagnosis report's (``report.md`` beside a
    ``diagnosis.json``) line by line; (identical, different, missing) file counts."""
    names = sorted(
        {p.relative_to(old) for p in old.rglob("*.json")} | {p.relative_to(new) for p in new.rglob("*.json")}
    )
    names += [n.parent / "report.md" for n in names if n.name == "diagnosis.json"]
    same = diff = missing = 0
    for rel in names:
        a, b = old / rel, new / rel
        if not (a.exists() and b.exists()):
            print(f"{rel}: only in {'old' if a.exists() else 'new'}")
            missing += 1
            continue
        if rel.suffix == ".md":
            d = _text_differences(a, b, old, new)
        else:
            try:
                A = _clean(json.loads(a.read_text()), str(old))
                B = _clean(json.loads(b.read_text()), str(new))
            except json.JSONDecodeError as e:
                print(f"{rel}: not JSON ({e})")
                diff += 1
                continue
            d = _differences(A, B)
        if d:
            diff += 1
            print(f"{rel}: {len(d)} differences")
            for line in d[:12]:
                print(f"    {line}")
        else:
            same += 1
    return same, diff, missing


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--old", default="HEAD", help="the revision compared against the working tree")
    ap.add_argument("--only", default=None, help="comma-separated steps: cli and study names (default: all)")
    ap.add_argument("--keep", default=None, help="keep both revisions' outputs here (reuse an existing old/)")
    ap.add_argument("--old-only", action="store_true", help="run the old revision only (into --keep), compare later")
    ap.add_argument("--compare-only", action="store_true", help="compare --keep's old/ and new/ without running")
    args = ap.parse_args(argv)
    steps = ["cli", *STUDIES] if args.only is None else args.only.split(",")
    if not DATA.is_dir():
        skipped = [s for s in steps if s in NEEDS_DATA]
        steps = [s for s in steps if s not in NEEDS_DATA]
        if skipped:
            print(f"no {DATA}: skipping {', '.join(skipped)}")
    keep = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bayesid-outputs-"))
    old_out, new_out = keep / "old", keep / "new"
    if args.compare_only:
        same, diff, missing = compare(old_out, new_out)
        print(f"\nidentical {same}\ndifferent {diff}\nmissing {missing}")
        return 0 if diff == 0 and missing == 0 else 1
    runs = keep / "runs"
    old_tree = Path(tempfile.mkdtemp(prefix="bayesid-old-")) / "tree"
    subprocess.run(
        ["git", "worktree", "add", "--detach", str(old_tree), args.old], cwd=ROOT, check=True, capture_output=True
    )
    try:
        if not runs.exists():
            runs.mkdir(parents=True)
            subprocess.run([sys.executable, "-c", DATA_SCRIPT, str(runs)], env=_env(old_tree), cwd=old_tree, check=True)
        if not old_out.exists():
            run_tree(old_tree, runs, old_out, steps)
        if args.old_only:
            return 0
        if new_out.exists():
            shutil.rmtree(new_out)
        run_tree(ROOT, runs, new_out, steps)
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(old_tree)], cwd=ROOT, capture_output=True)
    print(f"\nold: {args.old}, new: the working tree; outputs in {keep}")
    same, diff, missing = compare(old_out, new_out)
    print(f"\nidentical {same}\ndifferent {diff}\nmissing {missing}")
    return 0 if diff == 0 and missing == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
