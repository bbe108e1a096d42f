"""Benchmark (issue 67): does the fitted Esso Osaka model reproduce the turn it was trained on, and what
does it miss? The packaged ``esso_osaka_3m`` model fitted to every zigzag and random run plus one
turning run of the pond tests (``../shared/data/real/esso-osaka-frt``), without the wind effect
(15 s and 60 s fit windows: the window start resets the speed, so a longer window makes the fit see
the speed decay in the turn), with it, and with it and each of the ship catalogue's surge and
propeller effects (the MMG 2015 wake in a turn, the thrust deduction, the rudder's resistance), the
current or MMG 2015's coupling speed of the hull's coupling terms (the catalogue's ``coupling_speed``,
fitted to the four turns alone too); with the wind and more of the surge balance free (a fourth-order hull surge term, the
rudder's and the propeller's deductions ``tR`` and ``tP``, the slope ``k1`` of the propeller's open-water
curve); and, to tell a training set that weighs the turn down from a form that cannot hold it, with
the wind fitted to the four turns alone. Each fit's turning circles are then predicted whole from
the measured first state (:func:`bayesid.estimation.prediction.training_turns`): the training turn
and the three other turns the index reader reads. Also: each turn's logged wind against the hull's
resistance (:func:`bayesid.models.ship.dynamics.wind_to_resistance`).

    python benchmarks/esso_training_turn.py [--turn turn_14-Oct-2020_15_06_53] [--data ../shared/data/real]

Per fit and turn: the tactical and steady turning diameters' errors, the speed loss in the steady
turn (1 - u/U0) measured / predicted, and the suspected component. The last lines are
machine-readable: ``speed_loss_<fit>`` (the training turn's predicted speed loss) and
``speed_loss_measured``.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bayesid import FitOptions, identify  # noqa: E402
from bayesid.data import datasets  # noqa: E402
from bayesid.estimation.prediction import FittedModel, training_turns  # noqa: E402
from bayesid.models import ship  # noqa: E402
from bayesid.models.ship.dynamics import wind_to_resistance  # noqa: E402

#: The turns besides the training one whose measured and predicted circles the index reader reads.
JUDGED = (
    "turn_14-Oct-2020_15_06_53",
    "turn_14-Oct-2020_15_21_57",
    "turn_14-Sep-2020_13_39_32",
    "turn_14-Sep-2020_15_47_33",
)
#: (label, effects, fit window s, coefficients freed beside the file's list, training runs: "zigzags+turn"
#: (every zigzag and random run and ``--turn``) or "turns" (the four of :data:`JUDGED` alone))
FITS = (
    ("no wind, 15 s", (), 15.0, (), "zigzags+turn"),
    ("no wind, 60 s", (), 60.0, (), "zigzags+turn"),
    ("wind, 15 s", ("wind",), 15.0, (), "zigzags+turn"),
    # with the wind, each of the ship catalogue's surge and propeller effects in turn (and the current)
    ("wind+wake_in_turn, 15 s", ("wind", "wake_in_turn"), 15.0, (), "zigzags+turn"),
    ("wind+thrust_deduction, 15 s", ("wind", "thrust_deduction"), 15.0, (), "zigzags+turn"),
    ("wind+rudder_resistance, 15 s", ("wind", "rudder_resistance"), 15.0, (), "zigzags+turn"),
    ("wind+current, 15 s", ("wind", "current"), 15.0, (), "zigzags+turn"),
    # the hull's coupling terms with MMG 2015's coupling speed (the catalogue's model form)
    ("wind+coupling_speed, 15 s", ("wind", "coupling_speed"), 15.0, (), "zigzags+turn"),
    # with the wind, more of the surge balance free: the MMG hull's fourth-order surge term, both
    # deductions, the open-water curve's slope
    ("wind, Xvvvv free, 15 s", ("wind",), 15.0, ("Xvvvv",), "zigzags+turn"),
    ("wind, tR and tP free, 15 s", ("wind",), 15.0, ("tR", "tP"), "zigzags+turn"),
    ("wind, k1 free, 15 s", ("wind",), 15.0, ("k1",), "zigzags+turn"),
    # the four turns alone: can one parameter set hold them?
    ("turns only, wind, 15 s", ("wind",), 15.0, (), "turns"),
    ("turns only, wind, 60 s", ("wind",), 60.0, (), "turns"),
    ("turns only, wind+coupling_speed, 15 s", ("wind", "coupling_speed"), 15.0, (), "turns"),
)
#: The coefficients printed beside each fit (the surge balance's; the freed ones too)
SHOWN = ("Xuu", "wP")


def _pct(v) -> str:
    return "-" if v is None else f"{100 * v:+.1f} %"


def _f(v) -> str:
    return "-" if v is None else f"{v:.3f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--turn", default=JUDGED[0], help="the turning run added to the training runs")
    ap.add_argument("--data", default=str(ROOT / ".." / "shared" / "data" / "real"))
    args = ap.parse_args(argv)
    esso_dir = Path(args.data) / "esso-osaka-frt"
    if not esso_dir.is_dir():
        print(f"real data not found under {args.data}: nothing to do")
        return 0
    warnings.filterwarnings("ignore", module="bayesid")  # the coarse-rudder warnings of every random run
    runs = [p for p in datasets.list_runs(esso_dir, "esso-osaka") if "turn_cut" not in p.name]
    tracks = {t.name: t for t in (datasets.read_run(p, "esso-osaka") for p in runs)}
    train = [t for n, t in tracks.items() if n.startswith(("zigzag", "random"))]
    esso = ship.load_ship("esso_osaka_3m")
    judged = [tracks[n] for n in JUDGED]
    print("wind / resistance of the turns: " + ", ".join(f"{t.name} {_f(wind_to_resistance(esso, t))}" for t in judged))
    last = []
    for label, effects, window, extra, runs_of in FITS:
        t0 = time.perf_counter()
        vessel = esso.with_coefficients({k: 0.0 for k in extra if k not in esso.coefficients})  # a hull term
        opt = FitOptions(
            free=tuple(esso.free) + extra, effects=effects, window_s=window, dt=0.2, max_nfev=30, start="measured"
        )
        fitted_on = train + [tracks[args.turn]] if runs_of == "zigzags+turn" else judged
        res = identify(vessel, fitted_on, opt, calibration=None)
        what = f"{len(train)} runs + {args.turn}" if runs_of == "zigzags+turn" else f"the {len(judged)} turns"
        c = res.fit.coefficients()
        at = set(res.fit.at_bound or ())
        shown = ", ".join(f"{k} {c[k]:.4g}" + (" (at its bound)" if k in at else "") for k in (*extra, *SHOWN))
        q = dict(zip(res.model.param_names, np.asarray(res.fit.p, float)))  # the surge effects' parameters
        shown += "".join(f", {k} {v:.4g}" for k, v in q.items() if "." in k and not k.startswith("wind."))
        print(f"\n{label}: {what}; fit {time.perf_counter() - t0:.0f} s, cost {res.fit.cost:.4g}; {shown}")
        print("  run                          tactical   steady   speed loss meas / pred  suspect")
        for t in training_turns(FittedModel(res.model, np.asarray(res.fit.p, float), None), judged):
            r = t["rel_error"]
            tag = "TRAIN" if t["run"] == args.turn or runs_of == "turns" else "held "
            print(
                f"  {tag} {t['run']}  {_pct(r['tactical_diameter_m']):>8s} {_pct(r['steady_turning_diameter_m']):>8s}"
                f"   {_f(t['measured']['speed_loss'])} / {_f(t['predicted']['speed_loss'])}   {t['suspect'] or '-'}"
            )
            if t["run"] == args.turn and runs_of == "zigzags+turn":
                key = label.replace(", ", "_").replace(" ", "_").replace("+", "_").replace("_and_", "_")
                last.append(f"speed_loss_{key} {_f(t['predicted']['speed_loss'])}")
                measured = t["measured"]["speed_loss"]
    print()
    print("\n".join(last + [f"speed_loss_measured {_f(measured)}"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
