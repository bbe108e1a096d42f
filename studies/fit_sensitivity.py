"""How much do the real-data protocol scores depend on reasonable fit settings, and does any
setting win when it is chosen on training runs only?

Method
------
- Data and models as in ``studies/real_ships.py``: Esso Osaka 3 m model with the wind effect
  (the protocol table's "after" model), KVLCC2 7 m model at HSVA without effects; the vehicle
  files' free coefficients; 40 least-squares evaluations; residual (two-step GLS) weighting.
- Settings: the multiple-shooting window of the fit (15, 30, 60 s; the reference is 30 s, the
  issue-8 baseline's window and the package's first default)
  and the channels in the objective (every logged channel, or x, y, psi only: on both data sets
  the logged velocities are estimates derived from the same positions and heading, see the data
  READMEs).
- Splits: the issue's validation split (the numbers real_ships reports) and two splits of the
  *training* runs only (the validation held-out runs left out altogether), each holding out
  different runs of every kind. A setting that is better only on the validation split was
  chosen by the validation data; one that is better on the training-only splits too is a
  candidate for a default.
- Every fit starts from the equation-error seed (``bayesid.estimation.identify``, without the vehicle file's priors
  and without calibrating bands: the data and the setting alone) and is scored by the
  fixed window protocol (30 s and 60 s windows) on its split's held-out runs.
- Fits are tasks of :mod:`bayesid.tasks` (``--jobs N`` worker processes, or ``--scheduler`` on
  Dask); each finished fit is appended to ``journal.jsonl`` with the key it depends on (split,
  setting, evaluation budget) under the data's digest, and a re-run reuses it (``--fresh``
  starts over; a journal of other data or settings is refused).

    python studies/fit_sensitivity.py [--quick] [--out DIR] [--data DIR] [--fresh] [--jobs N] [--scheduler ADDRESS]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bayesid.tasks import Journal, Runner, Task, TaskError, add_arguments, parse_checked, run_tasks  # noqa: E402

ESSO_VALIDATION = [
    "random_06-Aug-2020_16_24_25_6",
    "turn_14-Oct-2020_15_06_53",
    "zigzag_31-Jul-2020_13_57_45",
    "berthing_12-Nov-2020_11_38_50",
]
KVLCC2_VALIDATION = ["Z_10_10_P", "Z_20_10_S", "Z_35_05", "Z_15_01"]
#: held-out runs of each split; the training-only splits never see the validation held-out runs
SPLITS = {
    "esso_osaka": {
        "validation": ESSO_VALIDATION,
        "train_cv_a": [
            "random_31-Jul-2020_12_29_58",
            "turn_14-Sep-2020_13_39_32",
            "zigzag_31-Jul-2020_13_22_52",
            "berthing_12-Nov-2020_11_14_47",
        ],
        "train_cv_b": [
            "random_03-Aug-2020_11_04_37",
            "turn_14-Oct-2020_14_29_49",
            "zigzag_31-Jul-2020_14_03_39",
            "berthing_12-Nov-2020_13_09_11",
        ],
    },
    "kvlcc2_hsva": {
        "validation": KVLCC2_VALIDATION,
        "train_cv_a": ["Z_10_05", "Z_20_10_P", "Z_30_05"],
        "train_cv_b": ["Z_10_10_S", "Z_15_05", "Z_25_05"],
    },
}
SETTINGS = {  # name -> (fit window s, channels in the objective)
    "w30_all": (30.0, None),
    "w15_all": (15.0, None),
    "w60_all": (60.0, None),
    "w30_xypsi": (30.0, ("x", "y", "psi")),
}
REFERENCE = "w30_all"
EFFECTS = {"esso_osaka": ["wind"], "kvlcc2_hsva": []}


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two runs, 3 evaluations, two settings (a smoke test)")
    ap.add_argument("--out", default="reports/fit_sensitivity")
    ap.add_argument("--data", default=str(ROOT / ".." / "shared" / "data" / "real"))
    ap.add_argument("--seed", type=int, default=2026, help="unused: the fits are deterministic (kept for the contract)")
    ap.add_argument("--fresh", action="store_true", help="start over: remove the journal of finished fits")
    add_arguments(ap, jobs_default=os.cpu_count() or 1)
    ap.add_argument("--max-nfev", type=int, default=40)
    return parse_checked(ap)


def load_runs(data: Path, dataset: str):
    """All runs of a data set as Tracks (Esso: the trimmed ``turn_cut_*`` copies left out)."""
    from bayesid.data import datasets

    if dataset == "esso_osaka":
        paths = [p for p in datasets.list_runs(data / "esso-osaka-frt", "esso-osaka") if "turn_cut" not in p.name]
        return [datasets.read_run(p, "esso-osaka") for p in paths]
    return [datasets.read_run(p, "simman-hsva") for p in datasets.list_runs(data / "kvlcc2-simman-hsva", "simman-hsva")]


DATA_FOLDERS = {"esso_osaka": "esso-osaka-frt", "kvlcc2_hsva": "kvlcc2-simman-hsva"}


def data_digest(data: Path, dataset: str) -> str:
    """SHA-256 over the relative paths and contents of a data set's files: a saved fit is reused
    only for the data it was made from."""
    import hashlib

    h = hashlib.sha256()
    root = data / DATA_FOLDERS[dataset]
    for p in sorted(q for q in root.rglob("*") if q.is_file()):
        h.update(str(p.relative_to(root)).encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()


def fit_key(job: dict, digest: str) -> dict:
    """What a saved fit depends on: data set, split and its held-out runs, the setting's fit
    window and channels, the evaluation budget, quick mode and the data's digest."""
    window, channels = SETTINGS[job["setting"]]
    return {
        "dataset": job["dataset"],
        "split": job["split"],
        "heldout": list(SPLITS[job["dataset"]][job["split"]]),
        "fit_window_s": window,
        "channels": list(channels) if channels else "all",
        "max_nfev": job["max_nfev"],
        "quick": bool(job["quick"]),
        "data_sha256": digest,
    }


