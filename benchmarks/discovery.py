"""Cost of structure discovery against the gap diagnosis' first round (issue 40: discovery adds
at most the time of the first round on the same data).

Three cases: a synthetic KVLCC2 set (closed-loop zigzags of the packaged model with a hidden
``Nabsdr`` term, two training and three held-out runs, 10 Hz, noise; ``bayesid.models.ship.trials``),
a synthetic NPS AUV II set whose round 1 has an effect to add (discovery runs beside it) and,
when ``../shared/data/real`` is present, the HSVA validation split of studies/real_ships.py.
Each runs one diagnosis (one round) with the ship catalogue less wind (submarine: sensor_bias, waves,
crossflow) and discovery, and prints the first
round's wall time, discovery's (beside round 1 and after the rounds, when it ran twice) and their
ratio; then the same diagnosis with the alternatives named and the separating runs designed
(issue 49: they add at most the time of one round) and what they add: as the difference of the two
whole diagnoses' wall times (which scatters by about 0.3 x the first round between runs) and as
the wall time of the stages only they run, timed inside the second diagnosis (the alternatives'
term refits, the design with its standard predictions).

    python benchmarks/discovery.py [--data DIR] [--max-nfev N]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bayesid.analysis.gap import DiagnoseOptions, diagnose  # noqa: E402
from bayesid.analysis.gap.design import DiscriminationOptions  # noqa: E402
from bayesid.analysis.gap.discovery import DiscoveryOptions  # noqa: E402
from bayesid.data.track import Track  # noqa: E402
from bayesid.models import ship  # noqa: E402
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial  # noqa: E402

NOISE = {"x": 0.01, "y": 0.01, "psi": math.radians(0.05), "u": 0.002, "v": 0.002, "r": math.radians(0.02)}


def synthetic(rng):
    """Two training and three held-out zigzags of KVLCC2 with a hidden Nabsdr = 0.002."""
    kv = ship.load_ship("kvlcc2_7m")
    truth = kv.with_coefficients({"Nabsdr": 0.002})
    speed, rpm = propulsion_point(truth, 1.179)
    tracks = []
    for angle, check in ((20, 20), (-10, 10), (15, 10), (-25, 5), (10, 5)):
        tr = simulate_trial(
            truth, "zigzag", angle, check_deg=check, speed=speed, rpm=rpm, options=TrialOptions(duration=150.0)
        ).track
        data = {
            k: np.asarray(tr[k], float) + rng.normal(0, NOISE.get(k, 0.0), tr.n_samples)
            for k in ("x", "y", "psi", "u", "v", "r")
        }
        data.update(delta_r=tr["delta_r"], n=tr["n"])
        tracks.append(Track(tr.t, data, name=f"z{angle}_{check}"))
    return kv, tracks[:2], tracks[2:]


def submarine(rng):
    """NPS AUV II whose model lacks its constant yaw moment (``Nprop`` 5e-4 in the world): waves
    and a sensor bias absorb part of it, so round 1 has an effect to add and discovery runs beside
    it (the case of tests/test_discovery.py)."""
    from bayesid.data.vehicle import load_vehicle
    from bayesid.models import manoeuvres as mv
    from bayesid.models.world import world_track

    veh = load_vehicle("nps_auv2")
    world = veh.with_coefficients({"Nprop": 5e-4})
    train = [mv.zigzag(veh, 20.0, dt=0.1, duration=150.0), mv.prbs(veh, 15.0, duration=150.0, rng=rng)]
    held = [
        mv.zigzag(veh, 10.0, dt=0.1, duration=150.0, first_sign=-1),
        mv.prbs(veh, 10.0, duration=150.0, rng=np.random.default_rng(2)),
    ]
    tracks = [world_track(world, m, {}, rng, name=f"run{i}") for i, m in enumerate(train + held)]
    return veh, ["Yv", "Nr", "Ndr"], tracks[:2], tracks[2:]


def hsva(data: Path):
    from bayesid.data import datasets

    hold = ["Z_10_10_P", "Z_20_10_S", "Z_35_05", "Z_15_01"]
    runs = [datasets.read_run(p, "simman-hsva") for p in datasets.list_runs(data / "kvlcc2-simman-hsva", "simman-hsva")]
    held = [t for t in runs if any(t.name.endswith(h) for h in hold)]
    return ship.load_ship("kvlcc2_7m"), [t for t in runs if t not in held], held


def _diagnose(kv, free, train, held, cands, max_nfev, alternatives: bool):
    t0 = time.perf_counter()
    d = diagnose(
        kv,
        kv.free if free is None else free,
        train,
        held,
        DiagnoseOptions(
            candidates=cands,
            window_s=60.0,
            max_nfev=max_nfev,
            max_effects=1,
            start="measured",
            discover=DiscoveryOptions(max_nfev=max_nfev, n_alternatives=2 if alternatives else 0),
            design=DiscriminationOptions() if alternatives else None,
        ),
    )
    return d, time.perf_counter() - t0


class _Timers:
    """Wall time of the stages only the alternatives and the design run, inside one diagnosis:
    each discovery's term refits (``fit_term``, labelled by the role ``_refit_terms`` gives the
    term: selected, alternative, mimicked, compared), the design (``_design``) and its standard
    predictions. The diagnosis runs its refits in this process (``Runner`` with one job), so
    wrapping the module functions sees every call."""

    def __init__(self):
        import importlib

        disc = importlib.import_module("bayesid.analysis.gap.discovery")
        diag = importlib.import_module("bayesid.analysis.gap.diagnose")
        self.mods = {"fit_term": disc, "_refit_terms": disc, "_design": diag, "standard_predictions": diag}
        self.orig = {k: getattr(m, k) for k, m in self.mods.items()}
        self.seconds, self.by_role, self.how = dict.fromkeys(self.mods, 0.0), {}, {}

    def __enter__(self):
        for k, m in self.mods.items():
            setattr(m, k, self._timed(k, self.orig[k]))
        return self

    def __exit__(self, *exc):
        for k, m in self.mods.items():
            setattr(m, k, self.orig[k])

    def _timed(self, key, f):
        def timed(*args, **kwargs):
            if key == "_refit_terms":
                self.how = args[0]
            t0 = time.perf_counter()
            out = f(*args, **kwargs)
            dt = time.perf_counter() - t0
            self.seconds[key] += dt
            if key == "fit_term":
                role = self.how.get(args[0].term, "selected")
                self.by_role[role] = self.by_role.get(role, [0, 0.0])
                self.by_role[role][0] += 1
                self.by_role[role][1] += dt
            return out

        return timed


def measure(name, kv, train, held, max_nfev, free=None, cands=None):
    cands = cands or ["current", "delay", "sensor_lag"]  # the catalogue its committed outputs were measured with
    d, total = _diagnose(kv, free, train, held, cands, max_nfev, False)
    first = d.round_seconds[0]
    # discovery beside round 1 (when round 1 has an effect to add) and after the rounds: both count
    beside = d.discovery_first
    disc = (d.discovery.seconds if d.discovery else 0.0) + (
        beside["seconds"] if beside and not beside["took_round"] else 0.0
    )
    ran = ("beside round 1 " + ("(took it) " if beside["took_round"] else "and after the rounds ")) if beside else ""
    print(
        f"{name}: first round ({len(cands)} candidates) {first:.1f} s, discovery {disc:.1f} s "
        f"{ran}(ratio {disc / first:.2f}), whole diagnosis {total:.1f} s; verdict {d.verdict}"
    )
    # issue 49: the alternatives and the design add at most the time of one diagnosis round
    with _Timers() as timers:
        d2, total2 = _diagnose(kv, free, train, held, cands, max_nfev, True)
    extra = total2 - total
    print(
        f"{name}, with alternatives and design: whole diagnosis {total2:.1f} s, {extra:+.1f} s "
        f"(ratio to the first round {extra / d2.round_seconds[0]:.2f}; {len(d2.design)} runs ranked); "
        f"verdict {d2.verdict}"
    )
    # the same inside this one diagnosis: the stages only the alternatives and the design run
    extra_roles = {k: v for k, v in timers.by_role.items() if k != "selected"}
    alt_s = sum(v[1] for v in extra_roles.values())
    design_s = timers.seconds["_design"]
    first2 = d2.round_seconds[0]
    roles = ", ".join(f"{v[0]} {k}" for k, v in sorted(extra_roles.items())) or "none"
    print(
        f"{name}, inside that diagnosis: the alternatives' refits {alt_s:.1f} s ({roles}), "
        f"the design {design_s:.1f} s (standard predictions {timers.seconds['standard_predictions']:.1f} s); "
        f"together {(alt_s + design_s) / first2:.2f} x its first round ({first2:.1f} s)"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"))
    ap.add_argument("--max-nfev", type=int, default=40)
    args = ap.parse_args()
    measure("synthetic KVLCC2 (hidden Nabsdr)", *synthetic(np.random.default_rng(0)), args.max_nfev)
    veh, free, train, held = submarine(np.random.default_rng(5))
    cands = ["sensor_bias", "waves", "crossflow"]
    measure("synthetic NPS AUV II (hidden Nprop)", veh, train, held, args.max_nfev, free, cands)
    data = Path(args.data)
    if (data / "kvlcc2-simman-hsva").is_dir():
        measure("KVLCC2 HSVA validation split", *hsva(data), args.max_nfev)
    else:
        print(f"no real data under {data}: the HSVA case is skipped")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
