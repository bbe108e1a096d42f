"""The report of a gap diagnosis (``bayesid diagnose``, ``studies/real_ships.py``):
``diagnosis.json``, ``report.md`` (how far, which effect, where) and its figures."""

from __future__ import annotations

import math
from dataclasses import replace
from functools import partial
from pathlib import Path

from ..analysis.gap.candidates import UNDETERMINED_SCALES
from ..analysis.gap.discovery import Discovery
from ..analysis.gap.records import (
    ApproachCheck,
    BaseCheck,
    CandidateRow,
    Contribution,
    DesignedRun,
    FirstRoundSummary,
    NoiseFloor,
    Remainder,
    TermRow,
    ThrustCheck,
    pair_label,
)
from .markdown import fmt, md_table, warning_lines
from .study import write_json

#: Report units of the protocol's channels: (factor from SI, unit).
CHANNEL_UNITS = {
    **{c: (1.0, "m") for c in ("x", "y", "z", "position")},
    **{c: (180.0 / math.pi, "deg") for c in ("phi", "theta", "psi")},
    **{c: (1.0, "m/s") for c in ("u", "v", "w")},
    **{c: (180.0 / math.pi, "deg/s") for c in ("p", "q", "r")},
}
#: Units of the missing forces and moments.
FORCE_UNITS = {"X": "N", "Y": "N", "Z": "N", "K": "N m", "M": "N m", "N": "N m"}


def channel_value(channel: str, value) -> str:
    """A channel's SI value in report units, with its unit (``psi 0.00336`` rad -> ``0.193 deg``).

    Parameters
    ----------
    channel : str
        The channel (a state name or ``position``).
    value : float or None
        Its value in SI (m, rad, m/s, rad/s).

    Returns
    -------
    str
        The value converted and formatted with its unit (``-`` for None; an unknown channel
        unconverted, without a unit).
    """
    if value is None:
        return "-"
    f, unit = CHANNEL_UNITS.get(channel, (1.0, ""))
    return f"{fmt(f * float(value))} {unit}".rstrip()


def attribution_lines(diag) -> list[str]:
    """The verdict of a diagnosis in words: cause, contributors (with their shares) and the remainder.

    Parameters
    ----------
    diag : bayesid.analysis.gap.Diagnosis
        The diagnosis (computed, or read back with :meth:`~bayesid.analysis.gap.Diagnosis.from_dict`).

    Returns
    -------
    list of str
        Markdown lines.
    """
    out = []
    if diag.cause:
        out.append(f"Cause: **{diag.cause}** (with it the held-out error is inside the noise-floor band).")
    for c in map(partial(_record, Contribution), diag.contributors):
        out.append(
            f"- Contributor **{c.effect}** ({'added' if c.added else 'not added'}): removes "
            f"{fmt(c.share_of_excess)} of the base model's excess (held-out {fmt(c.heldout_rms_m)} m; "
            f"paired window test p = {fmt(c.window_p_value)}, ΔBIC {fmt(c.delta_bic, 4)})."
        )
    rem = _record(Remainder, diag.remainder)
    if rem and diag.significant_gap:
        out.append(
            f"Remainder: {fmt(rem.fraction_of_excess)} of the excess over the floor "
            f"(held-out {fmt(rem.heldout_rms_m)} m), "
            + ("still significant: no candidate explains it." if rem.significant else "inside the band.")
        )
    return out


def _record(kind: type, value):
    """``value`` as a record of ``kind`` (a record of the diagnosis, or its JSON object read back:
    :meth:`~bayesid.analysis.gap.records.Record.from_dict`); None for an empty or missing one."""
    if not value:
        return None
    return value if isinstance(value, kind) else kind.from_dict(value)


def write_diagnosis(diag, out, heldout: list, command: str = "", inputs: dict | None = None) -> None:
    """Write the report of a gap diagnosis into a folder.

    Parameters
    ----------
    diag : bayesid.analysis.gap.Diagnosis
        The diagnosis.
    out : str or Path
        The folder (created); ``diagnosis.json``, ``report.md`` and ``figures/*.png`` are written there.
    heldout : list of Track
        The held-out tracks; the first one's windows are plotted.
    command : str
        The command line, quoted at the top of the report (none when empty).
    inputs : dict, optional
        What the caller checked of its input files: ``warnings`` (list of str) and
        ``input_sha256`` ({file: SHA-256}); written into ``diagnosis.json`` after the diagnosis.
    """
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    res = dict(diag.to_dict(), **(inputs or {}))
    _write_design_runs(diag.design, out)
    # the designed runs' input schedules are in their CSV files, not repeated in the JSON
    design = [
        replace(r, inputs=None, inputs_csv=_design_run_name(i, r) if r.inputs else None)
        for i, r in enumerate(diag.design, 1)
    ]
    res["design"] = [r.to_dict() for r in design]
    write_json(out / "diagnosis.json", res)
    figs = _figures(diag, out, heldout) + _discovery_figures(diag, design, out, heldout)
    lines = [*_summary_lines(diag, res.get("warnings") or [], command), *_how_far_lines(diag), *_which_lines(diag)]
    lines += [*_discovery_lines(diag), *_alternatives_lines(diag), *_predictions_lines(diag), *_design_lines(design)]
    lines += _where_lines(diag)
    lines += ["", *[f"![{p.stem}](figures/{p.name})" for p in figs], ""]
    (out / "report.md").write_text("\n".join(lines))


def _figures(diag, out: Path, heldout: list) -> list:
    """The diagnosis' figures (ranking, channels, regions, the first held-out track's windows
    before and after the effects added); returns their paths."""
    from . import plots

    figs = []
    if diag.ranking:
        figs.append(
            plots.gap_ranking(
                diag.ranking,
                diag.gap_before["heldout_rms_m"],
                _record(NoiseFloor, diag.noise_floor).heldout_rms_m,
                out / "figures" / "ranking.png",
                band_ratio=diag.thresholds.none_ratio,
            )
        )
    figs.append(plots.gap_channels(diag.where, out / "figures" / "channels.png"))
    figs.append(plots.gap_regions(diag.where, out / "figures" / "regions.png"))
    if diag.base is not None and heldout:
        after = diag.after if _added(diag) else None
        figs.append(_window_figure(diag.base, after, diag, heldout[0], out / "figures" / "heldout_track.png"))
    return figs


def _added(diag) -> list:
    """What the model after the rounds has on top of the base model, in the order added: the
    discovered terms when they took round 1 (``discovery_first``), then the effects."""
    first = _record(FirstRoundSummary, diag.discovery_first)
    return [*(first.found if _took_round(diag) else []), *diag.effects_added]


def _discovery(diag) -> Discovery | None:
    """Structure discovery after the rounds (``Diagnosis.discovery``, or its JSON object) as its
    record (:meth:`~bayesid.analysis.gap.discovery.Discovery.from_dict`), None when it was not run."""
    D = diag.discovery
    if not D:
        return None
    return D if isinstance(D, Discovery) else Discovery.from_dict(D)