def split_runs(tracks, dataset: str, split: str):
    """(train, held) of a split. Training-only splits drop the validation held-out runs first.
    Raises ValueError when a named held-out run is missing (named)."""

    def named(t, names):
        return any(t.name == n or t.name.endswith("_" + n) for n in names)

    pool = [t for t in tracks if split == "validation" or not named(t, SPLITS[dataset]["validation"])]
    names = SPLITS[dataset][split]
    held = [t for t in pool if named(t, names)]
    missing = [n for n in names if not any(named(t, [n]) for t in held)]
    if missing:
        raise ValueError(f"{dataset} split {split}: held-out run(s) not found: {', '.join(missing)}")
    return [t for t in pool if not named(t, names)], held


def run_fit(job: dict) -> dict:
    """One (data set, split, setting) fit and its protocol scores (runs in a worker)."""
    sys.path.insert(0, str(ROOT))
    from bayesid.estimation.identification import identify
    from bayesid.estimation.options import FitOptions
    from bayesid.estimation.prediction import predict
    from bayesid.models import ship

    t0 = time.perf_counter()
    tracks = load_runs(Path(job["data"]), job["dataset"])
    train, held = split_runs(tracks, job["dataset"], job["split"])
    if job["quick"]:
        train, held = train[:2], held[:1]
    vessel = ship.load_ship("esso_osaka_3m" if job["dataset"] == "esso_osaka" else "kvlcc2_7m")
    window, channels = SETTINGS[job["setting"]]
    # the fit settings alone, on the data alone: the journaled fits were made before fit used
    # the vehicle file's [prior] and calibrated its bands by default
    options = FitOptions(
        free=vessel.free,
        effects=EFFECTS[job["dataset"]],
        window_s=window,
        dt=0.2,
        max_nfev=job["max_nfev"],
        weighting="residual",
        channels=channels,
        start="measured",
        prior=False,
    )
    res = identify(vessel, train, options, calibration=None)
    out = {k: job[k] for k in ("dataset", "split", "setting", "key")}
    out.update(
        train_runs=[t.name for t in train],
        heldout_runs=[t.name for t in held],
        fit_window_s=window,
        channels=list(channels) if channels else "all",
        nfev=res.fit.n_simulations,
    )
    for key, w in (("w30", 30.0), ("w60", 60.0)):
        pr = predict(res.model, res.fit.p, held, w, start="measured")
        out[key] = pr.pooled["rms_position_m"]
        out[key + "_heading_deg"] = pr.pooled["rms_heading_deg"]
        out[key + "_per_run"] = {n: v["rms_position_m"] for n, v in pr.per_track.items()}
    out["parameters"] = dict(zip(res.model.param_names, map(float, res.fit.p)))
    out["seconds"] = time.perf_counter() - t0
    return out


