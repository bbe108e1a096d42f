"""The MARIN KVLCC2 reader (bayesid.data.datasets.read_simman_marin): full-scale files in the SIMMAN
2008 layout, Froude-scaled to the 7 m model. Synthetic files only: the MARIN runs are withheld
for independent evaluation, so none is read here."""

import json
import math

import numpy as np
import pytest

from bayesid.cli import main
from bayesid.data import datasets as ds
from bayesid.data.datasets import KVLCC2_SCALE, DatasetFormatError, read_run, read_simman_hsva, read_simman_marin
from bayesid.data.track import read_csv
from bayesid.estimation.indices import manoeuvre_indices
from bayesid.models import build_model

TITLE = ["MARIN(Maritime Research Institute Netherlands)", "Turning / Pull-out manoeuvring for KVLCC2 : 35 (deg)", ""]
DT_FULL = 0.02 * math.sqrt(KVLCC2_SCALE)  # 50 Hz at model scale


def port_turn_full_scale(R=520.0, U=7.98, t_approach=20.0, duration=700.0):
    """An exact steady port turn at full scale: straight approach along x, then a circle of
    radius R (heading psi = -U t / R, no drift). Returns rows of the 11 MARIN columns."""
    t = np.arange(0.0, duration, DT_FULL)
    w = U / R
    s = np.clip(t - t_approach, 0.0, None)
    psi = -w * s
    x = U * np.minimum(t, t_approach) + R * np.sin(w * s)
    y = -R * (1.0 - np.cos(w * s))
    xd, yd = U * np.cos(psi), U * np.sin(psi)
    r = np.where(t > t_approach, -w, 0.0)
    delta = np.where(t > t_approach, 35.0, -1.16)  # + = to port (gives r < 0)
    cols = [
        t,
        x,
        y,
        np.full_like(t, -0.1),
        np.degrees(psi),
        xd,
        yd,
        np.zeros_like(t),
        np.degrees(r),
        delta,
        np.full_like(t, 91.7),
    ]
    return np.column_stack(cols)


def marin_file(path, a, title=TITLE):
    body = ["\t".join(f"{v:.2E}" for v in row) if not isinstance(row, str) else row for row in a]
    path.write_text("\n".join(title + body) + "\n", encoding="cp1252")
    return path


def test_froude_scaling_signs_and_tactical_diameter(tmp_path):
    a = port_turn_full_scale()
    tr = read_simman_marin(marin_file(tmp_path / "MARIN_FREE_KVLCC2_tc_35_m.dat", a))
    sq = math.sqrt(KVLCC2_SCALE)
    # time rebuilt on the uniform grid despite 3-digit stamps (many repeat after 100 s)
    assert tr.n_samples == a.shape[0]
    np.testing.assert_allclose(np.diff(tr.t), 0.02, rtol=2e-3)
    assert tr.meta["sample_rate_hz"] == pytest.approx(50.0, rel=2e-3)
    # model scale: 7.98 m/s -> 1.18 m/s, 91.7 rpm -> 620 rpm; rudder + to port gives r < 0
    np.testing.assert_allclose(tr["u"][:50], 7.98 / sq, rtol=6e-3)
    # v = 0: the file's heading has 1 deg steps past 100 deg (3 digits), which would put up to
    # U sin(0.5 deg) = 0.010 m/s into v; the heading fused with the integral of r removes it
    psi_true = np.radians(a[:, 4].astype(float))
    assert np.abs(tr["psi_file"] - psi_true).max() > np.radians(0.3)  # the file is rounded
    assert np.abs(tr["psi"] - psi_true).max() < np.radians(0.1)
    np.testing.assert_allclose(tr["v"], 0.0, atol=0.002)
    raw = read_simman_marin(tmp_path / "MARIN_FREE_KVLCC2_tc_35_m.dat", heading_tau_s=None)
    assert np.abs(raw["v"]).max() > 0.006 and "psi_file" not in raw
    np.testing.assert_array_equal(raw["psi"], tr["psi_file"])
    np.testing.assert_allclose(tr["n"], 91.7 * sq, rtol=1e-3)
    turning = tr["delta_r"] > 0.5
    assert (tr["r"][turning] < 0).all()
    np.testing.assert_allclose(tr["r"][turning], -7.98 / 520.0 * sq, rtol=6e-3)
    assert tr.meta["scale"] == KVLCC2_SCALE and "Froude" in tr.meta["conversions"][0]
    # the tactical diameter of the converted track is the full-scale one over lambda (2 R / lambda)
    ind = manoeuvre_indices(tr.t, tr["x"], tr["y"], tr["psi"], tr["delta_r"])
    assert ind["kind"] == "turning"
    assert ind["tactical_diameter_m"] == pytest.approx(2 * 520.0 / KVLCC2_SCALE, rel=0.01)
    assert ind["advance_m"] == pytest.approx(520.0 / KVLCC2_SCALE, rel=0.01)
    assert ind["transfer_m"] == pytest.approx(520.0 / KVLCC2_SCALE, rel=0.01)
    # scale 1 keeps full scale
    full = read_simman_marin(tmp_path / "MARIN_FREE_KVLCC2_tc_35_m.dat", scale=1.0)
    assert full["x"][-1] == pytest.approx(a[-1, 1], rel=6e-3)
    assert full["n"][0] == pytest.approx(91.7)


