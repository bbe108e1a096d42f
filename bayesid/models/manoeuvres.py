"""Input time histories: the paper's spiral, turning circles and heading-triggered zigzags, and a
wider library for manoeuvre-richness comparison (pull-out, reverse spiral, speed steps, multisine,
PRBS, vertical zigzag; :func:`library` builds the standard set).

Every generator returns a :class:`~bayesid.models.simulate.Manoeuvre` on the integration grid, starts
from the steady straight-line state at the chosen propeller speed, and checks the vehicle's
control limits. Sign convention: positive ``delta_r`` turns NPS AUV II to port (r < 0), because
Y'dr > 0 and N'dr < 0; positive ``delta_s`` pitches it nose down (theta decreasing), because
M'ds < 0. Closed-loop manoeuvres (zigzags, reverse spiral) run the loop on the given vehicle (the
"truth", 6-DOF) and return the inputs it applied; identification replays them open loop.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from . import dynamics
from .simulate import Manoeuvre, Simulator


@dataclass(frozen=True)
class ZigzagOptions:
    """How a zigzag's commands are executed (:func:`zigzag`, :func:`vertical_zigzag`).

    Parameters
    ----------
    t_execute : float, default 10.0
        Time of the first command, s.
    rate_deg_s : float, default 0.0
        Rate limit of the control surface (the rudder of :func:`zigzag`, the stern planes of
        :func:`vertical_zigzag`), deg/s; 0 = instantaneous reversal (NPS AUV II has no published
        rate; its 0.1 s actuator time constant makes reversals nearly instantaneous).
    """

    t_execute: float = 10.0
    rate_deg_s: float = 0.0


@dataclass(frozen=True)
class ReverseSpiralOptions:
    """The approach and the yaw-rate controller of a reverse spiral (:func:`reverse_spiral`).

    Parameters
    ----------
    t_straight : float, default 10.0
        Straight approach, s.
    kp : float, default 4.0
        Proportional gain, rad rudder per rad/s (s).
    ki : float, default 2.0
        Integral gain, rad rudder per rad.
    rudder_rate_deg_s : float, default 0.0
        Rudder rate limit, deg/s (0 = instantaneous).
    rudder_max_deg : float, optional
        Saturation of the rudder, deg, in (0, the vehicle's limit]; default the limit.
    """

    t_straight: float = 10.0
    kp: float = 4.0
    ki: float = 2.0
    rudder_rate_deg_s: float = 0.0
    rudder_max_deg: float | None = None


@dataclass(frozen=True)
class MultisineOptions:
    """A multisine's phases, relative amplitudes and start (:func:`multisine`).

    Parameters
    ----------
    phases_rad : sequence of float, optional
        The phases of the sines, rad; default Schroeder phases (:func:`schroeder_phases`).
    weights : sequence of float, optional
        Their relative amplitudes ``w_k``; default 1 each.
    t_execute : float, default 10.0
        Start of the signal, s.
    """

    phases_rad: object = None
    weights: object = None
    t_execute: float = 10.0


@dataclass(frozen=True)
class PrbsOptions:
    """The clock and start of a PRBS (:func:`prbs`).

    Parameters
    ----------
    min_hold_s : float, default 5.0
        Clock period, s; at least one step.
    p_switch : float, default 0.5
        Probability of a sign flip per clock tick, in [0, 1].
    t_execute : float, default 10.0
        Start of the sequence, s.
    """

    min_hold_s: float = 5.0
    p_switch: float = 0.5
    t_execute: float = 10.0


def steady_state(vehicle, rpm: float | None = None) -> np.ndarray:
    """Straight, level state at the steady speed for a propeller speed.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.

    Returns
    -------
    ndarray, shape (12,)
        The state (only ``u`` non-zero).
    """
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


def _closed_loop(vehicle, rpm, dt, n):
    """What the closed-loop kernels need for the vehicle as it is (6-DOF): the prepared
    :class:`Simulator`, its kernel arrays for B = 1, and empty state/input buffers."""
    sim = Simulator(vehicle, Manoeuvre("closed-loop-probe", dt, np.zeros((1, 4)), steady_state(vehicle, rpm)))
    tcoef, Minv = (a[0] for a in sim.kernel_arrays())
    return sim, tcoef, Minv, np.empty((n + 1, 12)), np.empty((n, 4))


def _triggered_zigzag(
    vehicle,
    rpm,
    dt,
    n,
    i_input,
    i_state,
    delta_deg,
    trigger_deg,
    first_sign,
    response_sign,
    t_execute,
    rate_deg_s,
    what,
) -> np.ndarray:
    """Run :func:`bayesid.models.dynamics.simulate_triggered_zigzag`; the applied inputs (n, 4)."""
    sim, tcoef, Minv, out, inputs = _closed_loop(vehicle, rpm, dt, n)
    flag = dynamics.simulate_triggered_zigzag(
        sim.s0,
        n,
        dt,
        float(rpm),
        i_input,
        i_state,
        math.radians(delta_deg),
        math.radians(trigger_deg),
        float(first_sign),
        response_sign,
        t_execute,
        math.radians(rate_deg_s),
        sim.vp,
        sim.tfac,
        sim.tdof,
        tcoef,
        Minv,
        sim.xs,
        sim.ws,
        out,
        inputs,
    )
    if flag != dynamics.OK:
        raise RuntimeError(f"{what}: closed-loop simulation diverged")
    return inputs


def _steps(t_edges, dt) -> list[int]:
    """Grid indices of segment boundaries (s); each must be a whole number of steps."""
    ks = []
    for te in t_edges:
        k = int(round(te / dt))
        if k < 0 or abs(k * dt - te) > 1e-9 * max(1.0, abs(te)):
            raise ValueError(f"time {te} s is not a whole number of steps of {dt} s")
        ks.append(k)
    return ks


def _name_signed(prefix: str, value: float) -> str:
    """``turnp20`` / ``turnm20`` style name (as :func:`turning_circle`)."""
    return f"{prefix}{value:+g}".replace("+", "p").replace("-", "m")


def spiral(
    vehicle,
    dt: float = 0.1,
    duration: float = 600.0,
    rpm: float | None = None,
    t_straight: float = 30.0,
    rudder_steps_deg=(2, 4, 6, 8, 10, 12, 14, 16, 18, 20),
) -> Manoeuvre:
    """The paper's 10-minute spiral-type manoeuvre (Furlong et al. 2003, Fig. 1).

    The paper gives no sequence; ours: constant propeller speed; straight for ``t_straight`` s,
    then the rudder is stepped to each angle of ``rudder_steps_deg`` in turn, holding each for an
    equal share of the remaining time (57 s each for the defaults). Each step tightens the turn,
    so the track is an inward spiral. Rudder steps are instantaneous (zero-order hold).

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle (start state and control limits).
    dt : float, default 0.1
        Integration step, s.
    duration : float, default 600.0
        Length of the run, s; a whole number of steps.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.
    t_straight : float, default 30.0
        Straight approach, s.
    rudder_steps_deg : sequence of float, default (2, 4, ..., 20)
        The rudder angles in turn, deg.

    Returns
    -------
    Manoeuvre
        Named ``"spiral"``.

    Raises
    ------
    ValueError
        A duration that is not a whole number of steps, or inputs beyond the vehicle's limits.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    n = _grid(duration, dt)
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    t = np.arange(n) * dt
    hold = (duration - t_straight) / len(rudder_steps_deg)
    for i, a in enumerate(rudder_steps_deg):
        inputs[t >= t_straight + i * hold - 1e-9, 0] = math.radians(a)
    desc = (
        f"Spiral: {rpm:g} rpm throughout; rudder 0 for {t_straight:g} s, then stepped to "
        f"{', '.join(f'{a:g}' for a in rudder_steps_deg)} deg, each held {hold:g} s; "
        f"{duration:g} s, dt {dt:g} s."
    )
    return _finish(
        vehicle,
        "spiral",
        dt,
        inputs,
        rpm,
        desc,
        dict(
            dt=dt,
            duration=duration,
            rpm=rpm,
            t_straight=t_straight,
            rudder_steps_deg=list(rudder_steps_deg),
            hold_s=hold,
        ),
    )


def turning_circle(
    vehicle,
    rudder_deg: float = 20.0,
    dt: float = 0.1,
    duration: float = 150.0,
    rpm: float | None = None,
    t_execute: float = 10.0,
) -> Manoeuvre:
    """Turning circle: straight approach, then the rudder stepped to ``rudder_deg`` and held.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle (start state and control limits).
    rudder_deg : float, default 20.0
        Rudder angle, deg.
    dt : float, default 0.1
        Integration step, s.
    duration : float, default 150.0
        Length of the run, s; a whole number of steps.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.
    t_execute : float, default 10.0
        Time of the rudder step, s.

    Returns
    -------
    Manoeuvre
        Named ``turnp20`` / ``turnm20`` style after the rudder angle.

    Raises
    ------
    ValueError
        A duration that is not a whole number of steps, or inputs beyond the vehicle's limits.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    n = _grid(duration, dt)
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    inputs[np.arange(n) * dt >= t_execute - 1e-9, 0] = math.radians(rudder_deg)
    name = f"turn{rudder_deg:+g}".replace("+", "p").replace("-", "m")
    desc = (
        f"Turning circle: {rpm:g} rpm; straight {t_execute:g} s, then rudder {rudder_deg:g} deg "
        f"held to {duration:g} s; dt {dt:g} s."
    )
    return _finish(
        vehicle,
        name,
        dt,
        inputs,
        rpm,
        desc,
        dict(rudder_deg=rudder_deg, dt=dt, duration=duration, rpm=rpm, t_execute=t_execute),
    )


def zigzag(
    vehicle,
    rudder_deg: float = 10.0,
    heading_deg: float | None = None,
    *,
    dt: float = 0.1,
    duration: float = 120.0,
    rpm: float | None = None,
    first_sign: int = 1,
    options: ZigzagOptions = ZigzagOptions(),
) -> Manoeuvre:
    """Horizontal zigzag (Z-manoeuvre) ``rudder_deg/heading_deg`` triggered on heading.

    ITTC 7.5-04-02-01: after a straight approach the rudder is put to ``rudder_deg``; when the
    heading has changed by ``heading_deg`` from the execute heading the rudder is reversed; when it
    has changed by ``heading_deg`` to the other side it is reversed again, and so on. The trigger
    needs the vehicle's response, so this runs the closed loop with the given vehicle (the
    "truth") and returns the rudder history it applied; identification then replays that history
    open loop, as with a logged trial.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle, the "truth" of the closed loop (6-DOF).
    rudder_deg : float, default 10.0
        Rudder angle, deg.
    heading_deg : float, optional
        Heading change that reverses the rudder, deg; default ``rudder_deg``.
    dt : float, default 0.1
        Integration step, s.
    duration : float, default 120.0
        Length of the run, s; a whole number of steps.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.
    first_sign : int, default 1
        Sign of the first rudder command (the name gets an ``m`` suffix for -1).
    options : ZigzagOptions, default ZigzagOptions()
        The time of the first rudder command (``t_execute``, s) and the rudder rate limit
        (``rate_deg_s``, deg/s; 0 = instantaneous).

    Returns
    -------
    Manoeuvre
        Named ``zigzag10_10`` style; ``parameters`` records the switch times.

    Raises
    ------
    RuntimeError
        If the closed-loop simulation diverges.
    ValueError
        A duration that is not a whole number of steps, or inputs beyond the vehicle's limits.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    heading_deg = rudder_deg if heading_deg is None else heading_deg
    t_execute, rudder_rate_deg_s = options.t_execute, options.rate_deg_s
    n = _grid(duration, dt)
    turn_sign = math.copysign(1.0, vehicle.coefficients.get("Ndr", -1.0))
    inputs = _triggered_zigzag(
        vehicle,
        rpm,
        dt,
        n,
        0,
        5,
        rudder_deg,
        heading_deg,
        first_sign,
        turn_sign,
        t_execute,
        rudder_rate_deg_s,
        f"zigzag {rudder_deg}/{heading_deg}",
    )
    name = f"zigzag{rudder_deg:g}_{heading_deg:g}" + ("" if first_sign > 0 else "m")
    switches = np.flatnonzero(np.diff(np.sign(inputs[:, 0])) != 0) + 1
    desc = (
        f"Zigzag {rudder_deg:g}/{heading_deg:g}: {rpm:g} rpm; straight {t_execute:g} s, then rudder "
        f"{first_sign * rudder_deg:+g} deg, reversed each time the heading change reaches "
        f"{heading_deg:g} deg (closed loop on the true vehicle); {len(switches)} rudder changes in "
        f"{duration:g} s; rudder rate {'instantaneous' if rudder_rate_deg_s <= 0 else f'{rudder_rate_deg_s:g} deg/s'}; "
        f"dt {dt:g} s."
    )
    return _finish(
        vehicle,
        name,
        dt,
        inputs,
        rpm,
        desc,
        dict(
            rudder_deg=rudder_deg,
            heading_deg=heading_deg,
            dt=dt,
            duration=duration,
            rpm=rpm,
            t_execute=t_execute,
            first_sign=first_sign,
            rudder_rate_deg_s=rudder_rate_deg_s,
            switch_times_s=[float(k * dt) for k in switches],
        ),
    )


