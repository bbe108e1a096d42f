"""The IMO MSC.137(76) criteria (issue 38, "IMO table limits"): the L/V-dependent overshoot limits in
their three ranges, pass/fail at the limit, Froude scaling of a model test, the ship file's
``[particulars] scale`` (optional; refused naming the key when bad), the initial turning distance
by its definition, and the table in the ``predict`` and ``fit`` reports of a ship."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from bayesid import cli
from bayesid.estimation.imo import CRITERIA, imo_criteria, imo_tests, overshoot_limits
from bayesid.estimation.indices import manoeuvre_indices
from bayesid.models.ship import ShipFileError, load_ship
from bayesid.report.imo import imo_table_lines, predict_imo_lines

ROOT = Path(__file__).resolve().parents[1]
KVLCC2 = ROOT / "bayesid" / "vehicles" / "kvlcc2_7m.toml"
HSVA = ROOT.parent / "shared" / "data" / "real" / "kvlcc2-simman-hsva"


def _zigzag(first=8.0, second=15.0, speed=1.0, rudder=-10.0, check=10.4, distance=12.0) -> dict:
    """The indices of a zigzag as :func:`manoeuvre_indices` gives them (only the keys IMO reads)."""
    return {
        "kind": "zigzag",
        "rudder_deg": rudder,
        "check_heading_deg": [check, -check, check],
        "first_overshoot_deg": first,
        "second_overshoot_deg": second,
        "execute_speed_m_s": speed,
        "initial_turning_distance_m": distance,
    }


def _turn(advance=21.0, tactical=28.0, rudder=35.0, speed=1.0) -> dict:
    return {
        "kind": "turning",
        "rudder_deg": rudder,
        "advance_m": advance,
        "tactical_diameter_m": tactical,
        "execute_speed_m_s": speed,
        "initial_turning_distance_m": 5.0,
    }


def _rows(rows, criterion) -> list:
    return [r for r in rows if r["criterion"] == criterion]


@pytest.mark.parametrize(
    "lv,first,second",
    [
        (5.0, 10.0, 25.0),  # L/V < 10 s
        (9.999, 10.0, 25.0),
        (10.0, 10.0, 25.0),  # 5 + 10/2 and 17.5 + 7.5: continuous at 10 s
        (20.0, 15.0, 32.5),  # in between: 5 + L/(2V), 17.5 + 0.75 L/V
        (29.0, 19.5, 39.25),
        (30.0, 20.0, 40.0),  # L/V >= 30 s
        (45.0, 20.0, 40.0),
    ],
)
def test_overshoot_limits_in_the_three_ranges(lv, first, second):
    assert overshoot_limits(lv) == pytest.approx((first, second), abs=1e-12)


@pytest.mark.parametrize("lv", [0.0, -3.0, float("nan"), float("inf")])
def test_overshoot_limits_refuse_a_meaningless_l_over_v(lv):
    with pytest.raises(ValueError, match="L/V"):
        overshoot_limits(lv)


@pytest.mark.parametrize("lv_full,first,second", [(6.0, 10.0, 25.0), (20.0, 15.0, 32.5), (40.0, 20.0, 40.0)])
def test_the_table_sets_the_10_10_limits_from_full_scale_l_over_v(lv_full, first, second):
    lam = 49.0  # sqrt 7: full-scale L/V = 7 x the model's
    speed = 7.0 / (lv_full / 7.0)  # a 7 m model at the speed that gives that full-scale L/V
    rows = imo_criteria({"z": _zigzag(speed=speed)}, length_m=7.0, scale=lam)
    (r1,), (r2,) = _rows(rows, "first_overshoot_10_10"), _rows(rows, "second_overshoot_10_10")
    assert r1["l_over_v_s"] == pytest.approx(lv_full) and r2["l_over_v_s"] == pytest.approx(lv_full)
    assert (r1["limit"], r2["limit"]) == pytest.approx((first, second))
    (r20,) = _rows(rows, "first_overshoot_20_20")
    assert r20["result"] == "not run" and r20["limit"] == 25.0  # no 20/20 zigzag among the runs


def test_pass_at_the_limit_and_fail_just_beyond():
    speed = 7.0 / (20.0 / 7.0)  # full-scale L/V 20 s: first overshoot limit 15 deg, second 32.5
    at = imo_criteria(
        {"z": _zigzag(first=15.0, second=32.5, speed=speed, distance=17.5), "t": _turn(advance=31.5, tactical=35.0)},
        length_m=7.0,
        scale=49.0,
    )
    assert {r["criterion"]: r["result"] for r in at} == {
        "advance": "pass",
        "tactical_diameter": "pass",
        "initial_turning": "pass",
        "first_overshoot_10_10": "pass",
        "second_overshoot_10_10": "pass",
        "first_overshoot_20_20": "not run",
        "stopping_track_reach": "not run",
    }
    eps = 1e-6
    beyond = imo_criteria(
        {
            "z": _zigzag(first=15.0 + eps, second=32.5 + eps, speed=speed, distance=17.5 + eps),
            "t": _turn(advance=31.5 + eps, tactical=35.0 + eps),
        },
        length_m=7.0,
        scale=49.0,
    )
    assert {r["criterion"]: r["result"] for r in beyond if r["run"]} == {
        k: "fail"
        for k in ("advance", "tactical_diameter", "initial_turning", "first_overshoot_10_10", "second_overshoot_10_10")
    }


def _nomoto_zigzag(rudder_deg=10.0, check_deg=10.0, speed=1.2, slow=0.0, rate=15.0, scale=1.0):
    """A kinematic zigzag: yaw rate r of a first-order (Nomoto) ship, T r' + r = K delta (T 8 s,
    K 0.06 1/s), sampled every 0.05 s; the rudder (rate-limited) reverses when the heading reaches
    the check angle. The speed is ``speed`` until the rudder order at 5 s, then falls linearly by
    the fraction ``slow`` over 30 s. ``scale`` Froude-scales the run (times x sqrt, lengths x scale)."""
    T, K, dt = 8.0, 0.06, 0.05
    n = int(150.0 / dt)
    t = np.arange(n) * dt
    psi, r, d = np.zeros(n), 0.0, np.zeros(n)
    order, h = -math.radians(rudder_deg), 0.0
    for i in range(1, n):
        if t[i] >= 5.0 and abs(h) >= math.radians(check_deg) and np.sign(h) == -np.sign(order):
            order = -order
        target = order if t[i] >= 5.0 else 0.0
        step = math.radians(rate) * dt
        d[i] = d[i - 1] + np.clip(target - d[i - 1], -step, step)
        r += dt * (K * -d[i - 1] - r) / T
        h += dt * r
        psi[i] = h
    v = speed * (1.0 - slow * np.clip((t - 5.0) / 30.0, 0.0, 1.0))
    x = np.cumsum(v * np.cos(psi)) * dt
    y = np.cumsum(v * np.sin(psi)) * dt
    s = math.sqrt(scale)
    return t * s, x * scale, y * scale, psi, d


def test_froude_scaling_of_a_model_test_equals_the_full_scale_run():
    lam = 45.714
    model = manoeuvre_indices(*_nomoto_zigzag())
    full = manoeuvre_indices(*_nomoto_zigzag(scale=lam))
    assert imo_tests(model) == ["zigzag_10_10", "initial_turning"]
    a = imo_criteria({"z": model}, length_m=7.0, scale=lam)
    b = imo_criteria({"z": full}, length_m=7.0 * lam, scale=1.0)
    for ra, rb in zip(a, b):
        assert ra["criterion"] == rb["criterion"] and ra["result"] == rb["result"]
        for k in ("value", "limit", "l_over_v_s", "value_L"):
            if ra.get(k) is None or rb.get(k) is None:
                assert ra.get(k) is rb.get(k), (ra["criterion"], k)
            else:
                assert ra[k] == pytest.approx(rb[k], rel=1e-4), (ra["criterion"], k)
    # at model scale L/V is 7 / 1.2 = 5.8 s (limit 10 deg); at full scale sqrt(45.714) x that: 39.5 s (20 deg)
    (first,) = _rows(a, "first_overshoot_10_10")
    assert first["l_over_v_s"] == pytest.approx(7.0 / 1.2 * math.sqrt(lam), rel=1e-3) and first["limit"] == 20.0
    (dist,) = _rows(a, "initial_turning")
    assert dist["value"] == pytest.approx(model["initial_turning_distance_m"] * lam)


def test_the_initial_turning_distance_is_the_distance_to_10_deg_of_heading():
    t, x, y, psi, d = _nomoto_zigzag(speed=1.2)
    ind = manoeuvre_indices(t, x, y, psi, d)
    i = int(np.argmax(np.abs(psi) >= math.radians(10.0)))  # the first sample at 10 deg; linear before it
    a, b = abs(psi[i - 1]), abs(psi[i])
    t10 = t[i - 1] + (math.radians(10.0) - a) / (b - a) * (t[i] - t[i - 1])
    t0 = t[np.argmax(d != 0.0) - 1]  # the order: the last sample before the rudder moves
    assert ind["execute_t_s"] == pytest.approx(t0)
    assert ind["initial_turning_distance_m"] == pytest.approx(1.2 * (t10 - t0), rel=1e-4)
    assert ind["execute_speed_m_s"] == pytest.approx(1.2, rel=1e-3) and ind["rudder_deg"] == pytest.approx(-10.0)
    # a 10/5 zigzag reverses before the heading gets to 10 deg: no distance, and no IMO test; nor
    # does a 35/5 zigzag, whose heading passes 10 deg while the rudder swings back over
    ind5 = manoeuvre_indices(*_nomoto_zigzag(check_deg=5.0))
    assert math.isnan(ind5["initial_turning_distance_m"]) and imo_tests(ind5) == []
    ind35 = manoeuvre_indices(*_nomoto_zigzag(rudder_deg=35.0, check_deg=5.0, rate=2.3))
    assert ind35["kind"] == "zigzag" and math.isnan(ind35["initial_turning_distance_m"])
    # the test speed is the speed at the execute, not the speed the ship slows down to
    slowed = manoeuvre_indices(*_nomoto_zigzag(slow=0.3))
    assert slowed["execute_speed_m_s"] == pytest.approx(1.2, rel=5e-3)


@pytest.mark.parametrize(
    "ind,tests",
    [
        (_turn(rudder=35.0), ["turning"]),
        (_turn(rudder=-34.0), ["turning"]),
        (_turn(rudder=20.0), []),
        (_turn(rudder=10.0), ["initial_turning"]),
        (_zigzag(rudder=20.0, check=20.3), ["zigzag_20_20"]),
        (_zigzag(rudder=20.0, check=10.7), []),  # a 20/10 zigzag is no IMO test
        (_zigzag(rudder=10.0, check=5.5), []),
        ({"kind": "other", "reason": "x"}, []),
    ],
)
def test_which_runs_are_imo_standard_manoeuvres(ind, tests):
    assert imo_tests(ind) == tests


def test_a_ship_file_without_scale_loads_and_the_table_says_so(tmp_path):
    text = KVLCC2.read_text()
    assert re.search(r"^scale = ", text, re.M)
    p = tmp_path / "noscale.toml"
    p.write_text(re.sub(r"^scale = .*\n", "", text, flags=re.M))
    ship = load_ship(p)
    assert ship.scale is None and load_ship("kvlcc2_7m").scale == pytest.approx(320.0 / 7.0, rel=1e-4)
    runs = {"z": _zigzag(speed=1.2), "t": _turn()}
    rows = imo_criteria(runs, length_m=ship.L)
    res = {r["criterion"]: r for r in rows}
    # the L/V-dependent limits are not given; the scale-free ones are, at the file's scale
    assert res["first_overshoot_10_10"]["result"] == "no limit" and res["first_overshoot_10_10"]["limit"] is None
    assert res["second_overshoot_10_10"]["result"] == "no limit"
    assert res["advance"]["limit"] == pytest.approx(4.5 * 7.0) and res["advance"]["result"] == "pass"
    assert res["advance"]["value"] == 21.0 and not res["advance"]["full_scale"]
    text = "\n".join(imo_table_lines({"measured": runs}, length_m=ship.L, scale=ship.scale, vessel=ship.id))
    assert "no `[particulars] scale`" in text and "none without a scale" in text


@pytest.mark.parametrize("value", ["-45.7", "0", "nan", "inf", '"45"', "true"])
def test_a_bad_scale_is_refused_naming_file_and_key(tmp_path, value):
    p = tmp_path / "bad.toml"
    p.write_text(re.sub(r"^scale = .*$", f"scale = {value}", KVLCC2.read_text(), flags=re.M))
    with pytest.raises(ShipFileError, match=r"bad\.toml: \[particulars\] scale = "):
        load_ship(p)


def test_a_bad_scale_exits_2_through_the_cli(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(re.sub(r"^scale = .*$", "scale = -1", KVLCC2.read_text(), flags=re.M))
    rc = cli.main(
        ["simulate", "--vehicle", str(p), "--manoeuvre", "turn", "--angle", "35", "--out", str(tmp_path / "t.csv")]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "bad.toml: [particulars] scale = -1" in err and "Traceback" not in err


def test_a_submarine_model_gets_no_imo_table():
    doc = {"model": str(ROOT / "tests" / "data" / "model_written_by_0.1.0.json"), "indices": {}}
    assert predict_imo_lines(doc) == []


def test_the_criteria_are_the_sections_of_msc_137():
    assert [c[1] for c in CRITERIA] == ["5.3.1", "5.3.1", "5.3.2", "5.3.3.1", "5.3.3.2", "5.3.3.3", "5.3.4"]
    assert [c[5] for c in CRITERIA] == [4.5, 5.0, 2.5, None, None, 25.0, 15.0]


def _run(args, capsys):
    rc = cli.main([str(a) for a in args])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    return cap.out


def _table(report: str) -> dict:
    """{(criterion cell, run): [cells]} of the IMO table of a report."""
    sec = report.split("## IMO manoeuvring criteria")[1].split("\n## ")[0]
    rows = [line.strip("|").split("|") for line in sec.splitlines() if line.startswith("| 5.3")]
    return {(r[0].strip(), r[1].strip()): [c.strip() for c in r] for r in rows}


def test_the_table_is_in_the_predict_and_fit_reports_of_a_ship(tmp_path, capsys):
    z = tmp_path / "z10.csv"
    _run(
        ["simulate", "--vehicle", "kvlcc2_7m", "--manoeuvre", "zigzag", "--angle", -10, "--check", 10, "--out", z],
        capsys,
    )
    fit = tmp_path / "fit"
    _run(["fit", "--vehicle", "kvlcc2_7m", "--free", "Nr", "--train", z, "--max-nfev", 2, "--out", fit], capsys)
    pred = tmp_path / "pred"
    _run(["predict", "--model", fit / "model.json", "--track", z, "--draws", 0, "--out", pred], capsys)
    from bayesid.data.track import read_csv

    tr = read_csv(z)
    ind = manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
    lv = 7.0 / ind["execute_speed_m_s"] * math.sqrt(45.714)
    first = overshoot_limits(lv)[0]
    for report, columns in ((pred / "report.md", 6), (fit / "report.md", 5)):
        table = _table(report.read_text())
        row = table[("5.3.3.1 first overshoot", "z10")]
        assert len(row) == columns and row[2] == "10/10 zigzag, starboard first"
        assert row[3].startswith(f"{first:.3g} deg (L/V {lv:.3g} s)")
        assert row[4] == f"{ind['first_overshoot_deg']:.3g} deg **pass**"
        assert table[("5.3.1 advance", "-")][4] == "not run"
        dist = table[("5.3.2 distance to turn 10 deg with 10 deg rudder", "z10")][4]
        assert dist.startswith(f"{ind['initial_turning_distance_m'] / 7.0:.3g} L")
    pr = _table((pred / "report.md").read_text())[("5.3.3.1 first overshoot", "z10")]
    assert pr[5].endswith("**pass**") or pr[5].endswith("**fail**")


@pytest.mark.skipif(not HSVA.is_dir(), reason="HSVA KVLCC2 runs not present (../shared/data/real)")
def test_hsva_zigzags_only_10_10_runs_are_imo_tests():
    from bayesid.data.datasets import read_simman_hsva

    runs = {}
    for f in sorted(HSVA.glob("HSVA_CPMC_KVLCC2_Z_*.dat")):
        tr = read_simman_hsva(f)
        runs[f.stem] = manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
    ship = load_ship("kvlcc2_7m")
    rows = imo_criteria(runs, length_m=ship.L, scale=ship.scale)
    named = {r["run"] for r in rows if r["run"]}
    assert named == {"HSVA_CPMC_KVLCC2_Z_10_10_P", "HSVA_CPMC_KVLCC2_Z_10_10_S"}  # not 10/5, 20/10, 35/5
    for r in _rows(rows, "first_overshoot_10_10"):
        # 1.179 m/s at 1:45.714 is 15.5 kn: L/V near 40 s, the 20 deg limit
        assert 35.0 < r["l_over_v_s"] < 45.0 and r["limit"] == 20.0 and r["result"] in ("pass", "fail")