def summarise(fits: list[dict]) -> dict:
    """Per data set: the score table (split x setting), each setting's ratio to the reference
    per split, whether it beats the reference on every training-only split, and its geometric
    mean ratio over the training-only splits."""
    S = {}
    for ds in SPLITS:
        rows = [f for f in fits if f["dataset"] == ds]
        if not rows:
            continue
        tab = {}
        for f in rows:
            tab.setdefault(f["split"], {})[f["setting"]] = {"w30": f["w30"], "w60": f["w60"]}
        ratio, verdict, mean_cv = {}, {}, {}
        for st in [s for s in SETTINGS if any(s in v for v in tab.values())]:
            r = {
                sp: {k: tab[sp][st][k] / tab[sp][REFERENCE][k] for k in ("w30", "w60")}
                for sp in tab
                if st in tab[sp] and REFERENCE in tab[sp]
            }
            ratio[st] = r
            cv = [v for sp, v in r.items() if sp != "validation"]
            verdict[st] = {k: bool(cv) and all(v[k] < 1.0 for v in cv) for k in ("w30", "w60")}
            mean_cv[st] = {
                k: float(np.exp(np.mean([np.log(v[k]) for v in cv]))) if cv else None for k in ("w30", "w60")
            }
        spread = {
            sp: {k: [min(v[k] for v in tab[sp].values()), max(v[k] for v in tab[sp].values())] for k in ("w30", "w60")}
            for sp in tab
        }
        S[ds] = {
            "scores": tab,
            "ratio_to_reference": ratio,
            "beats_reference_on_every_cv_split": verdict,
            "geometric_mean_ratio_cv": mean_cv,
            "spread": spread,
        }
    return S


def overall(S: dict) -> dict:
    """{setting: {w30, w60}}: the product over data sets of the geometric mean ratio to the
    reference on the training-only splits (settings run on every data set only)."""
    sets = [
        st
        for st in SETTINGS
        if all(d["geometric_mean_ratio_cv"].get(st, {}).get("w30") is not None for d in S.values())
    ]
    return (
        {
            st: {k: float(np.prod([d["geometric_mean_ratio_cv"][st][k] for d in S.values()])) for k in ("w30", "w60")}
            for st in sets
        }
        if S
        else {}
    )