@pytest.mark.parametrize(
    "mutate,row,column,words",
    [
        (lambda a: a.__setitem__(5, "1.0\t2.0\t3.0"), 9, None, "has 3 fields, expected 11"),
        (
            lambda a: a.__setitem__(6, "\t".join(["8.11E-01", "6.4E+00", "x1", *["0"] * 8])),
            10,
            "col 2 (y0, m)",
            "non-numeric value 'x1'",
        ),
        (lambda a: a.__setitem__(7, "\t".join(["2.00E-01", *["0"] * 10])), 11, "col 0 (time, s)", "time decreases"),
    ],
)
def test_malformed_names_file_row_and_column(tmp_path, mutate, row, column, words):
    a = [list(r) for r in port_turn_full_scale(duration=5.0)]
    mutate(a)
    path = marin_file(tmp_path / "bad.dat", a)
    with pytest.raises(DatasetFormatError) as ei:
        read_simman_marin(path)
    e = ei.value
    assert (e.row, e.column) == (row, column)
    assert str(path) in str(e) and f"row {row}" in str(e) and words in str(e)


def test_time_gap_is_an_error_naming_the_row(tmp_path):
    a = port_turn_full_scale(duration=30.0)
    a = np.delete(a, np.s_[100:120], axis=0)  # 20 rows (2.7 s) missing: not a uniform grid
    with pytest.raises(DatasetFormatError, match="off the uniform grid") as ei:
        read_simman_marin(marin_file(tmp_path / "gap.dat", a))
    assert ei.value.column == "col 0 (time, s)" and ei.value.row is not None


def test_bad_scale_and_hsva_reader_points_to_marin(tmp_path):
    path = marin_file(tmp_path / "m.dat", port_turn_full_scale(duration=3.0))
    with pytest.raises(ValueError, match="scale must be a positive number"):
        read_simman_marin(path, scale=0.0)
    with pytest.raises(DatasetFormatError, match="simman-marin") as ei:
        read_simman_hsva(path)
    assert ei.value.row == 1
    assert read_run(path, "simman-marin", scale=2.0).meta["scale"] == 2.0