def _took_round(diag) -> bool:
    """Whether discovery's terms on the base model took round 1 (``discovery_first``)."""
    first = _record(FirstRoundSummary, diag.discovery_first)
    return first is not None and first.took_round


def _first_round_lines(diag) -> list:
    """Discovery beside round 1: its terms on the base model against round 1's best effect."""
    F = _record(FirstRoundSummary, diag.discovery_first)
    if F is None:
        return []
    if F.found:
        kept = (
            f"{'+'.join(F.found)} (held-out {fmt(F.heldout_rms_m)} m, as a {F.role}; paired window test "
            f"against the effect p = {fmt(F.window_p_value)}, {fmt(F.share_of_effect_excess)} of its excess "
            "over the floor removed)"
        )
    else:
        kept = f"no term (the base model's held-out {fmt(F.heldout_rms_m)} m)"
    on = "the base model"
    if F.train_starts == "kinematic":
        on = "the base model refitted with its training window starts held at the kinematics"
    other = F.other_starts
    if other:  # the start check flagged the fitted starts: discovery ran on both base fits
        kept += (
            f"; on the base model with {'fitted' if other['train_starts'] == 'fitted' else 'held'} window starts it "
            f"kept {'+'.join(other['found']) or 'no term'} (held-out {fmt(other['heldout_rms_m'])} m)"
        )
    return [
        f"Beside round 1, discovery on {on} kept {kept} "
        f"against round 1's {F.effect_role} **{F.effect}** ({fmt(F.effect_heldout_rms_m)} m), ranked "
        "by the rounds' rule (a cause first, then the lower held-out RMS): "
        + (
            "the terms took round 1 and the effects were tried on top of them; the discovery below is that one."
            if F.took_round
            else "the effect took round 1; the discovery below ran after the rounds."
        ),
        "",
    ]


def _window_figure(before, after, diag, track, path, labels=("base model", "with top effect")):
    """The protocol windows of a held-out track predicted by two stages (``after`` may be None)."""
    from ..analysis.gap import window_xy
    from . import plots

    st = diag.settings
    w, rule, lead = st["window_s"], st["start_rule"], st["leadin_s"]
    meas, xy_before = window_xy(before.model, before.fit, track, w, start=rule, leadin_s=lead)
    xy_after = None
    if after is not None:
        nu = None if after.nuisance is None else after.nuisance[0]
        _, xy_after = window_xy(after.model, after.fit, track, w, nu, start=rule, leadin_s=lead)
    return plots.window_tracks(meas, xy_before, xy_after, path, title=f"{track.name}: {w} s windows", labels=labels)


def _discovery_figures(diag, design: list, out: Path, heldout: list) -> list:
    """Structure discovery's figures: per held-out window the RMS position error before and after
    the kept terms, and the first held-out track's windows with them."""
    from . import plots

    D = _discovery(diag)
    found = getattr(diag, "discovered", None)
    if D is None or found is None:
        return []
    after, label = D.windows_after_m, "with " + "+".join(D.found)
    if not D.found:  # nothing kept: the best refitted term, to show why
        fitted = [r for r in map(partial(_record, TermRow), D.discovered) if r.heldout_windows_after_m]
        if not fitted:
            return []
        best = min(fitted, key=lambda r: r.heldout_rms_after_m)
        after, label = best.heldout_windows_after_m, f"with {best.term} (best refitted, not kept)"
    figs = [
        plots.window_scatter(
            D.windows_before_m,
            after,
            out / "figures" / "discovery_windows.png",
            title="Held-out windows: " + (D.verdict or ""),
            labels=("reference model", label),
        )
    ]
    if found.after is not None and heldout:
        path = out / "figures" / "discovery_track.png"
        labels = ("reference model", "with " + "+".join(D.found))
        figs.append(_window_figure(found.reference or diag.after, found.after, diag, heldout[0], path, labels))
    if design:
        ax = plots.plot_alternatives(design[0])
        path = out / "figures" / "design_top.png"
        ax.figure.savefig(path, dpi=120, bbox_inches="tight")
        plots.plt.close(ax.figure)
        figs.append(path)
    return figs


def _alternatives_lines(diag) -> list:
    """Which structures the runs cannot separate from each kept term, and whether the held-out
    test reached beyond the training manoeuvres."""
    kept = [d for d in diag.discovered_terms or [] if d["kept"]]
    if not kept:
        return []
    kinds = diag.manoeuvre_kinds or {}
    lines = ["## Which term, really (alternatives the runs cannot separate)", ""]
    for d in kept:
        if d["separable"]:
            lines.append(
                f"- **{d['term']}**: every other refitted term either predicts the held-out windows significantly "
                "worse (paired window test over all windows, or on one run), or follows the training runs "
                "significantly worse where the held-out runs tie them, or predicts the held-out windows worse and did "
                "not pass the kept test: among the refitted terms, the runs separate it."
            )
        else:
            alts = "; ".join(
                f"{a['term']} = {fmt(a.get('coefficient'))} (held-out {fmt(a['heldout_rms_m'])} m, window test "
                f"p = {fmt(a['window_p_value'])}{_widest_run(d, a)}"
                f"{'' if a.get('passed_kept_test', True) else '; its own gain did not pass the kept test'})"
                for a in d["alternatives"]
            )
            lines.append(
                f"- **{d['term']}** (held-out {fmt(d.get('heldout_rms_on_top_m', d['heldout_rms_m']))} m) is not "
                f"separable on these runs from: {alts}. "
                "Each predicts the held-out windows not significantly worse (and passes the kept test alone, or "
                "predicts them at least as well): the runs say "
                f"a force of one of these forms is missing in {'/'.join(sorted({d['dof'], *(a['term'][0] for a in d['alternatives'])}))}, "
                "not which."
            )
        if d.get("separated"):
            lines.append(
                f"  The runs separate {d['term']} from: " + "; ".join(_separated_cell(a) for a in d["separated"]) + "."
            )
        below = next(
            (a["on_top_of"] for a in [*d["alternatives"], *d.get("separated", [])] if a.get("on_top_of")), None
        )
        if below:
            lines.append(
                f"  {d['term']} was added on top of {' + '.join(below)}: each competitor above was refitted in its place, "
                f"on top of {' + '.join(below)}, and its held-out error and coefficient are of that model."
            )
    for d in kept:
        for w in d.get("worse_on_other_kinds") or []:
            lines.append(
                f"- **Warning**: with {d['term']} the held-out run {w['run']} (of kind {w['kind'].replace('_', ' ')}, "
                f"which the training runs lack) is predicted worse than by the reference model: {fmt(w['rms_m'])} "
                f"against {fmt(w['reference_rms_m'])} m (x{fmt(w['rms_m'] / w['reference_rms_m'])}; not significantly "
                "on its windows, or the term would not have been kept). The term may not carry to that kind of run."
            )
    if kinds:
        tr, he = sorted(set(kinds.get("train", []))), sorted(set(kinds.get("heldout", [])))
        lines += ["", f"Training runs: {', '.join(tr) or '-'}; held-out runs: {', '.join(he) or '-'}."]
        if kept[0].get("tested_only_within_training_manoeuvres"):
            lines.append(
                "The held-out runs are of the training runs' kinds only: the discovered terms are **tested only within "
                "the training manoeuvres**; a manoeuvre of another kind may reject them (see the designed runs below)."
            )
    return [*lines, ""]


