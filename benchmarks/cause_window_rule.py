"""Benchmark (issue 69): a cause rule that also asks the paired window test, re-applied offline to the
first round of every case of a ``studies/sim_to_real.py`` journal.

Today a cause needs the held-out error inside the floor band, at least half the excess removed and
ΔBIC <= -10 (:func:`bayesid.analysis.gap.verdict.is_cause`). The variant adds: the one-sided paired
window test p below ``level``, unless the test had too few windows to say anything
(:func:`~bayesid.analysis.gap.verdict.paired_window_test` returns exactly 1.0 then; an all-worse
test does too, which this reading takes for powerless). Only round 1 is re-judged (later rounds
depend on what round 1 added), and the verdicts are not rebuilt: the script prints each case whose
round-1 causes change, with the truth.

    python benchmarks/cause_window_rule.py [--journal reports/sim_to_real/journal.jsonl] [--levels 0.05,0.01]

The last lines are machine-readable: ``changed_<level>`` (cases whose round-1 causes change).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bayesid.analysis.gap.verdict import Thresholds, is_cause  # noqa: E402


def causes(rows: list, band: float, level: float | None, th: Thresholds) -> list:
    """The effects of ``rows`` (round-1 candidate rows) the cause rule names, with the window test
    at ``level`` (None: today's rule)."""
    out = []
    for r in rows:
        if r.get("failed_fit") or not is_cause(r, True, band, th):
            continue
        p = r["window_p_value"]
        if level is None or p < level or p == 1.0:
            out.append(r["effect"])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--journal", default=str(ROOT / "reports" / "sim_to_real" / "journal.jsonl"))
    ap.add_argument("--levels", default="0.05,0.01")
    args = ap.parse_args(argv)
    rows = [json.loads(line) for line in Path(args.journal).read_text().splitlines()[1:]]
    th = Thresholds()
    last = []
    for level in (float(v) for v in args.levels.split(",")):
        changed = 0
        for row in rows:
            res = row["result"]
            d = res["diagnosis"]
            if not d.get("rounds") or not d["significant_gap"]:
                continue
            band = th.none_ratio * d["noise_floor"]["heldout_rms_m"]
            first = d["rounds"][0]
            now, then = causes(first, band, None, th), causes(first, band, level, th)
            recorded = [r["effect"] for r in first if r.get("role") == "cause"]
            if now != recorded:
                raise SystemExit(f"{row['key']}: today's rule gives {now}, the journal records {recorded}")
            if now != then:
                changed += 1
                ps = ", ".join(f"{r['effect']} {r['window_p_value']:.3g}" for r in first if r["effect"] in now)
                print(
                    f"level {level:g}: {row['key']} (truth {'+'.join(res['case']['truth']) or '-'}): {now} -> {then}; p: {ps}"
                )
        print(f"level {level:g}: round-1 causes change in {changed} of {len(rows)} cases")
        last.append(f"changed_{level:g} {changed}")
    print("\n".join(last))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
