"""A ship's surge in the diagnosis (issue 67): hide a surge structure in a synthetic KVLCC2, train
on zigzags, hold out turns and a pull-out, and score what ``bayesid diagnose`` names and how far the
held-out excess shrinks once it is added.

Method
------
- Truth: the packaged KVLCC2 7 m model (``bayesid/vehicles/kvlcc2_7m.toml``) with one hidden
  structure: a fourth-order hull surge term (``Xvvvv`` 2.0, ``Xvvrr`` 0.3: the MMG hull surge
  polynomial's fourth-order terms, Yasukawa & Yoshimura 2015, J. Mar. Sci. Technol. 20:37-52,
  Sec. 2.2); the rudder's drag in the turn (the steering resistance deduction ``tR`` 0.387 -> 0,
  which the model holds at its captive-test value; the catalogue's ``rudder_resistance``); the MMG
  2015 wake in a turn (their eq. 16 with their KVLCC2 values C1 2.0, C2 1.6, 1.1, in place of the
  model's ``wP exp(-4 beta_P^2)``; the catalogue's ``wake_in_turn``); the thrust deduction
  (``tP`` 0.22 -> 0.32; ``thrust_deduction``); a propulsion-point shift (``wP`` 0.40 -> 0.30:
  the base model fits ``wP``, so it should absorb it: a control that must stay clean); a yaw term
  (``Nrrr`` -0.03: a miss that is not in the surge, whose search must stay in Y and N), nothing
  (the control) and a model form: MMG 2015's coupling speed ``U`` for the hull's coupling terms in
  place of the package's ``Ut`` (``[form] coupling_speed = "U"``; the catalogue's ``coupling_speed``).
- Runs (``bayesid.models.ship.trials``, rudder at 15.8 deg/s, 2 Hz, 2 cm / 0.1 deg noise and
  5 mm/s, 0.05 deg/s on the velocity log): three zigzags to train (10/10 port, 20/20 starboard,
  35/35 port, 200 s each), two 35 deg turning circles and a 20 deg pull-out held out.
- Each case with and without the velocity log (u, v, r), diagnosed by ``bayesid diagnose`` as a
  user runs it: the ship catalogue less the wind (the runs log none) and less the shifts of ``wP``
  and ``Xuu``, which the base model fits (current, delay, wake in a turn, coupling speed, rudder
  resistance, thrust deduction, sensor lag), 60 s scoring windows, two alternatives per degree of freedom, no
  design, ``--max-nfev 30``. The noise floor is the diagnosis's default (``--floor
  coefficients``): a model of the right form at the measured noise, its coefficients drawn from
  the base fit's uncertainty. With a perfect model's floor (``--floor noise``, the rule of this
  report at 2aa0e3b) the two no-log controls read ``unexplained`` at 4.5-5 x that floor.
- Scores: a hidden term is *named* when it is kept, or among the alternatives of a kept term; a
  hidden effect when the verdict names it (cause or contributor); a case is *clear* when the base
  model's held-out gap is significant (verdict not ``none``); a *wrong name alone* is a kept term
  or named effect that is not the hidden one, with the hidden one neither named nor among the
  alternatives; a control is *clean* when its verdict is ``none`` (no gap beyond the noise floor:
  nothing kept, no effect named, nothing left unexplained). The held-out excess shrink is
  ``(before - after) / (before - floor)`` of the held-out RMS position error, ``after`` the final
  model's (effects and kept terms added).
- Calibration: the nothing-hidden control diagnosed at ``--calibration`` (10) further seeds with and
  without the velocity log. A verdict other than ``none`` there is a false alarm of the floor band
  (held-out RMS above 1.5 x the floor): the share of ``none`` is the band's coverage on runs with
  nothing missing. Each false alarm is diagnosed again with the truth's coefficients (only ``wP``
  fitted) and with the rudder read at the gear's rate (``--inputs rate``), to say what the floor
  leaves out.

    python studies/ship_surge.py [--quick] [--out DIR] [--seed N] [--calibration N] [--render]
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
#: hidden structures: ``term`` (a hull term of the library) or ``effect`` (a catalogue effect) is what
#: the diagnosis should name; ``control``: nothing it should name (the base model holds or absorbs it)
STRUCTURES = (
    {"name": "Xvvvv", "hidden": {"Xvvvv": 2.0}, "term": "Xvvvv"},
    {"name": "Xvvrr", "hidden": {"Xvvrr": 0.3}, "term": "Xvvrr"},
    {"name": "rudder drag (tR 0)", "hidden": {"tR": 0.0}, "effect": "rudder_resistance"},
    {"name": "wake in a turn (MMG 2015)", "hidden": {"C1": 2.0, "C2": 1.6, "C2m": 1.1}, "effect": "wake_in_turn"},
    {"name": "thrust deduction (tP 0.32)", "hidden": {"tP": 0.32}, "effect": "thrust_deduction"},
    {"name": "propulsion point (wP 0.30)", "hidden": {"wP": 0.30}, "control": True},
    {"name": "yaw Nrrr", "hidden": {"Nrrr": -0.03}, "term": "Nrrr"},
    {"name": "control", "hidden": {}, "control": True},
    {"name": "coupling speed (MMG's U)", "hidden": {}, "form": {"coupling_speed": "U"}, "effect": "coupling_speed"},
)
QUICK = (0,)
#: The nothing-hidden control diagnosed at this many further seeds, with and without the velocity
#: log: how often the floor band (held-out RMS within ``none_ratio`` x the floor) holds on runs with
#: nothing missing, the band's coverage
CALIBRATION_SEEDS = 10
#: Offset of the calibration seeds from ``--seed`` (apart from the cases' seeds)
CALIBRATION_SEED_OFFSET = 1000


def tracks(hidden: dict, velocity_log: bool, seed: int, duration: float, folder: Path, form=None) -> dict:
    """The runs of a truth with ``hidden`` coefficients and ``form`` choices (a ship file's
    ``[form]``) written as CSV files: ``{name: path}``."""
    from bayesid.data.track import Track, write_csv
    from bayesid.models.ship import load_ship
    from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial

    base = load_ship("kvlcc2_7m")
    truth = base.with_coefficients(hidden) if hidden else base
    truth = truth.with_form(**form) if form else truth
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


def run_case(
    structure: dict, velocity_log: bool, seed: int, quick: bool, floor: str | None = None, extra: tuple = ()
) -> dict:
    """One diagnosis (``bayesid diagnose``, with ``--floor floor`` when given, else its default
    floor, and the further options ``extra``) and its scores."""
    from bayesid import cli

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        paths = tracks(
            structure["hidden"], velocity_log, seed, 120.0 if quick else 200.0, Path(d), structure.get("form")
        )
        train = [str(p) for n, p in paths.items() if not n.endswith("_held")]
        held = [str(p) for n, p in paths.items() if n.endswith("_held")]
        argv = ["-q", "diagnose", "--vehicle", "kvlcc2_7m", "--train", *train, "--heldout", *held]
        argv += ["--score-window", "60", "--max-nfev", "10" if quick else "30", "--no-design"]
        argv += ["--out", str(Path(d) / "diag")] + (["--floor", floor] if floor else []) + list(extra)
        rc = cli.main(argv)
        if rc != 0:
            raise RuntimeError(f"bayesid diagnose failed (exit {rc}) on {structure['name']}")
        D = json.loads((Path(d) / "diag" / "diagnosis.json").read_text())
    disc = D.get("discovery") or {}
    found = list(disc.get("found") or [])
    alts = {k: [a["term"] for a in (disc.get("alternatives") or {}).get(k, [])] for k in found}
    term, effect = structure.get("term"), structure.get("effect")
    chosen = list(D.get("effects_added") or [])
    named = (term is not None and (term in found or any(term in v for v in alts.values()))) or (
        effect is not None and effect in chosen
    )
    before = D["gap_before"]["heldout_rms_m"]
    after = (D.get("gap_discovered") or {}).get("heldout_rms_m") or D["gap_after"]["heldout_rms_m"]
    floor = D["noise_floor"]["heldout_rms_m"]
    ranking = [(r["effect"], r["share_of_excess"]) for r in D.get("ranking") or []]
    rows = [
        {
            k: r.get(k)
            for k in ("effect", "share_of_excess", "heldout_rms_m", "delta_bic", "window_p_value", "role", "failed_fit")
        }
        for r in D.get("ranking") or []
    ]
    return {
        "case": f"{structure['name']}, {'velocity log' if velocity_log else 'no velocity log'}",
        "structure": structure["name"],
        "hidden": structure["hidden"],
        "term": term,
        "effect": effect,
        "control": bool(structure.get("control")),
        "velocity_log": velocity_log,
        "verdict": D["verdict"],
        "dominant_channel": D["where"].get("dominant_channel"),
        "speed_from_positions_ratio": (D["where"].get("speed_from_positions") or {}).get("excess_ratio"),
        "routed": D["where"].get("discovery_routed"),
        "dofs": (disc.get("settings") or {}).get("dofs"),
        "found": found,
        "alternatives": alts,
        "effects": chosen,
        "effect_ranking": ranking,
        "effect_rows": rows,
        "named": bool(named),
        "wrong_alone": bool(found or chosen)
        and not named
        and (term or effect) is not None
        and all(not v for v in alts.values()),
        "clear": D["verdict"] != "none",
        "heldout_rms_before_m": before,
        "heldout_rms_after_m": after,
        "floor_m": floor,
        "excess_shrink": (before - after) / (before - floor) if before > floor else None,
        "seconds": time.perf_counter() - t0,
    }


def calibration(seed: int, n: int, quick: bool) -> list:
    """The nothing-hidden control at ``n`` seeds from ``seed + CALIBRATION_SEED_OFFSET``, with and
    without the velocity log: per diagnosis, its verdict and held-out RMS against its floor."""
    control = next(s for s in STRUCTURES if s["name"] == "control")
    rows = []
    for log in (True, False):
        for k in range(n):
            r = run_case(control, log, seed + CALIBRATION_SEED_OFFSET + k, quick)
            print(f"calibration {r['case']} seed {k}: {r['verdict']} ({r['seconds']:.0f} s)", flush=True)
            row = {
                "velocity_log": log,
                "seed": seed + CALIBRATION_SEED_OFFSET + k,
                "verdict": r["verdict"],
                "heldout_rms_m": r["heldout_rms_before_m"],
                "floor_m": r["floor_m"],
                "ratio": r["heldout_rms_before_m"] / r["floor_m"],
            }
            if r["verdict"] != "none":  # what the false alarm is made of
                row["probes"] = {
                    name: ratio_of(run_case(control, log, row["seed"], quick, extra=args))
                    for name, args in ALARM_PROBES.items()
                }
            rows.append(row)
    return rows


#: A false alarm of the calibration diagnosed again with the truth's coefficients (only ``wP``
#: fitted: the base model then is the truth) and with the rudder read at the gear's rate between
#: the 2 Hz samples (``--inputs rate``) in place of held: which part of the held-out error the
#: floor leaves out, the coefficients' or the input reconstruction's
ALARM_PROBES = {
    "truth, rudder held": ("--free", "wP"),
    "truth, rudder at the gear's rate": ("--free", "wP", "--inputs", "rate"),
    "fitted, rudder at the gear's rate": ("--inputs", "rate"),
}


def ratio_of(r: dict) -> dict:
    """A probe's held-out RMS, floor and their ratio."""
    return {
        "heldout_rms_m": r["heldout_rms_before_m"],
        "floor_m": r["floor_m"],
        "ratio": r["heldout_rms_before_m"] / r["floor_m"],
    }


