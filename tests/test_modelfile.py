"""model.json has one reader and writer (ModelDocument): a file written by bayesid 0.1.0 before
the class existed loads, rebuilds its model and writes back the same JSON object; files that lack
the optional fields get their defaults; a damaged file is refused, naming it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bayesid.estimation.modelfile import FORMAT, ModelDocument, load_model

OLD = Path(__file__).resolve().parent / "data" / "model_written_by_0.1.0.json"


def test_a_file_written_before_the_class_loads_and_round_trips(tmp_path):
    raw = json.loads(OLD.read_text())
    model, p, cov, doc = load_model(OLD)
    assert doc.vehicle == "nps_auv2" and list(model.free) == ["Yv", "Nr", "Ndr"]
    assert np.array_equal(p, np.array(raw["p"])) and cov.shape == (3, 3)
    assert doc.calibration.n_folds == 3 and doc.provenance["bayesid_version"] == "0.1.0"
    doc.to_json(tmp_path / "again.json")
    assert json.loads((tmp_path / "again.json").read_text()) == raw
    assert (tmp_path / "again.json").read_text() == OLD.read_text()  # byte for byte
    assert list(json.loads((tmp_path / "again.json").read_text())) == list(raw)  # the same key order


def test_the_calibration_section_reads_and_writes_back_unchanged():
    """Calibration.from_dict reads what to_dict writes, in its key order, and a calibration
    written before it recorded the excitation and the structural scales (the first format)."""
    from bayesid.estimation.calibration import Calibration

    raw = json.loads(OLD.read_text())["calibration"]
    cal = Calibration.from_dict(raw)
    assert cal.n_folds == 3 and cal.window_s == 60.0 and len(cal.fold_optima()) == 3
    assert cal.to_dict() == raw and list(cal.to_dict()) == list(raw)
    first = {k: v for k, v in raw.items() if k not in ("excitation", "index_score", "structural_scale")}
    old = Calibration.from_dict(first)
    assert old.excitation is None and old.excitation_range() == {}
    assert old.to_dict() == first and list(old.to_dict()) == list(first)
    assert old.normalised_index_scores() == cal.normalised_index_scores()  # recomputed from the folds


def test_optional_fields_get_their_defaults(tmp_path):
    raw = json.loads(OLD.read_text())
    for k in ("weighting", "fit_sd", "fit_channels", "start_rule", "prior", "calibration", "provenance"):
        raw.pop(k)
    path = tmp_path / "old.json"
    path.write_text(json.dumps(raw))
    doc = ModelDocument.from_json(path)
    assert doc.weighting == "noise" and doc.fit_sd == raw["noise_sd"] and doc.fit_channels is None
    assert doc.start_rule == "measured" and doc.prior == {"used": False} and doc.calibration is None
    assert doc.provenance == {}
    model, p, _ = doc.build()
    assert p.size == model.n_params


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda d: d.update(format="other"), "not a bayesid model file"),
        (lambda d: d.pop("cov"), "without 'cov'"),
        (lambda d: d.update(free="Yv"), "'free' and 'effects' lists"),
        (lambda d: d.update(p=[1.0, 2.0]), "'p' must be 3 finite numbers"),
        (lambda d: d.update(cov=[[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), "not a symmetric"),
        (lambda d: d.update(free=["Yv", "Xyz"]), "do not fit the vehicle"),
    ],
)
def test_a_damaged_file_is_refused_naming_it(tmp_path, edit, match):
    raw = json.loads(OLD.read_text())
    edit(raw)
    path = tmp_path / "damaged.json"
    path.write_text(json.dumps(raw))
    with pytest.raises(ValueError, match=match) as err:
        load_model(path)
    assert str(path) in str(err.value)


def test_a_sampled_posterior_replaces_the_estimate_and_keeps_the_rest(tmp_path):
    _, _, _, doc = load_model(OLD)
    post = doc.with_posterior([0.1, 0.2, 0.3], np.diag([1.0, 4.0, 9.0]), {"method": "importance"})
    assert post.p == [0.1, 0.2, 0.3] and post.sd == [1.0, 2.0, 3.0]
    d = post.to_dict()
    assert d["format"] == FORMAT and list(d)[-1] == "posterior_source"
    assert {k: v for k, v in d.items() if k not in ("p", "cov", "sd", "posterior_source")} == {
        k: v for k, v in doc.to_dict().items() if k not in ("p", "cov", "sd")
    }


def test_one_free_coefficient_gets_a_posterior_document_and_a_dossier():
    """bayesid sample with one free coefficient: np.cov of its draws is 0-d and it has no pair of
    coefficients to correlate (both raised before)."""
    from bayesid.analysis.dossier import data_dossier

    class FlatPrior:
        gaussian = np.array([False])

        def marginal_mean(self):
            return np.array([np.nan])

        def marginal_sd(self):
            return np.array([np.inf])

    draws = np.random.default_rng(0).normal(0.5, 0.1, size=(400, 1))
    d = data_dossier(["Nr"], np.array([[4.0]]), np.array([[2.0], [0.0]]), np.array([1.0]), FlatPrior(), draws)
    assert d["correlations"] == [] and d["collinearity"] == [] and d["coefficients"]["Nr"]["status"] == "determined"
    raw = json.loads(OLD.read_text())
    one = dict(raw, free=["Nr"], param_names=["Nr"], p=[raw["p"][1]], cov=[[raw["cov"][1][1]]], sd=[raw["sd"][1]])
    doc = ModelDocument(**{k: v for k, v in one.items() if k != "format"})
    post = doc.with_posterior(draws.mean(axis=0), np.cov(draws, rowvar=False), {"method": "importance"})
    assert np.array(post.cov).shape == (1, 1) and post.sd[0] == pytest.approx(0.1, rel=0.1)


def test_sample_dossier_marks_a_round_off_null_space_and_reports_it_by_coefficient():
    """Two coefficients the tracks see only through their sum (the Jacobian's columns equal): the
    Fisher information has one eigenvalue at round-off level; the dossier marks that direction
    round-off and gives the space by its projector's diagonal (0.5 each), and the sample report
    says so."""
    from bayesid.analysis.dossier import data_dossier
    from bayesid.report.sample import _round_off_lines

    class FlatPrior:
        gaussian = np.array([False, False, False])

        def marginal_mean(self):
            return np.full(3, np.nan)

        def marginal_sd(self):
            return np.full(3, np.inf)

    rng = np.random.default_rng(1)
    J = rng.normal(size=(50, 3))
    J[:, 1] = J[:, 0]
    draws = rng.normal(0.5, 0.1, size=(400, 3))
    d = data_dossier(["Yv", "Yr", "Nr"], J.T @ J, J, np.ones(3), FlatPrior(), draws)
    assert d["n_round_off_eigenvalues"] == 1
    assert [r["round_off"] for r in d["directions"]] == [True, False, False]
    assert d["round_off_participation"] == pytest.approx({"Yv": 0.5, "Yr": 0.5}, abs=1e-9)
    assert "1 Fisher eigenvalue(s) are at round-off level" in "\n".join(_round_off_lines(d))
    json.dumps(d)


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_a_failed_posteriors_constant_draws_leak_no_runtime_warning():
    """A posterior whose draws are one repeated point (ESS 1, issue 69): the dossier's correlations
    are undefined (NaN), said without numpy's RuntimeWarning leaking to the user."""
    from bayesid.analysis.dossier import data_dossier

    class FlatPrior:
        gaussian = np.array([False, False])

        def marginal_mean(self):
            return np.full(2, np.nan)

        def marginal_sd(self):
            return np.full(2, np.inf)

    draws = np.tile([[0.5, -0.2]], (400, 1))
    J = np.random.default_rng(2).normal(size=(30, 2))
    d = data_dossier(["Yv", "Nr"], J.T @ J, J, np.ones(2), FlatPrior(), draws)
    assert np.isnan(d["correlations"][0]["r"])