def _predictions_lines(diag) -> list:
    """The standard manoeuvres as the base model and each alternative predict them."""
    runs = diag.predictions or []
    if not runs:
        return []
    models = list(runs[0]["models"])
    rows = []
    for run in runs:
        for index in next(iter(run["models"].values())):
            cells = []
            for m in models:
                cells.append(_index_cell(run["models"][m][index]))
            where = "yes" if run["in_training_kinds"] else "**no**"
            rows.append([run["name"], where, index.replace("_", " "), *cells])
    return [
        "## The standard manoeuvres as each alternative predicts them",
        "",
        md_table(["run", "kind in the training runs", "index", *models], rows),
        "",
        "Free runs from the training runs' approach condition, the rudder moved at their rate (each model steers its "
        "own zigzag); the steady turning diameter is fitted to the turn from 180 deg of heading change on and the "
        "speed loss is 1 - u/U0 there (not reached: the run is too short for a steady turn). Brackets: the "
        "5-95 % range over the estimate and parameter draws from each refit's Laplace covariance (over the runs that "
        "did not diverge, counted when some did) -- parameter "
        "uncertainty only, not a calibrated band: where no run of the kind exists it cannot be checked. Where the "
        "alternatives' values part, the runs they were chosen on do not say which is right.",
        "",
    ]


def _index_cell(v: dict) -> str:
    """``12.3 [11.9, 12.8]``; ``diverged`` or ``not reached`` kept visible with the draws that did."""
    n, ok = v.get("n", 1), v.get("n_finite", 1)
    if not ok:
        return "diverged or not reached"
    span = f"[{fmt(v['low'])}, {fmt(v['high'])}]" + (f" ({ok} of {n} runs)" if ok < n else "")
    return f"{fmt(v['value'])} {span}" if math.isfinite(v["value"]) else f"estimate: diverged or not reached; {span}"


def _separated_cell(a: dict) -> str:
    """``Nvvr (held-out 0.64 m; on run R 1.8x the kept term's window errors, run test p = 0.001)``;
    where only the training runs separate them, their test (``on the training runs: ...``)."""
    if a.get("separated_by") == "training":
        if a.get("train_run_p_value") is not None and a["train_run_p_value"] < (a.get("train_window_p_value") or 1):
            how = (
                f"on the training run {a['train_separating_run']} {fmt(a['train_error_ratio'])}x the kept term's "
                f"fitted window errors, run test p = {fmt(a['train_run_p_value'])}"
            )
        else:
            how = f"on the training runs' fitted windows, window test p = {fmt(a['train_window_p_value'])}"
        return (
            f"{a['term']} (held-out {fmt(a['heldout_rms_m'])} m, not separated there; {how}: a structure of the "
            "same size that follows the training runs worse)"
        )
    if a.get("run_p_value") is not None and a["run_p_value"] < a["window_p_value"]:
        how = (
            f"on {a['separating_run']} {fmt(a['run_error_ratio'])}x the kept term's window errors, run test "
            f"p = {fmt(a['run_p_value'])}"
        )
    else:
        how = f"window test p = {fmt(a['window_p_value'])}"
    return f"{a['term']} (held-out {fmt(a['heldout_rms_m'])} m; {how})"


def _widest_run(kept: dict, alt: dict) -> str:
    """``, most apart on run R: 0.31 against 0.12 m``: the held-out run on which an alternative's
    position RMS differs most from the kept term's (empty without per-run scores)."""
    a, k = alt.get("heldout_rms_by_run_m") or {}, kept.get("heldout_rms_by_run_m") or {}
    runs = [r for r in a if r in k and a[r] is not None and k[r] is not None]
    if not runs:
        return ""
    r = max(runs, key=lambda n: abs(math.log(max(a[n], 1e-12) / max(k[n], 1e-12))))
    return f"; most apart on {r}: {fmt(a[r])} against {fmt(k[r])} m"


def design_duration_cell(r: DesignedRun) -> str:
    """The duration cell of a designed run in the report's table.

    Parameters
    ----------
    r : DesignedRun
        A designed run (``duration_s``; ``run_test.sized_from_s``).

    Returns
    -------
    str
        ``480 (from 180)`` for a run lengthened for the run test, else its duration, s.
    """
    sized = r.run_test.sized_from_s
    return f"{fmt(r.duration_s)} (from {fmt(sized)})" if sized else fmt(r.duration_s)


def run_test_cell(r: DesignedRun) -> str:
    """The run test's outlook on a designed run, over the pairs of the kept term and an alternative.

    Parameters
    ----------
    r : DesignedRun
        A designed run (``run_test.pairs``: ``expected_ratio``, ``windows_needed``,
        :func:`bayesid.analysis.gap.design.run_test_windows`).

    Returns
    -------
    str
        The most windows any separable pair needs, with its expected window error ratio and the
        pair, and how many pairs lie within the test's margin (``41 (x1.19, K vs A); 2 of 3 pairs
        within the margin``; ``within the margin (x1.08)`` for a single pair; ``-`` without).
    """
    pairs = r.run_test.pairs
    if not pairs:
        return "-"
    need = {k: math.inf if v.windows_needed is None else float(v.windows_needed) for k, v in pairs.items()}
    finite = [k for k in need if math.isfinite(need[k])]
    cells = []
    if finite:
        k = max(finite, key=need.get)
        cells.append(f"{math.ceil(need[k])} (x{fmt(pairs[k].expected_ratio)}, {pair_label(k)})")
    if len(need) == 1 and not finite:
        cells.append(f"within the margin (x{fmt(next(iter(pairs.values())).expected_ratio)})")
    elif len(finite) < len(need):
        cells.append(f"{len(need) - len(finite)} of {len(need)} pairs within the margin")
    return "; ".join(cells)


