"""Tests for bayesid.data.track: Track container and CSV track files."""

import math
import re

import numpy as np
import pytest

import bayesid.data.track as track_module
from bayesid.data.track import INPUT_NAMES, STATE_NAMES, UNITS, Track, TrackFormatError, read_csv, write_csv


def write_text(tmp_path, text, name="run42.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def assert_format_error(path, row=None, column=None, match=None):
    """read_csv(path) raises TrackFormatError naming file, row and column."""
    with pytest.raises(TrackFormatError) as info:
        read_csv(path)
    msg = str(info.value)
    assert path.name in msg
    if row is not None:
        assert re.search(rf"\brow {row}\b", msg), msg
        assert info.value.row == row
    if column is not None:
        assert f"'{column}'" in msg, msg
        assert info.value.column == column
    if match is not None:
        assert re.search(match, msg), msg
    return info.value


def bits(a):
    return np.asarray(a, dtype=np.float64).view(np.uint64)


# ----------------------------------------------------------------- round trip


def random_track(rng, n=60):
    t = np.cumsum(rng.uniform(1e-6, 2.0, n)) - 3.0 + rng.random() * 1e-12

    def col():
        mag = 10.0 ** rng.uniform(-310, 300, n)  # subnormals to huge
        v = rng.choice([-1.0, 1.0], n) * mag
        v[rng.random(n) < 0.2] = np.nan  # missing samples
        v[0] = 5e-324
        v[1] = -0.0
        v[2] = np.finfo(float).max
        v[3] = 0.1 + 0.2  # needs 17 digits
        return v

    states = {k: col() for k in ("psi", "x", "u", "r")}  # unordered subset
    inputs = {"n": col(), "delta_r": col()}
    tr = Track.from_arrays(
        t,
        states=states,
        inputs=inputs,
        name="whatever",
        wind_speed=col(),
        wind_dir=col(),
        depth_sounder=col(),
        gps_quality=col(),
    )
    tr.units["depth_sounder"] = "m below keel"
    tr.units["gps_quality"] = "-"
    tr.meta["comments"] = ["vessel: MV Test", "", "  indented, with comma", "#hash"]
    return tr


def test_round_trip_is_bit_exact(tmp_path):
    tr = random_track(np.random.default_rng(1))
    path = tmp_path / "trial.csv"
    write_csv(tr, path)
    back = read_csv(path)
    assert back.name == "trial"
    assert bits(back.t).tolist() == bits(tr.t).tolist()
    assert set(back.data) == set(tr.data)
    for k in tr.data:
        assert bits(back[k]).tolist() == bits(tr[k]).tolist(), k  # NaN bits too
    assert back.units == tr.units
    assert back.meta["comments"] == tr.meta["comments"]
    assert back.exogenous_columns == tr.exogenous_columns
    # writing the read-back track reproduces the file byte for byte
    path2 = tmp_path / "trial2.csv"
    write_csv(back, path2)
    assert path2.read_bytes() == path.read_bytes()


def test_written_file_layout(tmp_path):
    tr = random_track(np.random.default_rng(2), n=4)
    path = tmp_path / "layout.csv"
    write_csv(tr, path)
    lines = path.read_text().splitlines()
    assert lines[:4] == ["# vessel: MV Test", "# ", "#   indented, with comma", "# #hash"]
    assert lines[4] == ("t,x,psi,u,r,delta_r,n,wind_speed,wind_dir,depth_sounder [m below keel],gps_quality [-]")
    assert len(lines) == 5 + 4
    assert "nan" not in path.read_text().lower()


def test_write_rejects_unreadable_tracks(tmp_path):
    with pytest.raises(ValueError, match="no state column"):
        write_csv(Track([0.0, 1.0], {"n": [1.0, 2.0]}), tmp_path / "a.csv")
    with pytest.raises(ValueError, match="no samples"):
        write_csv(Track([], {"x": []}), tmp_path / "b.csv")
    with pytest.raises(ValueError, match="cannot be written"):
        write_csv(Track([0.0], {"x": [1.0], "bad [name]": [1.0]}), tmp_path / "c.csv")


# -------------------------------------------------------------- reading


def test_read_minimal_file_with_missing_values_and_whitespace(tmp_path):
    path = write_text(tmp_path, "\n# logger v2\n t , psi , wind_dir \n0, 0.5 ,\n 1.5,,3\n\n")
    tr = read_csv(path)
    assert tr.name == "run42"
    assert tr.t.tolist() == [0.0, 1.5]
    assert tr["psi"][0] == 0.5 and math.isnan(tr["psi"][1])
    assert math.isnan(tr["wind_dir"][0]) and tr["wind_dir"][1] == 3.0
    assert tr.meta["comments"] == ["logger v2"]
    assert tr.state_columns == ["psi"] and tr.exogenous_columns == ["wind_dir"]


def test_accepted_unit_annotations(tmp_path):
    header = [
        "t [s]",
        "x (m)",
        "psi [rad]",
        "u [ m/s ]",
        "r (rad/s)",
        "delta_r [rad]",
        "n [rpm]",
        "wind_speed (m/s)",
        "wind_dir [rad]",
        "volts [V]",
        "heel_alarm",
    ]
    path = write_text(tmp_path, ",".join(header) + "\n" + ",".join(["1"] * 11) + "\n")
    tr = read_csv(path)
    assert list(tr.data) == ["x", "psi", "u", "r", "delta_r", "n", "wind_speed", "wind_dir", "volts", "heel_alarm"]
    assert tr.units == {"volts": "V"}
    assert tr.state_columns == ["x", "psi", "u", "r"]
    assert tr.input_columns == ["delta_r", "n"]


def test_every_contract_unit_is_accepted(tmp_path):
    header = ",".join(f"{k} [{u}]" for k, u in UNITS.items())
    path = write_text(tmp_path, header + "\n" + ",".join(["0"] * len(UNITS)) + "\n")
    tr = read_csv(path)
    assert tr.state_columns == list(STATE_NAMES)
    assert tr.input_columns == list(INPUT_NAMES)
    assert tr.units == {}


def test_missing_file_raises_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_csv(tmp_path / "nope.csv")


# ---------------------------------------------------------- format errors


@pytest.mark.parametrize(
    "text, row, column, match",
    [
        # missing t column (header is line 2 after a comment)
        ("# c\ntime,x\n0,1\n", 2, "t", "no 't' column"),
        # non-increasing time at line 4
        ("t,x\n0,1\n1,1\n0.5,1\n2,1\n", 4, "t", "not strictly increasing"),
        # duplicate time at line 3
        ("t,x\n0,1\n0.0,2\n", 3, "t", "duplicate"),
        # non-numeric value at line 3, column psi
        ("t,x,psi\n0,1,0\n1,2,abc\n", 3, "psi", "non-numeric"),
        ("t,x,psi\n0,1,0\n1,2,inf\n", 3, "psi", "non-numeric"),
        ("t,x,psi\n0,1,-Infinity\n", 2, "psi", "non-numeric"),
        ("t,x,psi\n0,1,nan\n", 2, "psi", "non-numeric"),
        ("t,x,psi\n0,1_000,0\n", 2, "x", "non-numeric"),
        ("t,x\n0,1e999\n", 2, "x", "overflow"),
        ("t,x,psi\n0,1,0\n1,2,1e\n", 3, "psi", "non-numeric"),
        ("t,x,psi\n0,1,0\n1,2,1.2.3\n", 3, "psi", "non-numeric"),
        ("t,x,psi\n0,1,0\n1,2,\u0661\n", 3, "psi", "non-numeric"),
        ("t,x,psi\n0,1,0\n1,2,- 1\n", 3, "psi", "non-numeric"),
        # unknown units in a header
        ("t,x,psi [deg]\n0,1,0\n", 1, "psi", "unit 'deg'"),
        ("t,x [ft]\n0,1\n", 1, "x", "unit 'ft'"),
        ("t [ms],x\n0,1\n", 1, "t", "unit 'ms'"),
        ("t,x,volts []\n0,1,0\n", 1, "volts", "empty unit"),
        # no state column at all
        ("t,n,delta_r\n0,1,0\n", 1, None, "no state column"),
        # ragged row at line 3
        ("t,x,y\n0,1,2\n1,2\n", 3, None, "2 fields, header has 3"),
        ("t,x,y\n0,1,2\n1,2,3,\n", 3, None, "4 fields"),
        # duplicate column (also when one carries a unit)
        ("t,x,psi,psi [rad]\n0,1,0,0\n", 1, "psi", "duplicate column"),
        # missing t value
        ("t,x\n0,1\n,2\n", 3, "t", "missing time"),
        # header only
        ("t,x\n", 1, None, "no data rows"),
        # malformed header
        ("t,x,a[b]c\n0,1,2\n", 1, None, "malformed"),
        ("t,x,\n0,1,2\n", 1, None, "malformed"),
    ],
)
@pytest.mark.parametrize("block_rows", [1, 2, 65536])
def test_format_errors_name_file_row_and_column(tmp_path, monkeypatch, text, row, column, match, block_rows):
    """The streamed reader converts blocks of rows; an error names the same row
    and column whichever block it falls in (including time order across blocks)."""
    monkeypatch.setattr(track_module, "_CHUNK_ROWS", block_rows)
    assert_format_error(write_text(tmp_path, text), row=row, column=column, match=match)


@pytest.mark.parametrize("block_rows", [1, 7])
def test_round_trip_across_blocks(tmp_path, monkeypatch, block_rows):
    monkeypatch.setattr(track_module, "_CHUNK_ROWS", block_rows)
    tr = random_track(np.random.default_rng(3), n=30)
    write_csv(tr, tmp_path / "blocks.csv")
    back = read_csv(tmp_path / "blocks.csv")
    assert bits(back.t).tolist() == bits(tr.t).tolist()
    for k in tr.data:
        assert bits(back[k]).tolist() == bits(tr[k]).tolist(), k


@pytest.mark.parametrize("text", ["", "\n\n", "# only a comment\n"])
def test_empty_file(tmp_path, text):
    assert_format_error(write_text(tmp_path, text), match="empty file")


def test_error_is_a_value_error(tmp_path):
    err = assert_format_error(write_text(tmp_path, "t,x\n1,1\n1,1\n"), row=3, column="t")
    assert isinstance(err, ValueError)
    assert err.path.endswith("run42.csv")


# ------------------------------------------------------------- Track API


def test_inputs_fill_and_missing_keyerror():
    tr = Track.from_arrays(
        [0.0, 1.0, 2.0],
        states={"psi": [0, 0.1, 0.2]},
        inputs={"n": [100, 110, 120], "delta_r": [0.1, 0.2, 0.3]},
        name="zigzag",
    )
    u = tr.inputs(fill=0.0)
    assert u.shape == (3, 4)
    np.testing.assert_array_equal(u[:, 0], [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(u[:, 1:3], 0.0)
    np.testing.assert_array_equal(u[:, 3], [100, 110, 120])
    with pytest.raises(KeyError, match="delta_s") as info:
        tr.inputs()
    assert "zigzag" in str(info.value) and "delta_b" in str(info.value)


def test_from_arrays_with_full_state_and_input_arrays():
    n = 5
    t = np.linspace(0.0, 4.0, n)
    X = np.arange(n * 12, dtype=float).reshape(n, 12)
    U = -np.arange(n * 4, dtype=float).reshape(n, 4)
    tr = Track.from_arrays(t, states=X, inputs=U, wind_speed=np.ones(n))
    assert tr.state_columns == list(STATE_NAMES)
    assert tr.input_columns == list(INPUT_NAMES)
    assert tr.exogenous_columns == ["wind_speed"]
    np.testing.assert_array_equal(tr.states(), X)
    np.testing.assert_array_equal(tr["psi"], X[:, 5])
    np.testing.assert_array_equal(tr.inputs(), U)
    np.testing.assert_array_equal(tr.states(["r", "x"]), X[:, [11, 0]])
    X[0, 0] = 999.0  # track holds its own copy
    assert tr["x"][0] == 0.0
    with pytest.raises(ValueError, match=r"\(n, 12\)"):
        Track.from_arrays(t, states=X[:, :11])
    with pytest.raises(ValueError, match="unknown"):
        Track.from_arrays(t, states={"yaw": t})
    with pytest.raises(ValueError, match="states="):
        Track.from_arrays(t, states={"x": t}, psi=t)


def test_getitem_contains_and_keyerror():
    tr = Track.from_arrays([0.0, 1.0], states={"x": [1.0, 2.0]}, name="trial 7")
    assert "t" in tr and "x" in tr and "y" not in tr
    assert tr["t"].tolist() == [0.0, 1.0]
    with pytest.raises(KeyError) as info:
        tr["y"]
    assert "trial 7" in str(info.value) and "'x'" in str(info.value)
    assert tr.n_samples == 2


@pytest.mark.parametrize(
    "t, data, match",
    [
        ([0.0, 1.0, 1.0], {"x": [0, 0, 0]}, "'t'.*strictly increasing"),
        ([0.0, np.nan], {"x": [0, 0]}, "'t'.*non-finite"),
        ([[0.0, 1.0]], {"x": [0, 0]}, "'t'.*1-D"),
        ([0.0, 1.0], {"x": [0, 0, 0]}, "'x'.*shape"),
        ([0.0, 1.0], {"x": [0, np.inf]}, "'x'.*infinite"),
        ([0.0, 1.0], {"t": [0, 1]}, "'t'"),
    ],
)
def test_track_validation(t, data, match):
    with pytest.raises(ValueError, match=match):
        Track(t, data)


def test_units_validation():
    with pytest.raises(ValueError, match="'psi'.*contract unit"):
        Track([0.0], {"psi": [0.0]}, units={"psi": "deg"})
    with pytest.raises(ValueError, match="'volts'.*not in the track"):
        Track([0.0], {"x": [0.0]}, units={"volts": "V"})


def test_with_columns_and_slice_time():
    tr = Track.from_arrays(np.arange(6.0), states={"x": np.arange(6.0) * 2}, extra=np.zeros(6), name="s")
    tr.units["extra"] = "V"
    tr.meta["comments"] = ["c"]
    tr2 = tr.with_columns(y=np.ones(6), x=np.full(6, 7.0))
    assert tr2.state_columns == ["x", "y"] and tr2["x"][0] == 7.0
    assert tr["x"][0] == 0.0 and "y" not in tr  # original untouched
    assert tr2.units == {"extra": "V"}
    with pytest.raises(ValueError, match="'y'"):
        tr.with_columns(y=np.ones(5))
    part = tr.slice_time(1.0, 3.0)
    assert part.t.tolist() == [1.0, 2.0, 3.0]
    assert part["x"].tolist() == [2.0, 4.0, 6.0]
    assert part.name == "s" and part.units == {"extra": "V"}
    part.meta["comments"].append("more")
    assert tr.meta["comments"] == ["c"]
    assert tr.slice_time(10.0, 20.0).n_samples == 0
    with pytest.raises(ValueError):
        tr.slice_time(3.0, 1.0)
