"""studies/fit_sensitivity.py: its splits keep training and held-out runs apart (the
training-only splits never see the validation held-out runs), and --quick writes results.json
(skipped without shared/data/real)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import load_study

from bayesid.data.track import Track

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT / ".." / "shared" / "data" / "real"


def _study():
    return load_study("fit_sensitivity")


def _tracks(names):
    t = np.arange(0.0, 5.0, 0.5)
    return [Track(t, {"x": t, "y": 0 * t, "psi": 0 * t}, name=n) for n in names]


def test_training_only_splits_never_hold_out_or_train_on_the_validation_runs():
    fs = _study()
    for ds, splits in fs.SPLITS.items():
        names = sorted({n for sp in splits.values() for n in sp} | {"other_1", "other_2"})
        tracks = _tracks(["HSVA_CPMC_KVLCC2_" + n if ds == "kvlcc2_hsva" else n for n in names])
        for sp in splits:
            train, held = fs.split_runs(tracks, ds, sp)
            assert held and train and not {t.name for t in train} & {t.name for t in held}
            if sp != "validation":
                used = [t.name for t in train + held]
                assert not [n for n in used for v in splits["validation"] if n.endswith(v)], (ds, sp)
    with pytest.raises(ValueError, match="random_03-Aug-2020_11_04_37"):
        fs.split_runs(_tracks(["zigzag_31-Jul-2020_14_03_39"]), "esso_osaka", "train_cv_b")


def test_a_saved_fit_is_keyed_by_data_and_settings(tmp_path):
    fs = _study()
    for ds, folder in fs.DATA_FOLDERS.items():
        (tmp_path / folder / "sub").mkdir(parents=True)
        (tmp_path / folder / "sub" / "run1.csv").write_text("t,x\n0,0\n")
    job = {"dataset": "esso_osaka", "split": "validation", "setting": "w30_all", "max_nfev": 40, "quick": False}
    key = fs.fit_key(job, fs.data_digest(tmp_path, "esso_osaka"))
    (tmp_path / "esso-osaka-frt" / "sub" / "run1.csv").write_text("t,x\n0,1\n")  # the data changed
    assert fs.fit_key(job, fs.data_digest(tmp_path, "esso_osaka")) != key
    (tmp_path / "esso-osaka-frt" / "sub" / "run1.csv").write_text("t,x\n0,0\n")
    assert fs.fit_key(job, fs.data_digest(tmp_path, "esso_osaka")) == key
    assert fs.fit_key(dict(job, max_nfev=3), fs.data_digest(tmp_path, "esso_osaka")) != key
    assert fs.fit_key(dict(job, setting="w30_xypsi"), fs.data_digest(tmp_path, "esso_osaka")) != key


@pytest.mark.skipif(not REAL.is_dir(), reason="shared/data/real absent")
def test_fit_sensitivity_quick_writes_results(tmp_path):
    subprocess.run(
        [sys.executable, str(ROOT / "studies" / "fit_sensitivity.py"), "--quick", "--out", str(tmp_path)],
        check=True,
        cwd=ROOT,
    )
    R = json.loads((tmp_path / "results.json").read_text())
    assert R["quick"] and R["reference"] == "w30_all"
    for ds in ("esso_osaka", "kvlcc2_hsva"):
        tab = R["summary"][ds]["scores"]["validation"]
        assert set(tab) == {"w30_all", "w30_xypsi"} and all(v["w60"] > 0 for v in tab.values())
    assert all(not set(f["train_runs"]) & set(f["heldout_runs"]) for f in R["fits"])
    assert (tmp_path / "report.md").exists() and (tmp_path / "manifest.json").exists()
    assert all(f["key"]["data_sha256"] and f["key"]["quick"] for f in R["fits"])