def _design_lines(rows: list) -> list:
    """The runs that would separate the alternatives, best first (:class:`DesignedRun` as
    ``diagnosis.json`` writes them: ``inputs_csv`` in place of the input schedule)."""
    if not rows:
        return []
    from ..analysis.gap.diagnose import WITHOUT_TERMS

    against_base = any(WITHOUT_TERMS in r.worst_pair for r in rows)
    head = (
        [
            "## The run that would test it beyond the training manoeuvres",
            "",
            f"No refitted term competes with the kept term on these runs, but they are all of the training runs' "
            f"kinds: the runs below are ranked by how far the kept term's model and the model without it "
            f"(`{WITHOUT_TERMS}`) part on them, a run where the term would be tested, not only fitted.",
            "",
        ]
        if against_base
        else ["## The run that would separate them", ""]
    )
    return [
        *head,
        md_table(
            [
                "run",
                "side",
                "rudder (deg)",
                "check (deg)",
                "rpm",
                "duration (s)",
                "separation (nats)",
                "worst pair",
                "max position difference (m)",
                "run test: windows needed",
            ],
            [
                [
                    r.kind.replace("_", " "),
                    r.side,
                    fmt(r.rudder_deg),
                    fmt(r.check_deg),
                    fmt(r.rpm),
                    design_duration_cell(r),
                    fmt(r.separation),
                    pair_label(r.worst_pair),
                    fmt(r.max_position_difference_m),
                    run_test_cell(r),
                ]
                for r in rows
            ],
        ),
        "",
        "Duration: the three best runs are lengthened (to at most eight protocol windows; `from` the menu's length) "
        "towards the windows the run-by-run test needs to see the kept term apart from each alternative with 80 % "
        "power. Windows needed: the most any pair of the kept term and an alternative needs, from the expected ratio "
        "of the two models' window errors on the run and the scatter of the ratios within the held-out runs; a pair "
        "is *within the margin* where the expected ratio is below the test's 10 % margin, so that no length lets the "
        "run test separate it (the run may still rank high by the divergence below).",
        "",
        "Separation: the symmetric Kullback-Leibler (J) divergence between two alternatives' Gaussian predictive "
        "distributions of x, y and heading (the measurement noise of the training runs, or the alternatives' "
        "largest held-out error when larger, plus the spread over parameter draws from each refit's Laplace "
        "covariance), summed over samples 1 s apart of the protocol windows, each window started from the kept "
        "term's model; the run's value is its worst pair's (Box & Hill 1967, Technometrics 9:57-71, with equal "
        "prior probabilities). It is the expected log Bayes factor for the right one of a pair if the samples' "
        "errors were independent; they are correlated within a window, so read it as a ranking, and check it as "
        "studies/closing_the_loop.py does: add the top run to `--heldout` "
        "(or `--train`) and diagnose again with `--compare` this diagnosis.json, so that the kept terms and "
        "alternatives above are refitted on the new run whatever its selection picks.",
        "",
        *_inseparable_lines(rows),
        *(f"- Input schedule of run {i} ({r.name}): `{r.inputs_csv}`" for i, r in enumerate(rows, 1) if r.inputs_csv),
        "",
    ]


def _inseparable_lines(rows: list) -> list:
    """The pairs of alternatives that no run of the design's menu separates."""
    pairs = (rows[0].menu_inseparable or {}) if rows else {}
    if not pairs:
        return []
    items = "; ".join(
        f"{a} from {b} (best {fmt(v['separation'])} nats, {v['best_run']})" for (a, b), v in pairs.items()
    )
    return [
        f"**Not separable by the standard manoeuvres**: no run of the menu separates {items}, below the "
        "design's threshold on every run. Those terms make the same force history in every standard run; the runs "
        "above are ranked by the other pairs, and the runs you could add will not tell these apart. Keep them as "
        "one finding (the force they share), or design a run outside the menu that makes their columns differ.",
        "",
    ]


def _design_run_name(rank: int, row: DesignedRun) -> str:
    """The file name of a designed run's input schedule, e.g. ``design_runs/1_zigzag_20_20_port.csv``."""
    slug = "".join(c if c.isalnum() else "_" for c in row.name).strip("_")
    return f"design_runs/{rank}_{'_'.join(filter(None, slug.split('_')))}.csv"


def _write_design_runs(rows: list, out: Path) -> None:
    """The input schedules of the top designed runs as CSV (``t`` s, ``delta_r`` rad, ``n`` rpm),
    for a user to steer the run, or to simulate it from a vehicle file."""
    import numpy as np

    for i, r in enumerate(rows, 1):
        if not r.inputs:
            continue
        path = out / _design_run_name(i, r)
        path.parent.mkdir(parents=True, exist_ok=True)
        u = r.inputs
        # a comment line, then a plain header row (pandas.read_csv(path, comment="#") reads it)
        np.savetxt(
            path,
            np.column_stack([u["t"], u["delta_r"], u["n"]]),
            delimiter=",",
            header=f"# designed run {i}: {r.name} (rudder + to port, rad; zigzag switches as the kept model "
            "steers)\nt,delta_r,n",
            comments="",
            fmt="%.6g",
        )


def _held_starts_lines(settings: dict) -> list:
    """Discovery after the rounds on both base fits (fitted training window starts flagged by the
    start check): which one the section shows, and what the other kept."""
    other = settings.get("other_starts")
    if not other:
        return []
    held = settings.get("train_starts") == "kinematic"
    return [
        "The base fit's training window starts contradict the kinematics, so discovery also searched the base "
        "model refitted with them held; "
        + ("the held starts' search" if held else "the fitted starts' search")
        + f" is shown below (the other kept {'+'.join(other['found']) or 'no term'}, held-out "
        f"{fmt(other['heldout_rms_m'])} m). Read the coefficients of such a fit as start values for `bayesid fit`.",
        "",
    ]


def _cosine(c: float) -> str:
    """A column cosine truncated to three decimals: 0.9998 reads ``0.999``, never ``1``."""
    return f"{math.floor(abs(c) * 1000) / 1000:.3f}"


def _refit_result(row: dict) -> str:
    """What the refit of a term set aside as mimicked found (a row of ``discovered`` with
    ``refitted_as`` ``"mimicked"``)."""
    if row.get("heldout_rms_after_m") is None:
        return f"refitted all the same, every fit of {row['term']} failed"
    numbers = (
        f"{row['term']} {fmt(row.get('coefficient'))}, held-out RMS {fmt(row['heldout_rms_before_m'])} -> "
        f"{fmt(row['heldout_rms_after_m'])} m"
    )
    if row.get("kept"):
        return f"refitted all the same, every coefficient free ({numbers}), it passes the kept test"
    return f"refitted all the same, every coefficient free ({numbers}), it does not pass the kept test ({row.get('reason', '')})"