def calibration_lines(rows: list) -> list:
    """The calibration's section of the report: the floor band's coverage on the controls."""
    from bayesid.analysis.gap.verdict import Thresholds
    from bayesid.report.markdown import fmt, md_table

    if not rows:
        return []
    band = Thresholds().none_ratio
    table = []
    for log in (True, False):
        mine = [r for r in rows if r["velocity_log"] is log]
        ratio = np.array([r["ratio"] for r in mine])
        table.append(
            [
                "velocity log" if log else "no velocity log",
                len(mine),
                sum(r["verdict"] == "none" for r in mine),
                fmt(float(np.median(ratio))),
                fmt(float(np.quantile(ratio, 0.9))),
                fmt(float(ratio.max())),
            ]
        )
    n, held = len(rows), sum(r["verdict"] == "none" for r in rows)
    alarms = [r for r in rows if r["verdict"] != "none"]
    return [
        "## The floor band on controls",
        "",
        f"The nothing-hidden control diagnosed at {n // 2} further seeds with and without the velocity log: a "
        f"verdict other than none is a false alarm of the floor band (held-out RMS above {band:g} x the floor). "
        f"The band held in {held} of {n} ({fmt(100.0 * held / n)} %).",
        "",
        md_table(["runs", "diagnoses", "verdict none", "median held-out / floor", "90th percentile", "largest"], table),
        "",
        *(
            f"- False alarm, seed {r['seed']} ({'velocity log' if r['velocity_log'] else 'no velocity log'}): "
            f"{r['verdict']}, held-out RMS {fmt(r['heldout_rms_m'])} m against {fmt(r['floor_m'])} m "
            f"({fmt(r['ratio'])} x)."
            for r in alarms
        ),
        *([""] if alarms else []),
        *_probe_lines(alarms),
    ]


