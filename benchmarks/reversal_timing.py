"""How much does the timing of a rudder reversal between two log samples matter? (issue 50)

A closed-loop zigzag reverses the rudder when the heading passes the check angle, whenever that
is; an actuator much faster than the log (or a column that logs the rudder order) then shows each
reversal as a lone jump between two samples, and no reading of the log between samples (``--inputs
hold`` or ``linear``) knows where in the interval it happened. Synthetic, right structure: NPS AUV
II (Yv, Yr, Nv, Nr, Ydr, Ndr free, the file's values the truth), 20/20 zigzags to both sides with
instantaneous reversals, 100 s, integrated at 0.01 s, logged at 1, 2, 5 and 10 Hz (x, y, psi with
5 cm and 0.3 deg noise, no u, v, r). Two truths per rate: the zigzag's reversals decided on the
log's clock (each reversal at a sample: what the fit assumes) or on the 0.01 s clock (between
samples). Each fitted as ``bayesid fit --dt auto --inputs MODE --prior none`` would, MODE
``hold``, ``linear``, ``rate`` (a gear of :data:`GEAR_DEG_S`, far faster than the log: each
reversal within one interval, put in its middle) and ``retime`` (``--inputs rate --retime``: each
reversal's time estimated with the coefficients, its uncertainty in their covariance). Per rate,
truth and mode: the truth's Mahalanobis distance from the estimate (d^2 against the chi^2_6 90 %
quantile 10.6), the largest relative error of a coefficient and the fit's final step.

    python benchmarks/reversal_timing.py [--seeds 0,1,2] [--rates 1,2,5,10] [--modes hold,linear,rate,retime]
                                         [--out reports/benchmark_reversal_timing.txt]
"""

from __future__ import annotations

import argparse
import math
import platform
import time
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from bayesid import __version__
from bayesid.data.track import INPUT_NAMES, STATE_NAMES, Track
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation.identification import identify
from bayesid.estimation.options import FitOptions
from bayesid.models import build_model
from bayesid.models import manoeuvres as mv
from bayesid.report import git_commit

FREE = ("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr")
#: Integration step of the truth, s.
DT_TRUE = 0.01
NOISE_M, NOISE_DEG = 0.05, 0.3
#: The gear rate the ``rate`` and ``retime`` fits are given, deg/s: the truth's reversals are
#: instantaneous, so any rate far above 40 deg per log interval reads them as movements within one.
GEAR_DEG_S = 1000.0


def truth_runs(vehicle, clock_s: float) -> list:
    """The two zigzags, reversals decided every ``clock_s``: [(t, states, inputs)] at 0.01 s."""
    model = build_model(vehicle, dt=DT_TRUE)
    k = int(round(clock_s / DT_TRUE))
    out = []
    for side in (1, -1):
        m = mv.zigzag(vehicle, 20, 20, dt=clock_s, duration=100.0, first_sign=side)
        held = np.append(m.inputs, m.inputs[-1:], axis=0)
        u = {c: np.repeat(held[:, j], k)[: (m.t.size - 1) * k + 1] for j, c in enumerate(INPUT_NAMES)}
        t = np.round(np.arange(next(iter(u.values())).size) * DT_TRUE, 10)
        ctx = model.context(Track(t, u), None, s0=m.initial_state)
        S = model.simulate(ctx, model.start()[None], measured_start=False)[0]
        out.append((t, S, u))
    return out


