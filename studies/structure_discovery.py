"""Structure-discovery benchmark: hide a term of the library (or nothing, or an effect that is not a
force) in synthetic data, run the gap diagnosis with discovery, and score whether discovery names
what is missing.

Method
------
- Ship cases: the packaged KVLCC2 model with a hidden extra hull term (``Nabsdr``: a yaw moment in
  ``|delta|``, port/starboard asymmetric; ``N0``: a constant yaw moment; ``Nrrr``: cubic yaw
  damping; ``gRm``: the rudder's flow-straightening coefficient gamma_R for beta_R < 0 at 0.3
  while the model ties it to ``gR`` 0.5, a tied coefficient the library unties), closed-loop zigzags of ``bayesid.models.ship.trials`` (two training runs, three
  held-out runs of other angles, 150 s after the execute, 10 Hz, 1 cm / 0.05 deg noise and
  2 mm/s, 0.02 deg/s on the velocity log), with and without the velocity log.
- Submarine cases: NPS AUV II with a hidden ``Nvv`` (yaw moment in v^2), the user-shaped tracks of
  the gap tests (5 Hz, 0.2 m / 0.2 deg noise, zigzag, PRBS, turning circle; two training and three
  held-out runs), with and without the velocity log.
- Controls (nothing hidden) and effects that are not forces: the rudder log running 1 s late (a
  clock skew) and a 3 deg rudder backlash between the logged and the acting rudder angle.
- The diagnosis sees the tracks, the nominal vehicle and its free coefficients; no catalogue
  candidates (the benchmark isolates discovery), 60 s (ship) or 30 s (submarine) windows, the
  ``auto`` start rule.
- Each case is run ``--repeats`` times (3) with other noise and, for the submarine, other
  manoeuvre draws.
- Scores: a hidden term is *named* when it, or a member of its collinear group, is kept; its
  inclusion probability is the group's. A hidden-term case is *clear* when the base model's
  held-out gap is significant (verdict not ``none``): only there can any search see the term. A
  control or a non-force case is *clean* when no term is kept.

    python studies/structure_discovery.py [--quick] [--out DIR] [--seed N] [--repeats N]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SHIP_NOISE = {"x": 0.01, "y": 0.01, "psi": math.radians(0.05), "u": 0.002, "v": 0.002, "r": math.radians(0.02)}
#: (rudder angle deg, check heading deg): two training and three held-out zigzags
SHIP_RUNS = ((20, 20), (-10, 10), (15, 10), (-25, 5), (10, 5))
CASES = [
    {"name": "ship Nabsdr, velocity log", "family": "ship", "hidden": {"Nabsdr": 0.002}, "velocity_log": True},
    {"name": "ship Nabsdr, no velocity log", "family": "ship", "hidden": {"Nabsdr": 0.002}, "velocity_log": False},
    {"name": "ship N0, velocity log", "family": "ship", "hidden": {"N0": 0.001}, "velocity_log": True},
    {"name": "ship N0, no velocity log", "family": "ship", "hidden": {"N0": 0.001}, "velocity_log": False},
    {"name": "ship Nrrr, velocity log", "family": "ship", "hidden": {"Nrrr": -0.03}, "velocity_log": True},
    {"name": "ship control, velocity log", "family": "ship", "hidden": {}, "velocity_log": True},
    {"name": "ship control, no velocity log", "family": "ship", "hidden": {}, "velocity_log": False},
    {"name": "ship rudder clock skew 1 s", "family": "ship", "hidden": {}, "velocity_log": True, "nonforce": "skew"},
    {
        "name": "ship rudder backlash 3 deg",
        "family": "ship",
        "hidden": {},
        "velocity_log": True,
        "nonforce": "backlash",
    },
    {"name": "submarine Nvv, velocity log", "family": "submarine", "hidden": {"Nvv": 0.01}, "velocity_log": True},
    {"name": "submarine Nvv, no velocity log", "family": "submarine", "hidden": {"Nvv": 0.01}, "velocity_log": False},
    {"name": "submarine control, no velocity log", "family": "submarine", "hidden": {}, "velocity_log": False},
    {"name": "ship gRm 0.3 (gR 0.5), velocity log", "family": "ship", "hidden": {"gRm": 0.3}, "velocity_log": True},
    {"name": "ship gRm 0.3 (gR 0.5), no velocity log", "family": "ship", "hidden": {"gRm": 0.3}, "velocity_log": False},
]
QUICK = (0, 5)


def ship_tracks(hidden: dict, velocity_log: bool, rng, duration: float):
    """KVLCC2 zigzags with ``hidden`` terms (module docstring)."""
    from bayesid.data.track import Track
    from bayesid.models import ship
    from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial

    kv = ship.load_ship("kvlcc2_7m")
    truth = kv.with_coefficients(hidden) if hidden else kv
    speed, rpm = propulsion_point(truth, 1.179)
    out, clock = [], 7200.0
    for angle, check in SHIP_RUNS:
        tr = simulate_trial(
            truth, "zigzag", angle, check_deg=check, speed=speed, rpm=rpm, options=TrialOptions(duration=duration)
        ).track
        keep = ("x", "y", "psi", "u", "v", "r") if velocity_log else ("x", "y", "psi")
        data = {k: np.asarray(tr[k], float) + rng.normal(0, SHIP_NOISE[k], tr.n_samples) for k in keep}
        data.update(delta_r=np.asarray(tr["delta_r"], float), n=np.asarray(tr["n"], float))
        out.append(Track(tr.t + clock, data, name=f"z{angle}_{check}"))
        clock += tr.t[-1] + 60.0
    return kv, list(kv.free), out[:2], out[2:]


def submarine_tracks(hidden: dict, velocity_log: bool, seed: int, duration: float):
    """NPS AUV II user-shaped tracks with ``hidden`` terms."""
    from bayesid.data.track import Track
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models.world import LogOptions, world_track

    veh = load_vehicle("nps_auv2")
    truth = veh.with_coefficients(hidden) if hidden else veh
    rng = np.random.default_rng(seed)
    noise = {"x": 0.2, "y": 0.2, "psi": math.radians(0.2), "u": 0.02, "v": 0.02, "r": math.radians(0.1)}
    kinds = [
        lambda: mv.zigzag(veh, 20.0, dt=0.1, duration=duration),
        lambda: mv.prbs(veh, 15.0, duration=duration, rng=np.random.default_rng(seed)),
        lambda: mv.zigzag(veh, 10.0, dt=0.1, duration=duration, first_sign=-1),
        lambda: mv.turning_circle(veh, 15.0, dt=0.1, duration=duration),
        lambda: mv.multisine(veh, 15.0, duration=duration),
    ]
    logged = ("x", "y", "psi", "delta_r", "delta_s", "delta_b", "n")
    out, clock = [], 1234.5
    for i, make in enumerate(kinds):
        m = make()
        tr = world_track(truth, m, {}, rng, LogOptions(noise=noise, sample_every=2, hold_inputs=True))
        keep = {k: v for k, v in tr.data.items() if velocity_log or k in logged}
        out.append(Track(tr.t + clock, keep, name=f"{'train' if i < 2 else 'held'}{i}_{m.name}", meta=tr.meta))
        clock += duration + 100.0
    return veh, ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"], out[:2], out[2:]


def nonforce(tracks: list, kind: str) -> list:
    """The logged rudder of each track distorted by an effect that is not a force."""
    from bayesid.data.track import Track

    out = []
    for tr in tracks:
        d = dict(tr.data)
        x = np.asarray(tr["delta_r"], float)
        if kind == "skew":  # the rudder log runs 1 s late
            d["delta_r"] = np.interp(tr.t - 1.0, tr.t, x)
        else:  # backlash: the logged angle follows the acting one through a 3 deg dead band
            b, y = math.radians(3.0), np.empty_like(x)
            y[0] = x[0]
            for i in range(1, x.size):
                y[i] = min(max(y[i - 1], x[i] - b), x[i] + b)
            d["delta_r"] = y
        out.append(Track(tr.t, d, name=tr.name, meta=tr.meta))
    return out


def run_case(case: dict, seed: int, quick: bool) -> dict:
    """One case: data, the diagnosis with discovery, and its score."""
    from bayesid.analysis.gap import DiagnoseOptions, diagnose
    from bayesid.analysis.gap.discovery import DiscoveryOptions

    rng = np.random.default_rng(seed)
    if case["family"] == "ship":
        veh, free, train, held = ship_tracks(case["hidden"], case["velocity_log"], rng, 100.0 if quick else 150.0)
        window = 60.0
    else:
        veh, free, train, held = submarine_tracks(case["hidden"], case["velocity_log"], seed, 100.0 if quick else 150.0)
        window = 30.0
    if case.get("nonforce"):
        train, held = nonforce(train, case["nonforce"]), nonforce(held, case["nonforce"])
    nfev = 10 if quick else 40
    t0 = time.perf_counter()
    d = diagnose(
        veh,
        free,
        train,
        held,
        DiagnoseOptions(candidates=(), window_s=window, max_nfev=nfev, discover=DiscoveryOptions(max_nfev=nfev)),
        rng=np.random.default_rng(seed),
    )
    D = d.discovery.to_dict() if d.discovery else {}
    kept = [r for r in D.get("discovered", []) if r["kept"]]
    found = D.get("found", [])
    hidden = list(case["hidden"])
    named = None
    if hidden:
        h = hidden[0]
        hit = next((r for r in kept if r["term"] in found and h in [r["term"], *r["group"]]), None)
        named = {
            "named": hit is not None,
            "term": None if hit is None else hit["term"],
            "group_inclusion_probability": None if hit is None else hit["group_inclusion_probability"],
            "coefficient": None if hit is None else hit.get("coefficient"),
            "truth": case["hidden"][h],
            "inclusion_probability_of_hidden": D.get("inclusion", {}).get(h, 0.0) if D else None,
        }
    return {
        "case": case["name"],
        "family": case["family"],
        "hidden": case["hidden"],
        "velocity_log": case["velocity_log"],
        "nonforce": case.get("nonforce"),
        "verdict": d.verdict,
        "significant_gap": d.significant_gap,
        "heldout_rms_base_m": d.gap_before["heldout_rms_m"],
        "noise_floor_m": d.noise_floor["heldout_rms_m"],
        "base_check": d.base_check,
        "discovery_run": bool(D),
        "found": found,
        "heldout_rms_after_discovery_m": D.get("heldout_rms_after_m"),
        "discovered": [
            {
                k: r.get(k)
                for k in (
                    "term",
                    "group",
                    "inclusion_probability",
                    "group_inclusion_probability",
                    "coefficient",
                    "heldout_rms_after_m",
                    "delta_bic",
                    "window_p_value",
                    "kept",
                    "reason",
                )
            }
            for r in D.get("discovered", [])
        ],
        "score": named,
        "clean": not found if not hidden else None,
        "seconds": time.perf_counter() - t0,
        "discovery_seconds": D.get("seconds"),
    }


def _count(summary: dict, log: str) -> str:
    """``"9 of 11"``: clear hidden-term cases named at inclusion >= 0.9 with or without the log."""
    c = summary["clear_hidden_by_log"][log]
    return f"{c['named_at_0.9']} of {c['cases']}"


def write_report(out: Path, rows: list, args) -> dict:
    from bayesid.report import fmt, md_table

    hidden = [r for r in rows if r["score"]]
    clean = [r for r in rows if r["clean"] is not None]
    clear = [r for r in hidden if r["significant_gap"]]

    def named(r):
        return bool(r["score"]["named"] and (r["score"]["group_inclusion_probability"] or 0) >= 0.9)

    summary = {
        "clear_hidden_cases": len(clear),
        "clear_hidden_named_at_0.9": sum(named(r) for r in clear),
        # the target holds with and without the velocity log: each counted on its own
        "clear_hidden_by_log": {
            log: {"named_at_0.9": sum(named(r) for r in sub), "cases": len(sub)}
            for log, sub in (
                ("velocity_log", [r for r in clear if r["velocity_log"]]),
                ("no_velocity_log", [r for r in clear if not r["velocity_log"]]),
            )
        },
        "hidden_named": sum(r["score"]["named"] for r in hidden),
        "hidden_named_at_0.9": sum(named(r) for r in hidden),
        "hidden_cases": len(hidden),
        "clean": sum(r["clean"] for r in clean),
        "clean_cases": len(clean),
    }
    table = [
        [
            r["case"],
            r["verdict"],
            f"{fmt(r['heldout_rms_base_m'])} / {fmt(r['noise_floor_m'])}",
            fmt(r["heldout_rms_after_discovery_m"]),
            (
                f"{r['score']['term'] or '-'} ({fmt(r['score']['group_inclusion_probability'])}); coef "
                f"{fmt(r['score']['coefficient'])} vs {fmt(r['score']['truth'])}"
                if r["score"]
                else ("clean" if r["clean"] else "term kept: " + ", ".join(r["found"]))
            ),
            fmt(r["seconds"]),
        ]
        for r in rows
    ]
    text = [
        "# Structure discovery on synthetic data with a hidden term",
        "",
        "**Quick run** (smoke test)." if args.quick else "Full run.",
        "",
        __doc__.split("Method\n------\n")[1].split("\n    python")[0],
        "",
        f"Clear hidden-term cases (significant gap) named with group inclusion probability >= 0.9: "
        f"{summary['clear_hidden_named_at_0.9']} of {summary['clear_hidden_cases']} "
        f"(with the velocity log {_count(summary, 'velocity_log')}, without it {_count(summary, 'no_velocity_log')}). "
        f"Hidden terms named (kept, the term or its collinear group): {summary['hidden_named']} of "
        f"{summary['hidden_cases']}; with group inclusion probability >= 0.9: {summary['hidden_named_at_0.9']} of "
        f"{summary['hidden_cases']}. Controls and non-force effects without a kept term: {summary['clean']} of "
        f"{summary['clean_cases']}.",
        "",
        md_table(
            [
                "case",
                "verdict",
                "held-out RMS base / floor (m)",
                "after discovery (m)",
                "named (group p); coefficient",
                "s",
            ],
            table,
        ),
        "",
        "Every refitted term with its numbers is in results.json.",
        "",
    ]
    (out / "report.md").write_text("\n".join(text))
    return summary


def main() -> int:
    import matplotlib

    matplotlib.use("Agg")  # the study writes its figures, it never shows them
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two cases, short runs, few iterations (a smoke test)")
    ap.add_argument("--out", default="reports/structure_discovery")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--repeats", type=int, default=3, help="runs of each case with other noise (default 3)")
    args = ap.parse_args()
    from bayesid.report import write_json, write_manifest

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    cases = [CASES[i] for i in QUICK] if args.quick else CASES
    repeats = 1 if args.quick else max(1, args.repeats)
    rows = []
    for i, case in enumerate(c for c in cases for _ in range(repeats)):
        r = run_case(case, args.seed + i, args.quick)
        r["repeat"] = i % repeats
        print(f"{r['case']}: {r['verdict']} ({r['seconds']:.0f} s)", flush=True)
        rows.append(r)
    summary = write_report(out, rows, args)
    write_json(out / "results.json", {"summary": summary, "cases": rows, "quick": bool(args.quick)})
    write_manifest(out, seed=args.seed, quick=args.quick, t_start=t_start)
    print(summary)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
