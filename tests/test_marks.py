"""Report figures mark the ITTC manoeuvre indices (issue 38): :func:`bayesid.report.plots.mark_indices`
draws a KVLCC2 10/10 zigzag's executes, check headings and overshoots on its heading history and a
35 deg turn's advance, transfer and tactical diameter on its plan view, where
:func:`~bayesid.estimation.indices.manoeuvre_indices` measures them, and nothing on a PRBS-like
run; ``bayesid simulate`` writes the indices it prints to ``<out>.json``, and ``<out>.png``."""

from __future__ import annotations

import json
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from bayesid import cli  # noqa: E402
from bayesid.estimation.indices import manoeuvre_indices  # noqa: E402
from bayesid.models.runs import canonical_kind  # noqa: E402
from bayesid.models.ship import load_ship  # noqa: E402
from bayesid.models.ship.trials import TrialOptions, propulsion_point, service_condition, simulate_trial  # noqa: E402
from bayesid.report import plots  # noqa: E402
from bayesid.report.plots import MARK_GID, mark_indices  # noqa: E402


@pytest.fixture(scope="module")
def trials():
    ship = load_ship("kvlcc2_7m")
    service = service_condition(ship)
    speed, rpm = propulsion_point(ship, service["speed"])
    options = TrialOptions(rudder_rate_deg_s=service["rudder_rate_deg_s"])
    zz = simulate_trial(ship, "zigzag", -10.0, check_deg=10.0, speed=speed, rpm=rpm, options=options).track
    tc = simulate_trial(ship, "turn", -35.0, speed=speed, rpm=rpm, options=options).track
    return zz, tc


def _gid(ax, name):
    """The artists of ``ax`` (lines, texts, annotations) with gid ``ittc:<name>``."""
    return [a for a in ax.get_children() if a.get_gid() == MARK_GID + name]


def _arrow(ann):
    """(start, end) of a double-arrow annotation, in data coordinates."""
    return np.array(ann.xyann, float), np.array(ann.xy, float)


def test_zigzag_marks_sit_on_the_executes_check_headings_and_overshoots(trials):
    zz, _ = trials
    ind = manoeuvre_indices(zz.t, zz["x"], zz["y"], zz["psi"], zz["delta_r"])
    assert ind["kind"] == "zigzag"
    heading = np.degrees(np.unwrap(zz["psi"]))
    psi0 = float(np.interp(ind["executes_t_s"][0], zz.t, heading))
    fig, (ax_plan, ax) = plt.subplots(1, 2)
    got = mark_indices(ax_plan, ax, zz.t, zz, label="measured: ")
    assert got == ind
    assert not [a for a in ax_plan.get_children() if a.get_gid()]  # a zigzag: nothing on the plan view
    # the executes: one vertical line at each of the 1st to 4th
    ex = sorted(line.get_xdata()[0] for line in _gid(ax, "execute"))
    np.testing.assert_allclose(ex, ind["executes_t_s"][:4])
    # the check headings: a horizontal line from each later execute at the heading there
    checks = _gid(ax, "check_heading")
    assert len(checks) == 3
    for line, te, ch in zip(checks, ind["executes_t_s"][1:], ind["check_heading_deg"]):
        assert line.get_xdata()[0] == pytest.approx(te)
        np.testing.assert_allclose(line.get_ydata(), psi0 + ch, atol=1e-9)
    # the overshoots: an arrow from the check heading to the heading's extreme, labelled with the
    # value, drawn where the indices read them, between samples (issue 50): at overshoot_t_s,
    # from the check heading to check + overshoot
    for k, name in ((1, "first"), (2, "second")):
        (arrow,) = _gid(ax, f"{name}_overshoot")
        a, b = _arrow(arrow)
        check = psi0 + ind["check_heading_deg"][k - 1]
        value = ind[f"{name}_overshoot_deg"]
        going = np.sign(ind["check_heading_deg"][k - 1] - (ind["check_heading_deg"][k - 2] if k > 1 else 0.0))
        np.testing.assert_allclose(a, [ind["overshoot_t_s"][k - 1], check], atol=1e-6)
        np.testing.assert_allclose(b, [ind["overshoot_t_s"][k - 1], check + going * value], atol=1e-6)
        assert ind["executes_t_s"][k] <= a[0] < ind["executes_t_s"][k + 1]
        # the arrow ends on the heading history, at its extreme beyond the check heading: the
        # index reads it from a local cubic, the samples joined by lines bend less than 0.005 deg
        # from it at 0.1 s
        assert float(np.interp(b[0], zz.t, heading)) == pytest.approx(b[1], abs=0.005)
        (peak,) = _gid(ax, f"{name}_overshoot_peak")
        np.testing.assert_allclose([peak.get_xdata()[0], peak.get_ydata()[0]], b, atol=1e-6)
        (text,) = _gid(ax, f"{name}_overshoot_text")
        assert text.get_text() == f"{name} overshoot\n{value:.1f} deg"
    (peak,) = _gid(ax, "first_overshoot_peak")
    assert peak.get_xdata()[0] - ind["executes_t_s"][1] == pytest.approx(ind["time_to_check_yaw_s"], abs=1e-6)
    (span,) = _gid(ax, "initial_turning_time")
    a, b = _arrow(span)
    assert b[0] - a[0] == pytest.approx(ind["initial_turning_time_s"])
    labels = ax.get_legend_handles_labels()[1]
    assert labels == ["measured: executes", "measured: check headings"]
    plt.close(fig)


