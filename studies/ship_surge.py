"""A ship's surge in the diagnosis (issue 67): hide a surge structure in a synthetic KVLCC2, train
on zigzags, hold out turns and a pull-out, and score what ``bayesid diagnose`` names and how far the
held-out excess shrinks once it is added.

Method
------
- Truth: the packaged KVLCC2 7 m model (``bayesid/vehicles/kvlcc2_7m.toml``) with one hidden
  structure: a fourth-order hull surge term (``Xvvvv`` 2.0, ``Xvvrr`` 0.3: the MMG hull surge
  polynomial's fourth-order terms, Yasukawa & Yoshimura 2015, J. Mar. Sci. Technol. 20:37-52,
  Sec. 2.2), the rudder's drag in the turn (the steering resistance deduction ``tR`` 0.387 -> 0,
  which the model holds at its captive-test value: no term of the library has its name, a
  surrogate is the best discovery can do), a yaw term (``Nrrr`` -0.03: a miss that is not in the
  surge, whose search must stay in Y and N) and nothing (the control).
- Runs (``bayesid.models.ship.trials``, rudder at 15.8 deg/s, 2 Hz, 2 cm / 0.1 deg noise and
  5 mm/s, 0.05 deg/s on the velocity log): three zigzags to train (10/10 port, 20/20 starboard,
  35/35 port, 200 s each), two 35 deg turning circles and a 20 deg pull-out held out.
- Each case with and without the velocity log (u, v, r), diagnosed by ``bayesid diagnose`` as a
  user runs it: the ship catalogue (current, delay, sensor lag: the runs log no wind), 60 s
  scoring windows, two alternatives per degree of freedom, no design, ``--max-nfev 30``.
- Scores: a hidden term is *named* when it is kept, or among the alternatives of a kept term; a
  case is *clear* when the base model's held-out gap is significant (verdict not ``none``); a
  control is *clean* when its verdict is ``none`` (no gap beyond the noise floor: nothing kept,
  no effect named, nothing left unexplained). The held-out excess shrink is
  ``(before - after) / (before - floor)`` of the held-out RMS position error.

    python studies/ship_surge.py [--quick] [--out DIR] [--seed N]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

NOISE = {"x": 0.02, "y": 0.02, "psi": math.radians(0.1), "u": 0.005, "v": 0.005, "r": math.radians(0.05)}
#: (kind, rudder deg, name): training zigzags, held-out turns and pull-out (names ending "_held")
RUNS = (
    ("zigzag", 10.0, "z10p"),
    ("zigzag", -20.0, "z20s"),
    ("zigzag", 35.0, "z35p"),
    ("turn", 35.0, "t35p_held"),
    ("turn", -35.0, "t35s_held"),
    ("pull_out", 20.0, "po20p_held"),
)
STRUCTURES = (
    {"name": "Xvvvv", "hidden": {"Xvvvv": 2.0}, "term": "Xvvvv"},
    {"name": "Xvvrr", "hidden": {"Xvvrr": 0.3}, "term": "Xvvrr"},
    {"name": "rudder drag (tR 0)", "hidden": {"tR": 0.0}, "term": None},
    {"name": "yaw Nrrr", "hidden": {"Nrrr": -0.03}, "term": "Nrrr"},
    {"name": "control", "hidden": {}, "term": None},
)
QUICK = (0,)


def tracks(hidden: dict, velocity_log: bool, seed: int, duration: float, folder: Path) -> dict:
    """The runs of a truth with ``hidden`` written as CSV files: ``{name: path}``."""
    from bayesid.data.track import Track, write_csv
    from bayesid.models.ship import load_ship
    from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial

    base = load_ship("kvlcc2_7m")
    truth = base.with_coefficients(hidden) if hidden else base
    speed, rpm = propulsion_point(base, 1.179)
    rng = np.random.default_rng(seed)
    out = {}
    for kind, angle, name in RUNS:
        hold = duration / 2 if kind == "pull_out" else None
        opts = TrialOptions(dt=0.1, sample_every=5, rudder_rate_deg_s=15.8, hold=hold, duration=duration)
        tr = simulate_trial(truth, kind, angle, speed=speed, rpm=rpm, options=opts).track
        cols = ("x", "y", "psi", "u", "v", "r") if velocity_log else ("x", "y", "psi")
        data = {k: np.asarray(tr[k], float) + rng.normal(0, NOISE[k], tr.t.size) for k in cols}
        data.update(delta_r=np.asarray(tr["delta_r"], float), n=np.asarray(tr["n"], float))
        out[name] = folder / f"{name}.csv"
        write_csv(Track(np.asarray(tr.t, float), data, name=name, meta=tr.meta), out[name])
    return out


def run_case(structure: dict, velocity_log: bool, seed: int, quick: bool) -> dict:
    """One diagnosis and its scores."""
    from bayesid import cli

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        paths = tracks(structure["hidden"], velocity_log, seed, 120.0 if quick else 200.0, Path(d))
        train = [str(p) for n, p in paths.items() if not n.endswith("_held")]
        held = [str(p) for n, p in paths.items() if n.endswith("_held")]
        argv = ["-q", "diagnose", "--vehicle", "kvlcc2_7m", "--train", *train, "--heldout", *held]
        argv += ["--score-window", "60", "--max-nfev", "10" if quick else "30", "--no-design"]
        argv += ["--out", str(Path(d) / "diag")]
        rc = cli.main(argv)
        if rc != 0:
            raise RuntimeError(f"bayesid diagnose failed (exit {rc}) on {structure['name']}")
        D = json.loads((Path(d) / "diag" / "diagnosis.json").read_text())
    disc = D.get("discovery") or {}
    found = list(disc.get("found") or [])
    alts = {k: [a["term"] for a in (disc.get("alternatives") or {}).get(k, [])] for k in found}
    term = structure["term"]
    named = term is not None and (term in found or any(term in v for v in alts.values()))
    before = D["gap_before"]["heldout_rms_m"]
    after = (D.get("gap_discovered") or {}).get("heldout_rms_m") or D["gap_after"]["heldout_rms_m"]
    floor = D["noise_floor"]["heldout_rms_m"]
    chosen = list(D.get("effects_added") or [])
    return {
        "case": f"{structure['name']}, {'velocity log' if velocity_log else 'no velocity log'}",
        "structure": structure["name"],
        "hidden": structure["hidden"],
        "term": term,
        "velocity_log": velocity_log,
        "verdict": D["verdict"],
        "dominant_channel": D["where"].get("dominant_channel"),
        "routed": D["where"].get("discovery_routed"),
        "dofs": (disc.get("settings") or {}).get("dofs"),
        "found": found,
        "alternatives": alts,
        "effects": chosen,
        "named": bool(named),
        "wrong_alone": bool(found) and not named and term is not None and all(not v for v in alts.values()),
        "clear": D["verdict"] != "none",
        "heldout_rms_before_m": before,
        "heldout_rms_after_m": after,
        "floor_m": floor,
        "excess_shrink": (before - after) / (before - floor) if before > floor else None,
        "seconds": time.perf_counter() - t0,
    }


def summarise(rows: list) -> dict:
    """The issue's scores over the cases."""
    hidden = [r for r in rows if r["term"] is not None]
    clear = [r for r in hidden if r["clear"]]
    controls = [r for r in rows if not r["hidden"]]
    surge = [r for r in clear if r["term"].startswith("X")]
    shrink = [r["excess_shrink"] for r in rows if r["hidden"] and r["found"] and r["excess_shrink"] is not None]
    return {
        "clear_cases": len(clear),
        "named_in_clear": sum(r["named"] for r in clear),
        "wrong_term_alone": sum(r["wrong_alone"] for r in clear),
        "surge_cases_routed_to_x": sum("X" in (r["dofs"] or []) for r in surge),
        "surge_clear_cases": len(surge),
        "yaw_cases_routed_to_x": sum("X" in (r["dofs"] or []) for r in rows if r["structure"] == "yaw Nrrr"),
        "controls_clean": sum(r["verdict"] == "none" for r in controls),
        "controls": len(controls),
        "cases_with_a_kept_term": len(shrink),
        "median_excess_shrink": float(np.median(shrink)) if shrink else None,
    }


