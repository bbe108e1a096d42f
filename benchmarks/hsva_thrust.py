"""Benchmark (issue 67): what the HSVA runs' measured propeller thrust says about the ship model's propeller.

The 13 HSVA free-running zigzags of the KVLCC2 7 m model (SIMMAN 2008; ``../shared/data/real/kvlcc2-simman-hsva``)
log the propeller's thrust (col 10, N) beside the track. That is a direct measurement of one term of the surge
equation: the model's thrust ``T = rho n^2 D^4 KT(J)``, ``J = u (1 - w_P) / (n D)`` (Yasukawa & Yoshimura 2015,
J. Mar. Sci. Technol. 20:37-52, eqs. 9-12 and 16) can be evaluated along the logged states with no simulation
and no trajectory fit. Nothing of it enters the diagnosis today (the model is fitted to positions and heading).

The thrust is computed by the package's own kernel (:func:`bayesid.models.ship.dynamics.forces`) on a copy of
the ship whose other surge forces are zero (``Xuu = Xvv = Xvr = Xrr = 0``, ``tP = 0``, ``tR = 1``), at the
logged ``r``, ``n``, rudder and the body velocities ``u``, ``v`` derived from the positions (Savitzky-Golay,
2 s cubic; the files give no body velocity). Propeller models compared:

- the packaged file (``kvlcc2_7m.toml``): MMG 2015's open-water curve (Table 4) with HSVA's diameter 0.204 m
  (MMG's propeller is 9.86 m full scale, 0.216 m at 1:45.714), ``w_P = 0.40 exp(-4 beta_P^2)``;
- the data set's own open-water curve (``aux/open_water_characteristics.csv``, a quadratic in J fitted for
  J <= 0.7), with the package's wake ``exp(-4 beta_P^2)``, a constant wake, and the MMG 2015 wake in
  a turn (C1, C2, C2m of MMG's KVLCC2, or fitted).

``w_P`` (and C1, C2, C2m where said) are fitted by least squares on the seven runs of 5-15 deg rudder and
tested on the six of 20-35 deg, which reach larger propeller drift angles (|beta_P| up to 27 deg).
Then, to see whether the propeller's thrust explains the model's speed loss in a 35 deg turn (issue 67),
the packaged model is flown through 35 deg turns at the basin's 614 rpm with the resistance ``Xuu`` set so
that it is self-propelled at the HSVA approach (1.179 m/s), with either propeller curve.

    python benchmarks/hsva_thrust.py [--data ../shared/data/real]

The last lines are machine-readable (``bias_packaged_N``, ``rms_test_<model>_N``, ``ratio_<turn model>``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import brentq, least_squares
from scipy.signal import savgol_filter

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bayesid.data.datasets import read_simman_hsva  # noqa: E402
from bayesid.estimation.indices import manoeuvre_indices  # noqa: E402
from bayesid.models.ship import load_ship  # noqa: E402
from bayesid.models.ship.dynamics import forces  # noqa: E402
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial  # noqa: E402

#: The HSVA approach (data set README): 1.179 m/s at 614 rpm (10.2295 rps).
U0, RPM_BASIN = 1.179, 60.0 * 10.2295
#: Savitzky-Golay window of the body velocities from the positions: 41 samples at 20 Hz (2 s), cubic.
SG_WINDOW, SG_ORDER = 41, 3
#: The MMG 2015 wake in a turn of KVLCC2 (Yasukawa & Yoshimura 2015, Table 4).
MMG_WAKE = {"C1": 2.0, "C2": 1.6, "C2m": 1.1}
#: The propeller-only copy of a ship: every other surge force zero (X = T).
THRUST_ONLY = {"Xuu": 0.0, "Xvv": 0.0, "Xvr": 0.0, "Xrr": 0.0, "tP": 0.0, "tR": 1.0}


def open_water_curve(path: Path) -> dict:
    """k0, k1, k2 of a quadratic fitted to the data set's open-water table for J <= 0.7."""
    ow = np.genfromtxt(path, delimiter=",", names=True)
    keep = ow["J"] <= 0.7
    k2, k1, k0 = np.polyfit(ow["J"][keep], ow["Kt"][keep], 2)
    return {"k0": float(k0), "k1": float(k1), "k2": float(k2)}