def _probe_lines(alarms: list) -> list:
    """The false alarms diagnosed again (:data:`ALARM_PROBES`): held-out RMS over the floor."""
    from bayesid.report.markdown import fmt, md_table

    probed = [r for r in alarms if r.get("probes")]
    if not probed:
        return []
    names = list(ALARM_PROBES)
    table = [
        [
            r["seed"],
            "yes" if r["velocity_log"] else "no",
            fmt(r["ratio"]),
            *(fmt(r["probes"][n]["ratio"]) for n in names),
        ]
        for r in probed
    ]
    med = {n: float(np.median([r["probes"][n]["ratio"] for r in probed])) for n in names}
    return [
        "Each false alarm diagnosed again: with the truth's coefficients (only `wP` fitted, so the base model is "
        "the truth) and with the rudder read at the gear's rate between the 2 Hz samples (`--inputs rate`) in place "
        "of held (the default, which the diagnosis's own warning on these logs advises against). Held-out RMS over "
        "the floor:",
        "",
        md_table(["seed", "velocity log", "fitted, rudder held", *names], table),
        "",
        f"- Medians: the truth itself misses the held-out runs by {fmt(med[names[0]])} x its floor with the rudder held "
        f"and by {fmt(med[names[1]])} x with the gear's rate; the fitted model by {fmt(med[names[2]])} x with the gear's "
        "rate. The floor simulates its noisy copies and scores them with the same rudder reading and draws its "
        "coefficients from the noise's uncertainty alone (the Cramér-Rao bound)"
        + "".join(
            f"; {what}"
            for what, holds in (
                (
                    "it leaves out the error of reading the rudder between the samples (the truth with the rudder held, "
                    "against the truth with the rudder at the gear's rate)",
                    med[names[0]] > med[names[1]] + 0.1,
                ),
                (
                    "it leaves out the coefficients' error beyond that bound (the fitted model against the truth, "
                    "both at the gear's rate), such as the bias the input reading causes in the fit",
                    med[names[2]] > med[names[1]] + 0.1,
                ),
                ("the truth at the gear's rate is beyond the band itself", med[names[1]] > 1.5),
            )
            if holds
        )
        + ".",
        "",
    ]


