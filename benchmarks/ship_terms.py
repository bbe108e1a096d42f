"""Benchmark: the generated ship kernel with extra hull terms, one kernel per term set (as at
5b2d9ad) against one kernel that loops over the terms of each parameter row (now).

Structure discovery refits a dozen or more candidate terms per diagnosis, each a new term set. At
5b2d9ad each set was written into its own kernel source and compiled (8-17 s per set on a 2-core
machine, more under load); now every non-empty set shares one kernel. This script, in one run:

* compiles, in an empty kernel cache (``BAYESID_CACHE`` set to a temporary folder), the old
  kernel once per term set and the new kernel once, and prints the compile seconds of each;
* times both on the same arguments after a warm-up (KVLCC2 7 m with windage, ``--batch`` rows
  perturbed by 10 %, three windows of 300 steps, as ``tests/test_shipgen.py``'s cases), best of
  ``--repeats`` alternating calls, and checks that their outputs are bit-identical.

    python benchmarks/ship_terms.py [--batch 64] [--repeats 7]

The old kernel is ``bayesid/models/ship/kernel.py`` at ``--old`` (default 5b2d9ad), read with
``git show`` and loaded beside the package. The last lines are machine-readable:
``compile_s_old_total``, ``compile_s_new``, ``run_ratio_new_vs_old_<set>`` (new time / old time:
above 1 the loop is slower) and ``bit_identical``.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SETS = {
    "N0": ["N0"],
    "Nvvv": ["Nvvv"],
    "Nabsdr+Yvvv": ["Nabsdr", "Yvvv"],
    "four terms": ["Ndrdrdr", "Yabsvabsdr", "Nvabsvabsr", "Yrrr"],
}


def _old_kernel(rev: str):
    """The ship kernel module of revision ``rev``, loaded as a sibling of the current one."""
    src = subprocess.run(
        ["git", "show", f"{rev}:bayesid/models/ship/kernel.py"], cwd=ROOT, check=True, capture_output=True, text=True
    ).stdout
    path = Path(tempfile.mkdtemp()) / "kernel_old.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("bayesid.models.ship._kernel_old", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _args(names, B, seed):
    """Kernel arguments (tests/test_shipgen.py's case) with the extra terms ``names``."""
    spec = importlib.util.spec_from_file_location("_shipgen", ROOT / "tests" / "test_shipgen.py")
    tsg = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tsg)
    from bayesid.models import ship

    shp = ship.load_ship("kvlcc2_7m").with_coefficients({n: 0.003 * (1 + j) * (-1) ** j for j, n in enumerate(names)})
    args = tsg._case("kvlcc2_7m", seed, B=B)
    tail = ship.hullterms.encode(shp.hull_terms, shp.coefficients)
    args[5] = np.concatenate([args[5], np.repeat(tail[None], B, axis=0)], axis=1)
    return args, ship.hullterms.signature(shp.hull_terms), tsg._run


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--old", default="5b2d9ad")
    args = ap.parse_args()
    os.environ["BAYESID_CACHE"] = tempfile.mkdtemp(prefix="bayesid_cache_")  # both compile from cold
    from bayesid.models.ship import kernel as new

    old = _old_kernel(args.old)
    print(f"B = {args.batch} rows, 3 windows of 300 steps, KVLCC2 7 m with windage; empty kernel cache")
    compile_old, ratios, identical = 0.0, {}, True
    compile_new = None
    for i, (label, names) in enumerate(SETS.items()):
        kargs, sig, run = _args(names, args.batch, 20 + i)
        calls = {}
        for tag, mod in (("old", old), ("new", new)):
            tic = time.perf_counter()
            out_first = run(lambda *a, mod=mod, sig=sig: mod.generated(mod.LANES, sig).simulate_windows(*a), kargs)
            sec = time.perf_counter() - tic
            if tag == "old":
                compile_old += sec
            elif compile_new is None:
                compile_new = sec
            calls[tag] = (mod, out_first)
            print(f"  {label:>12}: {tag} first call (compile + run) {sec:6.1f} s")
        same = all(np.array_equal(a, b, equal_nan=True) for a, b in zip(calls["old"][1], calls["new"][1], strict=True))
        identical &= same
        best = {"old": np.inf, "new": np.inf}
        for _ in range(args.repeats):
            for tag, (mod, _) in calls.items():
                tic = time.perf_counter()
                run(lambda *a, mod=mod, sig=sig: mod.generated(mod.LANES, sig).simulate_windows(*a), kargs)
                best[tag] = min(best[tag], time.perf_counter() - tic)
        ratios[label] = best["new"] / best["old"]
        print(
            f"  {label:>12}: old {1e3 * best['old']:7.2f} ms, new {1e3 * best['new']:7.2f} ms, "
            f"new / old {ratios[label]:.2f}, bit-identical {same}"
        )
    print(f"compile_s_old_total {compile_old:.1f}")
    print(f"compile_s_new {compile_new:.1f}")
    for label, r in ratios.items():
        print(f"run_ratio_new_vs_old_{label.replace(' ', '_').replace('+', '_')} {r:.3f}")
    print(f"bit_identical {identical}")
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