def logged_runs(folder: Path) -> list:
    """Per run: name, states (N, 6), inputs (N, 2: rudder rad, rps), measured thrust (N,), max |rudder| deg."""
    runs = []
    for f in sorted(folder.glob("HSVA_CPMC_KVLCC2_Z_*.dat")):
        tr = read_simman_hsva(f)
        t = np.asarray(tr.t)
        dt = float(np.median(np.diff(t)))
        psi = tr["psi"]
        xd = savgol_filter(tr["x"], SG_WINDOW, SG_ORDER, deriv=1, delta=dt)
        yd = savgol_filter(tr["y"], SG_WINDOW, SG_ORDER, deriv=1, delta=dt)
        u = np.cos(psi) * xd + np.sin(psi) * yd
        v = -np.sin(psi) * xd + np.cos(psi) * yd
        states = np.column_stack([tr["x"], tr["y"], psi, u, v, tr["r"]])
        inputs = np.column_stack([tr["delta_r"], tr["n"] / 60.0])
        name = f.stem.replace("HSVA_CPMC_KVLCC2_", "")
        runs.append((name, states, inputs, np.asarray(tr["thrust"]), float(np.degrees(np.max(np.abs(tr["delta_r"]))))))
    return runs


def model_thrust(ship, coefficients: dict, states, inputs) -> np.ndarray:
    """The model's propeller thrust (N) at logged states: X of the propeller-only copy."""
    s = ship.with_coefficients({**coefficients, **THRUST_ONLY})
    out = np.empty((states.shape[0], 3))
    forces(states, inputs, np.zeros((states.shape[0], 2)), np.zeros(2), s.params(), out)
    return out[:, 0]


def beta_p_deg(ship, states) -> np.ndarray:
    """The propeller's drift angle, deg: atan(-(v + xP L r) / u)."""
    xP = ship.coefficients["xP"]
    return np.degrees(np.arctan2(-(states[:, 4] + xP * ship.L * states[:, 5]), np.abs(states[:, 3])))


def fit_propeller(ship, fixed: dict, free: dict, runs) -> tuple[dict, float]:
    """Least-squares fit of the coefficients ``free`` ({name: (start, lo, hi)}) to the runs' thrust;
    returns the fitted coefficients (with ``fixed``) and the RMS (N)."""
    names = list(free)

    def coef(x):
        return {**fixed, **dict(zip(names, map(float, x)))}

    def res(x):
        c = coef(x)
        return np.concatenate([model_thrust(ship, c, s, i) - T for _, s, i, T, _ in runs])

    if names:
        sol = least_squares(
            res, [free[n][0] for n in names], bounds=([free[n][1] for n in names], [free[n][2] for n in names])
        )
        x = sol.x
    else:
        x = []
    return coef(x), float(np.sqrt(np.mean(res(x) ** 2)))


def rms(ship, coefficients: dict, runs) -> tuple[float, float]:
    """RMS and mean of (model - measured) thrust over the runs, N."""
    r = np.concatenate([model_thrust(ship, coefficients, s, i) - T for _, s, i, T, _ in runs])
    return float(np.sqrt(np.mean(r**2))), float(np.mean(r))


def turn_row(ship, label: str) -> tuple[str, float]:
    """35 deg turns both ways from the approach at the model's propulsion point: a printed row and the ratio."""
    speed, rpm = propulsion_point(ship, U0)
    opts = TrialOptions(dt=0.1, rudder_rate_deg_s=15.8, duration=480.0)
    lines, ratio = [], float("nan")
    for angle, side in ((35.0, "port"), (-35.0, "stbd")):
        tr = simulate_trial(ship, "turn", angle, speed=speed, rpm=rpm, options=opts).track
        ind = manoeuvre_indices(np.asarray(tr.t), tr["x"], tr["y"], tr["psi"], tr["delta_r"])
        tail = np.asarray(tr.t) >= tr.t[-1] - 20.0
        U_end = float(np.mean(np.hypot(tr["u"][tail], tr["v"][tail])))
        steady = 2.0 * U_end / float(np.mean(np.abs(tr["r"][tail])))
        ratio = steady / ind["tactical_diameter_m"]
        lines.append(
            f"{label:44s} {side:5s} {rpm:6.0f} {ship.coefficients['Xuu']:8.4f} {ind['advance_m']:7.2f}"
            f" {ind['tactical_diameter_m']:8.2f} {steady:7.2f} {ratio:7.3f} {float(np.mean(tr['u'][tail])) / speed:6.3f}"
        )
    return "\n".join(lines), ratio


