"""Stand-in logs: the simulated tracks with sensor noise (positions 2 cm, heading 0.2 deg,
DVL velocities 5 mm/s, gyro 0.1 deg/s)."""

from pathlib import Path

import numpy as np

from bayesid.data.track import Track, read_csv, write_csv

rng = np.random.default_rng(2001)
NOISE = {"x": 0.02, "y": 0.02, "psi": np.radians(0.2), "u": 0.005, "v": 0.005, "r": np.radians(0.1)}
Path("logs").mkdir(exist_ok=True)
for path in sorted(Path("sim").glob("*.csv")):
    sim = read_csv(path)
    data = {k: sim[k] + rng.normal(0.0, sd, sim.n_samples) for k, sd in NOISE.items()}
    data.update(delta_r=sim["delta_r"], n=sim["n"])  # the logged commands
    write_csv(Track(sim.t, data, name=path.stem), Path("logs") / path.name)
    print(f"logs/{path.name}: {sim.n_samples} samples")
