"""The rudder limit of a ship file (issue 50): an optional ``[limits] rudder_max_deg``, given by
both packaged ships; ``bayesid simulate`` refuses an ``--angle`` beyond a vessel's limit naming
the option and the limit; ``check_track`` warns of a track whose ``|delta_r|`` passes it (a
warning: a log may hold a gear's overshoot), and not of the real HSVA runs; a ship file without
``[limits]`` keeps working, without a limit."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest

from bayesid import cli
from bayesid.data.track import Track
from bayesid.data.validate import check_track
from bayesid.data.vehicle import load_vehicle
from bayesid.models.ship import load_ship
from bayesid.models.ship.fileformat import ShipFileError

ROOT = Path(__file__).resolve().parents[1]
HSVA = ROOT.parent / "shared" / "data" / "real" / "kvlcc2-simman-hsva"
KVLCC2_FILE = ROOT / "bayesid" / "vehicles" / "kvlcc2_7m.toml"


def _run(args, capsys):
    rc = cli.main([str(a) for a in args])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def _without_limits(tmp_path: Path, extra: str = "") -> Path:
    """kvlcc2_7m's file with its ``[limits]`` section left out (and ``extra`` appended)."""
    text = KVLCC2_FILE.read_text()
    text = re.sub(r"\n\[limits\]\n(?:#[^\n]*\n|rudder_max_deg[^\n]*\n)*", "\n", text)
    assert "[limits]" not in text and "rudder_max_deg" not in text
    path = tmp_path / "my_tanker.toml"
    path.write_text(text + extra)
    return path


@pytest.mark.parametrize("vehicle", ["kvlcc2_7m", "esso_osaka_3m"])
def test_packaged_ships_give_a_35_deg_rudder_limit(vehicle):
    assert load_ship(vehicle).rudder_max_deg == 35.0


@pytest.mark.parametrize(
    "vehicle,manoeuvre,angle,limit",
    [
        ("kvlcc2_7m", "turn", "60", 35),
        ("kvlcc2_7m", "zigzag", "-40", 35),
        ("kvlcc2_7m", "spiral", "36", 35),
        ("esso_osaka_3m", "pull-out", "-35.5", 35),
        ("nps_auv2", "turn", "25", 20),
    ],
)
def test_simulate_refuses_an_angle_beyond_the_rudder_limit(tmp_path, capsys, vehicle, manoeuvre, angle, limit):
    out = tmp_path / "x.csv"
    args = ["simulate", "--vehicle", vehicle, "--manoeuvre", manoeuvre, "--angle", angle, "--speed", "1.0"]
    rc, text, err = _run([*args, "--no-figure", "--out", out], capsys)
    assert rc == 2, (text, err)
    assert "Traceback" not in err
    assert err.strip() == (
        f"error: --angle {angle}: beyond the rudder limit of {vehicle} ({limit} deg, [limits] rudder_max_deg "
        "of its file)"
    )
    assert not out.exists()


def test_simulate_at_the_rudder_limit_runs(tmp_path, capsys):
    out = tmp_path / "t.csv"
    limit = load_ship("kvlcc2_7m").rudder_max_deg
    args = ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "turn", "--angle", -limit, "--duration", "5"]
    rc, text, err = _run([*args, "--no-figure", "--out", out], capsys)
    assert rc == 0, err
    assert out.exists()


def test_a_ship_file_without_limits_loads_and_simulates_without_a_limit(tmp_path, capsys):
    path = _without_limits(tmp_path)
    ship = load_ship(path)
    assert ship.rudder_max_deg is None
    out = tmp_path / "t.csv"
    args = ["simulate", "--vehicle", path, "--manoeuvre", "turn", "--angle", "40", "--duration", "5"]
    rc, text, err = _run([*args, "--no-figure", "--out", out], capsys)
    assert rc == 0, err
    assert out.exists()
    assert check_track(_track(40.0), ship, "t.csv") == []


@pytest.mark.parametrize(
    "section,words",
    [
        ("[limits]\nrudder_max_deg = 0.0\n", ["[limits] rudder_max_deg", "(0, 90]"]),
        ("[limits]\nrudder_max_deg = 120\n", ["[limits] rudder_max_deg", "(0, 90]"]),
        ("[limits]\nrudder_max_deg = true\n", ["[limits] rudder_max_deg"]),
        ("[limits]\nrudder_rate_deg_s = 2.3\n", ["[limits] unknown key 'rudder_rate_deg_s'", "[service]"]),
    ],
)
def test_a_bad_limits_section_is_refused_naming_file_and_key(tmp_path, section, words):
    path = _without_limits(tmp_path, "\n" + section)
    with pytest.raises(ShipFileError) as e:
        load_ship(path)
    assert str(path) in str(e.value)
    for w in words:
        assert w in str(e.value)


def _track(peak_deg: float, n: int = 400, dt: float = 0.1) -> Track:
    """A straight run at 1 m/s whose rudder swings to ``peak_deg`` (no heading change, so the
    rudder-sign check has nothing to say)."""
    t = np.arange(n) * dt
    dr = np.radians(peak_deg) * np.sin(2 * np.pi * t / (n * dt))
    zero = np.zeros(n)
    data = {"x": t * 1.0, "y": zero, "psi": zero, "u": zero + 1.0, "v": zero, "r": zero, "delta_r": dr}
    return Track(t, dict(data, n=zero + 600.0), name="hard_over")


