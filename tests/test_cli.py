"""The bayesid command."""

import numpy as np

from bayesid.cli import main
from bayesid.data.track import read_csv


def test_simulate_writes_a_track(tmp_path, capsys):
    out = tmp_path / "zz.csv"
    assert (
        main(
            [
                "simulate",
                "--manoeuvre",
                "zigzag",
                "--angle",
                "10",
                "--duration",
                "30",
                "--mode",
                "horizontal",
                "--sample",
                "0.5",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    tr = read_csv(out)
    assert tr.n_samples == 61 and np.allclose(np.diff(tr.t), 0.5)
    assert np.max(np.abs(tr["delta_r"])) > 0.17


def test_bad_vehicle_is_an_error_message(tmp_path, capsys):
    assert main(["simulate", "--vehicle", "no_such_vehicle", "--out", str(tmp_path / "x.csv")]) == 2
    assert "no_such_vehicle" in capsys.readouterr().err