def straight(vehicle, dt: float = 0.1, duration: float = 60.0, rpm: float | None = None) -> Manoeuvre:
    """Straight run at constant propeller speed, zero control deflections.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.
    dt : float, default 0.1
        Integration step, s.
    duration : float, default 60.0
        Length of the run, s; a whole number of steps.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.

    Returns
    -------
    Manoeuvre
        Named ``"straight"``.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    n = _grid(duration, dt)
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    return _finish(
        vehicle,
        "straight",
        dt,
        inputs,
        rpm,
        f"Straight run, {rpm:g} rpm, {duration:g} s.",
        dict(dt=dt, duration=duration, rpm=rpm),
    )


def pull_out(
    vehicle,
    rudder_deg: float = 20.0,
    t_execute: float = 10.0,
    t_hold: float = 60.0,
    duration: float = 180.0,
    dt: float = 0.1,
    rpm: float | None = None,
) -> Manoeuvre:
    """Pull-out test (ITTC 7.5-04-02-01, Sec. 2.2.6 "Pullout Test").

    Sequence: constant propeller speed ``rpm`` (default nominal) throughout; rudder 0 for
    ``t_execute`` s; rudder stepped to ``rudder_deg`` (deg) and held for ``t_hold`` s, long enough
    for a near-steady turn (NPS AUV II, 20 deg, 60 s: yaw rate within ~2 % of its steady value); at
    ``t_execute + t_hold`` returned to 0 (instantaneous step) and held to ``duration`` s. Afterwards
    the yaw rate decays to zero if the vehicle is directionally stable and to a residual rate if not
    (ITTC: run to both sides; call twice with opposite signs).

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.
    rudder_deg : float, default 20.0
        Rudder angle of the turn, deg.
    t_execute : float, default 10.0
        Time of the rudder step, s.
    t_hold : float, default 60.0
        How long the rudder is held, s.
    duration : float, default 180.0
        Length of the run, s.
    dt : float, default 0.1
        Integration step, s.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.

    Returns
    -------
    Manoeuvre
        Named ``pull_outp20`` / ``pull_outm20``.

    Raises
    ------
    ValueError
        Times that are not whole numbers of steps or not ``0 <= t_execute <= t_execute + t_hold <
        duration``; inputs beyond the vehicle's limits.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    n = _grid(duration, dt)
    k_on, k_off = _steps((t_execute, t_execute + t_hold), dt)
    if not 0 <= k_on <= k_off < n:
        raise ValueError(
            f"pull-out: need 0 <= t_execute <= t_execute + t_hold < duration ({t_execute}, {t_hold}, {duration})"
        )
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    inputs[k_on:k_off, 0] = math.radians(rudder_deg)
    desc = (
        f"Pull-out (ITTC 7.5-04-02-01): {rpm:g} rpm; rudder 0 for {t_execute:g} s, {rudder_deg:g} deg "
        f"for {t_hold:g} s (steady turn), then 0 to {duration:g} s; dt {dt:g} s."
    )
    return _finish(
        vehicle,
        _name_signed("pull_out", rudder_deg),
        dt,
        inputs,
        rpm,
        desc,
        dict(
            rudder_deg=rudder_deg,
            t_execute=t_execute,
            t_hold=t_hold,
            duration=duration,
            dt=dt,
            rpm=rpm,
            t_release=t_execute + t_hold,
        ),
    )