def _mimicked_text(R: dict, free, shown: int = 5, refit_rows=()) -> str:
    """The sentences on the candidates set aside as mimicked (``R``: ``discovery.residuals``): the
    ``shown`` most likely stand-ins (``mimicked_by``'s order) named with their *mimic*, the free
    parameter whose column is closest to theirs, how far the fit moved it, and how to test them
    (refit with the mimic held).

    A mimicked term can be the missing one: a constant yaw moment hidden in synthetic runs was
    absorbed by the neutral rudder angle ``dR0`` (issue 50), and only a refit with ``dR0`` held
    lets discovery see ``N0``. Without ``mimicked_by`` (an older ``diagnosis.json``) the count
    alone.

    Parameters
    ----------
    R : dict
        ``mimicked`` (names) and optionally ``mimicked_by`` (``{term: {"parameter", "cosine",
        "span_cosine"[, "shift", "shift_effect"]}}``, most likely stand-ins first;
        :func:`bayesid.analysis.gap.discovery.selection.select_terms`).
    free : sequence of str
        The reference model's free coefficients (a mimic among them is held by leaving it out of
        ``--free``).
    shown : int, default 5
        Most terms named.
    refit_rows : sequence of dict, default ()
        The rows of ``discovered``: those of the mimicked terms refitted all the same
        (``refitted_as`` ``"mimicked"``) give their result in place of the advice to test them.

    Returns
    -------
    str
        One or more sentences, each ending with ``". "``.
    """
    n = len(R["mimicked"])
    refitted = {r["term"]: r for r in refit_rows if r.get("refitted_as") == "mimicked"}
    head = f"{n} set aside because a refit of the free coefficients reproduces them"
    by = R.get("mimicked_by") or {}
    if not by:
        return head + ". "
    groups: dict = {}
    for t in list(by)[:shown]:
        groups.setdefault(by[t]["parameter"], []).append(t)
    out = [
        head + " (*mimicked*). One of them can still be the missing term, hidden by the refit in its *mimic*, the "
        "free parameter whose column (the training residuals' sensitivity to it) is closest to the term's; the "
        "likeliest first (the mimic's move from its start along the term's column): "
    ]
    for p, terms in groups.items():
        names = terms[0] if len(terms) == 1 else ", ".join(terms[:-1]) + " and " + terms[-1]
        cos = ", ".join(_cosine(by[t]["cosine"]) for t in terms)
        part = min(by[t]["cosine"] for t in terms) < 0.9  # a combination of free parameters mimics it
        if part:
            cos += "; with all the free parameters together " + ", ".join(_cosine(by[t]["span_cosine"]) for t in terms)
        m = by[terms[0]]
        moved = (
            f"; the fit moved {p} from its start by {fmt(m['shift'])}, {fmt(m['shift_effect'], 2)} times the "
            "training residual's RMS"
            if "shift" in m
            else ""
        )
        s = f"{names} {'is' if len(terms) == 1 else 'are'} mimicked by {p} (column cosine {cos}{moved})"
        tested = [refitted[t] for t in terms if t in refitted]
        untested = [t for t in terms if t not in refitted]
        if tested:
            s += "; " + "; ".join(_refit_result(r) for r in tested)
        if p in free and not part and untested:
            s += (
                f"{'; the others' if tested else ''}: refit with {p} held (`--free` without {p}) to test "
                f"{'it' if len(untested) == 1 else 'them'}"
            )
        out.append(s + ". ")
    if len(by) > sum(map(len, groups.values())):
        out.append(
            f"The other {len(by) - sum(map(len, groups.values()))} with theirs: "
            "`discovery.residuals.mimicked_by` in diagnosis.json. "
        )
    return "".join(out)


def _compared_fate(D: Discovery, term: str) -> str:
    """What became of a term asked for with ``--compare`` (the discovery entry ``D``)."""
    if term in D.found:
        return "kept"
    for k, alts in D.alternatives.items():
        if any(a["term"] == term for a in alts):
            return f"an alternative of {k} (the runs do not separate them)"
    for k, seps in D.separated.items():
        a = next((a for a in seps if a["term"] == term), None)
        if a is not None:
            by = a.get("separated_by") or "held-out"
            run = a.get("separating_run") if by == "heldout" else a.get("train_separating_run")
            ratio = a.get("run_error_ratio") if by == "heldout" else a.get("train_error_ratio")
            where = f", run {run}" + (f", error ratio {fmt(ratio)}" if ratio is not None else "") if run else ""
            return f"set apart from {k} by the {'training' if by == 'training' else 'held-out'} runs{where}"
    row = next((r for r in D.discovered if r["term"] == term), None)
    if row is None:
        return "not refitted"
    if row.get("kept"):
        return "passed the kept test alone but not on top of " + "+".join(D.found)
    return "not kept: " + (row.get("reason") or "failed the kept test")


def _compared_lines(D: Discovery) -> list:
    """The fate of each term asked for with ``--compare`` (``settings.compare``), when any."""
    asked = list(D.settings.get("compare") or [])
    if not asked:
        return []
    return [
        "Asked to compare (`--compare`: an earlier round's terms, refitted whatever the selection picks): "
        + "; ".join(f"{t}: {_compared_fate(D, t)}" for t in asked)
        + ".",
        "",
    ]


def _discovery_lines(diag) -> list:
    """The structure-discovery section: every refitted term with its numbers, the missing force
    per degree of freedom against the best library terms, and what was tried."""
    D = _discovery(diag)
    if D is None:
        return []
    R = D.residuals
    lines = [
        "## What the model lacks (structure discovery)",
        "",
        *_first_round_lines(diag),
        # after the rounds; beside round 1 the sentence above says it
        *([] if _took_round(diag) else _held_starts_lines(D.settings)),
        f"**{D.verdict}** (held-out RMS {fmt(D.heldout_rms_before_m)} m -> {fmt(D.heldout_rms_after_m)} m). "
        f"Library: {D.library_size} candidate terms (products of v, r, |v|, |r|, rudder and |rudder| up to order "
        f"{D.settings['max_order']}, and constants, in {', '.join(D.settings['dofs'])}); "
        + _mimicked_text(R, D.settings.get("free", []), refit_rows=D.discovered)
        + f"{fmt(R['projected_rms'])} of the training residual's RMS is beyond any refit of the free coefficients; "
        f"the ensemble's median model explains {fmt(R['explained'])} of that.",
        "",
        md_table(
            [
                "term",
                "collinear group",
                "inclusion p",
                "group p",
                "coefficient (prime)",
                "held-out RMS before -> after (m)",
                "ΔBIC (train)",
                "window test p",
                "kept",
                "why",
            ],
            [
                [
                    r.term,
                    ", ".join(r.group[:4]) + (" ..." if len(r.group) > 4 else "") or "-",
                    fmt(r.inclusion_probability),
                    fmt(r.group_inclusion_probability),
                    fmt(r.coefficient),
                    f"{fmt(r.heldout_rms_before_m)} -> {fmt(r.heldout_rms_after_m)}",
                    fmt(r.delta_bic, 4),
                    fmt(r.window_p_value),
                    "yes" if r.kept else "no",
                    r.reason,
                ]
                for r in map(partial(_record, TermRow), D.discovered)
            ],
        )
        if D.discovered
        else "No candidate reached the inclusion probability at which it is refitted "
        f"({D.settings['min_probability']}).",
        "",
        *_compared_lines(D),
        "Method: the training residuals of the output-error fit, linearised in every candidate's "
        "coefficient, with the directions a refit of the free coefficients can take projected out; a sparse "
        "regression (pysindy STLSQ, block bootstrap over the fit windows) gives each term an inclusion "
        "probability; each group of nearly collinear terms is refitted (all coefficients re-identified) "
        "and kept only if it passes the contributor test on the held-out windows.",
        "",
    ]
    F = R.get("forces") or {}
    if F and "error" not in F:
        lines += [
            md_table(
                ["DOF", "missing force RMS", "noise RMS", "best terms (inclusion p, share of force variance)"],
                [
                    [
                        g,
                        fmt(d["rms"]) + (" N m" if g == "N" else " N"),
                        fmt(d["noise_rms"]) + (" N m" if g == "N" else " N"),
                        "; ".join(
                            f"{t['term']} ({fmt(t['inclusion_probability'])}, {fmt(t['force_r2'])})" for t in d["top"]
                        ),
                    ]
                    for g, d in F.items()
                ],
            ),
            "",
            "Missing force: inverse dynamics of the training tracks' smoothed motion minus the model's forces, less "
            "what the same processing gives on the model's own run (its twin); noise RMS: the twin with the data's "
            "noise. Both low-passed alike.",
            "",
        ]
    return lines