def summarise(rows: list) -> dict:
    """The issue's scores over the cases."""
    hidden = [r for r in rows if not r["control"]]
    clear = [r for r in hidden if r["clear"]]
    controls = [r for r in rows if r["control"]]
    surge = [r for r in clear if (r["term"] or "").startswith("X")]
    shrink = [
        r["excess_shrink"]
        for r in rows
        if not r["control"] and (r["found"] or r["effects"]) and r["excess_shrink"] is not None
    ]
    return {
        "clear_cases": len(clear),
        "named_in_clear": sum(r["named"] for r in clear),
        "effect_clear_cases": sum(r["effect"] is not None for r in clear),
        "effects_named_in_clear": sum(r["named"] for r in clear if r["effect"] is not None),
        "wrong_term_alone": sum(r["wrong_alone"] for r in clear),
        "surge_cases_routed_to_x": sum("X" in (r["dofs"] or []) for r in surge),
        "surge_clear_cases": len(surge),
        "yaw_cases_routed_to_x": sum("X" in (r["dofs"] or []) for r in rows if r["structure"] == "yaw Nrrr"),
        "controls_clean": sum(r["verdict"] == "none" for r in controls),
        "controls_clean_cases": [r["case"] for r in controls if r["verdict"] == "none"],
        "controls": len(controls),
        "cases_with_a_kept_term_or_effect": len(shrink),
        "median_excess_shrink": float(np.median(shrink)) if shrink else None,
    }


