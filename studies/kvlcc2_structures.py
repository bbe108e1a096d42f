"""Which term, on a real hull: the structures the KVLCC2 HSVA zigzags cannot tell apart, each
refitted on all 13 zigzags, and what each predicts where no HSVA run exists.

Method
------
- Data (read from ``shared/data/real``, never copied): KVLCC2 7 m model, HSVA tank, 13 zigzags at
  20 Hz (``bayesid.data.datasets``); the validation split of ``studies/real_ships.py`` (hold out
  Z_10_10_P, Z_20_10_S, Z_35_05, Z_15_01; train on the other nine).
- Diagnosis as in ``studies/real_ships.py`` (the ship catalogue without wind; 60 s held-out
  windows; measured starts) with structure discovery naming the alternatives the held-out runs
  cannot separate from each kept term (``DiscoveryOptions.n_alternatives = 2``; a competitor is
  separated when the kept term's held-out windows are significantly better pooled or on one run)
  and the design of the separating run (``DiagnoseOptions.design``: the menu of standard runs
  from the training runs' approach condition, ranked first by the pairs of the kept term and an
  alternative the run test could decide on them within eight windows, then by the smallest
  pairwise J divergence of the alternatives' predictive distributions, Box & Hill 1967).
- Structures: the model without a discovered term, each kept term, and each of its alternatives,
  one term at a time; each refitted with every free coefficient on all 13 HSVA zigzags (what
  ``bayesid fit`` does on the ``--write-vehicle`` file), 15 s fit windows, measured starts.
- Beyond the zigzags: each structure predicts the 35 deg turning circles both ways (from U0 =
  1.179 m/s at 10.23 rps, the rudder moved at the HSVA runs' rate, ``real_ships.turn_approach``;
  the ITTC indices, the 5-95 % range over Laplace draws), and every
  HSVA zigzag's overshoots (training runs now: a check of the fit, not a prediction).
- The other basin (MARIN, SIMMAN 2008 free-running runs of the same hull, Froude-scaled): when
  their files are under ``--data`` (they are withheld from this repository), each structure
  predicts every run whole from its measured start with its recorded rudder and propeller, and
  the report gives the advance and tactical diameter errors against the issue's targets (5 % /
  3 %); without them, the spread between structures is the finding.
- The loop on real data (with the MARIN runs): the MARIN runs of the kind of the design's top run
  (the run the design asks for, as this hull has it) join the held-out runs and the diagnosis runs
  again (``diagnosis_other_basin/``); the report names the term the design and the data keep and
  compares its MARIN turning-circle errors with those of the model without a discovered term.

    python studies/kvlcc2_structures.py [--quick] [--out DIR] [--data DIR] [--seed N] [--draws N]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studies.real_ships import KVLCC2_HOLD, U0, turn_approach  # noqa: E402

#: the turning indices each structure predicts, and the issue's targets on the other basin's runs
TURN_INDICES = ("advance_m", "transfer_m", "tactical_diameter_m", "steady_turning_diameter_m", "speed_loss")
TARGETS = {"tactical_diameter_m": 0.05, "advance_m": 0.03}
#: The KVLCC2 model's length between perpendiculars, m (bayesid/vehicles/kvlcc2_7m.toml).
L_PP = 7.0


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="few runs, few iterations (a smoke test)")
    ap.add_argument("--out", default="reports/kvlcc2_structures")
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"))
    ap.add_argument("--draws", type=int, default=50, help="Laplace draws of each predicted index's range")
    ap.add_argument("--max-nfev", type=int, default=40)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--render", action="store_true", help="rewrite report.md from --out's results.json")
    return ap.parse_args()


def diagnose_split(kv, train, held, args, out, log, folder: str = "diagnosis", compare: tuple = ()):
    """The validation split's diagnosis with alternatives and the design; its report written to
    ``out / folder``; ``compare``: terms refitted whatever the selection picks (an earlier
    round's kept terms and alternatives, ``DiscoveryOptions.compare``)."""
    from bayesid.analysis.gap import DiagnoseOptions, diagnose
    from bayesid.analysis.gap.design import DiscriminationOptions
    from bayesid.analysis.gap.diagnose import catalogue_candidates
    from bayesid.analysis.gap.discovery import DiscoveryOptions
    from bayesid.models import ship
    from bayesid.report import write_diagnosis
    from bayesid.tasks import Runner

    diag = diagnose(
        kv,
        kv.free,
        train,
        held,
        DiagnoseOptions(
            candidates=catalogue_candidates(ship.ShipModel, train + held, free=kv.free, vehicle=kv),
            window_s=60.0,
            fit_window_s=ship.FIT_WINDOW_S,
            dt=0.2,
            max_nfev=args.max_nfev,
            start="measured",
            discover=DiscoveryOptions(max_nfev=args.max_nfev, n_alternatives=2, compare=tuple(compare)),
            design=DiscriminationOptions(seed=args.seed),
        ),
        rng=np.random.default_rng(args.seed),
        runner=Runner(progress=lambda m: log(f"diagnose: {m}")),
    )
    write_diagnosis(diag, out / folder, held, command="studies/kvlcc2_structures.py")
    return diag


def structures(diag, out: dict | None = None) -> dict:
    """``{label: {term: coefficient}}``: the model without a discovered term, each kept term and
    each of its alternatives (one term each), from the diagnosis's top-level ``discovered`` list;
    added to ``out`` when given (a structure already there keeps its coefficient)."""
    items = diag.to_dict().get("discovered") or []
    out = {"without": {}} if out is None else out
    for it in items:
        if not it["kept"]:
            continue
        out.setdefault(it["term"], {it["term"]: it["coefficient"]})
        for a in it["alternatives"]:
            out.setdefault(a["term"], {a["term"]: a["coefficient"]})
    return out


def refit_all(kv, tracks, terms: dict, args):
    """One structure refitted on every HSVA zigzag: (FittedModel, coefficients of the terms, train RMS)."""
    from bayesid.estimation.identification import identify
    from bayesid.estimation.options import FitOptions
    from bayesid.estimation.prediction import FittedModel

    veh = kv.with_coefficients(terms) if terms else kv
    free = tuple(kv.free) + tuple(t for t in terms if t not in kv.free)
    res = identify(veh, tracks, FitOptions(free=free, dt=0.2, max_nfev=args.max_nfev, start="measured"))
    coefs = {k: v for k, v in res.fit.coefficients().items() if k in terms}
    return FittedModel(res.model, res.fit.p, res.cov), coefs, res.train_scores.get("rms_position_m")


def circles_of(fitted, args, rng, approach) -> dict:
    """35 deg turning circles both ways from ``approach``: each index at the estimate and its
    5-95 % range."""
    from bayesid.estimation.prediction import turning_circles

    tc = turning_circles(fitted, args.draws, rng, approach)
    return {
        side: {
            k: {"value": c["predicted"].get(k), "band_5_95": (c.get("band_5_95") or {}).get(k)} for k in TURN_INDICES
        }
        | {"n_finite_draws": c.get("n_finite_draws"), "steady": steady_turn(c["_S"][0])}
        for side, c in tc.items()
    }, {side: c["_S"] for side, c in tc.items()}


def steady_turn(S) -> dict:
    """The steady turn a simulated 35 deg turn settles in, from its states (n, 12: u, v, r at 6,
    7, 11) over the last tenth of the run: ``r_prime`` (r' = |r| L / U, how tight a turn the hull
    forces settle in, to set beside the training zigzags' largest r'), ``diameter_m`` (2 U / |r|,
    the steady turning diameter of a circle turned at steady speed) and ``speed_loss`` (1 - U /
    U0)."""
    tail = np.asarray(S)[-max(1, len(S) // 10) :]
    U = np.hypot(tail[:, 6], tail[:, 7])
    r = np.abs(tail[:, 11])
    return {
        "r_prime": float(np.median(r * L_PP / U)),
        "diameter_m": float(np.median(2.0 * U / r)),
        "speed_loss": float(1.0 - np.median(U) / U0),
    }


def zigzag_r_prime(tracks) -> float:
    """The largest r' the HSVA zigzags reach: the 95th percentile over each run
    (:func:`bayesid.estimation.calibration.yaw_rate_prime`), the largest run's."""
    from bayesid.estimation.calibration import yaw_rate_prime

    return max(float(np.percentile(yaw_rate_prime(t.t, t["x"], t["y"], t["psi"], L_PP), 95)) for t in tracks)


def overshoots_of(fitted, tracks) -> dict:
    """Every HSVA zigzag's first and second overshoot, measured and predicted (open loop from its
    first modelled state; training runs of the all-13 refit)."""
    from bayesid.estimation.indices import manoeuvre_indices
    from bayesid.estimation.prediction import turning_band

    out = {}
    for tr in tracks:
        m = manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
        p = turning_band(fitted, tr, 0, None)["predicted"]
        out[tr.name] = {
            k: {"measured": m.get(k), "predicted": p.get(k)} for k in ("first_overshoot_deg", "second_overshoot_deg")
        }
    errs = [
        abs(v["predicted"] - v["measured"])
        for d in out.values()
        for v in d.values()
        if v["predicted"] is not None and v["measured"] is not None and math.isfinite(v["predicted"])
    ]
    return {"runs": out, "mean_abs_error_deg": float(np.mean(errs)) if errs else None}


def other_basin_runs(data: Path) -> tuple[list, dict]:
    """The MARIN runs under ``data``: (tracks read, ``{file: why it was not read}``)."""
    from bayesid.data import datasets

    tracks, unread = [], {}
    for p in datasets.list_runs(data, "simman-marin"):
        try:
            tracks.append(datasets.read_run(p, "simman-marin"))
        except ValueError as exc:
            unread[str(p)] = str(exc)
    return tracks, unread


def kept_terms(diag) -> list:
    """The terms a diagnosis keeps (its verdict's discovered terms), in its order."""
    return [it["term"] for it in diag.to_dict().get("discovered") or [] if it["kept"]]


def loop_on_other_basin(kv, train, held, diag, marin: list, args, out, log) -> dict | None:
    """The loop of issue 49 on real data: the other basin's runs of the kind of the design's top
    run (the run the design asks for, as this hull has it) added to the held-out runs, and the
    diagnosis again, with the first round's kept terms and alternatives refitted whatever its
    selection picks. None when the design ranked no run or no MARIN run is of that kind.

    Returns ``{"kind", "added_runs", "verdict", "kept", "discovered", "_diag"}``: ``kept`` is the
    term (or terms) the design and the data keep; each item of ``discovered`` has its
    ``worse_on_other_kinds``, the added runs a kept term predicts worse than the model without it
    (by more than the separation margin); ``_diag`` is the diagnosis itself."""
    from bayesid.estimation.indices import manoeuvre_kind

    design = diag.to_dict().get("design") or []
    if not design or not marin:
        return None
    kind = design[0]["kind"]
    added = [t for t in marin if manoeuvre_kind(t) == kind]
    if not added:
        return None
    log(f"the loop: {len(added)} other-basin run(s) of the designed kind ({kind}) added to the held-out runs")
    # the first round's kept terms and alternatives are judged again on the added runs (``--compare``)
    asked = list(structures(diag))[1:]
    diag2 = diagnose_split(kv, train, [*held, *added], args, out, log, folder="diagnosis_other_basin", compare=asked)
    D2 = diag2.to_dict()
    return {
        "kind": kind,
        "added_runs": [t.name for t in added],
        "verdict": D2["verdict"],
        "kept": kept_terms(diag2),
        "discovered": [
            {k: it.get(k) for k in ("term", "kept", "reason", "coefficient", "heldout_rms_m", "alternatives")}
            | {"worse_on_other_kinds": it.get("worse_on_other_kinds") or []}
            for it in D2.get("discovered") or []
        ],
        "_diag": diag2,
    }


def other_basin(fitted, marin: list, unread: dict, draws: int, rng) -> dict | None:
    """The MARIN runs (``marin`` and ``unread`` as :func:`other_basin_runs` returns them; None when
    there are none): per run, measured and predicted turning indices with the 5-95 % range, and the
    relative errors of advance and tactical diameter; an unread file's entry says why."""
    from bayesid.estimation.prediction import turning_band

    if not marin and not unread:
        return None
    runs = {Path(k).stem: {"unread": v} for k, v in unread.items()}
    for tr in marin:
        tb = turning_band(fitted, tr, draws, rng)
        meas, pred = tb["measured"], tb["predicted"]
        e = {"kind": meas.get("kind"), "indices": {}}
        for k in (*TURN_INDICES, "first_overshoot_deg", "second_overshoot_deg"):
            m, q = meas.get(k), pred.get(k)
            if m is None or q is None or not (math.isfinite(m) and math.isfinite(q)):
                continue
            band = (tb.get("band_5_95") or {}).get(k)
            e["indices"][k] = {
                "measured": m,
                "predicted": q,
                "band_5_95": band,
                "in_band": bool(band and band[0] <= m <= band[1]),
                "rel_error": (q - m) / m if k in TURN_INDICES and m else None,
            }
        runs[tr.name] = e
    worst = {}
    for k in TARGETS:
        errs = [abs(e["indices"][k]["rel_error"]) for e in runs.values() if k in e.get("indices", {})]
        worst[k] = max(errs) if errs else None
    return {"runs": runs, "max_abs_rel_error": worst}


def figure(sims: dict, path: Path):
    """The 35 deg turning circles (starboard) of every structure, estimate and draws."""
    from bayesid.report import plots

    return plots.turning_band(
        sims, path, title="KVLCC2 35 deg turn to starboard:\neach structure refitted on all zigzags"
    )


def _cell(v: dict) -> str:
    """``value [low, high]`` of one predicted index."""
    from bayesid.report import fmt

    lo, hi = v["band_5_95"] or (math.nan, math.nan)
    return f"{fmt(v['value'])} [{fmt(lo)}, {fmt(hi)}]"


def _steady_lines(res: dict) -> list:
    """Each structure's steady turn against the zigzags' largest r' (results from before the
    measure: none)."""
    from bayesid.report import fmt

    top = res.get("zigzag_r_prime_max")
    if top is None:
        return []
    cells = []
    for label, s in res["structures"].items():
        c = s["circles"]["starboard"]
        if c.get("steady") is None:
            return []
        cells.append(
            f"{'no discovered term' if label == 'without' else label} r' {fmt(c['steady']['r_prime'])}, steady "
            f"diameter (2 U / r) {fmt(c['steady']['diameter_m'])} m against a tactical diameter of "
            f"{fmt(c['tactical_diameter_m']['value'])} m, speed loss {fmt(c['steady']['speed_loss'])}"
        )
    return [
        f"Beyond the zigzags: the zigzags reach a nondimensional yaw rate r' = r L / U of {fmt(top)} at most (95th "
        "percentile of the largest run); each structure's 35 deg turn to starboard settles at "
        + "; ".join(cells)
        + ". The steady turn lies beyond anything the zigzags show the hull, and there the structures "
        "extrapolate: a steady turning diameter far below the tactical diameter comes from the model (the index "
        "reads the circle the model turns), and `bayesid predict` warns where a model's own run goes past 1.25 x "
        "its training runs' r'.",
        "",
    ]


def write_report(out: Path, res: dict, args) -> None:
    from bayesid.analysis.gap.records import DesignedRun, pair_label
    from bayesid.report import fmt, md_table
    from bayesid.report.diagnosis import design_duration_cell, run_test_cell

    D = res["diagnosis"]
    S = res["structures"]
    lines = [
        "# KVLCC2: the structures the HSVA zigzags cannot tell apart, and what each predicts beyond them",
        "",
        "**Quick run** (smoke test)." if args.quick else "Full run.",
        "",
        __doc__.split("Method\n------\n")[1].split("\n    python")[0],
        "",
        "## The diagnosis on the validation split",
        "",
        f"Verdict: `{D['verdict']}`. Training runs: {', '.join(D['manoeuvre_kinds'].get('train', []))}; held-out "
        f"runs: {', '.join(D['manoeuvre_kinds'].get('heldout', []))}. The full diagnosis report is in "
        "`diagnosis/report.md`.",
        "",
    ]
    rows = []
    for it in D["discovered"]:
        if not it["kept"]:
            continue
        rows.append([f"**{it['term']}** (kept)", fmt(it["coefficient"]), fmt(it["heldout_rms_m"]), "-", "-"])
        for a in it["alternatives"]:
            rows.append(
                [
                    a["term"],
                    fmt(a["coefficient"]),
                    fmt(a["heldout_rms_m"]),
                    fmt(a["window_p_value"]),
                    fmt(a.get("run_p_value")),
                ]
            )
        for a in it.get("separated") or []:
            rows.append(
                [
                    f"{a['term']} (separated)",
                    fmt(a["coefficient"]),
                    fmt(a["heldout_rms_m"]),
                    fmt(a["window_p_value"]),
                    fmt(a.get("run_p_value")),
                ]
            )
    if rows:
        lines += [
            md_table(
                ["term", "coefficient (split refit)", "held-out RMS (m)", "window test p", "run test p"],
                rows,
            ),
            "",
        ]
    else:
        lines += ["No term kept on this split: there is nothing to tell apart.", ""]
    if D.get("design"):
        lines += [
            "The runs that would separate them best (first the runs on which the run test could decide a pair of "
            "the kept term within eight windows, then by the J divergence of the models' predictive distributions, "
            "nats, the smallest over the pairs; with no alternative, the kept term's model against the model without "
            "it, the run of another kind that would test the term):",
            "",
            md_table(
                ["rank", "run", "length (s)", "separation (nats)", "worst pair", "run test: windows needed"],
                [
                    [
                        i + 1,
                        r.name,
                        design_duration_cell(r),
                        fmt(r.separation),
                        pair_label(r.worst_pair),
                        run_test_cell(r),
                    ]
                    for i, r in enumerate(DesignedRun.from_dict(x) for x in D["design"][:5])
                ],
            ),
            "",
            "Length: the three best runs are lengthened (to at most eight 60 s windows) towards the windows the "
            "run-by-run test needs to see the pair apart with 80 % power (from the expected window error ratio and "
            "the scatter of the ratios within the held-out runs). Windows needed: with the expected ratio of the two "
            "models' window errors; *within the margin* where that ratio is below the test's 10 % margin, so that no "
            "length makes the run test separate the pair (the divergence may still rank the run).",
            "",
        ]
    lines += [
        f"## Each structure refitted on all {len(res['train_runs']) + len(res['heldout_runs'])} zigzags",
        "",
        "35 deg turning circles from 1.179 m/s at 10.23 rps, value at the estimate [5-95 % over "
        f"{args.draws} Laplace draws]; the zigzag overshoots' mean absolute error over the same runs (their "
        "training runs now).",
        "",
    ]
    rows = []
    for label, s in S.items():
        c = s["circles"]
        rows.append(
            [
                "no discovered term" if label == "without" else label,
                ", ".join(f"{k} {fmt(v)}" for k, v in s["coefficients"].items()) or "-",
                fmt(s["train_rms_position_m"]),
                fmt(s["overshoots"]["mean_abs_error_deg"]),
                _cell(c["starboard"]["advance_m"]),
                _cell(c["port"]["advance_m"]),
                _cell(c["starboard"]["tactical_diameter_m"]),
                _cell(c["port"]["tactical_diameter_m"]),
            ]
        )
    lines += [
        md_table(
            [
                "structure",
                "coefficient",
                "train RMS (m)",
                "overshoot error (deg)",
                "advance stbd (m)",
                "advance port (m)",
                "tactical diameter stbd (m)",
                "tactical diameter port (m)",
            ],
            rows,
        ),
        "",
        "![turning circles](figures/turning35_structures.png)",
        "",
        *_steady_lines(res),
    ]
    spread = res["spread_between_structures"]
    lines += [
        "Spread between the structures' estimates (largest minus smallest, relative to the model without a "
        "discovered term): "
        + "; ".join(
            f"{key.split(':')[1]} {key.split(':')[0]} {fmt(100 * v)} %" for key, v in spread.items() if v is not None
        )
        + ".",
        "",
    ]
    asym = []
    for label, s in S.items():
        c = s["circles"]
        p, q = c["port"]["tactical_diameter_m"]["value"], c["starboard"]["tactical_diameter_m"]["value"]
        if p is not None and q is not None:
            asym.append(f"{'no discovered term' if label == 'without' else label} {fmt(200 * (p - q) / (p + q))} %")
    b = S.get("without")
    for label, s in S.items():
        if label == "without" or b is None or not (s["train_rms_position_m"] and b["train_rms_position_m"]):
            continue
        e, e0 = s["overshoots"]["mean_abs_error_deg"], b["overshoots"]["mean_abs_error_deg"]
        lines += [
            f"Refitted on all the zigzags, {label} changes the training position RMS by "
            f"{fmt(100 * (s['train_rms_position_m'] / b['train_rms_position_m'] - 1))} % and the overshoots' mean "
            f"absolute error by {fmt(e - e0) if e is not None and e0 is not None else '-'} deg against the model "
            "without it.",
            "",
        ]
    if asym:
        lines += [
            "Port against starboard tactical diameter ((port - starboard) / mean): " + "; ".join(asym) + ". The "
            "zigzags hold both sides' rudder in turn, so a term that makes the turns asymmetric is tested on them "
            "only through its effect on the overshoots.",
            "",
        ]
    kinds = D["manoeuvre_kinds"]
    if set(kinds.get("heldout", [])) <= set(kinds.get("train", [])) | {"other"}:
        lines += [
            "The held-out runs are of the kinds of the training runs (zigzags): the kept term is tested only "
            "within the training manoeuvres, and the turning circles above are where it has not been tested.",
            "",
        ]
    M = res.get("other_basin")
    if M is None:
        lines += [
            "## The other basin",
            "",
            "No MARIN run is under `--data` (they are withheld from this repository): whether the term the "
            "design and the data would keep carries to the other basin's turning circles is for the independent "
            "evaluation, which runs this study with them. The spread above is where the structures part.",
            "",
        ]
    else:
        rows = []
        for label, m in M.items():
            w = m["max_abs_rel_error"]
            rows.append(
                [
                    "no discovered term" if label == "without" else label,
                    fmt(100 * w["tactical_diameter_m"]) if w["tactical_diameter_m"] is not None else "-",
                    fmt(100 * w["advance_m"]) if w["advance_m"] is not None else "-",
                ]
            )
        lines += [
            "## The other basin (MARIN)",
            "",
            md_table(["structure", "largest |tactical diameter error| (%)", "largest |advance error| (%)"], rows),
            "",
            f"Targets: tactical diameter within {fmt(100 * TARGETS['tactical_diameter_m'])} %, advance within "
            f"{fmt(100 * TARGETS['advance_m'])} %.",
            "",
            *_loop_lines(res),
        ]
    (out / "report.md").write_text("\n".join(lines))


def _loop_lines(res: dict) -> list:
    """The report's account of the loop on the other basin's runs (:func:`loop_on_other_basin`)."""
    from bayesid.report import fmt

    L, M = res.get("loop_on_other_basin"), res.get("other_basin") or {}
    D = res["diagnosis"]
    top = (D.get("design") or [{}])[0].get("name")
    lines = ["## The loop: the designed run, as the other basin has it", ""]
    if res.get("other_basin_unread"):
        lines += [
            "Not read (the message names the file): " + "; ".join(res["other_basin_unread"].values()) + ".",
            "",
        ]
    if L is None:
        return lines + [
            f"The design's top run is a {top}; no run of the other basin is of that kind, so the loop is not "
            "closed here."
            if top
            else "The diagnosis kept no term and designed no run: there is no loop to close.",
            "",
        ]
    kept1 = [it["term"] for it in D["discovered"] if it["kept"]]
    fate = []
    for t in kept1:
        it = next((i for i in L["discovered"] if i["term"] == t), None)
        fate.append(
            f"{t}: " + ("kept" if it and it["kept"] else f"not kept ({it['reason']})" if it else "not refitted")
        )
    kept = "+".join(L["kept"]) if L["kept"] else None
    lines += [
        f"The design's top run is a {top}; the other basin's runs of that kind ({', '.join(L['added_runs'])}) "
        "were added to the held-out runs and the diagnosis was run again (`diagnosis_other_basin/report.md`). "
        f"Verdict: `{L['verdict']}`. The first round's kept terms there: " + ("; ".join(fate) or "none") + ".",
        "",
    ]
    for it in L["discovered"]:
        for w in it.get("worse_on_other_kinds") or []:
            lines += [
                f"{it['term']} predicts {w['run']} ({w['kind']}, a kind the training runs lack) worse than the model "
                f"without it: {fmt(w['rms_m'])} m against {fmt(w['reference_rms_m'])} m.",
                "",
            ]
    base = (M.get("without") or {}).get("max_abs_rel_error") or {}
    mine = (M.get(kept) or {}).get("max_abs_rel_error") if kept else base
    if mine:
        verdict = []
        for k, lim in TARGETS.items():
            a, b = mine.get(k), base.get(k)
            if a is None or b is None:
                continue
            verdict.append(
                f"largest |{k.replace('_m', '').replace('_', ' ')} error| {fmt(100 * a)} % "
                f"(without the term {fmt(100 * b)} %; target {fmt(100 * lim)} %: "
                f"{'met' if a <= lim else 'not met'}; {'no worse' if a <= b else 'worse'} than without)"
            )
        lines += [
            f"The term the design and the data keep: **{kept or 'none'}**"
            + (" (the model without a discovered term)" if kept is None else "")
            + ". On the other basin's runs, refitted on all HSVA zigzags: "
            + "; ".join(verdict)
            + ".",
            "",
        ]
    return lines


def main() -> int:
    import matplotlib

    matplotlib.use("Agg")  # the study writes its figures, it never shows them
    args = parse_args()
    if args.render:  # the report again from the run's results.json (figures and numbers unchanged)
        import json

        out = Path(args.out)
        write_report(out, json.loads((out / "results.json").read_text()), args)
        return 0
    from bayesid.data import datasets
    from bayesid.models import ship
    from bayesid.report import write_json, write_manifest

    data = Path(args.data)
    kv_dir = data / "kvlcc2-simman-hsva"
    if not kv_dir.is_dir():
        print(f"real data not found under {data}: nothing to do (the study needs shared/data/real)")
        return 0
    out = Path(args.out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    log = lambda m: print(m, flush=True)  # noqa: E731
    if args.quick:
        args.max_nfev, args.draws = min(args.max_nfev, 6), min(args.draws, 4)
    tracks = [datasets.read_run(p, "simman-hsva") for p in datasets.list_runs(kv_dir, "simman-hsva")]
    held = [t for t in tracks if any(t.name.endswith(h) for h in KVLCC2_HOLD)]
    train = [t for t in tracks if t not in held]
    if args.quick:
        train, held, tracks = train[:3], held[:2], train[:3] + held[:2]
    kv = ship.load_ship("kvlcc2_7m")
    diag = diagnose_split(kv, train, held, args, out, log)
    D = diag.to_dict()
    res = {
        "train_runs": [t.name for t in train],
        "heldout_runs": [t.name for t in held],
        "diagnosis": {
            "verdict": D["verdict"],
            "manoeuvre_kinds": D.get("manoeuvre_kinds") or {},
            "discovered": D.get("discovered") or [],
            "design": [{k: v for k, v in r.items() if k not in ("predicted", "inputs")} for r in D.get("design") or []],
        },
        "structures": {},
        "quick": bool(args.quick),
    }
    marin, unread = other_basin_runs(data)
    loop = loop_on_other_basin(kv, train, held, diag, marin, args, out, log)
    sims, basin = {}, {}
    todo = structures(diag)
    if loop is not None:
        todo = structures(loop.pop("_diag"), todo)
        if len(loop["kept"]) > 1:  # the kept combination, refitted as one structure
            coef = {it["term"]: it["coefficient"] for it in loop["discovered"] if it["kept"]}
            todo["+".join(loop["kept"])] = {t: coef[t] for t in loop["kept"]}
    res["loop_on_other_basin"] = loop
    res["other_basin_unread"] = unread
    for label, terms in todo.items():
        log(f"refit on all {len(tracks)} zigzags: {label}")
        fitted, coefs, rms = refit_all(kv, tracks, terms, args)
        circles, S = circles_of(fitted, args, rng, turn_approach(tracks))
        sims["no discovered term" if label == "without" else label] = S["starboard"]
        res["structures"][label] = {
            "terms": list(terms),
            "coefficients": coefs,
            "train_rms_position_m": rms,
            "circles": circles,
            "overshoots": overshoots_of(fitted, tracks),
        }
        m = other_basin(fitted, marin, unread, args.draws, rng)
        if m is not None:
            basin[label] = m
    res["other_basin"] = basin or None
    res["zigzag_r_prime_max"] = zigzag_r_prime(tracks)
    spread = {}
    base = res["structures"]["without"]["circles"]
    for side in ("starboard", "port"):
        for k in TURN_INDICES:
            v = [s["circles"][side][k]["value"] for s in res["structures"].values()]
            v = [x for x in v if x is not None and math.isfinite(x)]
            ref = base[side][k]["value"]
            spread[f"{side}:{k}"] = (max(v) - min(v)) / ref if v and ref else None
    res["spread_between_structures"] = spread
    figure(sims, out / "figures" / "turning35_structures.png")
    write_json(out / "results.json", res)
    write_report(out, res, args)
    write_manifest(out, seed=args.seed, quick=args.quick, t_start=t_start)
    log(f"verdict {D['verdict']}; structures: {', '.join(res['structures'])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
