"""The newcomer's AUV (issue 69), rebuilt: a small AUV's own logs through the Python API, as a new
user brings them -- a compass heading, 5 Hz, no velocity log -- and what each step says.

Method
------
- Vehicle: REMUS 100 as packaged (``bayesid/vehicles/remus100.toml``, Prestero 2001); the
  user's file has ``Nv`` x 1.25, ``Ndr`` x 0.75 and ``Yr`` x 1.30 (the fit's job), and the world a
  constant current of 0.19 m/s towards 30 deg (the diagnosis's job).
- Logs: a 15 deg zigzag and a 15 deg turn to train, a 10 deg zigzag the other way and a -12 deg
  turn held out, 90 s each, simulated at 0.05 s (``bayesid.models.world``) and logged at 5 Hz with
  0.5 m of position and 0.5 deg of heading noise; x, y, psi and the inputs only (no u, v, r); an
  epoch clock; the heading wrapped to (-pi, pi] as a compass logs it, written to CSV and read back
  with ``bayesid.read_csv`` (and an unwrapped copy, to compare).
- Steps, each as the API gives it: the noise estimate of every log against the noise added; the
  fit (``bayesid.identify``: the six horizontal coefficients, the family's defaults otherwise) on
  the wrapped and on the unwrapped logs; the diagnosis (``bayesid.diagnose``, the default catalogue);
  each with the family's default windows and with the 5 s windows and fitted starts of the docs'
  REMUS walkthrough (``docs/vessel.rst``).
- Read: the issue's targets -- the wrapped and unwrapped logs give the same fit and sds; the
  heading's noise read within 2 x; the diagnosis names the current, or says that these logs
  cannot resolve it; no candidate that contains the base model fits the training runs worse.

    python studies/newcomer_auv.py [--quick] [--out DIR] [--seed N] [--render]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ROOT = Path(__file__).resolve().parents[1]
REMUS = ROOT / "bayesid" / "vehicles" / "remus100.toml"
#: The user's file: the docs' coefficients times these (the fit's job)
USER_ERRORS = {"Nv": 1.25, "Ndr": 0.75, "Yr": 1.30}
#: The world's current (the diagnosis's job): speed m/s, direction towards, deg from north
CURRENT = (0.19, 30.0)
#: The noise added: m, m, rad
NOISE = {"x": 0.5, "y": 0.5, "psi": math.radians(0.5)}
FREE = ("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr")
#: (kind, rudder deg, first side) of the runs: two to train, two held out
RUNS = (("zigzag", 15.0, 1), ("turning_circle", 15.0, 1), ("zigzag", 10.0, -1), ("turning_circle", -12.0, 1))
#: The logs' epoch clock: 2023-11-14 (s since 1970)
EPOCH = 1.7e9


def parse_args():
    from bayesid.tasks import add_arguments

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="few iterations (a smoke test)")
    ap.add_argument("--out", default="reports/newcomer_auv")
    ap.add_argument("--seed", type=int, default=69)
    ap.add_argument("--render", action="store_true", help="rewrite report.md from --out's results.json")
    add_arguments(ap)
    return ap.parse_args()


def write_logs(folder: Path, seed: int) -> dict:
    """The four runs as CSV files, the heading wrapped and unwrapped: ``{"wrapped": [paths],
    "unwrapped": [paths]}``."""
    from bayesid.data.track import Track, write_csv
    from bayesid.models import manoeuvres as mv
    from bayesid.models.world import LogOptions, world_track

    truth = load_truth()
    cur = {"current": dict(zip(("current_north_mps", "current_east_mps"), _current_components()))}
    log = LogOptions(noise=NOISE, sample_every=4, hold_inputs=True)
    rng = np.random.default_rng(seed)
    out = {"wrapped": [], "unwrapped": []}
    for i, (kind, angle, side) in enumerate(RUNS):
        if kind == "zigzag":
            m = mv.zigzag(truth, angle, dt=0.05, duration=90.0, first_sign=side)
        else:
            m = mv.turning_circle(truth, angle, dt=0.05, duration=90.0)
        tr = world_track(truth, m, cur, rng, log)
        keep = {k: np.asarray(tr[k], float) for k in ("x", "y", "psi", "delta_r", "delta_s", "delta_b", "n") if k in tr}
        name = f"{'train' if i < 2 else 'held'}{i}_{kind}_{angle:+g}"
        for form in out:
            data = dict(keep, psi=np.angle(np.exp(1j * keep["psi"])) if form == "wrapped" else keep["psi"])
            path = folder / form / f"{name}.csv"
            path.parent.mkdir(parents=True, exist_ok=True)
            write_csv(Track(tr.t + EPOCH + 200.0 * i, data, name=name), path)
            out[form].append(path)
    return out


def user_vehicle():
    """The user's file: the packaged REMUS 100 with :data:`USER_ERRORS`."""
    truth = load_truth()
    return truth.with_coefficients({k: truth.coefficients[k] * f for k, f in USER_ERRORS.items()})


