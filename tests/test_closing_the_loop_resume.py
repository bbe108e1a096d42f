"""studies/closing_the_loop.py resumes from its checkpoints as the run left them: the JSON writer
stores a diverged refit's NaN as the string "nan", which the report's ratios then divided by (a
resumed run failed); and a kept term whose refit diverged on the designed run is named."""

import json
import math

from conftest import load_study


def _study():
    return load_study("closing_the_loop")


def _case(study):
    from bayesid.report.study import write_json

    return {
        "case": "submarine Nvvr, no velocity log",
        "family": "submarine",
        "repeat": 1,
        "hidden": {"Nvvr": -0.3},
        "designed_run": {"name": "turning circle 35 deg port", "samples": 751, "duration_s": 150.0},
        "round2": {
            "verdict": "unexplained -> discovered: Yvvdr (not separable from Nvvr on these runs)+unexplained",
            "kept": ["Yvvdr"],
            "alternatives": {"Yvvdr": ["Nvvr"]},
            "alternative_rms_m": {"Yvvdr": {"Yvvdr": 0.849, "Nvvr": 0.9}},
            "run_rms_m": {"Yvvdr": float("nan"), "Nvvr": 0.41},
        },
    }, write_json


def test_a_checkpointed_case_reads_back_with_its_nan_and_the_report_rows_are_written(tmp_path):
    study = _study()
    case, write_json = _case(study)
    write_json(tmp_path / "case.json", case)
    stored = json.loads((tmp_path / "case.json").read_text())
    assert stored["round2"]["run_rms_m"]["Yvvdr"] == "nan"  # what the writer stores
    back = study._revive(stored)
    assert math.isnan(back["round2"]["run_rms_m"]["Yvvdr"]) and back["round2"]["run_rms_m"]["Nvvr"] == 0.41
    assert back["case"] == case["case"]  # other strings untouched
    row = study._miss_row(back, 30.0)  # divided a float by "nan" before
    assert row[0] == "submarine Nvvr, no velocity log (1)" and "Nvvr/Yvvdr nan" in row[3]
    text = " ".join(study._diverged_lines([back]))
    assert "submarine Nvvr, no velocity log (repeat 1): Yvvdr, held-out RMS 0.849 m" in text
    assert study._diverged_lines([{**back, "round2": {**back["round2"], "run_rms_m": {"Yvvdr": 0.5}}}]) == []
