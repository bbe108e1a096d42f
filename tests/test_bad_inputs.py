"""Bad inputs that passed silently before issue 38: a training track with a run of empty rudder
cells is refused (exit 2, naming file, column, rows and times), and a propeller at 0 rpm in every
row while the vessel moves is warned about (naming file and column)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayesid import cli
from bayesid.cli.inputs import read_tracks
from bayesid.data.track import Track, read_csv, write_csv
from bayesid.data.validate import HOLE_INTERVALS, check_track, input_gaps
from bayesid.models.ship import load_ship

N_COMMENTS = 2  # comment lines of the test files: the header is line 3, sample 0 line 4


def _ship_track(rpm=614.0, speed=1.18, duration=60.0, dt=0.1) -> Track:
    """A KVLCC2-like straight run with a gentle weave (no model needed)."""
    t = np.arange(0.0, duration + dt / 2, dt)
    psi = 0.05 * np.sin(2 * math.pi * t / 30.0)
    r = np.gradient(psi, t)
    x = speed * t
    y = np.cumsum(speed * np.sin(psi)) * dt
    states = {"x": x, "y": y, "psi": psi, "u": np.full_like(t, speed), "v": np.zeros_like(t), "r": r}
    inputs = {"delta_r": np.radians(5.0) * np.sign(np.sin(2 * math.pi * t / 30.0)), "n": np.full_like(t, rpm)}
    tr = Track.from_arrays(t, states=states, inputs=inputs, name="run")
    tr.meta["comments"] = ["test track", "vessel: kvlcc2_7m"]
    return tr


def _write(tr, path, **blank):
    """Write ``tr`` to ``path`` with the samples ``blank[col] = (i, j)`` (inclusive) empty."""
    data = {k: v.copy() for k, v in tr.data.items()}
    for col, (i, j) in blank.items():
        data[col][i : j + 1] = np.nan
    write_csv(Track(tr.t, data, name=tr.name, meta=tr.meta), path)
    return path


def _run(args, capsys):
    rc = cli.main([str(a) for a in args])
    cap = capsys.readouterr()
    return rc, cap.out + cap.err


def test_ten_seconds_of_empty_rudder_cells_are_refused_with_file_column_and_rows(tmp_path, capsys):
    p = _write(_ship_track(), tmp_path / "gappy.csv", delta_r=(200, 299))  # t = 20.0 .. 29.9 s
    rc, msg = _run(["fit", "--vehicle", "kvlcc2_7m", "--train", p, "--out", tmp_path / "fit"], capsys)
    assert rc == 2
    assert "Traceback" not in msg
    assert str(p) in msg and "column 'delta_r'" in msg
    first = N_COMMENTS + 2 + 200  # comments, header, then sample 0
    assert f"rows {first}-{first + 99}" in msg
    assert "t = 20 to 29.9 s" in msg
    assert not (tmp_path / "fit" / "model.json").exists()
    # the rows named are the empty ones
    lines = p.read_text().splitlines()
    col = lines[N_COMMENTS].split(",").index("delta_r")
    assert lines[first - 2].split(",")[col] != "" and lines[first - 1].split(",")[col] == ""
    assert lines[first + 98].split(",")[col] == "" and lines[first + 99].split(",")[col] != ""


def test_empty_rudder_at_the_start_and_an_empty_propeller_column(tmp_path):
    tr = read_csv(_write(_ship_track(), tmp_path / "a.csv", delta_r=(0, 49)))
    with pytest.raises(ValueError, match=r"column 'delta_r': empty in rows 4-53 \(t = 0 to 4.9 s"):
        check_track(tr, load_ship("kvlcc2_7m"), "a.csv")
    tr = read_csv(_write(_ship_track(), tmp_path / "b.csv", n=(0, 600)))
    with pytest.raises(ValueError, match=r"b.csv: column 'n': empty in .*\(the whole track\)"):
        check_track(tr, None, "b.csv")


def test_dropped_samples_and_a_slower_input_log_pass(tmp_path):
    short = int(HOLE_INTERVALS) - 2  # empty cells held between logged values 5 intervals apart
    input_gaps(read_csv(_write(_ship_track(), tmp_path / "c.csv", delta_r=(100, 100 + short))), "c.csv")
    with pytest.raises(ValueError, match="c2.csv: column 'delta_r'"):
        input_gaps(read_csv(_write(_ship_track(), tmp_path / "c2.csv", delta_r=(100, 100 + short + 1))), "c2.csv")
    slow = _ship_track()
    slow.data["n"][np.arange(slow.n_samples) % 10 != 0] = np.nan  # rpm logged at a tenth of the rate
    input_gaps(slow, "slow.csv")


def test_propeller_at_zero_rpm_while_moving_is_warned_about(tmp_path, capsys):
    p = _write(_ship_track(rpm=0.0), tmp_path / "stopped.csv")
    got = read_tracks([("--train", [p])], load_ship("kvlcc2_7m"))
    err = capsys.readouterr().err
    hit = [w for w in got["_warnings"] if "is 0 rpm in every row" in w]
    assert len(hit) == 1
    assert str(p) in hit[0] and "column 'n'" in hit[0] and "moves at 1.18 m/s" in hit[0]
    assert f"warning: {hit[0]}" in err


def test_no_zero_rpm_warning_when_the_propeller_turns_or_the_vessel_drifts(tmp_path):
    ship = load_ship("kvlcc2_7m")
    assert not [w for w in check_track(_ship_track(), ship, "ok.csv") if "column 'n'" in w]
    drift = check_track(_ship_track(rpm=0.0, speed=0.02), ship, "drift.csv")
    assert not [w for w in drift if "while the vessel moves" in w]
