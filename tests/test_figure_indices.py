"""The figures label the indices the tables give (issue 50): ``bayesid predict``'s figure of a 35
deg turn marks the advance, transfer and tactical diameter that ``predict.json`` and ``report.md``
give, measured and predicted. With the fitted start rule the scored samples begin after the 10 s
lead-in, at the execute; the figure read its indices from them, and its advance was 21.5 m where
the table said 21.7 m (the approach before the execute cut off)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from bayesid import cli  # noqa: E402
from bayesid.data.track import read_csv  # noqa: E402
from bayesid.estimation.indices import manoeuvre_indices  # noqa: E402
from bayesid.report import plots  # noqa: E402
from bayesid.report.markdown import fmt  # noqa: E402

TURN = ("advance", "transfer", "tactical_diameter")
COLOURS = {"measured": "tab:red", "predicted": "tab:purple"}


def _run(args):
    assert cli.main([str(a) for a in args]) == 0


@pytest.fixture
def saved(monkeypatch):
    """{file name: figure} of every figure the report layer writes (drawn, then closed)."""
    figs, real = {}, plots._save

    def keep(fig, path):
        figs[Path(path).name] = fig
        return real(fig, path)

    monkeypatch.setattr(plots, "_save", keep)
    return figs


def _labels(fig) -> dict:
    """{(run, index): label text} of the turning-circle values marked on a figure, the run told
    by the marks' colour."""
    run = {v: k for k, v in COLOURS.items()}
    return {
        (run[a.get_color()], name): a.get_text()
        for ax in fig.axes
        for a in ax.texts
        for name in TURN
        if a.get_gid() == f"{plots.MARK_GID}{name}_text"
    }


def test_predict_figure_labels_the_indices_of_the_table(tmp_path, capsys, saved):
    csv = tmp_path / "turn.csv"
    _run(["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "turn", "--angle", -35, "--duration", 80, "--out", csv])
    _run(["fit", "--vehicle", "kvlcc2_7m", "--free", "Nr", "--train", csv, "--max-nfev", 1, "--out", tmp_path / "f"])
    pred = tmp_path / "p"
    # one window over the whole run (the predicted marks too), windows started after a fitted lead-in
    _run(
        ["predict", "--model", tmp_path / "f" / "model.json", "--track", csv, "--start", "fitted"]
        + ["--score-window", 0, "--draws", 0, "--out", pred]
    )
    capsys.readouterr()
    doc = json.loads((pred / "predict.json").read_text())
    assert doc["start_rule"] == "fitted" and doc["leadin_s"] >= 10.0
    ind = doc["indices"]["turn"]
    assert ind["measured"]["kind"] == ind["predicted"]["kind"] == "turning"
    labels = _labels(saved["turn.png"])
    assert len(labels) == 6, labels
    table = (pred / "report.md").read_text()
    for run in ("measured", "predicted"):
        for name in TURN:
            value = ind[run][f"{name}_m"]
            assert labels[run, name] == f"{name.replace('_', ' ')}\n{value:.1f} m", (run, name)
    # the report's line of the indices shows the same values
    line = re.search(r"^- turn \(turning\): (.*)$", table, re.M).group(1)
    for name in TURN:
        m, p = (fmt(ind[run][f"{name}_m"]) for run in ("measured", "predicted"))
        assert f"{name}_m measured {m}, predicted {p}" in line


def test_prediction_band_reads_the_whole_run_when_given_no_indices(tmp_path, saved):
    # the fallback: a measured run with its own times (the whole run) and a prediction that starts
    # after the execute; the indices are read from the whole run, the prediction's with the
    # measured samples before it
    csv = tmp_path / "turn.csv"
    _run(["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "turn", "--angle", -35, "--duration", 80, "--out", csv])
    tr = read_csv(csv)
    whole = manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
    assert whole["execute_t_s"] < 12.0
    later = tr.t >= 12.0
    measured = {c: tr[c] for c in ("t", "x", "y", "psi", "delta_r")}
    predicted = {c: tr[c][later] for c in ("x", "y", "psi")}
    predicted.update(t=tr.t[later], win=np.zeros(later.sum(), int))
    plots.prediction_band(measured, predicted, {}, tmp_path / "b.png")
    labels = _labels(saved["b.png"])
    for run in ("measured", "predicted"):
        for name in TURN:
            assert labels[run, name] == f"{name.replace('_', ' ')}\n{whole[name + '_m']:.1f} m", (run, name)
