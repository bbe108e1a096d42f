"""Benchmark (issue 67): the packaged KVLCC2 file lacks the MMG hull's fourth-order surge term. Yasukawa &
Yoshimura (2015, J. Mar. Sci. Technol. 20:37-52, Table 3) give X'vvvv = 0.771 for KVLCC2 L7;
``bayesid/vehicles/kvlcc2_7m.toml`` has no fourth-order term. This script flies the packaged model's 35 deg
turning circles from the HSVA approach (1.179 m/s at its propulsion point, rudder at 15.8 deg/s) without
and with ``Xvvvv`` 0.771 and prints advance, tactical diameter, steady turning diameter (2 U / r over the
last 20 s), their ratio and u/U0 in the steady turn. The issue reports the other basin's measured turns at a
steady/tactical ratio of 0.78.

    python benchmarks/kvlcc2_xvvvv.py

Nothing is fitted; the last lines are machine-readable (``ratio_<model>``, ``u_over_U0_<model>``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bayesid.estimation.indices import manoeuvre_indices  # noqa: E402
from bayesid.models.ship import load_ship  # noqa: E402
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial  # noqa: E402

#: the MMG 2015 value (their Table 3, KVLCC2 L7)
XVVVV_MMG = 0.771


def main() -> int:
    base = load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(base, 1.179)
    opts = TrialOptions(dt=0.1, rudder_rate_deg_s=15.8, duration=480.0)
    last = []
    print("model                          side   advance  tactical  steady  steady/tactical  u/U0")
    for key, label, ship in (
        ("packaged", "packaged", base),
        ("Xvvvv", f"+ Xvvvv {XVVVV_MMG} (MMG 2015)", base.with_coefficients({"Xvvvv": XVVVV_MMG})),
    ):
        for angle, side in ((35.0, "port"), (-35.0, "stbd")):
            tr = simulate_trial(ship, "turn", angle, speed=speed, rpm=rpm, options=opts).track
            ind = manoeuvre_indices(np.asarray(tr.t), tr["x"], tr["y"], tr["psi"], tr["delta_r"])
            tail = np.asarray(tr.t) >= tr.t[-1] - 20.0
            u_end = float(np.mean(tr["u"][tail]))
            U_end = float(np.mean(np.hypot(tr["u"][tail], tr["v"][tail])))
            steady = 2.0 * U_end / float(np.mean(np.abs(tr["r"][tail])))
            ratio = steady / ind["tactical_diameter_m"]
            print(
                f"{label:30s} {side:5s} {ind['advance_m']:8.2f} {ind['tactical_diameter_m']:9.2f} {steady:7.2f}"
                f" {ratio:16.3f} {u_end / float(tr['u'][0]):5.3f}"
            )
        last += [f"ratio_{key} {ratio:.3f}", f"u_over_U0_{key} {u_end / float(tr['u'][0]):.3f}"]
    print("\n".join(last))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
