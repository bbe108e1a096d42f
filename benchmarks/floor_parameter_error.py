"""Why a ship diagnosis without a velocity log sees a gap with nothing missing (issue 69's noise floor,
reports/ship_surge's no-log controls): the noise floor is the error of the *true* coefficients at the
measured noise, while the base model's coefficients are *estimated* from zigzags that need not
determine the turns. This prints, on ship_surge's no-log control (synthetic KVLCC2, nothing hidden,
three zigzags to train, two turns and a pull-out held out, 2 Hz positions, 60 s windows, fitted
window starts):

- the held-out RMS of the true coefficients (what the noise floor estimates),
- that of the coefficients fitted on the zigzags (what the diagnosis compares with the floor),
- that of draws from the fit's Laplace covariance (the spread the coefficients' uncertainty alone gives),

all under the same protocol. When the truth's RMS is at the floor and the fitted model's is far above
it, the "gap" is estimation error, which a floor with the coefficients' uncertainty in it would hold.

    python benchmarks/floor_parameter_error.py [--draws N] [--seed N]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "studies"))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=20)
    ap.add_argument("--seed", type=int, default=74)  # ship_surge's seed of its control (67 + its index 7)
    ap.add_argument("--log", action="store_true", help="with the velocity log (u, v, r) instead")
    ap.add_argument("--inputs", default="hold", help="the logged rudder's reconstruction (hold, rate, linear)")
    args = ap.parse_args()
    import warnings

    import ship_surge

    from bayesid.data.track import read_csv
    from bayesid.estimation.identification import identify
    from bayesid.estimation.options import FitOptions
    from bayesid.estimation.prediction import predict
    from bayesid.models.ship import load_ship

    warnings.simplefilter("ignore")  # the 2 Hz logs' coarse-rudder warning, known here
    t0 = time.perf_counter()
    kv = load_ship("kvlcc2_7m")
    with tempfile.TemporaryDirectory() as d:
        paths = ship_surge.tracks({}, args.log, args.seed, 200.0, Path(d))
        train = [read_csv(p) for n, p in paths.items() if not n.endswith("_held")]
        held = [read_csv(p) for n, p in paths.items() if n.endswith("_held")]
    rate = 15.8 if args.inputs == "rate" else None
    res = identify(kv, train, FitOptions(max_nfev=30, inputs=args.inputs, rudder_rate_deg_s=rate), calibration=None)
    model, p = res.model, res.fit.p
    truth = model.theta0  # nothing hidden: the file's coefficients are the truth

    def rms(q):
        return predict(model, q, held, 60.0, start=res.start_rule).pooled["rms_position_m"]

    r_truth, r_fit = rms(truth), rms(p)
    rng = np.random.default_rng(0)
    cov = np.asarray(res.cov, float)
    draws = rng.multivariate_normal(p, cov, size=args.draws)
    r_draws = np.array([rms(q) for q in draws])
    z = (p - truth) / np.sqrt(np.diag(cov))
    print(f"# {__doc__.splitlines()[0]}")
    print(f"case: ship_surge control, {'velocity log' if args.log else 'no velocity log'}, seed {args.seed}")
    print(
        f"start rule {res.start_rule}; inputs {args.inputs}; {len(train)} training, {len(held)} held-out runs; 60 s windows"
    )
    print(f"held-out RMS, true coefficients           {r_truth:.4f} m")
    print(f"held-out RMS, fitted on the zigzags       {r_fit:.4f} m   ratio to the truth's {r_fit / r_truth:.2f}")
    q = np.quantile(r_draws, [0.05, 0.5, 0.95])
    print(f"held-out RMS, {args.draws} Laplace draws   5/50/95 %  {q[0]:.4f} {q[1]:.4f} {q[2]:.4f} m")
    print(
        f"fitted minus true, in Laplace sds: max |z| {np.max(np.abs(z)):.2f} ({model.param_names[int(np.argmax(np.abs(z)))]})"
    )
    print(f"wall {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
