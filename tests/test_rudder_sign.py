"""The rudder's sign convention (issue 50): a log whose positive rudder turns the vessel to
starboard (the MMG papers' convention) is refused naming ``delta_r``, never fitted silently; the
comment ``# rudder positive: starboard`` reads it into the package's convention (+ = to port)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayesid import cli
from bayesid.data.track import TrackFormatError, read_csv, write_csv
from bayesid.data.validate import check_track, rudder_response


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Package-simulated runs (the package's sign), logged at 0.5 s."""
    d = tmp_path_factory.mktemp("sign")
    out = {}
    for vehicle, manoeuvre in (("kvlcc2_7m", "zigzag"), ("kvlcc2_7m", "turn"), ("nps_auv2", "zigzag")):
        p = d / f"{vehicle}_{manoeuvre}.csv"
        argv = ["simulate", "--vehicle", vehicle, "--manoeuvre", manoeuvre, "--sample", "0.5"]
        assert cli.main([*argv, "--out", str(p), "--no-figure"]) == 0
        out[(vehicle, manoeuvre)] = p
    return out


def _negated(path, out, comment=None):
    tr = read_csv(path)
    tr = tr.with_columns(delta_r=-tr["delta_r"])
    if comment:
        tr.meta["comments"] = [comment]
    write_csv(tr, out)
    return out


@pytest.mark.parametrize("key", [("kvlcc2_7m", "zigzag"), ("kvlcc2_7m", "turn"), ("nps_auv2", "zigzag")])
def test_the_packages_own_runs_turn_to_port_with_a_positive_rudder_and_pass(runs, key, tmp_path):
    tr = read_csv(runs[key])
    resp = rudder_response(tr)
    assert resp["t"] < 0 and resp["t_K"] < 0
    # the sign: no word (the log-rate warnings are about timing)
    assert not [w for w in check_track(tr) if "delta_r" in w and "between samples" not in w and "jumps" not in w]
    neg = read_csv(_negated(runs[key], tmp_path / "neg.csv"))
    with pytest.raises(ValueError, match="column 'delta_r'.*rudder positive: starboard"):
        check_track(neg, where="neg.csv")


def test_a_fit_on_runs_logged_with_the_other_sign_exits_2_naming_the_column(runs, tmp_path, capsys):
    neg = _negated(runs[("kvlcc2_7m", "zigzag")], tmp_path / "mmg_sign.csv")
    rc = cli.main(["fit", "--vehicle", "kvlcc2_7m", "--train", str(neg), "--out", str(tmp_path / "fit")])
    err = capsys.readouterr().err
    assert rc == 2
    assert "mmg_sign.csv" in err and "delta_r" in err and "Traceback" not in err


def test_the_rudder_positive_comment_reads_the_other_convention_once(runs, tmp_path):
    src = runs[("kvlcc2_7m", "zigzag")]
    own = read_csv(src)
    p = _negated(src, tmp_path / "declared.csv", comment="rudder positive: starboard")
    back = read_csv(p)
    np.testing.assert_array_equal(back["delta_r"], own["delta_r"])
    assert "negated on reading" in back.meta["comments"][0]
    assert not [w for w in check_track(back) if "delta_r" in w and "between samples" not in w]
    write_csv(back, tmp_path / "copy.csv")  # a written copy is in the package's sign: read as is
    np.testing.assert_array_equal(read_csv(tmp_path / "copy.csv")["delta_r"], own["delta_r"])


def test_a_rudder_positive_comment_of_another_word_names_the_file(tmp_path):
    p = tmp_path / "odd.csv"
    p.write_text("# rudder positive: right\nt,x,y,psi,delta_r\n0,0,0,0,0\n1,1,0,0,0.1\n")
    with pytest.raises(TrackFormatError, match="odd.csv.*port or starboard"):
        read_csv(p)


def test_a_semicolon_separated_file_gets_a_hint(tmp_path):
    p = tmp_path / "semi.csv"
    p.write_text("t;x;y;psi;delta_r\n0;0;0;0;0\n")
    with pytest.raises(TrackFormatError, match="';'-separated"):
        read_csv(p)


def test_a_run_without_rudder_movement_says_nothing():
    from bayesid.data.track import Track

    t = np.arange(0.0, 100.0, 0.5)
    tr = Track(t, {"x": t, "y": 0 * t, "psi": 0.01 * np.sin(t / 5), "delta_r": 0 * t + math.radians(0.2)})
    assert rudder_response(tr) is None