def reverse_spiral(
    vehicle,
    yaw_rates_deg_s=(4.0, 3.0, 2.0, 1.0, 0.5, 0.0, -0.5, -1.0, -2.0, -3.0, -4.0),
    hold_s: float = 30.0,
    *,
    dt: float = 0.1,
    rpm: float | None = None,
    options: ReverseSpiralOptions = ReverseSpiralOptions(),
) -> Manoeuvre:
    """Bech's reverse spiral (ITTC 7.5-04-02-01, Sec. 2.2.5 "Spiral Manoeuvre", reverse form).

    Sequence: constant propeller speed ``rpm``; rudder 0 for ``t_straight`` s; then a closed-loop
    controller holds each body yaw rate r of ``yaw_rates_deg_s`` (deg/s; positive = starboard turn)
    for ``hold_s`` s in turn, and the rudder it applied is recorded (the manoeuvre's inputs).
    Duration ``t_straight + len(yaw_rates_deg_s) * hold_s`` (340 s for the defaults). The steady
    (r, delta_r) pairs trace the r-delta curve, including its unstable branch for a directionally
    unstable vehicle, where the direct spiral jumps.

    Controller (:func:`bayesid.models.dynamics.simulate_pi_hold`, run 6-DOF on the given vehicle): PI
    on the yaw-rate error, ``delta_r = sign(N'dr) * (kp*e + ki*integral(e dt))`` with
    ``e = r_target - r``, ``kp`` in rad rudder per rad/s (s), ``ki`` in rad rudder per rad;
    saturated at ``rudder_max_deg`` (default: the vehicle's limit), conditional-integration
    anti-windup, rudder rate limit ``rudder_rate_deg_s`` (0 = instantaneous), measured r at the
    start of each step, zero-order hold. Defaults tuned for NPS AUV II at 1500 rpm (Nomoto K ~
    0.4 1/s, T ~ 3 s; closed-loop poles ~ -0.43 +- 0.28j 1/s: r within 0.1 deg/s of each target
    after <= 5 s, steady error < 0.03 deg/s), integrator carried over between targets.
    ``parameters`` records, per target, the mean rudder and yaw rate over the last third of its
    hold (``steady_rudder_deg``, ``steady_yaw_rate_deg_s``) and whether the rudder saturated there.
    Yaw rates needing more rudder than the limit are not held (NPS AUV II: |r| < ~4.5 deg/s).

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle, the "truth" of the closed loop (6-DOF).
    yaw_rates_deg_s : sequence of float, default (4, 3, 2, 1, 0.5, 0, -0.5, -1, -2, -3, -4)
        Target yaw rates in turn, deg/s (positive = starboard turn).
    hold_s : float, default 30.0
        How long each target is held, s.
    dt : float, default 0.1
        Integration step, s.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.
    options : ReverseSpiralOptions, default ReverseSpiralOptions()
        The straight approach ``t_straight`` (s), the gains ``kp`` and ``ki``, the rudder rate
        limit ``rudder_rate_deg_s`` and saturation ``rudder_max_deg`` (deg).

    Returns
    -------
    Manoeuvre
        Named ``"reverse_spiral"``; ``parameters`` as above.

    Raises
    ------
    RuntimeError
        If the closed-loop simulation diverges.
    ValueError
        No targets, a rudder limit outside (0, the vehicle's limit], times that are not whole
        numbers of steps.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    t_straight, kp, ki = options.t_straight, options.kp, options.ki
    rudder_rate_deg_s, rudder_max_deg = options.rudder_rate_deg_s, options.rudder_max_deg
    rates = [float(x) for x in yaw_rates_deg_s]
    if not rates:
        raise ValueError("reverse spiral: no target yaw rates")
    lim_deg = math.degrees(vehicle.limits.rudder_max)
    rudder_max_deg = lim_deg if rudder_max_deg is None else float(rudder_max_deg)
    if not 0.0 < rudder_max_deg <= lim_deg + 1e-9:
        raise ValueError(f"reverse spiral: rudder_max_deg {rudder_max_deg} outside (0, {lim_deg:g}]")
    duration = t_straight + len(rates) * hold_s
    n = _grid(duration, dt)
    edges = _steps([t_straight + i * hold_s for i in range(len(rates) + 1)], dt)
    ref = np.full(n, np.nan)
    for i, r in enumerate(rates):
        ref[edges[i] : edges[i + 1]] = math.radians(r)
    sign = math.copysign(1.0, vehicle.coefficients.get("Ndr", -1.0))
    sim, tcoef, Minv, out, inputs = _closed_loop(vehicle, rpm, dt, n)
    flag = dynamics.simulate_pi_hold(
        sim.s0,
        n,
        dt,
        float(rpm),
        0,
        11,
        ref,
        float(kp),
        float(ki),
        sign,
        math.radians(rudder_max_deg),
        math.radians(rudder_rate_deg_s),
        sim.vp,
        sim.tfac,
        sim.tdof,
        tcoef,
        Minv,
        sim.xs,
        sim.ws,
        out,
        inputs,
    )
    if flag != dynamics.OK:
        raise RuntimeError("reverse spiral: closed-loop simulation diverged")
    steady_d, steady_r, sat = [], [], []
    for i in range(len(rates)):
        a, b = edges[i + 1] - (edges[i + 1] - edges[i]) // 3, edges[i + 1]
        steady_d.append(float(np.degrees(inputs[a:b, 0].mean())))
        steady_r.append(float(np.degrees(out[a + 1 : b + 1, 11].mean())))
        sat.append(bool(np.any(np.abs(inputs[a:b, 0]) >= math.radians(rudder_max_deg) - 1e-12)))
    desc = (
        f"Reverse spiral (Bech; ITTC 7.5-04-02-01): {rpm:g} rpm; rudder 0 for {t_straight:g} s, then a "
        f"PI yaw-rate controller (kp {kp:g} s, ki {ki:g}, rudder limit {rudder_max_deg:g} deg, rate "
        f"{'instantaneous' if rudder_rate_deg_s <= 0 else f'{rudder_rate_deg_s:g} deg/s'}) holds r = "
        f"{', '.join(f'{r:g}' for r in rates)} deg/s, {hold_s:g} s each (closed loop on the true "
        f"vehicle, applied rudder recorded); {duration:g} s, dt {dt:g} s."
    )
    return _finish(
        vehicle,
        "reverse_spiral",
        dt,
        inputs,
        rpm,
        desc,
        dict(
            yaw_rates_deg_s=rates,
            hold_s=hold_s,
            dt=dt,
            rpm=rpm,
            t_straight=t_straight,
            kp=kp,
            ki=ki,
            rudder_rate_deg_s=rudder_rate_deg_s,
            rudder_max_deg=rudder_max_deg,
            duration=duration,
            steady_rudder_deg=steady_d,
            steady_yaw_rate_deg_s=steady_r,
            saturated=sat,
        ),
    )


def speed_steps(
    vehicle,
    rpm_steps=(1000.0, 500.0, 1000.0, 1500.0),
    hold_s: float = 80.0,
    rudder_deg: float = 0.0,
    dt: float = 0.1,
    rpm: float | None = None,
    t_straight: float = 10.0,
) -> Manoeuvre:
    """Propeller-speed steps: acceleration and deceleration runs (surge and propulsion excitation).

    Sequence: start steady and straight at ``rpm`` (default nominal); ``rpm`` and rudder 0 for
    ``t_straight`` s; then the propeller speed is stepped (instantaneously) to each value of
    ``rpm_steps`` (rpm) in turn, each held ``hold_s`` s, with the rudder at ``rudder_deg`` (deg)
    from the first step on (0: straight-line runs; the first step then coincides with the rudder
    step -- repeat the start rpm as the first entry to let the turn settle first). Duration
    ``t_straight + len(rpm_steps) * hold_s`` (330 s for the defaults: 1500 -> 1000 -> 500 -> 1000
    -> 1500 rpm, surge time constant of NPS AUV II ~ 30 s at 1.9 m/s, longer at low speed).
    Source: reasoning -- ITTC 7.5-04-02-01 has stopping (2.2.7/2.2.8) and accelerating-turning
    (2.2.12) tests but no graded speed-step run; steps excite X'prop/eps and the u-dependence of
    all terms, which constant-rpm manoeuvres leave confounded. |rpm| <= the vehicle's rpm limit.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.
    rpm_steps : sequence of float, default (1000, 500, 1000, 1500)
        Propeller speeds in turn, rpm.
    hold_s : float, default 80.0
        How long each is held, s.
    rudder_deg : float, default 0.0
        Rudder angle from the first step on, deg.
    dt : float, default 0.1
        Integration step, s.
    rpm : float, optional
        Propeller speed of the start, rpm; default the nominal.
    t_straight : float, default 10.0
        Straight approach, s.

    Returns
    -------
    Manoeuvre
        Named ``"speed_steps"``.

    Raises
    ------
    ValueError
        No steps, times that are not whole numbers of steps, inputs beyond the vehicle's limits.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    steps = [float(x) for x in rpm_steps]
    if not steps:
        raise ValueError("speed steps: no rpm steps")
    duration = t_straight + len(steps) * hold_s
    n = _grid(duration, dt)
    edges = _steps([t_straight + i * hold_s for i in range(len(steps) + 1)], dt)
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    for i, r in enumerate(steps):
        inputs[edges[i] : edges[i + 1], 3] = r
    inputs[edges[0] :, 0] = math.radians(rudder_deg)
    desc = (
        f"Speed steps: {rpm:g} rpm straight for {t_straight:g} s, then "
        f"{', '.join(f'{r:g}' for r in steps)} rpm, each held {hold_s:g} s, rudder {rudder_deg:g} deg "
        f"from the first step; {duration:g} s, dt {dt:g} s."
    )
    return _finish(
        vehicle,
        "speed_steps",
        dt,
        inputs,
        rpm,
        desc,
        dict(
            rpm_steps=steps,
            hold_s=hold_s,
            rudder_deg=rudder_deg,
            dt=dt,
            rpm=rpm,
            t_straight=t_straight,
            duration=duration,
        ),
    )


