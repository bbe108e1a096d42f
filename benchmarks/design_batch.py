"""Benchmark: the design's standard predictions with each model's parameter draws flown in one
batched simulation per pass (``runs.simulate_runs``, ``runs.zigzag_rudders``: the package)
against one draw at a time (the same functions called with one row per draw: what the package did
before the lock-step search), in one run, on the same models.

Workloads: the models the gap diagnosis designs with (the base model, the kept term's refit and its
alternatives' refits, ``DiscriminationOptions().n_draws`` Laplace draws each) for the synthetic NPS AUV II
and KVLCC2 cases of ``benchmarks/discovery.py``; the standard runs of
``design.STANDARD_RUNS`` (turning circles both ways, zigzags 10/10 and 20/20). Each variant is
timed ``--repeats`` times alternately and the best time kept (other load only slows a run down);
the indices of both variants are compared (they must be identical).

    python benchmarks/design_batch.py [--repeats 3]

Then the index reads alone (``manoeuvre_indices`` of 20 NPS AUV II zigzags) with numpy's
``polyder`` against the package's ``indices._der``.

The last lines are machine-readable: ``batch_vs_single_<case>`` (the one-draw-at-a-time time
over the batched one) and ``indices_der_vs_polyder``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import discovery as cases  # noqa: E402  (benchmarks/discovery.py: the same synthetic cases)

from bayesid.analysis.gap import design as dz  # noqa: E402
from bayesid.models import runs as mr  # noqa: E402


def _models(case):
    """The (stages, setup, options) the diagnosis of ``case`` hands to ``standard_predictions``."""
    diag = importlib.import_module("bayesid.analysis.gap.diagnose")
    got = {}
    orig = diag.standard_predictions

    def grab(stages, setup, options=None, **kw):
        options = dz.DiscriminationOptions() if options is None else options
        got.update(stages=stages, setup=setup, options=options)
        return orig(stages, setup, options, **kw)

    diag.standard_predictions = grab
    try:
        cases._diagnose(*case, 40, True)
    finally:
        diag.standard_predictions = orig
    return got["stages"], got["setup"], got["options"]


def _one_at_a_time(stage, P, run, approach):
    """Each draw's indices from its own free run, one row per call (the cost of the old loop)."""
    return [dz._free_run_indices(stage, P[b : b + 1], run, approach)[0] for b in range(len(P))]


def _all_runs(stages, setup, options, batched: bool) -> list:
    """Every model's draws' indices on every standard run, batched or one draw at a time (the draws
    and the runs as :func:`~bayesid.analysis.gap.design.standard_predictions` makes them)."""
    rng = np.random.default_rng(options.seed)
    options = dz.within_limits(options, setup.vehicle)
    approach = mr.approach_condition(setup.train)
    D = float(options.duration_s or max(150.0, approach.duration_s))
    draws = {
        k: dz._draws(st, [st.model.context(tr, setup.fit_window_s) for tr in setup.train], options.n_draws, rng)
        for k, st in stages.items()
    }
    out = []
    for kind, rudder, check, side in dz.STANDARD_RUNS:
        a = float(options.max_rudder_deg) if rudder is None else min(rudder, float(options.max_rudder_deg))
        run = mr.ManoeuvreRun(kind, a, None if check is None else a, side, approach.rpm, D)
        for k, st in stages.items():
            f = dz._free_run_indices if batched else _one_at_a_time
            out.append(f(st, draws[k], run, approach))
    return out


def _best(args: tuple, repeats: int):
    best, got = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        got = _all_runs(*args)
        best = min(best, time.perf_counter() - t0)
    return best, got


def _index_reads(repeats: int) -> float:
    """The index reads (:func:`~bayesid.estimation.indices.manoeuvre_indices` of NPS AUV II zigzags
    10/10 and 20/20, 10 times each) with numpy's ``polyder`` against the package's ``_der``:
    printed, and the ratio returned."""
    import numpy.polynomial.polynomial as npoly

    from bayesid.data.vehicle import load_vehicle
    from bayesid.estimation import indices as ix
    from bayesid.models import manoeuvres as mv
    from bayesid.models.world import world_track

    veh = load_vehicle("nps_auv2")
    runs = [
        world_track(veh, mv.zigzag(veh, a, dt=0.1, duration=150.0), {}, np.random.default_rng(0)) for a in (10.0, 20.0)
    ]

    def reads():
        t0 = time.perf_counter()
        got = [ix.manoeuvre_indices(r.t, r["x"], r["y"], r["psi"], r["delta_r"]) for _ in range(10) for r in runs]
        return time.perf_counter() - t0, got

    reads()
    new, got_new = min((reads() for _ in range(repeats)), key=lambda x: x[0])
    der = ix._der
    ix._der = lambda c, m=1: npoly.polyder(c, m)
    try:
        old, got_old = min((reads() for _ in range(repeats)), key=lambda x: x[0])
    finally:
        ix._der = der
    same = all(repr(a) == repr(b) for a, b in zip(got_new, got_old))  # every index, NaN included
    print(
        f"index reads (20 zigzags): numpy polyder {old:.3f} s, _der {new:.3f} s (x {old / new:.2f}); identical: {same}"
    )
    return old / new


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    ratios = {}
    veh, free, train, held = cases.submarine(np.random.default_rng(5))
    kv, ktrain, kheld = cases.synthetic(np.random.default_rng(0))
    work = {
        "nps_auv2": (veh, free, train, held, ["sensor_bias", "waves", "crossflow"]),
        "kvlcc2": (kv, None, ktrain, kheld, ["current", "delay", "sensor_lag"]),  # as its outputs were measured
    }
    for name, (v, f, tr, he, cands) in work.items():
        stages, setup, options = _models((v, f, tr, he, cands))
        n = len(stages) * (options.n_draws + 1)
        _all_runs(stages, setup, options, True)  # warm-up (compilation)
        tb, got_b = _best((stages, setup, options, True), args.repeats)
        ts, got_s = _best((stages, setup, options, False), args.repeats)
        same = all(
            all(
                np.array_equal(np.asarray(list(a.values())), np.asarray(list(b.values())), equal_nan=True)
                for a, b in zip(x, y)
            )
            for x, y in zip(got_b, got_s)
        )
        ratios[name] = ts / tb
        print(
            f"{name}: {len(stages)} models x {options.n_draws + 1} parameter vectors = {n} free runs per standard run, "
            f"{len(dz.STANDARD_RUNS)} standard runs: batched {tb:.2f} s, one draw at a time {ts:.2f} s "
            f"(x {ts / tb:.2f}); indices identical: {same}"
        )
    ratios["indices_der_vs_polyder"] = _index_reads(args.repeats)
    for name, r in ratios.items():
        print(f"{name if name.startswith('indices') else 'batch_vs_single_' + name} {r:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
