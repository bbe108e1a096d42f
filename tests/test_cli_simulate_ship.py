"""``bayesid simulate`` for every vehicle family (issue 38): a ship file's turning circle, zigzag
(rudder angle and check heading apart), pull-out and direct/reverse spiral from its service
speed, with the ITTC indices printed and the track written in the format ``bayesid fit`` reads;
the submarine path unchanged, with ``--check``; bad options refused naming the option."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from bayesid import cli
from bayesid.data.track import read_csv
from bayesid.estimation.indices import manoeuvre_indices, rudder_orders
from bayesid.models.ship import load_ship
from bayesid.models.ship.trials import propulsion_point, service_condition


def _run(args, capsys):
    rc = cli.main([str(a) for a in args])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def _printed(out: str, label: str) -> float:
    m = re.search(rf"^\s+{label}\s+(\S+)", out, re.M)
    assert m, (label, out)
    return float(m.group(1))


@pytest.fixture(scope="module")
def kvlcc2():
    return load_ship("kvlcc2_7m")


@pytest.mark.parametrize("angle,check", [(10, 10), (20, 20), (35, 5)])
def test_ship_zigzag_reverses_at_the_check_heading_and_prints_its_indices(tmp_path, capsys, angle, check):
    out = tmp_path / "z.csv"
    rc, text, err = _run(
        [
            "simulate",
            "--vehicle",
            "kvlcc2_7m",
            "--manoeuvre",
            "zigzag",
            "--angle",
            -angle,
            "--check",
            check,
            "--out",
            out,
        ],
        capsys,
    )
    assert rc == 0, err
    tr = read_csv(out)
    assert {"x", "y", "psi", "u", "v", "r", "delta_r", "n"} <= set(tr.data)
    assert "vessel: kvlcc2_7m" in tr.meta["comments"]
    # the rudder goes to starboard first, to the angle asked for, and is reversed when the heading
    # has changed by the check heading (the rudder order at each later execute)
    assert np.degrees(tr["delta_r"].min()) == pytest.approx(-angle, abs=1e-6)
    ex = rudder_orders(tr.t, tr["delta_r"])["executes"]
    h = np.degrees(np.unwrap(tr["psi"]) - tr["psi"][ex[0]])
    assert len(ex) >= 4
    for m in ex[1:4]:
        assert abs(h[m]) == pytest.approx(check, abs=0.5)
    ind = manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
    assert ind["kind"] == "zigzag"
    assert _printed(text, "first overshoot") == pytest.approx(ind["first_overshoot_deg"], rel=1e-3)
    assert _printed(text, "second overshoot") == pytest.approx(ind["second_overshoot_deg"], rel=1e-3)
    for label in ("initial turning time", "time to check yaw", "period"):
        assert math.isfinite(_printed(text, label))


def test_check_defaults_to_the_angle(tmp_path, capsys):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    base = ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "zigzag", "--angle", "20", "--duration", "120"]
    assert _run([*base, "--out", a], capsys)[0] == 0
    assert _run([*base, "--check", "20", "--out", b], capsys)[0] == 0
    assert np.array_equal(read_csv(a)["delta_r"], read_csv(b)["delta_r"])
    assert _run([*base, "--check", "5", "--out", tmp_path / "c.csv"], capsys)[0] == 0
    assert not np.array_equal(read_csv(a)["delta_r"], read_csv(tmp_path / "c.csv")["delta_r"])


def test_ship_turn_from_the_service_speed_port_and_starboard(tmp_path, capsys, kvlcc2):
    got = {}
    for angle in (35, -35):
        out = tmp_path / f"t{angle}.csv"
        rc, text, err = _run(
            ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "turn", "--angle", angle, "--out", out], capsys
        )
        assert rc == 0, err
        tr = read_csv(out)
        speed = service_condition(kvlcc2)["speed"]
        assert tr["u"][0] == speed and np.allclose(tr["u"][tr.t < 10.0], speed, rtol=1e-6)  # steady approach
        assert tr["n"][0] == pytest.approx(propulsion_point(kvlcc2, speed=speed)[1])
        assert np.sign(tr["r"][-1]) == -np.sign(angle)  # + rudder to port turns to port (r < 0)
        got[angle] = {k: _printed(text, k) for k in ("advance", "transfer", "tactical diameter", "speed loss")}
        assert 1.0 < got[angle]["tactical diameter"] / kvlcc2.L < 6.0
        assert 0.0 < got[angle]["speed loss"] < 1.0
    assert got[35] == pytest.approx(got[-35], rel=1e-3)


def test_ship_spiral_prints_a_steady_yaw_rate_per_rudder_angle(tmp_path, capsys):
    out = tmp_path / "s.csv"
    rc, text, err = _run(
        ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "spiral", "--angle", "20", "--hold", "60", "--out", out],
        capsys,
    )
    assert rc == 0, err
    rows = re.findall(r"^\s+(-?[\d.]+)\s+(-?[\d.e+-]+)\s+(-?[\d.e+-]+)$", text, re.M)
    angles = [float(a) for a, _, _ in rows]
    rates = {}
    for a, rate, _ in rows:
        rates.setdefault(float(a), []).append(float(rate))
    assert angles[:7] == [20, 15, 10, 5, 3, 1, 0] and len(rows) == 25
    assert rates[20][0] < 0 < rates[-20][0]  # port rudder, port turn
    assert rates[20][-1] == pytest.approx(-rates[-20][0], rel=2e-2)  # both reached from 15 deg
    assert any(c.startswith("steady yaw rate") for c in read_csv(out).meta["comments"])


def test_ship_pull_out(tmp_path, capsys):
    rc, text, err = _run(
        ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "pull-out", "--angle", "20", "--out", tmp_path / "p.csv"],
        capsys,
    )
    assert rc == 0, err
    release, residual = _printed(text, "yaw rate at release"), _printed(text, "residual yaw rate")
    assert release < 0 and abs(residual) < abs(release)


def test_speed_and_rpm(tmp_path, capsys, kvlcc2):
    out = tmp_path / "a.csv"
    base = ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "straight", "--duration", "20"]
    assert _run([*base, "--speed", "0.8", "--out", out], capsys)[0] == 0
    tr = read_csv(out)
    assert tr["u"][0] == 0.8 and np.allclose(tr["u"], 0.8, rtol=1e-6)
    assert tr["n"][0] == pytest.approx(propulsion_point(kvlcc2, speed=0.8)[1])
    assert _run([*base, "--rpm", "600", "--out", out, "--overwrite"], capsys)[0] == 0
    tr = read_csv(out)
    assert np.all(tr["n"] == 600.0) and np.allclose(tr["u"], tr["u"][0], rtol=1e-6)
    assert tr["u"][0] == pytest.approx(propulsion_point(kvlcc2, rpm=600.0)[0])
    # both: starts at the speed, the propeller at the rpm (not in equilibrium: the ship slows down)
    assert _run([*base, "--rpm", "600", "--speed", "1.2", "--out", out, "--overwrite"], capsys)[0] == 0
    tr = read_csv(out)
    assert tr["u"][0] == 1.2 and tr["u"][-1] < 1.19 and np.all(tr["n"] == 600.0)


def test_a_ship_track_is_what_fit_reads(tmp_path, capsys):
    z = tmp_path / "z.csv"
    assert (
        _run(["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "zigzag", "--angle", "10", "--out", z], capsys)[0]
        == 0
    )
    rc, text, err = _run(
        ["fit", "--vehicle", "kvlcc2_7m", "--free", "Nr", "--train", z, "--max-nfev", "2", "--out", tmp_path / "fit"],
        capsys,
    )
    assert rc == 0, err
    assert (tmp_path / "fit" / "model.json").is_file()


def test_submarine_zigzag_takes_check_and_keeps_its_default(tmp_path, capsys):
    base = ["simulate", "--manoeuvre", "zigzag", "--angle", "20", "--duration", "60", "--mode", "horizontal"]
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    rc, text, err = _run([*base, "--out", a], capsys)
    assert rc == 0, err and "zigzag indices" in text
    assert _run([*base, "--check", "10", "--out", b], capsys)[0] == 0
    ta, tb = read_csv(a), read_csv(b)
    first = lambda tr: tr.t[np.flatnonzero(np.diff(np.sign(tr["delta_r"])) < 0)[0]]  # noqa: E731
    assert first(tb) < first(ta)  # reversed at 10 deg of heading change, before 20
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models.simulate import Simulator

    veh = load_vehicle("nps_auv2")
    ref = Simulator(veh, mv.zigzag(veh, 20.0, dt=0.1, duration=60.0), mode="horizontal").run().track(0)
    assert np.array_equal(ref["delta_r"], ta["delta_r"]) and np.allclose(ref["psi"], ta["psi"], atol=1e-12)


@pytest.mark.parametrize(
    "args,option",
    [
        (["--vehicle", "kvlcc2_7m", "--manoeuvre", "zigzag", "--check", "-5"], "--check"),
        (["--vehicle", "kvlcc2_7m", "--manoeuvre", "turn", "--check", "5"], "--check"),
        (["--vehicle", "kvlcc2_7m", "--mode", "6dof"], "--mode"),
        (["--vehicle", "kvlcc2_7m", "--crossflow", "polynomial"], "--crossflow"),
        (["--vehicle", "esso_osaka_3m", "--manoeuvre", "turn"], "--speed"),
        (["--vehicle", "kvlcc2_7m", "--speed", "0"], "--speed"),
        (["--vehicle", "kvlcc2_7m", "--rpm", "-3"], "--rpm"),
        (["--vehicle", "kvlcc2_7m", "--rudder-rate", "-1"], "--rudder-rate"),
        (["--vehicle", "kvlcc2_7m", "--manoeuvre", "spiral", "--duration", "100"], "--duration"),
        (["--vehicle", "kvlcc2_7m", "--manoeuvre", "turn", "--angle", "0"], "rudder angle"),
        (["--vehicle", "nps_auv2", "--manoeuvre", "turn", "--hold", "5"], "--hold"),
    ],
)
def test_bad_options_are_refused_naming_the_option(tmp_path, capsys, args, option):
    rc, text, err = _run(["simulate", *args, "--out", tmp_path / "x.csv"], capsys)
    assert rc == 2 and option in err and "Traceback" not in err, err
    assert not (tmp_path / "x.csv").exists()


def test_every_option_shows_its_help_and_default(capsys):
    with pytest.raises(SystemExit):
        cli.main(["simulate", "--help"])
    text = capsys.readouterr().out.split("options:", 1)[1]
    entries = re.split(r"\n(?=  -)", text.strip("\n"))  # one entry per option, its help lines joined
    shown = {}
    for e in entries:
        option = re.match(r"\s*(?:-h, )?(--[a-z-]+)", e).group(1)
        shown[option] = " ".join(e.split())
    for option in ("--vehicle", "--manoeuvre", "--angle", "--check", "--speed", "--rpm", "--rudder-rate"):
        assert option in shown
    for option in ("--duration", "--hold", "--dt", "--sample", "--mode", "--crossflow", "--out", "--overwrite"):
        assert option in shown
    for option, entry in shown.items():
        if option != "--help":  # a default, or "(required)" for an option without one
            assert ("(default:" in entry or "(required)" in entry) and len(entry) > len(option) + 30, entry
