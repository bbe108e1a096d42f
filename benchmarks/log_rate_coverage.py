"""Do the 90 % coefficient intervals of ``bayesid fit`` cover the truth at every log rate? (issue 50)

Synthetic, right structure: a ship (KVLCC2 7 m model, its file's free coefficients) and a
submarine (NPS AUV II, Yv, Yr, Nv, Nr, Ydr, Ndr), each with a truth whose free coefficients are
10-20 % off the vehicle file (sign and size drawn per coefficient; a coefficient that is zero in
the file stays zero). Four training runs per vessel, zigzags 10/10 and 20/20 to both sides,
simulated closed loop at 0.05 s with a rate-limited rudder (the ship's helm rate 15.8 deg/s, the
submarine's 16 deg/s) and logged at 1, 2, 5, 10 and 20 Hz: the instantaneous state and rudder
at each log time, position noise 0.05 m and heading noise 0.3 deg (the same noise draw at the
times the logs share), no u, v, r columns. Each log rate is fitted as ``bayesid fit`` does (the
family's step, window, weighting and start rule; the fitted start rule here, since no velocity
is logged) but without the vehicle file's prior (the truth is off the file by design) and
without calibration, once with the inputs held between samples (``--inputs hold``, the default),
once interpolated linearly (``--inputs linear``) and once moving at the gear's rate
(``--inputs rate``: the ship file's 15.8 deg/s, the submarine's 16 deg/s given as
``--rudder-rate``). Per vessel, rate and mode: the fraction of
free coefficients whose 90 % interval (estimate +- 1.645 Laplace sd) covers the truth, the
largest |z| = |estimate - truth| / sd and the fit's wall time.

    python benchmarks/log_rate_coverage.py [--seeds 0,1,2] [--vessels ship,submarine]
                                           [--rates 1,2,5,10,20] [--modes hold,linear,rate] [--dts default,0.1]
                                           [--max-nfev 60] [--duration-ship 150] [--duration-submarine 120]
                                           [--out reports/benchmark_log_rate.txt]

Times are wall clock on one worker (numba's threads as set by ``NUMBA_NUM_THREADS``).
"""

from __future__ import annotations

import argparse
import dataclasses
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
from bayesid.models import build_model, ship
from bayesid.models import manoeuvres as mv
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial
from bayesid.protocol import wrap
from bayesid.report import git_commit

#: Knots of the true rudder history, s (20 Hz: every log rate is a whole thinning of it).
DT_SIM = 0.05
#: Integration step of the true runs, s.
DT_TRUE = 0.01
#: Navigation noise (1 sd): position m, heading rad.
NOISE = {"x": 0.05, "y": 0.05, "psi": math.radians(0.3)}
#: (rudder deg, check heading deg, side): the four training zigzags.
RUNS = ((10, 10, 1), (10, 10, -1), (20, 20, 1), (20, 20, -1))
SUBMARINE_FREE = ("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr")
SUBMARINE_RATE_DEG_S = 16.0
Z90 = 1.6448536269514722


def off_truth(vehicle, free, rng):
    """The vehicle with each free coefficient 10-20 % off its file value (random sign)."""
    c = vehicle.coefficients
    return vehicle.with_coefficients(
        {k: c[k] * (1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.10, 0.20)) for k in free}
    )


def continuous_truth(truth, t, inputs: dict, s0) -> dict:
    """The truth's run with the rudder (and propeller) moving linearly between the knots ``t``
    (a rate-limited gear sampled every :data:`DT_SIM`), integrated at :data:`DT_TRUE`: the
    states and inputs at the knots, as an instrument samples them."""
    model = build_model(truth, [], (), dt=DT_TRUE, inputs="linear")
    ctx = model.context(Track(t, dict(inputs)), None, s0=s0)
    S = model.simulate(ctx, model.start()[None], measured_start=False)[0]
    if not np.all(np.isfinite(S)) or ctx.ts.size != t.size:
        raise RuntimeError("the truth's run diverged")
    return {**{k: S[:, i] for i, k in enumerate(STATE_NAMES)}, **inputs}