def _multistart_lines(ms: dict | None) -> list:
    """The base fit's extra starts, when it had any."""
    if not ms:
        return []
    better = "a better optimum, used" if ms["improved"] else "no better optimum"
    return [
        f"Base fit from {ms['n_starts']} extra start(s): lowest cost {fmt(ms['best_cost'], 6)} against the default "
        f"start's {fmt(ms['default_cost'], 6)} ({better}; {ms['distinct_optima']} distinct near-best optima).",
        "",
    ]


def _base_check_lines(check: BaseCheck | dict | None) -> list:
    """The base-fit check (generalisation and window starts): a warning when suspect, else a line."""
    check = _record(BaseCheck, check)
    if not check:
        return []
    ts = check.train_starts
    switch = (
        [
            "Training window starts (`--train-starts auto`): the fitted starts contradicted the tracks' kinematics, "
            "so the base model was refitted with them held at the kinematics; on its own training runs under the "
            f"held-out protocol it predicts {fmt(ts['fitted_train_rms_at_window_m'])} m with fitted starts and "
            f"{fmt(ts['kinematic_train_rms_at_window_m'])} m with held ones: every fit of this diagnosis uses "
            f"**{ts['used']}** starts.",
            "",
        ]
        if ts
        else []
    )
    if check.suspect:
        return [*switch, "**Warning:** " + check.message + ".", ""]
    return [*switch, "Base-fit check: " + check.message + ".", ""]


def _summary_lines(diag, warnings: list, command: str) -> list:
    """Title, command, input warnings, verdict and settings."""
    return [
        "# Gap diagnosis",
        "",
        f"`{command}`" if command else "",
        "",
        *warning_lines(warnings),
        *_base_check_lines(diag.base_check),
        *_multistart_lines(getattr(_record(BaseCheck, diag.base_check), "multistart", None)),
        f"**Verdict: {diag.verdict}**"
        + (f" (effects added: {', '.join(diag.effects_added)})" if diag.effects_added else ""),
        "",
        *_another_point_lines(diag.where.get("approach")),
        f"Training tracks: {', '.join(diag.train_tracks)}; held-out: {', '.join(diag.heldout_tracks)}. "
        f"Free coefficients: {', '.join(diag.settings['free']) or 'none'}. Protocol windows: "
        f"{diag.settings['window_s']} s; model step {diag.settings['dt']} s; channel weights of the fits: "
        f"{diag.settings.get('weighting', 'noise')} sds ({', '.join(f'{k} {channel_value(k, v)}' for k, v in diag.fit_sd.items())}).",
        "",
    ]


def _another_point_lines(check) -> list:
    """Beside the verdict: held-out runs at another propulsion point than the training runs'
    (Where's approach check), which no candidate can carry."""
    ap = _record(ApproachCheck, check)
    if ap is None or not ap.another_point:
        return []
    sh = ap.share_of_excess
    share = (
        ""
        if sh is None
        else f"; matching their rpm to their approach removes {sh:.0%} of the held-out excess"
        if sh >= 0
        else "; matching their rpm to their approach makes the held-out error worse"
    )
    judged = (
        " The verdict and every candidate were judged with their rpm matched (--heldout-propeller approach)."
        if ap.rediagnosed
        else " To judge the candidates with their rpm matched: --heldout-propeller approach."
    )
    return [
        f"**Also: held-out run(s) {', '.join(ap.off_runs)} at another propulsion point** than the training runs' "
        f"(the model at their logged rpm settles {ap.heldout_error:+.1%} off their approach speed{share}; see Where)."
        + judged,
        "",
    ]


def _how_far_lines(diag) -> list:
    """The "How far" section: base model against the model with the effects added (and with
    the terms discovery kept after the rounds, when it kept any)."""
    gb, ga, gd = diag.gap_before, diag.gap_after, diag.gap_discovered or {}
    added = _added(diag)
    rows = [("base model", gb), ("with " + ("+".join(added) or "nothing"), ga)]
    D = _discovery(diag)
    found, shrink = (D.found if D is not None else []), []
    if gd and found:
        # discovery's search on the base refitted with its training window starts held: its training
        # RMS is under those starts, not the fitted ones of the rows above
        held = D.settings.get("train_starts") == "kinematic" and diag.settings.get("train_starts") != "kinematic"
        how = "; training window starts held at the kinematics, its train RMS under them" if held else ""
        rows.append((f"with {'+'.join([*added, *found])} ({'+'.join(found)} discovered{how})", gd))
        gain = 1 - gd["heldout_rms_m"] / gb["heldout_rms_m"]
        shrink = [f"With the discovered terms: held-out shrinkage {fmt(gain)}.", ""]
    return [
        "## How far",
        "",
        md_table(
            [
                "",
                "train RMS (m)",
                "held-out RMS (m)",
                "held-out max (m)",
                "heading RMS (deg)",
                "train log-lik. (nats)",
                "held-out log-lik. (nats)",
            ],
            [
                [
                    label,
                    fmt(g["train_rms_m"]),
                    fmt(g["heldout_rms_m"]),
                    fmt(g["heldout_max_m"]),
                    fmt(g["heading_rms_deg"]),
                    fmt(g.get("train_log_likelihood"), 5),
                    fmt(g.get("heldout_log_likelihood"), 5),
                ]
                for label, g in rows
            ],
        ),
        "",
        "Log-likelihood: Gaussian at the fits' channel sds, samples treated as independent (a "
        "before/after comparison on the same samples, not a calibrated likelihood).",
        "",
        f"Held-out shrinkage {fmt(diag.heldout_shrinkage)} (fraction of the base model's held-out RMS removed); "
        f"noise floor ({_floor_what(diag)}) {fmt(_record(NoiseFloor, diag.noise_floor).heldout_rms_m)} m; gap ratio "
        f"{fmt(diag.gap_ratio)} (held-out RMS / noise floor, dimensionless; significant above "
        f"{diag.thresholds.none_ratio}).",
        "",
        *shrink,
    ]


def _failed_fit_lines(diag) -> list:
    """A sentence for each candidate whose fit failed (``CandidateRow.failed_fit``)."""
    rows = [r for r in map(partial(_record, CandidateRow), diag.ranking) if r.failed_fit]
    return [""] + [f"- **{r.effect}: fit failed**: {r.failed_fit}." for r in rows] if rows else []


