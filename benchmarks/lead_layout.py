"""Benchmark: the fitted start rule's start fits as they were (old: every window simulated to its
end, every simulation preparing its coefficients and inputs anew), with each simulation stopped at
its window start (``TrackContext.layout("lead")``, +lead), and with the parameter rows prepared
once per fit as well (``model.prepare``, new), in one run.

The start fit (:func:`bayesid.estimation.shooting.fit_starts`) reads only the lead-in samples
before each window start, yet every one of its simulations used to run each window to its end;
and it simulates the same parameter rows from many start states, yet each simulation rebuilt their
coefficient rows, mass matrices, inputs and forces. Neither changes a number: the script checks
that the offsets of the three settings are identical, to the last bit, and prints the time ratios.

Workloads (the diagnosis's lead-in of :func:`bayesid.analysis.gap.diagnose.start_settings`, 60 s
windows, fitted starts):

* ``nps`` -- the three training and four held-out runs of ``benchmarks/diagnose.py``'s NPS AUV II
  case (5 Hz, no velocity log), at the nominal coefficients;
* ``remus`` -- the newcomer's four REMUS 100 logs (``reports/newcomer_auv/logs/wrapped``);
* ``kvlcc2`` -- a 20/20 zigzag and a 35 deg turn of the packaged KVLCC2, positions and heading only.

    python benchmarks/lead_layout.py [--repeat 3]

Each fit starts from the model's start coefficients changed by 5 % (two parameter rows), as
the fits' own evaluations do. The last lines are machine-readable: ``ratio_<case>`` (old time / new
time), ``ratio_lead_<case>`` (old / +lead) and ``identical_<case>``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "studies"))

from bayesid.analysis.gap.diagnose import start_settings  # noqa: E402
from bayesid.data.track import Track  # noqa: E402
from bayesid.estimation import shooting  # noqa: E402
from bayesid.models import build_model  # noqa: E402


def _cases() -> dict:
    """{case: (model, tracks)}."""
    from diagnose import _nps_case
    from start_fits import newcomer_case

    from bayesid.models.ship import load_ship
    from bayesid.models.ship.trials import propulsion_point, service_condition, simulate_trial

    veh, free, train, held, _ = _nps_case()
    ship = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(ship, service_condition(ship)["speed"])
    runs = [simulate_trial(ship, k, a, speed=speed, rpm=rpm) for k, a in (("zigzag", 20.0), ("turn", -35.0))]
    ship_tracks = [
        Track(r.track.t, {c: r.track[c] for c in ("x", "y", "psi", "delta_r", "n")}, name=r.name) for r in runs
    ]
    return {
        "nps": (build_model(veh, free), train + held),
        "remus": newcomer_case(),
        "kvlcc2": (build_model(ship, None), ship_tracks),
    }


def _fit_all(model, ctxs, P, setting: str) -> tuple[list, float]:
    """Every context's start offsets for the rows ``P`` under ``setting`` (old, +lead, new), and
    the wall time."""
    saved = [c.lead_starts for c in ctxs]
    prepare = shooting._prepare
    if setting == "old":
        for c in ctxs:
            c.lead_starts = None
    if setting != "new":
        shooting._prepare = lambda *a: None
    try:
        t = time.perf_counter()
        out = [shooting.fit_starts(model, c, P) for c in ctxs]
        return out, time.perf_counter() - t
    finally:
        shooting._prepare = prepare
        for c, s in zip(ctxs, saved):
            c.lead_starts = s


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each setting (the fastest is kept)")
    args = ap.parse_args(argv)
    lines = []
    print("case     windows  lead steps / window steps   old s  +lead s   new s  old:+lead  old:new  identical")
    for name, (model, tracks) in _cases().items():
        _, lead = start_settings("fitted", tracks, 60.0, model.dt, None)
        ctxs = [model.context(tr, 60.0, start="fitted", leadin_s=lead) for tr in tracks]
        p = model.start()
        P = p[None] * (1.0 + 0.05 * np.random.default_rng(0).normal(size=(2, p.size)))
        _fit_all(model, ctxs, P, "new")  # compile and warm up
        runs = {
            k: min((_fit_all(model, ctxs, P, k) for _ in range(args.repeat)), key=lambda r: r[1])
            for k in ("old", "+lead", "new")
        }
        same = all(
            np.array_equal(a, b) and np.array_equal(a, c)
            for a, b, c in zip(runs["old"][0], runs["+lead"][0], runs["new"][0])
        )
        W = sum(c.W for c in ctxs)
        steps = sum(c.lead_starts[-1] for c in ctxs), sum(c.n_virtual for c in ctxs)
        t = {k: v[1] for k, v in runs.items()}
        r_lead, ratio = t["old"] / t["+lead"], t["old"] / t["new"]
        print(
            f"{name:8s} {W:7d}  {steps[0]:10d} / {steps[1]:<12d}  {t['old']:6.2f}  {t['+lead']:7.2f}  {t['new']:6.2f}"
            f"  {r_lead:9.2f}  {ratio:7.2f}  {same}"
        )
        lines += [f"ratio_lead_{name} {r_lead:.3f}", f"ratio_{name} {ratio:.3f}", f"identical_{name} {same}"]
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