def reading(rows: list) -> list:
    """What the cases say, from their numbers: the routing, the surrogates, the controls."""
    from bayesid.report.markdown import fmt

    lines = ["## Reading", ""]
    routed = [r for r in rows if "X" in (r["dofs"] or [])]
    for r in routed:
        kept = ", ".join(r["found"]) or "no term"
        lines.append(
            f"- {r['case']}: {r['routed'] or 'routed into X'}; discovery kept {kept}, the held-out "
            f"excess shrank by {fmt(r['excess_shrink'])}"
            + ("" if r["named"] else f"; the hidden {r['term']} was neither kept nor among the alternatives")
            + "."
        )
    quiet = [r for r in rows if r["term"] and r["term"].startswith("X") and "X" not in (r["dofs"] or []) and r["clear"]]
    for r in quiet:
        lines.append(
            f"- {r['case']}: the dominant channel was {r['dominant_channel']}, not the speed, so the search stayed in "
            "Y and N, and found nothing."
        )
    for r in rows:
        if not r["hidden"] and r["verdict"] != "none":
            lines.append(
                f"- {r['case']}: nothing hidden, yet a gap: held-out RMS {fmt(r['heldout_rms_before_m'])} m against a "
                f"noise floor of {fmt(r['floor_m'])} m ({fmt(r['heldout_rms_before_m'] / r['floor_m'])} x): the zigzag-"
                "trained base model does not predict the turns within the floor, with nothing missing from its form: "
                "the zigzags do not determine the turn, or the floor (window starts fitted to 2 Hz positions) "
                "underestimates the error a prediction makes."
            )
    return [*lines, ""]


