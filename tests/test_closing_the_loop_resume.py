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


def _truth_case(true_rms):
    """A miss whose hidden gRm's refit predicts the designed run worse than the kept Nabsvabsr, with
    the true structure's own coefficients at ``true_rms`` on it."""
    refit = {
        "gRm": {"estimate": 0.291, "truth": 0.3},
        "Yvvr": {"estimate": 0.755, "truth": 0.379},
        "Ycf": {"estimate": 0.262, "truth": 0.45},
        "Yv": {"estimate": -0.333, "truth": -0.315},
        "dR0": {"estimate": 0.0005, "truth": 0.0},
    }
    return {
        "case": "ship gRm 0.3 (gR 0.5), velocity log",
        "family": "ship",
        "repeat": 0,
        "hidden": {"gRm": 0.3},
        "round2": {
            "kept": ["Nabsvabsr"],
            "alternatives": {"Nabsvabsr": ["gRm"]},
            "run_rms_m": {"Nabsvabsr": 0.188, "gRm": 0.885},
        },
        "truth_on_run": {"true_coefficients_rms_m": true_rms, "refit": refit},
    }


def test_a_miss_says_whether_the_truths_own_coefficients_would_separate_the_designed_run():
    study = _study()
    right = _truth_case(0.0325)
    text = " ".join(study._truth_lines(right))
    # the refit's hidden coefficient, and its other coefficients more than 50 % off (a zero truth has no ratio)
    assert "predicts the designed run at 0.0325 m; refitted on the training runs, at 0.885 m" in text
    assert "gRm = 0.291 (truth 0.3), but 1 of its 4 other free coefficients are more than 50 %" in text
    assert "(furthest: Yvvr 0.755 for 0.379)" in text and "The structure is right" in text
    assert study._truth_separates(right) and study._truth_on_run_ratio(right) == "0.173"
    # the truth's coefficients within the run test's margin of the kept term: the run cannot tell them apart
    tied = _truth_case(0.18)
    text = " ".join(study._truth_lines(tied))
    assert "within the run test's margin of the kept term (1.04 x)" in text and "The structure is right" not in text
    assert not study._truth_separates(tied)
    # no truth scored (a control, or a checkpoint written before): nothing said
    assert (
        study._truth_lines({**right, "truth_on_run": None}) == []
        and study._truth_on_run_ratio({**right, "truth_on_run": None}) == "-"
    )