def _floor_decides_lines(diag) -> list:
    """A paragraph for a verdict the noise floor decides (issue 69): the gap is within the floor
    band, so nothing is named, while a candidate improves the held-out windows significantly
    (paired window test under ``partial_p``, training ΔBIC under ``bic_threshold``, a sound fit):
    the logs cannot separate that effect from the floor's own error, which a reader of "none" must
    know.

    Parameters
    ----------
    res : dict
        The diagnosis (``significant_gap``, ``gap_ratio``, ``ranking``, ``thresholds``).

    Returns
    -------
    list of str
        The lines (none when the gap is significant or no candidate qualifies).
    """
    if diag.significant_gap:
        return []
    th = diag.thresholds
    rows = [
        r
        for r in map(partial(_record, CandidateRow), diag.ranking)
        if not r.failed_fit
        and r.window_p_value is not None
        and r.window_p_value < th.partial_p
        and r.delta_bic <= th.bic_threshold
    ]
    if not rows:
        return []
    said = "; ".join(
        f"{r.effect} (window test p = {fmt(r.window_p_value)}, training ΔBIC {fmt(r.delta_bic)}, "
        f"{fmt(r.share_of_excess)} of the excess)"
        for r in rows
    )
    return [
        "",
        f"**The noise floor, not the model, decides this verdict.** The held-out error is within "
        f"{th.none_ratio:g} x the noise floor (gap ratio {fmt(diag.gap_ratio)}), so no effect is named; yet "
        f"{said} improves the held-out windows significantly. {_floor_what(diag, sentence=True)} scores the floor "
        "on these windows from start states read off noisy logs: these logs cannot separate that effect from the "
        "floor's own error. A velocity log, more precise positions, more held-out runs, training runs that determine "
        "the coefficients better, or windows over which the effect outgrows the start-state error would.",
    ]


def _floor_what(diag, sentence: bool = False) -> str:
    """What the diagnosis's noise floor is: a perfect model's error at the estimated noise, or that
    of a model of the right form with coefficients drawn from the base fit's uncertainty
    (``NoiseFloor.coefficient_draws``)."""
    n = _record(NoiseFloor, diag.noise_floor).coefficient_draws
    if sentence:
        if n is None:
            return "A perfect model"
        return f"A model of the right form, its coefficients known as well as the training runs tell them ({n} draws),"
    if n is None:
        return "perfect model at the estimated noise"
    return f"a model of the right form at the estimated noise, {n} coefficient draws from the base fit's Fisher information"


def _undetermined_lines(diag) -> list:
    """A paragraph naming the candidates whose parameters the training runs do not determine
    (``CandidateRow.undetermined``): their fitted values and held-out tests say nothing either way,
    so a verdict of none is "these runs cannot tell" for them, not "nothing is missing"."""
    rows = [r for r in map(partial(_record, CandidateRow), diag.ranking) if r.undetermined]
    if not rows:
        return []
    said = [
        f"{r.effect} ("
        + ", ".join(f"{p} {fmt(r.parameters[p])} +- {fmt(r.parameter_sd[p])}" for p in r.undetermined)
        + ")"
        for r in rows
    ]
    return [
        "",
        f"Not determined by the training runs: {'; '.join(said)} (Laplace sd over "
        f"{UNDETERMINED_SCALES:g} times the effect's typical size, a lower bound). For these candidates the "
        "fitted values and the held-out test say nothing either way: these runs cannot tell whether the effect "
        "is present, and a verdict that leaves it out is not evidence that it is absent. A velocity log, longer "
        "windows or a manoeuvre that excites it would.",
    ]


def _which_lines(diag) -> list:
    """The "Which" section: the ranking of the candidate effects, the verdict in words, the rules
    and the sparse-regression support."""
    th = diag.thresholds
    return [
        "## Which",
        "",
        md_table(
            [
                "effect",
                "held-out RMS (m)",
                "excess removed (fraction)",
                "window test p",
                "ΔBIC (train)",
                "role",
                "parameters (unit in the name)",
            ],
            [
                [
                    r.effect,
                    fmt(r.heldout_rms_m),
                    fmt(r.excess_removed),
                    fmt(r.window_p_value),
                    fmt(r.delta_bic, 4),
                    r.role or ("fit failed" if r.failed_fit else "-"),
                    ", ".join(f"{k} {fmt(v)}" for k, v in r.parameters.items() if k != "per_track_nuisance"),
                ]
                for r in map(partial(_record, CandidateRow), diag.ranking)
            ],
        ),
        *_floor_decides_lines(diag),
        *_undetermined_lines(diag),
        *_failed_fit_lines(diag),
        "",
        *attribution_lines(diag),
        "",
        *_bic_heldout_lines(diag),
        f"Rules: an effect is the cause if, added, the held-out error falls within "
        f"{th.none_ratio} x the floor, it removes >= {th.explain_fraction} "
        f"of the excess and its ΔBIC <= {th.bic_threshold}; a contributor improves the "
        f"held-out windows (paired Wilcoxon p < {th.partial_p}, ΔBIC <= "
        f"{th.bic_threshold}) without closing the gap and is added, the next round trying the "
        "others on top of it; `+unexplained` marks a remainder still above the band; `none`: the gap is not "
        f"significant. Window starts: {diag.settings.get('start_rule', 'measured')} rule"
        + (f" (lead-in {fmt(diag.settings.get('leadin_s'))} s)" if diag.settings.get("start_rule") == "fitted" else "")
        + ".",
        "",
        "Sparse-regression support (ensemble STLSQ inclusion probability of each effect's force "
        "signature in the missing forces; sensor bias leaves none): "
        + ", ".join(f"{k} {fmt(v)}" for k, v in diag.sindy_support.items() if not isinstance(v, str)),
        "",
    ]