def write_report(out: Path, rows: list, summary: dict, args) -> None:
    from bayesid.report.markdown import fmt, md_table

    lines = [
        "# A ship's surge in the diagnosis (synthetic KVLCC2)",
        "",
        "`python studies/ship_surge.py" + (" --quick" if args.quick else "") + "`",
        "",
        __doc__.split("Method\n------\n")[1].split("\n    python")[0].strip(),
        "",
        "## Scores",
        "",
        f"- Hidden terms named (kept, or among a kept term's alternatives) in {summary['named_in_clear']} of "
        f"{summary['clear_cases']} clear cases; a wrong term alone in {summary['wrong_term_alone']}.",
        f"- Surge cases whose search went into X: {summary['surge_cases_routed_to_x']} of {summary['surge_clear_cases']} "
        "(the routing needs the speed u: without a velocity log there is no u channel).",
        f"- Yaw cases routed into X: {summary['yaw_cases_routed_to_x']} (the search stays in Y and N).",
        f"- Controls clean (verdict none): {summary['controls_clean']} of {summary['controls']}.",
        f"- Median held-out excess shrink of the {summary['cases_with_a_kept_term']} hidden cases where a term was "
        f"kept: {fmt(summary['median_excess_shrink'])} (the issue's target: 0.5 on the turns; where nothing was kept "
        "it is 0).",
        "",
        *reading(rows),
        "## Cases",
        "",
        md_table(
            [
                "case",
                "verdict",
                "dominant channel",
                "searched",
                "kept (alternatives)",
                "named",
                "held-out RMS (m)",
                "shrink",
            ],
            [
                [
                    r["case"],
                    r["verdict"],
                    r["dominant_channel"] or "-",
                    ",".join(r["dofs"] or []) or "-",
                    "; ".join(f"{k} ({', '.join(v) or 'none'})" for k, v in r["alternatives"].items()) or "-",
                    "yes" if r["named"] else ("-" if r["term"] is None else "no"),
                    f"{fmt(r['heldout_rms_before_m'])} -> {fmt(r['heldout_rms_after_m'])} (floor {fmt(r['floor_m'])})",
                    fmt(r["excess_shrink"]),
                ]
                for r in rows
            ],
        ),
        "",
    ]
    (out / "report.md").write_text("\n".join(lines))


def main() -> int:
    import matplotlib

    matplotlib.use("Agg")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one structure, short runs, few iterations (a smoke test)")
    ap.add_argument("--out", default="reports/ship_surge")
    ap.add_argument("--seed", type=int, default=67)
    args = ap.parse_args()
    from bayesid.report import write_json, write_manifest

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    structures = [STRUCTURES[i] for i in QUICK] if args.quick else STRUCTURES
    rows = []
    for i, s in enumerate(structures):
        for log in (True,) if args.quick else (True, False):
            r = run_case(s, log, args.seed + i, args.quick)
            print(f"{r['case']}: {r['verdict']} ({r['seconds']:.0f} s)", flush=True)
            rows.append(r)
    summary = summarise(rows)
    write_report(out, rows, summary, args)
    write_json(out / "results.json", {"summary": summary, "cases": rows, "quick": bool(args.quick)})
    write_manifest(out, seed=args.seed, quick=args.quick, t_start=t_start)
    print(summary)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
