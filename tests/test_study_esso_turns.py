"""studies/esso_turns.py --quick: real Esso Osaka turns held out, end to end (skips without the real data)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "real" / "esso-osaka-frt"


@pytest.mark.skipif(not DATA.is_dir(), reason="needs shared/data/real (not in the package)")
def test_esso_turns_quick(tmp_path):
    out = tmp_path / "esso_turns"
    subprocess.run(
        [sys.executable, str(ROOT / "studies" / "esso_turns.py"), "--quick", "--out", str(out)],
        check=True,
        cwd=ROOT,
        timeout=900,
        capture_output=True,
    )
    res = json.loads((out / "results.json").read_text())
    assert res["quick"] is True and all(r.startswith("turn") for r in res["heldout_runs"])
    assert {r["effect"] for r in res["ranking"]} <= {"wake_in_turn", "rudder_resistance"}
    assert any("propulsion_point" in s for s in res["left_out"])  # wP is free in the Esso file
    for key in ("verdict", "dominant_channel", "heldout_rms_before_m", "floor_m", "turns"):
        assert key in res
    assert (out / "report.md").read_text().startswith("# Real turns held out")
    assert (out / "diagnosis" / "diagnosis.json").is_file()
