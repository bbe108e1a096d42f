"""
A small gap diagnosis
=====================

"World" tracks of NPS AUV II are made with an ocean current the model does not have
(:func:`bayesid.models.world.world_track`: the true vehicle, the effect switched on, navigation
noise on every state). The base model -- three free coefficients, fitted on two training tracks --
is then diagnosed on a held-out track against three candidate effects. The current should come
out as the cause: added, it brings the held-out error down to the noise floor.
"""

import matplotlib.pyplot as plt
import numpy as np

from bayesid.analysis.gap import DiagnoseOptions, diagnose
from bayesid.data.vehicle import load_vehicle
from bayesid.models import manoeuvres as mv
from bayesid.models.world import world_track

vehicle = load_vehicle("nps_auv2")
rng = np.random.default_rng(5)
world = {"current": {"current_north_mps": 0.15, "current_east_mps": -0.1}}
zigzag20 = mv.zigzag(vehicle, 20.0, duration=150.0)
turn20 = mv.turning_circle(vehicle, 20.0, duration=150.0)
zigzag10 = mv.zigzag(vehicle, 10.0, duration=150.0, first_sign=-1)
train = [
    world_track(vehicle, zigzag20, world, rng, name="zigzag20"),
    world_track(vehicle, turn20, world, rng, name="turn20"),
]
heldout = [world_track(vehicle, zigzag10, world, rng, name="zigzag10")]

# %%
# The diagnosis
# -------------
d = diagnose(
    vehicle,
    ["Yv", "Nr", "Ndr"],
    train,
    heldout,
    DiagnoseOptions(candidates=["current", "thrust", "delay"], window_s=60.0, max_nfev=30, max_effects=1),
    rng=np.random.default_rng(0),
)
print(f"verdict: {d.verdict}")
print(
    f"held-out RMS position error {d.gap_before['heldout_rms_m']:.3f} m"
    f" -> {d.gap_after['heldout_rms_m']:.3f} m;"
    f" noise floor {d.noise_floor['heldout_rms_m']:.3f} m"
)
for row in d.ranking:
    print(
        f"{row['effect']:8s} held-out {row['heldout_rms_m']:.3f} m, dBIC {row['delta_bic']:11.1f}, role {row['role']}"
    )

# %%
# The fitted current against the one the world had: the diagnosis never saw the truth.
print("fitted:", d.ranking[0]["parameters"], " world:", world["current"])

fig, ax = plt.subplots(figsize=(6, 3.5))
names = [r["effect"] for r in d.ranking]
ax.barh(names, [r["heldout_rms_m"] for r in d.ranking], color="tab:blue")
ax.axvline(d.gap_before["heldout_rms_m"], color="k", ls="--", label="base model")
ax.axvline(d.noise_floor["heldout_rms_m"], color="tab:green", ls=":", label="noise floor")
ax.set(xlabel="held-out RMS position error, m", title=f"verdict: {d.verdict}")
ax.invert_yaxis()
ax.legend(fontsize=8)
fig.tight_layout()
plt.show()
