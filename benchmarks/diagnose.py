"""Benchmark: three reference diagnoses, timed stage by stage, an old revision against the working
tree in one run (issue 68).

The cases:

* ``nps`` -- NPS AUV II with a hidden third-order term (``Nvvr``): three training and four held-out
  runs (zigzags, a PRBS, a speed-step run) logged at 5 Hz without a velocity log (x, y, psi and the
  inputs), 0.2 m and 0.2 deg noise; the submarine catalogue and discovery;
* ``kvlcc2`` -- the KVLCC2 HSVA validation split of ``studies/real_ships.py`` (9 zigzags train,
  4 held out), the ship catalogue less wind, discovery, measured window starts;
* ``esso`` -- Esso Osaka's free-running runs, the same validation split as the study (its
  ``ESSO_HOLD`` runs held out), the whole ship catalogue, discovery.

The real-data cases need ``../shared/data/real`` (``--data``) and are skipped without it. Each case
runs once per revision, each in a process of its own that imports ``bayesid`` from that revision
(the old one from a ``git worktree`` of ``--old``, default 5b2d9ad) with an empty kernel cache
(``BAYESID_CACHE``): the numba compiles of the generated kernels are part of what a user waits
for the first time a vessel is diagnosed. The package's own compiled functions are warmed first,
in another cache, by a short simulation of each vessel family. ``--warm`` times a second run on the
now warm kernel cache as well.

The stages are read from the diagnosis' progress messages (:meth:`bayesid.tasks.Runner.say`): the
time from one message to the next is charged to the stage the first one names -- the base fit
(``base fit``), the effects' rounds (``round k: ...``), discovery's linearisation and selection
(``discovery: N candidate terms`` until its refits), discovery's refits (``discovery: refitting``
and the alternatives'), the design (``design: ...``, with the standard predictions), and the
report (``write_diagnosis``), timed around its call. Each run also records its verdict, the kept
terms and their alternatives; the script says whether they are the same in both revisions. The
options are those of ``bayesid diagnose``'s defaults: discovery with two alternatives per degree of
freedom, and the design when a kept term has alternatives.

    python benchmarks/diagnose.py [--cases nps,kvlcc2,esso] [--old REV] [--jobs 2] [--warm]

The last lines are machine-readable: ``total_s_<case>_<old|new>``, ``ratio_<case>`` (old time /
new time: above 1 the new code is faster), ``stage_ratio_<case>_<stage>`` and
``same_answers_<case>``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the ship candidates (besides the wind) the committed outputs were measured with, before the catalogue
#: grew the surge and propeller effects: old and new revisions compare on the same work
BENCHMARK_CANDIDATES = ("current", "delay", "sensor_lag")
STAGES = ("setup", "base fit", "effects", "discovery: selection", "discovery: refits", "design", "other", "report")


# ---------------------------------------------------------------- the cases (run in a worker)
def _nps_case():
    """NPS AUV II with a hidden Nvvr, 3 + 4 runs at 5 Hz without a velocity log."""
    import numpy as np

    from bayesid.analysis.gap import DiagnoseOptions

    try:
        from bayesid.analysis.gap.design import DiscriminationOptions
    except ImportError:  # an old revision (benchmarks run them): the name before issue 66
        from bayesid.analysis.gap.design import DesignOptions as DiscriminationOptions
    from bayesid.analysis.gap.discovery import DiscoveryOptions
    from bayesid.data.track import Track
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models.world import LogOptions, world_track

    veh = load_vehicle("nps_auv2")
    world = veh.with_coefficients({"Nvvr": -0.05})
    rng = np.random.default_rng(68)
    runs = {
        "train": [
            mv.zigzag(veh, 20.0, duration=120.0),
            mv.prbs(veh, 15.0, duration=120.0, rng=np.random.default_rng(1)),
            mv.speed_steps(veh, (1200.0, 800.0, 1400.0), hold_s=40.0, rudder_deg=8.0),
        ],
        "held": [
            mv.zigzag(veh, 10.0, duration=120.0, first_sign=-1),
            mv.zigzag(veh, 15.0, duration=120.0),
            mv.prbs(veh, 12.0, duration=120.0, rng=np.random.default_rng(2)),
            mv.speed_steps(veh, (900.0, 1300.0), hold_s=60.0, rudder_deg=-10.0),
        ],
    }
    log = LogOptions(noise={"x": 0.05, "y": 0.05, "psi": math.radians(0.1)}, sample_every=2, hold_inputs=True)
    keep = ("x", "y", "psi", "delta_r", "delta_s", "delta_b", "n")
    train, held = (
        [
            Track(tr.t, {c: tr[c] for c in keep}, name=f"{k}_{i}")
            for i, tr in enumerate(world_track(world, m, {}, rng, log) for m in v)
        ]
        for k, v in runs.items()
    )
    options = DiagnoseOptions(
        window_s=60.0, discover=DiscoveryOptions(n_alternatives=2), design=DiscriminationOptions()
    )
    return veh, ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"], train, held, options


def _real_ship(which: str, data: Path):
    """The validation split of studies/real_ships.py for ``which`` ("kvlcc2" or "esso")."""
    import importlib.util

    from bayesid.analysis.gap import DiagnoseOptions

    try:
        from bayesid.analysis.gap.design import DiscriminationOptions
    except ImportError:  # an old revision (benchmarks run them): the name before issue 66
        from bayesid.analysis.gap.design import DesignOptions as DiscriminationOptions
    from bayesid.analysis.gap.discovery import DiscoveryOptions
    from bayesid.data import datasets
    from bayesid.models import ship

    spec = importlib.util.spec_from_file_location("real_ships", ROOT / "studies" / "real_ships.py")
    study = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(study)
    if which == "kvlcc2":
        tracks = [
            datasets.read_run(p, "simman-hsva") for p in datasets.list_runs(data / "kvlcc2-simman-hsva", "simman-hsva")
        ]
        held = [t for t in tracks if any(t.name.endswith(h) for h in study.KVLCC2_HOLD)]
        vessel, cands = ship.load_ship("kvlcc2_7m"), list(BENCHMARK_CANDIDATES)
    else:
        paths = [p for p in datasets.list_runs(data / "esso-osaka-frt", "esso-osaka") if "turn_cut" not in p.name]
        tracks = [datasets.read_run(p, "esso-osaka") for p in paths]
        held = [t for t in tracks if t.name in study.ESSO_HOLD]
        vessel, cands = ship.load_ship("esso_osaka_3m"), ["wind", *BENCHMARK_CANDIDATES]
    train = [t for t in tracks if t not in held]
    options = DiagnoseOptions(
        candidates=cands,
        window_s=60.0,
        fit_window_s=ship.FIT_WINDOW_S,
        dt=0.2,
        start="measured",
        discover=DiscoveryOptions(n_alternatives=2),
        design=DiscriminationOptions(),
    )
    return vessel, vessel.free, train, held, options


def _stage(message: str) -> str:
    if message.startswith("base fit"):
        return "base fit"
    if message.startswith("round "):
        return "effects"
    if message.startswith("discovery: refitting") or message.startswith("discovery: and"):
        return "discovery: refits"
    if message.startswith(("discovery:", "structure discovery")):
        return "discovery: selection"
    if message.startswith("design"):
        return "design"
    return "other"


def _warm_up():
    """Compile the package's own numba functions (not the generated kernels a case needs)."""
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models import ship
    from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial
    from bayesid.models.simulate import Simulator

    veh = load_vehicle("nps_auv2")
    Simulator(veh, mv.zigzag(veh, 20.0, duration=20.0), ["Yv"], mode="horizontal", kernel="interpreted").run()
    kv = ship.load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(kv, 1.179)
    simulate_trial(kv, "zigzag", 10.0, check_deg=10.0, speed=speed, rpm=rpm, options=TrialOptions(duration=30.0))


