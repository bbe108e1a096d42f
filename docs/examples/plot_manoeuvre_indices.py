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

ship = load_ship("kvlcc2_7m")
service = service_condition(ship)
speed, rpm = propulsion_point(ship, service["speed"])
options = TrialOptions(rudder_rate_deg_s=service["rudder_rate_deg_s"])

# %%
# The 10/10 zigzag (first to starboard: a negative rudder angle)
zz = simulate_trial(ship, "zigzag", -10.0, check_deg=10.0, speed=speed, rpm=rpm, options=options).track
ind = manoeuvre_indices(zz.t, zz["x"], zz["y"], zz["psi"], zz["delta_r"])
t, psi = zz.t, np.degrees(np.unwrap(zz["psi"]))
psi0 = float(np.interp(ind["executes_t_s"][0], t, psi))
heading = psi - psi0
fig, ax = plt.subplots(figsize=(8, 4))
ax.plot(t, heading, "k", lw=1.2, label="heading change (deg)")
ax.plot(t, np.degrees(zz["delta_r"]), "tab:blue", lw=1.0, label="rudder (deg, + port)")
ex = ind["executes_t_s"]
for k, te in enumerate(ex[:4]):
    ax.axvline(te, color="0.6", lw=0.8, ls=":")
    ax.text(te, 23 - 2.5 * k, f" execute {k + 1}", fontsize=7, va="top", color="0.3")
for k, name in ((1, "first"), (2, "second")):
    check = float(np.interp(ex[k], t, heading))
    seg = (t >= ex[k]) & (t <= (ex[k + 1] if k + 1 < len(ex) else t[-1]))
    j = np.flatnonzero(seg)[np.argmax(np.abs(heading[seg]))]
    ax.plot([ex[k], t[j]], [check, check], "tab:red", lw=0.8)
    ax.annotate(
        "",
        xy=(t[j], heading[j]),
        xytext=(t[j], check),
        arrowprops={"arrowstyle": "<->", "color": "tab:red"},
    )
    ax.text(
        t[j] + 1,
        (check + heading[j]) / 2,
        f"{name} overshoot\n{ind[f'{name}_overshoot_deg']:.1f} deg",
        fontsize=7,
        color="tab:red",
    )
ax.annotate(
    "",
    xy=(ex[1], -17),
    xytext=(ex[0], -17),
    arrowprops={"arrowstyle": "<->", "color": "tab:green"},
)
ax.text(ex[0], -19.5, f"initial turning time {ind['initial_turning_time_s']:.1f} s", fontsize=7, color="tab:green")
ax.set_xlim(0, ex[3] + 25 if len(ex) > 3 else t[-1])
ax.set_ylim(-22, 24)
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
ti = manoeuvre_indices(tc.t, tc["x"], tc["y"], tc["psi"], tc["delta_r"])
fig, ax = plt.subplots(figsize=(6, 6))
ax.plot(tc["y"], tc["x"], "k", lw=1.0, label="track (midship)")
k0 = int(np.searchsorted(tc.t, 10.0))  # the execute (trials.T_EXECUTE)
x0, y0 = tc["x"][k0], tc["y"][k0]
turned = np.degrees(np.abs(np.unwrap(tc["psi"]) - np.unwrap(tc["psi"])[k0]))
k90, k180 = int(np.argmax(turned >= 90.0)), int(np.argmax(turned >= 180.0))
ax.plot(y0, x0, "ko", ms=4)
ax.plot([y0, y0], [x0, tc["x"][k90] + 3], "0.6", lw=0.8, ls="--")  # the original course


def span(a, b, color, text, where):
    """A double arrow from a to b (y, x) labelled with text near ``where``."""
    ax.annotate("", xy=b, xytext=a, arrowprops={"arrowstyle": "<->", "color": color})
    ax.text(*where, text, fontsize=8, color=color, ha="center")


span(
    (y0 - 1.5, x0),
    (y0 - 1.5, tc["x"][k90]),
    "tab:blue",
    f"advance\n{ti['advance_m']:.1f} m",
    (y0 - 5, (x0 + tc["x"][k90]) / 2),
)
span(
    (y0, tc["x"][k90]),
    (tc["y"][k90], tc["x"][k90]),
    "tab:green",
    f"transfer {ti['transfer_m']:.1f} m",
    ((y0 + tc["y"][k90]) / 2, tc["x"][k90] + 0.8),
)
span(
    (y0, tc["x"][k180]),
    (tc["y"][k180], tc["x"][k180]),
    "tab:red",
    f"tactical diameter {ti['tactical_diameter_m']:.1f} m",
    ((y0 + tc["y"][k180]) / 2, tc["x"][k180] - 2.2),
)
ax.plot(tc["y"][[k90, k180]], tc["x"][[k90, k180]], "o", color="tab:red", ms=3)
ax.set_xlim(y0 - 9, None)
ax.set_aspect("equal")
ax.set_xlabel("y (east), m")
ax.set_ylabel("x (north), m")
ax.set_title(
    f"KVLCC2 model, 35 deg turn to starboard (90 and 180 deg of heading change marked);\n"
    f"steady turning diameter {ti['steady_turning_diameter_m']:.1f} m",
    fontsize=9,
)
ax.legend(fontsize=7, loc="lower right")
fig.tight_layout()