def fit_of(tracks, args, window_s=None) -> dict:
    """``bayesid.identify`` with the family's defaults (and ``window_s``, fitted starts, when given):
    estimates, sds and the warnings it raised."""
    import warnings

    import bayesid

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        kw = {} if window_s is None else {"window_s": window_s, "start": "fitted"}
        opts = bayesid.FitOptions(free=FREE, max_nfev=4 if args.quick else 60, **kw)
        res = bayesid.identify(user_vehicle(), tracks, opts)
    sd = np.sqrt(np.diag(res.cov))
    return {
        "estimate": dict(zip(res.fit.names, map(float, res.fit.p))),
        "sd": dict(zip(res.fit.names, map(float, sd))),
        "dt": res.model.dt,
        "window_s": res.window_s,
        "start_rule": res.start_rule,
        "train_rms_m": res.train_scores.get("rms_position_m"),
        "warnings": sorted({f"{w.category.__name__}: {str(w.message)[:300]}" for w in caught}),
    }


def diagnosis_of(train, held, window_s, args, out: Path, log) -> dict:
    """``bayesid.diagnose`` with the default catalogue at ``window_s`` (None: the default)."""
    import bayesid
    from bayesid.report import write_diagnosis
    from bayesid.tasks import Runner

    kw = {} if window_s is None else {"window_s": window_s, "fit_window_s": window_s, "start": "fitted"}
    opts = bayesid.DiagnoseOptions(max_nfev=4 if args.quick else 40, **kw)
    said = []
    t0 = time.perf_counter()
    d = bayesid.diagnose(
        user_vehicle(),
        list(FREE),
        train,
        held,
        opts,
        rng=np.random.default_rng(args.seed),
        runner=Runner(args.jobs, args.scheduler, progress=lambda m: (said.append(m), log(m))),
    )
    folder = out / f"diagnosis_{_label(window_s)}"
    write_diagnosis(d, folder, held, command="studies/newcomer_auv.py")
    doc = d.to_dict()
    rows = [
        {
            k: r.get(k)
            for k in (
                "effect",
                "heldout_rms_m",
                "share_of_excess",
                "delta_bic",
                "window_p_value",
                "role",
                "failed_fit",
                "parameters",
                "undetermined",
            )
        }
        for r in doc["ranking"]
    ]
    truth = dict(zip(("current_north_mps", "current_east_mps"), _current_components()))
    return {
        "window_s": doc["settings"].get("window_s"),
        "verdict": d.verdict,
        "floor": doc["noise_floor"],
        "gap_before": doc["gap_before"],
        "ranking": rows,
        "current_rank": next((i + 1 for i, r in enumerate(rows) if r["effect"] == "current"), None),
        "current_truth": truth,
        "failed_fits": [r["effect"] for r in rows if r["failed_fit"]],
        "said": said,
        "seconds": time.perf_counter() - t0,
        "report": str(folder.relative_to(out)),
    }


#: The windows of the fits and diagnoses: the family's defaults, and the docs' REMUS walkthrough's
#: 5 s fit and score windows with fitted starts (docs/vessel.rst: REMUS's sway-yaw dynamics are
#: unstable, an error in a window's start grows quickly)
WINDOWS = (None, 5.0)


