"""The main study's quick mode runs and writes the contract files."""

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_furlong2003_quick(tmp_path):
    out = tmp_path / "furlong2003"
    subprocess.run(
        [sys.executable, str(ROOT / "studies" / "furlong2003.py"), "--quick", "--out", str(out)],
        check=True,
        cwd=ROOT,
        timeout=600,
    )
    res = json.loads((out / "results.json").read_text())
    for case in ("case1", "case2", "case3"):
        c = res["cases"][case]
        for key in (
            "n_free",
            "start_cost",
            "final_cost",
            "max_position_error_m",
            "coefficient_ratio",
            "at_bound",
            "n_iterations",
            "n_simulations",
            "wall_s",
        ):
            assert key in c, (case, key)
        assert c["final_cost"] < c["start_cost"]
        assert set(c["coefficient_ratio"]) == set(c["free"])
    assert "true_coefficients_cost" in res["cases"]["case3"]
    assert res["cases"]["case1"]["n_free"] > res["cases"]["case2"]["n_free"]
    man = json.loads((out / "manifest.json").read_text())
    assert man["quick"] is True and man["seed"] == 2003
    assert (out / "report.md").read_text().startswith("# Furlong")
    assert len(list((out / "figures").glob("*.png"))) >= 7
