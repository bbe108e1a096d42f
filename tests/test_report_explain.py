"""Reports that explain (issue 38): predict's per-window error distribution and the start rule as
resolved; fit's budget warning, training figures, file value / prior / estimate side by side and the
AR(1) inflation; sample's failed criteria, the --draws warning and no "determined" against a flat
prior; diagnose's units, noise-floor band and BIC / held-out disagreement."""

from __future__ import annotations

import csv
import json
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from diagnosis_view import diagnosis_view

from bayesid import cli
from bayesid.analysis.gap.verdict import Thresholds
from bayesid.data.track import write_csv
from bayesid.data.vehicle import load_vehicle
from bayesid.models import manoeuvres as mv
from bayesid.models.world import LogOptions, world_track

NPS = Path(str(resources.files("bayesid") / "vehicles" / "nps_auv2.toml"))


@pytest.fixture(scope="module")
def csvs(tmp_path_factory):
    """Two NPS AUV II zigzags logging every state, and the second without u, v, r and with
    0.3 m of position noise (the fitted start rule's case)."""
    veh = load_vehicle("nps_auv2")
    d = tmp_path_factory.mktemp("tracks")
    out = []
    for i, m in enumerate(
        [mv.zigzag(veh, 20.0, dt=0.1, duration=60.0), mv.zigzag(veh, 10.0, dt=0.1, duration=60.0, first_sign=-1)]
    ):
        tr = world_track(veh, m, {}, np.random.default_rng(i), LogOptions(sample_every=2), name=f"run{i}")
        write_csv(tr, d / f"run{i}.csv")
        out.append(d / f"run{i}.csv")
    rows = list(csv.reader(out[1].open()))
    keep = [j for j, c in enumerate(rows[0]) if c not in ("u", "v", "r")]
    rng = np.random.default_rng(7)
    with (d / "nolog.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([rows[0][j] for j in keep])
        for r in rows[1:]:
            w.writerow(
                [float(r[j]) + (rng.normal(0, 0.3) if rows[0][j] in ("x", "y") else 0.0) if r[j] else "" for j in keep]
            )
    return out + [d / "nolog.csv"]


def _run(args, capsys):
    rc = cli.main([str(a) for a in args])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


@pytest.fixture(scope="module")
def fitted(csvs, tmp_path_factory):
    """A two-coefficient fit whose budget (--max-nfev 3) runs out: (folder, stdout, stderr)."""
    out = tmp_path_factory.mktemp("fit") / "fit"
    args = ["fit", "--vehicle", "nps_auv2", "--free", "Nr,Yv", "--train", csvs[0], "--window", "30"]
    rc = cli.main([str(a) for a in args + ["--max-nfev", "3", "--out", out]])
    assert rc == 0
    return out


# --- predict ---------------------------------------------------------------------------------


def test_window_distribution_names_the_windows_that_dominate_the_pooled_rms():
    from bayesid.report.predict import _distribution_lines, window_distribution

    wins = [
        dict(track="a", t_start=20.0 * k, duration_s=20.0, rms_position_m=1.0, max_position_m=2.0, rms_heading_deg=1.0)
        for k in range(8)
    ]
    wins += [
        dict(track="b", t_start=40.0, duration_s=20.0, rms_position_m=10.0, max_position_m=20.0, rms_heading_deg=5.0),
        dict(track="b", t_start=60.0, duration_s=20.0, rms_position_m=9.0, max_position_m=18.0, rms_heading_deg=4.0),
    ]
    d = window_distribution(wins, worst=2)
    assert d["n_windows"] == 10 and d["rms_position_m"]["median"] == 1.0 and d["rms_position_m"]["max"] == 10.0
    assert d["rms_position_m"]["p90"] == pytest.approx(np.quantile([1.0] * 8 + [9.0, 10.0], 0.9))
    assert [(w["track"], w["t_start"]) for w in d["worst"]] == [("b", 40.0), ("b", 60.0)]
    assert d["worst_share_of_pooled_squared_error"] == pytest.approx(181.0 / 189.0)
    text = "\n".join(_distribution_lines(d))
    assert "b from t = 40 s" in text and "dominate" in text and "90th percentile" in text


def test_predict_reports_the_per_window_distribution_and_the_start_rule_as_resolved(csvs, fitted, tmp_path, capsys):
    model = fitted / "model.json"
    rc, out, err = _run(
        ["predict", "--model", model, "--track", csvs[1], "--window", "20", "--draws", "2", "--out", tmp_path / "p"],
        capsys,
    )
    assert rc == 0, err
    doc = json.loads((tmp_path / "p" / "predict.json").read_text())
    dist = doc["window_distribution"]
    r = dist["rms_position_m"]
    assert dist["n_windows"] == len(doc["windows"]) and r["median"] <= r["p90"] <= r["max"]
    assert r["max"] == pytest.approx(max(w["rms_position_m"] for w in doc["windows"]))
    worst = dist["worst"][0]
    assert {(w["track"], w["t_start"]) for w in doc["windows"]} >= {(worst["track"], worst["t_start"])}
    report = (tmp_path / "p" / "report.md").read_text()
    assert "Per-window errors" in report and "90th percentile" in report
    assert f"{worst['track']} from t = " in report and "per window median" in out
    # the track logs u, v and r: never "no velocity log"
    assert doc["start"]["rule"] == "measured" and doc["start"]["without_velocity_log"] == []
    assert "every track logs u, v and r" in report and "no velocity log" not in report
    rc, out, err = _run(
        ["predict", "--model", model, "--track", csvs[2], "--window", "20", "--draws", "2", "--out", tmp_path / "q"],
        capsys,
    )
    assert rc == 0, err
    doc = json.loads((tmp_path / "q" / "predict.json").read_text())
    report = (tmp_path / "q" / "report.md").read_text()
    assert doc["start"]["rule"] == "fitted" and doc["start"]["without_velocity_log"] == ["nolog"]
    assert "nolog lacks u, v, r" in report and "too noisy" in report


# --- fit -------------------------------------------------------------------------------------


def test_budget_exhausted_reads_the_solver_message():
    from bayesid.report.fit import budget_advice, budget_exhausted

    assert budget_exhausted({"success": False, "message": "The maximum number of function evaluations is exceeded."})
    assert not budget_exhausted({"success": True, "message": "`ftol` termination condition is satisfied."})
    assert not budget_exhausted({"success": False, "message": "diverged"})
    assert "--max-nfev 20" in budget_advice({"max_nfev": 10})


def test_fit_says_the_budget_ran_out_and_shows_file_value_prior_estimate_and_figures(csvs, tmp_path, capsys):
    veh = tmp_path / "auv.toml"
    veh.write_text(
        NPS.read_text().split("\n[prior]")[0]
        + '\n[prior]\nsource = "tank"\nYv = { mean = -0.2, sd = 0.01 }\nNr = { rel_sd = 0.5 }\n'
    )
    args = ["fit", "--vehicle", veh, "--free", "Nr,Yv", "--train", csvs[0], "--window", "30", "--max-nfev", "3"]
    rc, out, err = _run(args + ["--out", tmp_path / "f"], capsys)
    assert rc == 0, err
    assert "budget" in err and "--max-nfev 6" in err
    doc = json.loads((tmp_path / "f" / "model.json").read_text())
    report = (tmp_path / "f" / "report.md").read_text()
    assert "**Budget ran out**" in report
    assert "| parameter | vehicle file | prior N(mean, sd) | identified |" in report and "| start |" not in report
    yv = doc["prior"]["coefficients"]["Yv"]
    assert abs(yv["z"]) > 3  # the file's -0.2 +- 0.01 against the data's value near -0.1
    assert "**Far from their prior**" in report and "Yv (" in report and "Nr (" not in report.split("Far from")[1]
    assert "(1 + rho) / (1 - rho)" in report and "widened" in report
    for run in doc["train_runs"]:
        assert (tmp_path / "f" / "figures" / f"training_{run}.png").is_file()
        assert f"(figures/training_{run}.png)" in report


def test_fit_report_without_a_prior_says_so_and_shows_the_vehicle_file_values(fitted):
    report = (fitted / "report.md").read_text()
    row = next(line for line in report.splitlines() if line.startswith("| Yv |"))
    assert row.split("|")[2].strip() == "-0.1" and row.split("|")[3].strip() == "none"  # nps_auv2's Yv
    assert "No prior in this fit" in report


# --- sample ----------------------------------------------------------------------------------


def test_sample_names_the_failed_criterion_warns_on_draws_and_judges_no_flat_prior(csvs, fitted, tmp_path, capsys):
    rc, out, err = _run(
        [
            "sample",
            "--model",
            fitted / "model.json",
            "--train",
            csvs[0],
            "--draws",
            "150",
            "--method",
            "importance",
            "--out",
            tmp_path / "s",
        ],
        capsys,
    )
    assert rc == 0, err
    assert "--draws 150 cannot reach the ESS criterion" in err
    doc = json.loads((tmp_path / "s" / "sample.json").read_text())
    crit = {c["criterion"]: c for c in doc["verdict_criteria"]}
    assert set(crit) == {"Pareto k-hat", "importance ESS"} and not crit["importance ESS"]["passed"]
    report = (tmp_path / "s" / "report.md").read_text()
    assert "Failed: importance ESS" in report and "(needs >= 400)" in report and "Failed: importance ESS" in out
    assert "| importance ESS |" in report and "**failed**" in report and "cannot reach the ESS criterion" in report
    coef = doc["dossier"]["coefficients"]
    assert all(c["prior"] != "normal" and c["status"] == "flat prior" for c in coef.values())
    table = report.split("## Coefficients")[1].split("\n\n")[2]
    assert "determined" not in table and "flat prior" in table


def test_criterion_text_says_which_way_a_test_failed():
    from bayesid.report.sample import criterion_text

    c = {"criterion": "Pareto k-hat", "value": 0.81, "test": "<", "threshold": 0.7, "passed": False}
    assert criterion_text(c) == "Pareto k-hat 0.81 >= 0.7 (needs < 0.7)"
    c = {"criterion": "R-hat", "value": 1.003, "test": "<=", "threshold": 1.01, "passed": True}
    assert criterion_text(c) == "R-hat 1.003 <= 1.01"


# --- diagnose --------------------------------------------------------------------------------


def _ranked(effect, held, shrink, p, dbic, removed):
    from test_failed_fit import _row

    return _row(
        effect=effect,
        heldout_rms_m=held,
        heldout_shrinkage=shrink,
        window_p_value=p,
        delta_bic=dbic,
        excess_removed=removed,
    ).to_dict()


def test_a_sentence_where_bic_and_the_heldout_windows_disagree():
    from bayesid.report.diagnosis import _bic_heldout_lines

    th = Thresholds(bic_threshold=-10.0, partial_p=0.01, explain_fraction=0.5)
    res = {
        "thresholds": th,
        "ranking": [
            _ranked("thrust", 0.52, -0.08, 1.0, -587.0, -0.4),  # BIC yes, held-out no
            _ranked("delay", 0.40, 0.2, 0.001, 4.0, 0.3),  # held-out yes, BIC no
            _ranked("current", 0.40, 0.2, 0.001, -50.0, 0.3),  # both agree
            _ranked("wind", 0.52, -0.08, 0.9, 3.0, -0.4),  # both agree (no)
            _ranked("waves", 0.30, 0.4, 0.05, -900.0, 0.4),  # BIC yes, a held-out gain that is not significant
        ],
    }
    text = "\n".join(_bic_heldout_lines(diagnosis_view(**res)))
    assert "disagree on thrust" in text and "no held-out gain" in text and "0.481 m -> 0.52 m" in text
    waves = next(ln for ln in text.splitlines() if "disagree on waves" in ln)
    assert "held-out gain is not significant" in waves and "no held-out gain" not in waves
    assert "disagree on delay" in text and "does not support it" in text
    assert "disagree on current" not in text and "disagree on wind" not in text


def test_ranking_figure_draws_the_noise_floor_band(tmp_path, monkeypatch):
    import matplotlib.axes

    from bayesid.report import plots

    spans = []
    orig = matplotlib.axes.Axes.axvspan

    def spy(self, *a, **k):
        spans.append((a, k))
        return orig(self, *a, **k)

    monkeypatch.setattr(matplotlib.axes.Axes, "axvspan", spy)
    rk = [{"effect": "thrust", "heldout_rms_m": 0.52}, {"effect": "delay", "heldout_rms_m": 0.48}]
    plots.gap_ranking(rk, 0.48, 0.385, tmp_path / "r.png", band_ratio=1.5)
    assert (tmp_path / "r.png").is_file()
    assert len(spans) == 1 and spans[0][0] == pytest.approx((0.385, 1.5 * 0.385))
    assert "noise-floor band" in spans[0][1]["label"]


def test_diagnose_report_gives_units_and_the_band(csvs, tmp_path, capsys, monkeypatch):
    import matplotlib.axes

    labels = []
    orig = matplotlib.axes.Axes.axvspan

    def spy(self, *a, **k):
        labels.append(k.get("label") or "")
        return orig(self, *a, **k)

    monkeypatch.setattr(matplotlib.axes.Axes, "axvspan", spy)
    args = ["diagnose", "--vehicle", "nps_auv2", "--free", "Nr", "--train", csvs[0], "--heldout", csvs[1]]
    args += ["--window", "30", "--candidates", "delay", "--max-nfev", "3", "--max-effects", "1"]
    rc, out, err = _run(args + ["--out", tmp_path / "d"], capsys)
    assert rc == 0, err
    report = (tmp_path / "d" / "report.md").read_text()
    where = report.split("## Where")[1]
    psi = next(line for line in where.splitlines() if line.startswith("| psi |"))
    assert psi.count(" deg") == 3
    x = next(line for line in where.splitlines() if line.startswith("| x |"))
    assert x.count(" m |") == 3
    res = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    if "error" not in res["where"]["forces"]:
        assert " N m" in where.split("Missing forces")[1].splitlines()[0]
    assert "psi " in report and "deg, u " in report  # the channel weights with their units
    assert "(figures/ranking.png)" in report and any("noise-floor band" in lb for lb in labels)


def test_mcmc_criteria_name_the_failed_rhat_and_the_tau_rule():
    from types import SimpleNamespace

    from bayesid.cli.sample import _criteria
    from bayesid.estimation.sampling import RHAT_MAX
    from bayesid.report.sample import _criteria_lines

    v = dict(method="mcmc", rhat_max=1.05, ess_bulk_min=900.0, ess_tail_min=800.0, tau_max=20.0)
    res = SimpleNamespace(verdict=v, mcmc={"result": SimpleNamespace(n_steps=600, reached_tau_rule=False)})
    crit = _criteria(res)
    assert [c["passed"] for c in crit] == [False, True, True, False]
    assert crit[0]["threshold"] == RHAT_MAX and crit[3]["value"] == 30.0
    text = "\n".join(_criteria_lines({"verdict": v, "verdict_criteria": crit}))
    assert "Failed: R-hat (max over parameters) 1.05 > 1.01" in text and "does not meet the tau rule" in text