def _bic_heldout_lines(diag) -> list:
    """A sentence for each candidate on which the training ΔBIC and the held-out windows disagree:
    strongly favoured by BIC (ΔBIC at most the threshold) without a held-out gain, or a held-out
    gain (positive shrinkage and the window test or the excess removed) that BIC does not support.
    Reads the ranking's rows as :class:`~bayesid.analysis.gap.records.CandidateRow` records."""
    th = diag.thresholds
    lines = []
    for r in map(partial(_record, CandidateRow), diag.ranking):
        if r.failed_fit:  # said in its own sentence: a failed fit is not evidence
            continue
        p = r.window_p_value
        gain = r.heldout_shrinkage > 0 and (
            (p is not None and p < th.partial_p) or r.excess_removed >= th.explain_fraction
        )
        favoured = r.delta_bic <= th.bic_threshold
        shrink = r.heldout_shrinkage
        ref = r.heldout_rms_m / (1.0 - shrink) if shrink != 1 else None
        held = f"held-out RMS {fmt(ref)} m -> {fmt(r.heldout_rms_m)} m, window test p = {fmt(p)}"
        if favoured and not gain:
            lines.append(
                f"- **BIC and held-out disagree on {r.effect}**: training ΔBIC {fmt(r.delta_bic, 4)} favours it "
                f"strongly, but "
                + ("its held-out gain is not significant" if shrink > 0 else "it brings no held-out gain")
                + f" ({held}; needs p < {th.partial_p} or {th.explain_fraction} of the excess removed). The "
                "training runs' improvement does not carry over to unseen runs reliably: its parameters fit something "
                "particular to the training runs (overfitting, or an effect that differs from run to run), so it is "
                "not added."
            )
        elif gain and not favoured:
            lines.append(
                f"- **BIC and held-out disagree on {r.effect}**: it improves the held-out windows ({held}), but "
                f"training ΔBIC {fmt(r.delta_bic, 4)} does not support it (needs <= {th.bic_threshold}): the "
                "training runs alone do not pay for its parameters. More or richer training runs would decide; it is "
                "not added on this evidence."
            )
    return lines + ([""] if lines else [])


def _speed_from_positions(sog: dict | None) -> list[str]:
    """The Where section's line on the speed over ground read from the positions (no speed log)."""
    if not sog:
        return []
    return [
        f"Speed over ground read from the positions (no speed log; {fmt(sog['span_s'])} s local quadratic slopes): "
        f"RMS error {fmt(sog['rms'])} m/s against a noise floor of {fmt(sog['floor_rms'])} m/s "
        f"({fmt(sog['excess_ratio'])} x).",
        "",
    ]


def _thrust_lines(check: ThrustCheck | dict | None) -> list[str]:
    """The Where section's lines on the propeller against the logged thrust
    (:func:`bayesid.analysis.gap.where.where`'s ``thrust``, or its JSON object)."""
    th = _record(ThrustCheck, check)
    if th is None:
        return []
    share = th.propeller_share
    if share is None:
        reading = ""
    elif share > 0:
        reading = (
            f" The thrust error carries {fmt(share)} of the missing surge force's mean square: part of the surge"
            " miss is the propeller's (its propulsion point, or the wake in a turn where the deficit grows with"
            " |beta_P|)."
        )
    else:
        reading = (
            " With the logged thrust the surge balance is no better: the fit has absorbed the thrust error in"
            " other surge terms (the resistance Xuu), or the surge miss is the hull's or the rudder's."
        )
    return [
        f"The propeller against the logged thrust ({th.tracks} held-out track(s)): the model's thrust "
        f"{fmt(th.model_mean_n)} N against {fmt(th.logged_mean_n)} N logged on average "
        f"({fmt(None if th.bias_fraction is None else 100.0 * th.bias_fraction)} %), RMS error {fmt(th.rms_n)} N; the deficit (logged - model) "
        f"correlates with |beta_P| at {fmt(th.error_corr_abs_beta_p)}. The missing surge force's RMS is "
        f"{fmt(th.missing_x_rms_n)} N, {fmt(th.missing_x_rms_logged_thrust_n)} N with the logged thrust "
        f"in place of the model's.{reading}",
        "",
    ]


def _approach_lines(check: ApproachCheck | dict | None) -> list[str]:
    """The Where section's lines on each run's propulsion point against the fitted model's
    (:func:`bayesid.analysis.gap.where.approach_check`, or its JSON object)."""
    ap = _record(ApproachCheck, check)
    if ap is None or not ap.sentence():
        return []
    rows = [
        [
            r["run"],
            r["role"],
            fmt(r["rpm"]),
            fmt(r["speed_m_s"]),
            fmt(r["model_speed_m_s"]),
            f"{100.0 * r['speed_error']:+.1f}",
            "yes" if r["steady"] else "no (not judged)",
            "**yes**" if r.get("off") else ("no" if r["role"] == "held-out" else "-"),
        ]
        for r in ap.runs
    ]
    head = [
        "run",
        "role",
        "approach rpm",
        "approach speed (m/s)",
        "model's speed at that rpm (m/s)",
        "error %",
        "steady",
        "another point",
    ]
    return [ap.sentence(), "", md_table(head, rows), ""]


def _where_lines(diag) -> list:
    """The "Where" section: channels, dominant region, phases, missing forces, wind dependence
    and the residuals' spectra."""
    lines = [
        "## Where",
        "",
        md_table(
            ["channel", "RMS", "noise sd", "floor RMS", "RMS / floor RMS"],
            [
                [
                    c,
                    channel_value(c, d.get("rms")),
                    channel_value(c, d.get("noise_sd")),
                    channel_value(c, d.get("floor_rms")),
                    fmt(d.get("excess_ratio")),
                ]
                for c, d in diag.where["channels"].items()
            ],
        ),
        "",
        f"Dominant channel: {diag.where['dominant_channel']}; dominant region: "
        f"{diag.where['dominant_region']['region']} (error growth {fmt(diag.where['dominant_region']['growth_ratio'])}"
        " x the mean).",
        "",
        *_speed_from_positions(diag.where.get("speed_from_positions")),
        *(
            [f"Structure discovery: {diag.where['discovery_routed']}.", ""]
            if diag.where.get("discovery_routed")
            else []
        ),
    ]
    ph = diag.where["phases"]
    lines += [
        "Phases: "
        + "; ".join(
            f"{k}: {fmt(v['fraction_of_time'])} of the time, growth {fmt(v['mean_error_growth_mps'])} m/s"
            for k, v in ph.items()
        ),
        "",
    ]
    if diag.where.get("forces"):
        lines += [
            "Missing forces (RMS, inverse dynamics of the first held-out track's smoothed motion minus "
            "the fitted model): "
            + ", ".join(
                f"{k} {fmt(v)} {FORCE_UNITS.get(k, '')}".rstrip()
                for k, v in diag.where["forces"].items()
                if not isinstance(v, str)
            ),
            "",
        ]
    if diag.where.get("wind_correlation"):
        lines += [
            "Apparent-wind dependence: correlation of the missing X, Y, N with the wind-load signatures "
            "(0.5 rho_a VA^2 A cos g, sin g) over the held-out tracks: "
            + ", ".join(f"{k} {fmt(v)}" for k, v in diag.where["wind_correlation"].items()),
            "",
        ]
    lines += _thrust_lines(diag.where.get("thrust"))
    lines += _approach_lines(diag.where.get("approach"))
    for k, v in diag.where.get("spectrum", {}).items():
        wb = diag.where["whiteness"].get(k, {})
        ic = diag.where["input_correlation"].get(k, {})
        lines.append(
            f"- {k}: spectral peak at {fmt(v['peak_period_s'])} s ({fmt(v['peak_to_median'])} x median); "
            f"Ljung-Box p = {fmt(wb.get('p_value'))}; "
            + ", ".join(f"corr with {n} {fmt(c['max_abs_corr'])} at lag {fmt(c['lag_s'])} s" for n, c in ic.items())
        )
    return lines
