"""studies/posterior.py --quick runs every case and writes issue 9's keys."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
KEYS = (
    "rhat_max",
    "ess_bulk_min",
    "ess_tail_min",
    "tau_max",
    "n_steps",
    "acceptance_mean",
    "correlation",
    "sloppiest_direction",
    "fim_condition_number",
    "coverage_90",
    "converged",
    "wall_s",
)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """One ``--quick`` run of every case (seed 2003), shared by the tests of this file."""
    out = tmp_path_factory.mktemp("posterior") / "posterior"
    subprocess.run(
        [sys.executable, str(ROOT / "studies" / "posterior.py"), "--quick", "--out", str(out)],
        check=True,
        cwd=ROOT,
        timeout=900,
    )
    return out


def test_posterior_quick(quick_run):
    out = quick_run
    res = json.loads((out / "results.json").read_text())
    for case in ("case1", "case2", "case3", "case3b"):
        for key in KEYS:
            assert key in res[case], (case, key)
            assert key in res["cases"][case], (case, key)
        c = res[case]
        assert len(c["correlation"]) == 10
        assert all(-1.0 <= r <= 1.0 for r in c["correlation"].values())
        assert 0.0 <= c["coverage_90"] <= 1.0
        assert isinstance(c["converged"], bool)
        assert abs(sum(w * w for w in c["sloppiest_direction"].values()) - 1.0) < 0.05
        assert (out / f"posterior_{case}.nc").exists()
    # the Bayesian Case 3 samples the towing-tank coefficients too
    assert res["cases"]["case3b"]["n_params"] > res["cases"]["case3"]["n_params"]
    # Case 1's exact nulls are found and leave the track unchanged
    nulls = res["cases"]["case1"]["dossier"]["structural_nulls"]
    assert len(nulls) == 3 and max(n["track_change_m"] for n in nulls) < 1e-6
    man = json.loads((out / "manifest.json").read_text())
    assert man["quick"] is True and "log_prob_evals_per_s" in man
    assert "## The paper's points (2)-(4), in numbers" in (out / "report.md").read_text()
    assert len(list((out / "figures").glob("*.png"))) >= 4 * 5 + 1


def test_a_checkpoint_reused_with_another_seed_is_not_reported_as_that_seed(quick_run, tmp_path):
    out = tmp_path / "post"
    # the shared run's case 1 checkpoint (seed 2003), as a run of --cases 1 leaves it
    shutil.copytree(
        quick_run, out, ignore=lambda d, names: [n for n in names if n.startswith("case") and "case1_" not in n]
    )
    cmd = [sys.executable, str(ROOT / "studies" / "posterior.py"), "--quick", "--cases", "1", "--out", str(out)]
    r = subprocess.run(cmd + ["--seed", "7"], cwd=ROOT, timeout=600, capture_output=True, text=True)
    assert r.returncode == 2 and "seed" in r.stderr and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "seed 2003" in (out / "report.md").read_text()  # the old report is untouched
    subprocess.run(cmd + ["--seed", "7", "--fresh"], check=True, cwd=ROOT, timeout=600)
    assert "seed 7" in (out / "report.md").read_text()
    r = subprocess.run(
        cmd[:-4] + ["--cases", "3", "--seed", "7", "--out", str(out)],
        cwd=ROOT,
        timeout=600,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0 and "dropped" in (out / "report.md").read_text() and "case1" in r.stdout