def test_turn_marks_advance_transfer_and_tactical_diameter_on_the_plan_view(trials):
    _, tc = trials
    ind = manoeuvre_indices(tc.t, tc["x"], tc["y"], tc["psi"], tc["delta_r"])
    assert ind["kind"] == "turning"
    fig, (ax, ax_heading) = plt.subplots(1, 2)
    mark_indices(ax, ax_heading, tc.t, tc, color="tab:purple")
    assert not [a for a in ax_heading.get_children() if a.get_gid()]
    te = ind["execute_t_s"]
    psi0 = float(np.interp(te, tc.t, np.unwrap(tc["psi"])))
    (ea, eb) = _arrow(_gid(ax, "advance")[0])
    # plan view: (y, x); the advance runs from the execute along the original course
    np.testing.assert_allclose(ea, [np.interp(te, tc.t, tc["y"]), np.interp(te, tc.t, tc["x"])], atol=1e-9)
    d = eb - ea
    # the lengths are the indices, read between samples (issue 50)
    assert np.hypot(*d) == pytest.approx(ind["advance_m"], abs=1e-6)
    np.testing.assert_allclose(d / np.hypot(*d), [np.sin(psi0), np.cos(psi0)], atol=1e-9)
    for name in ("transfer", "tactical_diameter"):
        (ann,) = _gid(ax, name)
        a, b = _arrow(ann)
        assert np.hypot(*(b - a)) == pytest.approx(ind[f"{name}_m"], abs=1e-6)
        # normal to the original course, ending on the track (within half a sample's 0.12 m run)
        assert np.dot(b - a, [np.sin(psi0), np.cos(psi0)]) == pytest.approx(0.0, abs=1e-9)
        assert np.min(np.hypot(tc["y"] - b[0], tc["x"] - b[1])) < 0.06
        (text,) = _gid(ax, f"{name}_text")
        assert text.get_text() == f"{name.replace('_', ' ')}\n{ind[name + '_m']:.1f} m"
        assert text.get_color() == "tab:purple"
    # the transfer starts where the advance ends (abeam the 90 deg point on the original course)
    np.testing.assert_allclose(_arrow(_gid(ax, "transfer")[0])[0], eb, atol=1e-9)
    plt.close(fig)


def test_a_prbs_like_run_is_not_marked(trials):
    zz, _ = trials
    rng = np.random.default_rng(3)
    t = zz.t
    # a multi-level PRBS rudder: switching side at random, every 3 to 8 s, to 4 to 20 deg (holds
    # of different sizes: neither a zigzag nor a turn)
    switches = np.cumsum(rng.uniform(3.0, 8.0, 200))
    level = rng.uniform(4.0, 20.0, 201) * np.where(np.arange(201) % 2, 1.0, -1.0)
    delta = np.radians(level[np.searchsorted(switches, t)])
    run = {"x": zz["x"], "y": zz["y"], "psi": zz["psi"], "delta_r": delta}
    ind = manoeuvre_indices(t, run["x"], run["y"], run["psi"], delta)
    assert ind["kind"] == "other"
    fig, (ax, ax2) = plt.subplots(1, 2)
    before = (len(ax.get_children()), len(ax2.get_children()))
    assert mark_indices(ax, ax2, t, run)["kind"] == "other"
    assert (len(ax.get_children()), len(ax2.get_children())) == before
    # either axis may be None
    mark_indices(None, None, t, run)
    plt.close(fig)


