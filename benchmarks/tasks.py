"""Benchmark of the task layer (:mod:`bayesid.tasks`): tasks per second on 1 and 2 local workers,
the per-task overhead of each path (serial, loky, Dask LocalCluster), and a gap diagnosis with its
candidates fitted by 2 workers against 1 (same diagnosis apart from timings).

Workloads:

* *simulation task*: one multiple-shooting objective evaluation's worth of work -- NPS AUV II,
  horizontal plane, a 300 s zigzag, 16 coefficient vectors in one batched call, repeated
  ``--sim-repeats`` times (about 1 s a task on this machine);
* *empty task*: returns at once; its wall time per task is the path's overhead;
* *diagnosis*: NPS AUV II with a current the base model lacks; 3 training and 4 held-out tracks of
  200 s at 5 Hz (0.2 m / 0.2 deg noise, no velocity log: the fitted window-start rule), free
  Yv, Yr, Nv, Nr, Ydr, Ndr, the whole catalogue, ``max_nfev`` 30, 60 s windows.

    python benchmarks/tasks.py [--tasks 16] [--sim-repeats 20] [--no-dask] [--no-diagnose]

Worker start-up (importing the package, loading the cached kernels) is part of every parallel
timing: that is what a user waits for. The last lines are machine-readable ``key value`` pairs:
``tasks_per_s_<path>``, ``overhead_ms_per_task_<path>``, ``speedup_2_workers``,
``diagnose_speedup_jobs2`` and ``diagnose_same``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np

from bayesid.tasks import Runner, Task, run_tasks

FREE = ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"]


def sim_task(sim, thetas, repeats: int) -> float:
    """Run the batched simulation ``repeats`` times; return a checksum (so nothing is skipped)."""
    s = 0.0
    for _ in range(repeats):
        s += float(np.nansum(sim.run(thetas).states[:, -1, :2]))
    return s


def empty_task(i: int) -> int:
    return i


def _time(fn, tasks, **kw) -> tuple[float, list]:
    tic = time.perf_counter()
    out = run_tasks(fn, tasks, Runner(**kw))
    return time.perf_counter() - tic, out


def _diagnosis_data(seed: int = 11):
    from bayesid.data.track import Track
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models.world import LogOptions, world_track

    veh = load_vehicle("nps_auv2")
    rng = np.random.default_rng(seed)
    noise = {"x": 0.2, "y": 0.2, "psi": math.radians(0.2)}
    kinds = [
        lambda: mv.zigzag(veh, 20.0, dt=0.1, duration=200.0),
        lambda: mv.prbs(veh, 15.0, duration=200.0, rng=np.random.default_rng(seed)),
        lambda: mv.zigzag(veh, 10.0, dt=0.1, duration=200.0, first_sign=-1),
        lambda: mv.turning_circle(veh, 15.0, dt=0.1, duration=200.0),
        lambda: mv.multisine(veh, 15.0, duration=200.0),
    ]
    tracks = []
    for i in range(7):
        m = kinds[i % len(kinds)]()
        tr = world_track(
            veh,
            m,
            {"current": {"current_north_mps": 0.15, "current_east_mps": -0.1}},
            rng,
            LogOptions(noise=noise, sample_every=2, hold_inputs=True),
        )
        keep = {k: v for k, v in tr.data.items() if k in ("x", "y", "psi", "delta_r", "delta_s", "delta_b", "n")}
        tracks.append(Track(tr.t + 1000.0 * i, keep, name=f"run{i}_{m.name}", meta=tr.meta))
    return veh, tracks[:3], tracks[3:]


def _without_timings(d: dict) -> str:
    from bayesid.tasks import jsonable

    d = jsonable(d)
    d.pop("seconds", None)
    for rows in [d.get("ranking", [])] + d.get("rounds", []):
        for r in rows:
            r.pop("fit_seconds", None)
    return json.dumps(d, sort_keys=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", type=int, default=16)
    ap.add_argument("--sim-repeats", type=int, default=400)
    ap.add_argument("--no-dask", action="store_true")
    ap.add_argument("--no-diagnose", action="store_true")
    args = ap.parse_args()

    import numba

    from bayesid._numba import use_package_threading_layer
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models.simulate import Simulator

    use_package_threading_layer()  # the layer the package's kernels select, printed before any runs
    print(f"cores {os.cpu_count()}, numba threading layer {numba.config.THREADING_LAYER}")
    veh = load_vehicle("nps_auv2")
    sim = Simulator(veh, mv.zigzag(veh, 20.0, dt=0.5, duration=300.0), free=FREE, mode="horizontal")
    theta0 = np.array([veh.coefficients[n] for n in FREE])
    rng = np.random.default_rng(0)
    thetas = theta0 * (1 + 0.05 * rng.uniform(-1, 1, (16, theta0.size)))
    sim.run(thetas)  # compile / load the cached kernel once here
    tasks = [Task(f"s{i}", {"i": i}, (sim, thetas, args.sim_repeats)) for i in range(args.tasks)]
    empties = [Task(f"e{i}", {"i": i}, (i,)) for i in range(200)]
    paths = {"serial": dict(jobs=1), "loky_2": dict(jobs=2)}
    try:
        import distributed  # noqa: F401

        if not args.no_dask:
            paths["dask_local_2"] = dict(scheduler="local:2")
    except ImportError:
        print("dask[distributed] not installed: the Dask path is skipped (pip install -e '.[dask]')")
    rates, overhead, ref = {}, {}, None
    for name, kw in paths.items():
        wall, out = _time(sim_task, tasks, **kw)
        if ref is None:
            ref = out
        same = all(a == b for a, b in zip(out, ref))
        rates[name] = args.tasks / wall
        e_wall, _ = _time(empty_task, empties, **kw)
        overhead[name] = 1e3 * e_wall / len(empties)
        print(
            f"{name:14s} {args.tasks} simulation tasks in {wall:6.2f} s = {rates[name]:6.2f} tasks/s "
            f"(results {'equal' if same else 'DIFFER'}); 200 empty tasks {e_wall:5.2f} s = "
            f"{overhead[name]:.2f} ms/task (worker start-up included)"
        )
    lines = {f"tasks_per_s_{k}": v for k, v in rates.items()}
    lines.update({f"overhead_ms_per_task_{k}": v for k, v in overhead.items()})
    lines["speedup_2_workers"] = rates["loky_2"] / rates["serial"]

    if not args.no_diagnose:
        from bayesid.analysis.gap import diagnose

        veh, train, held = _diagnosis_data()
        walls, docs = {}, {}
        for jobs in (1, 2):
            tic = time.perf_counter()
            d = diagnose(veh, FREE, train, held, window_s=60.0, max_nfev=30, rng=np.random.default_rng(0), jobs=jobs)
            walls[jobs] = time.perf_counter() - tic
            docs[jobs] = _without_timings(d.to_dict())
            print(
                f"diagnose --jobs {jobs}: {walls[jobs]:6.1f} s, verdict {d.verdict}, "
                f"ranking {[r['effect'] for r in d.ranking]}"
            )
        lines["diagnose_seconds_jobs1"] = walls[1]
        lines["diagnose_seconds_jobs2"] = walls[2]
        lines["diagnose_speedup_jobs2"] = walls[1] / walls[2]
        lines["diagnose_same"] = int(docs[1] == docs[2])
    lines.update(cluster_estimate(rates, overhead))
    for k, v in lines.items():
        print(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}")


def cluster_estimate(rates: dict, overhead: dict, n_cases: int = 1000, cores: int = 8) -> dict:
    """Wall time of a ``n_cases``-case withheld-effect benchmark on N machines of ``cores`` cores,
    from the measured per-case worker seconds of the committed full run
    (``reports/sim_to_real/journal.jsonl``: one thread per case): total work / (N cores) plus
    the longest case as the tail, plus the Dask overhead per task. Printed, and returned as
    ``estimate_hours_<N>_machines``."""
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "reports" / "sim_to_real" / "journal.jsonl"
    if not path.is_file():
        print(f"no {path}: no cluster estimate")
        return {}
    secs = np.array([json.loads(line)["seconds"] for line in path.read_text().splitlines()[1:]])
    over = overhead.get("dask_local_2", overhead.get("loky_2", 0.0)) / 1e3
    print(
        f"{path.name}: {secs.size} cases, worker time mean {secs.mean():.0f} s, median {np.median(secs):.0f} s, "
        f"longest {secs.max():.0f} s"
    )
    out = {}
    for n in (1, 10, 50):
        h = (n_cases * (secs.mean() + over) / (n * cores) + secs.max()) / 3600
        out[f"estimate_hours_{n}_machines"] = h
        print(
            f"estimate: {n_cases} cases on {n} machine(s) x {cores} cores: {h:.1f} h "
            f"(work {n_cases * secs.mean() / 3600:.0f} core-hours / {n * cores} cores + longest case)"
        )
    return out


if __name__ == "__main__":
    main()