def _label(window_s) -> str:
    return "default" if window_s is None else f"{window_s:g}s"


def _current_components() -> tuple:
    speed, towards = CURRENT
    return speed * math.cos(math.radians(towards)), speed * math.sin(math.radians(towards))


def run(args, out: Path, log) -> dict:
    from bayesid.data.track import read_csv
    from bayesid.protocol import estimate_noise

    paths = write_logs(out / "logs", args.seed)
    tracks = {form: [read_csv(p) for p in ps] for form, ps in paths.items()}
    noise = []
    for tr in tracks["wrapped"]:
        est = estimate_noise(tr, ["x", "y", "psi"], floor=False)
        noise.append(
            {
                "run": tr.name,
                "psi_wraps": tr.meta.get("psi_wraps", 0),
                **{f"{k}_over_truth": est[k] / NOISE[k] for k in ("x", "y", "psi")},
            }
        )
    psi_diff = max(
        float(np.max(np.abs(np.asarray(a["psi"], float) - np.asarray(b["psi"], float))))
        for a, b in zip(tracks["wrapped"], tracks["unwrapped"])
    )
    fits, same = {}, {}
    for w in WINDOWS:
        label = _label(w)
        log(f"fits, windows {label}: wrapped and unwrapped heading")
        fits[label] = {form: fit_of(ts[:2], args, w) for form, ts in tracks.items()}
        a, b = fits[label]["wrapped"], fits[label]["unwrapped"]
        same[label] = {
            "max_estimate_rel_diff": max(abs(a["estimate"][k] / b["estimate"][k] - 1.0) for k in FREE),
            "max_sd_rel_diff": max(abs(a["sd"][k] / b["sd"][k] - 1.0) for k in FREE),
            "max_shift_in_sd": max(
                abs(a["estimate"][k] - b["estimate"][k]) / max(a["sd"][k], b["sd"][k]) for k in FREE
            ),
        }
    neutral = actuator_neutral_gap(tracks["wrapped"][:2])
    diags = {}
    for w in WINDOWS:
        log(f"diagnosis, windows {_label(w)}")
        diags[_label(w)] = diagnosis_of(tracks["wrapped"][:2], tracks["wrapped"][2:], w, args, out, log)
    user = user_vehicle()
    return {
        "quick": bool(args.quick),
        "settings": {
            "vehicle": str(REMUS.relative_to(ROOT)),
            "user_errors": USER_ERRORS,
            "current_mps_towards_deg": CURRENT,
            "noise": NOISE,
            "runs": [dict(zip(("kind", "rudder_deg", "first_side"), r)) for r in RUNS],
            "log_hz": 5.0,
            "seed": args.seed,
        },
        "true_coefficients": {k: load_truth().coefficients[k] for k in FREE},
        "user_coefficients": {k: user.coefficients[k] for k in FREE},
        "noise_estimates": noise,
        "psi_read_max_abs_diff_rad": psi_diff,
        "actuator_neutral_max_state_diff": neutral,
        "fits": fits,
        "wrapped_against_unwrapped": same,
        "diagnoses": diags,
    }


def actuator_neutral_gap(tracks) -> dict:
    """How far the actuator effect at its ``neutral`` parameters (no lag, 2000 deg/s) is from the
    model without it: the largest difference of the simulated states (m, rad, m/s, rad/s; the user's
    file, measured starts, 5 s windows) per training run. A rudder step becomes a ramp at the rate
    limit, so the effect contains the base model only nearly, and its nested refit can end above it."""
    from bayesid.models import build_model

    base = build_model(user_vehicle(), list(FREE))
    act = build_model(user_vehicle(), list(FREE), ["actuator"])
    p = np.concatenate([base.start(), act.effects[0].neutral])
    out = {}
    for tr in tracks:
        Sb = base.simulate(base.context(tr, 5.0, start="measured"), base.start()[None])[0]
        Sa = act.simulate(act.context(tr, 5.0, start="measured"), p[None])[0]
        out[tr.name] = float(np.nanmax(np.abs(Sa - Sb)))
    return out


def load_truth():
    """The packaged REMUS 100 file: the world's vehicle."""
    from bayesid.models import load_any_vehicle

    return load_any_vehicle(str(REMUS))


