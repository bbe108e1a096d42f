"""``bayesid design``: the run that would tell apart the model structures the data cannot.

Structure discovery on a fitted model (as ``bayesid discover``), then, for a kept term with
alternatives the held-out runs cannot separate from it, the standard manoeuvres ranked by how far
apart the alternatives' predictions of them lie against measurement noise and parameter
uncertainty (:mod:`bayesid.analysis.gap.design`, Box & Hill 1967). Writes ``design.json`` (the
ranked runs), the input schedules of the top runs (``design_runs/*.csv``), ``diagnosis.json``,
``report.md`` and ``figures/design_top.png``; prints the ranked runs. Steer the top run (its
zigzag by your own heading), add it to ``--heldout`` and run ``bayesid discover`` again with
``--compare OUT/diagnosis.json``: the kept terms and their alternatives are then refitted on it
whatever the new selection picks.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from . import options as opt


def add_parser(sub) -> None:
    """Declare ``bayesid design`` and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    """
    from .discover import add_options

    d = opt.add_subcommand(sub, "design", "the run that separates the terms the runs cannot tell apart")
    add_options(d)


def run(args) -> int:
    """Run ``bayesid design``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.

    Returns
    -------
    int
        The exit code: 0 (also when there is nothing to separate: said).

    Raises
    ------
    ValueError
        ``--alternatives 0`` or ``--no-design``: nothing to design (exit 2).
    """
    from .. import __version__
    from ..report.study import write_json
    from .discover import discover

    if args.alternatives == 0 or args.no_design:
        raise ValueError("bayesid design needs --alternatives >= 1 and no --no-design (nothing to separate)")
    res = discover(args)
    rows = json.loads((Path(args.out) / "diagnosis.json").read_text())["design"]  # with the CSV names
    rows = [{k: v for k, v in r.items() if k != "predicted"} for r in rows]

    write_json(
        Path(args.out) / "design.json",
        {
            "design": rows,
            "discovered": res.to_dict()["discovered"],
            "criterion": "the pairs of the kept term and an alternative the run-by-run test could decide on the "
            "run within max_windows windows (decidable_pairs), then the smallest pairwise J divergence (nats) of "
            "the alternatives' Gaussian predictive distributions (Box & Hill 1967, Technometrics 9:57-71)",
            "version": __version__,
            "command": "bayesid " + " ".join(sys.argv[1:]),
            "seed": args.seed,
        },
    )
    if not rows:
        print("design: no kept term has alternatives the runs cannot separate; nothing to design")
        return 0
    print("runs that would separate the alternatives, best first (separation: nats, worst pair):")
    for i, r in enumerate(rows[:5], 1):
        sized = (r.get("run_test") or {}).get("sized_from_s")
        length = f"{r['duration_s']:.0f} s" + (f" (lengthened from {sized:.0f} s for the run test)" if sized else "")
        print(
            f"  {i}. {r['name']}, {length}: {r['separation']:.1f} ({r['worst_pair']}); "
            f"predicted positions up to {r['max_position_difference_m']:.2f} m apart"
        )
    print(
        f"wrote {Path(args.out) / 'design.json'} and the top runs' input schedules in {Path(args.out) / 'design_runs'}"
    )
    print(
        "fly the top run, add it to --heldout (or --train) and run again with "
        f"--compare {Path(args.out) / 'diagnosis.json'}: the kept terms and their alternatives are refitted on it"
    )
    return 0
