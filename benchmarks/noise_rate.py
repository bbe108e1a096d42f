"""Benchmark: the measurement-noise estimate from the data alone (:func:`bayesid.protocol.estimate_noise`)
against the noise actually added, at log rates from 20 Hz to 1 Hz.

The estimator took second differences of each channel (Gasser, Sroka & Jennen-Steinmetz 1986),
which assumes a signal smooth on the sampling scale. At coarse rates a manoeuvre's own curvature
(yaw acceleration in a zigzag, the turn's lateral acceleration) enters the differences and is
read as noise. The gap diagnosis simulates its noise floor (the held-out error of a perfect model)
at that estimate, so an inflated estimate raises the floor and hides gaps. Found on the HSVA KVLCC2
zigzags resampled to 2 Hz: the estimate of psi's noise was 0.0006 rad (0.00002 rad from the 20 Hz
logs) and the noise floor 0.52 m against 0.10 m. The package's estimate now lets the fourth, then
the sixth differences take over in a log coarser than ``protocol.COARSE_LOG_S``
(:func:`bayesid.protocol.difference_noise_sd`).

Workloads: KVLCC2 (packaged model) zigzags 20/20 and 35/5 and a 35 deg turn, and NPS AUV II
zigzags 20/20 and 10/10, simulated at 0.05 s and logged every 0.05, 0.2, 0.5 and 1 s with Gaussian
noise on x, y (m) and psi (rad) at a tank level and a GPS level. Per case and rate: the estimate
over the truth for x, y, psi with the second differences alone (``sec``, the package's estimator
before), the package's estimate now (``pac``) and the fourth differences alone
``(1, -4, 6, -4, 1) / sqrt(70)`` (``fou``, the same MAD), which cancel a cubic's worth of motion
(Hall, Kay & Titterington 1990, Biometrika 77(3), on difference-based variance estimators).

With ``../shared/data/real`` present, the consequence: the HSVA validation-like split (5 large
zigzags to train, 8 small ones held out), at 20 Hz and resampled to 2 Hz with x, y, psi only,
diagnosed with the second differences and with the package's estimate (the noise floor's noise;
fit weights are floored either way): the base held-out RMS and the floor.

    python benchmarks/noise_rate.py [--seed 7] [--data DIR]

The last lines are machine-readable: ``ratio_<estimator>_<channel>_<level>_<interval>`` (the
median over the cases of estimate / truth).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bayesid import __version__  # noqa: E402
from bayesid.data.track import Track  # noqa: E402
from bayesid.protocol import _mad_sd, estimate_noise  # noqa: E402
from bayesid.report import git_commit  # noqa: E402

INTERVALS = (0.05, 0.2, 0.5, 1.0)
LEVELS = {
    "tank": {"x": 0.0005, "y": 0.0005, "psi": math.radians(0.005)},
    "gps": {"x": 0.05, "y": 0.05, "psi": math.radians(0.2)},
}
CHANNELS = ("x", "y", "psi")


def differences(track: Track, order: int) -> dict:
    """The robust estimate from one order of differences alone, unfloored (the comparisons: the
    second order is the package's estimator before the coarse-log rule, the fourth the rule's
    first step at every rate)."""
    out = {}
    for k in CHANNELS:
        y = np.asarray(track[k], float)
        if k == "psi":
            y = np.unwrap(y)
        out[k] = _mad_sd(y, order)
    return out


def runs() -> list:
    """(name, Track at 0.05 s) of each workload, noise-free."""
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models import ship
    from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial
    from bayesid.models.world import LogOptions, world_track

    kv = ship.load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(kv, 1.179)
    opts = TrialOptions(dt=0.05, duration=200.0, rudder_rate_deg_s=15.8)
    out = []
    for kind, a, c in (("zigzag", 20, 20), ("zigzag", 35, 5), ("turn", 35, None)):
        tr = simulate_trial(kv, kind, a, check_deg=c, speed=speed, rpm=rpm, options=opts).track
        out.append((f"KVLCC2 {kind} {a}" + (f"/{c}" if c else ""), tr))
    nps = load_vehicle("nps_auv2")
    for a in (20.0, 10.0):
        m = mv.zigzag(nps, a, dt=0.05, duration=200.0)
        clean = world_track(nps, m, {}, np.random.default_rng(0), LogOptions(noise={}), name="z")
        out.append((f"NPS AUV II zigzag {a:g}/{a:g}", clean))
    return out


def hsva_floor(data: Path) -> None:
    """The diagnosis's noise floor on the HSVA split at 20 Hz and at 2 Hz, with the package's
    estimate and with the fourth differences substituted for it."""
    from bayesid.analysis.gap import DiagnoseOptions, diagnose
    from bayesid.data import datasets
    from bayesid.estimation import windows
    from bayesid.models import ship

    kv = ship.load_ship("kvlcc2_7m")
    runs = {t.name: t for t in (datasets.read_run(p, "simman-hsva") for p in datasets.list_runs(data, "simman-hsva"))}
    train = [v for k, v in runs.items() if k.endswith(("Z_20_05", "Z_25_05", "Z_30_05", "Z_35_05", "Z_20_10_P"))]
    held = [v for v in runs.values() if all(v is not t for t in train)]

    def every(tracks, k):
        keep = ("x", "y", "psi", "delta_r", "n")
        return [Track(t.t[::k], {c: np.asarray(t[c])[::k] for c in keep if c in t}, name=t.name) for t in tracks]

    package = windows.estimate_noise

    def second(track, channels=None, floor=True):
        out = package(track, channels, floor)
        return out if floor else {**out, **{k: v for k, v in differences(track, 2).items() if k in out}}

    options = DiagnoseOptions(candidates=("delay",), max_effects=1)
    for label, k in (("20 Hz, as logged", 1), ("2 Hz, x y psi", 10)):
        tr, ho = (train, held) if k == 1 else (every(train, k), every(held, k))
        for name, est in (("second differences (before)", second), ("package's estimate", package)):
            windows.estimate_noise = est
            try:
                d = diagnose(kv, kv.free, tr, ho, options, rng=np.random.default_rng(0))
            finally:
                windows.estimate_noise = package
            print(
                f"HSVA split {label}, {name}: base held-out RMS {d.gap_before['heldout_rms_m']:.3g} m, "
                f"noise floor {d.noise_floor['heldout_rms_m']:.3g} m, noise psi "
                f"{windows.pooled_noise_sd(ho, floor=False)['psi']:.2g} rad (package's); verdict {d.verdict}"
            )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"))
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"# python benchmarks/noise_rate.py --seed {args.seed}  (bayesid {__version__}, commit {git_commit()})")
    ratios = {}
    for name, tr in runs():
        clean = {k: np.asarray(tr[k], float) for k in CHANNELS}
        for level, sd in LEVELS.items():
            for h in INTERVALS:
                keep = np.arange(0, tr.n_samples, max(1, round(h / float(np.median(np.diff(tr.t))))))
                data = {k: clean[k][keep] + rng.normal(0.0, sd[k], keep.size) for k in CHANNELS}
                t = Track(np.asarray(tr.t, float)[keep], data, name="n")
                est = {
                    "second": differences(t, 2),
                    "package": estimate_noise(t, list(CHANNELS), floor=False),
                    "fourth": differences(t, 4),
                }
                row = []
                for e, v in est.items():
                    for k in CHANNELS:
                        r = v[k] / sd[k]
                        ratios.setdefault((e, k, level, h), []).append(r)
                        row.append(f"{e[:3]}:{k} {r:.3g}")
                print(f"{name:28s} {level:4s} every {h:4.2f} s: estimate / truth  " + "  ".join(row))
    data = Path(args.data) / "kvlcc2-simman-hsva"
    if data.is_dir():
        hsva_floor(data)
    else:
        print(f"no real data under {data}: the HSVA noise floors are skipped")
    print()
    print("median over the cases of estimate / truth (1 = right; above 1: motion read as noise)")
    for (e, k, level, h), v in sorted(ratios.items(), key=lambda kv: (kv[0][2], kv[0][1], kv[0][0], kv[0][3])):
        print(f"ratio_{e}_{k}_{level}_{h:g} {float(np.median(v)):.4g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
