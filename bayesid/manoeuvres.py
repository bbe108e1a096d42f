"""Input time histories: the paper's spiral, turning circles and heading-triggered zigzags.

Every generator returns a :class:`~bayesid.simulate.Manoeuvre` on the integration grid, starts
from the steady straight-line state at the chosen propeller speed, and checks the vehicle's
control limits. Sign convention: positive ``delta_r`` turns NPS AUV II to port (r < 0), because
Y'dr > 0 and N'dr < 0.
"""
from __future__ import annotations

import math

import numpy as np

from . import dynamics
from .simulate import Manoeuvre, Simulator


def steady_state(vehicle, rpm: float | None = None) -> np.ndarray:
    """Straight, level state at the steady speed for ``rpm`` (default: nominal), (12,)."""
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    s = np.zeros(12)
    s[6] = vehicle.steady_speed(rpm)
    return s


def _grid(duration: float, dt: float) -> int:
    n = int(round(duration / dt))
    if n < 1 or abs(n * dt - duration) > 1e-9 * max(1.0, duration):
        raise ValueError(f"duration {duration} s is not a whole number of steps of {dt} s")
    return n


def _finish(vehicle, name, dt, inputs, rpm, description, params) -> Manoeuvre:
    vehicle.limits.check(inputs, where=f"manoeuvre {name}")
    return Manoeuvre(name, dt, inputs, steady_state(vehicle, rpm), description, params)