def worker(case: str, data: Path, jobs: int, out: Path, warm_up: bool) -> None:
    """Run one case in this process (bayesid imported from sys.path[0]) and write its timings."""
    if warm_up:
        _warm_up()
        return
    import numpy as np

    from bayesid.analysis.gap import diagnose
    from bayesid.report import write_diagnosis
    from bayesid.tasks import Runner

    tic = time.perf_counter()
    vessel, free, train, held, options = _nps_case() if case == "nps" else _real_ship(case, data)
    marks = [("setup", tic), ("other", time.perf_counter())]
    runner = Runner(jobs=jobs, progress=lambda m: marks.append((_stage(m), time.perf_counter())))
    d = diagnose(vessel, free, train, held, options, rng=np.random.default_rng(0), runner=runner)
    t_report = time.perf_counter()
    write_diagnosis(d, Path(tempfile.mkdtemp()) / "report", held)
    end = time.perf_counter()
    marks.append(("report", t_report))
    seconds = dict.fromkeys(STAGES, 0.0)
    for (stage, t0), (_, t1) in zip(marks, marks[1:] + [("end", end)], strict=True):
        seconds[stage] += t1 - t0
    res = d.to_dict()
    disc = res.get("discovery") or {}
    answers = {
        "verdict": res["verdict"],
        "effects_added": res["effects_added"],
        "found": disc.get("found", []),
        "alternatives": disc.get("alternatives", {}),
    }
    import bayesid

    doc = {"seconds": seconds, "total": end - tic, "answers": answers, "package": str(Path(bayesid.__file__).parent)}
    out.write_text(json.dumps(doc, default=str))


