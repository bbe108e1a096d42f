"""Real turns held out (issue 67): the Esso Osaka model's zigzag and random runs to train, its turning
circles held out; what ``diagnose`` names, with the ship's surge and propeller in the catalogue, and
how far the turns' errors shrink.

Method
------
- Data (read from ``shared/data/real/esso-osaka-frt``, never copied; ``bayesid.data.datasets``):
  the 3 m model's free-running runs in the Inukai pond, 10 Hz, with the measured wind. Training: every
  zigzag and random run; held out: every turning run (the trimmed ``turn_cut_*`` copies left out).
- Model: the packaged ``esso_osaka_3m`` file, its ``[fit] free`` list.
- Diagnosis (``bayesid.analysis.gap.diagnose``): the ship catalogue less what the base model fits
  (:func:`bayesid.analysis.gap.diagnose.catalogue_candidates`: wind, current, delay, the MMG 2015
  wake in a turn, the rudder's resistance ``tR``, the thrust deduction ``tP``, sensor lag; the
  shifts of ``wP`` and ``Xuu`` are left out because the base model fits both), 60 s scoring windows
  from the measured start, the ship fit window, structure discovery with its alternatives, no design.
- Read: the verdict; each candidate's share of the held-out excess over the noise floor; *where*'s
  dominant channel; the held-out RMS before and after against the floor; and the turning circles
  the base model and the model with the named effects predict against the measured ones (advance,
  tactical and steady diameters, speed loss; each held-out turn from its own measured approach).

    python studies/esso_turns.py [--quick] [--out DIR] [--data DIR] [--coupling-speed U]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

INDICES = ("advance_m", "tactical_diameter_m", "steady_turning_diameter_m", "speed_loss")


def turn_indices(model, p, tracks) -> list:
    """Measured and predicted turning indices of each held-out turn, each run whole from its own
    measured first state with its logged inputs (:func:`bayesid.estimation.prediction.training_turns`,
    the fit report's check, here on runs the fit never saw)."""
    from bayesid.estimation.prediction import FittedModel, training_turns

    return training_turns(FittedModel(model, np.asarray(p, float)), tracks)


def main() -> int:
    import matplotlib

    matplotlib.use("Agg")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--quick",
        action="store_true",
        help="two training runs (their first 200 s), one turn, two candidates, few iterations",
    )
    ap.add_argument("--out", default="reports/esso_turns")
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"))
    ap.add_argument("--max-nfev", type=int, default=30)
    ap.add_argument("--seed", type=int, default=67)
    ap.add_argument(
        "--coupling-speed",
        choices=("Ut", "U"),
        default="Ut",
        help="the hull's coupling terms over the package's Ut (default) or MMG 2015's U (a ship file's [form])",
    )
    args = ap.parse_args()
    from bayesid.analysis.gap import DiagnoseOptions, diagnose
    from bayesid.analysis.gap.diagnose import catalogue_candidates
    from bayesid.analysis.gap.discovery import DiscoveryOptions
    from bayesid.data import datasets
    from bayesid.models import ship
    from bayesid.report import write_diagnosis, write_json, write_manifest
    from bayesid.tasks import Runner

    esso_dir = Path(args.data) / "esso-osaka-frt"
    if not esso_dir.is_dir():
        print(f"real data not found under {args.data}: nothing to do (the study needs shared/data/real)")
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    runs = [p for p in datasets.list_runs(esso_dir, "esso-osaka") if "turn_cut" not in p.name]
    tracks = [datasets.read_run(p, "esso-osaka") for p in runs]
    train = [t for t in tracks if t.name.startswith(("zigzag", "random"))]
    held = [t for t in tracks if t.name.startswith("turn")]
    if args.quick:  # a smoke test: the first 200 s of two training runs, one turn held out whole
        train, held, args.max_nfev = train[:2], held[:1], min(args.max_nfev, 4)
        train = [t.slice_time(t.t[0], t.t[0] + 200.0) for t in train]
    esso = ship.load_ship("esso_osaka_3m")
    if args.coupling_speed != "Ut":
        esso = esso.with_form(coupling_speed=args.coupling_speed)
    said = []
    cands = catalogue_candidates(
        ship.ShipModel, train + held, Runner(progress=said.append), free=esso.free, vehicle=esso
    )
    if args.quick:
        cands = [c for c in cands if c in ("wake_in_turn", "rudder_resistance")]
    log = lambda m: print(m, flush=True)  # noqa: E731
    diag = diagnose(
        esso,
        esso.free,
        train,
        held,
        DiagnoseOptions(
            candidates=cands,
            window_s=60.0,
            fit_window_s=ship.FIT_WINDOW_S,
            dt=0.2,
            max_nfev=args.max_nfev,
            start="measured",
            discover=DiscoveryOptions(max_nfev=args.max_nfev, **({"max_candidates": 2} if args.quick else {})),
            design=None,
        ),
        rng=np.random.default_rng(args.seed),
        runner=Runner(progress=lambda m: log(f"esso turns: {m}")),
    )
    write_diagnosis(diag, out / "diagnosis", held, command="studies/esso_turns.py")
    res = diag.to_dict()
    before, after = res["gap_before"]["heldout_rms_m"], (res.get("gap_discovered") or res["gap_after"])["heldout_rms_m"]
    floor = res["noise_floor"]["heldout_rms_m"]
    final = diag.after
    turns = {
        "base": turn_indices(diag.base.model, diag.base.fit.p, held),
        "after_effects": turn_indices(final.model, final.fit.p, held),
    }
    doc = {
        "quick": bool(args.quick),
        **({"coupling_speed": args.coupling_speed} if args.coupling_speed != "Ut" else {}),
        "train_runs": [t.name for t in train],
        "heldout_runs": [t.name for t in held],
        "candidates": cands,
        "left_out": said,
        "verdict": res["verdict"],
        "effects_added": res["effects_added"],
        "ranking": [
            {
                k: r[k]
                for k in ("effect", "share_of_excess", "heldout_rms_m", "delta_bic", "window_p_value", "parameters")
            }
            for r in res["ranking"]
        ],
        "dominant_channel": res["where"].get("dominant_channel"),
        "channels": res["where"].get("channels"),
        "discovery_routed": res["where"].get("discovery_routed"),
        "found": (res.get("discovery") or {}).get("found"),
        "heldout_rms_before_m": before,
        "heldout_rms_after_m": after,
        "floor_m": floor,
        "excess_shrink": (before - after) / (before - floor) if before > floor else None,
        "turns": turns,
        "seconds": res["seconds"],
    }
    write_json(out / "results.json", doc)
    write_report(out, doc, args)
    write_manifest(out, seed=args.seed, quick=args.quick, t_start=t_start)
    print(f"verdict: {doc['verdict']}; held-out RMS {before:.3f} -> {after:.3f} m (floor {floor:.3f} m)")
    return 0


