"""Benchmark: generated vs interpreted compiled kernels, batched vs one at a time, and the solve_ivp
references, for the 6-DOF submarine, the horizontal plane and the ship.

Workloads (B coefficient vectors per call, as an optimiser's finite-difference gradient or an
emcee step asks for):

* 6-DOF and horizontal plane: the paper's 600 s spiral (``manoeuvres.spiral``, dt 0.1 s, 6000 RK4
  steps), NPS AUV II, a batch of coefficient vectors perturbed uniformly by +-5 % around the truth
  in some horizontal-plane coefficients (added mass among them, so every track has its own mass
  matrix).
* Ship: Esso Osaka (3 m model), 600 s of a +-20 deg rudder sine at dt 0.2 s (3000 steps) with a
  measured-like wind and the wind effect on, one window, B parameter rows perturbed by +-5 %.

    python benchmarks/simulate.py [--batch 64] [--reference-tracks 2] [--single-tracks N]
                                  [--repeats 5] [--seed 0]

Each configuration's generated and interpreted kernels are timed alternately, ``--repeats`` times
each, and the best time of each is kept (the machine's other load only ever slows a run down).
Compile time is excluded (one warm-up call first). Times are ``time.perf_counter`` wall-clock.

The last lines are machine-readable: ``speedup_generated_vs_interpreted_<case>`` for 6dof,
horizontal and ship, ``speedup_vs_rk45`` (generated 6-DOF batch against ``solve_ivp`` RK45 at
rtol 1e-8, the fair reference), ``batch_vs_single``, ``tracks_per_s_compiled``,
``tracks_per_s_reference`` and ``speedup`` (= their ratio; the reference is DOP853 at rtol
1e-10, the accuracy anchor), and last ``speedup_generated_vs_interpreted`` (6-DOF).
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from bayesid.data.track import Track
from bayesid.data.vehicle import load_vehicle
from bayesid.models import manoeuvres as mv
from bayesid.models.reference import simulate_reference
from bayesid.models.ship import ShipModel, load_ship
from bayesid.models.simulate import Simulator

FREE = ["Xvv", "Yv", "Yr", "Ydr", "Yvdot", "Nv", "Nr", "Ndr", "Nrdot", "Yvabsv", "Nrabsr"]
KINDS = ("generated", "interpreted")


def _alternate(calls: dict, repeats: int) -> dict:
    """Best wall time (s) of each callable, timed alternately ``repeats`` times after a warm-up."""
    for f in calls.values():
        f()
    best = {k: np.inf for k in calls}
    for _ in range(repeats):
        for k, f in calls.items():
            tic = time.perf_counter()
            f()
            best[k] = min(best[k], time.perf_counter() - tic)
    return best


def _ship_workload(B: int, rng):
    """(run(kind) callables, description) of the ship workload."""
    ship = load_ship("esso_osaka_3m")
    dt, dur = 0.2, 600.0
    t = np.arange(0.0, dur + 1e-9, 1.0)
    u0 = 0.6
    data = {
        "x": u0 * t,
        "y": np.zeros_like(t),
        "psi": np.zeros_like(t),
        "u": np.full_like(t, u0),
        "v": np.zeros_like(t),
        "r": np.zeros_like(t),
        "delta_r": np.radians(20.0) * np.sin(2 * np.pi * t / 60.0),
        "n": np.full_like(t, 600.0),
        "wind_speed": 2.0 + 0.5 * np.sin(2 * np.pi * t / 97.0),
        "wind_dir": np.full_like(t, 40.0),
    }
    track = Track(t, data, name="ship-bench")
    models = {k: ShipModel(ship, None, ("wind",), dt=dt, kernel=k) for k in KINDS}
    ctx = models["generated"].context(track, None)
    P0 = models["generated"].start()
    P = P0 * (1.0 + rng.uniform(-0.05, 0.05, (B, P0.size)))
    out = {k: models[k].simulate(ctx, P) for k in KINDS}
    diff = float(np.nanmax(np.abs(out["generated"] - out["interpreted"])))
    calls = {k: (lambda k=k: models[k].simulate(ctx, P)) for k in KINDS}
    single = {k: (lambda k=k: [models[k].simulate(ctx, P[i : i + 1]) for i in range(B)]) for k in KINDS}
    desc = (
        f"ship {ship.id}: {dur:g} s rudder sine +-20 deg with wind, dt {dt:g} s "
        f"({ctx.n_steps} RK4 steps), {P0.size} parameters +-5 %"
    )
    return calls, single, diff, desc


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=64, help="coefficient vectors per batched call")
    ap.add_argument("--reference-tracks", type=int, default=2, help="tracks timed with solve_ivp")
    ap.add_argument(
        "--single-tracks", type=int, default=None, help="tracks timed one at a time (B = 1); default --batch"
    )
    ap.add_argument("--repeats", type=int, default=5, help="alternating timed repeats of each batched call")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    B = args.batch
    n_single = B if args.single_tracks is None else args.single_tracks

    vehicle = load_vehicle("nps_auv2")
    manoeuvre = mv.spiral(vehicle)  # 600 s, dt 0.1 s
    rng = np.random.default_rng(args.seed)
    truth = vehicle.coefficient_vector(FREE)
    theta = truth * (1.0 + rng.uniform(-0.05, 0.05, (B, len(FREE))))

    rows = []  # (case, path, tracks, seconds)
    ratios, batch_vs_single, diffs = {}, {}, {}
    results = {}
    for mode in ("6dof", "horizontal"):
        sims = {k: Simulator(vehicle, manoeuvre, free=FREE, mode=mode, kernel=k) for k in KINDS}
        best = _alternate({k: (lambda k=k: sims[k].run(theta)) for k in KINDS}, args.repeats)  # noqa: B023 - called in this iteration
        results[mode] = {k: sims[k].run(theta) for k in KINDS}
        single = _alternate(
            {
                k: (lambda k=k: [sims[k].run(theta[i % B][None]) for i in range(n_single)])  # noqa: B023
                for k in KINDS
            },
            1,
        )
        for k in KINDS:
            rows.append((mode, f"{k} batched (B={B})", B, best[k]))
            rows.append((mode, f"{k} one at a time", n_single, single[k]))
        ratios[mode] = best["interpreted"] / best["generated"]
        batch_vs_single[mode] = (B / best["generated"]) / (n_single / single["generated"])
        a, b = results[mode]["generated"].states, results[mode]["interpreted"].states
        diffs[mode] = float(np.nanmax(np.abs(a - b)))
    calls, single_calls, diffs["ship"], ship_desc = _ship_workload(B, rng)
    best = _alternate(calls, args.repeats)
    single = _alternate(single_calls, 1)
    for k in KINDS:
        rows.append(("ship", f"{k} batched (B={B})", B, best[k]))
        rows.append(("ship", f"{k} one at a time", B, single[k]))
    ratios["ship"] = best["interpreted"] / best["generated"]
    batch_vs_single["ship"] = single["generated"] / best["generated"]

    batch6 = results["6dof"]["generated"]
    t_batch = min(t for case, path, _, t in rows if case == "6dof" and path.startswith("generated batched"))
    ref_times, ref_diffs = [], []
    for i in range(args.reference_tracks):
        tic = time.perf_counter()
        ref = simulate_reference(vehicle, manoeuvre, mode="6dof", coefficients=dict(zip(FREE, theta[i])))
        ref_times.append(time.perf_counter() - tic)
        ref_diffs.append(float(np.max(np.linalg.norm(ref.states[0, :, :3] - batch6.states[i, :, :3], axis=1))))
    rk45_times, rk45_diffs = [], []
    for i in range(args.reference_tracks):
        tic = time.perf_counter()
        ref = simulate_reference(
            vehicle, manoeuvre, mode="6dof", coefficients=dict(zip(FREE, theta[i])), method="RK45", rtol=1e-8, atol=1e-8
        )
        rk45_times.append(time.perf_counter() - tic)
        rk45_diffs.append(float(np.max(np.linalg.norm(ref.states[0, :, :3] - batch6.states[i, :, :3], axis=1))))
    rows.append(("6dof", "reference solve_ivp DOP853 1e-10", args.reference_tracks, sum(ref_times)))
    rows.append(("6dof", "reference solve_ivp RK45 1e-8", args.reference_tracks, sum(rk45_times)))
    rate_batch = B / t_batch
    rate_ref = args.reference_tracks / sum(ref_times)
    rate_rk45 = args.reference_tracks / sum(rk45_times)

    print(
        f"# submarine: spiral {manoeuvre.duration:g} s, dt {manoeuvre.dt:g} s ({manoeuvre.n_steps} RK4 steps), "
        f"{vehicle.id}, {len(FREE)} free coefficients +-5 %"
    )
    print(f"# {ship_desc}")
    print(
        f"# numba threads {numba.get_num_threads()}, threading layer {numba.threading_layer()}; best of {args.repeats} alternating repeats "
        f"(one at a time: one pass)"
    )
    print(f"{'case':<12}{'path':<36}{'tracks':>8}{'seconds':>11}{'tracks/s':>12}{'ms/track':>10}")
    for case, path, n, t in rows:
        print(f"{case:<12}{path:<36}{n:>8d}{t:>11.4f}{n / t:>12.2f}{1e3 * t / n:>10.3f}")
    rhs_calls = B * manoeuvre.n_steps * 4
    print(
        f"6-DOF generated batched: {1e9 * t_batch / rhs_calls:.0f} ns per right-hand-side evaluation "
        f"(wall, all threads)"
    )
    print(
        "max |generated - interpreted| over all states (6dof, horizontal, ship): "
        + ", ".join(f"{diffs[k]:.3e}" for k in ("6dof", "horizontal", "ship"))
    )
    print(f"reference per track (s): {', '.join(f'{t:.2f}' for t in ref_times)}")
    print(
        f"max position difference compiled (RK4 dt {manoeuvre.dt:g} s) vs DOP853 rtol 1e-10, same "
        f"coefficients (m): {', '.join(f'{d:.3e}' for d in ref_diffs)}"
    )
    print(
        f"max position difference compiled vs solve_ivp RK45 rtol 1e-8 (m): {', '.join(f'{d:.3e}' for d in rk45_diffs)}"
    )
    for case in ("6dof", "horizontal", "ship"):
        print(f"batch_vs_single_{case} {batch_vs_single[case]:.4f}")
    for case in ("horizontal", "ship", "6dof"):
        print(f"speedup_generated_vs_interpreted_{case} {ratios[case]:.4f}")
    print(f"speedup_vs_rk45 {rate_batch / rate_rk45:.6g}")
    print(f"batch_vs_single {batch_vs_single['6dof']:.4f}")
    print(f"tracks_per_s_compiled {rate_batch:.6g}")
    print(f"tracks_per_s_reference {rate_ref:.6g}")
    print(f"speedup {rate_batch / rate_ref:.6g}")
    print(f"speedup_generated_vs_interpreted {ratios['6dof']:.4f}")


if __name__ == "__main__":
    main()
