"""studies/ship_surge.py --quick runs one hidden surge structure end to end and writes the scores."""

import json
import subprocess
import sys
from pathlib import Path

from conftest import load_study

ROOT = Path(__file__).resolve().parents[1]


def test_ship_surge_quick(tmp_path):
    out = tmp_path / "ship_surge"
    subprocess.run(
        [sys.executable, str(ROOT / "studies" / "ship_surge.py"), "--quick", "--out", str(out)],
        check=True,
        cwd=ROOT,
        timeout=600,
        capture_output=True,
    )
    res = json.loads((out / "results.json").read_text())
    assert res["quick"] is True and len(res["cases"]) == 1
    case = res["cases"][0]
    assert case["term"] == "Xvvvv" and case["velocity_log"] is True
    for key in ("verdict", "dominant_channel", "dofs", "found", "alternatives", "named", "excess_shrink"):
        assert key in case
    for key in (
        "clear_cases",
        "named_in_clear",
        "wrong_term_alone",
        "controls_clean",
        "median_excess_shrink",
        "cases_with_a_kept_term_or_effect",
        "effects_named_in_clear",
    ):
        assert key in res["summary"]
    assert (out / "report.md").read_text().startswith("# A ship's surge")
    assert json.loads((out / "manifest.json").read_text())["quick"] is True


def test_the_calibration_reports_the_floor_bands_coverage_and_each_false_alarm():
    rows = [
        {"velocity_log": log, "seed": 1000 + k, "verdict": v, "heldout_rms_m": 0.3 * x, "floor_m": 0.3, "ratio": x}
        for log in (True, False)
        for k, (v, x) in enumerate([("none", 0.9), ("none", 1.2), ("unexplained", 1.7), ("none", 1.1)])
    ]
    rows[-1] = {**rows[-1], "verdict": "current", "ratio": 2.0, "heldout_rms_m": 0.6}
    text = "\n".join(load_study("ship_surge").calibration_lines(rows))
    assert "The band held in 5 of 8 (62.5 %)" in text
    assert text.count("- False alarm, seed") == 3
    assert "seed 1003 (no velocity log): current" in text
    assert "| velocity log | 4 | 3 |" in text and "| no velocity log | 4 | 2 |" in text
    assert load_study("ship_surge").calibration_lines([]) == []
