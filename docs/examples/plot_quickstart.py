"""
Quickstart: tracks, fit, predict
================================

The Python API in fewer than fifteen lines (:doc:`../quickstart`): two noisy zigzags of NPS AUV II to fit
six linear sway and yaw coefficients on, a turning circle held out and predicted under the window
protocol. With your own data, load the tracks with ``bayesid.read_csv`` and your vehicle file by its path.
"""

import numpy as np

import bayesid
from bayesid.models import manoeuvres as mv
from bayesid.models.world import world_track

vehicle = bayesid.load_any_vehicle("nps_auv2")  # a packaged id, or the path of your vehicle (or ship) TOML
rng = np.random.default_rng(0)  # tracks: simulated with navigation noise, or bayesid.read_csv("run.csv")
train = [world_track(vehicle, mv.zigzag(vehicle, angle), {}, rng) for angle in (10.0, 20.0)]
heldout = [world_track(vehicle, mv.turning_circle(vehicle, 15.0), {}, rng)]
res = bayesid.identify(vehicle, train, bayesid.FitOptions(free=("Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"), dt=0.1))
for name, value, sd in zip(res.model.param_names, res.fit.x, np.sqrt(np.diag(res.cov))):
    print(f"{name:4s} identified {value:+.5f} +- {sd:.5f}   vehicle file {vehicle.coefficients[name]:+.5f}")
scores = bayesid.predict(res.model, res.fit.x, heldout, window_s=30.0).pooled  # over 30 s windows
print(f"held-out turn: RMS position {scores['rms_position_m']:.3f} m, heading {scores['rms_heading_deg']:.2f} deg")