def balanced(ship, coefficients: dict):
    """The ship with ``coefficients`` and ``Xuu`` set so that it is self-propelled at U0 and the basin's rpm."""

    def excess(xuu):
        return propulsion_point(ship.with_coefficients({**coefficients, "Xuu": xuu}), U0)[1] - RPM_BASIN

    return ship.with_coefficients({**coefficients, "Xuu": brentq(excess, -0.05, -0.002, xtol=1e-7)})


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "real"))
    args = ap.parse_args()
    folder = Path(args.data) / "kvlcc2-simman-hsva"
    if not folder.is_dir():
        print(f"no HSVA data at {folder}: nothing to do")
        return 0
    ship = load_ship("kvlcc2_7m")
    hsva = open_water_curve(folder / "aux" / "open_water_characteristics.csv")
    runs = logged_runs(folder)
    train = [r for r in runs if r[4] <= 15.5]
    test = [r for r in runs if r[4] > 15.5]
    last = []
    print(f"{len(runs)} HSVA runs; train: {len(train)} of 5-15 deg, test: {len(test)} of 20-35 deg")
    print(f"open-water curve of the data set (J <= 0.7): k0 {hsva['k0']:.4f} k1 {hsva['k1']:.4f} k2 {hsva['k2']:.4f};")
    c = ship.coefficients
    print(
        f"packaged (MMG 2015 Table 4): k0 {c['k0']:.4f} k1 {c['k1']:.4f} k2 {c['k2']:.4f}, D {ship.particulars['D_prop']} m"
    )
    print()
    print("run        max rudder  measured T mean [min, max] N   packaged model T mean N   |beta_P| max deg")
    for name, s, i, T, dmax in runs:
        Tm = model_thrust(ship, {}, s, i)
        print(
            f"{name:10s} {dmax:10.1f}  {T.mean():6.1f} [{T.min():5.1f}, {T.max():5.1f}]"
            f" {Tm.mean():24.1f} {np.max(np.abs(beta_p_deg(ship, s))):18.1f}"
        )
    r_all, bias = rms(ship, {}, runs)
    last.append(f"bias_packaged_N {bias:.2f}")
    print(f"\npackaged model: thrust RMS {r_all:.2f} N, mean (model - measured) {bias:.2f} N over all runs")
    print()
    wp = {"wP": (0.4, 0.0, 0.9)}
    cases = [
        ("packaged", "packaged curve, exp wake, wP fitted", {}, wp),
        ("hsva_exp", "data set curve, exp(-4 beta_P^2) wake, wP fitted", dict(hsva), wp),
        ("hsva_const", "data set curve, constant wake, wP fitted", {**hsva, "C1": 1.0, "C2": 1.0, "C2m": 1.0}, wp),
        ("hsva_mmg", "data set curve, MMG wake (C1 2.0, C2 1.6, C2m 1.1), wP fitted", {**hsva, **MMG_WAKE}, wp),
        (
            "hsva_mmg_fit",
            "data set curve, MMG wake, wP C1 C2 C2m fitted",
            dict(hsva),
            {**wp, "C1": (2.0, 0.05, 10.0), "C2": (1.6, 0.5, 3.0), "C2m": (1.1, 0.5, 3.0)},
        ),
    ]
    print("propeller model                                              train RMS N  test RMS N  test bias N  fitted")
    for key, label, fixed, free in cases:
        coef, train_rms = fit_propeller(ship, fixed, free, train)
        test_rms, test_bias = rms(ship, coef, test)
        shown = " ".join(f"{n} {coef[n]:.3f}" for n in free)
        print(f"{label:60s} {train_rms:11.2f} {test_rms:11.2f} {test_bias:12.2f}  {shown}")
        last.append(f"rms_test_{key}_N {test_rms:.2f}")
        if key == "hsva_exp":
            hsva_wp = coef["wP"]
        if key == "hsva_mmg":
            hsva_mmg_wp = coef["wP"]
    print()
    print(
        "35 deg turns from the HSVA approach (1.179 m/s) at the model's propulsion point; Xuu set for 614 rpm where said"
    )
    print("model                                        side     rpm      Xuu advance tactical  steady  st/tac   u/U0")
    for key, label, s in (
        ("packaged", "packaged (its own propulsion point)", ship),
        ("packaged_614", "packaged propeller, Xuu for 614 rpm", balanced(ship, {})),
        ("hsva_614", f"data set curve, wP {hsva_wp:.3f}, Xuu for 614 rpm", balanced(ship, {**hsva, "wP": hsva_wp})),
        (
            "hsva_mmg_614",
            f"data set curve, MMG wake, wP {hsva_mmg_wp:.3f}, Xuu for 614",
            balanced(ship, {**hsva, **MMG_WAKE, "wP": hsva_mmg_wp}),
        ),
    ):
        text, ratio = turn_row(s, label)
        print(text)
        last.append(f"ratio_{key} {ratio:.3f}")
    print("\n".join(last))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