def spiral(vehicle, dt: float = 0.1, duration: float = 600.0, rpm: float | None = None,
           t_straight: float = 30.0, rudder_steps_deg=(2, 4, 6, 8, 10, 12, 14, 16, 18, 20)) -> Manoeuvre:
    """The paper's 10-minute spiral-type manoeuvre (Furlong et al. 2003, Fig. 1).

    The paper gives no sequence; ours: constant propeller speed; straight for ``t_straight`` s,
    then the rudder is stepped to each angle of ``rudder_steps_deg`` in turn, holding each for an
    equal share of the remaining time (57 s each for the defaults). Each step tightens the turn,
    so the track is an inward spiral. Rudder steps are instantaneous (zero-order hold).
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    n = _grid(duration, dt)
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    t = np.arange(n) * dt
    hold = (duration - t_straight) / len(rudder_steps_deg)
    for i, a in enumerate(rudder_steps_deg):
        inputs[t >= t_straight + i * hold - 1e-9, 0] = math.radians(a)
    desc = (f"Spiral: {rpm:g} rpm throughout; rudder 0 for {t_straight:g} s, then stepped to "
            f"{', '.join(f'{a:g}' for a in rudder_steps_deg)} deg, each held {hold:g} s; "
            f"{duration:g} s, dt {dt:g} s.")
    return _finish(vehicle, "spiral", dt, inputs, rpm, desc,
                   dict(dt=dt, duration=duration, rpm=rpm, t_straight=t_straight,
                        rudder_steps_deg=list(rudder_steps_deg), hold_s=hold))


def turning_circle(vehicle, rudder_deg: float = 20.0, dt: float = 0.1, duration: float = 150.0,
                   rpm: float | None = None, t_execute: float = 10.0) -> Manoeuvre:
    """Turning circle: straight approach, then the rudder stepped to ``rudder_deg`` and held."""
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    n = _grid(duration, dt)
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    inputs[np.arange(n) * dt >= t_execute - 1e-9, 0] = math.radians(rudder_deg)
    name = f"turn{rudder_deg:+g}".replace("+", "p").replace("-", "m")
    desc = (f"Turning circle: {rpm:g} rpm; straight {t_execute:g} s, then rudder {rudder_deg:g} deg "
            f"held to {duration:g} s; dt {dt:g} s.")
    return _finish(vehicle, name, dt, inputs, rpm, desc,
                   dict(rudder_deg=rudder_deg, dt=dt, duration=duration, rpm=rpm, t_execute=t_execute))


def zigzag(vehicle, rudder_deg: float = 10.0, heading_deg: float | None = None, dt: float = 0.1,
           duration: float = 120.0, rpm: float | None = None, t_execute: float = 10.0,
           first_sign: int = 1, rudder_rate_deg_s: float = 0.0) -> Manoeuvre:
    """Horizontal zigzag (Z-manoeuvre) ``rudder_deg/heading_deg`` triggered on heading.

    ITTC 7.5-04-02-01: after a straight approach the rudder is put to ``rudder_deg``; when the
    heading has changed by ``heading_deg`` from the execute heading the rudder is reversed; when it
    has changed by ``heading_deg`` to the other side it is reversed again, and so on. The trigger
    needs the vehicle's response, so this runs the closed loop with the given vehicle (the
    "truth") and returns the rudder history it applied; identification then replays that history
    open loop, as with a logged trial.

    Parameters
    ----------
    rudder_rate_deg_s : rudder rate limit; 0 = instantaneous reversal (NPS AUV II has no
        published rate; its 0.1 s actuator time constant makes reversals nearly instantaneous).

    Raises
    ------
    RuntimeError if the closed-loop simulation diverges.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    heading_deg = rudder_deg if heading_deg is None else heading_deg
    n = _grid(duration, dt)
    sim = Simulator(vehicle, Manoeuvre("zigzag-probe", dt, np.zeros((1, 4)), steady_state(vehicle, rpm)))
    tcoef, Minv = (a[0] for a in sim.kernel_arrays())
    out = np.empty((n + 1, 12))
    inputs = np.empty((n, 4))
    turn_sign = math.copysign(1.0, vehicle.coefficients.get("Ndr", -1.0))
    flag = dynamics.simulate_zigzag(sim.s0, n, dt, float(rpm), math.radians(rudder_deg),
                                    math.radians(heading_deg), float(first_sign), turn_sign,
                                    t_execute, math.radians(rudder_rate_deg_s), sim.vp, sim.tfac,
                                    sim.tdof, tcoef, Minv, sim.xs, sim.ws, out, inputs)
    if flag != dynamics.OK:
        raise RuntimeError(f"zigzag {rudder_deg}/{heading_deg}: closed-loop simulation diverged")
    name = f"zigzag{rudder_deg:g}_{heading_deg:g}" + ("" if first_sign > 0 else "m")
    switches = np.flatnonzero(np.diff(np.sign(inputs[:, 0])) != 0) + 1
    desc = (f"Zigzag {rudder_deg:g}/{heading_deg:g}: {rpm:g} rpm; straight {t_execute:g} s, then rudder "
            f"{first_sign * rudder_deg:+g} deg, reversed each time the heading change reaches "
            f"{heading_deg:g} deg (closed loop on the true vehicle); {len(switches)} rudder changes in "
            f"{duration:g} s; rudder rate {'instantaneous' if rudder_rate_deg_s <= 0 else f'{rudder_rate_deg_s:g} deg/s'}; "
            f"dt {dt:g} s.")
    return _finish(vehicle, name, dt, inputs, rpm, desc,
                   dict(rudder_deg=rudder_deg, heading_deg=heading_deg, dt=dt, duration=duration,
                        rpm=rpm, t_execute=t_execute, first_sign=first_sign,
                        rudder_rate_deg_s=rudder_rate_deg_s,
                        switch_times_s=[float(k * dt) for k in switches]))


def straight(vehicle, dt: float = 0.1, duration: float = 60.0, rpm: float | None = None) -> Manoeuvre:
    """Straight run at constant propeller speed, zero control deflections."""
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    n = _grid(duration, dt)
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    return _finish(vehicle, "straight", dt, inputs, rpm, f"Straight run, {rpm:g} rpm, {duration:g} s.",
                   dict(dt=dt, duration=duration, rpm=rpm))


__all__ = ["steady_state", "spiral", "turning_circle", "zigzag", "straight"]
