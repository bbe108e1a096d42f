"""Priors from a vehicle file (issue 31): the [prior] section is read for submarines and ships,
bad entries are errors naming the file and the coefficient, a MAP fit is pulled to the prior where
the data say little, and what ``fit`` writes ``predict`` accepts (an ill-conditioned covariance is
round-off, not an edit)."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from bayesid.cli import main
from bayesid.data.vehicle import VehicleFileError, load_vehicle
from bayesid.estimation.laplace import psd_covariance
from bayesid.estimation.modelfile import load_model
from bayesid.models.ship import ShipFileError, load_ship

NPS = Path(str(resources.files("bayesid") / "vehicles" / "nps_auv2.toml"))
KVLCC2 = Path(str(resources.files("bayesid") / "vehicles" / "kvlcc2_7m.toml"))


def _with_prior(tmp_path, src: Path, section: str, name="v.toml") -> Path:
    f = tmp_path / name
    f.write_text(src.read_text().split("\n[prior]")[0] + "\n[prior]\n" + section + "\n")
    return f


def test_the_kvlcc2_file_carries_the_captive_test_priors_with_a_source():
    ship = load_ship("kvlcc2_7m")
    assert "Yasukawa" in ship.prior_source
    assert ship.prior["Yv"] == pytest.approx((-0.315, 0.0315))  # 10 % of the captive-test value
    assert ship.prior["Xvr"] == pytest.approx((0.002, 0.02))  # an absolute sd
    assert "Ycf" not in ship.prior and "dR0" not in ship.prior  # uniform inside the bounds
    assert ship.with_coefficients({"Yv": -0.3}).prior == ship.prior


def test_a_prior_section_of_a_submarine_file(tmp_path):
    f = _with_prior(
        tmp_path, NPS, 'source = "tank"\nrel_sd = 0.2\ncoefficients = ["Yv", "Nr"]\nYdr = { mean = 0.02, sd = 0.005 }'
    )
    v = load_vehicle(f)
    assert v.prior["Yv"] == pytest.approx((v.coefficients["Yv"], 0.2 * abs(v.coefficients["Yv"])))
    assert v.prior["Ydr"] == (0.02, 0.005) and v.prior_source == "tank"
    assert load_vehicle("nps_auv2").prior == {}


@pytest.mark.parametrize(
    "section,message",
    [
        ("Yfoo = { rel_sd = 0.1 }", "unknown coefficient 'Yfoo'"),
        ("Yv = { sd = 0.0 }", "Yv: sd must be positive"),
        ("Yv = { sd = -1 }", "Yv: sd must be positive"),
        ("Yv = { rel_sd = -0.1 }", "Yv: rel_sd must be positive"),
        ("Yv = { rel_sd = 0.1, sd = 0.1 }", "exactly one of sd and rel_sd"),
        ("Yv = { rel = 0.1 }", "unknown key"),
        ("Yv = 0.1", "Yv = 0.1"),
        ('rel_sd = 0.1\ncoefficients = ["Yv"]\nYv = { sd = 1.0 }', "Yv given twice"),
    ],
)
def test_bad_prior_entries_name_the_file_and_the_coefficient(tmp_path, section, message):
    f = _with_prior(tmp_path, NPS, section)
    with pytest.raises(VehicleFileError, match=message) as e:
        load_vehicle(f)
    assert str(f) in str(e.value)
    g = _with_prior(tmp_path, KVLCC2, section.replace("Ydr", "Yv"), "ship.toml")
    if "Yfoo" in section:  # ships check names against their own (MMG) coefficients
        with pytest.raises(ShipFileError, match="unknown coefficient 'Yfoo'"):
            load_ship(g)


def test_a_map_fit_stays_at_the_prior_where_the_data_say_little(tmp_path, capsys):
    """A straight run says nothing about Nr: with a tight prior the fit keeps Nr at the prior mean;
    without it the fit is free to wander; the prior's coefficient table is in the outputs."""
    assert (
        main(
            [
                "simulate",
                "--manoeuvre",
                "zigzag",
                "--angle",
                "15",
                "--mode",
                "horizontal",
                "--duration",
                "90",
                "--sample",
                "0.5",
                "--out",
                str(tmp_path / "z.csv"),
            ]
        )
        == 0
    )
    v = load_vehicle("nps_auv2")
    nr = v.coefficients["Nr"]
    f = _with_prior(tmp_path, NPS, f'source = "test"\nNr = {{ mean = {nr * 1.3}, sd = {abs(nr) * 0.01} }}')
    common = [
        "fit",
        "--vehicle",
        str(f),
        "--train",
        str(tmp_path / "z.csv"),
        "--free",
        "Yv,Nv,Nr,Ndr",
        "--max-nfev",
        "15",
    ]
    assert main([*common, "--out", str(tmp_path / "with")]) == 0
    assert main([*common, "--prior", "none", "--out", str(tmp_path / "without")]) == 0
    w = json.loads((tmp_path / "with" / "model.json").read_text())
    wo = json.loads((tmp_path / "without" / "model.json").read_text())
    i = w["param_names"].index("Nr")
    assert w["prior"]["used"] and not wo["prior"]["used"]
    c = w["prior"]["coefficients"]["Nr"]
    # the zigzag does determine Nr: the data pull it off a prior 30 % away; the fit is between
    assert abs(w["p"][i] - nr * 1.3) < abs(wo["p"][i] - nr * 1.3)
    assert c["posterior_sd"] < c["sd"] and c["z"] == pytest.approx((w["p"][i] - nr * 1.3) / (abs(nr) * 0.01))
    assert "## Priors from the vehicle file" in (tmp_path / "with" / "report.md").read_text()
    assert ("Nr" in w["prior"]["moved"]) == (abs(c["z"]) > 1)
    # predict accepts what fit wrote, with the prior or without
    for d in ("with", "without"):
        assert (
            main(
                [
                    "predict",
                    "--model",
                    str(tmp_path / d / "model.json"),
                    "--track",
                    str(tmp_path / "z.csv"),
                    "--draws",
                    "0",
                    "--score-window",
                    "30",
                    "--out",
                    str(tmp_path / f"p_{d}"),
                ]
            )
            == 0
        )