def schroeder_phases(n: int) -> np.ndarray:
    """Schroeder (1970) low-peak-factor phases of equal-amplitude components:
    ``phi_k = -pi k (k - 1) / n``, k = 1..n.

    Parameters
    ----------
    n : int
        Number of components.

    Returns
    -------
    ndarray, shape (n,)
        The phases, rad.
    """
    k = np.arange(1, n + 1)
    return -math.pi * k * (k - 1) / n


def multisine(
    vehicle,
    amplitude_deg: float = 10.0,
    frequencies_hz=(0.005, 0.01, 0.02, 0.035, 0.05, 0.08, 0.12, 0.2),
    *,
    duration: float = 300.0,
    dt: float = 0.1,
    rpm: float | None = None,
    name: str = "multisine",
    options: MultisineOptions = MultisineOptions(),
) -> Manoeuvre:
    """Multisine rudder: sum of sines, equal amplitudes (or relative ``weights``, as a
    manoeuvre design chooses them) with (default) Schroeder phases.

    Sequence: constant ``rpm``; rudder 0 for ``t_execute`` s; then, with ``tau = t - t_execute``,
    ``delta_r(t) = c * sum_k w_k sin(2 pi f_k tau + phi_k)`` to ``duration`` s (``w_k`` = ``weights``,
    default 1, non-negative, not all zero), sampled on the grid and
    held over each step. ``phi_k`` = ``phases_rad`` or Schroeder phases
    (:func:`schroeder_phases`, low peak factor). Scaling, not clipping: ``c`` is chosen so the peak
    |delta_r| over the run equals ``amplitude_deg`` exactly; an ``amplitude_deg`` above the rudder
    limit is rejected by the limit check. The signal need not start at 0 (a step at execute).
    Default band 0.005-0.2 Hz brackets the NPS AUV II yaw corner (~0.05 Hz; Nomoto T ~ 3 s).
    Source: reasoning (system-identification input design; Schroeder 1970, IEEE Trans. Inf.
    Theory 16(1):85-89). Frequencies must lie in (0, 1/(2 dt)).

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.
    amplitude_deg : float, default 10.0
        Peak rudder angle over the run, deg.
    frequencies_hz : sequence of float, default (0.005, 0.01, 0.02, 0.035, 0.05, 0.08, 0.12, 0.2)
        Frequencies of the sines, Hz.
    duration : float, default 300.0
        Length of the run, s.
    dt : float, default 0.1
        Integration step, s.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.
    name : str, default "multisine"
        Name of the manoeuvre.
    options : MultisineOptions, default MultisineOptions()
        The phases ``phases_rad`` (default Schroeder), the relative amplitudes ``weights``
        (default 1 each) and the start of the signal ``t_execute`` (s).

    Returns
    -------
    Manoeuvre
        The manoeuvre; ``parameters`` records the phases, weights and component amplitude.

    Raises
    ------
    ValueError
        Frequencies outside (0, 1/(2 dt)), phases or weights of another length or not finite,
        negative or all-zero weights, ``t_execute`` outside the run, inputs beyond the limits.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    phases_rad, weights, t_execute = options.phases_rad, options.weights, options.t_execute
    f = np.asarray(frequencies_hz, dtype=float).ravel()
    if f.size == 0 or np.any(~np.isfinite(f)) or np.any(f <= 0) or np.any(f >= 0.5 / dt):
        raise ValueError(f"multisine: frequencies must be in (0, {0.5 / dt:g}) Hz, got {f.tolist()}")
    ph = schroeder_phases(f.size) if phases_rad is None else np.asarray(phases_rad, dtype=float).ravel()
    if ph.shape != f.shape or np.any(~np.isfinite(ph)):
        raise ValueError(f"multisine: need {f.size} finite phases, got {np.size(phases_rad)}")
    w = np.ones(f.size) if weights is None else np.asarray(weights, dtype=float).ravel()
    if w.shape != f.shape or np.any(~np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
        raise ValueError(f"multisine: need {f.size} non-negative weights, not all zero, got {w.tolist()}")
    n = _grid(duration, dt)
    (k0,) = _steps((t_execute,), dt)
    if not 0 <= k0 < n:
        raise ValueError(f"multisine: t_execute {t_execute} s outside the run")
    tau = (np.arange(n - k0) * dt)[:, None]
    raw = (w[None, :] * np.sin(2.0 * math.pi * f[None, :] * tau + ph[None, :])).sum(axis=1)
    peak = float(np.max(np.abs(raw)))
    scale = math.radians(amplitude_deg) / peak
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    inputs[k0:, 0] = scale * raw
    kind = "equal" if weights is None else "weighted"
    desc = (
        f"Multisine: {rpm:g} rpm; rudder 0 for {t_execute:g} s, then the sum of {f.size} {kind} sines at "
        f"{', '.join(f'{x:g}' for x in f)} Hz ({'Schroeder' if phases_rad is None else 'given'} phases), "
        f"scaled to a peak of {amplitude_deg:g} deg ({math.degrees(scale):.3g} deg each); "
        f"{duration:g} s, dt {dt:g} s."
    )
    return _finish(
        vehicle,
        name,
        dt,
        inputs,
        rpm,
        desc,
        dict(
            amplitude_deg=amplitude_deg,
            frequencies_hz=f.tolist(),
            phases_rad=ph.tolist(),
            weights=w.tolist(),
            schroeder=phases_rad is None,
            component_amplitude_deg=math.degrees(scale),
            duration=duration,
            dt=dt,
            rpm=rpm,
            t_execute=t_execute,
        ),
    )


def prbs(
    vehicle,
    amplitude_deg: float = 10.0,
    *,
    duration: float = 300.0,
    rng: np.random.Generator | None = None,
    dt: float = 0.1,
    rpm: float | None = None,
    options: PrbsOptions = PrbsOptions(),
) -> Manoeuvre:
    """Pseudo-random binary rudder sequence with a minimum hold time.

    Sequence: constant ``rpm``; rudder 0 for ``t_execute`` s; then the rudder is +-``amplitude_deg``
    (deg), on a clock of period ``min_hold_s`` s: the first level's sign is drawn with equal
    probability, and at each later clock tick the sign flips with probability ``p_switch`` (else it
    holds). Every hold is thus a whole number of clock periods, >= ``min_hold_s`` (the last may be
    cut by ``duration``). All randomness comes from ``rng`` (a ``numpy.random.Generator``, required):
    the same generator state gives the same sequence. ``parameters`` records the levels per clock
    period and the switch times, so the sequence is reproducible without the generator.
    Source: reasoning (random binary test signal of system identification; ``min_hold_s`` sets the
    band, ~ up to 1/(2 min_hold_s) Hz; 5 s suits NPS AUV II's ~3 s yaw time constant).

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.
    amplitude_deg : float, default 10.0
        Rudder level, deg.
    duration : float, default 300.0
        Length of the run, s.
    rng : numpy.random.Generator
        All randomness (required, despite the None default).
    dt : float, default 0.1
        Integration step, s.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.
    options : PrbsOptions, default PrbsOptions()
        The clock period ``min_hold_s`` (s), the switch probability ``p_switch`` and the start
        of the sequence ``t_execute`` (s).

    Returns
    -------
    Manoeuvre
        Named ``"prbs"``.

    Raises
    ------
    TypeError
        When ``rng`` is not a ``numpy.random.Generator``.
    ValueError
        ``p_switch`` outside [0, 1], ``min_hold_s`` below a step, ``t_execute`` outside the run,
        inputs beyond the limits.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("prbs: rng must be a numpy.random.Generator (randomness only through it)")
    min_hold_s, p_switch, t_execute = options.min_hold_s, options.p_switch, options.t_execute
    if not 0.0 <= p_switch <= 1.0:
        raise ValueError(f"prbs: p_switch {p_switch} outside [0, 1]")
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    n = _grid(duration, dt)
    k0, k_hold = _steps((t_execute, min_hold_s), dt)
    if k_hold < 1 or not 0 <= k0 < n:
        raise ValueError("prbs: need min_hold_s >= dt and t_execute inside the run")
    n_slots = -(-(n - k0) // k_hold)
    first = 1.0 if rng.random() < 0.5 else -1.0
    flips = rng.random(n_slots - 1) < p_switch
    levels = first * np.concatenate(([1.0], np.cumprod(np.where(flips, -1.0, 1.0))))
    inputs = np.zeros((n, 4))
    inputs[:, 3] = rpm
    inputs[k0:, 0] = math.radians(amplitude_deg) * np.repeat(levels, k_hold)[: n - k0]
    switches = [float((k0 + (i + 1) * k_hold) * dt) for i in np.flatnonzero(flips)]
    desc = (
        f"PRBS: {rpm:g} rpm; rudder 0 for {t_execute:g} s, then +-{amplitude_deg:g} deg, clock "
        f"{min_hold_s:g} s, switch probability {p_switch:g} per tick, first level "
        f"{first * amplitude_deg:+g} deg, {len(switches)} switches; {duration:g} s, dt {dt:g} s."
    )
    return _finish(
        vehicle,
        "prbs",
        dt,
        inputs,
        rpm,
        desc,
        dict(
            amplitude_deg=amplitude_deg,
            min_hold_s=min_hold_s,
            duration=duration,
            dt=dt,
            rpm=rpm,
            t_execute=t_execute,
            p_switch=p_switch,
            bit_generator=type(rng.bit_generator).__name__,
            levels=[int(x) for x in levels],
            switch_times_s=switches,
        ),
    )


def vertical_zigzag(
    vehicle,
    planes_deg: float = 10.0,
    pitch_deg: float | None = None,
    *,
    dt: float = 0.1,
    duration: float = 120.0,
    rpm: float | None = None,
    first_sign: int = 1,
    options: ZigzagOptions = ZigzagOptions(),
) -> Manoeuvre:
    """Vertical-plane zigzag ``planes_deg/pitch_deg``: stern planes triggered on pitch angle (6-DOF).

    The submarine analogue of the ITTC 7.5-04-02-01 Z-manoeuvre (Sec. 2.2.2) in the vertical plane:
    after ``t_execute`` s straight and level, the stern planes ``delta_s`` are put to
    ``first_sign * planes_deg`` (deg); when the pitch angle theta has changed from its execute value
    by ``pitch_deg`` (deg, default ``planes_deg``) in the direction the planes drive it they are
    reversed, and so on to ``duration`` s; rudder and bow planes 0, constant ``rpm``. A positive
    ``delta_s`` changes theta with the sign of M'ds (NPS AUV II: nose down, diving first). Runs the
    closed loop on the given vehicle (the same kernel as :func:`zigzag`, with input 1 triggered on
    state 4) and returns the plane history it applied. 6-DOF only (``mode="horizontal"`` rejects
    non-zero planes).

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle, the "truth" of the closed loop (6-DOF).
    planes_deg : float, default 10.0
        Stern-plane angle, deg.
    pitch_deg : float, optional
        Pitch change that reverses the planes, deg; default ``planes_deg``.
    dt : float, default 0.1
        Integration step, s.
    duration : float, default 120.0
        Length of the run, s.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.
    first_sign : int, default 1
        Sign of the first command (the name gets an ``m`` suffix for -1).
    options : ZigzagOptions, default ZigzagOptions()
        The time of the first plane command (``t_execute``, s) and the plane rate limit
        (``rate_deg_s``, deg/s; 0 = instantaneous).

    Returns
    -------
    Manoeuvre
        Named ``vertical_zigzag10_10`` style; ``parameters`` records the switch times.

    Raises
    ------
    RuntimeError
        If the closed-loop simulation diverges.
    ValueError
        A duration that is not a whole number of steps, or inputs beyond the vehicle's limits.
    """
    rpm = vehicle.nominal_rpm if rpm is None else rpm
    pitch_deg = planes_deg if pitch_deg is None else pitch_deg
    t_execute, plane_rate_deg_s = options.t_execute, options.rate_deg_s
    n = _grid(duration, dt)
    pitch_sign = math.copysign(1.0, vehicle.coefficients.get("Mds", -1.0))
    inputs = _triggered_zigzag(
        vehicle,
        rpm,
        dt,
        n,
        1,
        4,
        planes_deg,
        pitch_deg,
        first_sign,
        pitch_sign,
        t_execute,
        plane_rate_deg_s,
        f"vertical zigzag {planes_deg}/{pitch_deg}",
    )
    name = f"vertical_zigzag{planes_deg:g}_{pitch_deg:g}" + ("" if first_sign > 0 else "m")
    switches = np.flatnonzero(np.diff(np.sign(inputs[:, 1])) != 0) + 1
    desc = (
        f"Vertical zigzag {planes_deg:g}/{pitch_deg:g}: {rpm:g} rpm; straight and level {t_execute:g} s, "
        f"then stern planes {first_sign * planes_deg:+g} deg, reversed each time the pitch change reaches "
        f"{pitch_deg:g} deg (closed loop on the true vehicle, 6-DOF); {len(switches)} plane changes in "
        f"{duration:g} s; plane rate "
        f"{'instantaneous' if plane_rate_deg_s <= 0 else f'{plane_rate_deg_s:g} deg/s'}; dt {dt:g} s."
    )
    return _finish(
        vehicle,
        name,
        dt,
        inputs,
        rpm,
        desc,
        dict(
            planes_deg=planes_deg,
            pitch_deg=pitch_deg,
            dt=dt,
            duration=duration,
            rpm=rpm,
            t_execute=t_execute,
            first_sign=first_sign,
            plane_rate_deg_s=plane_rate_deg_s,
            switch_times_s=[float(k * dt) for k in switches],
        ),
    )


def library(vehicle, dt: float = 0.1, rpm: float | None = None, seed: int = 0) -> dict[str, Manoeuvre]:
    """The standard manoeuvre set, ``{name: Manoeuvre}`` (each manoeuvre's ``name`` is its key).

    - ``spiral``: :func:`spiral`, the paper's 10-minute spiral (600 s);
    - ``turn+20``, ``turn-20``: :func:`turning_circle` at +-20 deg (150 s each);
    - ``zigzag10_10``: :func:`zigzag` 10/10 (120 s); ``zigzag20_20``: 20/20 (150 s);
    - ``pull_out``: :func:`pull_out`, 20 deg held 60 s, then 0 (180 s);
    - ``reverse_spiral``: :func:`reverse_spiral`, r = 4, 3, 2, 1, 0.5, 0, -0.5, ... -4 deg/s, 30 s
      each (340 s);
    - ``speed_steps``: :func:`speed_steps`, 1500 -> 1000, 500, 1000, 1500 rpm, 80 s each (330 s);
    - ``multisine``: :func:`multisine`, 10 deg peak, 8 Schroeder-phased sines 0.005-0.2 Hz (300 s);
    - ``prbs``: :func:`prbs`, +-10 deg, 5 s clock, ``numpy.random.default_rng(seed)`` (300 s);
    - ``vertical_zigzag10_10``: :func:`vertical_zigzag` 10/10, stern planes on pitch (120 s).

    2740 s in all. All at ``rpm`` (default nominal) except the speed steps, which start there;
    the reverse-spiral targets and gains suit NPS AUV II at its nominal 1500 rpm. The generators'
    own names ``turnp20``, ``turnm20``, ``pull_outp20`` are replaced by the keys. The vertical
    zigzag has non-zero stern planes: simulate it with ``mode="6dof"``.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle, the "truth" of the closed-loop manoeuvres.
    dt : float, default 0.1
        Integration step, s.
    rpm : float, optional
        Propeller speed, rpm; default the nominal.
    seed : int, default 0
        Seed of the PRBS generator.

    Returns
    -------
    dict
        ``{name: Manoeuvre}`` in the order above.
    """
    out = [
        ("spiral", spiral(vehicle, dt=dt, rpm=rpm)),
        ("turn+20", turning_circle(vehicle, 20.0, dt=dt, rpm=rpm)),
        ("turn-20", turning_circle(vehicle, -20.0, dt=dt, rpm=rpm)),
        ("zigzag10_10", zigzag(vehicle, 10.0, dt=dt, rpm=rpm)),
        ("zigzag20_20", zigzag(vehicle, 20.0, dt=dt, rpm=rpm, duration=150.0)),
        ("pull_out", pull_out(vehicle, dt=dt, rpm=rpm)),
        ("reverse_spiral", reverse_spiral(vehicle, dt=dt, rpm=rpm)),
        ("speed_steps", speed_steps(vehicle, dt=dt, rpm=rpm)),
        ("multisine", multisine(vehicle, dt=dt, rpm=rpm)),
        ("prbs", prbs(vehicle, rng=np.random.default_rng(seed), dt=dt, rpm=rpm)),
        ("vertical_zigzag10_10", vertical_zigzag(vehicle, dt=dt, rpm=rpm)),
    ]
    return {key: (m if m.name == key else dataclasses.replace(m, name=key)) for key, m in out}


__all__ = [
    "ZigzagOptions",
    "ReverseSpiralOptions",
    "MultisineOptions",
    "PrbsOptions",
    "steady_state",
    "spiral",
    "turning_circle",
    "zigzag",
    "straight",
    "pull_out",
    "reverse_spiral",
    "speed_steps",
    "schroeder_phases",
    "multisine",
    "prbs",
    "vertical_zigzag",
    "library",
]