def render(R: dict) -> str:
    from bayesid.report.markdown import fmt, md_table

    lines = [
        "# The newcomer's AUV: a REMUS 100's own logs through the Python API (issue 69)",
        "",
        "**Quick run** (smoke test; the committed report is the full run)." if R["quick"] else "Full run.",
        "",
        __doc__.split("Method\n------\n", 1)[1].split("\n    python")[0].strip(),
        "",
        "## Result",
        "",
        "### The noise each log reads (estimate / truth)",
        "",
        md_table(
            ["run", "heading wraps unwrapped on reading", "x", "y", "psi"],
            [
                [n["run"], n["psi_wraps"], fmt(n["x_over_truth"]), fmt(n["y_over_truth"]), fmt(n["psi_over_truth"])]
                for n in R["noise_estimates"]
            ],
        ),
        "",
        "### The fit on the wrapped and on the unwrapped heading",
        "",
        f"Read back, the wrapped heading equals the unwrapped one within {fmt(R['psi_read_max_abs_diff_rad'])} rad.",
        "",
    ]
    for label, fits in R["fits"].items():
        same = R["wrapped_against_unwrapped"][label]
        rows = [
            [
                k,
                fmt(R["true_coefficients"][k]),
                fmt(R["user_coefficients"][k]),
                *(f"{fmt(fits[f]['estimate'][k])} +- {fmt(fits[f]['sd'][k])}" for f in ("wrapped", "unwrapped")),
            ]
            for k in FREE
        ]
        w = fits["wrapped"]
        lines += [
            f"**{'Default windows' if label == 'default' else label + ' windows, fitted starts'}** "
            f"({fmt(w['window_s'])} s windows, model step {fmt(w['dt'])} s, start rule {w['start_rule']}; training "
            f"RMS {fmt(w['train_rms_m'])} m):",
            "",
            md_table(["coefficient", "truth", "user's file", "fit, wrapped log", "fit, unwrapped log"], rows),
            "",
            f"Largest relative difference wrapped / unwrapped: estimates {fmt(same['max_estimate_rel_diff'])}, sds "
            f"{fmt(same['max_sd_rel_diff'])}.",
            "",
            "Warnings `bayesid.identify` raised (wrapped logs):",
            "",
            *([f"- {x}" for x in w["warnings"]] or ["- none"]),
            "",
        ]
    for label, d in R["diagnoses"].items():
        fl, gb = d["floor"], d["gap_before"]
        lines += [
            f"### The diagnosis, {'default windows' if label == 'default' else label + ' windows, fitted starts'} "
            f"({fmt(d['window_s'])} s)",
            "",
            f"- Verdict: **{d['verdict']}** (the hidden effect: a current of {CURRENT[0]} m/s). The current ranks "
            f"{d['current_rank']} of {len(d['ranking'])}.",
            f"- Held-out RMS {fmt(gb['heldout_rms_m'])} m (training {fmt(gb['train_rms_m'])} m) against a noise floor "
            f"of {fmt(fl['heldout_rms_m'])} m; the floor's heading RMS {fmt(fl['heading_rms_deg'])} deg from a "
            f"{fmt(math.degrees(NOISE['psi']))} deg sensor: what a model of the right form scores on these windows, "
            "started from noisy positions, its coefficients known as well as the training runs tell them.",
            f"- Candidates that contain the base model and fitted the training runs worse than it: "
            f"{', '.join(d['failed_fits']) or 'none'}.",
            f"- Report: `{d['report']}/report.md`; {fmt(d['seconds'])} s.",
            "",
            md_table(
                [
                    "effect",
                    "held-out RMS (m)",
                    "share of the excess",
                    "training ΔBIC",
                    "window p",
                    "role",
                    "undetermined",
                ],
                [
                    [
                        r["effect"],
                        fmt(r["heldout_rms_m"]),
                        fmt(r["share_of_excess"]),
                        fmt(r["delta_bic"]),
                        fmt(r["window_p_value"]),
                        r["role"] or "-",
                        ", ".join(r["undetermined"] or []) or "-",
                    ]
                    for r in d["ranking"]
                ],
            ),
            "",
        ]
    gap = R["actuator_neutral_max_state_diff"]
    lines += [
        "### Read",
        "",
        f"- The logs read back equal to rounding ({fmt(R['psi_read_max_abs_diff_rad'])} rad), yet the fits on them "
        "differ, by up to "
        + "; ".join(
            f"{fmt(v['max_shift_in_sd'])} of their larger Laplace sd at {k} windows"
            for k, v in R["wrapped_against_unwrapped"].items()
        )
        + ": with fitted window starts on these two runs the fit lands in another optimum for a change of the data "
        "at rounding level. The difference is the fit's, not the reading's.",
        "- The actuator at its neutral parameters (no lag, 2000 deg/s) is the model without it only nearly: a "
        "rudder step becomes a ramp, and the simulated states differ by up to "
        + ", ".join(f"{fmt(v)} ({k})" for k, v in gap.items())
        + " over a training run from measured starts. Its nested refit can therefore end above the base fit, and "
        "the diagnosis reports it as a failed fit.",
        "",
    ]
    return "\n".join(lines + _targets(R)) + "\n"


