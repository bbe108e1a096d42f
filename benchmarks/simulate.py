"""Benchmark: compiled batched simulator vs compiled one-at-a-time vs the solve_ivp reference.

The workload is the paper's 600 s spiral (``manoeuvres.spiral``, dt 0.1 s, 6000 RK4 steps), 6-DOF,
NPS AUV II, with a batch of coefficient vectors perturbed uniformly by +-5 % around the truth in
some horizontal-plane coefficients (added mass among them, so every track has its own mass
matrix), as an optimiser's finite-difference gradient or an emcee step would ask for.

    python benchmarks/simulate.py [--batch 64] [--reference-tracks 2] [--single-tracks N]
                                  [--repeats 3] [--seed 0]

The last lines are machine-readable: ``speedup_vs_rk45`` (against ``solve_ivp`` RK45 at rtol
1e-8, the fair reference), ``batch_vs_single``, ``tracks_per_s_compiled``,
``tracks_per_s_reference`` and ``speedup`` (= their ratio; the reference is DOP853 at rtol 1e-10,
the accuracy anchor).
Compile time is excluded (one warm-up call first). Times are ``time.perf_counter`` wall-clock;
the compiled batch is the best of ``--repeats`` runs.
"""
from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from bayesid.models import manoeuvres as mv
from bayesid.models.reference import simulate_reference
from bayesid.models.simulate import Simulator
from bayesid.data.vehicle import load_vehicle

FREE = ["Xvv", "Yv", "Yr", "Ydr", "Yvdot", "Nv", "Nr", "Ndr", "Nrdot", "Yvabsv", "Nrabsr"]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=64, help="coefficient vectors per batched call")
    ap.add_argument("--reference-tracks", type=int, default=2, help="tracks timed with solve_ivp")
    ap.add_argument("--single-tracks", type=int, default=None,
                    help="tracks timed one at a time (B = 1) with the compiled path; default --batch")
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats of the batched call")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    n_single = args.batch if args.single_tracks is None else args.single_tracks

    vehicle = load_vehicle("nps_auv2")
    manoeuvre = mv.spiral(vehicle)  # 600 s, dt 0.1 s
    rng = np.random.default_rng(args.seed)
    truth = vehicle.coefficient_vector(FREE)
    theta = truth * (1.0 + rng.uniform(-0.05, 0.05, (args.batch, len(FREE))))
    sim = Simulator(vehicle, manoeuvre, free=FREE, mode="6dof")

    sim.run(theta)  # warm-up: compile (or load the numba cache) and touch the memory

    batch_times = []
    for _ in range(args.repeats):
        tic = time.perf_counter()
        batch = sim.run(theta)
        batch_times.append(time.perf_counter() - tic)
    t_batch = min(batch_times)
    n_bad = int(batch.diverged.sum())

    tic = time.perf_counter()
    for i in range(n_single):
        sim.run(theta[i % args.batch][None])
    t_single = time.perf_counter() - tic

    ref_times, ref_diffs = [], []
    for i in range(args.reference_tracks):
        coeffs = dict(zip(FREE, theta[i]))
        tic = time.perf_counter()
        ref = simulate_reference(vehicle, manoeuvre, mode="6dof", coefficients=coeffs)
        ref_times.append(time.perf_counter() - tic)
        d = np.linalg.norm(ref.states[0, :, :3] - batch.states[i, :, :3], axis=1)
        ref_diffs.append(float(np.max(d)))
    t_ref = sum(ref_times)
    rk45_times, rk45_diffs = [], []
    for i in range(args.reference_tracks):
        tic = time.perf_counter()
        ref = simulate_reference(vehicle, manoeuvre, mode="6dof", coefficients=dict(zip(FREE, theta[i])),
                                 method="RK45", rtol=1e-8, atol=1e-8)
        rk45_times.append(time.perf_counter() - tic)
        rk45_diffs.append(float(np.max(np.linalg.norm(ref.states[0, :, :3] - batch.states[i, :, :3], axis=1))))
    t_rk45 = sum(rk45_times)

    rate_batch = args.batch / t_batch
    rate_single = n_single / t_single
    rate_ref = args.reference_tracks / t_ref
    rhs_calls = args.batch * manoeuvre.n_steps * 4
    print(f"# spiral {manoeuvre.duration:g} s, dt {manoeuvre.dt:g} s ({manoeuvre.n_steps} RK4 steps), "
          f"6-DOF, {vehicle.id}, {len(FREE)} free coefficients +-5 %, numba threads "
          f"{numba.get_num_threads()}")
    print(f"{'path':<34}{'tracks':>8}{'seconds':>12}{'tracks/s':>12}{'ms/track':>11}")
    for label, n, t in ((f"compiled batched (B={args.batch})", args.batch, t_batch),
                        ("compiled one at a time (B=1)", n_single, t_single),
                        ("reference solve_ivp DOP853 1e-10", args.reference_tracks, t_ref),
                        ("reference solve_ivp RK45 1e-8", args.reference_tracks, t_rk45)):
        print(f"{label:<34}{n:>8d}{t:>12.4f}{n / t:>12.3f}{1e3 * t / n:>11.2f}")
    print(f"compiled batched: {1e9 * t_batch / rhs_calls:.0f} ns per right-hand-side evaluation "
          f"(wall, all threads); batched repeats (s): {', '.join(f'{t:.4f}' for t in batch_times)}; "
          f"diverged tracks: {n_bad}")
    print(f"reference per track (s): {', '.join(f'{t:.2f}' for t in ref_times)}")
    print(f"max position difference compiled (RK4 dt {manoeuvre.dt:g} s) vs reference, same "
          f"coefficients (m): {', '.join(f'{d:.3e}' for d in ref_diffs)}")
    print(f"max position difference compiled vs solve_ivp RK45 rtol 1e-8 (m): "
          f"{', '.join(f'{d:.3e}' for d in rk45_diffs)}")
    print(f"speedup_vs_rk45 {rate_batch / (args.reference_tracks / t_rk45):.6g}")
    print(f"batch_vs_single {rate_batch / rate_single:.4f}")
    print(f"tracks_per_s_compiled {rate_batch:.6g}")
    print(f"tracks_per_s_reference {rate_ref:.6g}")
    print(f"speedup {rate_batch / rate_ref:.6g}")


if __name__ == "__main__":
    main()
