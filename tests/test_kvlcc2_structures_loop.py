"""studies/kvlcc2_structures.py closes issue 49's loop on real data when the other basin's runs are
under --data: the MARIN runs of the kind of the design's top run join the held-out runs, the
diagnosis runs again, and the report says which term the design and the data keep and how its
turning circles compare with the model without it. Synthetic MARIN files only (the real ones are
withheld); the second diagnosis is replaced by a stand-in so that the test stays fast."""

import json

import numpy as np
from conftest import load_study
from test_marin import marin_file, port_turn_full_scale


def _study():
    return load_study("kvlcc2_structures")


class _Diag:
    def __init__(self, d):
        self.d = d

    def to_dict(self):
        return json.loads(json.dumps(self.d))


def _zigzag_full_scale():
    a = port_turn_full_scale(duration=300.0)
    t = a[:, 0]
    a[:, 9] = np.where(t > 20.0, 20.0 * np.sign(np.sin(2 * np.pi * (t - 20.0) / 120.0) + 1e-9), 0.0)
    return a


ROUND1 = {
    "verdict": "unexplained -> discovered: Nvdrabsdr+unexplained",
    "manoeuvre_kinds": {"train": ["zigzag"], "heldout": ["zigzag"]},
    "discovered": [{"term": "Nvdrabsdr", "kept": True, "coefficient": 0.04, "alternatives": []}],
    "design": [{"kind": "turning_circle", "name": "turning circle 35 deg starboard", "separation": 299.0}],
}
ROUND2 = {
    "verdict": "unexplained -> no term of the library explains it",
    "discovered": [
        {
            "term": "Nvdrabsdr",
            "kept": False,
            "reason": "predicts run MARIN_FREE_KVLCC2_tc_35_m worse than the model without it",
            "coefficient": 0.04,
            "heldout_rms_m": 0.9,
            "alternatives": [],
        }
    ],
}


def test_loop_adds_the_other_basins_runs_of_the_designed_kind(tmp_path, monkeypatch):
    study = _study()
    data = tmp_path / "data" / "kvlcc2-other-basin"
    data.mkdir(parents=True)
    marin_file(data / "MARIN_FREE_KVLCC2_tc_35_m.dat", port_turn_full_scale())
    marin_file(data / "MARIN_FREE_KVLCC2_zz_20_m.dat", _zigzag_full_scale())
    bad = port_turn_full_scale(duration=30.0).tolist()
    bad[40] = "1.0\t2.0"
    marin_file(data / "MARIN_FREE_KVLCC2_tc_bad_m.dat", bad)
    marin, unread = study.other_basin_runs(tmp_path / "data")
    assert sorted(t.name for t in marin) == ["MARIN_FREE_KVLCC2_tc_35_m", "MARIN_FREE_KVLCC2_zz_20_m"]
    assert (
        list(unread) == [str(data / "MARIN_FREE_KVLCC2_tc_bad_m.dat")]
        and "row 44" in unread[str(data / "MARIN_FREE_KVLCC2_tc_bad_m.dat")]
    )
    seen = {}

    def fake(kv, train, held, args, out, log, folder="diagnosis", compare=()):
        seen.update(held=[t.name for t in held], folder=folder, compare=list(compare))
        return _Diag(ROUND2)

    monkeypatch.setattr(study, "diagnose_split", fake)
    loop = study.loop_on_other_basin(None, [], [], _Diag(ROUND1), marin, None, tmp_path, lambda m: None)
    # only the turning circle joins the held-out runs: the design asked for a turning circle; the
    # first round's kept term is refitted on them whatever the selection picks
    assert seen == {"held": ["MARIN_FREE_KVLCC2_tc_35_m"], "folder": "diagnosis_other_basin", "compare": ["Nvdrabsdr"]}
    assert loop["kind"] == "turning_circle" and loop["added_runs"] == ["MARIN_FREE_KVLCC2_tc_35_m"]
    assert loop["kept"] == [] and loop["verdict"] == ROUND2["verdict"]
    # a design of a kind the other basin lacks, or no design: no loop
    other = dict(ROUND1, design=[{"kind": "pull_out", "name": "pull out 20 deg port"}])
    assert study.loop_on_other_basin(None, [], [], _Diag(other), marin, None, tmp_path, lambda m: None) is None
    assert study.loop_on_other_basin(None, [], [], _Diag(dict(ROUND1, design=[])), marin, None, tmp_path, print) is None


def _res(loop, basin):
    return {"diagnosis": ROUND1, "loop_on_other_basin": loop, "other_basin": basin, "other_basin_unread": {}}


def test_loop_report_names_the_kept_term_and_compares_it_with_the_model_without():
    study = _study()
    basin = {
        "without": {"max_abs_rel_error": {"tactical_diameter_m": 0.046, "advance_m": 0.010}},
        "Nvdrabsdr": {"max_abs_rel_error": {"tactical_diameter_m": 0.097, "advance_m": 0.039}},
    }
    loop = {
        "kind": "turning_circle",
        "added_runs": ["MARIN_FREE_KVLCC2_tc_35_m"],
        "verdict": ROUND2["verdict"],
        "kept": [],
        "discovered": [dict(ROUND2["discovered"][0], worse_on_other_kinds=[])],
    }
    text = "\n".join(study._loop_lines(_res(loop, basin)))
    assert "Nvdrabsdr: not kept (predicts run MARIN_FREE_KVLCC2_tc_35_m worse" in text
    assert "keep: **none** (the model without a discovered term)" in text
    assert "tactical diameter error| 4.6 % (without the term 4.6 %; target 5 %: met; no worse than without)" in text
    # had the loop kept the term, the report says it is worse than without and misses the targets
    kept = dict(loop, kept=["Nvdrabsdr"])
    kept["discovered"] = [
        dict(
            ROUND2["discovered"][0],
            kept=True,
            worse_on_other_kinds=[
                {"run": "MARIN_FREE_KVLCC2_tc_35_m", "kind": "turning_circle", "rms_m": 1.2, "reference_rms_m": 0.8}
            ],
        )
    ]
    text = "\n".join(study._loop_lines(_res(kept, basin)))
    assert "keep: **Nvdrabsdr**" in text and "target 5 %: not met; worse than without" in text
    assert "Nvdrabsdr predicts MARIN_FREE_KVLCC2_tc_35_m (turning_circle, a kind the training runs lack) worse" in text
    assert "no run of the other basin is of that kind" in "\n".join(study._loop_lines(_res(None, basin)))