def reading(rows: list) -> list:
    """What the cases say, from their numbers: the routing, the surrogates, the controls."""
    from bayesid.analysis.gap.verdict import Thresholds
    from bayesid.report.markdown import fmt

    lines = ["## Reading", ""]
    routed = [r for r in rows if "X" in (r["dofs"] or [])]
    for r in routed:
        kept = ", ".join(r["found"]) or "no term"
        lines.append(
            f"- {r['case']}: {r['routed'] or 'routed into X'}; discovery kept {kept}, the held-out "
            f"excess shrank by {fmt(r['excess_shrink'])}"
            + (
                ""
                if r["named"] or r["term"] is None
                else f"; the hidden {r['term']} was neither kept nor among the alternatives"
            )
            + (
                f"; the hidden effect {r['effect']} is {'named' if r['named'] else 'not named'} by the verdict"
                if r["effect"] is not None
                else ""
            )
            + "."
        )
    for r in rows:
        if r["effect"] is None or not r["clear"]:
            continue
        rank = ", ".join(f"{e} {fmt(x)}" for e, x in r["effect_ranking"][:3])
        mine = next((x for x in r.get("effect_rows") or [] if x["effect"] == r["effect"]), None)
        why = (
            f"; its training ΔBIC {fmt(mine['delta_bic'], 4)}, window test p {fmt(mine['window_p_value'])}"
            + (f", fit failed: {mine['failed_fit']}" if mine.get("failed_fit") else "")
            if mine is not None and not r["named"]
            else ""
        )
        said = (
            f"the verdict names {r['effect']}"
            if r["named"]
            else f"the verdict does not name {r['effect']} (it names {', '.join(r['effects']) or 'no effect'}{why})"
        )
        own = ""
        if mine is not None and not r["named"] and mine.get("heldout_rms_m") is not None:
            ratio = mine["heldout_rms_m"] / r["floor_m"]
            own = (
                f"; the hidden effect's own refit (the right form, fitted on the zigzags) predicts the held-out runs "
                f"at {fmt(mine['heldout_rms_m'])} m against the base model's {fmt(r['heldout_rms_before_m'])} m and "
                f"the floor's {fmt(r['floor_m'])} m ({fmt(ratio)} x the floor)"
                + (
                    f": the right form does not reach the floor band either (it removes {fmt(mine['share_of_excess'])} of the "
                    "excess): the gap on these runs is mostly not the hidden effect's, and no name is the honest answer"
                    if ratio > Thresholds().none_ratio
                    else ": the right form closes the gap; the verdict's rule, not the runs, leaves it unnamed"
                )
            )
        lines.append(
            f"- {r['case']}: {said}; the catalogue's best shares of the held-out excess: {rank}; "
            f"the held-out excess shrank by {fmt(r['excess_shrink'])}{own}."
        )
    quiet = [r for r in rows if (r["term"] or "").startswith("X") and "X" not in (r["dofs"] or []) and r["clear"]]
    for r in quiet:
        sog = r.get("speed_from_positions_ratio")
        lines.append(
            f"- {r['case']}: the dominant channel was {r['dominant_channel']}, not the speed"
            + (
                f", and the speed over ground from the positions missed by {fmt(sog)} x its floor (under 2)"
                if sog
                else ""
            )
            + ", so the search stayed in Y and N"
            + (f" and kept {', '.join(r['found'])}." if r["found"] else ", and found nothing.")
        )
    for r in rows:
        if r["control"] or r["clear"]:
            continue
        mine = next((x for x in r.get("effect_rows") or [] if x["effect"] == r["effect"]), None)
        lines.append(
            f"- {r['case']}: verdict none, a hidden structure the held-out runs do not show beyond the floor: "
            f"held-out RMS {fmt(r['heldout_rms_before_m'])} m against {fmt(r['floor_m'])} m "
            f"({fmt(r['heldout_rms_before_m'] / r['floor_m'])} x, under 1.5): the turns miss it no more than a model of "
            "the right form misses them with its coefficients known only as well as the zigzags tell them"
            + (
                f" ({r['effect']}: training ΔBIC {fmt(mine['delta_bic'], 4)}, window test p "
                f"{fmt(mine['window_p_value'])}, share of the excess {fmt(mine['share_of_excess'])})"
                if mine is not None
                else ""
            )
            + "."
        )
    for r in rows:
        if r["control"] and r["verdict"] != "none":
            lines.append(
                f"- {r['case']}: nothing hidden, yet a gap: held-out RMS {fmt(r['heldout_rms_before_m'])} m against a "
                f"noise floor of {fmt(r['floor_m'])} m ({fmt(r['heldout_rms_before_m'] / r['floor_m'])} x): the zigzag-"
                "trained base model does not predict the turns within the floor, with nothing missing from its form: "
                "the zigzags do not determine the turn, or the floor (window starts fitted to 2 Hz positions) "
                "underestimates the error a prediction makes."
            )
    return [*lines, ""]


