"""Base-fit benchmark: is the gap diagnosis' base fit at its optimum on tracks without a velocity
log, and does its check flag the fits that are not to be trusted?

Issue 40 asks that, on synthetic cases without a velocity log and with a hidden effect, the base
model's held-out error stay within 3 x that of an independent output-error fit of the same model
(it was up to 48 x), and that window starts only a model far off needs are flagged.

Method
------
- Cases: every case of ``studies/sim_to_real.py`` (same seed, same world tracks: NPS AUV II,
  free Yv, Yr, Nv, Nr, Ydr, Ndr, one hidden effect or none or two) whose tracks log no u, v, r,
  so that window starts are fitted with the model.
- Base fit: ``bayesid.analysis.gap.diagnose`` without candidates (its base fit, scores and base-fit
  check only), as the full diagnosis makes it (40 iterations, channel weights by the noise).
- Two independent output-error fits of the same model on the same training tracks and windows,
  scored by the same held-out protocol:

  * *truth start*: the same objective started at the world's true coefficients (a fit that cannot
    have lost its way to the optimum);
  * *kinematic starts*: the window start states held at the tracks' own kinematics
    (:func:`bayesid.estimation.shooting.kinematic_rates`: positions and heading, a centred local
    cubic) instead of fitted, the fit the issue's evaluator made ("initial states estimated from
    the logged positions").

- Scores: the ratio of the base fit's held-out RMS to the better independent fit's (target <= 3);
  the base-fit check's verdict (``suspect``), its held-out / training ratio and the fraction of
  window starts more than 5 sd from the kinematics; the true model's held-out RMS for scale.
- Cases are tasks (``--jobs``), journalled in ``journal.jsonl`` and resumed on a re-run.

    python studies/base_fit_check.py [--quick] [--out DIR] [--seed N] [--fresh] [--jobs N]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bayesid.tasks import Journal, Runner, Task, TaskError, add_arguments, parse_checked, run_tasks  # noqa: E402
from studies import sim_to_real as s2r  # noqa: E402

VERSION = 1  # of this benchmark's design; saved cases of another version are re-run
TARGET_RATIO = 3.0


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="three cases (a smoke test)")
    ap.add_argument("--out", default="reports/base_fit_check")
    ap.add_argument("--seed", type=int, default=2026, help="the sim_to_real seed (default 2026: its cases)")
    ap.add_argument("--fresh", action="store_true", help="start over: remove the journal of finished cases")
    add_arguments(ap, jobs_default=os.cpu_count() or 1)
    return parse_checked(ap)


def cases(quick: bool) -> list[dict]:
    """The sim_to_real cases without a velocity log (full design: the same draws as that study), its
    structural cases aside (they repeat the outside-the-catalogue effects for discovery, and one
    removes a term from the diagnosis' vehicle, which this benchmark's fits do not)."""
    out = [c for c in s2r.case_list(False) if not c["velocity_log"] and not c.get("discover")]
    return [c for c in out if c["id"] in ("control_1", "crossflow_L2", "outside_yaw_bias_1")] if quick else out


def run_case(case: dict, seed: int, quick: bool) -> dict:
    """The base fit and its check, the two independent fits, the true model (JSON-able)."""
    from bayesid.analysis.gap import DiagnoseOptions, diagnose
    from bayesid.estimation import shooting
    from bayesid.estimation.windows import WindowProblem, fit_model, scores

    tic = time.perf_counter()
    world, train, held = s2r.case_data(case, seed, False)
    cfg, wv = world["logging"], world["world_vehicle"]
    window = s2r.window_for(cfg)
    nfev = 15 if quick else 40
    d = diagnose(
        world["vehicle"],
        s2r.FREE,
        train,
        held,
        DiagnoseOptions(candidates=[], window_s=window, dt=s2r.DT, max_nfev=nfev),
        rng=np.random.default_rng(seed),
    )
    base, ctr, cho = d.setup.build(())
    truth_p = np.array([wv.coefficients[k] for k in s2r.FREE])
    f_truth = fit_model(WindowProblem(base, ctr, d.fit_sd, max_nfev=nfev), truth_p, None)
    ckin = shooting.kinematic_contexts(base, train, d.setup.fit_window_s, d.fit_sd)
    f_kin = fit_model(WindowProblem(base, ckin, d.fit_sd, max_nfev=nfev), None, None)
    held_of = {k: scores(base, f, cho)["rms_position_m"] for k, f in (("truth_start", f_truth), ("kinematic", f_kin))}
    oracle = s2r.true_model_scores(wv, held, world["objs"], window, d.settings)
    base_held = d.gap_before["heldout_rms_m"]
    check = d.base_check
    auto = {"heldout_rms_m": base_held, "used": "fitted", "refit": False}
    if (check.get("starts") or {}).get("suspect"):
        da = diagnose(
            world["vehicle"],
            s2r.FREE,
            train,
            held,
            DiagnoseOptions(candidates=[], window_s=window, dt=s2r.DT, max_nfev=nfev, train_starts="auto"),
            rng=np.random.default_rng(seed),
        )
        ts = da.base_check["train_starts"]
        auto = {"heldout_rms_m": da.gap_before["heldout_rms_m"], "used": ts["used"], "refit": True, **ts}
    best_independent = min(held_of.values())
    return {
        "id": case["id"],
        "truth": world["truth"],
        "rate_hz": cfg["rate_hz"],
        "position_sd_m": cfg["position_sd_m"],
        "n_train": cfg["n_train"],
        "n_heldout": cfg["n_heldout"],
        "start_rule": d.settings["start_rule"],
        "base_heldout_rms_m": base_held,
        "base_cost": float(d.base.fit.cost),
        "truth_start_cost": float(f_truth.cost),
        "truth_start_heldout_rms_m": held_of["truth_start"],
        "kinematic_starts_heldout_rms_m": held_of["kinematic"],
        "ratio_to_independent": base_held / best_independent,
        "auto": auto,
        "auto_ratio_to_independent": auto["heldout_rms_m"] / best_independent,
        "true_model_heldout_rms_m": oracle["heldout_rms_m"],
        "noise_floor_m": d.noise_floor["heldout_rms_m"],
        "check": {k: check[k] for k in ("ratio", "suspect", "message")},
        "starts": check.get("starts"),
        "seconds": time.perf_counter() - tic,
    }


def summarise(rows: list[dict]) -> dict:
    hidden = [r for r in rows if r["truth"]]
    controls = [r for r in rows if not r["truth"]]
    ratios = [r["ratio_to_independent"] for r in hidden]
    auto = [r["auto_ratio_to_independent"] for r in hidden]
    return {
        "max_auto_ratio_to_independent": max(auto) if auto else None,
        "n_auto_within_target": sum(x <= TARGET_RATIO for x in auto),
        "n_auto_kinematic": sum(r["auto"]["used"] == "kinematic" for r in rows),
        "n_controls_auto_kinematic": sum(r["auto"]["used"] == "kinematic" for r in controls),
        "n_auto_better": sum(r["auto"]["heldout_rms_m"] < 0.9 * r["base_heldout_rms_m"] for r in rows),
        "n_auto_worse": sum(r["auto"]["heldout_rms_m"] > 1.1 * r["base_heldout_rms_m"] for r in rows),
        "worst_auto_factor": max((r["auto"]["heldout_rms_m"] / r["base_heldout_rms_m"] for r in rows), default=None),
        "n_cases": len(rows),
        "n_hidden": len(hidden),
        "n_controls": len(controls),
        "max_ratio_to_independent": max(ratios) if ratios else None,
        "median_ratio_to_independent": float(np.median(ratios)) if ratios else None,
        "n_within_target": sum(x <= TARGET_RATIO for x in ratios),
        "target_ratio": TARGET_RATIO,
        "n_hidden_suspect": sum(r["check"]["suspect"] for r in hidden),
        "n_hidden_starts_flagged": sum(bool(r["starts"] and r["starts"]["suspect"]) for r in hidden),
        "n_controls_suspect": sum(r["check"]["suspect"] for r in controls),
        "max_control_start_z": max(
            (abs(w["z"]) for r in controls if r["starts"] for w in r["starts"]["worst"][:1]), default=None
        ),
    }


def starts_cell(starts: dict | None) -> str:
    """Flagged window starts of the training and the held-out windows (the check judges each set)."""
    if not starts:
        return "-"
    return ", ".join(f"{b['n_flagged']} / {b['n_windows']}" for b in starts["by_set"].values())


def write_report(out: Path, s: dict, rows: list[dict], command: str) -> None:
    from bayesid.report import fmt, md_table

    table = [
        [
            r["id"],
            f"{r['rate_hz']} Hz, {fmt(r['position_sd_m'], 2)} m",
            f"{r['n_train']} / {r['n_heldout']}",
            fmt(r["base_heldout_rms_m"]),
            fmt(r["truth_start_heldout_rms_m"]),
            fmt(r["kinematic_starts_heldout_rms_m"]),
            fmt(r["ratio_to_independent"]),
            f"{fmt(r['auto']['heldout_rms_m'])} ({r['auto']['used']})",
            fmt(r["true_model_heldout_rms_m"]),
            fmt(r["check"]["ratio"]),
            starts_cell(r["starts"]),
            "suspect" if r["check"]["suspect"] else "ok",
        ]
        for r in rows
    ]
    text = [
        "# Base-fit benchmark (issue 40)",
        "",
        f"`{command}`",
        "",
        "Cases: those of `studies/sim_to_real.py` without a velocity log (same seed and world tracks). "
        "Method: the module docstring of `studies/base_fit_check.py`.",
        "",
        "## Targets",
        "",
        md_table(
            ["target", "reached", "wanted"],
            [
                [
                    "base held-out RMS / the better independent fit's, hidden-effect cases (max)",
                    fmt(s["max_ratio_to_independent"]),
                    f"<= {TARGET_RATIO:g}",
                ],
                [
                    "hidden-effect cases within the target",
                    f"{s['n_within_target']} / {s['n_hidden']}",
                    f"{s['n_hidden']} / {s['n_hidden']}",
                ],
                [
                    "the same with `--train-starts auto` (max ratio)",
                    fmt(s["max_auto_ratio_to_independent"]),
                    f"<= {TARGET_RATIO:g}",
                ],
                [
                    "hidden-effect cases within the target with `--train-starts auto`",
                    f"{s['n_auto_within_target']} / {s['n_hidden']}",
                    f"{s['n_hidden']} / {s['n_hidden']}",
                ],
                ["controls the base-fit check calls suspect", f"{s['n_controls_suspect']} / {s['n_controls']}", "0"],
            ],
        ),
        "",
        f"Median ratio {fmt(s['median_ratio_to_independent'])}. The base-fit check calls "
        f"{s['n_hidden_suspect']} of {s['n_hidden']} hidden-effect fits suspect; in "
        f"{s['n_hidden_starts_flagged']} of them because their window starts contradict the tracks' kinematics. "
        f"With `--train-starts auto` the held starts were used in {s['n_auto_kinematic']} case(s) "
        f"({s['n_controls_auto_kinematic']} of them controls): the held-out error fell by more than 10 % in "
        f"{s['n_auto_better']} and rose by more than 10 % in {s['n_auto_worse']} (at worst x "
        f"{fmt(s['worst_auto_factor'])}). Its choice is made on the training runs alone (which fit predicts "
        "them better under the held-out protocol), and that choice is not always the one the held-out runs "
        "would make: `auto` is an option, not the default.",
        "",
        "## Cases",
        "",
        "Held-out 60 s protocol RMS position error, m. *truth start*: the same fit started at the world's "
        "coefficients; *kinematic starts*: window starts held at the tracks' kinematics; *ratio*: base / the "
        "better of the two; *auto*: the base fit with `--train-starts auto` (refitted with starts held at the "
        "kinematics when the check finds the fitted ones inconsistent, kept if it predicts its own training tracks "
        "better under the held-out protocol); *true*: the true model (world coefficients and the hidden effect); *check ratio*: "
        "the base fit's held-out / training RMS under the same protocol; *starts flagged*: window starts more "
        "than 5 sd from the kinematics, of the training windows and of the held-out windows (more than 10 % of "
        "either makes the check suspect).",
        "",
        md_table(
            [
                "case",
                "log",
                "train / held-out",
                "base",
                "truth start",
                "kinematic starts",
                "ratio",
                "auto (starts used)",
                "true",
                "check ratio",
                "starts flagged",
                "check",
            ],
            table,
        ),
        "",
    ]
    (out / "report.md").write_text("\n".join(text))


def main() -> int:
    import matplotlib

    matplotlib.use("Agg")  # the study writes its figures, it never shows them
    args = parse_args()
    from bayesid.report import prepare_out, write_json, write_manifest

    t0 = time.perf_counter()
    out = prepare_out(args.out)
    journal_path = out / "journal.jsonl"
    if args.fresh and journal_path.exists():
        journal_path.unlink()
    journal = Journal(journal_path, {"seed": args.seed, "quick": args.quick, "version": VERSION})
    tasks = [Task(c["id"], c, (c, args.seed, args.quick)) for c in cases(args.quick)]
    n_done = sum(journal.get(t) is not None for t in tasks)
    print(f"{n_done} case(s) resumed from {journal_path}, {len(tasks) - n_done} to run", flush=True)

    def done(task, r, seconds):
        if isinstance(r, TaskError):
            print(f"  {r}", flush=True)
            return
        print(
            f"  {r['id']:24s} base {r['base_heldout_rms_m']:.3g} m, truth start {r['truth_start_heldout_rms_m']:.3g},"
            f" kinematic {r['kinematic_starts_heldout_rms_m']:.3g} (ratio {r['ratio_to_independent']:.2f});"
            f" check {'suspect' if r['check']['suspect'] else 'ok'} ({r['seconds']:.0f} s)",
            flush=True,
        )

    outs = run_tasks(run_case, tasks, Runner(jobs=args.jobs, scheduler=args.scheduler, journal=journal), on_done=done)
    rows = [r for r in outs if not isinstance(r, TaskError)]
    failed = [{"id": f.key, "error": f.error} for f in outs if isinstance(f, TaskError)]
    s = summarise(rows)
    command = "python studies/base_fit_check.py" + (" --quick" if args.quick else "")
    write_json(out / "results.json", {"summary": s, "cases": rows, "failed_cases": failed, "quick": args.quick})
    write_report(out, s, rows, command)
    write_manifest(out, seed=args.seed, quick=args.quick, t_start=t0, extra={"tasks_resumed_from_journal": n_done})
    print(s)
    return 1 if failed else 0


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except ValueError as e:  # a journal of another run, a bad option: a message, not a traceback
        print(f"error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