def ship_runs(truth, duration):
    """The ship's runs at the knots: [(name, t, {states, delta_r, n})]. The closed-loop zigzag
    of :func:`~bayesid.models.ship.trials.simulate_trial` gives the rudder history (the angle at
    each knot, helm rate 15.8 deg/s), replayed open loop with the rudder moving between knots."""
    speed, rpm = propulsion_point(truth, 1.179)
    opts = TrialOptions(dt=DT_SIM, duration=duration, rudder_rate_deg_s=15.8)
    out = []
    for angle, check, side in RUNS:
        tr = simulate_trial(truth, "zigzag", side * angle, check_deg=check, speed=speed, rpm=rpm, options=opts).track
        s0 = np.zeros(12)
        for k in ("x", "y", "psi", "u", "v", "r"):
            s0[STATE_NAMES.index(k)] = tr[k][0]
        d = continuous_truth(truth, tr.t, {"delta_r": np.asarray(tr["delta_r"], float), "n": tr["n"]}, s0)
        out.append((f"z{angle}_{check}{'m' if side < 0 else ''}", tr.t, d))
    return out


def submarine_runs(truth, duration):
    """The submarine's runs at the knots: [(name, t, {states, inputs})]; the closed-loop zigzag of
    :func:`~bayesid.models.manoeuvres.zigzag` (rudder rate 16 deg/s) gives the rudder history."""
    out = []
    zz = mv.ZigzagOptions(rate_deg_s=SUBMARINE_RATE_DEG_S)
    for angle, check, side in RUNS:
        m = mv.zigzag(truth, angle, check, dt=DT_SIM, duration=duration, first_sign=side, options=zz)
        u = {k: np.append(m.inputs[:, j], m.inputs[-1, j]) for j, k in enumerate(INPUT_NAMES)}
        out.append((m.name, m.t, continuous_truth(truth, m.t, u, m.initial_state)))
    return out


def logs(runs, hz, noise):
    """The runs logged at ``hz``: x, y, psi (noisy) and the inputs at the log times."""
    k = int(round(1.0 / (hz * DT_SIM)))
    out = []
    for (name, t, d), nz in zip(runs, noise):
        data = {c: d[c][::k] + nz[c][::k] for c in ("x", "y", "psi")}
        data["psi"] = wrap(data["psi"])
        data.update({c: d[c][::k] for c in ("delta_r", "delta_s", "delta_b", "n") if c in d})
        out.append(Track(t[::k], data, name=f"{name}_{hz:g}Hz"))
    return out


def coverage(vehicle, free, truth, train, options: FitOptions) -> dict:
    """One fit's ``covered`` fraction, ``zmax`` (max |z|) and its ``worst`` coefficient, the
    truth's Mahalanobis distance ``d2`` and whether it lies in the joint 90 % ellipsoid
    (``joint``), the fit's final model step ``dt`` and step check's largest shift
    ``shift_sd``, and the ``wall`` time, s."""
    t0 = time.perf_counter()
    res = identify(vehicle, train, options, calibration=None)
    wall = time.perf_counter() - t0
    n = len(free)
    p, sd = res.fit.p[:n], np.sqrt(np.clip(np.diag(res.cov)[:n], 0.0, None))
    tv = np.array([truth.coefficients[k] for k in free])
    z = np.abs(p - tv) / np.where(sd > 0, sd, np.nan)
    worst = int(np.nanargmax(z))
    d = p - tv
    d2 = float(d @ np.linalg.lstsq(res.cov[:n, :n], d, rcond=None)[0])
    # the chance that a calibrated posterior with this covariance meets the target in one fit:
    # errors drawn from N(0, cov), the share of coefficients inside their marginal 90 % intervals
    rng = np.random.default_rng(0)
    draws = rng.multivariate_normal(np.zeros(n), res.cov[:n, :n], size=4000, method="eigh")
    p_target = float(np.mean(np.mean(np.abs(draws) <= Z90 * sd, axis=1) >= 0.8))
    return {
        "covered": float((np.abs(p - tv) <= Z90 * sd).mean()),
        "zmax": float(z[worst]),
        "worst": free[worst],
        "d2": d2,
        "joint": d2 <= chi2.ppf(0.9, n),
        "dt": res.model.dt,
        "shift_sd": res.step_check.max_shift_sd,
        "p_target": p_target,
        "wall": wall,
    }


def vessel_runs(vessel: str, seed: int, a):
    """(nominal vehicle, free names, truth, runs, noise) of one vessel and seed."""
    rng = np.random.default_rng(seed)
    if vessel == "ship":
        veh = ship.load_ship("kvlcc2_7m")
        free = tuple(veh.free)
        truth = off_truth(veh, free, rng)
        runs = ship_runs(truth, a.duration_ship)
    else:
        veh, free = load_vehicle("nps_auv2"), SUBMARINE_FREE
        truth = off_truth(veh, free, rng)
        runs = submarine_runs(truth, a.duration_submarine)
    noise = [{c: rng.normal(0.0, NOISE[c], t.size) for c in NOISE} for _, t, _ in runs]
    return veh, free, truth, runs, noise