def test_report_figures_mark_the_measured_run(trials, tmp_path):
    zz, tc = trials
    ind = manoeuvre_indices(zz.t, zz["x"], zz["y"], zz["psi"], zz["delta_r"])
    drawn = {}
    real = plots.mark_indices

    def spy(ax_plan, ax_heading, t, run, **kw):
        drawn.setdefault(kw.get("label"), []).append(real(ax_plan, ax_heading, t, run, **kw)["kind"])
        return {"kind": drawn[kw.get("label")][-1]}

    meas = {c: zz[c] for c in ("x", "y", "psi", "delta_r")}
    win = np.zeros(zz.t.size, int)
    try:
        plots.mark_indices = spy
        plots.training_fit(zz.t, meas, meas, win, tmp_path / "a.png")
        plots.prediction_band(meas, {**meas, "t": zz.t, "win": win}, {}, tmp_path / "b.png")
        plots.window_tracks(np.c_[tc["x"], tc["y"]], np.c_[tc["x"], tc["y"]], None, tmp_path / "c.png", run=tc)
    finally:
        plots.mark_indices = real
    # training fit and prediction: the measured zigzag; the whole-run prediction too; the window tracks' turn
    assert drawn == {"measured: ": ["zigzag", "zigzag", "turning"], "predicted: ": ["zigzag"]}
    assert ind["kind"] == "zigzag"
    assert all((tmp_path / f).is_file() for f in ("a.png", "b.png", "c.png"))


def _printed(out: str, label: str) -> float:
    m = re.search(rf"^\s+{label}\s+(\S+)", out, re.M)
    assert m, (label, out)
    return float(m.group(1))


@pytest.mark.parametrize(
    "manoeuvre,angle,labels",
    [
        ("zigzag", -10, ("first overshoot", "second overshoot", "initial turning time", "time to check yaw", "period")),
        ("turn", -35, ("advance", "transfer", "tactical diameter", "steady turning diameter")),
    ],
)
def test_simulate_writes_the_printed_indices_to_json_and_a_figure(tmp_path, capsys, manoeuvre, angle, labels):
    out = tmp_path / "run.csv"
    args = ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", manoeuvre, "--angle", str(angle), "--out", str(out)]
    assert cli.main(args) == 0
    text = capsys.readouterr().out
    doc = json.loads((tmp_path / "run.json").read_text())
    assert (tmp_path / "run.png").stat().st_size > 10_000
    assert doc["vehicle"]["id"] == "kvlcc2_7m"
    # the summary names the manoeuvre in the package's one vocabulary (``turn`` is an alias)
    assert doc["manoeuvre"]["name"] == canonical_kind(manoeuvre) and doc["manoeuvre"]["angle_deg"] == angle
    assert doc["bayesid_version"] and doc["command"].startswith("bayesid ")
    assert doc["indices"]["kind"] == ("zigzag" if manoeuvre == "zigzag" else "turning")
    by_name = {v["name"]: v for v in doc["indices"]["values"].values()}
    for label in labels:
        assert by_name[label]["value"] == pytest.approx(_printed(text, label), rel=1e-3), label
    assert by_name[labels[0]]["unit"] == ("deg" if manoeuvre == "zigzag" else "m")
    # never overwritten silently: the JSON alone is enough to refuse, --overwrite replaces it
    out.unlink()
    assert cli.main(args) == 2
    assert "run.json" in capsys.readouterr().err
    assert cli.main([*args, "--overwrite", "--no-figure"]) == 0
    assert out.is_file()


def test_simulate_no_figure_writes_none(tmp_path, capsys):
    out = tmp_path / "s.csv"
    args = ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "zigzag", "--angle", "-10", "--duration", "60"]
    assert cli.main([*args, "--out", str(out), "--no-figure"]) == 0
    assert (tmp_path / "s.json").is_file() and not (tmp_path / "s.png").exists()
    assert cli.main([*args, "--out", str(tmp_path / "s.json")]) == 2
    assert "another suffix" in capsys.readouterr().err


@pytest.mark.parametrize("zoom_out", [1.0, 4.0])
def test_turn_labels_do_not_overlap_on_a_large_or_a_small_circle(trials, zoom_out):
    # a turning circle small on its page (the Esso held-out turn in a 45 m wide plan view) had its
    # transfer and tactical-diameter labels on top of each other
    _, tc = trials
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.plot(tc["y"], tc["x"])
    ax.set_aspect("equal")
    mark_indices(ax, None, tc.t, tc)
    cy, cx, half = np.mean(tc["y"]), np.mean(tc["x"]), zoom_out * np.ptp(tc["x"])
    ax.set_xlim(cy - half, cy + half)
    ax.set_ylim(cx - half, cx + half)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    boxes = [_gid(ax, f"{n}_text")[0].get_window_extent(r) for n in ("advance", "transfer", "tactical_diameter")]
    for i in range(3):
        for j in range(i + 1, 3):
            assert not boxes[i].overlaps(boxes[j]), (i, j)
    plt.close(fig)