def write_report(out: Path, rows: list, summary: dict, args, calib: list = ()) -> None:
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
        f"- Hidden terms and effects named (a term kept or among a kept term's alternatives; an effect named by "
        f"the verdict) in {summary['named_in_clear']} of {summary['clear_cases']} clear cases (effects: "
        f"{summary['effects_named_in_clear']} of {summary['effect_clear_cases']}); a wrong name alone in "
        f"{summary['wrong_term_alone']}.",
        f"- Surge cases whose search went into X: {summary['surge_cases_routed_to_x']} of {summary['surge_clear_cases']} "
        "(with a velocity log when the speed u is the channel missed most; without one when the speed over ground "
        "read from the positions is missed by at least 2 x its noise floor).",
        f"- Yaw cases routed into X: {summary['yaw_cases_routed_to_x']} (the search stays in Y and N).",
        f"- Controls clean (verdict none; the nothing-hidden control and the propulsion point the base fit "
        f"absorbs): {summary['controls_clean']} of {summary['controls']}.",
        f"- Median held-out excess shrink of the {summary['cases_with_a_kept_term_or_effect']} hidden cases where a "
        f"term was kept or an effect named: {fmt(summary['median_excess_shrink'])} (the issue's target: 0.5 on the "
        "turns; where nothing was kept it is 0).",
        *(
            [
                f"- The floor band held (verdict none) on the nothing-hidden control at further seeds in "
                f"{summary['calibration_band_held']} of {summary['calibration_diagnoses']} diagnoses (*The floor band "
                "on controls* below: what the false alarms are made of)."
            ]
            if summary.get("calibration_diagnoses")
            else []
        ),
        "",
        *reading(rows),
        *calibration_lines(list(calib)),
        "## Cases",
        "",
        md_table(
            [
                "case",
                "verdict",
                "dominant channel",
                "speed from positions / floor",
                "searched",
                "kept (alternatives)",
                "effects named",
                "named",
                "held-out RMS (m)",
                "shrink",
            ],
            [
                [
                    r["case"],
                    r["verdict"],
                    r["dominant_channel"] or "-",
                    fmt(r.get("speed_from_positions_ratio")),
                    ",".join(r["dofs"] or []) or "-",
                    "; ".join(f"{k} ({', '.join(v) or 'none'})" for k, v in r["alternatives"].items()) or "-",
                    ", ".join(r["effects"]) or "-",
                    "yes" if r["named"] else ("-" if r["control"] else "no"),
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
    ap.add_argument("--render", action="store_true", help="rewrite report.md from --out's results.json")
    ap.add_argument(
        "--calibration",
        type=int,
        default=None,
        help=f"seeds of the nothing-hidden control per log setting (default {CALIBRATION_SEEDS}; 0 with --quick)",
    )
    args = ap.parse_args()
    from bayesid.report import write_json, write_manifest

    out = Path(args.out)
    if args.render:
        doc = json.loads((out / "results.json").read_text())
        args.quick = doc["quick"]
        write_report(out, doc["cases"], doc["summary"], args, doc.get("calibration") or [])
        return 0
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    structures = [STRUCTURES[i] for i in QUICK] if args.quick else STRUCTURES
    rows = []
    for i, s in enumerate(structures):
        for log in (True,) if args.quick else (True, False):
            r = run_case(s, log, args.seed + i, args.quick)
            print(f"{r['case']}: {r['verdict']} ({r['seconds']:.0f} s)", flush=True)
            rows.append(r)
    n_cal = args.calibration if args.calibration is not None else (0 if args.quick else CALIBRATION_SEEDS)
    calib = calibration(args.seed, n_cal, args.quick)
    summary = summarise(rows)
    if calib:
        summary["calibration_band_held"] = sum(r["verdict"] == "none" for r in calib)
        summary["calibration_diagnoses"] = len(calib)
    write_report(out, rows, summary, args, calib)
    write_json(
        out / "results.json",
        {"summary": summary, "cases": rows, "calibration": calib, "quick": bool(args.quick)},
    )
    write_manifest(out, seed=args.seed, quick=args.quick, t_start=t_start, extra={"calibration_seeds": n_cal})
    print(summary)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