def summary(rows, vessels, steps, modes, rates) -> list:
    """Lines of the summary table per rate: the covered fraction over seeds (max |z|), the fits
    whose truth lies in the joint 90 % ellipsoid and, under ``--dts auto``, the steps used."""
    out = [f"{'vessel':10s} {'dt':>7s} {'inputs':7s} " + " ".join(f"{f'{hz:g} Hz':>20s}" for hz in rates)]
    for vessel in vessels:
        for step in steps:
            for inputs in modes:
                cells = []
                for hz in rates:
                    sel = [
                        r for r in rows if (r["vessel"], r["step"], r["hz"], r["inputs"]) == (vessel, step, hz, inputs)
                    ]
                    joint = f"{sum(r['joint'] for r in sel)}/{len(sel)}"
                    cells.append(
                        f"{np.mean([r['covered'] for r in sel]):4.2f} ({max(r['zmax'] for r in sel):4.1f}) {joint:>5s}"
                    )
                out.append(f"{vessel:10s} {step:>7s} {inputs:7s} " + " ".join(f"{c:>20s}" for c in cells))
                if step == "auto":
                    used = [
                        "/".join(
                            f"{d:g}"
                            for d in sorted(
                                {
                                    r["dt"]
                                    for r in rows
                                    if (r["vessel"], r["step"], r["hz"], r["inputs"]) == (vessel, step, hz, inputs)
                                }
                            )
                        )
                        for hz in rates
                    ]
                    out.append(f"{'':10s} {'steps':>7s} {'':7s} " + " ".join(f"{u:>20s}" for u in used))
    return out


