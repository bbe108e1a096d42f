"""``bayesid convert --vessel`` writes the vessel line a user wants, and the refusal of a track
of another vessel says how to fix it (issue 38). The conversion tests read the KVLCC2 HSVA runs
from ../shared/data/real and skip when they are absent."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from bayesid import cli
from bayesid.cli.convert import vessel_name
from bayesid.cli.inputs import read_tracks
from bayesid.data.track import Track, read_csv
from bayesid.data.validate import check_vessel, track_vessel
from bayesid.models.ship import load_ship

ROOT = Path(__file__).resolve().parents[1]
HSVA = ROOT.parent / "shared" / "data" / "real" / "kvlcc2-simman-hsva" / "HSVA_CPMC_KVLCC2_Z_10_10_S.dat"
needs_hsva = pytest.mark.skipif(not HSVA.is_file(), reason="KVLCC2 HSVA data (../shared) not present")


def _run(args, capsys):
    rc = cli.main([str(a) for a in args])
    cap = capsys.readouterr()
    return rc, cap.out + cap.err


@pytest.fixture
def myship(tmp_path):
    """The user's own ship file: the KVLCC2 file under another id."""
    text = (ROOT / "bayesid" / "vehicles" / "kvlcc2_7m.toml").read_text()
    p = tmp_path / "myship.toml"
    p.write_text(re.sub(r'^id = "kvlcc2_7m"', 'id = "coastal_tanker"', text, flags=re.M))
    return p


def test_vessel_name_takes_a_vehicle_files_id(myship, tmp_path):
    assert vessel_name("kvlcc2_7m") == "kvlcc2_7m"
    assert vessel_name(str(myship)) == "coastal_tanker"
    with pytest.raises(ValueError, match="--vessel"):
        vessel_name(str(tmp_path / "absent.toml"))
    with pytest.raises(ValueError, match="--vessel"):
        vessel_name(" ")


def test_the_refusal_of_another_vessel_says_how_to_re_convert():
    t = np.arange(0.0, 10.0, 0.5)
    tr = Track(t, {"x": t, "y": 0 * t, "psi": 0 * t}, name="run", meta={"comments": ["vessel: Esso Osaka 3 m"]})
    with pytest.raises(ValueError) as err:
        check_vessel(tr, load_ship("kvlcc2_7m"), "run.csv")
    msg = str(err.value)
    assert "run.csv" in msg and "--vehicle esso_osaka_3m" in msg
    assert "bayesid convert --vessel kvlcc2_7m" in msg and "'# vessel:' line" in msg


@needs_hsva
def test_convert_vessel_makes_the_track_fit_the_users_ship(myship, tmp_path, capsys):
    # as the data set names it, the run is refused for the user's ship, with the way out named
    rc, _ = _run(["convert", "--format", "simman-hsva", HSVA, "--out", tmp_path / "as_is"], capsys)
    assert rc == 0
    as_is = tmp_path / "as_is" / f"{HSVA.stem}.csv"
    rc, msg = _run(["fit", "--vehicle", myship, "--train", as_is, "--out", tmp_path / "fit"], capsys)
    assert rc == 2 and "Traceback" not in msg
    assert str(as_is) in msg and "bayesid convert --vessel coastal_tanker" in msg
    # re-converted with --vessel, it is taken
    rc, msg = _run(["convert", "--format", "simman-hsva", HSVA, "--vessel", myship, "--out", tmp_path / "mine"], capsys)
    assert rc == 0, msg
    mine = tmp_path / "mine" / f"{HSVA.stem}.csv"
    lines = mine.read_text().splitlines()
    assert sum(1 for x in lines if x.startswith("# vessel:")) == 1 and "# vessel: coastal_tanker" in lines
    assert any("the data set says: KVLCC2" in x for x in lines)
    assert track_vessel(read_csv(mine)) == "coastal_tanker"
    got = read_tracks([("--train", [mine])], load_ship(myship))
    assert not [w for w in got["_warnings"] if "vessel line" in w]
    doc = json.loads((tmp_path / "mine" / "convert.json").read_text())
    assert doc["vessel"] == "coastal_tanker" and doc["runs"][0]["vessel"] == "coastal_tanker"
