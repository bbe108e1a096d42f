"""Benchmark: the submarine kernel of a discovery candidate, generated per candidate (as at
5b2d9ad) against the open kernel generated once for the base terms, which takes the candidate at
run time (now; :class:`bayesid.models.codegen.Open`).

Structure discovery refits the model once per candidate term (NPS AUV II's library offers 114);
each refit frees a coefficient the vehicle lacks. At 5b2d9ad each refit's active-term set was
written into its own kernel source and compiled (about 10 s each on a 2-core machine; a cold
test run compiled 45 of them); now every candidate of one base shares the open kernel. This
script, in one run:

* compiles, in an empty kernel cache (``BAYESID_CACHE`` set to a temporary folder), the kernel
  generated per candidate for each of ``--candidates`` candidates and the open kernel once, and
  prints the compile seconds of each;
* times both on the same arguments after a warm-up (NPS AUV II, horizontal plane, a 60 s random
  rudder sequence, ``--batch`` coefficient rows perturbed by 10 %), best of ``--repeats``
  alternating calls, and checks that the tracks are bit-identical.

    python benchmarks/open_kernel.py [--batch 64] [--repeats 7] [--candidates 4]

The last lines are machine-readable: ``compile_s_generated_total``, ``compile_s_open``,
``run_ratio_open_vs_generated_<candidate>`` (open time / generated time: above 1 the loop is
slower) and ``bit_identical``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

CANDIDATES = ["Nvvr", "Yabsrdrdr", "Nuu", "Yvrr", "Nconst", "Yvvv"]


def _manoeuvre(vehicle, seconds=60.0, dt=0.1, seed=1):
    """A random piecewise-constant rudder at the vehicle's cruise rpm, from rest in sway and yaw."""
    from bayesid.models import manoeuvres
    from bayesid.models.simulate import Manoeuvre

    rng = np.random.default_rng(seed)
    n = int(round(seconds / dt))
    s0 = manoeuvres.steady_state(vehicle)
    inp = np.zeros((n, 4))
    inp[:, 0] = np.repeat(rng.uniform(-0.35, 0.35, n // 50 + 1), 50)[:n]
    inp[:, 3] = vehicle.rpm if getattr(vehicle, "rpm", None) else 1500.0
    return Manoeuvre("random rudder", dt, inp, s0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--candidates", type=int, default=4, help=f"how many of {CANDIDATES}")
    args = ap.parse_args(argv)
    os.environ["BAYESID_CACHE"] = tempfile.mkdtemp(prefix="bayesid-bench-")

    from bayesid.data import terms
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import codegen
    from bayesid.models.simulate import Simulator

    veh = load_vehicle("nps_auv2")
    man = _manoeuvre(veh)
    rng = np.random.default_rng(0)
    cands = [terms.term(terms.listed_name(c) or c).name for c in CANDIDATES[: args.candidates]]
    print(f"NPS AUV II, horizontal, {man.n_steps} steps, batch {args.batch}, cache {os.environ['BAYESID_CACHE']}")
    sims, theta, t_gen = {}, {}, 0.0
    same = True
    for c in cands:
        free = ["Yv", "Nr", "Yr", "Nv", c]
        new = Simulator(veh, man, free, mode="horizontal")
        old = Simulator(veh, man, free, mode="horizontal")
        old._kernel = codegen.generated(old.force_names, "horizontal")  # the 5b2d9ad path
        th = new.vehicle.coefficient_vector(free) * (1 + rng.uniform(-0.1, 0.1, (args.batch, len(free))))
        th[:, -1] = rng.normal(0.0, 0.002, args.batch)
        tic = time.perf_counter()
        a = old.run(th[:1]).states
        dt_old = time.perf_counter() - tic
        t_gen += dt_old
        tic = time.perf_counter()
        b = new.run(th[:1]).states
        dt_new = time.perf_counter() - tic
        print(f"{c:>10}: first call (compile) generated {dt_old:6.1f} s, open {dt_new:6.1f} s")
        same &= np.array_equal(a, b, equal_nan=True)
        sims[c], theta[c] = (old, new), th
    t_open = None
    ratios = {}
    for c in cands:
        old, new = sims[c]
        th = theta[c]
        same &= np.array_equal(old.run(th).states, new.run(th).states, equal_nan=True)
        best = {"old": np.inf, "new": np.inf}
        for _ in range(args.repeats):
            for key, sim in (("old", old), ("new", new)):
                tic = time.perf_counter()
                sim.run(th)
                best[key] = min(best[key], time.perf_counter() - tic)
        ratios[c] = best["new"] / best["old"]
        print(f"{c:>10}: run generated {best['old'] * 1e3:7.2f} ms, open {best['new'] * 1e3:7.2f} ms")
    # the open kernel compiled at the first candidate's first call: time a fresh process's view
    t_open = _open_compile_seconds()
    print(f"compile_s_generated_total {t_gen:.1f}")
    print(f"compile_s_open {t_open:.1f}")
    for c, r in ratios.items():
        print(f"run_ratio_open_vs_generated_{c} {r:.3f}")
    print(f"bit_identical {same}")
    return 0 if same else 1


def _open_compile_seconds() -> float:
    """Seconds to compile the open kernel of the base terms in a fresh, empty cache."""
    import subprocess

    code = (
        "import os, tempfile, time, sys;"
        "os.environ['BAYESID_CACHE'] = tempfile.mkdtemp();"
        "sys.path.insert(0, os.path.dirname(sys.argv[1]));"
        "import open_kernel as ok;"
        "from bayesid.data.vehicle import load_vehicle;"
        "from bayesid.models.simulate import Simulator;"
        "v = load_vehicle('nps_auv2'); m = ok._manoeuvre(v);"
        "s = Simulator(v, m, ['Yv', 'Nr', 'Nvvr'], mode='horizontal');"
        "t = time.perf_counter(); s.run(); print(time.perf_counter() - t)"
    )
    out = subprocess.run([sys.executable, "-c", code, __file__], check=True, capture_output=True, text=True)
    return float(out.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    raise SystemExit(main())
