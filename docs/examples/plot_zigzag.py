"""
A zigzag of NPS AUV II
======================

The packaged vehicle (Healey & Lienard 1993), a 20/20 zigzag closed on heading, simulated in the
horizontal plane (surge, sway, yaw; paper Sec. 4). One :class:`~bayesid.models.simulate.Simulator`
call flies several coefficient vectors at once: here the yaw damping ``Nr`` at its nominal value
and 30 % either side, on the same rudder history.
"""

import matplotlib.pyplot as plt
import numpy as np

from bayesid.data.vehicle import load_vehicle
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator

vehicle = load_vehicle("nps_auv2")
zigzag = mv.zigzag(vehicle, 20.0, duration=150.0)  # rudder 20 deg, reversed at 20 deg heading change
print(zigzag.description)

# %%
# Three coefficient vectors in one batched call
# ---------------------------------------------
# ``free`` names the coefficients :meth:`~bayesid.models.simulate.Simulator.run` sets per track;
# every other one keeps the vehicle file's value. The rudder history is the one the closed-loop
# zigzag applied to the nominal vehicle, replayed open loop as in a logged trial.
nr = vehicle.coefficients["Nr"]
sim = Simulator(vehicle, zigzag, free=["Nr"], mode="horizontal")
result = sim.run([[0.7 * nr], [nr], [1.3 * nr]])
print("status per track (0 = ok):", result.status)

fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
for b, label in enumerate(["Nr x 0.7", "Nr (nominal)", "Nr x 1.3"]):
    s = result.states[b]
    ax.plot(s[:, 1], s[:, 0], label=label)
    ax2.plot(result.t, np.degrees(s[:, 5]), label=label)
ax2.plot(result.t, np.degrees(result.inputs[:, 0]), "k:", lw=1, label="rudder delta_r")
ax.set(xlabel="y (east), m", ylabel="x (north), m", title="track")
ax.set_aspect("equal", adjustable="datalim")
ax2.set(xlabel="t, s", ylabel="deg", title="heading psi and rudder")
ax2.legend(fontsize=8)
fig.tight_layout()
plt.show()

# %%
# The first overshoot angle of each: weaker yaw damping overshoots more.
for b, label in enumerate(["Nr x 0.7", "Nr (nominal)", "Nr x 1.3"]):
    psi = np.degrees(result.states[b, :, 5])
    print(f"{label:13s} largest heading {np.max(np.abs(psi)):.1f} deg")

# %%
# Each row of the batch is an ordinary :class:`~bayesid.data.track.Track`, ready for
# :func:`bayesid.data.track.write_csv`:
track = result.track(1, name="zigzag20_nominal")
print(track)