def _turn_rows(doc) -> list:
    from bayesid.report.markdown import fmt

    rows = []
    for which in ("base", "after_effects"):
        for t in doc["turns"][which]:
            m, p = t["measured"], t["predicted"]
            rows.append(
                [
                    which,
                    t["run"],
                    *(f"{fmt(m.get(k))} / {fmt(p.get(k))}" for k in INDICES),
                    t["suspect"] or "-",
                    fmt(t.get("wind_to_resistance")),
                ]
            )
    return rows


def write_report(out: Path, doc: dict, args) -> None:
    from bayesid.report.markdown import fmt, md_table

    rank = [
        [r["effect"], fmt(r["share_of_excess"]), fmt(r["heldout_rms_m"]), fmt(r["delta_bic"]), fmt(r["window_p_value"])]
        for r in doc["ranking"]
    ]
    lines = [
        "# Real turns held out: Esso Osaka",
        "",
        "`python studies/esso_turns.py"
        + (" --quick" if args.quick else "")
        + (f" --coupling-speed {args.coupling_speed}" if args.coupling_speed != "Ut" else "")
        + "`",
        "",
        __doc__.split("Method\n------\n")[1].split("\n    python")[0].strip(),
        "",
        *(
            [
                f"- Form: the hull's coupling terms over MMG 2015's U (``[form] coupling_speed = "
                f'"{args.coupling_speed}"``), in place of the packaged file\'s Ut.',
                "",
            ]
            if args.coupling_speed != "Ut"
            else []
        ),
        "## Result",
        "",
        f"- Training: {len(doc['train_runs'])} runs (zigzag and random); held out: {len(doc['heldout_runs'])} "
        "turning runs.",
        f"- Verdict: **{doc['verdict']}**; effects named: {', '.join(doc['effects_added']) or 'none'}; terms kept: "
        f"{', '.join(doc['found'] or []) or 'none'}.",
        f"- *Where*: the dominant channel is {doc['dominant_channel']}"
        + (f"; {doc['discovery_routed']}" if doc["discovery_routed"] else "")
        + ".",
        f"- Held-out 60 s RMS {fmt(doc['heldout_rms_before_m'])} m -> {fmt(doc['heldout_rms_after_m'])} m "
        f"(noise floor {fmt(doc['floor_m'])} m): the excess over the floor shrank by {fmt(doc['excess_shrink'])}.",
        *(f"- Left out: {s}" for s in doc["left_out"]),
        "",
        "## Each candidate on the held-out turns",
        "",
        md_table(["effect", "share of the excess", "held-out RMS (m)", "training ΔBIC", "window p"], rank),
        "",
        "## Turning circles, measured / predicted",
        "",
        "Each held-out turn run whole from its measured first state with its logged inputs, by the base model and "
        "by the model with the named effects (kept terms not included); a run the index reader does not read as a "
        "turning circle is left out. *Suspect*: the component :func:`bayesid.estimation.prediction.training_turns` "
        "suspects where the tactical or steady diameter is more than 5 % off (``wind`` where the run's logged wind "
        "pushes with at least 0.25 of the hull's resistance, *wind / resistance*, and the model has no wind effect; "
        "else the speed in the turn or the turning forces by the speed loss).",
        "",
        md_table(["model", "run", *INDICES, "suspect", "wind / resistance"], _turn_rows(doc)),
        "",
    ]
    (out / "report.md").write_text("\n".join(lines))


if __name__ == "__main__":
    raise SystemExit(main())