# ---------------------------------------------------------------- the driver
def _run(root: Path, case: str, args, cache: str, warm_up: bool = False) -> dict | None:
    out = Path(tempfile.mkdtemp()) / "result.json"
    env = dict(os.environ, BAYESID_CACHE=cache, PYTHONPATH=str(root))
    cmd = [sys.executable, __file__, "--worker", case, "--root", str(root), "--data", str(args.data)]
    cmd += ["--jobs", str(args.jobs), "--result", str(out)] + (["--warm-up"] if warm_up else [])
    r = subprocess.run(cmd, env=env, cwd=root, capture_output=True, text=True)
    if r.returncode != 0:
        print(f"{case} ({root}): failed\n{r.stderr[-3000:]}")
        return None
    return None if warm_up else json.loads(out.read_text())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="nps,kvlcc2,esso")
    ap.add_argument("--old", default="5b2d9ad")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--warm", action="store_true", help="also time a second run on the warm kernel cache")
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "real")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--root", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--result", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--warm-up", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        sys.path.insert(0, str(args.root))
        worker(args.worker, args.data, args.jobs, args.result, args.warm_up)
        return 0
    cases = [c for c in args.cases.split(",") if c]
    if not args.data.is_dir():
        print(f"no real data under {args.data}: the real-ship cases are skipped")
        cases = [c for c in cases if c == "nps"]
    old_tree = Path(tempfile.mkdtemp(prefix="bayesid-old-")) / "tree"
    subprocess.run(
        ["git", "worktree", "add", "--detach", str(old_tree), args.old], cwd=ROOT, check=True, capture_output=True
    )
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    print(
        f"old: {args.old} (git worktree), new: working tree at {head}; --jobs {args.jobs}; empty kernel cache per run"
    )
    lines = []
    try:
        trees = {"old": old_tree, "new": ROOT}
        for tree in trees.values():
            _run(tree, "warm-up", args, tempfile.mkdtemp(prefix="bayesid-warmup-"), warm_up=True)
        for case in cases:
            res = {}
            for label, tree in trees.items():
                cache = tempfile.mkdtemp(prefix=f"bayesid-{label}-")
                res[label] = _run(tree, case, args, cache)
                if args.warm and res[label] is not None:
                    res[label + " warm"] = _run(tree, case, args, cache)
            if res["old"] is None or res["new"] is None:
                continue
            print(
                f"\n{case}: stage seconds (old / new / old:new); packages {res['old']['package']}, {res['new']['package']}"
            )
            for stage in STAGES:
                o, n = res["old"]["seconds"][stage], res["new"]["seconds"][stage]
                if o + n > 0.05:
                    print(f"  {stage:<22} {o:8.1f} {n:8.1f}   {o / n if n > 0 else math.inf:5.2f}")
                    lines.append(
                        f"stage_ratio_{case}_{stage.replace(' ', '_').replace(':', '')} {o / max(n, 1e-9):.3f}"
                    )
            o, n = res["old"]["total"], res["new"]["total"]
            print(f"  {'total':<22} {o:8.1f} {n:8.1f}   {o / n:5.2f}")
            for label in ("old warm", "new warm"):
                if res.get(label):
                    print(f"  total, warm kernel cache ({label.split()[0]}): {res[label]['total']:.1f} s")
                    lines.append(f"total_s_{case}_{label.replace(' ', '_')} {res[label]['total']:.1f}")
            same = res["old"]["answers"] == res["new"]["answers"]
            print(
                f"  answers: {json.dumps(res['new']['answers'])}"
                + ("" if same else f"\n  old: {json.dumps(res['old']['answers'])}")
            )
            lines += [f"total_s_{case}_old {o:.1f}", f"total_s_{case}_new {n:.1f}", f"ratio_{case} {o / n:.3f}"]
            lines.append(f"same_answers_{case} {same}")
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(old_tree)], cwd=ROOT, capture_output=True)
    print()
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