def fit_options(vessel: str, step: str, inputs: str, max_nfev: int) -> FitOptions:
    """The fit's options: the vessel's free coefficients as fitted by ``bayesid fit --dt STEP
    --inputs INPUTS`` (``default`` the family's step, ``auto`` refined by the step check) without
    the file's prior."""
    return FitOptions(
        dt=None if step in ("default", "auto") else float(step),
        refine_step=step == "auto",
        max_nfev=max_nfev,
        prior=False,
        inputs=inputs,
        # the ship file gives its gear's rate; the submarine's is the benchmark's (read by --inputs rate alone)
        rudder_rate_deg_s=SUBMARINE_RATE_DEG_S if vessel == "submarine" and inputs == "rate" else None,
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="0,1,2", help="comma-separated seeds (truth and noise)")
    ap.add_argument("--vessels", default="ship,submarine")
    ap.add_argument("--rates", default="1,2,5,10,20", help="log rates, Hz (divisors of 20)")
    ap.add_argument("--modes", default="hold,linear,rate", help="--inputs of the fits")
    ap.add_argument(
        "--dts", default="default,0.1,auto", help="model steps of the fits, s (default: the family's; auto: --dt auto)"
    )
    ap.add_argument("--max-nfev", type=int, default=60)
    ap.add_argument("--duration-ship", type=float, default=150.0, help="ship run after the execute, s")
    ap.add_argument("--duration-submarine", type=float, default=120.0, help="submarine run, s")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "reports" / "benchmark_log_rate.txt"))
    a = ap.parse_args(argv)
    t_all = time.perf_counter()
    seeds = [int(s) for s in a.seeds.split(",")]
    rates = [float(r) for r in a.rates.split(",")]
    modes, vessels, steps = a.modes.split(","), a.vessels.split(","), a.dts.split(",")
    lines = [
        f"benchmarks/log_rate_coverage.py: bayesid {__version__}, commit {git_commit()}, {platform.node()}, "
        f"{time.strftime('%Y-%m-%d')}",
        f"seeds {a.seeds}; rates {a.rates} Hz; inputs {a.modes}; model steps {a.dts}; max_nfev {a.max_nfev}; "
        f"ship runs {a.duration_ship:g} s after the execute, submarine runs {a.duration_submarine:g} s; noise x, y "
        f"{NOISE['x']:g} m, psi {math.degrees(NOISE['psi']):g} deg; no u, v, r logged; no prior; no calibration",
        "",
        "covered: free coefficients whose 90 % interval (estimate +- 1.645 Laplace sd) holds the truth;",
        "max|z|: largest |estimate - truth| / sd (worst: that coefficient); d2: the truth's Mahalanobis",
        "distance from the estimate (in the joint 90 % ellipsoid when d2 <= the chi^2 quantile: 'in');",
        "dt: the fit's model step (auto: after the step check's halvings); shift: the step check's largest",
        "shift, sd; P80: the chance that a calibrated posterior with the fit's covariance covers >= 80 % of the",
        "coefficients (errors drawn from N(0, cov)); wall: the fit (identify), s",
        "",
        f"{'vessel':10s} {'seed':>4s} {'dt':>7s} {'Hz':>4s} {'inputs':7s} {'covered':>8s} {'max|z|':>7s} "
        f"{'worst':>8s} {'d2':>7s} {'joint':>5s} {'step':>6s} {'shift':>6s} {'P80':>5s} {'wall s':>7s}",
    ]
    print("\n".join(lines), flush=True)
    rows = []
    for vessel in vessels:
        for seed in seeds:
            veh, free, truth, runs, noise = vessel_runs(vessel, seed, a)
            for step in steps:
                for hz in rates:
                    train = logs(runs, hz, noise)
                    for inputs in modes:
                        options = dataclasses.replace(fit_options(vessel, step, inputs, a.max_nfev), free=free)
                        r = coverage(veh, free, truth, train, options)
                        rows.append({"vessel": vessel, "step": step, "hz": hz, "inputs": inputs, **r})
                        frac = f"{round(r['covered'] * len(free))}/{len(free)}"
                        lines.append(
                            f"{vessel:10s} {seed:4d} {step:>7s} {hz:4g} {inputs:7s} "
                            f"{frac:>8s} {r['zmax']:7.2f} {r['worst']:>8s} "
                            f"{r['d2']:7.2f} {'in' if r['joint'] else 'out':>5s} {r['dt']:6.3g} {r['shift_sd']:6.2f} {r['p_target']:5.2f} "
                            f"{r['wall']:7.1f}"
                        )
                        print(lines[-1], flush=True)
    table = summary(rows, vessels, steps, modes, rates)
    met = {
        (v, st, m): all(r["covered"] >= 0.8 for r in rows if (r["vessel"], r["step"], r["inputs"]) == (v, st, m))
        for v in vessels
        for st in steps
        for m in modes
    }
    joint = {
        (v, st, m): [r["joint"] for r in rows if (r["vessel"], r["step"], r["inputs"]) == (v, st, m)]
        for v in vessels
        for st in steps
        for m in modes
    }
    calibrated = {
        key: (
            sum(r["covered"] >= 0.8 for r in sel),
            sum(r["p_target"] for r in sel),
            float(np.prod([r["p_target"] for r in sel])),
            len(sel),
        )
        for key in joint
        for sel in [[r for r in rows if (r["vessel"], r["step"], r["inputs"]) == key]]
    }
    lines += [
        "",
        "summary by log rate: covered fraction, mean over seeds (max |z| over seeds), fits with the truth in the",
        "joint 90 % ellipsoid (dt default: 0.2 s ship, 0.5 s submarine)",
        "",
        *table,
        "",
        "target (>= 80 % covered in every fit at every rate): "
        + "; ".join(f"{v} dt {st} {m} {'met' if ok else 'not met'}" for (v, st, m), ok in met.items()),
        "joint 90 % ellipsoid holds the truth (expected 90 % of fits): "
        + "; ".join(f"{v} dt {st} {m} {sum(j)}/{len(j)}" for (v, st, m), j in joint.items()),
        "",
        "the target under a calibrated posterior (each fit's errors drawn from its own covariance): fits meeting it",
        "observed / expected, and the chance that every fit meets it:",
        *(
            f"  {v} dt {st} {m}: {obs}/{n} observed, {exp:.1f}/{n} expected, all {n} with probability {pall:.2g}"
            for (v, st, m), (obs, exp, pall, n) in calibrated.items()
        ),
        "",
        "wall per fit, s (median over fits): "
        + "; ".join(
            f"{v} {st} {m} {np.median([r['wall'] for r in rows if (r['vessel'], r['step'], r['inputs']) == (v, st, m)]):.1f}"
            for v in vessels
            for st in steps
            for m in modes
        ),
        f"wall {time.perf_counter() - t_all:.0f} s",
    ]
    text = "\n".join(lines)
    print("\n".join(lines[-(len(table) + 8) :]))
    if a.out:
        Path(a.out).write_text(text + "\n")
        print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
