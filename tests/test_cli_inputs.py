"""Bad and unusual inputs to the bayesid command (issue 21, the outputs / duplicates / provenance
part): each is refused with exit code 2 and a message naming the culprit, before any
computation, or handled correctly."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from bayesid import cli
from bayesid.data.track import Track, write_csv
from bayesid.data.vehicle import load_vehicle
from bayesid.models import manoeuvres as mv
from bayesid.models.world import LogOptions, world_track

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def csvs(tmp_path_factory):
    veh = load_vehicle("nps_auv2")
    d = tmp_path_factory.mktemp("tracks")
    out = []
    for i, m in enumerate(
        [mv.zigzag(veh, 20.0, dt=0.1, duration=60.0), mv.zigzag(veh, 10.0, dt=0.1, duration=60.0, first_sign=-1)]
    ):
        tr = world_track(veh, m, {}, np.random.default_rng(i), LogOptions(sample_every=2), name=f"run{i}")
        write_csv(tr, d / f"run{i}.csv")
        out.append(d / f"run{i}.csv")
    return out


def _run(args, capsys):
    rc = cli.main([str(a) for a in args])
    cap = capsys.readouterr()
    return rc, cap.out + cap.err


def _diag(train, held, out, *extra):
    return [
        "diagnose",
        "--vehicle",
        "nps_auv2",
        "--free",
        "Nr",
        "--train",
        *train,
        "--heldout",
        *held,
        "--score-window",
        "30",
        "--candidates",
        "thrust",
        "--max-nfev",
        "3",
        "--max-effects",
        "1",
        "--out",
        out,
        *extra,
    ]


BAD = {  # name: (args builder, text the message must contain)
    "out is a file": (lambda c, t: _diag([c[0]], [c[1]], c[0]), "--out"),
    "same file twice in --train": (lambda c, t: _diag([c[0], c[0]], [c[1]], t / "o"), "same content"),
    "held-out equals a training file": (lambda c, t: _diag([c[0]], [c[1], t / "copy.csv"], t / "o"), "same content"),
    "two files with one name": (lambda c, t: _diag([c[0]], [t / "sub" / "run0.csv"], t / "o"), "both named"),
    "a folder as a track": (lambda c, t: _diag([c[0]], [t], t / "o"), "is a folder"),
    "simulate --dt 0": (lambda c, t: ["simulate", "--dt", "0", "--out", t / "s.csv"], "--dt"),
    "simulate over an existing file": (lambda c, t: ["simulate", "--out", c[0]], "--overwrite"),
    "unknown start rule": (lambda c, t: _diag([c[0]], [c[1]], t / "o", "--start", "smooth"), None),
    "a track of another packaged vessel": (lambda c, t: _diag([c[0]], [t / "esso.csv"], t / "o"), "esso.csv"),
    "--compare with a term the library lacks": (
        lambda c, t: _diag([c[0]], [c[1]], t / "o", "--compare", "Nvvr,Nfoo"),
        "Nfoo",
    ),
    "--compare with a coefficient the vehicle has": (
        lambda c, t: _diag([c[0]], [c[1]], t / "o", "--compare", "Nr"),
        "Nr",
    ),
    "--compare with a missing diagnosis.json": (
        lambda c, t: _diag([c[0]], [c[1]], t / "o", "--compare", t / "none" / "diagnosis.json"),
        "--compare",
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_is_refused_naming_the_culprit(csvs, tmp_path, capsys, case):
    shutil.copy(csvs[0], tmp_path / "copy.csv")
    (tmp_path / "sub").mkdir()
    data = csvs[1].read_text().replace("0.0", "0.00", 1)  # other content, same stem as run0
    (tmp_path / "sub" / "run0.csv").write_text(data)
    (tmp_path / "esso.csv").write_text("# vessel: Esso Osaka 3 m model\n" + csvs[1].read_text())
    build, text = BAD[case]
    if text is None:  # argparse refuses the choice itself
        with pytest.raises(SystemExit) as e:
            cli.main([str(a) for a in build(csvs, tmp_path)])
        assert e.value.code == 2
        return
    rc, msg = _run(build(csvs, tmp_path), capsys)
    assert rc == 2 and text in msg and "Traceback" not in msg, msg
    assert not (tmp_path / "o" / "diagnosis.json").exists()


def test_a_non_empty_out_is_refused_and_overwrite_clears_what_the_command_wrote(csvs, tmp_path, capsys):
    out = tmp_path / "diag"
    (out / "figures").mkdir(parents=True)
    (out / "figures" / "stale.png").write_bytes(b"old")
    (out / "notes.txt").write_text("mine")
    rc, msg = _run(_diag([csvs[0]], [csvs[1]], out), capsys)
    assert rc == 2 and "--overwrite" in msg and (out / "figures" / "stale.png").exists()
    # figures/ without diagnosis.json: not this command's output, kept even with --overwrite
    rc, msg = _run(_diag([csvs[0]], [csvs[1]], out, "--overwrite"), capsys)
    assert rc == 2 and "did not write" in msg and (out / "figures" / "stale.png").exists()
    (out / "diagnosis.json").write_text("{}")  # an earlier diagnosis
    rc, msg = _run(_diag([csvs[0]], [csvs[1]], out, "--overwrite"), capsys)
    assert rc == 0, msg
    assert not (out / "figures" / "stale.png").exists() and (out / "notes.txt").read_text() == "mine"
    assert json.loads((out / "diagnosis.json").read_text())
    # another command's folder is never overwritten
    rc, msg = _run(["predict", "--model", out / "model.json", "--track", csvs[1], "--out", out, "--overwrite"], capsys)
    assert rc == 2 and "'bayesid diagnose'" in msg and json.loads((out / "diagnosis.json").read_text())


def test_fit_records_provenance_and_predict_refuses_a_changed_vehicle(csvs, tmp_path, capsys):
    veh_file = tmp_path / "auv.toml"
    shutil.copy(ROOT / "bayesid" / "vehicles" / "nps_auv2.toml", veh_file)
    rc, msg = _run(
        [
            "fit",
            "--vehicle",
            veh_file,
            "--free",
            "Nr",
            "--train",
            csvs[0],
            "--fit-window",
            "30",
            "--max-nfev",
            "3",
            "--out",
            tmp_path / "fit",
        ],
        capsys,
    )
    assert rc == 0, msg
    prov = json.loads((tmp_path / "fit" / "model.json").read_text())["provenance"]
    assert prov["bayesid_version"] and len(prov["vehicle_sha256"]) == 64 and "Yv" in prov["vehicle_coefficients"]
    assert list(prov["input_sha256"]) == [str(csvs[0])]
    pred = [
        "predict",
        "--model",
        tmp_path / "fit" / "model.json",
        "--track",
        csvs[1],
        "--score-window",
        "30",
        "--draws",
        "0",
    ]
    assert _run(pred + ["--out", tmp_path / "p0"], capsys)[0] == 0
    # matching the propeller to the approach needs a propeller model: refused, naming the option, nothing written
    rc, msg = _run(pred + ["--propeller", "approach", "--out", tmp_path / "pa"], capsys)
    assert rc == 2 and "--propeller approach" in msg and "no propeller model" in msg and not (tmp_path / "pa").exists()
    veh_file.write_text(veh_file.read_text().replace("Yv = -1.0e-1", "Yv = -1.2e-1"))
    rc, msg = _run(pred + ["--out", tmp_path / "p1"], capsys)
    assert rc == 2 and "changed after the fit" in msg
    rc, msg = _run(pred + ["--out", tmp_path / "p2", "--allow-changed-vehicle"], capsys)
    assert rc == 0 and "WARNING" in msg


def test_convert_overwrite_leaves_no_stale_run(tmp_path, capsys):
    src = ROOT.parent / "shared" / "data" / "real" / "kvlcc2-simman-hsva"
    if not src.is_dir():
        pytest.skip("real data not present")
    out = tmp_path / "conv"
    out.mkdir()
    (out / "old_run.csv").write_text("t,x\n0,0\n")
    (out / "convert.json").write_text(json.dumps({"runs": [{"output": str(out / "old_run.csv")}]}))
    rc, msg = _run(["convert", "--format", "simman-hsva", src, "--out", out], capsys)
    assert rc == 2 and "--overwrite" in msg
    rc, msg = _run(["convert", "--format", "simman-hsva", src, "--out", out, "--overwrite"], capsys)
    assert rc == 0 and not (out / "old_run.csv").exists()
    listed = {Path(r["output"]).name for r in json.loads((out / "convert.json").read_text())["runs"]}
    assert listed == {p.name for p in out.glob("*.csv")}


def test_version_and_defaults_in_help(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--version"])
    assert "bayesid 0." in capsys.readouterr().out
    with pytest.raises(SystemExit):
        cli.main(["diagnose", "--help"])
    assert "(default: 60.0)" in capsys.readouterr().out.replace("\n", " ").replace("  ", " ")


# --- units and plausibility (bayesid.data.validate) ------------------------------------------------
def _variant(path, tmp_path, name, change):
    from bayesid.data.track import read_csv

    tr = read_csv(path)
    data = {k: np.array(v) for k, v in tr.data.items()}
    t = change(tr.t.copy(), data)
    from bayesid.data.track import Track

    p = tmp_path / f"{name}.csv"
    write_csv(Track(t, data, name=name), p)
    return p


UNITS = {  # name: (change (t, data) -> t, column, text)
    "heading in degrees": (lambda t, d: (d.__setitem__("psi", np.degrees(d["psi"]) + 40.0), t)[1], "psi", "degrees"),
    "rudder in degrees": (
        lambda t, d: (d.__setitem__("delta_r", np.degrees(d["delta_r"])), t)[1],
        "delta_r",
        "degrees",
    ),
    "time in milliseconds": (lambda t, d: t * 1000.0, "'t'", "milliseconds"),
    "speeds in knots": (
        lambda t, d: (d.__setitem__("u", d["u"] / 0.514444), d.__setitem__("v", d["v"] / 0.514444), t)[2],
        "'u'",
        "knots",
    ),
    "yaw rate in deg/s": (lambda t, d: (d.__setitem__("r", np.degrees(d["r"])), t)[1], "'r'", "deg/s"),
    "rpm given as rps": (lambda t, d: (d.__setitem__("n", d["n"] / 60.0), t)[1], "'n'", "rev/s"),
    "time in minutes": (lambda t, d: t / 60.0, "'t'", "minutes"),
    "positions in km": (
        lambda t, d: (d.__setitem__("x", d["x"] / 1e3), d.__setitem__("y", d["y"] / 1e3), t)[2],
        "'x'",
        "km",
    ),
    "positions in feet": (
        lambda t, d: (d.__setitem__("x", d["x"] / 0.3048), d.__setitem__("y", d["y"] / 0.3048), t)[2],
        "'x'",
        "feet",
    ),
}


@pytest.mark.parametrize("case", list(UNITS))
def test_a_column_in_the_wrong_unit_is_refused_naming_it(csvs, tmp_path, capsys, case):
    change, col, unit = UNITS[case]
    bad = _variant(csvs[0], tmp_path, "bad", change)
    rc, msg = _run(_diag([bad], [csvs[1]], tmp_path / "o"), capsys)
    assert rc == 2 and "bad.csv" in msg and col.strip("'") in msg and unit in msg, msg


def test_the_correct_units_pass_without_warning(csvs):
    from bayesid.data import validate
    from bayesid.data.track import read_csv

    for p in csvs:
        # the zigzags' instantaneous reversals, decided every 0.1 s and logged every 0.2 s, fall
        # between samples: that timing warning is about the log, not its units
        warned = validate.check_track(read_csv(p), load_vehicle("nps_auv2"))
        assert [w for w in warned if "the rudder jumps" not in w] == []


def test_odd_but_possible_inputs_are_warned_about_in_the_outputs(csvs, tmp_path, capsys):
    stopped = _variant(csvs[0], tmp_path, "stopped", lambda t, d: (d.__setitem__("n", 0.0 * d["n"]), t)[1])
    fast = _variant(
        csvs[1], tmp_path, "fast", lambda t, d: (d.__setitem__("x", 10 * d["x"]), d.__setitem__("y", 10 * d["y"]), t)[2]
    )
    rc, msg = _run(_diag([stopped], [fast], tmp_path / "o"), capsys)
    assert rc == 0, msg
    doc = json.loads((tmp_path / "o" / "diagnosis.json").read_text())
    assert any("propeller speed is 0" in w for w in doc["warnings"])
    assert any("another vessel" in w for w in doc["warnings"])
    assert "Input warnings" in (tmp_path / "o" / "report.md").read_text()


def test_the_wind_effect_without_wind_columns_is_refused(csvs, tmp_path, capsys):
    rc, msg = _run(
        ["fit", "--vehicle", "esso_osaka_3m", "--train", csvs[0], "--effects", "wind", "--out", tmp_path / "f"], capsys
    )
    assert rc == 2 and "wind_speed" in msg and "run0" in msg, msg


@pytest.mark.parametrize(
    "args,text",
    [
        (["--dt", "0"], "--dt"),
        (["--max-nfev", "-5"], "--max-nfev"),
        (["--max-effects", "0"], "--max-effects"),
        (["--leadin", "-1"], "--leadin"),
        (["--score-window", "nan"], "--score-window"),
        (["--fit-window", "inf"], "--fit-window"),
    ],
)
def test_a_bad_number_is_refused_naming_the_option(csvs, tmp_path, capsys, args, text):
    rc, msg = _run(_diag([csvs[0]], [csvs[1]], tmp_path / "o", *args), capsys)
    assert rc == 2 and text in msg and "Traceback" not in msg, msg


def test_predict_refuses_negative_draws(csvs, tmp_path, capsys):
    rc, msg = _run(
        ["predict", "--model", tmp_path / "none.json", "--track", csvs[0], "--draws", "-5", "--out", tmp_path / "p"],
        capsys,
    )
    assert rc == 2 and "--draws" in msg


@pytest.mark.parametrize("key,value", [("mass_kg", "-5.0"), ("length_m", "0.0")])
def test_a_vehicle_file_with_an_impossible_value_names_it(tmp_path, capsys, csvs, key, value):
    import re

    text = (ROOT / "bayesid" / "vehicles" / "nps_auv2.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(re.sub(rf"(?m)^{key}\s*=.*$", f"{key} = {value}", text, count=1))
    rc, msg = _run(
        ["diagnose", "--vehicle", bad, "--train", csvs[0], "--heldout", csvs[1], "--out", tmp_path / "o"], capsys
    )
    assert rc == 2 and key in msg and "bad.toml" in msg, msg


def test_load_vehicle_on_a_ship_file_names_the_right_loader():
    from bayesid.data.vehicle import VehicleFileError

    with pytest.raises(VehicleFileError, match="load_ship"):
        load_vehicle("kvlcc2_7m")


def test_vessel_line_of_a_track_is_checked_against_the_vehicle():
    from bayesid.data.track import Track
    from bayesid.data.validate import check_track
    from bayesid.models import load_any_vehicle

    def track(vessel):
        return Track([0.0, 1.0], {"x": [0.0, 1.0]}, meta={"comments": [f"vessel: {vessel}"]})

    auv, esso = load_vehicle("nps_auv2"), load_any_vehicle("esso_osaka_3m")
    assert check_track(track("NPS AUV II, trial 3"), auv) == []
    assert check_track(track("Esso Osaka 3 m model (VLCC)"), esso) == []
    warn = check_track(track("REMUS 100"), auv, "a.csv")
    assert len(warn) == 1 and "REMUS 100" in warn[0] and "a.csv" in warn[0]
    with pytest.raises(ValueError, match="kvlcc2_7m"):
        check_track(track("KVLCC2 7 m model"), esso, "b.csv")


def test_implausible_tracks_for_the_vehicle_are_warned_about(csvs, tmp_path):
    """A propeller astern while moving ahead; a submarine's track (1.9 m/s) given to the 3 m
    full-form Esso Osaka model; pitch-plane columns on a surface ship."""
    from bayesid.data.track import read_csv
    from bayesid.data.validate import check_track
    from bayesid.models import load_any_vehicle

    auv, esso = load_vehicle("nps_auv2"), load_any_vehicle("esso_osaka_3m")
    astern = read_csv(_variant(csvs[0], tmp_path, "astern", lambda t, d: (d.__setitem__("n", -d["n"]), t)[1]))
    assert any("astern" in w and "astern.csv" in w for w in check_track(astern, auv, str(tmp_path / "astern.csv")))
    sub = read_csv(csvs[0])
    assert any("Froude" in w for w in check_track(sub, esso))
    planes = read_csv(_variant(csvs[0], tmp_path, "planes", lambda t, d: (d.__setitem__("delta_s", 0 * t + 0.1), t)[1]))
    assert any("delta_s" in w and "surface ship" in w for w in check_track(planes, esso))
    assert [w for w in check_track(sub, auv) if "the rudder jumps" not in w] == []  # (timing: not implausible)


def test_too_little_training_data_is_refused(csvs, tmp_path, capsys):
    short = _variant(csvs[0], tmp_path, "short", lambda t, d: t)
    text = short.read_text().splitlines()
    short.write_text("\n".join(text[:5]) + "\n")  # header + 4 samples
    rc, msg = _run(
        ["fit", "--vehicle", "nps_auv2", "--train", short, "--max-nfev", "3", "--out", tmp_path / "f"], capsys
    )
    assert rc == 2 and "short.csv" in msg and "scored samples" in msg, msg


def test_another_export_of_one_log_is_refused_and_a_training_file_is_flagged(csvs, tmp_path, capsys):
    from bayesid.data.track import read_csv

    tr = read_csv(csvs[0])
    lines = ["t,x,y,psi,u,v,r,delta_r,n"] + [
        ",".join(f"{tr[k][i]:.7g}" for k in ("t", "x", "y", "psi", "u", "v", "r", "delta_r", "n"))
        for i in range(tr.n_samples)
    ]
    (tmp_path / "export7.csv").write_text("\n".join(lines) + "\n")  # 7 significant digits
    rc, msg = _run(_diag([csvs[0]], [tmp_path / "export7.csv"], tmp_path / "o"), capsys)
    assert rc == 2 and "same samples" in msg and "export7.csv" in msg, msg
    # predict on the model's own training file: scored, with a warning in predict.json
    rc, msg = _run(
        [
            "fit",
            "--vehicle",
            "nps_auv2",
            "--free",
            "Nr",
            "--train",
            csvs[0],
            "--fit-window",
            "30",
            "--max-nfev",
            "2",
            "--out",
            tmp_path / "f",
        ],
        capsys,
    )
    assert rc == 0, msg
    model = json.loads((tmp_path / "f" / "model.json").read_text())
    rc, msg = _run(
        [
            "predict",
            "--model",
            tmp_path / "f" / "model.json",
            "--track",
            csvs[0],
            "--draws",
            "0",
            "--score-window",
            "30",
            "--out",
            tmp_path / "p",
        ],
        capsys,
    )
    assert rc == 0 and "training scores" in msg
    assert any("training scores" in w for w in json.loads((tmp_path / "p" / "predict.json").read_text())["warnings"])
    # a hand-edited model file is refused naming the file and the key
    for key, value in (("p", ["a"]), ("cov", [[float("nan")]]), ("dt", -1)):
        bad = dict(model, **{key: value})
        (tmp_path / "f" / "bad.json").write_text(json.dumps(bad))
        rc, msg = _run(
            ["predict", "--model", tmp_path / "f" / "bad.json", "--track", csvs[1], "--out", tmp_path / f"q{key}"],
            capsys,
        )
        assert rc == 2 and "bad.json" in msg and f"'{key}'" in msg and "Traceback" not in msg, (key, msg)


@pytest.mark.parametrize(
    "args,text", [(["--dt", "0.1", "--sample", "0.25"], "--sample"), (["--duration", "1e9"], "--duration")]
)
def test_simulate_refuses_impossible_sampling_and_durations(tmp_path, capsys, args, text):
    rc, msg = _run(["simulate", "--manoeuvre", "straight", *args, "--out", tmp_path / "s.csv"], capsys)
    assert rc == 2 and text in msg and not (tmp_path / "s.csv").exists(), msg


def test_duplicate_names_in_an_option_and_an_empty_vehicle_name_are_refused(csvs, tmp_path, capsys):
    rc, msg = _run(_diag([csvs[0]], [csvs[1]], tmp_path / "o", "--candidates", "thrust,thrust"), capsys)
    assert rc == 2 and "--candidates" in msg and "twice" in msg, msg
    with pytest.raises(FileNotFoundError, match="empty vehicle name"):
        load_vehicle("")


def test_a_warning_every_file_of_a_coarse_log_raises_is_printed_once_and_kept_for_each(tmp_path, capsys):
    # four zigzags logged at 2 Hz, their rudder reversals within single intervals: one warning in full, the
    # other files named after it; the outputs keep each file's own
    veh = load_vehicle("nps_auv2")
    paths = []
    for i, a in enumerate((20.0, 15.0, 10.0, 18.0)):
        tr = world_track(veh, mv.zigzag(veh, a, dt=0.1, duration=60.0), {}, np.random.default_rng(i), name=f"z{i}")
        keep = np.arange(0, tr.n_samples, 5)
        coarse = Track(
            tr.t[keep], {k: np.asarray(tr[k])[keep] for k in ("x", "y", "psi", "delta_r", "n")}, name=f"z{i}"
        )
        paths.append(tmp_path / f"z{i}.csv")
        write_csv(coarse, paths[-1])
    got = cli.inputs.read_tracks([("--train", paths[:2]), ("--heldout", paths[2:])], veh)
    err = capsys.readouterr().err
    jumps = [w for w in got["_warnings"] if "the rudder jumps" in w]
    assert len(jumps) == 4 and {w.split(": ")[0] for w in jumps} == {str(p) for p in paths}
    assert err.count("the rudder jumps") == 1, err
    same = f"the same for 3 more file(s), with their own numbers (in the outputs' warnings): {paths[1]}, {paths[2]}, {paths[3]}"
    assert same in err
    # the diagnosis report reads the same way; its JSON keeps every file's warning
    rc, msg = _run(_diag(paths[:2], paths[2:], tmp_path / "o"), capsys)
    assert rc == 0, msg
    text = (tmp_path / "o" / "report.md").read_text()
    assert text.count("the rudder jumps") == 1 and f"- {same}" in text, text[:3000]
    doc = json.loads((tmp_path / "o" / "diagnosis.json").read_text())
    assert sum("the rudder jumps" in w for w in doc["warnings"]) == 4


def test_a_gap_on_an_epoch_clock_is_named_with_its_times_to_the_tenth(csvs, tmp_path):
    """Issue 69: an AUV logs on an epoch clock (about 1.8e9 s). The gap's times print in full
    (``:g`` printed both ends as 1.8e+09), and a short clock prints as before."""
    from bayesid.data import validate
    from bayesid.data.track import clock, read_csv

    tr = read_csv(csvs[1])
    keep = (tr.t < 20.0) | (tr.t >= 30.0)
    T0 = 1795789700.0
    p = tmp_path / "epoch.csv"
    write_csv(Track(tr.t[keep] + T0, {k: np.array(v)[keep] for k, v in tr.data.items()}, name="epoch"), p)
    warned = [w for w in validate.check_track(read_csv(p), load_vehicle("nps_auv2"), str(p)) if " gap" in w]
    assert len(warned) == 1 and "t = 1795789719.8-1795789730 s" in warned[0], warned
    assert (clock(19.8), clock(-3.25e-3), clock(1795789719.8049), clock(float("nan"))) == (
        "19.8",
        "-0.00325",
        "1795789719.8",
        "nan",
    )


def test_a_gap_that_splits_a_run_is_named_in_the_outputs(csvs, tmp_path, capsys):
    """A gap in the positions (here 10 s cut out of a 0.2 s log, and a row of empty x, y, psi cells
    elsewhere, too short to split) is named with its times and file rows: the run is fitted and
    scored as two pieces."""
    from bayesid.data import validate
    from bayesid.data.track import read_csv

    tr = read_csv(csvs[1])
    keep = (tr.t < 20.0) | (tr.t >= 30.0)
    data = {k: np.array(v)[keep] for k, v in tr.data.items()}
    for k in ("x", "y", "psi"):
        data[k][5] = np.nan  # one empty row: held over, no gap
    p = tmp_path / "gapped.csv"
    write_csv(Track(tr.t[keep], data, name="gapped"), p)
    warned = [w for w in validate.check_track(read_csv(p), load_vehicle("nps_auv2"), str(p)) if " gap" in w]
    assert len(warned) == 1, warned
    # the last sample before the gap is t = 19.8 s (row 101 of the file: header, then t = 0 on row 2)
    assert "1 gap in x, y, psi" in warned[0] and "t = 19.8-30 s" in warned[0] and "rows 101-102" in warned[0]
    assert "2 continuous pieces" in warned[0] and str(p) in warned[0]
    rc, msg = _run(_diag([csvs[0]], [p], tmp_path / "o"), capsys)
    assert rc == 0, msg
    doc = json.loads((tmp_path / "o" / "diagnosis.json").read_text())
    assert any("2 continuous pieces" in w for w in doc["warnings"])
    # the runs without a gap are not warned of one
    assert not any(" gap" in w for w in validate.check_track(read_csv(csvs[0]), load_vehicle("nps_auv2")))