def test_list_runs_tells_the_basins_apart_and_convert_round_trips(tmp_path, capsys):
    marin_file(tmp_path / "MARIN_FREE_KVLCC2_zz_10_m.dat", port_turn_full_scale(duration=10.0))
    hsva = [
        " HSVA, experimental data CPMC",
        " KVLCC2",
        " Z10/10",
        " Time series of motions",
        "  ".join(["0.0", *["1.0"] * 11]),
        "  ".join(["0.05", *["1.0"] * 11]),
    ]
    (tmp_path / "HSVA_Z.dat").write_text("\n".join(hsva) + "\n", encoding="cp1252")
    assert [p.name for p in ds.list_runs(tmp_path, "simman-marin")] == ["MARIN_FREE_KVLCC2_zz_10_m.dat"]
    assert [p.name for p in ds.list_runs(tmp_path, "simman-hsva")] == ["HSVA_Z.dat"]
    out = tmp_path / "out"
    assert main(["convert", "--format", "simman-marin", str(tmp_path), "--out", str(out)]) == 0
    summary = json.loads((out / "convert.json").read_text())
    assert summary["n_runs"] == 1
    back = read_csv(summary["runs"][0]["output"])
    src = read_simman_marin(tmp_path / "MARIN_FREE_KVLCC2_zz_10_m.dat")
    np.testing.assert_allclose(back.t, src.t, rtol=1e-12)
    for k in ("x", "y", "psi", "u", "v", "r", "delta_r", "n"):
        np.testing.assert_allclose(back[k], src[k], rtol=1e-12, atol=1e-15, err_msg=k)
    assert (
        main(
            [
                "convert",
                "--format",
                "simman-hsva",
                str(tmp_path / "HSVA_Z.dat"),
                "--scale",
                "2",
                "--out",
                str(tmp_path / "o2"),
            ]
        )
        == 2
    )
    assert "--scale applies to --format simman-marin only" in capsys.readouterr().err


def test_real_ships_study_compares_marin_turns_when_present(tmp_path):
    """studies/real_ships.py picks MARIN files up anywhere under --data (here a synthetic port
    turn beside an HSVA-like folder) and scores the tactical diameter against the measured one."""
    from conftest import load_study

    from bayesid.models import ship

    study = load_study("real_ships")
    data = tmp_path / "data"
    (data / "kvlcc2-other-basin").mkdir(parents=True)
    R = 520.0
    marin_file(data / "kvlcc2-other-basin" / "MARIN_FREE_KVLCC2_tc_35_m.dat", port_turn_full_scale(R=R))
    am = build_model(ship.load_ship("kvlcc2_7m"))
    af = type("Fit", (), {"p": am.start()})()
    cov = np.diag((0.01 * np.maximum(np.abs(am.start()), 1e-3)) ** 2)
    (tmp_path / "fig").mkdir()
    bad = port_turn_full_scale(duration=30.0).tolist()
    bad[40] = "1.0\t2.0"
    marin_file(data / "kvlcc2-other-basin" / "MARIN_FREE_KVLCC2_zz_bad_m.dat", bad)
    M, figs = study.marin_runs(am, af, cov, data, 4, np.random.default_rng(0), tmp_path / "fig")
    assert list(M["unread"]) == [str(data / "kvlcc2-other-basin" / "MARIN_FREE_KVLCC2_zz_bad_m.dat")]
    assert "row 44" in next(iter(M["unread"].values()))
    assert M["n_runs"] == 1 and M["n_turning_with_td"] == 1 and len(figs) == 1 and figs[0].exists()
    e = M["runs"]["MARIN_FREE_KVLCC2_tc_35_m"]
    td_m = e["measured"]["tactical_diameter_m"]
    assert td_m == pytest.approx(2 * R / KVLCC2_SCALE, rel=0.01)
    assert e["tactical_diameter_rel_error"] == pytest.approx(e["predicted"]["tactical_diameter_m"] / td_m - 1)
    assert M["tactical_diameter_within_5pct"] == int(abs(e["tactical_diameter_rel_error"]) <= 0.05)
    assert e["w60"]["rms_position_m"] >= 0 and set(M["pooled_rms_position_m"]) == {"w30", "w60"}
    text = "\n".join(study.marin_section(M, figs))
    assert "MARIN_FREE_KVLCC2_tc_35_m" in text and "within 5 %" in text
    assert "No MARIN file" in "\n".join(study.marin_section(None, []))
    assert study.marin_runs(am, af, cov, tmp_path / "fig", 4, np.random.default_rng(0), tmp_path / "fig") == (None, [])
