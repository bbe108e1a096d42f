"""A fit whose covariance cannot be trusted says so (issue 69): a free coefficient the tracks do
not determine (the wind coefficient ``Cn1`` of a run without wind, which has no prior in the ship
file) made the Laplace covariance singular. With the file's priors the fit ended in a
``LinAlgError`` traceback; without a prior the pseudo-inverse gave the direction zero variance,
an sd of 0 printed as if it were known exactly."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import bayesid
from bayesid import cli
from bayesid.data.track import write_csv
from bayesid.estimation.laplace import CovarianceWarning, covariance_sentence
from bayesid.models.ship import load_ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial


@pytest.fixture(scope="module")
def zigzag():
    ship = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(ship, 1.179)
    opts = TrialOptions(dt=0.1, sample_every=5, duration=120.0)
    return ship, simulate_trial(ship, "zigzag", 20.0, speed=speed, rpm=rpm, options=opts).track


def _identify(ship, track, free, prior=True):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = bayesid.identify(ship, [track], bayesid.FitOptions(free=free, max_nfev=10, prior=prior))
    return res, [w for w in caught if issubclass(w.category, CovarianceWarning)]


@pytest.mark.parametrize("prior", [True, False], ids=["file's priors", "no prior"])
def test_a_coefficient_the_runs_do_not_determine_is_flagged_not_given_an_sd_of_zero(zigzag, prior):
    ship, track = zigzag
    res, caught = _identify(ship, track, ("Nr", "Cn1"), prior)
    assert res.posterior["directions_cut"] == 1 and res.posterior["sds_meaningful"] is False
    assert len(caught) == 1 and "near-singular" in str(caught[0].message)
    assert covariance_sentence(res.posterior) == str(caught[0].message)


def test_a_determined_fit_raises_no_covariance_warning(zigzag):
    ship, track = zigzag
    res, caught = _identify(ship, track, ("Nr", "Yr"))
    assert res.posterior["directions_cut"] == 0 and res.posterior["sds_meaningful"] is True
    assert not caught and covariance_sentence(res.posterior) is None
    assert np.all(np.sqrt(np.diag(res.cov)) > 0)


def test_bayesid_fit_prints_it_and_the_report_says_it(zigzag, tmp_path, capsys):
    _, track = zigzag
    write_csv(track, tmp_path / "z20.csv")
    rc = cli.main(["fit", "--vehicle", "kvlcc2_7m", "--train", str(tmp_path / "z20.csv"), "--free", "Nr,Cn1"]
                  + ["--max-nfev", "10", "--out", str(tmp_path / "fit")])  # fmt: skip
    assert rc == 0
    assert "near-singular" in capsys.readouterr().err
    assert "**Covariance:** The Laplace covariance is near-singular" in (tmp_path / "fit" / "report.md").read_text()