def logged(runs, hz: float, rng) -> list:
    """The runs logged at ``hz`` with position and heading noise."""
    k = int(round(1.0 / (hz * DT_TRUE)))
    out = []
    for i, (t, S, u) in enumerate(runs):
        d = {c: S[::k, STATE_NAMES.index(c)].copy() for c in ("x", "y", "psi")}
        d["x"] += rng.normal(0.0, NOISE_M, d["x"].size)
        d["y"] += rng.normal(0.0, NOISE_M, d["y"].size)
        d["psi"] += rng.normal(0.0, math.radians(NOISE_DEG), d["psi"].size)
        d.update({c: u[c][::k] for c in u})
        out.append(Track(t[::k], d, name=f"z20_{i}_{hz:g}Hz"))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--rates", default="1,2,5,10")
    ap.add_argument("--modes", default="hold,linear,rate,retime")
    ap.add_argument(
        "--out", default=str(Path(__file__).resolve().parents[1] / "reports" / "benchmark_reversal_timing.txt")
    )
    a = ap.parse_args(argv)
    t_all = time.perf_counter()
    veh = load_vehicle("nps_auv2")
    truth = veh.coefficient_vector(list(FREE))
    q90 = chi2.ppf(0.9, len(FREE))
    lines = [
        f"benchmarks/reversal_timing.py: bayesid {__version__}, commit {git_commit()}, {platform.node()}, "
        f"{time.strftime('%Y-%m-%d')}",
        f"seeds {a.seeds}; NPS AUV II 20/20 zigzags both sides, instantaneous reversals, 100 s; noise {NOISE_M} m, "
        f"{NOISE_DEG} deg; fits --dt auto --prior none (rate, retime: --inputs rate --rudder-rate {GEAR_DEG_S:g}); "
        f"d2: the truth's Mahalanobis distance (chi^2_6 90 %: {q90:.2f})",
        "",
        f"{'Hz':>4s} {'reversals':>10s} {'inputs':>7s} {'seed':>4s} {'d2':>8s} {'joint':>5s} {'max |rel err|':>14s} "
        f"{'worst':>6s} {'dt':>6s}",
    ]
    print("\n".join(lines), flush=True)
    rows = []
    fine = truth_runs(veh, DT_TRUE)
    for hz in [float(r) for r in a.rates.split(",")]:
        for where, runs in (("at samples", truth_runs(veh, 1.0 / hz)), ("between", fine)):
            for mode in a.modes.split(","):
                for seed in [int(s) for s in a.seeds.split(",")]:
                    train = logged(runs, hz, np.random.default_rng(seed))
                    opts = FitOptions(
                        free=FREE,
                        prior=False,
                        inputs="rate" if mode == "retime" else mode,
                        rudder_rate_deg_s=GEAR_DEG_S if mode in ("rate", "retime") else None,
                        retime=mode == "retime",
                        refine_step=True,
                    )
                    res = identify(veh, train, opts, calibration=None)
                    d = res.fit.p[: len(FREE)] - truth
                    d2 = float(d @ np.linalg.lstsq(res.cov[: len(FREE), : len(FREE)], d, rcond=None)[0])
                    rel = np.abs(d / truth)
                    rows.append((hz, where, mode, d2 <= q90, float(rel.max())))
                    lines.append(
                        f"{hz:4g} {where:>10s} {mode:>7s} {seed:4d} {d2:8.1f} {'in' if d2 <= q90 else 'out':>5s} "
                        f"{rel.max():14.2f} {FREE[int(rel.argmax())]:>6s} {res.model.dt:6.3g}"
                    )
                    print(lines[-1], flush=True)
    lines += ["", "summary: fits with the truth in the joint 90 % ellipsoid (median of the largest relative error)", ""]
    for hz in sorted({r[0] for r in rows}):
        for where in ("at samples", "between"):
            cells = []
            for mode in a.modes.split(","):
                sel = [r for r in rows if r[:3] == (hz, where, mode)]
                cells.append(f"{mode} {sum(r[3] for r in sel)}/{len(sel)} ({np.median([r[4] for r in sel]):.2f})")
            lines.append(f"{hz:4g} Hz, reversals {where:>10s}: " + "; ".join(cells))
    lines.append(f"wall {time.perf_counter() - t_all:.0f} s")
    print("\n".join(lines[-(2 + 2 * len({r[0] for r in rows})) :]))
    if a.out:
        Path(a.out).write_text("\n".join(lines) + "\n")
        print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