def test_check_track_warns_of_a_rudder_beyond_the_ship_limit():
    ship = load_ship("kvlcc2_7m")
    warn = check_track(_track(40.0), ship, "hard_over.csv")
    assert len(warn) == 1, warn
    w = warn[0]
    assert w.startswith("hard_over.csv: column 'delta_r':")
    assert "40 deg" in w and "35 deg" in w and "kvlcc2_7m" in w
    assert f"[limits] rudder_max_deg of {ship.file_path}" in w


def test_check_track_warns_of_a_rudder_beyond_a_submarine_limit():
    auv = load_vehicle("nps_auv2")
    limit = math.degrees(auv.limits.rudder_max)
    warn = [w for w in check_track(_track(limit + 5.0), auv, "auv.csv") if "'delta_r'" in w]
    assert len(warn) == 1 and f"({limit:g} deg, [limits] rudder_max_deg" in warn[0], warn


def test_check_track_is_quiet_within_a_degree_of_the_limit_or_without_one():
    ship = load_ship("kvlcc2_7m")
    assert check_track(_track(35.9), ship, "a.csv") == []
    assert check_track(_track(40.0), dataclasses.replace(ship, rudder_max_deg=None), "b.csv") == []
    assert check_track(_track(40.0), None, "c.csv") == []


@pytest.mark.skipif(not HSVA.is_dir(), reason="the HSVA KVLCC2 runs are not in ../shared/data/real")
def test_the_real_hsva_runs_stay_within_the_limit():
    from bayesid.data.datasets import list_runs, read_run

    ship = load_ship("kvlcc2_7m")
    runs = list_runs(HSVA, "simman-hsva")
    assert runs
    peaks = []
    for p in runs:
        track = read_run(p, "simman-hsva")
        peaks.append(float(np.nanmax(np.abs(np.degrees(track["delta_r"])))))
        assert not [w for w in check_track(track, ship, p.name) if "rudder limit" in w], p.name
    assert 34.0 < max(peaks) <= ship.rudder_max_deg + 1.0  # the 35/5 zigzag reaches the limit


def _zigzag_rudder(rate_deg_s: float, log_s: float, n_reversals: int = 6) -> Track:
    """A straight-running track whose rudder reverses between +-20 deg at ``rate_deg_s`` every
    15 s (``inf``: a step), logged every ``log_s`` seconds."""
    t = np.arange(0.0, 15.0 * n_reversals, log_s)
    target = 20.0 * np.where((t // 15.0) % 2 == 0, 1.0, -1.0)
    ramp = np.clip((t % 15.0) * rate_deg_s, 0.0, 40.0) if np.isfinite(rate_deg_s) else np.full_like(t, 40.0)
    delta = np.where(t < 15.0, 20.0, target - np.sign(target) * (40.0 - ramp))
    z = 0 * t
    return Track(t, {"x": t, "y": z, "psi": z, "delta_r": np.radians(delta), "n": z + 600.0}, name="zz")


@pytest.mark.parametrize(
    "rate, log_s, warned",
    [(16.0, 0.2, True), (16.0, 1.0, True), (16.0, 0.05, False), (16.0, 0.1, False), (np.inf, 0.5, False)],
)
def test_a_log_coarse_for_the_rudders_rate_is_warned_about_naming_the_column(rate, log_s, warned):
    """Issue 50: a 16 deg/s rudder logged at 1-5 Hz moves 3.2-16 deg between samples, and held
    between them it acts half an interval late; at 10-20 Hz (1.6 and 0.8 deg) nothing is said of
    the ramps, nor of a logged step's (its lone jumps have their own warning, below)."""
    msgs = [w for w in check_track(_zigzag_rudder(rate, log_s), None, "zz.csv") if "between samples" in w]
    assert bool(msgs) is warned, msgs
    if warned:
        assert msgs[0].startswith("zz.csv: column 'delta_r':") and "--inputs linear" in msgs[0]
        assert f"{16.0 * log_s:.2g} deg between samples" in msgs[0]


@pytest.mark.parametrize("log_s", [0.1, 0.5, 1.0])
def test_a_rudder_that_reverses_within_single_intervals_is_warned_about_its_timing(log_s):
    """Issue 50: an instantaneous rudder (or a logged order) reversing between samples, as a
    closed-loop zigzag's does, shows as lone jumps whose times within the interval no reading of
    the log knows; on NPS AUV II zigzags that moved the coefficients far beyond their intervals
    even at 10 Hz (reports/benchmark_reversal_timing.txt). Ramps logged across samples and a single
    execute are not lone-jump warnings."""
    msgs = [w for w in check_track(_zigzag_rudder(np.inf, log_s), None, "zz.csv") if "jumps" in w]
    assert len(msgs) == 1 and msgs[0].startswith("zz.csv: column 'delta_r': the rudder jumps 5 times by up to 40 deg")
    assert f"({log_s:.3g} s)" in msgs[0]
    assert not [w for w in check_track(_zigzag_rudder(16.0, 0.1), None, "zz.csv") if "jumps" in w]
    one = _zigzag_rudder(np.inf, log_s, n_reversals=2)  # the execute and one reversal
    assert not [w for w in check_track(one, None, "zz.csv") if "jumps" in w]
