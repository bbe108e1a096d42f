"""The API says what the CLI says (issue 69): every warning ``bayesid fit`` prints about its files
is a Python warning (:class:`bayesid.data.validate.TrackWarning`) from ``bayesid.identify`` on the
same tracks, and the command prints each once (its own line, not the API's as well)."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np

import bayesid
from bayesid.cli import main
from bayesid.data.track import Track, write_csv
from bayesid.data.validate import BayesidWarning, TrackWarning, in_api_terms
from bayesid.models.ship import load_ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial

FREE = ("Yv", "Nr")


def _files(tmp_path):
    """Two 2 Hz zigzags (a coarse log for the rudder's rate), the second with a compass heading."""
    kv = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(kv, 1.179)
    files = []
    for i, angle in enumerate((20.0, -20.0)):
        opts = TrialOptions(dt=0.1, duration=100.0, sample_every=5, rudder_rate_deg_s=15.8)
        tr = simulate_trial(kv, "zigzag", angle, speed=speed, rpm=rpm, options=opts).track
        if i == 1:  # turned half a circle and the heading wrapped to (-pi, pi] like a compass
            psi = np.angle(np.exp(1j * (np.asarray(tr["psi"]) + math.pi)))
            tr = tr.with_columns(psi=psi, x=-np.asarray(tr["x"]), y=-np.asarray(tr["y"]))
        path = tmp_path / f"z{i}.csv"
        write_csv(Track(np.asarray(tr.t, float), dict(tr.data), name=f"z{i}", meta=tr.meta), path)
        files.append(path)
    return files


def _text(w: str) -> str:
    """A warning without its leading file or track name."""
    return w.split(": ", 1)[1]


def test_every_warning_bayesid_fit_prints_on_a_file_is_a_python_warning_of_identify(tmp_path, capsys):
    files = _files(tmp_path)
    out = tmp_path / "fit"
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        assert main(["fit", "--vehicle", "kvlcc2_7m", "--free", ",".join(FREE), "--train", *map(str, files)]
                    + ["--max-nfev", "2", "--calibration", "none", "--out", str(out)]) == 0  # fmt: skip
    err = capsys.readouterr().err
    cli = json.loads((out / "model.json").read_text())["provenance"]["warnings"]
    assert any("wrapped like a compass" in w for w in cli) and any("coarse for the rudder" in w for w in cli)
    assert "warning: " in err
    # each printed once: the command's own line, the API's warnings silenced inside it
    assert not [r for r in rec if issubclass(r.category, BayesidWarning)]
    tracks = [bayesid.read_csv(f) for f in files]
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        bayesid.identify(load_ship("kvlcc2_7m"), tracks, bayesid.FitOptions(free=FREE, max_nfev=2))
    api = [str(r.message) for r in rec if issubclass(r.category, TrackWarning)]
    # the API's text is the command's, with the API's name of each command option it names
    assert {_text(in_api_terms(w)) for w in cli} <= {_text(w) for w in api}, (cli, api)
    rudder = next(w for w in api if "coarse for the rudder" in w)
    assert '--inputs rate is FitOptions(inputs="rate")' in rudder and "rudder_rate_deg_s" in rudder, rudder
    assert all(issubclass(r.category, BayesidWarning) for r in rec if "rudder" in str(r.message))