def figure(S, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(S), figsize=(6 * len(S), 4.2), squeeze=False)
    for ax, (ds, d) in zip(axes[0], S.items()):
        splits = list(d["scores"])
        sets = [s for s in SETTINGS if all(s in d["scores"][sp] for sp in splits)]
        x = np.arange(len(splits))
        wdt = 0.8 / max(len(sets), 1)
        for i, st in enumerate(sets):
            ax.bar(x + (i - (len(sets) - 1) / 2) * wdt, [d["scores"][sp][st]["w60"] for sp in splits], wdt, label=st)
        ax.set_xticks(x, splits)
        ax.set_ylabel("held-out RMS position error, 60 s windows (m)")
        ax.set_title(ds)
        ax.legend(fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_report(out: Path, S: dict, fits: list[dict], quick: bool, fig: Path | None):
    from bayesid.report import fmt, md_table

    L = [
        "# Sensitivity of the real-data protocol scores to the fit settings",
        "",
        "Quick run (smoke test: two runs, few evaluations)." if quick else "Full run.",
        "",
        (__doc__ or "").split("Method\n------\n", 1)[1].split("\n    python", 1)[0].strip(),
        "",
    ]
    for ds, d in S.items():
        L += [
            f"## {ds}",
            "",
            "Held-out RMS position error (m) at 30 s / 60 s windows; in brackets the ratio to "
            f"the reference setting {REFERENCE} on the same split.",
            "",
        ]
        splits = list(d["scores"])
        rows = []
        for st in [s for s in SETTINGS if any(s in d["scores"][sp] for sp in splits)]:
            cells = []
            for sp in splits:
                v = d["scores"][sp].get(st)
                rr = d["ratio_to_reference"][st].get(sp)
                cells.append(
                    "-"
                    if v is None
                    else f"{fmt(v['w30'])} / {fmt(v['w60'])}"
                    + ("" if rr is None else f" ({rr['w30']:.3f} / {rr['w60']:.3f})")
                )
            b = d["beats_reference_on_every_cv_split"][st]
            g = d["geometric_mean_ratio_cv"][st]
            rows.append(
                [
                    st,
                    *cells,
                    "-" if st == REFERENCE else f"{'yes' if b['w30'] else 'no'} / {'yes' if b['w60'] else 'no'}",
                    "-" if g["w30"] is None else f"{g['w30']:.3f} / {g['w60']:.3f}",
                ]
            )
        L += [
            md_table(
                [
                    "setting",
                    *splits,
                    "better on every training-only split (30 s / 60 s)",
                    "mean ratio, training-only splits (30 s / 60 s)",
                ],
                rows,
            ),
            "",
        ]
        L += [
            "Spread over the settings (min - max, m): "
            + "; ".join(
                f"{sp}: 30 s {fmt(v['w30'][0])}-{fmt(v['w30'][1])}, 60 s {fmt(v['w60'][0])}-{fmt(v['w60'][1])}"
                for sp, v in d["spread"].items()
            ),
            "",
        ]
        winners = [st for st, b in d["beats_reference_on_every_cv_split"].items() if st != REFERENCE and b["w60"]]
        L += [
            "Settings better than the reference at 60 s on every training-only split: "
            + (", ".join(winners) if winners else "none")
            + ".",
            "",
        ]
    if fig is not None:
        L += [f"![60 s scores]({fig.relative_to(out).as_posix()})", ""]
    from bayesid.models.ship import FIT_WINDOW_S

    both = overall(S)
    L += [
        "## Both ships",
        "",
        "Product over the two ships of each setting's geometric mean ratio to the reference on the "
        "training-only splits (below 1: better than the reference):",
        "",
        md_table(["setting", "30 s", "60 s"], [[st, f"{v['w30']:.3f}", f"{v['w60']:.3f}"] for st, v in both.items()]),
        "",
        "Lowest at 30 s: "
        + min(both, key=lambda k: both[k]["w30"])
        + "; lowest at 60 s: "
        + min(both, key=lambda k: both[k]["w60"])
        + "."
        if both
        else "-",
        "",
    ]
    L += [
        "## Reading",
        "",
        f"- The package's ship fit window is {FIT_WINDOW_S:g} s (`bayesid.models.ship.FIT_WINDOW_S`). A per-ship "
        "choice would be read off the same training-only rows; one default for every ship is what a user "
        "gets on a hull nobody has tuned. Provenance: 15 s and x/y/psi were first tried on the validation "
        "split, where both looked better; the training-only splits were added to check them, and only the "
        "window passed.",
        "- The validation split is what real_ships reports against the issue's targets; a setting that "
        "helps there but not on the training-only splits was selected by the validation data and is not "
        "adopted. The spread across settings on one split is the size of difference a fit setting alone "
        "makes; compare it with the distance to a target before reading a shortfall as a modelling failure.",
        "- Per-run scores and fitted parameters of every fit are in results.json (`fits`).",
    ]
    (out / "report.md").write_text("\n".join(L) + "\n")


def main() -> int:
    args = parse_args()
    t_start = time.perf_counter()
    from bayesid.report import write_json, write_manifest

    data = Path(args.data)
    if not (data / "esso-osaka-frt").is_dir() or not (data / "kvlcc2-simman-hsva").is_dir():
        print(f"real data not found under {data}: nothing to do (the study needs shared/data/real)")
        return 0
    out = Path(args.out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    settings = [REFERENCE, "w30_xypsi"] if args.quick else list(SETTINGS)
    splits = {ds: (["validation"] if args.quick else list(sp)) for ds, sp in SPLITS.items()}
    nfev = min(args.max_nfev, 3) if args.quick else args.max_nfev
    jobs = [
        {"dataset": ds, "split": sp, "setting": st, "data": str(data), "quick": args.quick, "max_nfev": nfev}
        for ds in SPLITS
        for sp in splits[ds]
        for st in settings
    ]
    digests = {ds: data_digest(data, ds) for ds in SPLITS}
    journal_path = out / ("journal_quick.jsonl" if args.quick else "journal.jsonl")
    if args.fresh and journal_path.exists():
        journal_path.unlink()
        print(f"--fresh: removed {journal_path}")
    journal = Journal(journal_path, {"data_sha256": digests, "quick": bool(args.quick), "max_nfev": nfev})
    tasks = []
    for j in jobs:
        j["key"] = fit_key(j, digests[j["dataset"]])
        tasks.append(Task(f"{j['dataset']}__{j['split']}__{j['setting']}", j["key"], (j,)))
    n_done = sum(journal.get(t) is not None for t in tasks)
    print(
        f"{len(jobs)} fits, {len(jobs) - n_done} to run ({n_done} in {journal_path}) on "
        f"{args.scheduler or f'{args.jobs} worker(s)'}",
        flush=True,
    )

    def done(task, r, seconds):
        if isinstance(r, TaskError):
            print(f"  {r}", flush=True)
        else:
            print(f"  {task.key}: 30 s {r['w30']:.3f} m, 60 s {r['w60']:.3f} m ({r['seconds']:.0f} s)", flush=True)

    outs = run_tasks(run_fit, tasks, Runner(jobs=args.jobs, scheduler=args.scheduler, journal=journal), on_done=done)
    failed = [r for r in outs if isinstance(r, TaskError)]
    fits = [r for r in outs if not isinstance(r, TaskError)]
    if failed:  # the summary needs every fit of a setting; say which failed and stop
        print(f"{len(failed)} fit(s) failed; re-run to retry them (the finished ones are journaled)", file=sys.stderr)
        return 1
    S = summarise(fits)
    fig = figure(S, out / "figures" / "scores_60s.png") if S else None
    write_json(
        out / "results.json",
        {
            "summary": S,
            "both_ships": overall(S),
            "settings": {k: {"fit_window_s": w, "channels": list(c) if c else "all"} for k, (w, c) in SETTINGS.items()},
            "reference": REFERENCE,
            "splits": SPLITS,
            "quick": bool(args.quick),
            "max_nfev": nfev,
            "fits": sorted(fits, key=lambda f: (f["dataset"], f["split"], f["setting"])),
        },
    )
    write_report(out, S, fits, args.quick, fig)
    write_manifest(
        out,
        seed=args.seed,
        quick=args.quick,
        t_start=t_start,
        extra={
            "journal": journal_path.name,
            "tasks_resumed_from_journal": n_done,
            "tasks_run": len(tasks) - n_done,
            "task_seconds_total": sum(r["seconds"] for r in journal.records.values()),
        },
    )
    print(f"wrote {out / 'report.md'}")
    return 0


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except ValueError as e:  # a journal of other data or settings: a message, not a traceback
        print(f"error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
