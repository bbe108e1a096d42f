"""Benchmark: the fitted start rule's second guess (:data:`bayesid.estimation.shooting.RETRY_COST`),
on against off, on runs logged without a velocity log (the start states are fitted).

Workloads: the synthetic cases of ``studies/structure_discovery.py`` without a velocity log (NPS
AUV II user-shaped runs at 5 Hz with a hidden ``Nvvr`` or nothing hidden; KVLCC2 zigzags at 10 Hz
with a hidden ``N0``), each a gap diagnosis without candidates (the base fit, its held-out windows
and the noise floor: the multiple-shooting fit refits the window starts at every evaluation;
with ``--discover`` also structure discovery, its refits and alternatives).
Per case and setting: the wall time, how many start fits retried a window and how many kept the
second fit, the base fit's held-out RMS, and the true model's worst held-out window (the start
fit's own accuracy: the truth should predict every window to the noise).

    python benchmarks/start_retry.py [--seed 2056] [--repeats 1] [--discover]

The last lines are machine-readable: ``time_ratio_on_vs_off_<case>`` and
``true_worst_window_m_<on|off>_<case>``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bayesid.analysis.gap import DiagnoseOptions, diagnose  # noqa: E402
from bayesid.analysis.gap.discovery import DiscoveryOptions  # noqa: E402
from bayesid.estimation import shooting  # noqa: E402
from bayesid.estimation.prediction import predict  # noqa: E402
from bayesid.models import build_model  # noqa: E402
from studies import structure_discovery as sd  # noqa: E402

CASES = {
    "submarine_Nvvr": ("submarine", {"Nvvr": -0.3}),
    "submarine_control": ("submarine", {}),
    "ship_N0": ("ship", {"N0": 0.0008}),
}


class Counted:
    """Counts the retries of :func:`shooting.fit_starts` (calls of ``zero_sideslip``) and the
    windows whose second fit was kept."""

    def __init__(self):
        self.retries = 0
        self.kept = 0
        self._zero = shooting.zero_sideslip
        self._lm = shooting._levenberg_marquardt

    def __enter__(self):
        def zero(ctx, D):
            self.retries += 1
            self._pending = True
            return self._zero(ctx, D)

        def lm(args, D):
            out = self._lm(args, D)
            if getattr(self, "_pending", False):
                self._pending = False
                self.kept += int(np.sum(out[1] < shooting.RETRY_GAIN * self._last_cost))
            else:
                rows = np.maximum(np.asarray(args[5].sum(axis=1)).ravel(), 1.0)
                self._last_cost = np.where(out[1] / rows > shooting.RETRY_COST, out[1], 0.0)
            return out

        shooting.zero_sideslip, shooting._levenberg_marquardt = zero, lm
        return self

    def __exit__(self, *exc):
        shooting.zero_sideslip, shooting._levenberg_marquardt = self._zero, self._lm


def data(family: str, hidden: dict, seed: int):
    if family == "ship":
        return sd.ship_tracks(hidden, False, np.random.default_rng(seed), 150.0), 60.0
    return sd.submarine_tracks(hidden, False, seed, 150.0), 30.0


def run(name: str, seed: int, retry: bool, discover: bool) -> dict:
    family, hidden = CASES[name]
    (veh, free, train, held), window = data(family, hidden, seed)
    saved = shooting.RETRY_COST
    shooting.RETRY_COST = saved if retry else np.inf
    try:
        with Counted() as c:
            tic = time.perf_counter()
            d = diagnose(
                veh,
                free,
                train,
                held,
                DiagnoseOptions(
                    candidates=(),
                    window_s=window,
                    max_nfev=40,
                    discover=DiscoveryOptions(max_nfev=40, n_alternatives=2) if discover else None,
                ),
                rng=np.random.default_rng(seed),
            )
            seconds = time.perf_counter() - tic
        truth = build_model(veh.with_coefficients(hidden) if hidden else veh, free)
        pr = predict(truth, truth.start(), held, window, start="fitted", leadin_s=10.0)
    finally:
        shooting.RETRY_COST = saved
    return {
        "seconds": seconds,
        "retries": c.retries,
        "kept": c.kept,
        "base_heldout_m": d.gap_before["heldout_rms_m"],
        "true_worst_m": max(w["rms_position_m"] for w in pr.windows),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=2056)
    ap.add_argument("--repeats", type=int, default=1, help="timings per setting (the best is kept)")
    ap.add_argument("--discover", action="store_true", help="with structure discovery (its refits and alternatives)")
    args = ap.parse_args()
    what = "with discovery (n_alternatives 2)" if args.discover else "without discovery"
    print(f"# seed {args.seed}; best of {args.repeats}; diagnosis without candidates, {what}, max_nfev 40, one process")
    print(
        f"{'case':20s} {'retry':5s} {'seconds':>8s} {'retries':>8s} {'kept':>5s} {'base m':>8s} {'truth worst m':>14s}"
    )
    lines = []
    for name in CASES:
        res = {}
        for retry in (False, True):
            outs = [run(name, args.seed, retry, args.discover) for _ in range(args.repeats)]
            r = min(outs, key=lambda o: o["seconds"])
            res[retry] = r
            print(
                f"{name:20s} {'on' if retry else 'off':5s} {r['seconds']:8.1f} {r['retries']:8d} {r['kept']:5d} "
                f"{r['base_heldout_m']:8.3f} {r['true_worst_m']:14.3f}",
                flush=True,
            )
        lines += [
            f"time_ratio_on_vs_off_{name} {res[True]['seconds'] / res[False]['seconds']:.3f}",
            f"true_worst_window_m_off_{name} {res[False]['true_worst_m']:.3f}",
            f"true_worst_window_m_on_{name} {res[True]['true_worst_m']:.3f}",
        ]
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
