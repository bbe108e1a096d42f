"""
Manoeuvre indices by the ITTC definitions
=========================================

A 10/10 zigzag and a 35 deg turning circle of the packaged KVLCC2 model
(:func:`bayesid.models.ship.trials.simulate_trial`, from its service approach with the steering
gear's rate), with every index :func:`bayesid.estimation.indices.manoeuvre_indices` reads from them
marked where it is measured (ITTC Recommended Procedure 7.5-04-02-01, Sec. 2.2.1-2.2.2; IMO
MSC.137(76)):

* **zigzag**: the *executes* are the moments the rudder leaves a hold (the first: the order from
  the approach; each later one: the order to reverse, given when the heading reached the *check
  heading*). The *first* and *second overshoot* are how far the heading goes beyond the check
  heading at the 2nd and 3rd executes (not beyond the nominal angle: the rudder moves at a finite
  rate, so the check heading is already past it). *Initial turning time*: 1st to 2nd execute; *time
  to check yaw*: 2nd execute to the heading's extreme; *period*: 2nd to 4th execute.
* **turning circle**: from the execute, *advance* is the distance along the original course and
  *transfer* the distance normal to it where the heading has changed by 90 deg; *tactical diameter*
  the normal distance at 180 deg; *steady turning diameter* the diameter of the circle fitted to
  the track after 180 deg.
"""

import matplotlib.pyplot as plt
import numpy as np

from bayesid.estimation.indices import manoeuvre_indices
from bayesid.models.ship import load_ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, service_condition, simulate_trial
from bayesid.report.plots import mark_indices

ship = load_ship("kvlcc2_7m")
service = service_condition(ship)
speed, rpm = propulsion_point(ship, service["speed"])
options = TrialOptions(rudder_rate_deg_s=service["rudder_rate_deg_s"])

# %%
# The 10/10 zigzag (first to starboard: a negative rudder angle). The heading is drawn as the
# change from the original course, so the run is given to
# :func:`bayesid.report.plots.mark_indices` with its heading offset the same way (the indices do
# not change: they are heading differences).
zz = simulate_trial(ship, "zigzag", -10.0, check_deg=10.0, speed=speed, rpm=rpm, options=options).track
ind = manoeuvre_indices(zz.t, zz["x"], zz["y"], zz["psi"], zz["delta_r"])
psi = np.unwrap(zz["psi"])
change = psi - float(np.interp(ind["executes_t_s"][0], zz.t, psi))
fig, ax = plt.subplots(figsize=(8, 4))
ax.plot(zz.t, np.degrees(change), "k", lw=1.2, label="heading change (deg)")
ax.plot(zz.t, np.degrees(zz["delta_r"]), "tab:blue", lw=1.0, label="rudder (deg, + port)")
run = {"x": zz["x"], "y": zz["y"], "psi": change, "delta_r": zz["delta_r"]}
mark_indices(None, ax, zz.t, run, indices=ind)
ex = ind["executes_t_s"]
ax.set_xlim(0, ex[3] + 25 if len(ex) > 3 else zz.t[-1])
ax.set_xlabel("t (s)")
ax.set_title(
    f"KVLCC2 model, 10/10 zigzag: period {ind['period_s']:.1f} s, time to check yaw {ind['time_to_check_yaw_s']:.1f} s",
    fontsize=9,
)
ax.legend(fontsize=7, loc="lower right")
fig.tight_layout()

# %%
# The 35 deg turning circle to starboard
tc = simulate_trial(ship, "turn", -35.0, speed=speed, rpm=rpm, options=options).track
fig, ax = plt.subplots(figsize=(6, 6))
ax.plot(tc["y"], tc["x"], "k", lw=1.0, label="track (midship)")
ti = mark_indices(ax, None, tc.t, tc)
ax.set_aspect("equal", adjustable="datalim")
ax.set_xlabel("y (east), m")
ax.set_ylabel("x (north), m")
ax.set_title(
    "KVLCC2 model, 35 deg turn to starboard\n(90 and 180 deg of heading change marked);\n"
    f"steady turning diameter {ti['steady_turning_diameter_m']:.1f} m",
    fontsize=9,
)
ax.legend(fontsize=7, loc="lower right")
fig.tight_layout()