def _targets(R: dict) -> list:
    """The issue's targets, each read from the results."""
    from bayesid.analysis.gap.verdict import Thresholds
    from bayesid.report.markdown import fmt

    th = Thresholds()  # the diagnoses' (default) thresholds
    psi = [n["psi_over_truth"] for n in R["noise_estimates"]]
    out = ["## Against the issue's targets", ""]
    same = R["wrapped_against_unwrapped"]
    out.append(
        f"- **Wrapped and unwrapped logs give the same fit and sds**: the logs read back equal within "
        f"{fmt(R['psi_read_max_abs_diff_rad'])} rad of heading; the fits differ by up to "
        + "; ".join(
            f"{fmt(v['max_estimate_rel_diff'])} (estimates) and {fmt(v['max_sd_rel_diff'])} (sds) at {k} windows"
            for k, v in same.items()
        )
        + ". A difference of the fits on logs equal to rounding is the fit's own sensitivity, not the reading: a fit "
        "that moves that much is not determined by these logs."
    )
    out.append(
        f"- **The heading's noise read within 2 x**: {fmt(min(psi))}-{fmt(max(psi))} x the 0.5 deg added "
        f"({'met' if all(0.5 <= x <= 2.0 for x in psi) else 'not met'})."
    )
    for k, d in R["diagnoses"].items():
        named = "current" in d["verdict"].split("->")[0]
        # the report's "the noise floor, not the model, decides" paragraph (report.diagnosis)
        floor = [
            r["effect"]
            for r in d["ranking"]
            if d["verdict"].startswith("none")
            and not r["failed_fit"]
            and r["window_p_value"] is not None
            and r["window_p_value"] < th.partial_p
            and r["delta_bic"] <= th.bic_threshold
        ]
        said = (
            f"; the report says the noise floor, not the model, decides the verdict, naming {', '.join(floor)}"
            if floor
            else ""
        )
        out.append(
            f"- **The diagnosis ({k} windows) names the current, or says the logs cannot resolve it**: verdict "
            f"{d['verdict']}; the current {'is named' if named else 'is not named'} (rank {d['current_rank']}){said}; "
            f"nesting candidates that fit the training runs worse than the base: {len(d['failed_fits'])}"
            + (
                f" ({', '.join(d['failed_fits'])}: reported as a failed fit, not as evidence)"
                if d["failed_fits"]
                else ""
            )
            + "."
        )
    return out


def main() -> int:
    import json

    from bayesid.report import prepare_out, write_json, write_manifest

    args = parse_args()
    out = prepare_out(args.out)
    if args.render:
        R = json.loads((out / "results.json").read_text())
        (out / "report.md").write_text(render(R))
        return 0
    t0 = time.perf_counter()
    log = lambda m: print(m, flush=True)  # noqa: E731
    R = run(args, out, log)
    write_json(out / "results.json", R)
    (out / "report.md").write_text(render(R))
    write_manifest(out, seed=args.seed, quick=args.quick, t_start=t0)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