def test_predict_accepts_round_off_in_a_covariance_and_refuses_an_edit(tmp_path, capsys):
    assert (
        main(
            [
                "simulate",
                "--manoeuvre",
                "zigzag",
                "--angle",
                "15",
                "--mode",
                "horizontal",
                "--duration",
                "60",
                "--sample",
                "0.5",
                "--out",
                str(tmp_path / "z.csv"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "fit",
                "--vehicle",
                "nps_auv2",
                "--train",
                str(tmp_path / "z.csv"),
                "--free",
                "Yv,Nr",
                "--max-nfev",
                "3",
                "--out",
                str(tmp_path / "f"),
            ]
        )
        == 0
    )
    doc = json.loads((tmp_path / "f" / "model.json").read_text())
    rng = np.random.default_rng(0)
    A = rng.normal(size=(2, 2))
    # an ill-conditioned covariance as a Gauss-Newton inverse leaves it: eigenvalues 1e-9 and 1e3,
    # asymmetric at 2e-7 relative
    C = A @ np.diag([1e-9, 1e3]) @ A.T
    C[0, 1] *= 1 + 2e-7
    for name, cov, ok in (("roundoff", C, True), ("edited", C * [[1, 1.01], [1, 1]], False)):
        (tmp_path / "f" / f"{name}.json").write_text(json.dumps(dict(doc, cov=cov.tolist())))
        rc = main(
            [
                "predict",
                "--model",
                str(tmp_path / "f" / f"{name}.json"),
                "--track",
                str(tmp_path / "z.csv"),
                "--draws",
                "5",
                "--score-window",
                "30",
                "--out",
                str(tmp_path / f"p_{name}"),
            ]
        )
        assert (rc == 0) == ok, (name, capsys.readouterr().err)
    assert "not a symmetric positive semi-definite" in capsys.readouterr().err
    model, p, cov, _ = load_model(tmp_path / "f" / "roundoff.json")
    assert np.array_equal(cov, cov.T) and np.linalg.eigvalsh(cov).min() >= 0


def test_psd_covariance_keeps_a_good_matrix_and_clips_round_off():
    C = np.array([[2.0, 0.5], [0.5, 1.0]])
    assert np.allclose(psd_covariance(C), C)
    D = np.array([[1.0, 1.0], [1.0, 1.0 - 1e-12]])
    assert np.linalg.eigvalsh(psd_covariance(D)).min() >= 0
